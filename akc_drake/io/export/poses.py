"""Skeletons to export: read and check ``poses.npz`` (what ``run`` writes), choose a stage, smooth, change frame.

``poses.npz`` (see :mod:`akc_drake.commands.run`) holds ``t`` (T,), ``names`` (12,) and per stage a ``(T, 12, 3)``
array in the camera frame C, metres, NaN where missing: ``raw``, ``accepted`` (after the occlusion filter),
``filtered``, ``corrected``, ``truth``; optionally ``dims`` (5,) ``[LUA, LLA, RUA, RLA, SW]`` (the calibrated
body dimensions the run used) and ``up_C`` (3,) (the up direction from an IMU).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS, SEGMENT_NAMES, BodyDimensions
from akc_drake.core.world_frame import WorldFrame, estimate_world_frame
from akc_drake.errors import UserError

#: Stages an export can take from ``poses.npz``.
STAGES: tuple[str, ...] = ("raw", "accepted", "filtered", "corrected", "truth")


@dataclass
class PoseSet:
    """A recorded session's skeletons.

    Attributes:
        t: ``(T,)`` frame times, seconds.
        stages: stage name -> ``(T, 12, 3)`` landmarks in C, metres.
        dims: the calibrated body dimensions, when known.
        up_C: the up direction in C from an IMU, when known.
        source: the file it came from.
    """

    t: np.ndarray
    stages: dict[str, np.ndarray]
    dims: BodyDimensions | None = None
    up_C: np.ndarray | None = None
    source: str = "<memory>"
    notes: list[str] = field(default_factory=list)

    @property
    def num_frames(self) -> int:
        return len(self.t)

    @property
    def rate_hz(self) -> float:
        """The frame rate from the median frame interval (10 Hz for a single frame)."""
        if len(self.t) < 2:
            return 10.0
        dt = float(np.median(np.diff(self.t)))
        return 1.0 / dt if dt > 0 else 10.0

    def stage(self, name: str) -> np.ndarray:
        if name not in self.stages:
            have = ", ".join(self.stages) or "none"
            raise UserError(f"{self.source}: no stage {name!r} (it has {have})")
        return self.stages[name]


def _field(npz, path: str, key: str) -> np.ndarray:
    try:
        return np.asarray(npz[key])
    except ValueError as e:  # object arrays need pickle, which we never allow
        raise UserError(f"{path}: field {key!r} cannot be read without pickle ({e})") from None


def load_poses(path) -> PoseSet:
    """Read and check a ``poses.npz``; a user mistake raises :class:`UserError` naming the file and field."""
    p = Path(path)
    if not p.is_file():
        raise UserError(f"{p}: no such file")
    try:
        npz = np.load(p, allow_pickle=False)
    except Exception as e:  # not a zip, truncated, ...
        raise UserError(f"{p}: not a readable .npz file ({type(e).__name__}: {e})") from None
    with npz:
        if "t" not in npz.files:
            raise UserError(f"{p}: missing field 't'")
        t = _field(npz, str(p), "t").astype(float)
        if t.ndim != 1 or not np.all(np.isfinite(t)):
            raise UserError(f"{p}: field 't' must be a 1-D array of finite times, got shape {t.shape}")
        if "names" in npz.files:
            names = tuple(str(n) for n in _field(npz, str(p), "names"))
            if names != LANDMARKS:
                raise UserError(f"{p}: field 'names' must be the 12 landmarks {', '.join(LANDMARKS)}; got {names}")
        stages = {}
        for s in STAGES:
            if s not in npz.files:
                continue
            a = _field(npz, str(p), s)
            if a.shape != (len(t), NUM_LANDMARKS, 3):
                raise UserError(f"{p}: field {s!r} must have shape ({len(t)}, {NUM_LANDMARKS}, 3), got {a.shape}")
            a = a.astype(float)
            if s == "truth" and not np.isfinite(a).any():
                continue  # sources without ground truth store NaN
            stages[s] = a
        if not stages:
            raise UserError(f"{p}: no skeleton field (one of {', '.join(STAGES)})")
        dims = up = None
        if "dims" in npz.files:
            d = _field(npz, str(p), "dims").astype(float).reshape(-1)
            if d.shape != (len(SEGMENT_NAMES),):
                raise UserError(f"{p}: field 'dims' must hold {len(SEGMENT_NAMES)} lengths {SEGMENT_NAMES}")
            try:
                dims = BodyDimensions(**dict(zip(SEGMENT_NAMES, d, strict=True)))
            except ValueError as e:
                raise UserError(f"{p}: field 'dims': {e}") from None
        if "up_C" in npz.files:
            up = _field(npz, str(p), "up_C").astype(float).reshape(-1)
            if up.shape != (3,) or not np.all(np.isfinite(up)) or np.linalg.norm(up) < 1e-6:
                raise UserError(f"{p}: field 'up_C' must be a non-zero 3-vector")
    return PoseSet(t=t, stages=stages, dims=dims, up_C=up, source=str(p))


def world_frame_for(poses: PoseSet, calibration: PoseSet | None = None, *, frame: str = "world") -> WorldFrame:
    """The frame to export in: ``camera`` (C itself) or ``world`` (see :mod:`akc_drake.core.world_frame`).

    ``world`` is estimated from ``calibration`` (a T-pose session) when given, else from the session itself
    (the operator is assumed upright on average), with the IMU's up direction when either file has one.
    """
    if frame == "camera":
        return WorldFrame.camera()
    if frame != "world":
        raise UserError(f"--frame must be camera or world, got {frame!r}")
    ref = calibration if calibration is not None else poses
    # The occlusion filter's output first: a hidden shoulder's depth (the hand's) would tilt the trunk vector; the
    # accepted landmarks have it removed (measured on a rendered Motion II: 0.8 deg tilt vs 20 deg from the KF's).
    stage = next((s for s in ("accepted", "corrected", "filtered", "raw") if s in ref.stages), None)
    if stage is None:
        raise UserError(f"{ref.source}: no measured skeleton to estimate the world frame from")
    up = ref.up_C if ref.up_C is not None else poses.up_C
    dims = poses.dims or ref.dims
    try:
        return estimate_world_frame(ref.stages[stage], dims, up_C=up, source="imu" if up is not None else "body")
    except ValueError as e:
        raise UserError(f"{ref.source}: cannot estimate the world frame ({e}); use --frame camera") from None
