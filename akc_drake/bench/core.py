"""Speed and memory benchmark of every stage, run side by side in one process (``akc-drake bench``).

Every figure is measured in the same run on the same machine, after a warm-up, with several repeats, and
reported as a median and a maximum (plus mean, 95th percentile and sample count):

* **core, per frame** (both arms, 12 landmarks): the occlusion filter, the constant-velocity KF, the EKF,
  AKC, AKC+ (with the KF's covariance and the occlusion filter's measurement, as the evaluation runs it),
  COIK with each solver (SNOPT, IPOPT, NLopt; warm start) and the control frames; and the ratio COIK / AKC
  of the medians;
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
import os
import platform
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from akc_drake import compiled
from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, PROXIMAL_DISTAL_PAIRS, BodyDimensions
from akc_drake.fileio import write_json

#: Speed targets on the reference machine (2 cores, no GPU): figure key -> (comparison, bound).
TARGETS: dict[str, tuple[str, float]] = {
    "akc_us_per_frame": ("<=", 25.0),
    "akc_plus_us_per_frame": ("<=", 25.0),
    "kf_us_per_frame": ("<=", 20.0),
    "ekf_us_per_frame": ("<=", 60.0),
    "coik_snopt_ms_per_frame": ("<=", 3.0),
    "coik_over_akc_snopt": (">=", 50.0),
    "mocap_diagram_fps": (">=", 500.0),
    "render_extract_fps": (">=", 25.0),
    "teleop_realtime_factor": (">=", 2.0),
    "memory_growth_pct": ("<", 5.0),
    "skinning_ms_per_frame": ("<=", 2.0),
    "skinned_mediapipe_fps": (">=", 10.0),
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
        body, detector: the operator and the detector of the rendered input session (``--body``,
            ``--detector``); the skinned-body figures always use the skinned body with MediaPipe.
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
    body: str = "primitive"
    detector: str = "sim"

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
        # AKC+'s per-frame modules: compiled with Cython or run as source (akc_drake/compiled.py)
        "akc_plus_modules": compiled.build_state(),
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
        accepted: occlusion-filter output. kf: KF estimates. kf_var: the KF's posterior variance of each
        coordinate. ekf: EKF estimates. akc: AKC(KF) output.
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
    kf_var: np.ndarray | None = None
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
        held = np.full(self.raw.shape[1:], np.nan)  # (the filter's state over the sequence)
        self.accepted = np.stack([occlusion_filter(z, p, v, w, held=held)[0] for z, p, v in frames])
        kf, ekf = ConstantVelocityKF(), ExtendedKalmanFilterCV(self.dims)
        dt = self.dt
        kf_out, kf_var = [], []
        for z in self.accepted:
            kf_out.append(kf.step(z, dt))
            kf_var.append(kf.position_variance)
        self.kf, self.kf_var = np.stack(kf_out), np.stack(kf_var)
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


def rendered_measurements(
    cycles: int = 1, seed: int = 0, progress=None, body: str = "primitive", detector: str = "sim"
) -> BenchInput:
    """A rendered Motion I session (the evaluation's renderer; the simulated detector by default)."""
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.operator.model import OperatorParams
    from akc_drake.operator.motions import make_motion
    from akc_drake.systems.depth_camera_source import render_session

    intr = scaled_intrinsics(640, 480)
    motion = make_motion("I", cycles=cycles, seed=seed)
    r = render_session(motion, intr, seed=seed, progress=progress, body=body, detector=detector)
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
    held = np.full(inp.raw.shape[1:], np.nan)
    ns = time_calls(lambda f: occlusion_filter(f[0], f[1], f[2], width, held=held), frames, repeats=reps,
                    warmup=wu)
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

    say("core: AKC+")
    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus

    plus = ArmKinematicCorrectorPlus(inp.dims)
    # As the evaluation runs it: the KF's output, the occlusion filter's measurement and the KF's variance.
    triples = list(zip(inp.kf, inp.accepted, inp.kf_var, strict=True))
    ns = time_calls(lambda x: plus.correct(x[0], x[1], x[2]), triples, repeats=reps, warmup=wu,
                    before_pass=plus.reset)
    out["akc_plus"] = summarize(ns / 1e3, "us")

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



# ================================================================================================ JSON
def write_json_atomic(path, data: dict) -> Path:
    """Write ``data`` as JSON to ``path`` atomically (temporary file in the same folder, then rename)."""
    return write_json(path, data)


def _settings_dict(s: BenchSettings) -> dict:
    return asdict(s)

