"""``akc-drake export``: a ``poses.npz`` (from ``run``) to BVH, TRC, C3D, CSV or a ROS 2 MCAP bag.

Thin: the work is in :mod:`akc_drake.pipeline.export` and :mod:`akc_drake.io.export`.
"""

from __future__ import annotations

from akc_drake.commands._common import load_dims_option
from akc_drake.errors import UserError
from akc_drake.fileio import write_json


def main(args) -> int:
    from akc_drake.io.export.poses import load_poses
    from akc_drake.pipeline.export import check_format, check_writable, export_bag, export_poses, rts_report

    fmt = str(args.format).strip().lower()
    if fmt != "mcap":
        check_format(fmt)
    check_writable(args.out)
    if args.json:
        check_writable(args.json)
    dims = load_dims_option(args.dims)
    poses = load_poses(args.poses)
    calibration = load_poses(args.calibration) if args.calibration else None
    if fmt == "mcap":
        if args.smooth != "none":
            raise UserError("--smooth applies to bvh, trc, c3d and csv exports")
        summary = export_bag(poses, args.out, frame=args.frame, calibration=calibration)
    else:
        summary = export_poses(poses, fmt, args.out, stage=args.stage, frame=args.frame, calibration=calibration,
                               smooth=args.smooth, dims=dims)
        if args.smooth == "rts":
            gain = rts_report(poses, dims)
            if gain is not None:
                summary["rts_gain"] = gain
    what = summary.get("stage", "all stages")
    print(f"{summary['frames']} frames ({what}, {summary['frame']} frame) -> {summary['path']}")
    for topic, n in summary.get("messages", {}).items():
        print(f"  {topic}: {n} messages")
    for stage, g in summary.get("rts_gain", {}).items():
        pct = "" if g["gain_percent"] is None else f" ({g['gain_percent']:.0f} % lower)"
        rmse = f"{g['forward_rmse_cm']:.2f} -> {g['rts_rmse_cm']:.2f} cm"
        print(f"  RTS vs forward KF, {stage}: arm-joint RMSE {rmse}{pct}")
    if args.json:
        write_json(args.json, summary)
    return 0
