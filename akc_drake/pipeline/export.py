"""Exports of the pipeline's skeletons: BVH, TRC, C3D, CSV, and every stage in one ROS 2 MCAP bag.

:func:`export_poses` is what ``akc-drake export`` and ``run/evaluate --export`` call. Coordinates:

* ``frame="world"`` (default): the gravity-aligned world frame W of :mod:`akc_drake.core.world_frame` (z up, floor
  at 0, origin on the floor below the camera); CSV and C3D are written in W (Z up), TRC and BVH in W's Y-up
  version (TRC: X forward of the operator, Y up, Z right, OpenSim's convention; BVH: Y up, the character facing
  +Z).
* ``frame="camera"``: the camera frame C unchanged (x right, y down, z forward) in every format.

Units: CSV metres, TRC and C3D millimetres, BVH centimetres.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import LANDMARKS, BodyDimensions
from akc_drake.core.world_frame import BVH_FROM_W, Y_UP_FROM_W, WorldFrame
from akc_drake.errors import UserError
from akc_drake.io.export.poses import STAGES, PoseSet, load_poses, world_frame_for

#: Skeleton formats and their file suffixes.
FORMATS: dict[str, str] = {"bvh": ".bvh", "trc": ".trc", "c3d": ".c3d", "csv": ".csv"}
SMOOTHERS: tuple[str, ...] = ("none", "rts")


def check_format(fmt: str, option: str = "--format") -> str:
    """``fmt`` lower-cased, or a :class:`UserError` naming ``option`` and listing the formats."""
    f = str(fmt).strip().lower()
    if f not in FORMATS:
        raise UserError(f"{option}: unknown format {fmt!r}; choose from {', '.join(FORMATS)}")
    return f


def check_writable(path) -> Path:
    """A :class:`UserError` naming ``path`` when its folder cannot be created or written (before any work)."""
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{p}: is a folder, not a file")
    existing = p.parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir() or not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{p}: cannot write into {existing}")
    return p


def stage_points(poses: PoseSet, stage: str, smooth: str = "none", dims: BodyDimensions | None = None) -> np.ndarray:
    """The ``(T, 12, 3)`` camera-frame landmarks of ``stage``, with the RTS smoother in place of the KF if asked.

    With ``smooth="rts"``: ``filtered`` and ``corrected`` are recomputed from ``accepted`` (the KF's input) by
    :func:`akc_drake.core.smoother.smoothed_stages` (``corrected`` needs the calibrated ``dims``); ``raw``,
    ``accepted`` and ``truth`` are smoothed directly.
    """
    if stage not in STAGES:
        raise UserError(f"--stage: unknown stage {stage!r}; choose from {', '.join(STAGES)}")
    if smooth not in SMOOTHERS:
        raise UserError(f"--smooth: unknown smoother {smooth!r}; choose from {', '.join(SMOOTHERS)}")
    if smooth == "none":
        return poses.stage(stage)
    from akc_drake.core.smoother import rts_smooth, smoothed_stages

    dt = 1.0 / poses.rate_hz
    if stage in ("filtered", "corrected") and "accepted" in poses.stages:
        d = dims or poses.dims
        if stage == "corrected" and d is None:
            raise UserError(f"{poses.source}: --smooth rts on 'corrected' needs the arm lengths (--dims FILE.json)")
        return smoothed_stages(poses.stages["accepted"], dt, d if stage == "corrected" else None)[stage]
    return rts_smooth(poses.stage(stage), dt)


def _dims_for_bvh(poses: PoseSet, points_C: np.ndarray, dims: BodyDimensions | None) -> BodyDimensions:
    if dims is not None:
        return dims
    if poses.dims is not None:
        return poses.dims
    from akc_drake.core.skeleton import SEGMENT_NAMES, segment_lengths

    seg = segment_lengths(points_C)
    vals = {k: float(np.nanmedian(seg[k])) if np.isfinite(seg[k]).any() else np.nan for k in SEGMENT_NAMES}
    try:
        return BodyDimensions(**vals)
    except ValueError as e:
        raise UserError(f"{poses.source}: no arm lengths for the BVH hierarchy ({e}); give --dims FILE.json") from None


def write_points(fmt: str, out, t: np.ndarray, points_C: np.ndarray, world: WorldFrame, *,
                 rate_hz: float, dims: BodyDimensions | None = None) -> Path:
    """Write camera-frame landmarks ``(T, 12, 3)`` in ``world`` (identity for the camera frame) as ``fmt``."""
    fmt = check_format(fmt)
    camera = world.source == "identity"
    P_W = world.to_world(points_C)
    names = list(LANDMARKS)
    if fmt == "csv":
        from akc_drake.io.export.table import write_csv

        return write_csv(out, t, P_W, names)
    if fmt == "trc":
        from akc_drake.io.export.table import write_trc

        P = P_W if camera else P_W @ Y_UP_FROM_W.T
        return write_trc(out, t, P * 1000.0, names, rate_hz=rate_hz)
    if fmt == "c3d":
        from akc_drake.io.export.c3d import write_c3d

        return write_c3d(out, P_W * 1000.0, names, rate_hz=rate_hz, z_up=not camera)
    from akc_drake.operator.bvh_export import write_bvh_export

    if dims is None:
        raise ValueError("BVH export needs the body dimensions")
    P = P_W if camera else P_W @ BVH_FROM_W.T
    try:
        return write_bvh_export(out, P, dims, frame_time=1.0 / rate_hz)
    except ValueError as e:
        raise UserError(f"{out}: {e}") from None


def export_poses(poses: PoseSet, fmt: str, out, *, stage: str = "corrected", frame: str = "world",
                 calibration: PoseSet | None = None, smooth: str = "none",
                 dims: BodyDimensions | None = None) -> dict:
    """Export one stage of ``poses`` to ``out`` as ``fmt``; returns a summary for the JSON/stdout.

    Args:
        poses: the session (:func:`load_poses`).
        fmt: ``bvh``, ``trc``, ``c3d`` or ``csv``.
        out: the file to write (atomically).
        stage: which skeleton (``raw``, ``accepted``, ``filtered``, ``corrected``, ``truth``).
        frame: ``world`` or ``camera``.
        calibration: a T-pose session to estimate the world frame from (default: ``poses`` itself).
        smooth: ``none`` or ``rts``.
        dims: the calibrated body dimensions (default: those stored in ``poses``).
    """
    fmt = check_format(fmt)
    check_writable(out)
    world = world_frame_for(poses, calibration, frame=frame)
    P = stage_points(poses, stage, smooth, dims)
    bvh_dims = _dims_for_bvh(poses, P, dims) if fmt == "bvh" else None
    path = write_points(fmt, out, poses.t, P, world, rate_hz=poses.rate_hz, dims=bvh_dims)
    summary = {
        "path": str(path),
        "format": fmt,
        "stage": stage,
        "frame": frame,
        "smooth": smooth,
        "frames": poses.num_frames,
        "rate_hz": poses.rate_hz,
        "world_frame": world.as_dict(),
    }
    if bvh_dims is not None:
        summary["bvh_dims"] = bvh_dims.as_dict()
    return summary


def export_bag(poses: PoseSet, out, *, frame: str = "world", calibration: PoseSet | None = None) -> dict:
    """Every stage of ``poses`` (and the operator's control frames) in one ROS 2 MCAP bag at ``out``."""
    from akc_drake.io.export.ros2bag import write_ros2_bag

    check_writable(out)
    world = world_frame_for(poses, calibration, frame="world")
    counts = write_ros2_bag(out, poses.t, poses.stages, world=world, frame=frame)
    return {"path": str(out), "format": "mcap", "frame": frame, "frames": poses.num_frames,
            "messages": counts, "world_frame": world.as_dict()}


def rts_report(poses: PoseSet, dims: BodyDimensions | None = None) -> dict | None:
    """With ground truth: RMSE of the forward KF vs the RTS smoother (``filtered`` and, with dims, ``corrected``)
    on the arm joints (:func:`akc_drake.core.smoother.rts_gain`); None without truth or ``accepted``."""
    if "truth" not in poses.stages or "accepted" not in poses.stages:
        return None
    from akc_drake.core.smoother import rts_gain, smoothed_stages

    smoothed = smoothed_stages(poses.stages["accepted"], 1.0 / poses.rate_hz, dims or poses.dims)
    return rts_gain(poses.stages["truth"], poses.stages, smoothed)




# ----------------------------------------------------------------------------------------------------------------
# Hooks for run / evaluate / demo


def export_run(npz_path, formats, out_dir, *, frame: str = "world", smooth: str = "none",
               stages=("raw", "filtered", "corrected"), dims: BodyDimensions | None = None) -> list[dict]:
    """``run/evaluate --export FMT[,FMT]``: each of ``stages`` of a ``poses.npz`` as ``out_dir/<stage>.<ext>``."""
    items = str(formats).split(",") if isinstance(formats, str) else list(formats)
    fmts = [check_format(f, "--export") for f in items if str(f).strip()]
    if not fmts:
        raise UserError("--export: give at least one format (bvh, trc, c3d, csv)")
    poses = load_poses(npz_path)
    out = []
    for fmt in fmts:
        for stage in stages:
            if stage in poses.stages:
                out.append(export_poses(poses, fmt, Path(out_dir) / f"{stage}{FORMATS[fmt]}", stage=stage,
                                        frame=frame, smooth=smooth, dims=dims))
    return out


@dataclass
class TeleopRecording:
    """One teleop run's arrays for a ROS 2 bag (:func:`teleop_recording`).

    Attributes:
        t: ``(T,)`` camera frame times (s); skeletons: stage -> ``(T, 12, 3)`` in C;
        commands: the arm joint commands at the IK rate; targets: ``{frame: (t, (N, 4, 4))}`` the wrist targets
        and the achieved end effectors (``{left,right}_ee``) in the robot's torso frame; states: the measured arm
        joint positions and velocities at the IK rate (None when the monitor did not record them).
    """

    t: np.ndarray
    skeletons: dict
    commands: object
    targets: dict
    states: object = None


def teleop_recording(td, log=None, num_frames: int | None = None) -> TeleopRecording:
    """The arrays a built and simulated TeleopDiagram logged: skeletons (stage loggers), arm commands and wrist
    targets (its TeleopMonitor's history, ``keep_history=True``).

    Args:
        td: a :class:`~akc_drake.diagrams.TeleopDiagram` after its simulation.
        log: its :class:`~akc_drake.diagrams.MocapLog` (default: read from the loggers with the last context).
        num_frames: frames to read when ``log`` is None.
    """
    from akc_drake.diagrams import camera_period, read_logs
    from akc_drake.io.export.ros2bag import JointSeries
    from akc_drake.robot.model import arm_joint_names

    if log is None:
        log = read_logs(td.loggers, td._last_context, camera_period(td.config), num_frames)
    skeletons = {"raw": log.raw, "filtered": log.estimated, "corrected": log.corrected}
    hist = td.monitor.history_arrays()
    t = np.asarray(hist.get("t", []), dtype=float)
    if len(t) == 0:
        raise ValueError("the teleop monitor kept no history (keep_history=False)")
    names = arm_joint_names("left") + arm_joint_names("right")
    q = np.concatenate([np.asarray(hist["q_left"]), np.asarray(hist["q_right"])], axis=1)
    # The run may start at any simulation time (the demo puts its Meshcat-recorded runs one after the other): the
    # recording starts at 0 at its first frame.
    t_frames = np.asarray(log.t, dtype=float)
    t0 = min(float(t_frames[0]) if len(t_frames) else 0.0, float(t[0]))
    t_frames, t = t_frames - t0, t - t0
    targets = {f"{s}_wrist_target": (t, np.asarray(hist[f"target_{s}"])) for s in ("left", "right")}
    # The robot's achieved end effectors (its state, as frames): where the targets were reached.
    targets.update({f"{s}_ee": (t, np.asarray(hist[f"ee_{s}"])) for s in ("left", "right")})
    states = None  # the measured arm joints (the plant's state at each IK step)
    if len(hist.get("q_measured_left", [])) == len(t):
        states = JointSeries(
            t, names,
            np.concatenate([np.asarray(hist["q_measured_left"]), np.asarray(hist["q_measured_right"])], axis=1),
            np.concatenate([np.asarray(hist["v_measured_left"]), np.asarray(hist["v_measured_right"])], axis=1))
    return TeleopRecording(t_frames, skeletons, JointSeries(t, names, q), targets, states)


def write_teleop_bag(path, recordings, *, world: WorldFrame | None = None, gap_s: float = 1.0,
                     start_ns: int | None = None) -> dict[str, int]:
    """``run/demo --ros2-bag``: teleop runs one after the other (``gap_s`` apart) in one MCAP bag.

    Args:
        path: the ``.mcap`` file.
        recordings: :class:`TeleopRecording`\\ s (e.g. one per motion).
        world: the world frame (default: estimated from the first recording's filtered skeleton).
    """
    from akc_drake.core.world_frame import estimate_world_frame
    from akc_drake.io.export.ros2bag import JointSeries, write_ros2_bag

    recs = list(recordings)
    if not recs:
        raise ValueError("write_teleop_bag: no recording")
    if world is None:
        try:
            world = estimate_world_frame(recs[0].skeletons["filtered"])
        except ValueError:
            world = WorldFrame.camera()
    offset, ts, sk, qt, qv, tg, st = 0.0, [], {}, [], [], {}, []
    for r in recs:
        ts.append(r.t + offset)
        for k, v in r.skeletons.items():
            sk.setdefault(k, []).append(v)
        qt.append(r.commands.t + offset)
        qv.append(r.commands.position)
        if r.states is not None:
            st.append((r.states.t + offset, r.states.position, r.states.velocity))
        for k, (tt, X) in r.targets.items():
            tg.setdefault(k, ([], []))
            tg[k][0].append(tt + offset)
            tg[k][1].append(X)
        offset = max(float(ts[-1][-1]), float(qt[-1][-1])) + gap_s
    cmds = JointSeries(np.concatenate(qt), recs[0].commands.names, np.concatenate(qv))
    states = None
    if len(st) == len(recs):  # the measured joint state of every run (else none: a bag is not half-logged)
        states = JointSeries(np.concatenate([a for a, _, _ in st]), recs[0].states.names,
                             np.concatenate([b for _, b, _ in st]), np.concatenate([c for _, _, c in st]))
    robot_frames = {k: (np.concatenate(a), np.concatenate(b)) for k, (a, b) in tg.items()}
    return write_ros2_bag(path, np.concatenate(ts), {k: np.concatenate(v) for k, v in sk.items()}, world=world,
                          joint_commands=cmds, joint_states=states, robot_frames=robot_frames, start_ns=start_ns)


def _file_stem(method: str) -> str:
    """``AKC(KF)`` -> ``AKC_KF``: a method name as a file name."""
    return method.replace("(", "_").replace(")", "").replace("+", "plus").replace(",", "_")


def export_evaluation(ev, formats, out_dir, *, frame: str = "world") -> dict:
    """``evaluate --export FMT[,FMT]``: each method's skeleton per motion as ``out_dir/<motion>/<method>.<ext>``
    (plus ``Raw`` and ``truth``), and the RTS smoother's accuracy gain over the forward KF.

    Args:
        ev: the :class:`~akc_drake.evaluation.experiment.Evaluation`.
        formats: comma-separated formats (bvh, trc, c3d, csv).
        out_dir: the export folder.
        frame: ``world`` (estimated per motion from the occlusion filter's output) or ``camera``.

    Returns:
        ``{"files": [...], "rts_gain": {motion: rts_gain(...)}}``: the gain on the evaluated frames (the first
        cycle excluded as in the tables) of RTS(KF) over KF and of AKC on RTS(KF) over AKC(KF).
    """
    from akc_drake.core.akc import WEIGHT_PRESETS
    from akc_drake.core.kalman import KFConfig
    from akc_drake.core.occlusion import occlusion_filter
    from akc_drake.core.smoother import rts_gain, smoothed_stages

    fmts = [check_format(f, "--export") for f in str(formats).split(",") if f.strip()]
    if not fmts:
        raise UserError("--export: give at least one format (bvh, trc, c3d, csv)")
    cfg = ev.config
    opts = cfg.options
    files, gains = [], {}
    for motion, run in ev.runs.items():
        s = run.session
        held = np.full(s.raw.shape[1:], np.nan)  # (the occlusion filter's state, as in the evaluation)
        accepted = np.stack([
            np.asarray(occlusion_filter(s.raw[k], s.pixels[k], s.visibility[k], s.intrinsics.width,
                                        visibility_threshold=opts.visibility_threshold,
                                        proximity=opts.proximity, held=held,
                                        **(opts.occlusion_rules or {}))[0]) for k in range(s.num_frames)])
        base = PoseSet(t=np.asarray(s.t, dtype=float), stages={"accepted": accepted}, dims=ev.dims, source=motion)
        world = world_frame_for(base, frame=frame)
        outputs = {"truth": s.truth, **{m: r.estimates for m, r in run.methods.items()}}
        outputs.setdefault("Raw", s.raw)
        for fmt in fmts:
            for name, P in outputs.items():
                path = Path(out_dir) / str(motion) / f"{_file_stem(name)}{FORMATS[fmt]}"
                check_writable(path)
                files.append(str(write_points(fmt, path, base.t, P, world, rate_hz=base.rate_hz,
                                              dims=ev.dims if fmt == "bvh" else None)))
        if "KF" in run.methods:
            mask = s.evaluation_mask(cfg.exclude_first_cycle)
            truth = np.where(mask[:, None, None], s.truth, np.nan)
            forward = {"filtered": run.methods["KF"].estimates}
            if "AKC(KF)" in run.methods:
                forward["corrected"] = run.methods["AKC(KF)"].estimates
            smoothed = smoothed_stages(accepted, 1.0 / base.rate_hz, ev.dims, opts.kf_config or KFConfig(),
                                       WEIGHT_PRESETS[cfg.weights])
            gains[str(motion)] = rts_gain(truth, forward, smoothed)
    return {"files": files, "rts_gain": gains}


def imu_up_for_source(spec: str):
    """The up direction in the camera frame from the accelerometer of a ``bag:FILE`` source (a D435i recording),
    or None (another source, no accelerometer stream, or samples not at rest). Stored in ``poses.npz`` as
    ``up_C``, where the world frame of the exports takes it instead of the trunk direction."""
    from akc_drake.core.world_frame import up_from_accel

    kind, _, path = str(spec).strip().partition(":")
    if kind.lower() != "bag" or not path:
        return None
    from akc_drake.io.realsense import read_bag_accel

    got = read_bag_accel(path)
    if got is None or len(got[0]) == 0:
        return None
    try:
        return up_from_accel(*got)
    except ValueError:
        return None


__all__ = ["FORMATS", "PoseSet", "TeleopRecording", "check_format", "export_bag", "export_evaluation", "export_poses",
           "export_run", "imu_up_for_source",
           "load_poses", "rts_report", "stage_points", "teleop_recording", "write_points", "write_teleop_bag"]
