"""Calibrating the operator's arm lengths and shoulder width on a source (paper §III-F).

The source runs through the mocap diagram's first stages (extractor -> occlusion filter -> constant-velocity
KF, no corrector) for a number of frames (100 in the paper); the KF-filtered landmarks go to
:func:`akc_drake.core.calibration.calibrate_report`. On ``sim`` the simulated operator holds the pose; a real
source is read from its start (the pose held from the first frame) until the frames are done or it ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from akc_drake.errors import UserError
from akc_drake.pipeline.inputs import open_inputs, source_kind
from akc_drake.pipeline.runner import RunResult, build_and_run

#: A segment must be finite in at least this many frames (and in half of them).
MIN_VALID_FRAMES = 5
#: Fewer calibration frames than this are refused.
MIN_FRAMES = 10


def check_frames(frames) -> int:
    """``frames`` when it is an integer of at least :data:`MIN_FRAMES`; else a UserError naming ``--frames``."""
    if isinstance(frames, bool) or not isinstance(frames, int) or frames < MIN_FRAMES:
        raise UserError(f"--frames must be an integer of at least {MIN_FRAMES}, got {frames!r}")
    return frames


def min_valid_frames(frames: int) -> int:
    """Frames in which every segment must be measured for ``frames`` calibration frames."""
    return max(MIN_VALID_FRAMES, math.ceil(0.5 * frames))


@dataclass
class Calibration:
    """The outcome of :func:`calibrate_on_source`.

    Attributes:
        dims: the calibrated :class:`~akc_drake.core.skeleton.BodyDimensions`.
        report: the :class:`~akc_drake.core.calibration.CalibrationReport` (spread, frames used, warnings).
        result: the run that produced the frames.
        truth: the simulated operator's true dimensions (``sim`` only), else None.
        notes: remarks for the user.
    """

    dims: object
    report: object
    result: RunResult
    truth: dict | None
    notes: list[str]


def calibrate_on_source(
    cfg,
    pose: str,
    frames: int,
    *,
    dims_path: str | None = None,
    depth_m: float | None = None,
    pose_model: str | None = None,
    seconds: float | None = None,
    progress: bool = False,
    notify=None,
) -> Calibration:
    """Run ``cfg.source`` for ``frames`` frames through extractor, occlusion filter and KF, and calibrate.

    Args:
        cfg: the pipeline configuration (its filter and corrector are set to ``KF`` and ``none`` here).
        pose: ``"tpose"`` or ``"lpose"``.
        frames: calibration frames (at least :data:`MIN_FRAMES`).
        dims_path, depth_m, pose_model, seconds: as in :func:`~akc_drake.pipeline.inputs.open_inputs`.
        progress: a progress bar on stderr.
        notify: called with each remark for the user before the run (e.g. printing to stderr).

    Raises:
        UserError: too few frames asked for, or too few valid frames to calibrate (one line saying why).
    """
    from akc_drake.core.calibration import calibrate_report

    check_frames(frames)
    cfg.motion = pose
    # The paper calibrates on KF-filtered frames; nothing downstream of the filter is needed.
    cfg.filter = "KF"
    cfg.corrector = "none"
    cfg = cfg.validate()
    motion = None
    sim = cfg.source.strip().lower() == "sim"
    if sim:
        from akc_drake.operator import motions

        make = motions.tpose if pose == "tpose" else motions.lpose
        motion = make(frames / cfg.camera.rate_hz, cfg.seed)
    inputs = open_inputs(
        cfg,
        dims_path=dims_path,
        depth_m=depth_m,
        pose_model=pose_model,
        seconds=seconds,
        motion=motion,
        default_real_dims=True,
    )
    notes = [n for n in inputs.notes if "--dims" not in n]  # the dimensions are what we are measuring
    for note in notes if notify is not None else ():
        notify(note)
    try:
        _, result = build_and_run(
            cfg, inputs, num_frames=frames, realtime=source_kind(cfg.source) == "realsense", progress=progress
        )
    finally:
        inputs.close()
    try:
        dims, report = calibrate_report(result.log.estimated, pose, min_valid_frames=min_valid_frames(frames))
    except ValueError as e:
        person = int((result.log.visibility.max(axis=1, initial=0) > 0).sum()) if result.frames else 0
        raise UserError(
            f"too few valid frames to calibrate ({e}; a person was detected in {person} of {result.frames} "
            f"frames): keep the whole upper body in view and hold the {pose} from the first frame"
        ) from None
    truth = None
    if sim:
        from akc_drake.diagrams import resolve_dims

        truth = resolve_dims(cfg).as_dict()
    return Calibration(dims=dims, report=report, result=result, truth=truth, notes=notes)
