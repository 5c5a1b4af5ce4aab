"""C3D export through ``ezc3d`` (the C3D library of the biomechanics community, with wheels on PyPI).

Points are written in millimetres in the world frame W (Z up, the usual laboratory convention; the
``POINT:X_SCREEN``/``Y_SCREEN`` parameters say so for viewers such as Mokka), one point per landmark named
with MediaPipe's names. A missing landmark is NaN in ezc3d, which C3D stores as an invalid point (residual -1).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from akc_drake.fileio import atomic_write_via_path


def _ezc3d():
    try:
        import ezc3d
    except ImportError as e:  # pragma: no cover - a dependency of the package
        raise ImportError(f"C3D export needs ezc3d (pip install ezc3d): {e}") from None
    return ezc3d


def write_c3d(path, points_mm: np.ndarray, names, *, rate_hz: float, z_up: bool = True) -> Path:
    """Write ``points_mm`` ``(T, M, 3)`` (millimetres, NaN where missing) as a C3D file, atomically.

    Args:
        path: the ``.c3d`` file.
        points_mm: marker positions in millimetres.
        names: the M marker labels.
        rate_hz: the frame rate.
        z_up: the data are Z-up (world frame); False for camera-frame data (Y down).
    """
    ezc3d = _ezc3d()
    P = np.asarray(points_mm, dtype=float)
    T, M, _ = P.shape
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rate_hz)]
    c["parameters"]["POINT"]["LABELS"]["value"] = [str(n) for n in names]
    c["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = [f"akc-drake landmark {n}" for n in names]
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, M, T))
    pts[:3] = P.transpose(2, 1, 0)
    c["data"]["points"] = pts
    c.add_parameter("POINT", "X_SCREEN", ["+X"])
    c.add_parameter("POINT", "Y_SCREEN", ["+Z" if z_up else "-Y"])

    def writer(tmp: Path) -> None:
        c.write(str(tmp))

    return atomic_write_via_path(path, writer)
