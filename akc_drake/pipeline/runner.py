"""Running a built mocap or teleop diagram frame by frame, stage by stage, with per-stage latency.

:func:`run_pipeline` advances the simulator through each camera period in slices, one slice per stage: the
stages are sampled at ``t_k + i * stage_offset`` (:mod:`akc_drake.systems.timing`), so the slice
``(t_k + (i - 1/2) offset, t_k + (i + 1/2) offset]`` holds stage ``i``'s update and nothing else of the
pipeline. The wall time of a slice is the stage's latency as the diagram runs it (Drake's event dispatch
included). Within stage S2 (``extractor``) the detector is timed by :class:`TimedDetector`, the depth lookup
and deprojection (``depth_deprojection``) by calling their core functions again on the frame's depth image and
detected pixels; the remainder (``extractor_overhead``) is building the frame from the Drake images and the
event itself. The occlusion filter, which is direct feedthrough evaluated inside the Kalman filter's update,
is timed by calling its core function on the same inputs, and subtracted from the filter's slice.
``end_to_end`` is the sum of the slices from the source read to the corrected pose; ``frame_wall`` is the
whole camera period's wall time. With a teleop diagram the robot plant's steps fall on the source, filter and
mapper instants and are included in those figures.

Every time is read from an injectable ``clock`` (default :func:`time.perf_counter`), so tests can check the
arithmetic with a deterministic clock instead of the machine's load.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from akc_drake.errors import UserError

#: Stage names of ``latency_ms``, in pipeline order.
LATENCY_STAGES = (
    "source",
    "extractor",
    "detector",
    "depth_deprojection",
    "extractor_overhead",
    "occlusion_filter",
    "filter",
    "corrector",
    "mapper",
    "end_to_end",
    "frame_wall",
)

Clock = Callable[[], float]


class TimedDetector:
    """A :class:`~akc_drake.core.camera.Detector` that times each ``detect`` call of another detector.

    Args:
        inner: the detector to time (its ``name``, ``needs_color`` and ``needs_label`` are passed through).
        clock: seconds, monotonic (default :func:`time.perf_counter`).

    Attributes:
        times_s: wall time of each call, seconds.
        found: whether each call found a person.
    """

    def __init__(self, inner, clock: Clock = time.perf_counter):
        if not callable(getattr(inner, "detect", None)):
            raise ValueError(f"inner must be a Detector (with detect(frame)), got {inner!r}")
        self.inner = inner
        self.clock = clock
        self.name = str(getattr(inner, "name", type(inner).__name__))
        for attr in ("needs_color", "needs_label"):
            if hasattr(inner, attr):
                setattr(self, attr, getattr(inner, attr))
        self.times_s: list[float] = []
        self.found: list[bool] = []

    def detect(self, frame):
        """``inner.detect(frame)``, timed."""
        t0 = self.clock()
        det = self.inner.detect(frame)
        self.times_s.append(self.clock() - t0)
        self.found.append(bool(det.person_found))
        return det

    def close(self) -> None:
        """Close the inner detector if it can be closed."""
        close = getattr(self.inner, "close", None)
        if callable(close):
            close()


@dataclass
class RunResult:
    """The outcome of :func:`run_pipeline`.

    Attributes:
        log: the per-frame poses of every stage (:class:`~akc_drake.diagrams.MocapLog`).
        frames: frames processed.
        wall_s: wall-clock seconds of the whole run.
        latency_s: per stage, one wall time per frame, seconds (NaN where a stage did not run).
        stop_reason: ``"frames"`` (the requested count), ``"source ended"``, ``"source error: ..."`` or
            ``"interrupted"``.
        ik: a teleop diagram's differential-IK updates (:class:`~akc_drake.robot.ik_status.IKStatusCounter`):
            ``steps``, ``failures`` (no solution and no fallback moved the arm: the command held), ``relaxed``
            (the position-only fallback moved it) and ``joint_space``, per side, and ``kinds`` (failures per
            status, both arms); None for a mocap diagram.
    """

    log: object
    frames: int
    wall_s: float
    latency_s: dict[str, np.ndarray]
    stop_reason: str
    ik: dict | None = None


def _frame_source_system(built):
    from akc_drake.systems.frame_source import FrameSourceSystem

    src = built.systems.get("source")
    return src if isinstance(src, FrameSourceSystem) else None


def _occlusion_timer(built, clock: Clock):
    """A function timing the occlusion filter's core call on its current inputs (None without one)."""
    from akc_drake.core.occlusion import occlusion_filter
    from akc_drake.core.skeleton import NUM_LANDMARKS

    ports = built.ports
    if "occlusion" not in built.systems or ports.raw is None or ports.pixels is None:
        return None
    cfg = built.config
    width = float(cfg.camera.width)

    def timed(root) -> float:
        def val(port):
            return port.Eval(port.get_system().GetMyContextFromRoot(root))

        points = np.asarray(val(ports.raw)).reshape(NUM_LANDMARKS, 3)
        pixels = np.asarray(val(ports.pixels)).reshape(NUM_LANDMARKS, 2)
        vis = np.asarray(val(ports.visibility)).reshape(NUM_LANDMARKS)
        t0 = clock()
        occlusion_filter(
            points, pixels, vis, width, visibility_threshold=cfg.visibility_threshold, proximity=cfg.proximity
        )
        return clock() - t0

    return timed


def _depth_timer(built, clock: Clock):
    """A function timing the extractor's depth lookup + deprojection (core calls) on its current frame."""
    from akc_drake.core.camera import deproject, depth_lookup

    ext = built.systems.get("extractor")
    if ext is None or not ext.HasInputPort("depth_image") or not ext.HasInputPort("camera_info"):
        return None
    window, rule = int(ext.window), ext.depth_rule
    lo, hi = getattr(ext, "_range", (0.2, 10.0))
    pixels = ext.GetOutputPort("pixels")

    def timed(root) -> float:
        ctx = ext.GetMyContextFromRoot(root)
        depth = ext.GetInputPort("depth_image").Eval(ctx).data[:, :, 0]
        K = ext.GetInputPort("camera_info").Eval(ctx)
        uv = np.asarray(pixels.Eval(ctx)).reshape(-1, 2)
        if not np.isfinite(uv).any():
            return math.nan  # nobody detected: the extractor skipped the lookup
        t0 = clock()
        deproject(uv, depth_lookup(depth, uv, window=window, min_depth=lo, max_depth=hi, rule=rule), K)
        return clock() - t0

    return timed


def run_pipeline(
    built,
    num_frames: int | None = None,
    *,
    detector: TimedDetector | None = None,
    realtime: bool = False,
    progress: bool = False,
    clock: Clock = time.perf_counter,
) -> RunResult:
    """Run a built mocap or teleop diagram frame by frame, timing each stage.

    A teleop diagram's differential-IK outcomes are counted (``RunResult.ik``) and Drake's per-step warnings about
    them (an arm's IK starting or stopping to find solutions) are silenced for the run: the counts say it once.

    Args:
        built: a :class:`~akc_drake.diagrams.MocapDiagram` (or TeleopDiagram).
        num_frames: stop after this many frames; None runs until a frame source ends (required for ``sim``).
        detector: the TimedDetector inside the diagram's extractor, to split stage S2.
        realtime: pace the frames at the camera rate in wall-clock time (live cameras).
        progress: show a progress bar on stderr.
        clock: seconds, monotonic (default :func:`time.perf_counter`); every latency is read from it.

    Returns:
        A :class:`RunResult`. A source that fails mid-run ends the run (``stop_reason`` says why) with the
        frames done so far; Ctrl-C ends it too.

    Raises:
        UserError: the source failed (or ended) before its first frame.
        ValueError: ``num_frames`` is None on a diagram without a frame source.
    """
    from akc_drake.robot.ik_status import IKStatusCounter, quiet_drake_warnings

    ik = getattr(built, "ik", None)
    if not ik:
        return _run_pipeline(built, num_frames, detector, realtime, progress, clock, None)
    counter = IKStatusCounter(ik, float(built.ik_time_step))
    with quiet_drake_warnings():
        result = _run_pipeline(built, num_frames, detector, realtime, progress, clock, counter)
    result.ik = counter.counts()
    return result


def _run_pipeline(built, num_frames, detector, realtime, progress, clock, counter) -> RunResult:
    """:func:`run_pipeline`'s run, ``counter`` (an ``IKStatusCounter`` or None) the simulator's monitor."""
    from pydrake.systems.analysis import Simulator
    from tqdm import tqdm

    from akc_drake.diagrams import camera_period, read_logs
    from akc_drake.systems.timing import STAGE_INDEX

    cfg = built.config
    period = camera_period(cfg)
    d = float(cfg.stage_offset_s)
    if num_frames is None and _frame_source_system(built) is None:
        raise ValueError("run_pipeline: num_frames is required for a source without an end")
    sliced = period > (STAGE_INDEX["mapper"] + 1.5) * d  # room for one slice per stage in a period
    fsys = _frame_source_system(built)
    occ_timer = _occlusion_timer(built, clock)
    depth_timer = _depth_timer(built, clock)
    ext = built.systems.get("extractor")
    ext_inputs = [
        ext.GetInputPort(n) for n in ("color_image", "depth_image") if ext is not None and ext.HasInputPort(n)
    ]

    simulator = Simulator(built.diagram)
    if counter is not None:
        simulator.set_monitor(counter)
    simulator.set_target_realtime_rate(0.0)
    simulator.Initialize()
    root = simulator.get_context()
    fsys_ctx = fsys.GetMyContextFromRoot(root) if fsys is not None else None
    ext_ctx = ext.GetMyContextFromRoot(root) if ext is not None else None

    rec: dict[str, list[float]] = {k: [] for k in LATENCY_STAGES}

    def advance(t: float) -> float:
        t = max(t, root.get_time())
        t0 = clock()
        simulator.AdvanceTo(t)
        return clock() - t0

    stop_reason = "frames"
    done = 0
    start = clock()
    total = num_frames if num_frames is not None else getattr(built, "num_frames", None)
    bar = tqdm(total=total, desc="run", unit="frame", disable=not progress, leave=False, file=sys.stderr)
    try:
        k = 0
        while num_frames is None or k < num_frames:
            t_k = k * period
            if realtime:
                wait = start + t_k - clock()
                if wait > 0:
                    time.sleep(wait)
            row = dict.fromkeys(LATENCY_STAGES, math.nan)
            if not sliced:
                row["frame_wall"] = advance(t_k + period - 0.5 * d)
                row["end_to_end"] = row["frame_wall"]
                if fsys is not None and (
                    fsys.error is not None or fsys.GetOutputPort("finished").Eval(fsys_ctx)[0] > 0.5
                ):
                    stop_reason = "source ended" if fsys.error is None else f"source error: {fsys.error}"
                    break
            else:
                between = advance(t_k - 0.5 * d) if k > 0 else 0.0
                src = advance(t_k + 0.5 * d)
                if fsys is not None:
                    if fsys.error is not None:
                        stop_reason = f"source error: {fsys.error}"
                        break
                    if fsys.GetOutputPort("finished").Eval(fsys_ctx)[0] > 0.5:
                        stop_reason = "source ended"
                        break
                t0 = clock()
                for port in ext_inputs:  # the source's images, as the extractor will read them
                    port.Eval(ext_ctx)
                row["source"] = src + (clock() - t0)
                n_det = len(detector.times_s) if detector is not None else 0
                row["extractor"] = advance(t_k + 1.5 * d)
                if detector is not None and len(detector.times_s) > n_det:
                    row["detector"] = detector.times_s[-1]
                if depth_timer is not None:
                    row["depth_deprojection"] = depth_timer(root)
                if math.isfinite(row["detector"]):
                    inner = row["detector"] + np.nan_to_num(row["depth_deprojection"], nan=0.0)
                    row["extractor_overhead"] = max(row["extractor"] - inner, 0.0)
                occ = occ_timer(root) if occ_timer is not None else 0.0
                filt = advance(t_k + 2.5 * d)
                if "filter" in built.systems:
                    row["filter"] = max(filt - occ, 0.0)
                if occ_timer is not None:
                    row["occlusion_filter"] = occ
                corr = advance(t_k + 3.5 * d)
                if "corrector" in built.systems:
                    row["corrector"] = corr
                mapper = advance(t_k + 4.5 * d)
                if getattr(built, "mapper", None) is not None:
                    row["mapper"] = mapper
                row["end_to_end"] = row["source"] + row["extractor"] + filt + corr
                row["frame_wall"] = between + row["source"] + row["extractor"] + filt + corr + mapper
            for key, v in row.items():
                rec[key].append(v)
            k += 1
            done = k
            bar.update(1)
    except KeyboardInterrupt:
        stop_reason = "interrupted"
    finally:
        bar.close()
    if done == 0:
        if stop_reason.startswith("source error"):
            raise UserError(f"--source {cfg.source}: {stop_reason[len('source error: ') :]}")
        raise UserError(f"--source {cfg.source}: no frames")
    # The loggers record frame k at t_{k+1} (see diagrams.AddStageLoggers): run on to the last frame's record.
    n = len(rec["frame_wall"])
    latency = {key: np.asarray(v[:n], dtype=float) for key, v in rec.items()}
    try:
        advance(done * period + 0.5 * d)
    except KeyboardInterrupt:
        stop_reason = "interrupted"
    wall = clock() - start
    log = read_logs(built.loggers, root, period, done)
    built._last_context = root
    return RunResult(
        log=log,
        frames=done,
        wall_s=wall,
        latency_s={k: v[:done] for k, v in latency.items()},
        stop_reason=stop_reason,
    )


def frames_to_run(built, rate_hz: float, seconds: float | None) -> int | None:
    """The diagram's own frame count (None: until the source ends), capped at ``seconds`` of camera frames."""
    n = built.num_frames
    if seconds is not None:
        if not (math.isfinite(seconds) and seconds > 0):
            raise UserError(f"--seconds must be a positive number, got {seconds!r}")
        cap = max(int(round(seconds * rate_hz)), 1)
        n = cap if n is None else min(n, cap)
    return n


def build_and_run(
    cfg,
    inputs,
    *,
    teleop: bool = False,
    num_frames: int | None = None,
    seconds: float | None = None,
    meshcat=None,
    lcm=None,
    realtime: bool = False,
    progress: bool = False,
    clock: Clock = time.perf_counter,
):
    """Build the mocap (or teleop) diagram on opened ``inputs`` and run it with :func:`run_pipeline`.

    Args:
        cfg: the pipeline configuration.
        inputs: a :class:`~akc_drake.pipeline.inputs.PipelineInputs` (not closed here).
        teleop: the teleop diagram (the robot follows the corrected pose) instead of the mocap one.
        num_frames: at most this many frames (default: the diagram's own count, or until the source ends).
        seconds: at most this many seconds of camera frames.
        meshcat: a ``pydrake.geometry.Meshcat`` for the teleop diagram, or None.
        lcm: a ``pydrake.lcm.DrakeLcm``: the teleop diagram publishes its commands and control frames on it.
        realtime, progress, clock: as in :func:`run_pipeline`.

    Returns:
        ``(built, result)``: the diagram and its :class:`RunResult`.
    """
    from akc_drake import diagrams

    builder = diagrams.build_teleop_diagram if teleop else diagrams.build_mocap_diagram
    kwargs = {"meshcat": meshcat} if meshcat is not None else {}
    if lcm is not None:
        if not teleop:
            raise UserError("--lcm publishes the robot's commands: use it with --teleop")
        kwargs["lcm"] = lcm
    built = builder(
        cfg,
        frame_source=inputs.frame_source,
        detector=inputs.detector,
        dims=inputs.dims,
        motion=inputs.motion,
        **kwargs,
    )
    n = frames_to_run(built, cfg.camera.rate_hz, seconds)
    if num_frames is not None:
        n = num_frames if n is None else min(n, num_frames)
    result = run_pipeline(built, n, detector=inputs.detector, realtime=realtime, progress=progress, clock=clock)
    return built, result
