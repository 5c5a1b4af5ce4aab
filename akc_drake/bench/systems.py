"""Benchmarks of the stage LeafSystems alone (net and Drake overhead) and of the mocap diagram replaying
measurements (no rendering).
"""


from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from akc_drake.bench.core import BenchInput, BenchSettings, summarize


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
        ("OcclusionFilter", lambda: OcclusionFilter(inp.intrinsics.width, period_s=period), inp.raw,
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


