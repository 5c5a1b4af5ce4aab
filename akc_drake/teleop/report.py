"""The demo's report: the comparison table (text) and the figures (matplotlib ``Figure``, no pyplot)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from akc_drake.fileio import atomic_write
from akc_drake.teleop.scenario import MAIN_CORRECTOR, SETTLING_S, SIDES, TeleopRun

# ------------------------------------------------------------------------------------------------------------
# Plots


def _save_figure(fig, path: Path) -> Path:
    """Save a matplotlib figure atomically (temp file, then rename)."""
    return atomic_write(path, lambda f: fig.savefig(f, dpi=110, format=path.suffix.lstrip(".") or "png"))


_COLORS = {"Raw": "tab:red", "KF": "tab:orange", "AKC(KF)": "tab:blue", "AKC+(KF)": "tab:cyan", "COIK(KF)": "tab:green"}


def plot_paths(runs: list[TeleopRun], path: Path, title: str = "") -> Path:
    """End-effector paths of one motion: a row per corrector, top (x-y) and side (x-z) views per arm.

    Each panel shows the operator's true wrist mapped to the robot frame T (grey), the mapped target
    ``X_TE_desired`` (dashed) and the achieved end-effector position (solid).
    """
    from matplotlib.figure import Figure

    views = [
        ("left", (1, 0), "top"),
        ("left", (0, 2), "side"),
        ("right", (1, 0), "top"),
        ("right", (0, 2), "side"),
    ]
    axis_name = {0: "x forward (m)", 1: "y left (m)", 2: "z up (m)"}
    fig = Figure(figsize=(16, 3.6 * len(runs)))
    axes = fig.subplots(len(runs), 4, squeeze=False)
    for i, run in enumerate(runs):
        color = _COLORS.get(run.corrector, "tab:purple")
        for j, (side, (a, b), view) in enumerate(views):
            ax = axes[i, j]
            op, tg, ee = run.operator[side][:, :3, 3], run.target[side][:, :3, 3], run.ee[side]
            ax.plot(op[:, a], op[:, b], color="0.55", lw=3.0, alpha=0.6, label="operator wrist (true, mapped)")
            ax.plot(tg[:, a], tg[:, b], "--", color=color, lw=1.0, label="target X_TE_desired")
            ax.plot(ee[:, a], ee[:, b], "-", color="k", lw=1.0, label="achieved end effector")
            ax.set_xlabel(axis_name[a])
            ax.set_ylabel(axis_name[b])
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(True, alpha=0.3)
            ax.set_title(f"{run.corrector}: {side} arm, {view} view", fontsize=9)
            if i == 0 and j == 0:
                ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or f"Motion {runs[0].motion}: end-effector paths in the robot torso frame T")
    fig.tight_layout()
    return _save_figure(fig, path)


def plot_errors(runs_by_motion: dict[str, list[TeleopRun]], path: Path, settling_s: float = SETTLING_S) -> Path:
    """Tracking error (target to achieved, cm) over time: a row per motion, a column per arm, a line per
    corrector; the settling second is marked and dropped-out frames are shaded."""
    from matplotlib.figure import Figure

    motions = list(runs_by_motion)
    fig = Figure(figsize=(14, 3.8 * len(motions)))
    axes = fig.subplots(len(motions), 2, squeeze=False)
    for i, name in enumerate(motions):
        for j, side in enumerate(SIDES):
            ax = axes[i, j]
            for run in runs_by_motion[name]:
                ax.plot(
                    run.error_t[side],
                    100.0 * run.errors[side],
                    lw=1.0,
                    color=_COLORS.get(run.corrector, "tab:purple"),
                    label=run.corrector,
                )
            runs = runs_by_motion[name]
            if runs and runs[0].dropout.any():
                P = runs[0].period_s
                for k in np.flatnonzero(runs[0].dropout):
                    ax.axvspan(k * P, (k + 1) * P, color="0.85", lw=0)
            ax.axvline(settling_s, color="0.4", ls=":", lw=1.0)
            ax.set_yscale("symlog", linthresh=1.0)
            ax.set_ylim(bottom=0.0)
            ax.set_xlabel("time (s)")
            ax.set_ylabel("target - achieved (cm)")
            ax.set_title(f"Motion {name}, {side} arm", fontsize=10)
            ax.grid(True, alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=8)
    fig.tight_layout()
    return _save_figure(fig, path)


# ------------------------------------------------------------------------------------------------------------
# The table


def _fmt(v, spec: str = ".1f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, spec)


def _lr(d: dict, spec: str = ".1f") -> str:
    return f"{_fmt(d.get('left'), spec)}/{_fmt(d.get('right'), spec)}"


def format_table(summary: dict) -> str:
    """The comparison table of a demo summary, per motion and pooled, as text.

    Columns: EE error (median after the settling second, then including it), the error to the operator's true
    mapped wrist, the control-frame jitter, limit hits (position/velocity/acceleration), IK steps without a
    solution, NaN commands, the share of time with tracking lost and the replay's realtime factor. The "(operator)"
    row is the jitter of the operator's true wrist mapped to the robot: the motion's own speed, for reference.
    """
    cols = (
        ("", 10, ""),
        ("EE error", 12, "L/R cm"),
        ("w/ settle", 12, "L/R cm"),
        ("vs operator", 13, "L/R cm"),
        ("jitter", 13, "L/R rad/s"),
        ("jitter", 13, "L/R m/s"),
        ("limit hits", 14, "pos/vel/acc"),
        ("IK fail", 9, "steps"),
        ("NaN", 6, "cmds"),
        ("lost", 7, "%"),
        ("RTF", 7, "replay"),
    )
    header = "".join(f"{name:>{w}s}" if name else " " * w for name, w, _ in cols)
    units = "".join(f"{u:>{w}s}" if u else " " * w for _, w, u in cols)

    def row(name: str, m: dict) -> str:
        j = m["jitter"]
        lost = m.get("tracking_lost_share")
        cells = (
            _lr(m["ee_tracking_error_cm"]),
            _lr(m["ee_tracking_error_cm_with_settling"]),
            _lr(m["ee_operator_error_cm"]),
            _lr(j["angular_rad_s"], ".2f"),
            _lr(j["linear_m_s"], ".3f"),
            f"{m['position_limit_hits']}/{m['velocity_limit_hits']}/{m.get('acceleration_limit_hits', 0)}",
            str(m["ik_failures"]),
            str(m["nan_commands"]),
            _fmt(None if lost is None else 100.0 * lost, ".0f"),
            _fmt(m["realtime_factor"], ".2f"),
        )
        return f"{name:10s}" + "".join(f"{c:>{w}s}" for c, (_, w, _) in zip(cells, cols[1:], strict=True))

    def reference(m: dict) -> str:
        j = m["operator_jitter"]
        widths = [w for _, w, _ in cols]
        pad = " " * sum(widths[1:4])
        return (
            f"{'(operator)':10s}{pad}{_lr(j['angular_rad_s'], '.2f'):>{widths[4]}s}"
            f"{_lr(j['linear_m_s'], '.3f'):>{widths[5]}s}"
        )

    lines = []
    for motion in summary["config"]["motions"]:
        rs = [r for r in summary["runs"] if r["motion"] == motion and not r["rendered"]]
        if not rs:
            continue
        lines.append(f"Motion {motion} ({rs[0]['frames']} frames, {rs[0]['sim_s']:.1f} s)")
        lines += [header, units, *(row(r["corrector"], r) for r in rs), reference(rs[0]), ""]
    correctors = summary["correctors"]
    lines.append(f"Both motions ({summary['frames']} frames per corrector)")
    lines += [header, units, *(row(c, m) for c, m in correctors.items())]
    lines += [reference(next(iter(correctors.values()))), ""]
    rr = summary.get("rendered_run")
    if rr:
        lines.append(
            f"{MAIN_CORRECTOR} with the camera rendered in the diagram: realtime factor "
            f"{_fmt(summary['realtime_factor'], '.2f')} ({rr['frames']} frames in {rr['wall_s']:.1f} s), "
            f"EE error L/R {_lr(rr['ee_tracking_error_cm'])} cm, NaN commands {rr['nan_commands']}"
        )
    lines.append(
        f"Headline ({MAIN_CORRECTOR}, after the first {summary['config']['settling_s']:g} s): EE tracking "
        f"error L/R {_lr(summary['ee_tracking_error_cm'])} cm; NaN commands {summary['nan_commands']}, "
        f"IK failures {summary['ik_failures']} (all runs)"
    )
    lines += ["", *control_frame_lines(summary)]
    task = summary.get("task")
    if task:
        lines.append("")
        lines.append(
            f"Pick and place ({task['seeds']} seeded runs per corrector; success: box within "
            f"{task['success_radius_cm']:g} cm of the target, upright, released):"
        )
        for c, rate in task["success_rate"].items():
            runs = [r for r in task["runs"] if r["corrector"] == c]
            errs = ", ".join(f"{r['box_error_cm']:.1f}" for r in runs)
            lines.append(f"  {c:10s} {100 * rate:5.0f} %   (box to target, cm: {errs})")
    return "\n".join(lines)


def control_frame_lines(summary: dict) -> list[str]:
    """The control-frame figures per corrector (both motions): the target against the operator's true mapped
    wrist, jitter relative to the operator's, the smoothing's added latency, workspace clips, IK failures and
    position-only and joint-space IK steps, midline crossings."""
    out = [
        "Control frames, both motions: target vs the operator's true mapped wrist (median/p95 cm; unsmoothed "
        "median, constant offset), jitter "
        "relative to the operator's (angular, linear), smoothing latency of positions (and rotations) in ms, "
        "clipped to the workspace (%), "
        "IK steps failed (%) / position-only / joint-space move, midline crossings"
    ]
    for c, m in summary["correctors"].items():
        if "target_operator_error_cm" not in m:
            continue
        med, p95 = m["target_operator_error_cm"], m["target_operator_error_p95_cm"]
        j, o = m["jitter"], m["operator_jitter"]

        def ratio(key: str, side: str, j=j, o=o) -> str:
            a, b = j[key].get(side), o[key].get(side)
            return _fmt(a / b if a is not None and b else None, ".1f")

        lat = m.get("smoothing_latency_ms") or {}
        rlat = m.get("smoothing_rotation_latency_ms") or {}
        clip = m.get("workspace_clipped_share") or {}
        cross = m.get("midline_crossings") or {}
        share = m.get("ik_failure_share")
        raw, offset = m.get("target_operator_error_unsmoothed_cm") or {}, m.get("target_operator_offset_cm") or {}
        pct = {k: None if clip.get(k) is None else 100 * clip[k] for k in ("left", "right")}
        out.append(
            f"  {c:10s} L {_fmt(med.get('left'))}/{_fmt(p95.get('left'))}  R {_fmt(med.get('right'))}/"
            f"{_fmt(p95.get('right'))} (unsmoothed {_lr(raw, '.1f')}, offset {_lr(offset, '.1f')})   jitter "
            f"x{ratio('angular_rad_s', 'left')}/"
            f"x{ratio('angular_rad_s', 'right')}"
            f" ang, x{ratio('linear_m_s', 'left')}/x{ratio('linear_m_s', 'right')} lin   latency "
            f"{_lr(lat, '.0f')} ms (rotation {_lr(rlat, '.0f')})   clipped {_lr(pct, '.0f')} %   IK failed "
            f"{_fmt(None if share is None else 100 * share, '.2f')} % / {m.get('ik_orientation_relaxed', 0)} "
            f"position-only / {m.get('ik_joint_space_steps', 0)} joint-space   "
            f"midline {cross.get('left', 0)}/{cross.get('right', 0)}"
        )
    return out
