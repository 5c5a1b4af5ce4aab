"""Real-motion evaluations side by side, and what changed between two (``akc-drake compare``).

Reads the JSON that ``akc-drake evaluate --motion-dir DIR`` writes with ``--json`` (one clip: a folder holding it)
and works only from its per-clip records (:mod:`akc_drake.evaluation.set_metrics`), so it compares any corrector the
run had, a corrector of your own included, against the filter it corrected:

* :func:`glance`: one row per run and corrector: its worst RMSE increase over its filter per axis over all frames
  and over the frames a joint is seen, the worst in 3D, the lost joint-frames' 3D RMSE (filter -> corrector) and the
  pooled arm 3D RMSE (filter -> corrector). The README's "Every set at a glance" is this table.
* :func:`changes`: two runs of the same clips (before and after a change of rule, setting or detector): every
  (corrector, clip, arm joint, axis) whose increase over its filter crossed the target, either way, or moved by at
  least ``min_change_cm``; and per corrector the worst increase and the pooled figures, before -> after.

Plain data in (the parsed JSON), plain data out; :func:`format_glance` and :func:`format_changes` print Markdown.
"""

from __future__ import annotations

import math
from pathlib import Path

from akc_drake.core.skeleton import ARM_JOINTS
from akc_drake.evaluation.methods import parse_method
from akc_drake.evaluation.set_metrics import (
    AXES,
    joint_pairs,
    lost_frames,
    norm3,
    pooled,
    worst_regression,
    worst_regression_3d,
)

#: The issue's target: a corrector never worse than its filter by more than this (cm RMSE, any clip, joint, axis).
TARGET_CM = 0.5


def load_run(path) -> dict:
    """The JSON of ``akc-drake evaluate --json`` for a motion set, with ``"label"`` set to the file's stem.

    Raises:
        ValueError: the file is missing, not JSON, or not a motion-set evaluation (no per-clip records: ``evaluate``
            without ``--motion-dir``, the bench's or one ``--motion-file``'s, writes another layout).
    """
    import json

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: no such file")
    try:
        run = json.loads(p.read_text())
    except (ValueError, UnicodeDecodeError) as e:
        raise ValueError(f"{p}: not JSON ({e})") from None
    clips = run.get("clips") if isinstance(run, dict) else None
    if not isinstance(clips, list) or not clips or not all(
            isinstance(c, dict) and isinstance(c.get("methods"), dict) for c in clips):
        # (a set's sources manifest, mocap_sources.json, has clips too: without per-method records)
        raise ValueError(f"{p}: not a real-motion evaluation (write one with `akc-drake evaluate --motion-dir DIR "
                         f"--json FILE`)")
    run["label"] = p.stem
    return run


def describe(run: dict) -> str:
    """What a run was: detector, body, protocol, drive, rate, and any camera, operator size, depth noise or noise
    seed that is not the default."""
    parts = [str(run.get("detector", "?")), str(run.get("body", "?")), f"`{run.get('protocol', '?')}`"]
    if run.get("drive", "angles") != "angles":
        parts.append(f"drive {run['drive']}")
    if run.get("rate_hz") is not None:
        parts.append(f"{run['rate_hz']:g} Hz")
    cam = run.get("camera", "default")
    if cam not in (None, "default"):
        parts.append("camera " + ",".join(f"{k}={v:g}" for k, v in cam.items() if v is not None)
                     if isinstance(cam, dict) else f"camera {cam}")
    if run.get("body_scale", 1.0) not in (None, 1.0):
        parts.append(f"operator x {run['body_scale']:g}")
    noise = run.get("depth_noise", "default")
    if noise not in (None, "default"):
        parts.append("depth noise " + ",".join(f"{k}={v:g}" for k, v in noise.items())
                     if isinstance(noise, dict) else f"depth noise {noise}")
    if run.get("seed", 0):
        parts.append(f"seed {run['seed']}")
    return ", ".join(parts)


def corrected_pairs(run: dict) -> list[tuple[str, str]]:
    """``(corrector method, its filter)`` for every corrected method the run has (``AKC+(KF)``, ``KF``), in its
    order; COIK and the correctors of your own included."""
    own = list((run.get("correctors") or {}).keys())
    out = []
    for name in run.get("methods", []):
        try:
            spec = parse_method(name, own)
        except ValueError:
            continue
        if spec.corrector != "none" and spec.filter in run["methods"]:
            out.append((spec.name, spec.filter))
    return out


def _pooled_3d(pool: dict, method: str) -> float:
    """The mean over the arm joints of their pooled 3D RMSE (cm)."""
    v = [norm3(pool[method][j]) for j in ARM_JOINTS]
    return sum(v) / len(v)


def glance(runs: list[dict]) -> list[dict]:
    """One record per run and corrected method (:func:`corrected_pairs`): ``label``, ``run`` (:func:`describe`),
    ``frames``, ``method``, ``filter``, ``worst`` / ``worst_seen`` / ``worst_3d`` (``set_metrics`` records:
    ``delta_cm``, ``clip``, ``joint``, ``axis``), ``lost`` (:func:`~akc_drake.evaluation.set_metrics.lost_frames`)
    and ``pooled_3d_cm``: ``(filter, corrector)``."""
    rows = []
    for run in runs:
        clips = run["clips"]
        frames = sum(int(c.get("frames") or 0) for c in clips)
        pairs = corrected_pairs(run)
        pool = pooled(clips, {m for p in pairs for m in p})
        for m, f in pairs:
            rows.append({
                "label": run.get("label", ""), "run": describe(run), "frames": frames, "method": m, "filter": f,
                "worst": worst_regression(clips, m, f), "worst_seen": worst_regression(clips, m, f, "seen"),
                "worst_3d": worst_regression_3d(clips, m, f), "lost": lost_frames(clips, m, f),
                "pooled_3d_cm": (_pooled_3d(pool, f), _pooled_3d(pool, m)),
            })
    return rows


def _delta(w: dict, target: float, where: bool = True) -> str:
    d = w.get("delta_cm", -math.inf)
    if not math.isfinite(d):
        return "-"
    s = f"{d:+.2f}"
    if d > target:
        s = f"**{s}**"
        if where and "clip" in w:
            s += f" ({w['clip']} {w['joint'].replace('_', ' ')}{' ' + w['axis'] if 'axis' in w else ''})"
    return s


def _cm(x) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.2f}"


def format_glance(rows: list[dict], target_cm: float = TARGET_CM) -> str:
    """:func:`glance` as a Markdown table (cm; increases over ``target_cm`` in bold, with where)."""
    out = ["| run | what | frames | method | worst increase over its filter: all / seen frames | worst in 3D "
           "| lost joint-frames 3D: filter -> method | pooled arm 3D: filter -> method |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lost = r["lost"]
        out.append(
            f"| {r['label']} | {r['run']} | {r['frames']} | {r['method']} "
            f"| {_delta(r['worst'], target_cm)} / {_delta(r['worst_seen'], target_cm)} "
            f"| {_delta(r['worst_3d'], target_cm, where=False)} "
            f"| {_cm(lost['filter_3d_cm'])} -> {_cm(lost['corrected_3d_cm'])} "
            f"| {_cm(r['pooled_3d_cm'][0])} -> {_cm(r['pooled_3d_cm'][1])} |")
    return "\n".join(out)


def _increases(run: dict, method: str, filt: str) -> dict:
    """``{(clip, joint, axis): increase over the filter (cm)}`` over all frames."""
    return {(c, j, AXES[i]): a[i] - b[i]
            for c, j, a, b, _, _ in joint_pairs(run["clips"], method, filt) for i in range(3)}


def changes(old: dict, new: dict, target_cm: float = TARGET_CM, min_change_cm: float = 0.1) -> dict:
    """What changed from run ``old`` to run ``new`` of the same clips.

    Returns:
        ``{"summary": [...], "entries": [...]}``. ``summary``: per corrected method both runs have, its
        :func:`glance` figures before and after (``"old"``, ``"new"``). ``entries``: every (method, clip, arm
        joint, axis) whose increase over its filter is over ``target_cm`` in one run and not the other, or moved
        by at least ``min_change_cm``: ``method``, ``clip``, ``joint``, ``axis``, ``old_cm``, ``new_cm``
        (None where a run lacks it), largest move first.

    Raises:
        ValueError: the runs share no clip (not the same set).
    """
    if not {c["name"] for c in old["clips"]} & {c["name"] for c in new["clips"]}:
        raise ValueError(f"{old.get('label', 'old')} and {new.get('label', 'new')} share no clip: not the same set")
    before = {r["method"]: r for r in glance([old])}
    summary, entries = [], []
    for r in glance([new]):
        b = before.get(r["method"])
        if b is None or b["filter"] != r["filter"]:
            continue
        summary.append({"method": r["method"], "old": b, "new": r})
        a, z = _increases(old, r["method"], r["filter"]), _increases(new, r["method"], r["filter"])
        for key in sorted(set(a) | set(z)):
            x, y = a.get(key), z.get(key)
            if not all(math.isfinite(v) for v in (x, y) if v is not None):
                continue  # (no frame of that joint in one run)
            crossed = x is None or y is None or (x > target_cm) != (y > target_cm)
            if crossed or abs(y - x) >= min_change_cm:
                entries.append({"method": r["method"], "clip": key[0], "joint": key[1], "axis": key[2],
                                "old_cm": x, "new_cm": y})
    entries.sort(key=lambda e: -abs((e["new_cm"] or 0.0) - (e["old_cm"] or 0.0)))
    return {"summary": summary, "entries": entries}


def format_changes(ch: dict, target_cm: float = TARGET_CM) -> str:
    """:func:`changes` as Markdown: the per-method summary, then the entries."""
    out = ["| method | worst: all frames | worst: seen frames | worst in 3D | lost joint-frames 3D | pooled arm 3D |",
           "|---|---|---|---|---|---|"]
    for s in ch["summary"]:
        o, n = s["old"], s["new"]
        out.append(
            f"| {s['method']} | {_delta(o['worst'], target_cm, False)} -> {_delta(n['worst'], target_cm)} "
            f"| {_delta(o['worst_seen'], target_cm, False)} -> {_delta(n['worst_seen'], target_cm)} "
            f"| {_delta(o['worst_3d'], target_cm, False)} -> {_delta(n['worst_3d'], target_cm, False)} "
            f"| {_cm(o['lost']['corrected_3d_cm'])} -> {_cm(n['lost']['corrected_3d_cm'])} "
            f"| {_cm(o['pooled_3d_cm'][1])} -> {_cm(n['pooled_3d_cm'][1])} |")
    if not ch["entries"]:
        out += ["", "No (method, clip, joint, axis) crossed the target or moved by the threshold."]
        return "\n".join(out)
    out += ["", "| method | clip | joint | axis | increase over its filter (cm): before -> after |",
            "|---|---|---|---|---|"]
    for e in ch["entries"]:
        o = "-" if e["old_cm"] is None else f"{e['old_cm']:+.2f}"
        n = "-" if e["new_cm"] is None else f"{e['new_cm']:+.2f}"
        out.append(f"| {e['method']} | {e['clip']} | {e['joint'].replace('_', ' ')} | {e['axis']} | {o} -> {n} |")
    return "\n".join(out)
