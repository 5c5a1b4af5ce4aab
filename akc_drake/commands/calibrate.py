"""``akc-drake calibrate``: arm lengths and shoulder width from a held T-pose or L-pose (paper §III-F).

The source runs through the mocap diagram's first stages (extractor -> occlusion filter -> constant-velocity
KF, no corrector) for ``--frames`` frames (default 100, as in the paper), see
:func:`akc_drake.pipeline.calibration.calibrate_on_source`; :func:`~akc_drake.core.calibration.save_dims`
writes the result atomically to ``--out``, which ``--dims`` then reads (``akc-drake run --dims FILE.json``).

``--source sim`` renders the simulated operator holding the pose for ``--frames`` frames; a real source is
read from its start (hold the pose from the first frame) until ``--frames`` frames or its end.

Every segment must be measured in at least half of the frames (and at least :data:`MIN_VALID_FRAMES`);
otherwise the command prints one line saying which segment and how many frames, and exits with code 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

from akc_drake.commands._common import check_output_file
from akc_drake.errors import UserError
from akc_drake.pipeline.calibration import MIN_FRAMES, MIN_VALID_FRAMES, check_frames, min_valid_frames

__all__ = ["MIN_FRAMES", "MIN_VALID_FRAMES", "main", "min_valid_frames"]


def _config(args):
    from akc_drake.config import PipelineConfig, load_config

    cfg = load_config(args.config) if args.config else PipelineConfig()
    cfg.source = args.source
    for name, default in (("body", "primitive"), ("detector", "sim")):
        value = getattr(args, name, default)
        if not args.config or value != default:
            setattr(cfg, name, value)
    return cfg


def main(args) -> int:
    from akc_drake.core.calibration import save_dims
    from akc_drake.pipeline.calibration import calibrate_on_source

    check_frames(args.frames)
    out = Path(args.out)
    if out.exists() and out.is_dir():
        raise UserError(f"--out {out}: is a folder; give a file name such as dims.json")
    check_output_file(args.out, "--out")
    cfg = _config(args)
    cal = calibrate_on_source(
        cfg,
        args.pose,
        args.frames,
        dims_path=getattr(args, "dims", None),
        depth_m=getattr(args, "depth", None),
        pose_model=getattr(args, "pose_model", None),
        seconds=getattr(args, "seconds", None),
        progress=sys.stderr.isatty(),
        notify=lambda note: print(f"note: {note}", file=sys.stderr),
    )
    if not out.parent.exists():
        try:
            out.parent.mkdir(parents=True)
        except OSError as e:
            raise UserError(f"--out {out}: cannot create folder {out.parent} ({e.strerror})") from None
    save_dims(out, cal.dims, cal.report)

    print(f"calibrated from {cal.result.frames} frames ({args.pose}, {cfg.source}) -> {out}")
    for name, value in cal.dims.as_dict().items():
        line = (
            f"  {name:3s} {100 * value:6.2f} cm  (std {100 * cal.report.std_m[name]:.2f} cm, "
            f"{cal.report.used_frames[name]} frames)"
        )
        if cal.truth is not None:
            truth = cal.truth[name]
            line += f"  true {100 * truth:6.2f} cm, error {100 * (value - truth):+.2f} cm"
        print(line)
    for w in cal.report.warnings:
        print(f"warning: {w}", file=sys.stderr)
    return 0
