"""A gravity-aligned world frame W with the floor at z = 0, estimated from the operator's body (or an IMU).

The pipeline works in the camera frame C (x right, y down, z forward). Tools outside it (Blender, OpenSim,
RViz) expect a world frame: gravity along -z (or -y), the floor at height 0. We build W as:

* ``z_W`` = up. From the operator standing upright (a T-pose calibration, or the session itself): the median
  over frames of the unit trunk vector, hip midpoint -> shoulder midpoint. From a D435i's accelerometer when
  the recording has one: at rest it measures the specific force, which points up, so ``up = unit(mean accel)``
  rotated into C (:func:`up_from_accel`).
* The floor: a standing adult's shoulder midpoint is at 0.818 H above the floor and the hip joints at 0.530 H
  (Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., 2009, fig. 4.1), with the stature H
  from the calibrated arm segments (upper arm 0.186 H, forearm 0.146 H, same source). The floor height along
  ``z_W`` is the mean of the shoulder- and hip-based estimates (shoulder only when no hip is seen). This
  is an anthropometric estimate: a few centimetres for a typical adult, not a measured floor.
* ``x_W`` = the camera's optical axis projected on the floor (from the camera towards the operator),
  ``y_W = z_W x x_W``; the origin is on the floor directly below the camera. So the camera sits at
  ``(0, 0, h)`` in W, looking along +x (tilted by its pitch), and the operator facing the camera looks along
  -x with their right hand towards +y.

:data:`Y_UP_FROM_W` maps W to the Y-up convention of OpenSim's TRC (X forward of the operator, Y up, Z to the
operator's right); :data:`BVH_FROM_W` to BVH's (Y up, the character facing +Z, its left along +X). Both are
rotations (determinant +1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from akc_drake.core.skeleton import INDEX, BodyDimensions

#: Height of the shoulder midpoint (acromion) and the hip joints (greater trochanter) as fractions of stature,
#: and the upper-arm / forearm lengths as fractions of stature (Winter 2009, fig. 4.1).
SHOULDER_HEIGHT_RATIO = 0.818
HIP_HEIGHT_RATIO = 0.530
UPPER_ARM_RATIO = 0.186
FOREARM_RATIO = 0.146

#: W (z up) -> TRC/OpenSim (X = operator forward = -x_W, Y = up = z_W, Z = operator right = y_W).
Y_UP_FROM_W = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
#: W -> BVH (X = operator left = -y_W, Y = up = z_W, Z = operator forward = -x_W).
BVH_FROM_W = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n < 1e-9:
        raise ValueError(f"cannot normalise the vector {v!r}")
    return v / n


@dataclass(frozen=True)
class WorldFrame:
    """The pose of the world frame W in the camera frame C.

    Attributes:
        R_CW: ``(3, 3)`` rotation whose columns are W's axes expressed in C.
        p_CW: ``(3,)`` W's origin (the floor below the camera) in C, metres.
        source: how it was estimated (``"body"``, ``"imu"``, ``"identity"``), for reports.
        stature_m: the stature used for the floor estimate (NaN when none).
    """

    R_CW: np.ndarray
    p_CW: np.ndarray
    source: str = "body"
    stature_m: float = float("nan")

    def __post_init__(self):
        R = np.asarray(self.R_CW, dtype=float)
        p = np.asarray(self.p_CW, dtype=float).reshape(-1)
        if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ValueError(f"WorldFrame.R_CW must be a rotation matrix, got {R!r}")
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"WorldFrame.p_CW must be 3 finite numbers, got {self.p_CW!r}")
        object.__setattr__(self, "R_CW", R)
        object.__setattr__(self, "p_CW", p)

    @classmethod
    def camera(cls) -> WorldFrame:
        """W = C (for ``--frame camera``)."""
        return cls(np.eye(3), np.zeros(3), source="identity")

    @property
    def camera_height_m(self) -> float:
        """Height of the camera above the floor (``z`` of C's origin in W)."""
        return float(-(self.R_CW.T @ self.p_CW)[2])

    def to_world(self, points_C) -> np.ndarray:
        """``p_W = R_CW^T (p_C - p_CW)`` for points ``(..., 3)``; NaN stays NaN."""
        P = np.asarray(points_C, dtype=float)
        return (P - self.p_CW) @ self.R_CW

    def to_camera(self, points_W) -> np.ndarray:
        """The inverse of :meth:`to_world`."""
        return np.asarray(points_W, dtype=float) @ self.R_CW.T + self.p_CW

    def as_dict(self) -> dict:
        return {
            "R_CW": self.R_CW.tolist(),
            "p_CW": self.p_CW.tolist(),
            "source": self.source,
            "stature_m": None if not np.isfinite(self.stature_m) else float(self.stature_m),
            "camera_height_m": self.camera_height_m,
        }


def _mid(poses: np.ndarray, a: str, b: str) -> np.ndarray:
    return 0.5 * (poses[:, INDEX[a]] + poses[:, INDEX[b]])


def up_from_body(poses_C) -> np.ndarray:
    """Unit up vector in C: the normalised median of the unit trunk vectors (hip mid -> shoulder mid).

    Args:
        poses_C: ``(T, 12, 3)`` landmarks in C, NaN where missing; the operator stands upright.

    Raises:
        ValueError: when no frame sees both shoulders and both hips.
    """
    P = np.asarray(poses_C, dtype=float)
    trunk = _mid(P, "left_shoulder", "right_shoulder") - _mid(P, "left_hip", "right_hip")
    ok = np.isfinite(trunk).all(axis=1)
    n = np.linalg.norm(trunk, axis=1)
    ok &= n > 0.05
    if not ok.any():
        raise ValueError("no frame with both shoulders and both hips: cannot find the up direction")
    return _unit(np.median(trunk[ok] / n[ok, None], axis=0))


def up_from_accel(accel, R_C_imu=None) -> np.ndarray:
    """Unit up vector in C from accelerometer samples taken at rest (specific force points up).

    Args:
        accel: ``(N, 3)`` or ``(3,)`` accelerometer readings (m/s^2) in the IMU frame.
        R_C_imu: rotation from the IMU frame to C (identity when the IMU is aligned with C).
    """
    a = np.asarray(accel, dtype=float).reshape(-1, 3)
    a = a[np.isfinite(a).all(axis=1)]
    if len(a) == 0:
        raise ValueError("no finite accelerometer sample")
    g = np.median(a, axis=0)
    if not 5.0 < np.linalg.norm(g) < 15.0:
        raise ValueError(f"accelerometer reads |a| = {np.linalg.norm(g):.2f} m/s^2: not at rest, or not m/s^2")
    R = np.eye(3) if R_C_imu is None else np.asarray(R_C_imu, dtype=float)
    return _unit(R @ g)


def stature_from_dims(dims: BodyDimensions) -> float:
    """Stature (m) from the calibrated arm segments: mean of ``l / ratio`` over the four segments."""
    upper = (dims.LUA + dims.RUA) / UPPER_ARM_RATIO
    fore = (dims.LLA + dims.RLA) / FOREARM_RATIO
    return float((upper + fore) / 4.0)


def _median_dims(poses: np.ndarray) -> BodyDimensions:
    from akc_drake.core.skeleton import segment_lengths

    seg = segment_lengths(poses)
    vals = {k: float(np.nanmedian(v)) if np.isfinite(v).any() else np.nan for k, v in seg.items()}
    if not all(np.isfinite(vals[k]) for k in ("LUA", "LLA", "RUA", "RLA")):
        raise ValueError("an arm segment is never seen: give the calibrated body dimensions")
    return BodyDimensions(**vals)


def estimate_world_frame(poses_C, dims: BodyDimensions | None = None, *, up_C=None, source: str = "body") -> WorldFrame:
    """Estimate W from an upright operator (see the module docstring).

    Args:
        poses_C: ``(T, 12, 3)`` landmarks in C (a T-pose calibration, or the session itself).
        dims: the calibrated body dimensions (default: median segment lengths measured in ``poses_C``).
        up_C: a known up vector in C (e.g. from :func:`up_from_accel`); default :func:`up_from_body`.
        source: label stored in the result.

    Returns:
        The :class:`WorldFrame`.
    """
    P = np.asarray(poses_C, dtype=float)
    if P.ndim != 3 or P.shape[1:] != (len(INDEX), 3):
        raise ValueError(f"poses must have shape (T, {len(INDEX)}, 3), got {P.shape}")
    u = _unit(np.asarray(up_C, dtype=float)) if up_C is not None else up_from_body(P)
    if dims is None:
        dims = _median_dims(P)
    H = stature_from_dims(dims)
    # Height along u of the floor, from each frame's shoulders and hips (median over frames).
    sh = _mid(P, "left_shoulder", "right_shoulder") @ u - SHOULDER_HEIGHT_RATIO * H
    hp = _mid(P, "left_hip", "right_hip") @ u - HIP_HEIGHT_RATIO * H
    est = [float(np.nanmedian(v)) for v in (sh, hp) if np.isfinite(v).any()]
    if not est:
        raise ValueError("no frame with both shoulders or both hips: cannot find the floor")
    floor = float(np.mean(est))  # the floor plane is {p : u . p = floor}
    # x_W: the optical axis projected on the floor plane.
    z_c = np.array([0.0, 0.0, 1.0])
    x = z_c - (z_c @ u) * u
    if np.linalg.norm(x) < 1e-6:  # camera looking straight down/up: use its x axis instead
        x_c = np.array([1.0, 0.0, 0.0])
        x = x_c - (x_c @ u) * u
    x = _unit(x)
    y = np.cross(u, x)
    R_CW = np.column_stack([x, y, u])
    return WorldFrame(R_CW, floor * u, source=source, stature_m=H)
