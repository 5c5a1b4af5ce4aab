"""``akc-drake calibrate``: arm lengths and shoulder width from a held T-pose or L-pose (paper §III-F).

The source runs through the mocap diagram's first stages (extractor -> occlusion filter -> constant-velocity
KF, no corrector) for ``--frames`` frames (default 100, as in the paper); the KF-filtered landmarks go to
:func:`akc_drake.core.calibration.calibrate_report`, and :func:`~akc_drake.core.calibration.save_dims` writes
the result atomically to ``--out``, which ``--dims`` then reads (``akc-drake run --dims FILE.json``).

``--source sim`` renders the simulated operator holding the pose for ``--frames`` frames; a real source is
read from its start (hold the pose from the first frame) until ``--frames`` frames or its end.

Every segment must be measured in at least half of the frames (and at least :data:`MIN_VALID_FRAMES`);
otherwise the command prints one line saying which segment and how many frames, and exits with code 2.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from akc_drake.errors import UserError

#: A segment must be finite in at least this many frames (and in half of them).
MIN_VALID_FRAMES = 5
#: ``--frames`` below this are refused.
MIN_FRAMES = 10


def min_valid_frames(frames: int) -> int:
    """Frames in which every segment must be measured for ``frames`` calibration frames."""
    return max(MIN_VALID_FRAMES, math.ceil(0.5 * frames))


def _config(args):
    from akc_drake.config import PipelineConfig, load_config

    cfg = load_config(args.config) if args.config else PipelineConfig()
    cfg.source = args.source
    cfg.motion = args.pose
    # The paper calibrates on KF-filtered frames; nothing downstream of the filter is needed.
    cfg.filter = "KF"
    cfg.corrector = "none"
    return cfg.validate()


def main(args) -> int:
    from akc_drake.commands.run import open_inputs, run_pipeline
    from akc_drake.core.calibration import calibrate_report, save_dims

    if isinstance(args.frames, bool) or not isinstance(args.frames, int) or args.frames < MIN_FRAMES:
        raise UserError(f"--frames must be an integer of at least {MIN_FRAMES}, got {args.frames!r}")
    out = Path(args.out)
    if out.exists() and out.is_dir():
        raise UserError(f"--out {out}: is a folder; give a file name such as dims.json")
    cfg = _config(args)
    motion = None
    if cfg.source.strip().lower() == "sim":
        from akc_drake.operator import motions

        make = motions.tpose if args.pose == "tpose" else motions.lpose
        motion = make(args.frames / cfg.camera.rate_hz, cfg.seed)
    inputs = open_inputs(args, cfg, motion=motion, default_real_dims=True)
    try:
        for note in inputs.notes:
            if "--dims" not in note:  # the dimensions are what we are measuring
                print(f"note: {note}", file=sys.stderr)
        from akc_drake import diagrams

        built = diagrams.build_mocap_diagram(
            cfg,
            frame_source=inputs.frame_source,
            detector=inputs.detector,
            dims=inputs.dims,
            motion=inputs.motion,
        )
        n = args.frames if built.num_frames is None else min(args.frames, built.num_frames)
        result = run_pipeline(
            built,
            n,
            detector=inputs.detector,
            realtime=cfg.source.startswith("realsense"),
            progress=sys.stderr.isatty(),
        )
    finally:
        inputs.close()

    frames = result.log.estimated
    need = min_valid_frames(args.frames)
    try:
        dims, report = calibrate_report(frames, args.pose, min_valid_frames=need)
    except ValueError as e:
        person = int(result.log.visibility.max(axis=1, initial=0).__gt__(0).sum()) if result.frames else 0
        raise UserError(
            f"too few valid frames to calibrate ({e}; a person was detected in {person} of {result.frames} "
            f"frames): keep the whole upper body in view and hold the {args.pose} from the first frame"
        ) from None
    if not out.parent.exists():
        try:
            out.parent.mkdir(parents=True)
        except OSError as e:
            raise UserError(f"--out {out}: cannot create folder {out.parent} ({e.strerror})") from None
    save_dims(out, dims, report)

    d = dims.as_dict()
    print(f"calibrated from {result.frames} frames ({args.pose}, {cfg.source}) -> {out}")
    truth = None
    if motion is not None:
        from akc_drake.diagrams import resolve_dims

        truth = resolve_dims(cfg).as_dict()
    for name, value in d.items():
        line = (
            f"  {name:3s} {100 * value:6.2f} cm  (std {100 * report.std_m[name]:.2f} cm, "
            f"{report.used_frames[name]} frames)"
        )
        if truth is not None:
            line += f"  true {100 * truth[name]:6.2f} cm, error {100 * (value - truth[name]):+.2f} cm"
        print(line)
    for w in report.warnings:
        print(f"warning: {w}", file=sys.stderr)
    return 0
