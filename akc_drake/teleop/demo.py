"""The demo job: :class:`DemoOptions` and :func:`run_demo` (calibrate, render, teleoperate, report)."""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write_text
from akc_drake.robot.ik_status import quiet_drake_warnings
from akc_drake.teleop.metrics import run_metrics
from akc_drake.teleop.report import _lr, plot_errors, plot_paths
from akc_drake.teleop.scenario import (
    CALIBRATION_FRAMES,
    CORRECTORS,
    DROPOUT_BURST_S,
    FULL_CYCLES,
    MAIN_CORRECTOR,
    MOTIONS,
    QUICK_CYCLES,
    RECORDING_GAP_S,
    SETTLING_S,
    TeleopRun,
    calibrate_from_tpose,
    make_meshcat,
    run_teleop,
    truncate_motion,
)

# ------------------------------------------------------------------------------------------------------------
# The demo


@dataclass
class DemoOptions:
    """What :func:`run_demo` runs.

    Attributes:
        quick: one cycle of each motion (instead of :data:`FULL_CYCLES`).
        cycles: cycles per motion (overrides ``quick``).
        dropout: share of frames lost in bursts of 0.5-3 s, in [0, 1] (replays only).
        seed: motion variation, depth noise, detector and dropout seed.
        out_dir: output folder.
        html: where to write the Meshcat recording (default ``out_dir/teleop.html``).
        record: record the AKC(KF) runs in Meshcat and write the HTML page.
        meshcat: an existing Meshcat to use (else one is created when ``record``).
        plots, graph: write the figures and the diagram's graph.
        render_run: also run AKC(KF) with the camera rendered in the diagram (the realtime factor).
        max_frames: cut every motion to this many frames (quick checks and tests).
        correctors: which of :data:`CORRECTORS` to compare.
        config: the base :class:`~akc_drake.config.PipelineConfig` (camera, weights, ...).
        progress: progress bars on stderr.
        ros2_bag: write the AKC(KF) replays (skeletons, wrist targets, joint commands) to this ROS 2 MCAP bag
            (:func:`akc_drake.pipeline.export.write_teleop_bag`).
        body, detector: the rendered operator and the 2D detector; by default the real pipeline, MediaPipe on
            the skinned body (``"primitive"``, ``"sim"``: the fast simulated path).
        task, seeds, operator: ``"pick-place"`` runs the task ``seeds`` times per corrector
            (:func:`~akc_drake.teleop.task.run_pick_place`); ``operator`` "closed" (the operator watches the robot
            and corrects it, rendered in the loop) or "open" (rendered once per seed, replayed).
    """

    quick: bool = False
    cycles: int | None = None
    dropout: float = 0.0
    seed: int = 0
    out_dir: str | Path = "out/demo"
    html: str | Path | None = None
    record: bool = True
    meshcat: object = None
    plots: bool = True
    graph: bool = True
    render_run: bool = True
    max_frames: int | None = None
    correctors: tuple[str, ...] = tuple(CORRECTORS)
    config: object = None
    progress: bool = False
    ros2_bag: str | Path | None = None
    task: str | None = None
    seeds: int = 5
    operator: str = "closed"
    body: str = "skinned"
    detector: str = "mediapipe"
    #: MediaPipe Hands' model file (None: the packaged one), for the hand channel with ``detector`` mediapipe.
    hand_model: str | None = None

    def validate(self) -> DemoOptions:
        """Check the options; raises UserError naming the option."""
        d = self.dropout
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d) or not 0.0 <= d <= 1.0:
            raise UserError(f"--dropout must be a share of frames in [0, 1], got {d!r}")
        if self.cycles is not None and (
            isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or self.cycles < 1
        ):
            raise UserError(f"cycles must be a positive integer, got {self.cycles!r}")
        if self.max_frames is not None and (
            isinstance(self.max_frames, bool) or not isinstance(self.max_frames, int) or self.max_frames < 10
        ):
            raise UserError(f"max_frames must be an integer >= 10, got {self.max_frames!r}")
        unknown = [c for c in self.correctors if c not in CORRECTORS]
        if unknown or not self.correctors:
            raise UserError(f"correctors must be among {', '.join(CORRECTORS)}, got {list(self.correctors)!r}")
        if not str(self.out_dir).strip():
            raise UserError("--out: empty folder name")
        if self.task not in (None, "pick-place"):
            raise UserError(f"--task must be pick-place, got {self.task!r}")
        if isinstance(self.seeds, bool) or not isinstance(self.seeds, int) or self.seeds < 1:
            raise UserError(f"--seeds must be a positive integer, got {self.seeds!r}")
        if self.operator not in ("closed", "open"):
            raise UserError(f"--operator must be closed or open, got {self.operator!r}")
        if self.hand_model is not None:  # a wrong path fails now, not after the demo's runs
            from akc_drake.io.hand_detector import find_hand_model

            find_hand_model(self.hand_model)
        return self

    @property
    def num_cycles(self) -> int:
        if self.cycles is not None:
            return int(self.cycles)
        return QUICK_CYCLES if self.quick else FULL_CYCLES


def _prepare_out_dir(out: Path) -> Path:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"--out {out}: cannot create the folder: {e.strerror or e}") from None
    if not os.access(out, os.W_OK):
        raise UserError(f"--out {out}: the folder is not writable")
    return out


def run_demo(opts: DemoOptions, *, log: Callable[[str], None] = print) -> dict:
    """Run the demo (see the module docstring) and write its outputs; returns the summary (``demo.json``).

    Args:
        opts: the options.
        log: where progress lines go (``print`` by default).

    Returns:
        The summary dict, also written to ``opts.out_dir/demo.json``; ``summary["outputs"]`` lists the files.
    """
    import dataclasses

    from akc_drake.config import PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import Measurements, camera_period
    from akc_drake.faults import inject_dropouts
    from akc_drake.fileio import write_json
    from akc_drake.operator.motions import make_motion

    opts.validate()
    t_start = time.perf_counter()
    out = _prepare_out_dir(Path(opts.out_dir))
    cfg = (opts.config if opts.config is not None else PipelineConfig()).validate()
    cfg = dataclasses.replace(cfg, seed=int(opts.seed), body=opts.body, detector=opts.detector).validate()
    rate = float(cfg.camera.rate_hz)
    period = camera_period(cfg)
    cycles = opts.num_cycles

    meshcat, meshcat_error = opts.meshcat, None
    if meshcat is None and opts.record:
        meshcat, meshcat_error = make_meshcat()
        if meshcat is None:
            log(f"warning: Meshcat could not start ({meshcat_error}); no HTML recording will be written")

    # 1. Calibration from a rendered T-pose.
    log(
        f"Calibrating from a rendered T-pose ({min(CALIBRATION_FRAMES, opts.max_frames or 10**9)} "
        "frames, occlusion filter + KF) ..."
    )
    calib = calibrate_from_tpose(cfg, seed=opts.seed, progress=opts.progress, max_frames=opts.max_frames)
    true_dims = BodyDimensions.paper_participant()
    calib_err = {k: 100.0 * (getattr(calib.dims, k) - getattr(true_dims, k)) for k in true_dims.as_dict()}
    log(
        "  calibrated (cm): "
        + ", ".join(f"{k} {100 * v:.1f} ({calib_err[k]:+.1f})" for k, v in calib.dims.as_dict().items())
    )
    for w in calib.report.warnings:
        log(f"  warning: {w}")

    runs: dict[str, list[TeleopRun]] = {}
    rendered: list[TeleopRun] = []
    render_info: dict[str, dict] = {}
    dropout_info: dict[str, dict] = {}
    graph_diagram = None
    rec_time = 0.0
    bag_runs = []  # --ros2-bag: the main corrector's replays
    if meshcat is not None:
        # Draw live only when the user watches (--meshcat); the recording is what the HTML page shows.
        meshcat.StartRecording(set_visualizations_while_recording=opts.meshcat is not None)
    # With MediaPipe, MediaPipe Hands runs on each rendered frame: its knuckle vectors set the wrist frames.
    hands = None
    if getattr(cfg, "detector", "sim") == "mediapipe":
        from akc_drake.io.hand_detector import HandDetector

        hands = HandDetector(opts.hand_model)
    from akc_drake.teleop.task import render_with_hands

    with quiet_drake_warnings(), hands if hands is not None else contextlib.nullcontext():
        for m_index, name in enumerate(MOTIONS):
            motion = make_motion(name, cycles, opts.seed)
            if opts.max_frames is not None:
                motion = truncate_motion(motion, opts.max_frames, rate)
            log(
                f"Motion {name}: rendering {len(motion.frame_times(rate))} frames "
                f"({cycles} cycle{'s' if cycles > 1 else ''}) ..."
            )
            session, recorder = render_with_hands(motion, cfg, opts.seed, opts.progress, hands)
            knuckles = None if recorder is None else recorder.knuckles
            render_info[name] = {
                "frames": len(session),
                "render_ms_per_frame": 1e3 * float(np.mean(session.render_s)),
                "extract_ms_per_frame": 1e3 * float(np.mean(session.extract_s)),
            }
            meas = Measurements.from_session(session)
            mask = np.zeros(meas.num_frames, dtype=bool)
            bursts = []
            if opts.dropout > 0:
                # The whole person is lost (NaN landmarks and pixels, visibility 0), in seeded bursts.
                meas, plan = inject_dropouts(
                    meas,
                    opts.dropout,
                    seed=[int(opts.seed), m_index, 0xD20],
                    burst_s=DROPOUT_BURST_S,
                    rate_hz=rate,
                    kinds=("person",),
                )
                mask = plan.frames
                bursts = [[round(b.start * period, 6), round(b.num_frames * period, 6)] for b in plan.bursts]
            dropout_info[name] = {"frames": int(mask.sum()), "bursts_start_duration_s": bursts}
            if knuckles is not None:
                knuckles[mask[: len(knuckles)]] = np.nan  # the person (hands too) lost in those frames
            runs[name] = []
            for corrector in opts.correctors:
                record = meshcat is not None and corrector == MAIN_CORRECTOR
                run, td = run_teleop(
                    cfg,
                    calib.dims,
                    torso_model=calib.torso,
                    corrector=corrector,
                    replay=meas,
                    motion=motion,
                    hand_knuckles=knuckles,
                    meshcat=meshcat if record else None,
                    start_time=rec_time if record else 0.0,
                    dropout=mask,
                    progress=opts.progress,
                )
                if record:
                    rec_time = math.ceil(rec_time + run.sim_s + RECORDING_GAP_S)
                if opts.ros2_bag is not None and corrector == MAIN_CORRECTOR:
                    from akc_drake.pipeline.export import teleop_recording

                    bag_runs.append(teleop_recording(td, num_frames=run.frames))
                runs[name].append(run)
                m = run_metrics([run])
                log(
                    f"  {corrector:9s} replay: {run.frames} frames in {run.wall_s:5.1f} s "
                    f"(x{run.realtime_factor:.2f} realtime), EE error L/R "
                    f"{_lr(m['ee_tracking_error_cm'])} cm, "
                    f"NaN commands {run.nan_commands}"
                )
            if opts.render_run:
                run, td = run_teleop(
                    cfg,
                    calib.dims,
                    torso_model=calib.torso,
                    corrector=MAIN_CORRECTOR,
                    motion=motion,
                    num_frames=meas.num_frames,
                    truth_C=session.truth,
                    progress=opts.progress,
                )
                rendered.append(run)
                graph_diagram = td.diagram
                log(
                    f"  {MAIN_CORRECTOR} with rendering: {run.frames} frames in {run.wall_s:5.1f} s "
                    f"(x{run.realtime_factor:.2f} realtime)"
                )
    task = None
    if opts.task == "pick-place":
        from akc_drake.teleop.task import run_pick_place

        log(f"Pick and place: {opts.seeds} seeded run(s) per corrector ...")
        task = run_pick_place(
            cfg,
            calib,
            opts.seeds,
            correctors=opts.correctors,
            progress=opts.progress,
            log=log,
            meshcat=meshcat,
            start_time=rec_time,
            hand_model=opts.hand_model,
            operator=opts.operator,
        )
    outputs: dict[str, object] = {}
    task_html = task.pop("recording_html", None) if task is not None else None
    if task_html is not None:  # the closed-loop task run, recorded on its own page
        try:
            atomic_write_text(out / "pick_place.html", task_html)
        except OSError as e:
            raise UserError(f"{out / 'pick_place.html'}: cannot write: {e.strerror or e}") from None
        outputs["pick_place_html"] = str(out / "pick_place.html")
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        html = Path(opts.html) if opts.html else out / "teleop.html"
        try:
            atomic_write_text(html, meshcat.StaticHtml())
            outputs["html"] = str(html)
        except OSError as e:
            raise UserError(f"--html {html}: cannot write: {e.strerror or e}") from None
    if opts.graph:
        from akc_drake.graphs import write_graph

        if graph_diagram is None:
            from akc_drake.diagrams import build_teleop_diagram

            graph_diagram = build_teleop_diagram(dataclasses.replace(cfg, filter="KF", corrector="AKC")).diagram
        paths = write_graph(graph_diagram, out, "teleop")
        outputs["graph_dot"] = str(paths["dot"])
        outputs["graph_svg"] = str(paths["svg"]) if paths["svg"] is not None else None
        if paths["svg"] is None:
            log("note: graphviz's 'dot' is not installed, so the diagram was written as .dot only")
    if bag_runs:
        from akc_drake.pipeline.export import write_teleop_bag

        counts = write_teleop_bag(opts.ros2_bag, bag_runs)
        outputs["ros2_bag"] = str(opts.ros2_bag)
        log(f"ROS 2 bag: {opts.ros2_bag} ({sum(counts.values())} messages on {len(counts)} topics)")
    if opts.plots:
        figs = []
        for name, rs in runs.items():
            figs.append(str(plot_paths(rs, out / f"paths_motion_{name}.png")))
        figs.append(str(plot_errors(runs, out / "tracking_error.png")))
        outputs["plots"] = figs

    summary = _summary(opts, cfg, cycles, calib, true_dims, calib_err, runs, rendered, render_info, dropout_info)
    if task is not None:
        summary["task"] = task
        for c, rate in task["success_rate"].items():
            summary["correctors"].setdefault(c, {})["success_rate"] = rate
    summary["outputs"] = outputs
    summary["wall_s"] = time.perf_counter() - t_start
    json_path = out / "demo.json"
    outputs["json"] = str(json_path)
    write_json(json_path, summary)
    return summary


def _summary(opts, cfg, cycles, calib, true_dims, calib_err, runs, rendered, render_info, dropout_info) -> dict:
    all_runs = [r for rs in runs.values() for r in rs] + list(rendered)
    by_corrector = {c: [r for rs in runs.values() for r in rs if r.corrector == c] for c in opts.correctors}
    correctors = {c: run_metrics(rs) for c, rs in by_corrector.items() if rs}
    main = correctors.get(MAIN_CORRECTOR) or next(iter(correctors.values()))
    render_metrics = run_metrics(rendered) if rendered else None
    per_run = []
    for r in all_runs:
        m = run_metrics([r])
        m.update({"motion": r.motion, "corrector": r.corrector, "rendered": r.rendered})
        per_run.append(m)
    return {
        "config": {
            "quick": bool(opts.quick),
            "body": cfg.body,
            "detector": cfg.detector,
            "task": opts.task,
            "cycles": cycles,
            "motions": list(runs),
            "seed": int(opts.seed),
            "dropout": float(opts.dropout),
            "rate_hz": float(cfg.camera.rate_hz),
            "width": int(cfg.camera.width),
            "height": int(cfg.camera.height),
            "weights": cfg.weights,
            "correctors": {c: {"filter": CORRECTORS[c][0], "corrector": CORRECTORS[c][1]} for c in opts.correctors},
            "settling_s": SETTLING_S,
            "max_frames": opts.max_frames,
        },
        "definitions": {
            "frames": "camera frames teleoperated per corrector (all motions)",
            "ee_tracking_error_cm": (
                f"{MAIN_CORRECTOR}, both motions: median distance between the mapped target X_TE_desired "
                "and the achieved end-effector position, sampled once per camera frame, after the first "
                f"{SETTLING_S:g} s "
                "(the jump from the home pose); ee_tracking_error_cm_with_settling includes it"
            ),
            "ee_operator_error_cm": "median distance from the achieved end effector to the operator's true "
            "wrist "
            "mapped to the robot (ground truth through the same mapping), after settling",
            "jitter": "RMS angular (rad/s) and linear (m/s) speed of X_TE_desired between camera frames, "
            "after settling",
            "nan_commands": "IK-period samples with a non-finite joint command, all runs of the demo",
            "ik_failures": "differential-IK steps (100 Hz per arm) where neither the full-pose IK nor its "
            "position-only fallback found a solution ('no solution' or 'stuck') and no joint-space move drove the "
            "arm (the command is held), all runs of the demo; ik_orientation_relaxed and ik_joint_space_steps "
            "count the steps the fallback and the joint-space move drove",
            "limit_hits": "IK-period samples with a joint command within 1e-3 rad of a position limit "
            "(position_limit_hits), a step at >= 97% of a velocity limit (velocity_limit_hits) or a change of step "
            "over 1.05 times an acceleration limit (acceleration_limit_hits; max_joint_speed_ratio and "
            "max_joint_acceleration_ratio: the largest fractions of a limit, all runs)",
            "realtime_factor": f"{MAIN_CORRECTOR} with the camera rendered in the diagram (S1-S5, robot): "
            "simulated / wall-clock seconds; realtime_factor_replay is per corrector on "
            "replayed measurements (the recorded run draws to Meshcat too)",
            "dropout": "frames blanked in bursts in the replays (not in the rendered run)",
            "smoothing_latency_ms": "per corrector and side: the delay of the smoothed targets behind the same "
            "tracker's unsmoothed ones (same torso, same workspace clip), the shift minimising the median squared "
            "distance of the positions (smoothing_rotation_latency_ms: of the rotation matrices' entries)",
            "target_operator_error_cm": "per corrector and side: median (and _p95_cm) distance between the target "
            "X_TE_desired and the operator's true wrist through the same mapping and workspace, after settling",
            "target_operator_offset_cm": "per corrector and side: length of the component-wise median target-minus-"
            "operator vector "
            "(the error's constant part: a calibration or depth offset); target_operator_error_unsmoothed_cm: the "
            "median error of the unsmoothed targets (same torso and clip); target_operator_error_unclipped_cm (and "
            "_p95_cm): over the frames whose target was not clipped to the workspace",
        },
        "calibration": {
            "pose": "tpose",
            "frames": calib.frames,
            "dims_m": calib.dims.as_dict(),
            "true_dims_m": true_dims.as_dict(),
            "error_cm": calib_err,
            "report": calib.report.as_dict(),
        },
        "frames": main["frames"],
        "nan_commands": int(sum(r.nan_commands for r in all_runs)),
        "ik_failures": int(sum(sum(r.ik_failures.values()) for r in all_runs)),
        "ee_tracking_error_cm": main["ee_tracking_error_cm"],
        "ee_tracking_error_cm_with_settling": main["ee_tracking_error_cm_with_settling"],
        "ee_operator_error_cm": main["ee_operator_error_cm"],
        "jitter": main["jitter"],
        "realtime_factor": render_metrics["realtime_factor"] if render_metrics else None,
        "realtime_factor_replay": {c: m["realtime_factor"] for c, m in correctors.items()},
        "rendering": render_info,
        "rendered_run": render_metrics,
        "dropout": dropout_info,
        "correctors": correctors,
        "runs": per_run,
    }
