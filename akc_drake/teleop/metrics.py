"""The demo's figures: tracking errors, the error to the operator, control-frame jitter, IK counts."""

from __future__ import annotations

import math

import numpy as np

from akc_drake.teleop.scenario import SETTLING_S, SIDES, TeleopRun

# ------------------------------------------------------------------------------------------------------------
# Metrics


def _median_cm(values) -> float | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.median(v) * 100.0) if v.size else None


def _p95_cm(values) -> float | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, 95) * 100.0) if v.size else None


def pooled_jitter(sequences: list[np.ndarray], period_s: float) -> tuple[float, float]:
    """:func:`~akc_drake.core.frames.frame_jitter` over several ``(T, 4, 4)`` sequences, no pair spanning two.

    Returns:
        ``(rms angular speed rad/s, rms linear speed m/s)``; NaN when there is no consecutive pair.
    """
    from akc_drake.core.frames import frame_jitter

    parts = []
    for X in sequences:
        parts += [np.asarray(X, dtype=float).reshape(-1, 4, 4), np.full((1, 4, 4), np.nan)]
    if not parts:
        return math.nan, math.nan
    return frame_jitter(np.concatenate(parts), period_s)


def run_metrics(runs: list[TeleopRun], settling_s: float = SETTLING_S) -> dict:
    """The figures of one run, or pooled over several (samples concatenated; jitter over consecutive frames of
    the same run only).

    Returns:
        A dict: ``frames``; per side (``{"left", "right"}``): ``ee_tracking_error_cm`` (median after
        ``settling_s``), ``ee_tracking_error_cm_with_settling``, ``ee_tracking_error_p95_cm``,
        ``ee_reachable_error_cm`` (to the target after the IK's reach guard), ``ee_operator_error_cm`` (to the
        operator's true mapped wrist), ``target_operator_rotation_error_deg`` (median angle between the target's
        rotation and the operator's true mapped wrist's), ``target_operator_error_unsmoothed_cm`` (the same median
        for the unsmoothed targets), ``target_operator_offset_cm`` (the length of the component-wise median
        target-minus-operator vector: the error's constant part), ``target_operator_error_unclipped_cm`` (and
        ``_p95_cm``: the error over the frames whose target the workspace did not clip),
        ``target_unreachable_share``, ``jitter`` and ``operator_jitter`` (the true mapped wrist's, for reference;
        each ``angular_rad_s``, ``linear_m_s``); totals:
        ``position_limit_hits``, ``velocity_limit_hits``, ``acceleration_limit_hits``, ``max_joint_speed_ratio``,
        ``max_joint_acceleration_ratio``, ``ik_steps``, ``ik_failures``, ``nan_commands``;
        ``tracking_lost_share``, ``dropout_frames``, ``sim_s``, ``wall_s``, ``realtime_factor``.
    """
    if not runs:
        raise ValueError("run_metrics: no runs")
    period = runs[0].period_s
    after = [r.frame_t >= settling_s for r in runs]

    def per_frame(fn, side: str) -> np.ndarray:
        return np.concatenate([fn(r, side)[a] for r, a in zip(runs, after, strict=True)])

    keys = ("err", "err_all", "p95", "reach", "op", "unreach", "jang", "jlin", "oang", "olin", "top", "top95")
    keys += ("lag", "rlag", "cross", "clip", "rot", "top_raw", "offset", "top_in", "top_in95")
    v: dict[str, dict] = {k: {} for k in keys}
    for side in SIDES:
        e_after = np.concatenate([r.errors[side][r.error_t[side] >= settling_s] for r in runs])
        v["err"][side] = _median_cm(e_after)
        v["p95"][side] = _p95_cm(e_after)
        v["err_all"][side] = _median_cm(np.concatenate([r.errors[side] for r in runs]))
        v["reach"][side] = _median_cm(
            per_frame(lambda r, s: np.linalg.norm(r.reachable_target[s] - r.ee[s], axis=1), side)
        )
        v["op"][side] = _median_cm(
            per_frame(lambda r, s: np.linalg.norm(r.operator[s][:, :3, 3] - r.ee[s], axis=1), side)
        )
        top = per_frame(lambda r, s: np.linalg.norm(r.operator[s][:, :3, 3] - r.target[s][:, :3, 3], axis=1), side)
        v["top"][side] = _median_cm(top)
        v["top95"][side] = _p95_cm(top)
        # The same on the frames whose target the workspace did not clip (clipping reported apart from error).
        inside = ~per_frame(lambda r, s: np.asarray(r.clipped.get(s, np.zeros(r.frames, bool)), bool), side)
        v["top_in"][side], v["top_in95"][side] = _median_cm(top[inside]), _p95_cm(top[inside])
        # The error's parts: the unsmoothed targets' (same torso and clip: the smoothing's share is the difference)
        # and its constant part, the length of the component-wise median error vector (a calibration or depth
        # offset, which no smoothing removes; the median, so a few outliers, e.g. Raw's, do not make one).
        v["top_raw"][side] = _median_cm(per_frame(
            lambda r, s: np.linalg.norm(r.operator[s][:, :3, 3] - r.unsmoothed[s][:, :3, 3], axis=1)
            if r.unsmoothed and s in r.unsmoothed else np.full(r.frames, np.nan), side))
        d = per_frame(lambda r, s: r.target[s][:, :3, 3] - r.operator[s][:, :3, 3], side)
        d = d[np.all(np.isfinite(d), axis=1)]
        v["offset"][side] = float(np.linalg.norm(np.median(d, axis=0)) * 100.0) if len(d) else None
        rot = per_frame(_rotation_error_rad, side)
        rot = rot[np.isfinite(rot)]
        v["rot"][side] = float(np.degrees(np.median(rot))) if rot.size else None
        v["lag"][side] = _added_latency_ms(runs, side, after)
        v["rlag"][side] = _added_latency_ms(runs, side, after, rotation=True)
        v["cross"][side] = int(sum(_midline_crossings(r, side, a) for r, a in zip(runs, after, strict=True)))
        clip = [r.clipped[side][a] for r, a in zip(runs, after, strict=True) if side in r.clipped]
        v["clip"][side] = float(np.mean(np.concatenate(clip))) if clip and sum(map(len, clip)) else None
        gap = per_frame(lambda r, s: np.linalg.norm(r.reachable_target[s] - r.target[s][:, :3, 3], axis=1), side)
        gap = gap[np.isfinite(gap)]
        v["unreach"][side] = float(np.mean(gap > 1e-6)) if gap.size else None
        v["jang"][side], v["jlin"][side] = pooled_jitter(
            [r.target[side][a] for r, a in zip(runs, after, strict=True)], period
        )
        v["oang"][side], v["olin"][side] = pooled_jitter(
            [r.operator[side][a] for r, a in zip(runs, after, strict=True)], period
        )
    sim_s = sum(r.sim_s for r in runs)
    wall = sum(r.wall_s for r in runs)
    lost = [(r.tracking_lost_share, r.sim_s) for r in runs if math.isfinite(r.tracking_lost_share)]
    return {
        "frames": int(sum(r.frames for r in runs)),
        "ee_tracking_error_cm": v["err"],
        "ee_tracking_error_cm_with_settling": v["err_all"],
        "ee_tracking_error_p95_cm": v["p95"],
        "ee_reachable_error_cm": v["reach"],
        "ee_operator_error_cm": v["op"],
        "target_unreachable_share": v["unreach"],
        "target_operator_error_cm": v["top"],
        "target_operator_error_p95_cm": v["top95"],
        "target_operator_rotation_error_deg": v["rot"],
        "target_operator_error_unsmoothed_cm": v["top_raw"],
        "target_operator_error_unclipped_cm": v["top_in"],
        "target_operator_error_unclipped_p95_cm": v["top_in95"],
        "target_operator_offset_cm": v["offset"],
        "smoothing_latency_ms": v["lag"],
        "smoothing_rotation_latency_ms": v["rlag"],
        "midline_crossings": v["cross"],
        "workspace_clipped_share": v["clip"],
        "jitter": {"angular_rad_s": v["jang"], "linear_m_s": v["jlin"]},
        "operator_jitter": {"angular_rad_s": v["oang"], "linear_m_s": v["olin"]},
        "position_limit_hits": int(sum(r.position_limit_hits for r in runs)),
        "velocity_limit_hits": int(sum(r.velocity_limit_hits for r in runs)),
        "max_joint_speed_ratio": float(max(r.max_speed_ratio for r in runs)),
        "acceleration_limit_hits": int(sum(r.acceleration_limit_hits for r in runs)),
        "max_joint_acceleration_ratio": float(max(r.max_acceleration_ratio for r in runs)),
        "ik_steps": int(sum(sum(r.ik_steps.values()) for r in runs)),
        "ik_failures": int(sum(sum(r.ik_failures.values()) for r in runs)),
        "ik_failure_kinds": _sum_dicts(r.ik_failure_kinds for r in runs),
        "ik_orientation_relaxed": int(sum(sum(r.ik_relaxed.values()) for r in runs)),
        "ik_joint_space_steps": int(sum(sum(r.ik_joint_space.values()) for r in runs)),
        "ik_failure_share": _share(
            sum(sum(r.ik_failures.values()) for r in runs), sum(sum(r.ik_steps.values()) for r in runs)
        ),
        "nan_commands": int(sum(r.nan_commands for r in runs)),
        "tracking_lost_share": (sum(x * w for x, w in lost) / sum(w for _, w in lost)) if lost else None,
        "dropout_frames": int(sum(int(np.count_nonzero(r.dropout)) for r in runs)),
        "sim_s": sim_s,
        "wall_s": wall,
        "realtime_factor": sim_s / wall if wall > 0 else None,
    }


def _rotation_error_rad(run, side: str) -> np.ndarray:
    """Per frame, the angle (rad) between the target's rotation and the operator's true mapped wrist's (NaN where
    either is unknown)."""
    from akc_drake.core.frames import rotation_angle

    A, B = run.target[side], run.operator[side]
    out = np.full(len(A), np.nan)
    for k in np.flatnonzero(np.all(np.isfinite(A), axis=(1, 2)) & np.all(np.isfinite(B), axis=(1, 2))):
        out[k] = rotation_angle(A[k, :3, :3].T @ B[k, :3, :3])
    return out


def _share(num: int, den: int) -> float | None:
    return float(num) / float(den) if den else None


def _added_latency_ms(runs, side: str, after, rotation: bool = False) -> float | None:
    """Delay (ms) the smoothing adds: :func:`~akc_drake.core.smoothing.estimate_lag` (robust: the shift that
    minimises the *median* squared distance, so the frames where the filter rejected a flip of its input do not
    count as lag) of the target positions (``rotation``: the nine entries of the rotation matrices) behind the
    unsmoothed ones, frames weighted over the runs."""
    from akc_drake.core.smoothing import estimate_lag

    lags, weights = [], []
    for r, a in zip(runs, after, strict=True):
        raw = r.unsmoothed.get(side) if r.unsmoothed else None
        if raw is None:
            continue
        if rotation:
            n = int(np.count_nonzero(a))
            lag = estimate_lag(raw[a][:, :3, :3].reshape(n, 9), r.target[side][a][:, :3, :3].reshape(n, 9),
                               r.period_s, max_lag_s=1.5, robust=True)
        else:
            lag = estimate_lag(raw[a][:, :3, 3], r.target[side][a][:, :3, 3], r.period_s, max_lag_s=0.5, robust=True)
        if math.isfinite(lag):
            lags.append(lag)
            weights.append(int(np.count_nonzero(a)))
    return float(np.average(lags, weights=weights) * 1e3) if lags else None


def _midline_crossings(run, side: str, after) -> int:
    """Frames where ``side``'s target is across the robot's midline (y = 0 in T) while the operator's true
    mapped wrist is not: a crossing the operator did not make."""
    sign = 1.0 if side == "left" else -1.0
    y_t = sign * run.target[side][after][:, 1, 3]
    y_o = sign * run.operator[side][after][:, 1, 3]
    ok = np.isfinite(y_t) & np.isfinite(y_o)
    return int(np.count_nonzero(ok & (y_t < 0.0) & (y_o > 0.0)))


def _sum_dicts(dicts) -> dict:
    out: dict = {}
    for d in dicts:
        for k, v in d.items():
            out[k] = out.get(k, 0) + int(v)
    return out
