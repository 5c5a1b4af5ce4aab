"""A long simulated teleoperation session with random tracking loss (and, optionally, detector garbage),
watching what must not drift: memory, NaN commands, joint speeds, filter covariances (``akc-drake soak``).

The operator's motion (``--motion``, one 6 s cycle) is rendered once by the simulated RGB-D camera; the
measurements are repeated for ``--minutes`` (the motions are periodic), ``--dropout`` of the frames are lost
in bursts of 0.5-3 s (:func:`akc_drake.faults.inject_dropouts`: the person leaves, an arm leaves the frame,
some landmarks vanish) and ``--garbage`` of the frames are corrupted
(:func:`akc_drake.faults.inject_garbage`).
The teleop diagram replays them with its long-run settings (no per-stage loggers, no monitor history), and
every ``--sample-s`` simulated seconds the process's resident memory and the filter's largest position
variance are sampled.

JSON (``--json``): ``simulated_s``, ``frames``, ``wall_s``, ``realtime_factor``, ``dropout_share``,
``garbage_share``, ``nan_commands``, ``max_joint_speed_ratio``, ``joint_velocity_limit_exceeded``,
``tracking_lost_share``, ``ee_tracking_error_cm`` (median per side), ``rss_mb`` (samples),
``rss_growth_mb`` (from the end of the first minute, or of the first quarter of a shorter run, to the end),
``max_position_variance_m2`` (samples), ``checks`` (each with ``ok``) and ``ok``.
"""

from __future__ import annotations

import gc
import math
import sys
import time

import numpy as np

from akc_drake.bench import rss_bytes
from akc_drake.errors import UserError
from akc_drake.robot.ik_status import quiet_drake_warnings

#: Growth of the resident memory (MB) from the end of the warm-up to the end that a soak accepts.
MAX_RSS_GROWTH_MB = 25.0
#: The largest filter position variance (m^2) a soak accepts: a held landmark's uncertainty grows, but
#: stays bounded (see :class:`~akc_drake.core.kalman.ConstantVelocityKF`).
MAX_POSITION_VARIANCE_M2 = 1.0e4


def _check_share(name: str, value) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= 1.0):
        raise UserError(f"--{name} must be a share of frames in [0, 1], got {value!r}")
    return float(value)


def soak_measurements(minutes: float, *, motion: str = "I", dropout: float = 0.3, garbage: float = 0.0,
                      seed: int = 0, config=None):
    """The replayed measurements of a soak: one rendered cycle repeated, with dropouts and garbage.

    Returns:
        ``(Measurements, info)`` with ``info`` = ``{"frames", "dropout_share", "garbage_share", "bursts"}``.
    """
    from akc_drake import diagrams
    from akc_drake.config import PipelineConfig
    from akc_drake.faults import inject_dropouts, inject_garbage
    from akc_drake.operator.motions import make_motion
    from akc_drake.systems.depth_camera_source import render_session

    cfg = (config or PipelineConfig(motion=motion, seed=seed)).validate()
    rate = float(cfg.camera.rate_hz)
    intrinsics, placement, noise = diagrams.sim_camera(cfg)
    one = make_motion(motion, cycles=1, seed=seed)
    rendered = render_session(one, intrinsics, camera_pose=placement, noise=noise, seed=seed)
    per_cycle = len(rendered.t) - 1  # the last frame of a cycle is the first of the next
    n = max(int(round(minutes * 60.0 * rate)), 1)
    reps = -(-n // per_cycle)

    def tile(a):
        return np.concatenate([np.asarray(a)[:per_cycle]] * reps)[:n]

    meas = diagrams.Measurements(tile(rendered.raw), tile(rendered.visibility), tile(rendered.pixels),
                                 tile(rendered.truth))
    start = min(int(rate), n)  # a clean first second: the filter starts on a person
    meas, plan = inject_dropouts(meas, dropout, seed=seed, rate_hz=rate, start_frame=start)
    garbage_share = 0.0
    if garbage > 0.0:
        meas, log = inject_garbage(meas, garbage, seed=seed + 1, intrinsics=intrinsics, start_frame=start)
        garbage_share = float(log.frames.mean())
    info = {"frames": n, "dropout_share": plan.fraction, "garbage_share": garbage_share,
            "bursts": len(plan.bursts)}
    return meas, info


def _max_position_variance(kf, root) -> float:
    """The filter's largest position variance (arm covariance included for the EKF), m^2."""
    if kf is None:
        return 0.0
    f = kf.filter
    f.set_state_vector(kf.GetMyContextFromRoot(root).get_discrete_state(kf.filter_state_index()).get_value())
    v = np.asarray(f.position_variance, dtype=float)
    worst = float(np.nanmax(v)) if np.isfinite(v).any() else 0.0
    if hasattr(f, "arm_covariance"):
        worst = max(worst, float(np.max(np.diag(f.arm_covariance))))
    return worst


def run_soak(minutes: float = 30.0, *, motion: str = "I", dropout: float = 0.3, garbage: float = 0.0,
             seed: int = 0, sample_s: float = 10.0, progress: bool = False, config=None) -> dict:
    """Run a soak (see the module docstring) and return its summary (the JSON written by ``--json``).

    Args:
        minutes: simulated duration.
        motion: ``I`` or ``II``.
        dropout: share of frames lost in bursts, in [0, 1].
        garbage: share of frames with detector garbage, in [0, 1].
        seed: seeds the rendering, the dropouts and the garbage.
        sample_s: simulated seconds between two samples of memory and covariance.
        progress: a progress bar on stderr.
        config: the :class:`~akc_drake.config.PipelineConfig` (default: its defaults with ``motion``).
    """
    from pydrake.systems.analysis import Simulator
    from tqdm import tqdm

    from akc_drake import diagrams
    from akc_drake.config import PipelineConfig

    if not (isinstance(minutes, (int, float)) and math.isfinite(minutes) and minutes > 0):
        raise UserError(f"--minutes must be a positive number, got {minutes!r}")
    dropout, garbage = _check_share("dropout", dropout), _check_share("garbage", garbage)
    if not (math.isfinite(sample_s) and sample_s > 0):
        raise UserError(f"--sample-s must be a positive number of seconds, got {sample_s!r}")
    cfg = (config or PipelineConfig(motion=motion, seed=seed)).validate()
    t0 = time.perf_counter()
    meas, info = soak_measurements(minutes, motion=motion, dropout=dropout, garbage=garbage, seed=seed,
                                   config=cfg)
    render_s = time.perf_counter() - t0
    td = diagrams.build_teleop_diagram(cfg, replay=meas, keep_history=False, log_stages=False)
    kf = td.systems.get("filter")
    sim = Simulator(td.diagram)
    sim.set_target_realtime_rate(0.0)
    sim.Initialize()
    root = sim.get_context()
    period = diagrams.camera_period(cfg)
    t_end = info["frames"] * period
    n = max(int(math.ceil(t_end / sample_s)), 1)
    warmup_s = min(60.0, 0.25 * t_end)
    gc.collect()
    samples = {"t_s": [0.0], "rss_mb": [rss_bytes() / 2**20], "max_position_variance_m2": [0.0]}
    t_wall = time.perf_counter()
    with quiet_drake_warnings():  # (the IK's "stuck at a joint limit" notices are part of teleoperation)
        with tqdm(total=n, desc="soak", unit="sample", disable=not progress, file=sys.stderr,
                  leave=False) as bar:
            for k in range(1, n + 1):
                t = min(k * sample_s, t_end)
                sim.AdvanceTo(t)
                samples["t_s"].append(t)
                samples["rss_mb"].append(rss_bytes() / 2**20)
                samples["max_position_variance_m2"].append(_max_position_variance(kf, root))
                bar.update(1)
    wall = time.perf_counter() - t_wall
    m = td.monitor
    t_s = np.asarray(samples["t_s"])
    rss = np.asarray(samples["rss_mb"])
    i0 = int(np.argmin(np.abs(t_s - warmup_s)))
    growth = float(rss[-1] - rss[i0])
    max_var = float(np.max(samples["max_position_variance_m2"]))
    checks = {
        "nan_commands": {"value": m.nan_commands, "limit": 0, "ok": m.nan_commands == 0},
        "max_joint_speed_ratio": {"value": m.max_speed_ratio, "limit": 1.0,
                                  "ok": m.max_speed_ratio <= 1.0 + 1e-9},
        "max_joint_acceleration_ratio": {"value": m.max_acceleration_ratio, "limit": 1.05,
                                         "ok": m.max_acceleration_ratio <= 1.05},
        "rss_growth_mb": {"value": growth, "limit": MAX_RSS_GROWTH_MB, "ok": growth <= MAX_RSS_GROWTH_MB},
        "max_position_variance_m2": {"value": max_var, "limit": MAX_POSITION_VARIANCE_M2,
                                     "ok": math.isfinite(max_var) and max_var <= MAX_POSITION_VARIANCE_M2},
    }
    errors = {s: m.ee_errors(s) for s in ("left", "right")}
    return {
        "config": {"minutes": minutes, "motion": motion, "dropout": dropout, "garbage": garbage, "seed": seed,
                   "filter": cfg.filter, "corrector": cfg.corrector, "rate_hz": cfg.camera.rate_hz},
        "simulated_s": t_end,
        "frames": info["frames"],
        "bursts": info["bursts"],
        "dropout_share": info["dropout_share"],
        "garbage_share": info["garbage_share"],
        "render_s": render_s,
        "wall_s": wall,
        "realtime_factor": t_end / wall if wall > 0 else None,
        "nan_commands": m.nan_commands,
        "max_joint_speed_ratio": m.max_speed_ratio,
        "joint_velocity_limit_exceeded": not checks["max_joint_speed_ratio"]["ok"],
        "max_joint_acceleration_ratio": m.max_acceleration_ratio,
        "tracking_lost_share": m.tracking_lost_samples / max(m.samples, 1),
        "ee_tracking_error_cm": {s: float(np.median(e) * 100) if len(e) else None for s, e in errors.items()},
        "rss_mb": {"t_s": t_s.tolist(), "rss": rss.round(2).tolist()},
        "rss_growth_mb": growth,
        "rss_growth_from_s": float(t_s[i0]),
        "max_position_variance_m2": {"t_s": t_s.tolist(), "value": samples["max_position_variance_m2"]},
        "checks": checks,
        "ok": all(c["ok"] for c in checks.values()),
    }
