"""Arm-length calibration: T-pose / L-pose from landmark frames, or manual (ruler) values (paper §III-F).

The T-pose and L-pose methods average each segment's length over the frames in which the operator holds
the pose (the paper uses 100 KF-filtered frames). Frames where a segment is missing are skipped, and
outlier frames (a landmark jumping to a wrong depth) are rejected around the median before averaging.

Files: :func:`save_dims` writes JSON atomically (a temporary file in the same folder, then a rename), and
:func:`load_dims` reads it back, naming the file and the field on any error.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import (
    SEGMENT_NAMES,
    SIDES,
    BodyDimensions,
    check_pose,
    segment_lengths,
    side_indices,
)
from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write_text

#: Calibration postures: ``tpose`` arms straight out to the sides, ``lpose`` elbows bent ~90 degrees.
POSES: tuple[str, ...] = ("tpose", "lpose")
#: Expected median elbow angle (degrees) per posture; outside it the report carries a warning.
POSE_ELBOW_RANGE_DEG: dict[str, tuple[float, float]] = {"tpose": (140.0, 180.0), "lpose": (50.0, 130.0)}
#: Robust outlier rejection: frames farther than this many scaled MADs from the median are dropped.
OUTLIER_MADS = 3.5
#: ... but never closer than this to the median (metres), so that a noise-free series keeps all its frames.
OUTLIER_FLOOR_M = 1e-4
_MAD_TO_SIGMA = 1.4826

FILE_FORMAT = "akc-drake-body-dimensions"
FILE_VERSION = 1
_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class CalibrationReport:
    """How a calibration was obtained.

    Attributes:
        method: ``"tpose"``, ``"lpose"`` or ``"manual"``.
        frames: number of frames given (0 for manual).
        valid_frames: per segment, frames where its length was finite.
        used_frames: per segment, frames kept after outlier rejection (averaged).
        std_m: per segment, standard deviation of the kept lengths, metres.
        elbow_angle_deg: median elbow angle per side (``"left"``, ``"right"``), NaN if unknown.
        warnings: human-readable notes (e.g. the posture does not look like the requested one).
    """

    method: str
    frames: int = 0
    valid_frames: dict[str, int] = field(default_factory=dict)
    used_frames: dict[str, int] = field(default_factory=dict)
    std_m: dict[str, float] = field(default_factory=dict)
    elbow_angle_deg: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        def num(x: float):
            return None if not math.isfinite(x) else float(x)

        return {
            "method": self.method,
            "frames": int(self.frames),
            "valid_frames": {k: int(v) for k, v in self.valid_frames.items()},
            "used_frames": {k: int(v) for k, v in self.used_frames.items()},
            "std_m": {k: num(v) for k, v in self.std_m.items()},
            "elbow_angle_deg": {k: num(v) for k, v in self.elbow_angle_deg.items()},
            "warnings": list(self.warnings),
        }


def robust_mean(values: np.ndarray) -> tuple[float, float, int]:
    """Mean of the finite ``values`` after median/MAD outlier rejection.

    Returns:
        ``(mean, std, n_kept)``; NaN mean and std when there is no finite value.
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, 0
    med = float(np.median(v))
    mad = float(np.median(np.abs(v - med)))
    limit = max(OUTLIER_MADS * _MAD_TO_SIGMA * mad, OUTLIER_FLOOR_M)
    kept = v[np.abs(v - med) <= limit]
    return float(kept.mean()), float(kept.std()), int(kept.size)


def _median_elbow_angles(frames: np.ndarray) -> dict[str, float]:
    out = {}
    for side in SIDES:
        s, e, w = side_indices(side)
        a = frames[:, s] - frames[:, e]
        b = frames[:, w] - frames[:, e]
        na = np.linalg.norm(a, axis=1)
        nb = np.linalg.norm(b, axis=1)
        ok = np.isfinite(na) & np.isfinite(nb) & (na > 1e-9) & (nb > 1e-9)
        if not ok.any():
            out[side] = math.nan
            continue
        c = np.einsum("ij,ij->i", a[ok], b[ok]) / (na[ok] * nb[ok])
        out[side] = float(np.degrees(np.median(np.arccos(np.clip(c, -1.0, 1.0)))))
    return out


def calibrate_report(
    frames, pose: str = "tpose", *, min_valid_frames: int = 10
) -> tuple[BodyDimensions, CalibrationReport]:
    """Body dimensions from frames of an operator holding a calibration pose, with a report.

    Args:
        frames: ``(T, 12, 3)`` landmarks (the paper uses KF-filtered ones), NaN where missing.
        pose: ``"tpose"`` or ``"lpose"``; lengths are computed the same way, the posture is only checked
            (a median elbow angle outside the expected range adds a warning to the report).
        min_valid_frames: each segment needs at least this many frames where it is finite.

    Returns:
        ``(dims, report)``.

    Raises:
        ValueError: for a bad shape or pose name, or naming the segment that has too few valid frames.
    """
    if pose not in POSES:
        raise ValueError(f"calibration pose must be one of {', '.join(POSES)}, got {pose!r}")
    if isinstance(min_valid_frames, bool) or not isinstance(min_valid_frames, (int, np.integer)):
        raise ValueError(f"min_valid_frames must be an integer, got {min_valid_frames!r}")
    if min_valid_frames < 1:
        raise ValueError(f"min_valid_frames must be >= 1, got {min_valid_frames!r}")
    a = check_pose(frames, name="calibration frames", allow_trajectory=True)
    if a.ndim != 3:
        raise ValueError(f"calibration frames must have shape (T, 12, 3), got {a.shape}")
    a = np.where(np.isfinite(a), a, np.nan)
    lengths = segment_lengths(a)
    report = CalibrationReport(method=pose, frames=int(a.shape[0]))
    values: dict[str, float] = {}
    for name in SEGMENT_NAMES:
        series = lengths[name]
        n_valid = int(np.count_nonzero(np.isfinite(series) & (series > 0)))
        report.valid_frames[name] = n_valid
        if n_valid < min_valid_frames:
            raise ValueError(
                f"calibration: segment {name} has {n_valid} valid frame(s) out of {a.shape[0]}; "
                f"need at least {min_valid_frames}"
            )
        mean, std, kept = robust_mean(np.where(series > 0, series, np.nan))
        values[name] = mean
        report.used_frames[name] = kept
        report.std_m[name] = std
    report.elbow_angle_deg = _median_elbow_angles(a)
    lo, hi = POSE_ELBOW_RANGE_DEG[pose]
    for side, ang in report.elbow_angle_deg.items():
        if math.isfinite(ang) and not lo <= ang <= hi:
            report.warnings.append(
                f"{side} median elbow angle {ang:.0f} deg is outside [{lo:.0f}, {hi:.0f}] deg "
                f"expected for {pose}"
            )
    try:
        dims = BodyDimensions(**values)
    except ValueError as e:
        raise ValueError(f"calibration: {e}") from None
    return dims, report


def calibrate(frames, pose: str = "tpose", *, min_valid_frames: int = 10) -> BodyDimensions:
    """Body dimensions from frames of an operator holding a T-pose or L-pose.

    Per frame, the segment lengths (:func:`akc_drake.core.skeleton.segment_lengths`); per segment, the
    mean over the frames where it is finite, after rejecting frames more than 3.5 scaled MADs from the
    median. See :func:`calibrate_report` for the arguments and errors.
    """
    return calibrate_report(frames, pose, min_valid_frames=min_valid_frames)[0]


def manual(*, LUA: float, LLA: float, RUA: float, RLA: float, SW: float, unit: str = "m") -> BodyDimensions:
    """Body dimensions measured by hand (e.g. with a ruler, the paper's "Manual" column).

    Args:
        LUA, LLA, RUA, RLA, SW: the segment lengths in ``unit``.
        unit: ``"m"``, ``"cm"`` or ``"mm"``.

    Raises:
        ValueError: naming the unit or the field that is not a positive length.
    """
    if unit not in _UNITS:
        raise ValueError(f"unit must be one of {', '.join(_UNITS)}, got {unit!r}")
    scale = _UNITS[unit]
    values = {}
    for name, v in (("LUA", LUA), ("LLA", LLA), ("RUA", RUA), ("RLA", RLA), ("SW", SW)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ValueError(f"manual dimensions: {name} must be a number, got {v!r}")
        values[name] = float(v) * scale
    return BodyDimensions(**values)


def save_dims(path, dims: BodyDimensions, report: CalibrationReport | None = None) -> Path:
    """Write body dimensions (and how they were obtained) as JSON, atomically.

    Args:
        path: the output file; its folder must exist.
        dims: the dimensions.
        report: the calibration report, if any.

    Returns:
        The path written.

    Raises:
        UserError: naming the file when it cannot be written (nothing already there is lost).
    """
    if not isinstance(dims, BodyDimensions):
        raise ValueError(f"dims must be a BodyDimensions, got {type(dims).__name__}")
    path = Path(path)
    doc = {
        "format": FILE_FORMAT,
        "version": FILE_VERSION,
        "units": "m",
        "dimensions": dims.as_dict(),
        "calibration": report.as_dict() if report is not None else None,
    }
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise UserError(f"{path}: folder {folder} does not exist")
    try:
        atomic_write_text(path, text, fsync=True)
    except OSError as e:
        raise UserError(f"{path}: cannot write body dimensions: {e.strerror or e}") from None
    return path


def load_dims(path) -> BodyDimensions:
    """Read body dimensions written by :func:`save_dims` (or a plain ``{"LUA": ..., ...}`` JSON in metres).

    Raises:
        UserError: naming the file and the field (or the JSON line) that is wrong.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise UserError(f"{path}: cannot read: {e}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    if not isinstance(doc, dict):
        raise UserError(f"{path}: expected a JSON object, got {type(doc).__name__}")
    if "dimensions" in doc:
        fmt = doc.get("format", FILE_FORMAT)
        if fmt != FILE_FORMAT:
            raise UserError(f"{path}: field 'format' is {fmt!r}, expected {FILE_FORMAT!r}")
        version = doc.get("version", FILE_VERSION)
        if version != FILE_VERSION:
            raise UserError(
                f"{path}: field 'version' is {version!r}; this akc-drake reads version {FILE_VERSION}"
            )
        units = doc.get("units", "m")
        if units != "m":
            raise UserError(f"{path}: field 'units' is {units!r}; body dimensions files are in metres ('m')")
        d, where = doc["dimensions"], f"{path}: field 'dimensions'"
    else:
        d, where = doc, str(path)
    try:
        return BodyDimensions.from_dict(d, where=where)
    except ValueError as e:
        raise UserError(str(e)) from None
