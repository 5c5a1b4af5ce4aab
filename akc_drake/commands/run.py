"""``akc-drake run``: the mocap (or teleop) diagram on a source, with per-stage latency.

Sources: ``sim`` (the rendered operator doing ``--motion``), ``recording:DIR``, ``bag:FILE``, ``realsense``,
``video:FILE`` (see :mod:`akc_drake.io.sources`). Real sources go through MediaPipe's PoseLandmarker.

Outputs: ``poses.npz`` (per frame: ``t``, ``raw``, ``accepted``, ``filtered``, ``corrected``, ``truth``,
``visibility``, ``names``; NaN where missing) in ``--out`` (default: next to ``--json``, else ``out/run``), a
short summary on stdout and, with ``--json``, the summary as JSON: ``frames``, ``frames_with_person``,
``visibility_mean`` and ``visible_share`` per landmark, ``latency_ms`` per stage, arm-length ranges, and
errors against the ground truth when the source has it (``sim``, simulated recordings).

Latency per stage. :func:`run_pipeline` advances the simulator through each camera period in slices, one slice
per stage: the stages are sampled at ``t_k + i * stage_offset`` (:mod:`akc_drake.systems.timing`), so the
slice ``(t_k + (i - 1/2) offset, t_k + (i + 1/2) offset]`` holds stage ``i``'s update and nothing else of the
pipeline. The wall time of a slice is the stage's latency as the diagram runs it (Drake's event dispatch
included). Within stage S2 (``extractor``) the detector is timed by :class:`TimedDetector`, the depth lookup
and deprojection (``depth_deprojection``) by calling their core functions again on the frame's depth image and
detected pixels; the remainder (``extractor_overhead``) is building the frame from the Drake images and the
event itself. The occlusion filter, which is direct feedthrough evaluated inside the Kalman filter's update,
is timed by calling its core function on the same inputs, and subtracted from the filter's slice.
``end_to_end`` is the sum of the slices from the source read to the corrected pose; ``frame_wall`` is the
whole camera period's wall time. With ``--teleop`` the robot plant's 2 ms steps fall on the source, filter and
mapper instants and are included in those figures; the mocap stages are the ones to read (``latency_note`` in
the JSON says so).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.commands._common import load_dims_option
from akc_drake.fileio import atomic_save_npz as save_npz_atomic
from akc_drake.fileio import write_json
from akc_drake.operator.retarget import motion_from_spec
from akc_drake.core.skeleton import ARM_JOINTS, LANDMARKS, SEGMENT_NAMES
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


class TimedDetector:
    """A :class:`~akc_drake.core.camera.Detector` that times each ``detect`` call of another detector.

    Args:
        inner: the detector to time (its ``name``, ``needs_color`` and ``needs_label`` are passed through).

    Attributes:
        times_s: wall time of each call, seconds.
        found: whether each call found a person.
    """

    def __init__(self, inner):
        if not callable(getattr(inner, "detect", None)):
            raise ValueError(f"inner must be a Detector (with detect(frame)), got {inner!r}")
        self.inner = inner
        self.name = str(getattr(inner, "name", type(inner).__name__))
        for attr in ("needs_color", "needs_label"):
            if hasattr(inner, attr):
                setattr(self, attr, getattr(inner, attr))
        self.times_s: list[float] = []
        self.found: list[bool] = []

    def detect(self, frame):
        """``inner.detect(frame)``, timed."""
        t0 = time.perf_counter()
        det = self.inner.detect(frame)
        self.times_s.append(time.perf_counter() - t0)
        self.found.append(bool(det.person_found))
        return det

    def close(self) -> None:
        """Close the inner detector if it can be closed."""
        close = getattr(self.inner, "close", None)
        if callable(close):
            close()


@dataclass
class PipelineInputs:
    """What a command needs to build the diagram on ``--source``.

    Attributes:
        config: the pipeline configuration (camera size and rate set from a real source).
        frame_source: the opened real source, or None for ``sim``.
        detector: a :class:`TimedDetector` around MediaPipe for a real source, around the simulated detector
            (as the extractor's default) for ``sim``.
        motion: the operator motion for ``sim``.
        dims: body dimensions (None: the diagram's default, the simulated operator's).
        dims_origin: where ``dims`` come from, for the report.
    """

    config: object
    frame_source: object = None
    detector: TimedDetector | None = None
    motion: object = None
    dims: object = None
    dims_origin: str = "simulated operator"
    notes: list[str] = field(default_factory=list)

    def close(self) -> None:
        """Release the source and the detector (MediaPipe's graph, the camera)."""
        for obj in (self.detector, self.frame_source):
            close = getattr(obj, "close", None)
            if callable(close):
                try:
                    close()
                except Exception:  # closing must never hide the run's own outcome
                    pass


def open_inputs(args, cfg, *, motion=None, default_real_dims=True) -> PipelineInputs:
    """Open ``cfg.source`` (and MediaPipe for a real one), load ``--dims``; user mistakes raise UserError.

    Args:
        args: the parsed command line (``dims``, ``depth``, ``pose_model``, ``seconds``, ``motion``, ...).
        cfg: the :class:`~akc_drake.config.PipelineConfig`; a real source's size and rate are copied into it.
        motion: the motion to render for ``sim`` (default: ``args.motion``).
        default_real_dims: without ``--dims``, give a real source the paper's manual arm lengths.
    """
    from akc_drake.io.sources import open_source

    dims = load_dims_option(getattr(args, "dims", None))
    inputs = PipelineInputs(config=cfg, dims=dims, dims_origin=str(args.dims) if dims is not None else "")
    spec = cfg.source
    kind = spec.strip().split(":", 1)[0].lower()
    if kind == "sim" and ":" not in spec:
        if getattr(args, "depth", None) is not None:
            raise UserError("--depth applies to a video:FILE source only")
        if motion is None:
            motion = motion_from_spec(
                cfg.motion,
                cycles=cfg.cycles,
                seed=cfg.seed,
                skeleton=getattr(args, "skeleton", None) or cfg.skeleton or None,
                rate_hz=cfg.camera.rate_hz,
            )
        inputs.motion = motion
        from akc_drake.core.sim_detector import SimulatedDetector

        inputs.detector = TimedDetector(SimulatedDetector(seed=cfg.seed))
        if dims is None:
            inputs.dims_origin = "simulated operator"
        return inputs
    opts = {"depth_m": getattr(args, "depth", None)}
    if kind == "realsense":
        # The camera streams at its own fps; the pipeline pulls the newest frame at the configured rate.
        opts = {"rate_hz": cfg.camera.rate_hz, "seconds": getattr(args, "seconds", None)}
    source = open_source(spec, **opts)
    inputs.frame_source = source
    try:
        K = source.intrinsics
        cfg.camera.width, cfg.camera.height, cfg.camera.rate_hz = (
            int(K.width),
            int(K.height),
            float(source.rate_hz),
        )
        from akc_drake.io.mediapipe_detector import MediaPipeDetector

        inputs.detector = TimedDetector(MediaPipeDetector(model_path=getattr(args, "pose_model", None)))
    except BaseException:
        inputs.close()
        raise
    if dims is None and default_real_dims:
        from akc_drake.core.skeleton import BodyDimensions

        inputs.dims = BodyDimensions.paper_manual()
        inputs.dims_origin = "paper manual (no --dims)"
        inputs.notes.append(
            "no --dims given: using the paper's manual arm lengths (run 'akc-drake calibrate')"
        )
    return inputs


# ----------------------------------------------------------------------------------------------------
# Running the diagram frame by frame, stage by stage


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
    """

    log: object
    frames: int
    wall_s: float
    latency_s: dict[str, np.ndarray]
    stop_reason: str


def _frame_source_system(built):
    from akc_drake.systems.frame_source import FrameSourceSystem

    src = built.systems.get("source")
    return src if isinstance(src, FrameSourceSystem) else None


def _occlusion_timer(built):
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
        t0 = time.perf_counter()
        occlusion_filter(
            points, pixels, vis, width, visibility_threshold=cfg.visibility_threshold, proximity=cfg.proximity
        )
        return time.perf_counter() - t0

    return timed


def _depth_timer(built):
    """A function timing the extractor's depth lookup + deprojection (core calls) on its current frame."""
    from akc_drake.core.camera import deproject, depth_lookup

    ext = built.systems.get("extractor")
    if ext is None or not ext.HasInputPort("depth_image") or not ext.HasInputPort("camera_info"):
        return None
    window = int(getattr(ext, "_window", 5))
    lo, hi = getattr(ext, "_range", (0.2, 10.0))
    pixels = ext.GetOutputPort("pixels")

    def timed(root) -> float:
        ctx = ext.GetMyContextFromRoot(root)
        depth = ext.GetInputPort("depth_image").Eval(ctx).data[:, :, 0]
        K = ext.GetInputPort("camera_info").Eval(ctx)
        uv = np.asarray(pixels.Eval(ctx)).reshape(-1, 2)
        if not np.isfinite(uv).any():
            return math.nan  # nobody detected: the extractor skipped the lookup
        t0 = time.perf_counter()
        deproject(uv, depth_lookup(depth, uv, window=window, min_depth=lo, max_depth=hi), K)
        return time.perf_counter() - t0

    return timed


def run_pipeline(
    built,
    num_frames: int | None = None,
    *,
    detector: TimedDetector | None = None,
    realtime: bool = False,
    progress: bool = False,
) -> RunResult:
    """Run a built mocap or teleop diagram frame by frame, timing each stage.

    Args:
        built: a :class:`~akc_drake.diagrams.MocapDiagram` (or TeleopDiagram).
        num_frames: stop after this many frames; None runs until a frame source ends (required for ``sim``).
        detector: the TimedDetector inside the diagram's extractor, to split stage S2.
        realtime: pace the frames at the camera rate in wall-clock time (live cameras).
        progress: show a progress bar on stderr.

    Returns:
        A :class:`RunResult`. A source that fails mid-run ends the run (``stop_reason`` says why); Ctrl-C
        ends it too, keeping the frames done so far.
    """
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
    occ_timer = _occlusion_timer(built)
    depth_timer = _depth_timer(built)
    ext = built.systems.get("extractor")
    ext_inputs = [
        ext.GetInputPort(n) for n in ("color_image", "depth_image") if ext is not None and ext.HasInputPort(n)
    ]

    simulator = Simulator(built.diagram)
    simulator.set_target_realtime_rate(0.0)
    simulator.Initialize()
    root = simulator.get_context()
    fsys_ctx = fsys.GetMyContextFromRoot(root) if fsys is not None else None
    ext_ctx = ext.GetMyContextFromRoot(root) if ext is not None else None

    rec: dict[str, list[float]] = {k: [] for k in LATENCY_STAGES}

    def advance(t: float) -> float:
        t = max(t, root.get_time())
        t0 = time.perf_counter()
        simulator.AdvanceTo(t)
        return time.perf_counter() - t0

    stop_reason = "frames"
    done = 0
    start = time.perf_counter()
    total = num_frames if num_frames is not None else getattr(built, "num_frames", None)
    bar = tqdm(total=total, desc="run", unit="frame", disable=not progress, leave=False, file=sys.stderr)
    try:
        k = 0
        while num_frames is None or k < num_frames:
            t_k = k * period
            if realtime:
                wait = start + t_k - time.perf_counter()
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
                t0 = time.perf_counter()
                for port in ext_inputs:  # the source's images, as the extractor will read them
                    port.Eval(ext_ctx)
                row["source"] = src + (time.perf_counter() - t0)
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
    for key in rec:
        rec[key] = np.asarray(rec[key][:n], dtype=float)
    try:
        advance(done * period + 0.5 * d)
    except KeyboardInterrupt:
        stop_reason = "interrupted"
    wall = time.perf_counter() - start
    log = read_logs(built.loggers, root, period, done)
    built._last_context = root
    return RunResult(
        log=log,
        frames=done,
        wall_s=wall,
        latency_s={k: v[:done] for k, v in rec.items()},
        stop_reason=stop_reason,
    )


# ----------------------------------------------------------------------------------------------------
# Summaries


def latency_summary(latency_s: dict[str, np.ndarray]) -> dict:
    """Median, mean and max (ms) per stage over the frames where it ran; stages that never ran are omitted."""
    out = {}
    for name in LATENCY_STAGES:
        v = np.asarray(latency_s.get(name, []), dtype=float)
        v = v[np.isfinite(v)] * 1e3
        if v.size:
            out[name] = {
                "median": float(np.median(v)),
                "mean": float(v.mean()),
                "max": float(v.max()),
                "frames": int(v.size),
            }
    return out


def person_mask(log) -> np.ndarray:
    """Frames where the detector found a person: any landmark with a position or a non-zero visibility."""
    vis = np.nan_to_num(np.asarray(log.visibility, dtype=float), nan=0.0)
    return (vis > 0).any(axis=1) | np.isfinite(log.raw).all(axis=2).any(axis=1)


def summarize(
    log,
    *,
    wall_s: float,
    visibility_threshold: float = 0.7,
    stages=("raw", "accepted", "estimated", "corrected"),
) -> dict:
    """Frames, detection rate, visibility, arm-length ranges and (with ground truth) errors per stage."""
    from akc_drake.core.metrics import arm_length_range, joint_errors

    n = len(log.t)
    person = person_mask(log)
    vis = np.asarray(log.visibility, dtype=float)
    out = {
        "frames": n,
        "frames_with_person": int(person.sum()),
        "person_share": float(person.mean()) if n else None,
        "visibility_mean": {
            name: float(np.nanmean(vis[person, j])) if person.any() else None
            for j, name in enumerate(LANDMARKS)
        },
        "visible_share": {
            name: float(np.mean(vis[:, j] >= visibility_threshold)) if n else None
            for j, name in enumerate(LANDMARKS)
        },
        "wall_s": wall_s,
        "fps": n / wall_s if wall_s > 0 else None,
        "arm_length_range_cm": {},
    }
    for stage in stages:
        rng = arm_length_range(getattr(log, stage))
        out["arm_length_range_cm"][stage] = {
            k: (None if not np.isfinite(v) else 100.0 * v) for k, v in rng.items()
        }
    if np.isfinite(log.truth).any():
        out["errors"] = {stage: joint_errors(getattr(log, stage), log.truth, ARM_JOINTS) for stage in stages}
    return out


# ----------------------------------------------------------------------------------------------------
# The command


def _config(args):
    from akc_drake.config import PipelineConfig, load_config

    cfg = load_config(args.config) if args.config else PipelineConfig()
    # Options given on the command line win over the file (argparse defaults do not).
    cfg.source = args.source
    for name, default in (
        ("motion", "II"),
        ("cycles", 1),
        ("seed", 0),
        ("filter", "KF"),
        ("corrector", "AKC"),
    ):
        value = getattr(args, name)
        if not args.config or value != default:
            setattr(cfg, name, value)
    if getattr(args, "skeleton", None):
        cfg.skeleton = args.skeleton
    return cfg.validate()


def _num_frames(built, cfg, seconds: float | None) -> int | None:
    n = built.num_frames
    if seconds is not None:
        if not (math.isfinite(seconds) and seconds > 0):
            raise UserError(f"--seconds must be a positive number, got {seconds!r}")
        cap = max(int(round(seconds * cfg.camera.rate_hz)), 1)
        n = cap if n is None else min(n, cap)
    return n


def main(args) -> int:
    cfg = _config(args)
    kind = cfg.source.strip().split(":", 1)[0].lower()
    inputs = open_inputs(args, cfg)
    try:
        if kind == "realsense" and args.seconds is None:
            inputs.notes.append("live camera without --seconds: press Ctrl-C to stop")
        for note in inputs.notes:
            print(f"note: {note}", file=sys.stderr)
        from akc_drake import diagrams

        builder = diagrams.build_teleop_diagram if args.teleop else diagrams.build_mocap_diagram
        kwargs = {}
        if args.meshcat:
            if not args.teleop:
                raise UserError("--meshcat draws the robot: use it with --teleop")
            from pydrake.geometry import Meshcat, MeshcatParams

            params = MeshcatParams()
            params.host = "localhost"  # Drake's default ("*") would listen on every network interface
            kwargs["meshcat"] = Meshcat(params)
            print(f"Meshcat: {kwargs['meshcat'].web_url()}", file=sys.stderr)
        built = builder(
            cfg,
            frame_source=inputs.frame_source,
            detector=inputs.detector,
            dims=inputs.dims,
            motion=inputs.motion,
            **kwargs,
        )
        num_frames = _num_frames(built, cfg, args.seconds)
        result = run_pipeline(
            built,
            num_frames,
            detector=inputs.detector,
            realtime=(kind == "realsense"),
            progress=sys.stderr.isatty(),
        )
    finally:
        inputs.close()
    if result.stop_reason.startswith("source error"):
        print(
            f"warning: the source stopped after {result.frames} frames ({result.stop_reason})",
            file=sys.stderr,
        )

    log, wall = result.log, result.wall_s
    summary = {
        "config": {
            "source": cfg.source,
            "motion": cfg.motion if kind == "sim" else None,
            "cycles": cfg.cycles,
            "seed": cfg.seed,
            "filter": cfg.filter,
            "corrector": cfg.corrector,
            "weights": cfg.weights,
            "rate_hz": cfg.camera.rate_hz,
            "width": cfg.camera.width,
            "height": cfg.camera.height,
            "depth_m": args.depth,
            "teleop": bool(args.teleop),
        },
        "detector": inputs.detector.name,
        "dims": built.dims.as_dict(),
        "dims_origin": inputs.dims_origin,
        "stop_reason": result.stop_reason,
        **summarize(log, wall_s=wall, visibility_threshold=cfg.visibility_threshold),
        "latency_ms": latency_summary(result.latency_s),
    }
    if args.teleop:
        m = built.monitor
        summary["latency_note"] = (
            "with --teleop, source, filter and mapper include the robot's steps at the same instants"
        )
        summary["teleop"] = {
            "nan_commands": m.nan_commands,
            "max_joint_speed_ratio": m.max_speed_ratio,
            "ee_tracking_error_cm": {
                s: float(np.median(m.ee_errors(s)) * 100) if len(m.ee_errors(s)) else None
                for s in ("left", "right")
            },
            "realtime_factor": (result.frames / cfg.camera.rate_hz) / wall if wall > 0 else None,
        }
    out_dir = Path(args.out) if args.out else (Path(args.json).parent if args.json else Path("out/run"))
    npz = save_npz_atomic(
        out_dir / "poses.npz",
        t=log.t,
        raw=log.raw,
        accepted=log.accepted,
        filtered=log.estimated,
        corrected=log.corrected,
        truth=log.truth,
        visibility=log.visibility,
        names=np.array(LANDMARKS),
    )
    summary["poses_npz"] = str(npz)
    if args.json:
        write_json(args.json, summary)
    _print_summary(summary, wall)
    return 0


def _print_summary(summary: dict, wall: float) -> None:
    rng = summary["arm_length_range_cm"]
    print(
        f"{summary['frames']} frames ({summary['frames_with_person']} with a person) in {wall:.1f} s; "
        f"poses -> {summary['poses_npz']}"
    )
    lat = summary["latency_ms"]
    parts = [
        f"{k} {lat[k]['median']:.2f}"
        for k in (
            "source",
            "detector",
            "depth_deprojection",
            "extractor_overhead",
            "occlusion_filter",
            "filter",
            "corrector",
            "end_to_end",
        )
        if k in lat
    ]
    if parts:
        print("  latency, median ms: " + ", ".join(parts))
    for stage in ("raw", "estimated", "corrected"):
        vals = ", ".join(
            f"{s} {rng[stage][s]:.2f}" if rng[stage].get(s) is not None else f"{s} -"
            for s in SEGMENT_NAMES
            if s != "SW"
        )
        print(f"  arm-length range (cm), {stage:9s}: {vals}")
    if "errors" in summary:
        e = summary["errors"]
        for stage in ("raw", "corrected"):
            z = [e[stage][j]["rmse_cm"]["z"] for j in ("left_shoulder", "left_elbow")]
            print(
                f"  RMSE z (cm) left shoulder / elbow, {stage:9s}: "
                + " / ".join("-" if v is None or not np.isfinite(v) else f"{v:.2f}" for v in z)
            )
