"""Helpers shared by the subcommands: motions from names or files, body dimensions, JSON output."""

from __future__ import annotations

import os
from pathlib import Path

from akc_drake.errors import UserError
from akc_drake.fileio import atomic_save_npz
from akc_drake.fileio import write_json as _write_json

MOTION_FILE_SUFFIXES = (".bvh", ".amc")


def motion_from_spec(spec: str, *, cycles: int = 1, seed: int = 0, skeleton: str | None = None, rate_hz=10.0):
    """An :class:`~akc_drake.operator.motions.OperatorMotion` from a name (I, II, tpose, lpose) or a BVH/AMC file."""
    from akc_drake.operator.motions import make_motion

    if str(spec).lower().endswith(MOTION_FILE_SUFFIXES) or os.sep in str(spec):
        from akc_drake.operator.retarget import load_motion_file

        path = Path(spec)
        if not path.is_file():
            raise UserError(f"{path}: motion file not found")
        if skeleton is not None and not Path(skeleton).is_file():
            raise UserError(f"{skeleton}: skeleton file not found")
        return load_motion_file(path, skeleton, rate_hz=rate_hz)
    try:
        return make_motion(spec, cycles, seed)
    except ValueError as e:
        raise UserError(str(e)) from None


def load_dims_option(path: str | None):
    """BodyDimensions from ``--dims FILE.json`` (None when not given)."""
    if not path:
        return None
    from akc_drake.core.calibration import load_dims

    return load_dims(path)


def write_json(path: str | Path, data: dict) -> Path:
    """Write ``data`` as JSON atomically (temp file + rename); non-finite floats become null."""
    return _write_json(path, data)


def save_npz_atomic(path: str | Path, **arrays) -> Path:
    """``np.savez_compressed`` to a temp file, then rename (no pickled objects)."""
    return atomic_save_npz(path, **arrays)
