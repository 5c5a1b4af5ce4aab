"""Speed and memory benchmark of every stage, run side by side in one process (``akc-drake bench``).

Every figure is measured in the same run on the same machine, after a warm-up, with several repeats, and
reported as a median and a maximum (plus mean, 95th percentile and sample count):

* **core, per frame** (both arms, 12 landmarks): the occlusion filter, the constant-velocity KF, the EKF,
  AKC, COIK with each solver (SNOPT, IPOPT, NLopt; warm start) and the control frames; and the ratio
  COIK / AKC of the medians;
* **LeafSystem overhead**: each stage's system alone, fed by a :class:`MeasurementReplay` and stepped by a
  ``Simulator`` at its own rate; the replay alone is the baseline, so ``net_us`` is what the stage costs in a
  diagram and ``overhead_us`` what the Drake wrapping adds on top of the core call;
* **mocap diagram** replaying recorded measurements (no rendering): frames per second;
* **rendering + landmark extraction** per frame at 640x480 (the DepthCameraSource + LandmarkExtractor
  diagram), and **MediaPipe** per frame on those renders when the extra is installed;
* **teleop diagram** (rendering at 10 Hz, plant stepping): realtime factor;
* **memory**: RSS of a long simulated teleop run (10 min; 20 s with ``quick``), sampled along the way, its
  peak and its growth from the first sample to the last (minute 1 to minute 10).

The input of the core and system benchmarks is a rendered Motion I session when rendering works, else a
synthetic one (:func:`synthetic_measurements`): the operator model's true landmarks seen by the default
camera, with detector noise and self-occlusion injected the way the renderer produces it.

All times use ``time.perf_counter_ns``; the garbage collector is disabled inside the tight core loops.
The result is a JSON-able dict (:func:`run_bench`) whose top-level keys include DESIGN.md's contract
(``akc_us_per_frame``, ``kf_us_per_frame``, ``ekf_us_per_frame``, ``coik_ms_per_frame``,
``mocap_diagram_fps``, ``teleop_realtime_factor``).
"""

from __future__ import annotations

import gc
import logging
import math
import os
import platform
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, PROXIMAL_DISTAL_PAIRS, BodyDimensions
from akc_drake.fileio import write_json

#: Speed targets on the reference machine (2 cores, no GPU): figure key -> (comparison, bound).
TARGETS: dict[str, tuple[str, float]] = {
    "akc_us_per_frame": ("<=", 25.0),
    "kf_us_per_frame": ("<=", 20.0),
    "ekf_us_per_frame": ("<=", 60.0),
    "coik_snopt_ms_per_frame": ("<=", 3.0),
    "coik_over_akc_snopt": (">=", 50.0),
    "mocap_diagram_fps": (">=", 500.0),
    "render_extract_fps": (">=", 25.0),
    "teleop_realtime_factor": (">=", 2.0),
    "memory_growth_pct": ("<", 5.0),
}

BENCH_FORMAT = 1


# ================================================================================================ settings
@dataclass(frozen=True)
class BenchSettings:
    """Sizes of one benchmark run.

    Attributes:
        quick: the CI-sized run.
        cycles: Motion I cycles (6 s each) of the input session.
        core_repeats: passes over the session for KF, EKF, AKC, the occlusion filter and the frames.
        coik_frames: frames solved per COIK solver and pass; coik_repeats: passes.
        system_repeats: simulator runs per stage system (the median per-frame time is kept).
        mocap_repeats: mocap diagram runs.
        render_frames: frames rendered and extracted for the rendering figure (after one warm-up frame).
        mediapipe_frames: frames given to MediaPipe (after one warm-up frame).
        teleop_seconds: simulated seconds of the teleop realtime-factor run.
        memory_seconds: simulated seconds of the memory run; memory_sample_s: its RSS sampling period.
        memory_growth_from_s: growth is measured from the sample at this time to the last one.
        warmup_frames: calls made before timing starts (core loops).
    """

    quick: bool = False
    cycles: int = 2
    core_repeats: int = 20
    coik_frames: int = 120
    coik_repeats: int = 2
    system_repeats: int = 5
    mocap_repeats: int = 5
    render_frames: int = 60
    mediapipe_frames: int = 30
    teleop_seconds: float = 30.0
    memory_seconds: float = 600.0
    memory_sample_s: float = 60.0
    memory_growth_from_s: float = 60.0
    warmup_frames: int = 20

    @classmethod
    def full(cls) -> BenchSettings:
        return cls()

    @classmethod
    def quick_run(cls) -> BenchSettings:
        """CI-sized: well under a minute in total."""
        return cls(
            quick=True,
            cycles=1,
            core_repeats=3,
            coik_frames=15,
            coik_repeats=1,
            system_repeats=1,
            mocap_repeats=1,
            render_frames=5,
            mediapipe_frames=3,
            teleop_seconds=2.0,
            memory_seconds=20.0,
            memory_sample_s=2.0,
            memory_growth_from_s=10.0,
            warmup_frames=5,
        )


# ================================================================================================ statistics
def summarize(samples: Iterable[float], unit: str) -> dict:
    """Median, max, mean, 95th percentile and count of ``samples`` (already in ``unit``)."""
    a = np.asarray(list(samples) if not isinstance(samples, np.ndarray) else samples, dtype=float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return {"median": float("nan"), "max": float("nan"), "mean": float("nan"), "p95": float("nan"),
                "n": 0, "unit": unit}
    return {
        "median": float(np.median(a)),
        "max": float(a.max()),
        "mean": float(a.mean()),
        "p95": float(np.percentile(a, 95)),
        "n": int(a.size),
        "unit": unit,
    }


def time_calls(
    fn: Callable,
    inputs: Sequence,
    *,
    repeats: int = 1,
    warmup: int = 0,
    before_pass: Callable[[], None] | None = None,
) -> np.ndarray:
    """Time ``fn(x)`` for every ``x`` of ``inputs``, ``repeats`` times, with the garbage collector off.

    Args:
        fn: the call to time.
        inputs: its arguments, in order (state carries over from call to call within a pass).
        repeats: passes over ``inputs``.
        warmup: calls on the first inputs before timing (after a ``before_pass``), not recorded.
        before_pass: called (untimed) before the warm-up and before every pass, e.g. a filter reset.

    Returns:
        ``(repeats * len(inputs),)`` int64 nanoseconds per call.
    """
    n = len(inputs)
    out = np.empty(repeats * n, dtype=np.int64)
    clock = time.perf_counter_ns
    was_enabled = gc.isenabled()
    gc.collect()
    gc.disable()
    try:
        if warmup:
            if before_pass is not None:
                before_pass()
            for k in range(warmup):
                fn(inputs[k % n])
        i = 0
        for _ in range(repeats):
            if before_pass is not None:
                before_pass()
            for x in inputs:
                t0 = clock()
                fn(x)
                out[i] = clock() - t0
                i += 1
    finally:
        if was_enabled:
            gc.enable()
    return out


def rss_bytes() -> int:
    """The process's resident set size in bytes (psutil, else ``/proc/self/status`` VmRSS; 0 if unknown)."""
    try:
        import psutil

        return int(psutil.Process().memory_info().rss)
    except ImportError:
        pass
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def peak_rss_bytes() -> int:
    """The process's peak RSS so far (``VmHWM``, else ``ru_maxrss``), bytes."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        import resource

        return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024
    except (ImportError, OSError):
        return 0


def machine_info() -> dict:
    """CPU, cores, memory, OS and library versions."""
    from importlib import metadata

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem_gb = float("nan")
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    mem_gb = int(line.split()[1]) / 1024**2
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = os.cpu_count()

    def version(dist: str) -> str | None:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return None

    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "cpus_usable": usable,
        "memory_gb": round(mem_gb, 2),
        "os": platform.platform(),
        "python": platform.python_version(),
        "drake": version("drake"),
        "numpy": version("numpy"),
        "scipy": version("scipy"),
        "mediapipe": version("mediapipe"),
        "akc_drake": version("akc-drake"),
        "load_average_at_start": _load_average(),
    }


def _load_average() -> list[float] | None:
    """The 1, 5 and 15 minute load averages (other work on the machine skews every figure)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


# ================================================================================================ input
@dataclass
class BenchInput:
    """The measurements every core/system benchmark is fed, and each stage's output on them.

    Attributes:
        t: ``(T,)`` frame times, s. raw: ``(T, 12, 3)`` extracted landmarks in C.
        visibility: ``(T, 12)``. pixels: ``(T, 12, 2)``. truth: ``(T, 12, 3)``.
        intrinsics: the camera. dims: the operator's dimensions.
        accepted: occlusion-filter output. kf: KF estimates. ekf: EKF estimates. akc: AKC(KF) output.
        kind: ``"rendered"`` or ``"synthetic"``.
    """

    t: np.ndarray
    raw: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray
    truth: np.ndarray
    intrinsics: CameraIntrinsics
    dims: BodyDimensions
    kind: str
    accepted: np.ndarray | None = None
    kf: np.ndarray | None = None
    ekf: np.ndarray | None = None
    akc: np.ndarray | None = None

    @property
    def num_frames(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t))) if self.t.size > 1 else 1.0 / self.intrinsics.rate_hz

    def run_stages(self) -> BenchInput:
        """Fill :attr:`accepted`, :attr:`kf`, :attr:`ekf` and :attr:`akc` by running the core stages once."""
        from akc_drake.core.akc import ArmKinematicCorrector
        from akc_drake.core.kalman import ConstantVelocityKF, ExtendedKalmanFilterCV
        from akc_drake.core.occlusion import occlusion_filter

        w = self.intrinsics.width
        frames = zip(self.raw, self.pixels, self.visibility, strict=True)
        self.accepted = np.stack([occlusion_filter(z, p, v, w)[0] for z, p, v in frames])
        kf, ekf = ConstantVelocityKF(), ExtendedKalmanFilterCV(self.dims)
        dt = self.dt
        self.kf = np.stack([kf.step(z, dt) for z in self.accepted])
        self.ekf = np.stack([ekf.step(z, dt) for z in self.accepted])
        akc = ArmKinematicCorrector(self.dims)
        self.akc = np.stack([akc.correct(p).pose for p in self.kf])
        return self


def camera_rotation_CO() -> np.ndarray:
    """``R_CO``: operator frame O (x forward, y left, z up) to camera frame C (x right, y down, z forward),
    for a camera in front of the operator looking back at them (its optical axis is -x_O)."""
    return np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]])


def synthetic_measurements(
    cycles: int = 1,
    seed: int = 0,
    intrinsics: CameraIntrinsics | None = None,
    *,
    motion: str = "I",
    distance_m: float = 1.8,
    height_m: float = 0.35,
    sigma_xy_m: float = 0.005,
    sigma_z_m: float = 0.02,
    dropout_rate: float = 0.02,
) -> BenchInput:
    """A session without rendering: the operator's true landmarks seen by the camera, with detector noise,
    self-occlusion and dropouts injected the way the renderer and detector produce them.

    * every landmark: Gaussian noise (``sigma_xy_m`` in x, y and ``sigma_z_m`` in depth), visibility 0.95;
    * self-occlusion: for each proximal/distal pair of an arm whose pixels are within 5 % of the image width,
      the one farther from the camera is hidden: a hidden distal joint gets visibility 0.3; a hidden proximal
      joint keeps a passing visibility (0.75) but its depth is the occluder's, as a depth camera would read it
      (what the occlusion filter's proximity check is for);
    * dropouts: bursts of 1-5 frames in which a landmark's visibility is 0.2, started with probability
      ``dropout_rate`` per landmark and frame.

    Args:
        cycles: Motion cycles (6 s each). seed: the noise seed.
        intrinsics: the camera (default 640x480, 10 Hz).
        motion: ``"I"`` or ``"II"``. distance_m, height_m: camera position in front of / above the pelvis.
        sigma_xy_m, sigma_z_m: measurement noise. dropout_rate: dropout burst rate.

    Returns:
        A :class:`BenchInput` of kind ``"synthetic"`` (stages not yet run).
    """
    from akc_drake.operator.model import OperatorParams
    from akc_drake.operator.motions import make_motion

    intr = intrinsics or CameraIntrinsics()
    m = make_motion(motion, cycles=cycles, seed=seed)
    t = m.frame_times(intr.rate_hz)
    params = OperatorParams()
    L_O = m.landmarks_O(t, params)
    R = camera_rotation_CO()
    truth = (L_O - np.array([distance_m, 0.0, height_m])) @ R.T
    T = t.size
    rng = np.random.default_rng(seed)
    raw = truth + rng.normal(0.0, 1.0, truth.shape) * np.array([sigma_xy_m, sigma_xy_m, sigma_z_m])
    z = np.maximum(truth[..., 2], 0.1)
    pixels = np.stack([intr.fx * truth[..., 0] / z + intr.cx, intr.fy * truth[..., 1] / z + intr.cy], axis=-1)
    vis = np.full((T, NUM_LANDMARKS), 0.95)
    radius2 = (0.05 * intr.width) ** 2
    for prox, dist in PROXIMAL_DISTAL_PAIRS:
        i, j = INDEX[prox], INDEX[dist]
        near = np.sum((pixels[:, i] - pixels[:, j]) ** 2, axis=-1) < radius2
        distal_front = near & (truth[:, j, 2] < truth[:, i, 2])
        raw[distal_front, i, 2] = raw[distal_front, j, 2]
        vis[distal_front, i] = np.minimum(vis[distal_front, i], 0.75)
        vis[near & ~distal_front, j] = 0.3
    starts = rng.random((T, NUM_LANDMARKS)) < dropout_rate
    for k, j in zip(*np.nonzero(starts), strict=True):
        vis[k : k + int(rng.integers(1, 6)), j] = 0.2
    return BenchInput(t, raw, vis, pixels, truth, intr, params.dims, "synthetic")


def rendered_measurements(cycles: int = 1, seed: int = 0, progress=None) -> BenchInput:
    """A rendered Motion I session (the evaluation's renderer and simulated detector)."""
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.operator.model import OperatorParams
    from akc_drake.operator.motions import make_motion
    from akc_drake.systems.depth_camera_source import render_session

    intr = scaled_intrinsics(640, 480)
    motion = make_motion("I", cycles=cycles, seed=seed)
    r = render_session(motion, intr, seed=seed, progress=progress)
    return BenchInput(
        np.asarray(r.t, float), np.asarray(r.raw, float), np.asarray(r.visibility, float),
        np.asarray(r.pixels, float), np.asarray(r.truth, float), intr, OperatorParams().dims, "rendered",
    )


# ================================================================================================ core
def bench_core(inp: BenchInput, s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """Per-frame time of every core stage on ``inp`` (both arms, 12 landmarks).

    Returns:
        ``{name: summarize(...)}`` in microseconds (``coik_<solver>`` in milliseconds), plus
        ``coik_status`` (share of frames per solver status) and ``coik_over_akc`` (ratio of medians).
    """
    from akc_drake.core.akc import ArmKinematicCorrector
    from akc_drake.core.coik import COIKConfig, COIKSolver, available_solvers
    from akc_drake.core.frames import RobotMapping, robot_targets
    from akc_drake.core.kalman import ConstantVelocityKF, ExtendedKalmanFilterCV
    from akc_drake.core.occlusion import occlusion_filter

    def say(msg):
        if progress is not None:
            progress(msg)

    out: dict = {}
    dt = inp.dt
    reps, wu = s.core_repeats, s.warmup_frames
    width = inp.intrinsics.width
    frames = list(zip(inp.raw, inp.pixels, inp.visibility, strict=True))

    say("core: occlusion filter")
    ns = time_calls(lambda f: occlusion_filter(f[0], f[1], f[2], width), frames, repeats=reps, warmup=wu)
    out["occlusion"] = summarize(ns / 1e3, "us")

    say("core: KF")
    kf = ConstantVelocityKF()
    zs = list(inp.accepted)
    ns = time_calls(lambda z: kf.step(z, dt), zs, repeats=reps, warmup=wu, before_pass=kf.reset)
    out["kf"] = summarize(ns / 1e3, "us")

    say("core: EKF")
    ekf = ExtendedKalmanFilterCV(inp.dims)
    ns = time_calls(lambda z: ekf.step(z, dt), zs, repeats=reps, warmup=wu, before_pass=ekf.reset)
    out["ekf"] = summarize(ns / 1e3, "us")

    say("core: AKC")
    akc = ArmKinematicCorrector(inp.dims)
    ns = time_calls(akc.correct, list(inp.kf), repeats=reps, warmup=wu, before_pass=akc.reset)
    out["akc"] = summarize(ns / 1e3, "us")

    say("core: control frames")
    mapping = RobotMapping.default()  # built once, as FrameMapper does
    ns = time_calls(lambda p: robot_targets(p, mapping), list(inp.akc), repeats=reps, warmup=wu)
    out["frames"] = summarize(ns / 1e3, "us")

    out["coik_status"] = {}
    out["coik_over_akc"] = {}
    n = min(s.coik_frames, inp.num_frames)
    # Start after the filter has converged (the first frames are initialisation).
    first = min(10, max(inp.num_frames - n, 0))
    poses = list(inp.kf[first : first + n])
    available = set(available_solvers())
    for name in ("snopt", "ipopt", "nlopt"):
        if name not in available:
            out[f"coik_{name}"] = summarize([], "ms")
            out["coik_status"][name] = "unavailable"
            continue
        say(f"core: COIK ({name})")
        solver = COIKSolver(inp.dims, COIKConfig(solver=name, warm_start=True))
        statuses: list[str] = []

        def solve(p, solver=solver, statuses=statuses):
            statuses.append(solver.solve(p).status)

        ns = time_calls(solve, poses, repeats=s.coik_repeats, warmup=min(wu, 3), before_pass=solver.reset)
        out[f"coik_{name}"] = summarize(ns / 1e6, "ms")
        timed = statuses[-len(ns) :]
        out["coik_status"][name] = {st: timed.count(st) / len(timed) for st in sorted(set(timed))}
        out["coik_over_akc"][name] = out[f"coik_{name}"]["median"] * 1e3 / out["akc"]["median"]
    return out


# ================================================================================================ systems
def _simulate_per_frame(diagram, num_frames: int, period: float, repeats: int) -> np.ndarray:
    """Wall time per frame (s) of ``repeats`` fresh simulations of ``diagram`` over ``num_frames`` frames."""
    from pydrake.systems.analysis import Simulator

    t_end = num_frames * period + 0.5e-3
    out = []
    for _ in range(repeats):
        sim = Simulator(diagram)
        sim.Initialize()
        t0 = time.perf_counter_ns()
        sim.AdvanceTo(t_end)
        out.append((time.perf_counter_ns() - t0) / 1e9 / num_frames)
    return np.array(out)


def _replay_diagram(landmarks, vis, pixels, period: float, stage=None,
                    connect: Sequence[str] = ("landmarks_C",), pull: str | None = None):
    """MeasurementReplay (-> ``stage``) (-> a VectorLogSink on ``pull``, which makes a stateless stage run
    once per frame)."""
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import VectorLogSink

    from akc_drake.systems.measurement_replay import MeasurementReplay

    b = DiagramBuilder()
    src = b.AddSystem(MeasurementReplay(landmarks, vis, pixels, period_s=period))
    if stage is not None:
        b.AddSystem(stage)
        for name in connect:
            b.Connect(src.GetOutputPort(name), stage.GetInputPort(name))
    if pull is not None:
        port = stage.GetOutputPort(pull) if stage is not None else src.GetOutputPort(pull)
        log = b.AddSystem(VectorLogSink(port.size(), period))
        b.Connect(port, log.get_input_port())
    return b.Build()


def bench_systems(inp: BenchInput, core: dict, s: BenchSettings,
                  progress: Callable[[str], None] | None = None) -> dict:
    """Each stage's LeafSystem alone, fed by a MeasurementReplay, stepped by a Simulator at the camera rate.

    Returns:
        ``{stage: {"per_frame_us", "net_us", "core_us", "overhead_us"}}`` (medians over the repeats) and
        ``"baseline"``: the replay alone. ``net_us`` = stage diagram - baseline diagram per frame;
        ``overhead_us`` = ``net_us`` - the core call's median.
    """
    from akc_drake.core.akc import WEIGHT_PRESETS
    from akc_drake.core.coik import COIKConfig
    from akc_drake.systems.arm_kinematic_correction import ArmKinematicCorrection
    from akc_drake.systems.constrained_optimization_ik import ConstrainedOptimizationIK
    from akc_drake.systems.frame_mapper import FrameMapper
    from akc_drake.systems.landmark_kalman_filter import LandmarkKalmanFilter
    from akc_drake.systems.occlusion_filter import OcclusionFilter

    period = inp.dt
    T = inp.num_frames
    vis, pix = inp.visibility, inp.pixels
    reps = s.system_repeats
    out: dict = {}

    def say(msg):
        if progress is not None:
            progress(msg)

    say("systems: baseline")
    base = np.median(_simulate_per_frame(_replay_diagram(inp.raw, vis, pix, period), T, period, reps))
    base_pull = np.median(
        _simulate_per_frame(_replay_diagram(inp.raw, vis, pix, period, pull="landmarks_C"), T, period, reps)
    )
    out["baseline"] = {"per_frame_us": base * 1e6, "with_log_sink_us": base_pull * 1e6}

    n_coik = min(T, max(s.coik_frames, 10))
    cases = [
        ("OcclusionFilter", lambda: OcclusionFilter(inp.intrinsics.width), inp.raw,
         ("landmarks_C", "visibility", "pixels"), "landmarks_C_accepted", "occlusion", T),
        ("LandmarkKalmanFilter(KF)", lambda: LandmarkKalmanFilter("KF", dims=inp.dims, period_s=period),
         inp.accepted, ("landmarks_C",), None, "kf", T),
        ("LandmarkKalmanFilter(EKF)", lambda: LandmarkKalmanFilter("EKF", dims=inp.dims, period_s=period),
         inp.accepted, ("landmarks_C",), None, "ekf", T),
        ("ArmKinematicCorrection", lambda: ArmKinematicCorrection(inp.dims, WEIGHT_PRESETS["Wb"],
                                                                  rate_hz=1.0 / period),
         inp.kf, ("landmarks_C",), None, "akc", T),
        ("ConstrainedOptimizationIK(snopt)", lambda: ConstrainedOptimizationIK(
            inp.dims, COIKConfig(solver="snopt"), period_s=period), inp.kf[:n_coik], ("landmarks_C",), None,
         "coik_snopt", n_coik),
        ("FrameMapper", lambda: FrameMapper(period_s=period), inp.akc, ("landmarks_C",), None, "frames", T),
    ]
    for name, make, data, ports, pull, core_key, n in cases:
        say(f"systems: {name}")
        diagram = _replay_diagram(data, vis[:n], pix[:n], period, make(), ports, pull)
        per = np.median(_simulate_per_frame(diagram, n, period, reps))
        core_us = core.get(core_key, {}).get("median", float("nan"))
        if core.get(core_key, {}).get("unit") == "ms":
            core_us *= 1e3
        net = per - (base_pull if pull else base)
        out[name] = {
            "per_frame_us": per * 1e6,
            "net_us": net * 1e6,
            "core_us": core_us,
            "overhead_us": net * 1e6 - core_us,
            "frames": int(n),
        }
    return out


# ================================================================================================ mocap
def bench_mocap(inp: BenchInput, s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """The mocap diagram (replay -> occlusion -> filter -> corrector, with the stage loggers) replaying
    ``inp``'s measurements, for KF+AKC (the headline), EKF+AKC and KF+COIK(snopt): frames per second."""
    from akc_drake.config import PipelineConfig
    from akc_drake.diagrams import Measurements, build_mocap_diagram

    meas = Measurements(inp.raw, inp.visibility, inp.pixels, inp.truth)
    out: dict = {}
    for filt, corr in (("KF", "AKC"), ("EKF", "AKC"), ("KF", "COIK")):
        label = f"{corr}({filt})"
        if progress is not None:
            progress(f"mocap diagram: {label}")
        cfg = PipelineConfig(filter=filt, corrector=corr)
        md = build_mocap_diagram(cfg, replay=meas, dims=inp.dims)
        reps = s.mocap_repeats if corr == "AKC" else 1
        per = _simulate_per_frame(md.diagram, inp.num_frames, inp.dt, reps)
        fps = 1.0 / per
        out[label] = {"fps": summarize(fps, "frames/s"), "us_per_frame": summarize(per * 1e6, "us"),
                      "frames": inp.num_frames, "repeats": reps}
    return out


# ================================================================================================ JSON
def write_json_atomic(path, data: dict) -> Path:
    """Write ``data`` as JSON to ``path`` atomically (temporary file in the same folder, then rename)."""
    return write_json(path, data)


def _settings_dict(s: BenchSettings) -> dict:
    return asdict(s)

# ================================================================================================ rendering
def bench_rendering(s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """Rendering + landmark extraction per frame at 640x480, in the diagram the pipeline runs
    (DepthCameraSource -> LandmarkExtractor, stepped frame by frame by a Simulator)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.diagrams import AddMeasurementSource

    if progress is not None:
        progress("rendering + extraction (640x480)")
    n = s.render_frames
    cycles = max(1, math.ceil((n + 2) / 60.0))  # Motion I cycles are 6 s, 60 frames at 10 Hz
    cfg = PipelineConfig(motion="I", cycles=cycles, camera=CameraConfig(width=640, height=480))
    period = 1.0 / cfg.camera.rate_hz
    builder = DiagramBuilder()
    AddMeasurementSource(builder, cfg)
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.Initialize()  # renders and extracts frame 0 (the warm-up)
    sim.AdvanceTo(period - 1e-6)
    per = np.empty(n)
    for k in range(1, n + 1):
        t0 = time.perf_counter_ns()
        sim.AdvanceTo(k * period + 0.5 * period)
        per[k - 1] = (time.perf_counter_ns() - t0) / 1e6
    ms = summarize(per, "ms")
    return {
        "ms_per_frame": ms,
        "fps": 1e3 / ms["median"] if ms["median"] > 0 else float("nan"),
        "width": 640,
        "height": 480,
        "frames": n,
    }


def bench_mediapipe(s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """MediaPipe PoseLandmarker per frame on rendered 640x480 colour frames, when the extra is installed.

    Returns:
        ``{"available": False, "reason": ...}`` without MediaPipe (or its model); else the timing summary
        (milliseconds, the ``detect`` call) and the share of frames in which it found a person.
    """
    import importlib.util

    if importlib.util.find_spec("mediapipe") is None:
        return {"available": False, "reason": "mediapipe is not installed (pip install -e .[mediapipe])"}
    from akc_drake.errors import UserError
    from akc_drake.io.mediapipe_detector import MediaPipeDetector

    try:
        detector = MediaPipeDetector()
    except (UserError, RuntimeError, OSError) as e:  # the optional extra is there but cannot run here
        return {"available": False, "reason": str(e)}
    from akc_drake.core.camera import CameraFrame
    from akc_drake.core.sim_detector import SimulatedDetector
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.operator.motions import make_motion
    from akc_drake.systems.depth_camera_source import render_session

    if progress is not None:
        progress("MediaPipe")
    intr = scaled_intrinsics(640, 480)
    n = s.mediapipe_frames + 1
    frames: list[CameraFrame] = []
    motion = make_motion("I", cycles=1, seed=0)
    duration = min(motion.duration, (n + 0.5) / intr.rate_hz)
    keep = motion.times <= motion.start + duration + 1e-9
    if keep.sum() < 2:
        keep[:2] = True
    from akc_drake.operator.motions import OperatorMotion

    short = OperatorMotion(motion.times[keep], motion.q_left[keep], motion.q_right[keep], name="I")
    render_session(short, intr, seed=0, detector=SimulatedDetector(seed=0), render_color=True,
                   frame_callback=lambda f: frames.append(f))
    frames = frames[:n]
    found = []

    def detect(f):
        found.append(detector.detect(f).person_found)

    with detector:
        ns = time_calls(detect, frames[1:], warmup=1)
    return {
        "available": True,
        "ms_per_frame": summarize(ns / 1e6, "ms"),
        "person_found_share": float(np.mean(found[1:])) if len(found) > 1 else float("nan"),
        "frames": len(ns),
        "model": str(detector.model_path),
    }


# ================================================================================================ teleop
class _QuietDrake:
    """Raise the ``drake`` logger to ERROR inside the block: the differential IK's status changes (a warning
    each time it gets stuck at a joint limit and recovers) are part of normal teleoperation, and the
    benchmark should print figures, not them."""

    def __enter__(self):
        self._logger = logging.getLogger("drake")
        self._level = self._logger.level
        self._logger.setLevel(logging.ERROR)
        return self

    def __exit__(self, *exc):
        self._logger.setLevel(self._level)


def _teleop(seconds: float, *, log_stages: bool, keep_history: bool, motion: str = "I"):
    from akc_drake.config import PipelineConfig
    from akc_drake.diagrams import build_teleop_diagram

    cycles = max(1, math.ceil(seconds / 6.0) + 1)
    cfg = PipelineConfig(source="sim", motion=motion, cycles=cycles)
    return build_teleop_diagram(cfg, log_stages=log_stages, keep_history=keep_history)


def bench_teleop(s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """The teleop diagram (rendering at 10 Hz, plant stepping) run for ``teleop_seconds`` simulated seconds:
    its realtime factor."""
    from pydrake.systems.analysis import Simulator

    if progress is not None:
        progress(f"teleop diagram ({s.teleop_seconds:g} s simulated)")
    t0 = time.perf_counter()
    td = _teleop(s.teleop_seconds, log_stages=True, keep_history=True)
    build_s = time.perf_counter() - t0
    sim = Simulator(td.diagram)
    sim.set_target_realtime_rate(0.0)
    t0 = time.perf_counter()
    sim.Initialize()
    init_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    with _QuietDrake():
        sim.AdvanceTo(s.teleop_seconds)
    wall = time.perf_counter() - t0
    return {
        "realtime_factor": s.teleop_seconds / wall,
        "simulated_s": s.teleop_seconds,
        "wall_s": wall,
        "build_s": build_s,
        "initialize_s": init_s,
        "plant_time_step_s": td.station.plant.time_step() if td.station is not None else None,
    }


def bench_memory(s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """RSS along a long simulated teleop run (stage loggers and monitor history off, as for a long run).

    RSS is sampled every ``memory_sample_s`` simulated seconds; growth is from the sample at
    ``memory_growth_from_s`` (minute 1 in the full run) to the last (minute 10).
    """
    from pydrake.systems.analysis import Simulator

    seconds = s.memory_seconds
    td = _teleop(seconds, log_stages=False, keep_history=False, motion="II")
    sim = Simulator(td.diagram)
    sim.set_target_realtime_rate(0.0)
    sim.Initialize()
    gc.collect()
    samples = [(0.0, rss_bytes())]
    n = max(1, int(round(seconds / s.memory_sample_s)))
    t0 = time.perf_counter()
    if progress is not None:
        progress(f"memory ({seconds:g} s simulated teleop)")
    with _QuietDrake():
        for k in range(1, n + 1):
            sim.AdvanceTo(k * s.memory_sample_s)
            samples.append((k * s.memory_sample_s, rss_bytes()))
    wall = time.perf_counter() - t0
    times = np.array([t for t, _ in samples])
    rss = np.array([r for _, r in samples], dtype=float)
    i0 = int(np.argmin(np.abs(times - s.memory_growth_from_s)))
    growth = (rss[-1] - rss[i0]) / rss[i0] * 100.0 if rss[i0] > 0 else float("nan")
    return {
        "simulated_s": seconds,
        "wall_s": wall,
        "realtime_factor": seconds / wall,
        "rss_mb": {"t_s": times.tolist(), "rss": (rss / 2**20).round(2).tolist()},
        "rss_start_mb": rss[0] / 2**20,
        "rss_from_mb": rss[i0] / 2**20,
        "rss_end_mb": rss[-1] / 2**20,
        "peak_rss_mb": rss.max() / 2**20,
        "process_peak_rss_mb": peak_rss_bytes() / 2**20,
        "growth_from_s": float(times[i0]),
        "growth_pct": growth,
    }


# ================================================================================================ the run
def _target_status(value, key: str) -> dict:
    op, bound = TARGETS[key]
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        met = None
    else:
        met = bool(value <= bound if op == "<=" else value >= bound if op == ">=" else value < bound)
    return {"value": value, "target": f"{op} {bound:g}", "met": met}


def paper_table3(result: dict) -> list[dict]:
    """The paper's Table III (averaged per-frame computation time, ms) beside ours (ms).

    The paper's figures are per-frame averages on a 13th-gen i9 with MediaPipe Holistic as its "Raw" stage;
    ours are medians and means of the same stage on this machine. "Raw" is our rendering + simulated
    detection + depth lookup (and MediaPipe alone when installed).
    """
    from akc_drake.resources import paper_results

    paper = paper_results()["table3_compute_time_ms"]
    core = result.get("core", {})
    rows = []

    def ours(summary: dict | None, scale: float) -> dict:
        if not summary or not summary.get("n"):
            return {"median": None, "mean": None, "max": None}
        return {k: summary[k] * scale for k in ("median", "mean", "max")}

    render = result.get("rendering", {}).get("ms_per_frame")
    mp = result.get("mediapipe", {}).get("ms_per_frame")
    raw_I, raw_II = paper["I"]["Raw"], paper["II"]["Raw"]
    rows.append({"stage": "Raw", "paper_I": raw_I, "paper_II": raw_II, "ours": ours(render, 1.0),
                 "ours_what": "render 640x480 + simulated detector + depth lookup"})
    if mp:
        rows.append({"stage": "Raw (MediaPipe only)", "paper_I": raw_I, "paper_II": raw_II,
                     "ours": ours(mp, 1.0), "ours_what": "MediaPipe PoseLandmarker on a 640x480 render"})
    rows.append({"stage": "KF", "paper_I": paper["I"]["KF"], "paper_II": paper["II"]["KF"],
                 "ours": ours(core.get("kf"), 1e-3), "ours_what": "constant-velocity KF, 12 landmarks"})
    rows.append({"stage": "EKF", "paper_I": None, "paper_II": None,
                 "ours": ours(core.get("ekf"), 1e-3), "ours_what": "bone-length EKF, 12 landmarks"})
    rows.append({"stage": "COIK", "paper_I": paper["I"]["COIK"], "paper_II": paper["II"]["COIK"],
                 "ours": ours(core.get("coik_snopt"), 1.0), "ours_what": "COIK, SNOPT, warm start"})
    rows.append({"stage": "AKC", "paper_I": paper["I"]["AKC"], "paper_II": paper["II"]["AKC"],
                 "ours": ours(core.get("akc"), 1e-3), "ours_what": "AKC, both arms"})
    return rows


def run_bench(settings: BenchSettings | None = None, progress: Callable[[str], None] | None = None) -> dict:
    """Run every benchmark in this process and return the JSON-able result (see the module docstring)."""
    s = settings or BenchSettings.full()
    start = time.perf_counter()
    result: dict = {"format": BENCH_FORMAT, "quick": s.quick, "settings": asdict(s)}
    result["machine"] = machine_info()

    def section(name: str, fn: Callable[[], dict]) -> dict:
        t0 = time.perf_counter()
        out = fn()
        result.setdefault("section_wall_s", {})[name] = time.perf_counter() - t0
        result[name] = out
        return out

    # Input: a rendered Motion I session (its render/extract times are the renderer's own breakdown).
    def make_input() -> dict:
        if progress is not None:
            progress("input: rendering Motion I")
        try:
            inp = rendered_measurements(cycles=s.cycles)
        except (ImportError, RuntimeError) as e:  # no renderer: synthetic measurements instead
            inp = synthetic_measurements(cycles=s.cycles)
            inp.kind = f"synthetic (rendering failed: {e})"
        make_input.inp = inp.run_stages()
        return {"kind": inp.kind, "frames": inp.num_frames, "rate_hz": 1.0 / inp.dt,
                "width": inp.intrinsics.width, "height": inp.intrinsics.height}

    section("input", make_input)
    inp = make_input.inp
    core = section("core", lambda: bench_core(inp, s, progress))
    section("systems", lambda: bench_systems(inp, core, s, progress))
    mocap = section("mocap_diagram", lambda: bench_mocap(inp, s, progress))
    render = section("rendering", lambda: bench_rendering(s, progress))
    section("mediapipe", lambda: bench_mediapipe(s, progress))
    teleop = section("teleop", lambda: bench_teleop(s, progress))
    memory = section("memory", lambda: bench_memory(s, progress))

    result["load_average_at_end"] = _load_average()
    # The contract keys (DESIGN.md) and the other headline figures.
    coik = {name: core[f"coik_{name}"]["median"] for name in ("snopt", "ipopt", "nlopt")}
    result.update(
        akc_us_per_frame=core["akc"]["median"],
        kf_us_per_frame=core["kf"]["median"],
        ekf_us_per_frame=core["ekf"]["median"],
        coik_ms_per_frame=coik,
        mocap_diagram_fps=mocap["AKC(KF)"]["fps"]["median"],
        teleop_realtime_factor=teleop["realtime_factor"],
        akc_us_per_frame_max=core["akc"]["max"],
        kf_us_per_frame_max=core["kf"]["max"],
        ekf_us_per_frame_max=core["ekf"]["max"],
        coik_ms_per_frame_max={name: core[f"coik_{name}"]["max"] for name in coik},
        coik_over_akc=core["coik_over_akc"],
        render_extract_ms_per_frame=render["ms_per_frame"]["median"],
        render_extract_fps=render["fps"],
        mediapipe_ms_per_frame=(result["mediapipe"]["ms_per_frame"]["median"]
                                if result["mediapipe"].get("available") else None),
        memory_growth_pct=memory["growth_pct"],
        peak_rss_mb=memory["peak_rss_mb"],
    )
    result["targets"] = {
        "akc_us_per_frame": _target_status(result["akc_us_per_frame"], "akc_us_per_frame"),
        "kf_us_per_frame": _target_status(result["kf_us_per_frame"], "kf_us_per_frame"),
        "ekf_us_per_frame": _target_status(result["ekf_us_per_frame"], "ekf_us_per_frame"),
        "coik_snopt_ms_per_frame": _target_status(coik["snopt"], "coik_snopt_ms_per_frame"),
        "coik_over_akc_snopt": _target_status(core["coik_over_akc"].get("snopt"), "coik_over_akc_snopt"),
        "mocap_diagram_fps": _target_status(result["mocap_diagram_fps"], "mocap_diagram_fps"),
        "render_extract_fps": _target_status(result["render_extract_fps"], "render_extract_fps"),
        "teleop_realtime_factor": _target_status(result["teleop_realtime_factor"], "teleop_realtime_factor"),
        "memory_growth_pct": _target_status(result["memory_growth_pct"], "memory_growth_pct"),
    }
    result["paper_table3_ms"] = paper_table3(result)
    result["elapsed_s"] = time.perf_counter() - start
    return result


# ================================================================================================ report
def _f(v, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}g}"


_MET = {True: "yes", False: "NO", None: "-"}


def format_report(result: dict) -> str:
    """A plain-text summary: the figures with median, max and target, then Table III beside the paper's."""
    core, targets = result["core"], result["targets"]
    m = result["machine"]
    lines = [
        f"akc-drake bench{' --quick' if result['quick'] else ''}: {m['cpu']}, {m['cpus_usable']} cores, "
        f"drake {m['drake']}, python {m['python']}; input: {result['input']['kind']} "
        f"({result['input']['frames']} frames)",
        "",
        f"{'figure':<46}{'median':>10}{'max':>10}  {'target':<9}{'met':>4}",
    ]

    def line(name: str, med, mx=None, target_key: str | None = None) -> None:
        t = targets.get(target_key, {}) if target_key else {}
        met = _MET[t.get("met")] if t else ""
        lines.append(f"{name:<46}{_f(med):>10}{_f(mx):>10}  {t.get('target', ''):<9}{met:>4}")

    def stat(name: str, summary: dict | None, target_key: str | None = None) -> None:
        summary = summary or {}
        line(name, summary.get("median"), summary.get("max"), target_key)

    stat("core: occlusion filter [us]", core["occlusion"])
    stat("core: KF [us]", core["kf"], "kf_us_per_frame")
    stat("core: EKF [us]", core["ekf"], "ekf_us_per_frame")
    stat("core: AKC, both arms [us]", core["akc"], "akc_us_per_frame")
    stat("core: control frames, eq. 17 [us]", core["frames"])
    for name in ("snopt", "ipopt", "nlopt"):
        key = "coik_snopt_ms_per_frame" if name == "snopt" else None
        stat(f"core: COIK {name} [ms]", core[f"coik_{name}"], key)
    for name, ratio in core["coik_over_akc"].items():
        line(f"COIK {name} / AKC [x]", ratio, None, "coik_over_akc_snopt" if name == "snopt" else None)
    lines += ["", f"{'stage system alone in a Simulator [us/frame]':<46}{'total':>10}{'net':>10}{'core':>10}"
                  f"{'overhead':>10}"]
    for name, v in result["systems"].items():
        if name == "baseline":
            lines.append(f"{'MeasurementReplay (the baseline)':<46}{_f(v['per_frame_us']):>10}")
        else:
            lines.append(f"{name:<46}{_f(v['per_frame_us']):>10}{_f(v['net_us']):>10}{_f(v['core_us']):>10}"
                         f"{_f(v['overhead_us']):>10}")
    lines.append("")
    for label, v in result["mocap_diagram"].items():
        stat(f"mocap diagram replay, {label} [frames/s]", v["fps"],
             "mocap_diagram_fps" if label == "AKC(KF)" else None)
    r = result["rendering"]
    stat("rendering + extraction 640x480 [ms]", r["ms_per_frame"])
    line("rendering + extraction 640x480 [frames/s]", r["fps"], None, "render_extract_fps")
    mp = result["mediapipe"]
    if mp.get("available"):
        stat("MediaPipe PoseLandmarker 640x480 [ms]", mp["ms_per_frame"])
    else:
        lines.append(f"{'MediaPipe':<46}skipped: {mp.get('reason', '')}")
    line("teleop diagram, rendering at 10 Hz [x realtime]", result["teleop"]["realtime_factor"], None,
         "teleop_realtime_factor")
    mem = result["memory"]
    line(f"memory: RSS growth {_f(mem['growth_from_s'])}-{_f(mem['simulated_s'])} s simulated [%]",
         mem["growth_pct"], None, "memory_growth_pct")
    line("memory: peak RSS during that run [MB]", mem["peak_rss_mb"])
    line("memory run: realtime factor [x]", mem["realtime_factor"])
    lines += [
        "",
        "Table III, per-frame computation time [ms]: the paper's (13th-gen i9, MediaPipe Holistic) and ours",
        f"{'stage':<22}{'paper I':>9}{'paper II':>10}{'ours med':>11}{'ours mean':>11}{'ours max':>11}",
    ]
    for rr in result["paper_table3_ms"]:
        o = rr["ours"]
        lines.append(f"{rr['stage']:<22}{_f(rr['paper_I'], 4):>9}{_f(rr['paper_II'], 4):>10}"
                     f"{_f(o['median']):>11}{_f(o['mean']):>11}{_f(o['max']):>11}")
    lines += ["", f"total {result['elapsed_s']:.1f} s"]
    return "\n".join(lines)
