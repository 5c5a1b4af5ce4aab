"""A run's summary (the ``akc-drake run --json`` keys, see DESIGN.md) and its per-frame poses (``poses.npz``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import ARM_JOINTS, LANDMARKS
from akc_drake.fileio import atomic_save_npz
from akc_drake.pipeline.inputs import source_kind
from akc_drake.pipeline.runner import LATENCY_STAGES


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
            name: float(np.nanmean(vis[person, j])) if person.any() else None for j, name in enumerate(LANDMARKS)
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
        out["arm_length_range_cm"][stage] = {k: (None if not np.isfinite(v) else 100.0 * v) for k, v in rng.items()}
    if np.isfinite(log.truth).any():
        out["errors"] = {stage: joint_errors(getattr(log, stage), log.truth, ARM_JOINTS) for stage in stages}
    return out


def run_summary(cfg, inputs, built, result, *, teleop: bool = False, depth_m: float | None = None) -> dict:
    """The summary of one run (``akc-drake run --json``): configuration, detector, dimensions, stop reason,
    :func:`summarize`'s figures, ``latency_ms`` per stage and, for a teleop run, the robot's tracking."""
    log, wall = result.log, result.wall_s
    summary = {
        "config": {
            "source": cfg.source,
            "motion": cfg.motion if source_kind(cfg.source) == "sim" else None,
            "joint_names": dict(cfg.joint_names) if cfg.joint_names and source_kind(cfg.source) == "sim" else None,
            "cycles": cfg.cycles,
            "seed": cfg.seed,
            "filter": cfg.filter,
            "corrector": cfg.corrector,
            "weights": cfg.weights,
            "rate_hz": cfg.camera.rate_hz,
            "width": cfg.camera.width,
            "height": cfg.camera.height,
            "depth_m": depth_m,
            "teleop": bool(teleop),
        },
        "detector": inputs.detector.name,
        "dims": built.dims.as_dict(),
        "dims_origin": inputs.dims_origin,
        "stop_reason": result.stop_reason,
        **summarize(log, wall_s=wall, visibility_threshold=cfg.visibility_threshold),
        "latency_ms": latency_summary(result.latency_s),
    }
    if teleop:
        m = built.monitor
        summary["latency_note"] = (
            "with --teleop, source, filter and mapper include the robot's steps at the same instants"
        )
        summary["teleop"] = {
            "nan_commands": m.nan_commands,
            "max_joint_speed_ratio": m.max_speed_ratio,
            "max_joint_acceleration_ratio": m.max_acceleration_ratio,
            "arm_limits": _arm_limits(built),
            "ee_tracking_error_cm": {
                s: float(np.median(m.ee_errors(s)) * 100) if len(m.ee_errors(s)) else None for s in ("left", "right")
            },
            "realtime_factor": (result.frames / cfg.camera.rate_hz) / wall if wall > 0 else None,
            "ik": result.ik,
        }
    return summary


def _arm_limits(built) -> dict:
    """Per side, the limits the commands kept to: ``motion_limiter`` (whether the arm had one) and
    ``acceleration`` / ``jerk`` (rad/s^2, rad/s^3, joints 1-7; without a limiter the acceleration limits the
    monitor measured against, and no jerk)."""
    out = {}
    for side, arm in built.ik.items():
        if arm.limiter is not None:
            _, acc, jerk = arm.limiter.limits
            out[side] = {"motion_limiter": True, "acceleration": acc.tolist(), "jerk": jerk.tolist()}
        else:
            out[side] = {"motion_limiter": False, "acceleration": built.monitor.acceleration_limits[side].tolist(),
                         "jerk": None}
    return out


def save_poses(out_dir: str | Path, log, dims=None, up_C=None) -> Path:
    """Write ``out_dir/poses.npz`` atomically: ``t``, ``raw``, ``accepted``, ``filtered``, ``corrected``,
    ``truth``, ``visibility``, ``names`` (NaN where missing) and, given the run's ``BodyDimensions``, ``dims``
    (``[LUA, LLA, RUA, RLA, SW]``, what ``akc-drake export`` builds a BVH and RTS corrections on) and ``up_C`` (the
    up direction in the camera frame from an IMU, when the source has one). Called after a
    partial run too."""
    extra = {} if dims is None else {"dims": dims.as_array()}
    if up_C is not None:
        extra["up_C"] = np.asarray(up_C, dtype=float)
    return atomic_save_npz(
        Path(out_dir) / "poses.npz",
        t=log.t,
        raw=log.raw,
        accepted=log.accepted,
        filtered=log.estimated,
        corrected=log.corrected,
        truth=log.truth,
        visibility=log.visibility,
        names=np.array(LANDMARKS),
        **extra,
    )
