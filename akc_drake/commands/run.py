"""``akc-drake run``: the mocap (or teleop) diagram on a source, with per-stage latency.

Sources: ``sim`` (the rendered operator doing ``--motion``), ``recording:DIR``, ``bag:FILE``, ``realsense``,
``video:FILE`` (see :mod:`akc_drake.io.sources`). Real sources go through MediaPipe's PoseLandmarker.

Outputs: ``poses.npz`` (per frame: ``t``, ``raw``, ``accepted``, ``filtered``, ``corrected``, ``truth``,
``visibility``, ``names``; NaN where missing) in ``--out`` (default: next to ``--json``, else ``out/run``), a
short summary on stdout and, with ``--json``, the summary as JSON: ``frames``, ``frames_with_person``,
``visibility_mean`` and ``visible_share`` per landmark, ``latency_ms`` per stage, arm-length ranges, and
errors against the ground truth when the source has it (``sim``, simulated recordings).

The work is done in :mod:`akc_drake.pipeline` (opening the source, the stage-sliced runner and its latency
figures, the summary); this module parses the options and prints.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from akc_drake.commands._common import check_output_dir, check_output_file
from akc_drake.core.skeleton import SEGMENT_NAMES
from akc_drake.errors import UserError
from akc_drake.fileio import write_json


def _config(args):
    from akc_drake.config import PipelineConfig, load_config

    if args.cycles < 1:
        raise UserError(f"--cycles must be at least 1, got {args.cycles}")
    cfg = load_config(args.config) if args.config else PipelineConfig()
    # Options given on the command line win over the file (argparse defaults do not).
    cfg.source = args.source
    for name, default in (
        ("motion", "II"),
        ("cycles", 1),
        ("seed", 0),
        ("filter", "KF"),
        ("corrector", "AKC"),
        ("body", "primitive"),
        ("detector", "sim"),
    ):
        value = getattr(args, name, default)
        if not args.config or value != default:
            setattr(cfg, name, value)
    if getattr(args, "skeleton", None):
        cfg.skeleton = args.skeleton
    if getattr(args, "joint_names", None):
        from akc_drake.operator.retarget import parse_joint_names

        cfg.joint_names = parse_joint_names(args.joint_names)
    if getattr(args, "akc_plus", None):
        from akc_drake.config import parse_akc_plus

        if cfg.corrector != "AKC+":
            raise UserError(f"--akc-plus: sets AKC+, but the corrector is {cfg.corrector} (add --corrector AKC+)")
        cfg.akc_plus = {**cfg.akc_plus, **parse_akc_plus(args.akc_plus)}
    if getattr(args, "arm_limits", None):
        from akc_drake.config import parse_arm_limits

        if not args.teleop:
            raise UserError("--arm-limits: limits the robot's commands, use it with --teleop")
        cfg.arm_limits = parse_arm_limits(args.arm_limits)
    return cfg.validate()


def _meshcat(args):
    if not args.meshcat:
        return None
    if not args.teleop:
        raise UserError("--meshcat draws the robot: use it with --teleop")
    from pydrake.geometry import Meshcat, MeshcatParams

    params = MeshcatParams()
    params.host = "localhost"  # Drake's default ("*") would listen on every network interface
    meshcat = Meshcat(params)
    print(f"Meshcat: {meshcat.web_url()}", file=sys.stderr)
    return meshcat


def main(args) -> int:
    from akc_drake.pipeline import build_and_run, open_inputs, run_summary, save_poses
    from akc_drake.pipeline.inputs import source_kind

    cfg = _config(args)
    kind = source_kind(cfg.source)
    out_dir = Path(args.out) if args.out else (Path(args.json).parent if args.json else Path("out/run"))
    check_output_file(args.json, "--json")
    check_output_dir(str(out_dir), "--out" if args.out else "the poses.npz folder")
    lcm = _interop_checks(args)
    inputs = open_inputs(
        cfg,
        dims_path=getattr(args, "dims", None),
        depth_m=getattr(args, "depth", None),
        pose_model=getattr(args, "pose_model", None),
        seconds=getattr(args, "seconds", None),
        skeleton=getattr(args, "skeleton", None),
    )
    try:
        if kind == "realsense" and args.seconds is None:
            inputs.notes.append("live camera without --seconds: press Ctrl-C to stop")
        for note in inputs.notes:
            print(f"note: {note}", file=sys.stderr)
        built, result = build_and_run(
            cfg,
            inputs,
            teleop=bool(args.teleop),
            seconds=args.seconds,
            meshcat=_meshcat(args),
            lcm=lcm,
            realtime=(kind == "realsense"),
            progress=sys.stderr.isatty(),
        )
        built.close()  # (the detectors the diagram made for itself: the run is over)
    finally:
        inputs.close()
    if result.stop_reason.startswith("source error"):
        print(
            f"warning: the source stopped after {result.frames} frames ({result.stop_reason})",
            file=sys.stderr,
        )
    summary = run_summary(cfg, inputs, built, result, teleop=bool(args.teleop), depth_m=args.depth)
    from akc_drake.pipeline.export import imu_up_for_source

    summary["poses_npz"] = str(save_poses(out_dir, result.log, dims=built.dims, up_C=imu_up_for_source(cfg.source)))
    _interop_outputs(args, summary, built, result, out_dir)
    if args.json:
        write_json(args.json, summary)
    _print_summary(summary, result.wall_s)
    return 0


def _interop_checks(args):
    """Check --export/--ros2-bag/--lcm before running (one line, exit 2); returns the DrakeLcm or None."""
    from akc_drake.pipeline.export import check_format, check_writable

    for f in (args.export or "").split(","):
        if f.strip():
            check_format(f, "--export")
    if args.smooth != "none" and not args.export:
        raise UserError("--smooth applies to the --export files: give --export FMT")
    if args.ros2_bag:
        check_writable(args.ros2_bag)
    if not args.lcm:
        return None
    if not args.teleop:
        raise UserError("--lcm publishes the robot's commands: use it with --teleop")
    from akc_drake.systems.lcm_publishers import open_lcm

    lcm = open_lcm(args.lcm)
    print(f"LCM: publishing on {lcm.get_lcm_url()}", file=sys.stderr)
    return lcm


def _interop_outputs(args, summary: dict, built, result, out_dir: Path) -> None:
    """--export files and the --ros2-bag, from the run's poses.npz and (teleop) the diagram's logs."""
    if args.export:
        from akc_drake.pipeline.export import export_run

        done = export_run(summary["poses_npz"], args.export, out_dir, frame=args.export_frame, smooth=args.smooth)
        summary["exports"] = [d["path"] for d in done]
        print(f"exports: {', '.join(summary['exports'])}")
    if args.ros2_bag:
        from akc_drake.io.export.poses import load_poses, world_frame_for
        from akc_drake.io.export.ros2bag import write_ros2_bag
        from akc_drake.pipeline.export import teleop_recording, write_teleop_bag

        poses = load_poses(summary["poses_npz"])
        world = world_frame_for(poses)
        if args.teleop:
            counts = write_teleop_bag(args.ros2_bag, [teleop_recording(built, result.log)], world=world)
        else:
            counts = write_ros2_bag(args.ros2_bag, poses.t, poses.stages, world=world,
                                    intrinsics=getattr(built, "intrinsics", None))
        summary["ros2_bag"] = {"path": str(args.ros2_bag), "messages": counts}
        print(f"ROS 2 bag: {args.ros2_bag} ({sum(counts.values())} messages on {len(counts)} topics)")


def _print_summary(summary: dict, wall: float) -> None:
    rng = summary["arm_length_range_cm"]
    print(
        f"{summary['frames']} frames ({summary['frames_with_person']} with a person) in {wall:.1f} s; "
        f"poses -> {summary['poses_npz']}"
    )
    lat = summary["latency_ms"]
    stages = ("source", "detector", "depth_deprojection", "extractor_overhead", "occlusion_filter", "filter",
              "corrector", "end_to_end")
    parts = [f"{k} {lat[k]['median']:.2f}" for k in stages if k in lat]
    if parts:
        print("  latency, median ms: " + ", ".join(parts))
    for stage in ("raw", "estimated", "corrected"):
        vals = ", ".join(
            f"{s} {rng[stage][s]:.2f}" if rng[stage].get(s) is not None else f"{s} -"
            for s in SEGMENT_NAMES
            if s != "SW"
        )
        print(f"  arm-length range (cm), {stage:9s}: {vals}")
    if summary.get("teleop"):
        print("  robot: " + _robot_line(summary["teleop"]))
    if "errors" in summary:
        e = summary["errors"]
        for stage in ("raw", "corrected"):
            z = [e[stage][j]["rmse_cm"]["z"] for j in ("left_shoulder", "left_elbow")]
            print(
                f"  RMSE z (cm) left shoulder / elbow, {stage:9s}: "
                + " / ".join("-" if v is None or not np.isfinite(v) else f"{v:.2f}" for v in z)
            )


def _robot_line(t: dict) -> str:
    """The teleop run's robot side in one line: end-effector tracking, the differential IK's outcomes, the commands."""
    sides = ("left", "right")
    ee = t.get("ee_tracking_error_cm") or {}
    parts = ["EE tracking error L/R " + "/".join("-" if ee.get(s) is None else f"{ee[s]:.1f}" for s in sides)
             + " cm (median)"]
    ik = t.get("ik")
    if ik:
        def share(key):
            return "/".join(f"{100 * ik[key].get(s, 0) / ik['steps'][s]:.1f}" if ik["steps"].get(s) else "-"
                            for s in sides)

        kinds = ", ".join(f"{n} {k}" for k, n in sorted(ik.get("kinds", {}).items()))
        parts.append(f"IK held the command on {share('failures')} % of L/R steps" + (f" ({kinds})" if kinds else "")
                     + f", position-only on {share('relaxed')} %")
    parts.append(f"NaN commands {t.get('nan_commands', 0)}")
    rtf = t.get("realtime_factor")
    if rtf is not None:
        parts.append(f"realtime factor {rtf:.2f}")
    return "; ".join(parts)
