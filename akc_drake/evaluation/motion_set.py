"""Evaluation on a set of real motion-capture clips: ``akc-drake evaluate --motion-dir DIR``.

Each clip (a BVH, or an AMC with its ASF, listed in ``DIR/mocap_sources.json`` or found in ``DIR``) drives the
simulated operator (:func:`~akc_drake.operator.retarget.load_motion_file`), is rendered through the simulated
RGB-D camera and detector once, and every method runs on the same measurements. The unit of work is
:func:`evaluate_clip`, a module-level function on plain data returning plain (JSON-able) data, mapped over the
clips by :func:`~akc_drake.evaluation.executor.run_tasks`. The same operator does every clip, so one T-pose
calibration serves all of them.

Per clip and method, the RMSE of each arm joint and axis over the whole clip, the squared-error sums and counts
(so that the pooled RMSE over all clips is exact), the share of frames whose depth the camera loses for each
joint (the occlusion filter drops or rejects it), the arm-length range and the corrector's time per frame.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import ARM_JOINTS, INDEX
from akc_drake.errors import UserError

#: Methods of the real-motion set by default (COIK is slow and is not what the set is for).
DEFAULT_METHODS: tuple[str, ...] = ("KF", "EKF", "AKC(KF)", "AKC+(KF)", "AKC(EKF)", "AKC+(EKF)")
AXES = ("x", "y", "z")
#: A joint whose depth the camera loses in at least this share of a clip's frames counts as "lost" there.
LOST_SHARE = 0.10
MANIFEST = "mocap_sources.json"


def find_clips(motion_dir) -> list[dict]:
    """The clips of ``motion_dir``: from its ``mocap_sources.json`` (with windows and name maps), else every
    ``*.bvh`` and every ``*.amc`` that has an ``.asf`` of the same stem (or a single ``.asf``) beside it.

    Raises:
        UserError: the folder does not exist, or holds no clip, or a listed file is missing.
    """
    d = Path(motion_dir)
    if not d.is_dir():
        raise UserError(f"--motion-dir {d}: no such folder")
    man = d / MANIFEST
    clips: list[dict] = []
    if man.is_file():
        try:
            data = json.loads(man.read_text())
            entries = data["clips"]
        except (json.JSONDecodeError, KeyError, TypeError) as e:
            raise UserError(f"{man}: not a motion-set manifest ({e})") from None
        for e in entries:
            clip = {
                "name": str(e["name"]),
                "path": str(d / e["file"]),
                "skeleton": str(d / e["skeleton"]) if e.get("skeleton") else None,
                "window_s": list(e["window_s"]) if e.get("window_s") else None,
                "names": dict(e["names"]) if e.get("names") else None,
                "activity": e.get("activity", ""),
            }
            if not Path(clip["path"]).is_file():
                raise UserError(f"{man}: clip {clip['name']}: file {clip['path']} is missing (run: make mocap-data)")
            clips.append(clip)
    else:
        asfs = sorted(d.glob("*.asf"))
        for p in sorted(d.iterdir()):
            if p.suffix.lower() == ".bvh":
                clips.append({"name": p.stem, "path": str(p), "skeleton": None, "window_s": None, "names": None})
            elif p.suffix.lower() == ".amc":
                sk = p.with_suffix(".asf")
                if not sk.is_file() and len(asfs) == 1:
                    sk = asfs[0]
                if not sk.is_file():
                    raise UserError(f"{p}: an AMC motion needs its ASF skeleton ({p.stem}.asf) beside it")
                clips.append({"name": p.stem, "path": str(p), "skeleton": str(sk), "window_s": None, "names": None})
    if not clips:
        raise UserError(f"--motion-dir {d}: no .bvh or .amc clip (and no {MANIFEST})")
    return clips


def clip_motion(clip: dict):
    """The operator motion of one clip (its window cut out, restarting at t = 0)."""
    from akc_drake.operator.motions import OperatorMotion
    from akc_drake.operator.retarget import load_motion_file

    m = load_motion_file(clip["path"], clip.get("skeleton"), names=clip.get("names"))
    win = clip.get("window_s")
    if win:
        t = m.times - m.times[0]
        sel = (t >= float(win[0]) - 1e-9) & (t <= float(win[1]) + 1e-9)
        if sel.sum() < 2:
            raise UserError(f"{clip['path']}: window {win} s holds no frames (the clip lasts {t[-1]:.1f} s)")
        m = OperatorMotion(t[sel] - t[sel][0], m.q_left[sel], m.q_right[sel], name=clip["name"])
    return m


def render_clip(motion, protocol: str, seed: int, width: int = 640, height: int = 480):
    """Render a motion into a :class:`~akc_drake.evaluation.session.Session` with the protocol's extraction."""
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.evaluation.protocol import render_kwargs
    from akc_drake.evaluation.session import session_from_render
    from akc_drake.systems.depth_camera_source import render_session

    intr = scaled_intrinsics(width, height)
    rendered = render_session(motion, intr, seed=seed, **render_kwargs(protocol))
    return session_from_render(rendered, intrinsics=intr, motion=motion.name, cycle_s=None, use_render_cycles=False)


def evaluate_clip(item: dict) -> dict:
    """Evaluate every method on one clip: the unit of work of :func:`evaluate_motion_dir` (plain in, plain out).

    Args:
        item: ``{"clip": find_clips() entry, "dims": {segment: metres}, "methods": [...], "seed": int,
            "protocol": "paper" | "ours", "weights": "Wa" | "Wb" | "Wc"}``.

    Returns:
        ``{"name", "frames", "duration_s", "lost_share": {joint: share}, "methods": {method: {"rmse_cm":
        {joint: [x, y, z]}, "sse_m2": {joint: [..]}, "n": {joint: [..]}, "corr": {joint: [..]},
        "arm_length_range_cm": {segment: cm}, "corrector_us": mean µs per frame or None}}}``.
    """
    from akc_drake.core import metrics
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.evaluation.methods import MethodRunner
    from akc_drake.evaluation.protocol import method_options

    clip = item["clip"]
    protocol = item.get("protocol", "paper")
    motion = clip_motion(clip)
    session = render_clip(motion, protocol, int(item.get("seed", 0)))
    dims = BodyDimensions(**item["dims"])
    runner = MethodRunner(session, dims, item.get("weights", "Wb"), method_options(protocol))
    accepted, _ = runner.occlusion()
    lost = {j: float(np.mean(~np.isfinite(accepted[:, INDEX[j], 2]))) for j in ARM_JOINTS}
    out = {
        "name": clip["name"],
        "activity": clip.get("activity", ""),
        "frames": int(session.num_frames),
        "duration_s": float(session.t[-1] - session.t[0]),
        "lost_share": lost,
        "toward_camera_share": _toward_camera_share(session.truth),
        "methods": {},
    }
    for method in item["methods"]:
        res = runner.run(method)
        est = res.estimates
        m_out = {"rmse_cm": {}, "sse_m2": {}, "n": {}, "corr": {}}
        for joint in ARM_JOINTS:
            j = INDEX[joint]
            e = est[:, j] - session.truth[:, j]
            ok = np.isfinite(e)
            m_out["sse_m2"][joint] = [float(np.sum(np.where(ok[:, a], e[:, a], 0.0) ** 2)) for a in range(3)]
            m_out["n"][joint] = [int(ok[:, a].sum()) for a in range(3)]
            m_out["rmse_cm"][joint] = [
                math.sqrt(s / n) * 100.0 if n else float("nan")
                for s, n in zip(m_out["sse_m2"][joint], m_out["n"][joint], strict=True)
            ]
            r, _, _ = metrics.pearson_per_axis(est[:, j], session.truth[:, j])
            m_out["corr"][joint] = [float(x) for x in np.asarray(r, dtype=float)]
        rng = metrics.arm_length_range(est)
        m_out["arm_length_range_cm"] = {s: float(rng[s]) * 100.0 for s in ("LUA", "LLA", "RUA", "RLA")}
        tc = res.stage_time_s.get("corrector")
        m_out["corrector_us"] = float(np.mean(tc) * 1e6) if tc is not None else None
        out["methods"][method] = m_out
    return out


def _toward_camera_share(truth: np.ndarray) -> float:
    """Share of frames in which a wrist is at least 20 cm nearer the camera than its shoulder."""
    d = []
    for side in ("left", "right"):
        d.append(truth[:, INDEX[f"{side}_shoulder"], 2] - truth[:, INDEX[f"{side}_wrist"], 2])
    reach = np.nanmax(np.stack(d, axis=1), axis=1)
    return float(np.mean(reach > 0.20))


def pooled(results: list[dict], methods) -> dict:
    """Pooled RMSE (cm) per method, joint and axis over every clip's frames (exact: sums of squares)."""
    out = {}
    for m in methods:
        out[m] = {}
        for joint in ARM_JOINTS:
            sse = np.zeros(3)
            n = np.zeros(3)
            for r in results:
                if m in r["methods"]:
                    sse += np.asarray(r["methods"][m]["sse_m2"][joint])
                    n += np.asarray(r["methods"][m]["n"][joint])
            with np.errstate(invalid="ignore", divide="ignore"):
                out[m][joint] = (np.sqrt(sse / n) * 100.0).tolist()
    return out


def worst_regression(results: list[dict], corrected: str, filt: str) -> dict:
    """The largest RMSE increase (cm) of ``corrected`` over ``filt`` on any clip, arm joint and axis."""
    worst = {"delta_cm": -math.inf}
    for r in results:
        if corrected not in r["methods"] or filt not in r["methods"]:
            continue
        for joint in ARM_JOINTS:
            a = r["methods"][corrected]["rmse_cm"][joint]
            b = r["methods"][filt]["rmse_cm"][joint]
            for i, ax in enumerate(AXES):
                dlt = a[i] - b[i]
                if dlt > worst["delta_cm"]:
                    worst = {"delta_cm": dlt, "clip": r["name"], "joint": joint, "axis": ax}
    return worst


def lost_joint_gain(results: list[dict], corrected: str, filt: str) -> dict:
    """Mean z RMSE of ``filt`` and ``corrected`` over the (clip, joint) pairs the camera loses (cm)."""
    a, b = [], []
    for r in results:
        for joint in ARM_JOINTS:
            if r["lost_share"][joint] >= LOST_SHARE and corrected in r["methods"] and filt in r["methods"]:
                a.append(r["methods"][filt]["rmse_cm"][joint][2])
                b.append(r["methods"][corrected]["rmse_cm"][joint][2])
    return {"pairs": len(a), "filter_z_cm": float(np.mean(a)) if a else None,
            "corrected_z_cm": float(np.mean(b)) if b else None}


def evaluate_motion_dir(
    motion_dir,
    *,
    methods=DEFAULT_METHODS,
    seed: int = 0,
    protocol: str = "paper",
    weights: str = "Wb",
    scheduler: str = "inprocess",
    progress: bool = True,
) -> dict:
    """Calibrate once on a rendered T-pose, then :func:`evaluate_clip` on every clip of ``motion_dir``.

    Returns:
        ``{"protocol", "seed", "methods", "dims_cm", "clips": [evaluate_clip results], "failures": [...],
        "pooled_rmse_cm", "worst_regression", "lost_joint_gain", "elapsed_s"}``.
    """
    from akc_drake.evaluation.executor import TaskFailure, run_tasks
    from akc_drake.evaluation.experiment import calibrate_session
    from akc_drake.evaluation.protocol import check_protocol, method_options
    from akc_drake.operator import motions

    check_protocol(protocol)
    t0 = time.perf_counter()
    clips = find_clips(motion_dir)
    tpose = render_clip(motions.tpose(10.0, seed), protocol, seed)
    dims = calibrate_session(tpose, "tpose", method_options(protocol))
    items = [
        {"clip": c, "dims": dims.as_dict(), "methods": list(methods), "seed": seed, "protocol": protocol,
         "weights": weights}
        for c in clips
    ]
    raw = run_tasks(evaluate_clip, items, scheduler=scheduler, desc="clips", labels=[c["name"] for c in clips],
                    progress=progress)
    results = [r for r in raw if not isinstance(r, TaskFailure)]
    failures = [str(r) for r in raw if isinstance(r, TaskFailure)]
    out = {
        "protocol": protocol,
        "seed": seed,
        "methods": list(methods),
        "dims_cm": {k: v * 100.0 for k, v in dims.as_dict().items()},
        "clips": results,
        "failures": failures,
        "pooled_rmse_cm": pooled(results, methods),
        "worst_regression": {},
        "lost_joint_gain": {},
    }
    for corr in ("AKC", "AKC+"):
        for filt in ("KF", "EKF"):
            name = f"{corr}({filt})"
            if name in methods and filt in methods:
                out["worst_regression"][name] = worst_regression(results, name, filt)
                out["lost_joint_gain"][name] = lost_joint_gain(results, name, filt)
    out["elapsed_s"] = time.perf_counter() - t0
    return out


def motion_dir_tables(result: dict) -> list:
    """Per-clip tables (mean arm-joint RMSE per axis and method) and the pooled table (per joint and axis)."""
    from akc_drake.evaluation.report import Table

    methods = result["methods"]
    tables = []
    for axis_i, ax in enumerate(AXES):
        rows = [c["name"] for c in result["clips"]]
        vals = [[float(np.mean([c["methods"][m]["rmse_cm"][j][axis_i] for j in ARM_JOINTS])) for m in methods]
                for c in result["clips"]]
        t = Table(f"clips_{ax}", f"Mean {ax} RMSE (cm) over the six arm joints, per clip "
                  f"({result['protocol']} protocol)", rows, list(methods), np.array(vals))
        tables.append(t)
    rows, vals = [], []
    for joint in ARM_JOINTS:
        for axis_i, ax in enumerate(AXES):
            rows.append(f"{joint} {ax}")
            vals.append([result["pooled_rmse_cm"][m][joint][axis_i] for m in methods])
    t = Table("pooled", f"Pooled RMSE (cm) over {len(result['clips'])} real mocap clips "
              f"({result['protocol']} protocol)", rows, list(methods), np.array(vals))
    for name, w in result["worst_regression"].items():
        if "clip" in w:
            t.notes.append(f"{name}: worst increase over its filter {w['delta_cm']:+.2f} cm "
                           f"({w['clip']}, {w['joint']} {w['axis']})")
    for name, g in result["lost_joint_gain"].items():
        if g["pairs"]:
            t.notes.append(f"{name}: z RMSE on the {g['pairs']} (clip, joint) pairs the camera loses "
                           f"(>= {LOST_SHARE:.0%} of frames): filter {g['filter_z_cm']:.2f} -> "
                           f"{g['corrected_z_cm']:.2f} cm")
    tables.append(t)
    return tables


def plot_errors_per_clip(result: dict, path) -> Path:
    """Bar chart of the mean 3D arm-joint RMSE per clip and method (matplotlib.figure.Figure, no pyplot)."""
    from matplotlib.figure import Figure

    from akc_drake.fileio import atomic_write_bytes

    methods = result["methods"]
    clips = result["clips"]
    fig = Figure(figsize=(max(6.0, 0.9 * len(clips) + 2), 4.0), layout="constrained")
    ax = fig.add_subplot()
    width = 0.8 / max(len(methods), 1)
    x = np.arange(len(clips))
    for k, m in enumerate(methods):
        vals = [float(np.mean([np.sqrt(np.sum(np.square(c["methods"][m]["rmse_cm"][j]))) for j in ARM_JOINTS]))
                for c in clips]
        ax.bar(x + (k - (len(methods) - 1) / 2) * width, vals, width, label=m)
    ax.set_xticks(x, [c["name"] for c in clips], rotation=30, ha="right")
    ax.set_ylabel("mean arm-joint 3D RMSE (cm)")
    ax.set_title(f"Error per real mocap clip and method ({result['protocol']} protocol)")
    ax.legend(fontsize=7, ncols=min(len(methods), 3))
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return path
