"""The figures of a real-motion set (``akc-drake evaluate --motion-dir``; :mod:`akc_drake.evaluation.motion_set`):
a corrector's errors paired with its filter's per clip, the pooled RMSE, the worst increases (per axis and in 3D,
over all frames, the frames a joint is seen and those it is lost) and the lost joints' gain. Plain data in, plain
data out: they run on the JSON of :func:`~akc_drake.evaluation.motion_set.evaluate_clip`.
"""

from __future__ import annotations

import math

import numpy as np

from akc_drake.core.skeleton import ARM_JOINTS, INDEX

AXES = ("x", "y", "z")
#: A joint whose depth the camera loses in at least this share of a clip's frames counts as "lost" there.
LOST_SHARE = 0.10


def paired_errors(est: np.ndarray, base: np.ndarray, truth: np.ndarray, base_name: str,
                  seen: np.ndarray | None = None) -> dict:
    """A corrector's errors against its filter's on the frames where both give an estimate.

    Each method's ``rmse_cm`` is over its own frames. A corrector that gives an estimate where its filter has none
    (a shoulder whose depth was never measured, rebuilt from the elbow) would be charged for those frames in a
    comparison of the two: the paired RMSEs compare like with like, and the frames where only the corrector
    estimates are counted apart, with its RMSE there.

    With ``seen``, the same pairs are also kept over the frames where the joint was seen: its depth measured and
    passed by the occlusion filter. That is the easy case, the one a corrector must not make worse. And over the
    other frames both estimate, where the joint was lost (its depth dropped or not measured): the guesses, which a
    corrector must make better.

    Args:
        est: ``(T, 12, 3)`` the corrector's estimates; base: its filter's; truth: the ground truth (NaN where none).
        base_name: the filter's method name.
        seen: ``(T, 12)`` bool, the joints whose depth passed the occlusion filter, or None.

    Returns:
        ``{"filter": base_name, "n": {joint: [x, y, z]}, "rmse_cm": {...}, "filter_rmse_cm": {...},
        "only_n": {...}, "only_rmse_cm": {...}}`` (NaN where there is no frame), and with ``seen`` also
        ``"seen_n"``, ``"seen_rmse_cm"``, ``"seen_filter_rmse_cm"`` and the same three with ``lost_``.
    """
    out: dict = {"filter": base_name, "n": {}, "rmse_cm": {}, "filter_rmse_cm": {}, "only_n": {}, "only_rmse_cm": {}}
    if seen is not None:
        out.update(seen_n={}, seen_rmse_cm={}, seen_filter_rmse_cm={}, lost_n={}, lost_rmse_cm={},
                   lost_filter_rmse_cm={})

    def rmse(e, ok):
        n = ok.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (np.sqrt(np.sum(np.where(ok, e, 0.0) ** 2, axis=0) / n) * 100.0).tolist(), n.tolist()

    for joint in ARM_JOINTS:
        j = INDEX[joint]
        e, b = est[:, j] - truth[:, j], base[:, j] - truth[:, j]
        both = np.isfinite(e) & np.isfinite(b)
        only = np.isfinite(e) & ~np.isfinite(b)
        out["rmse_cm"][joint], out["n"][joint] = rmse(e, both)
        out["filter_rmse_cm"][joint], _ = rmse(b, both)
        out["only_rmse_cm"][joint], out["only_n"][joint] = rmse(e, only)
        if seen is not None:
            for key, ok in (("seen", both & seen[:, j, None]), ("lost", both & ~seen[:, j, None])):
                out[f"{key}_rmse_cm"][joint], out[f"{key}_n"][joint] = rmse(e, ok)
                out[f"{key}_filter_rmse_cm"][joint], _ = rmse(b, ok)
    return out


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


def _compared(r: dict, corrected: str, filt: str):
    """``(corrected's, filt's)`` RMSE per joint of one clip and the paired record (:func:`paired_errors`) they come
    from, or each method's own RMSE and None where none was recorded."""
    p = r["methods"][corrected].get("paired")
    if p is not None and p["filter"] == filt:
        return p["rmse_cm"], p["filter_rmse_cm"], p
    return r["methods"][corrected]["rmse_cm"], r["methods"][filt]["rmse_cm"], None


def joint_pairs(results: list[dict], corrected: str, filt: str, frames: str = "both"):
    """``(clip name, arm joint, corrected's RMSE, filt's RMSE, paired, frames)`` for every clip that ran both
    methods (:func:`_compared`); with ``frames="seen"`` (``"lost"``) over the frames where the joint was seen
    (lost), and only for the clips and joints that recorded such frames (their number; None for ``"both"``)."""
    if frames not in ("both", "seen", "lost"):
        raise ValueError(f"frames must be 'both', 'seen' or 'lost', got {frames!r}")
    for r in results:
        if corrected not in r["methods"] or filt not in r["methods"]:
            continue
        a_all, b_all, p = _compared(r, corrected, filt)
        if frames != "both":
            if p is None or f"{frames}_n" not in p:
                continue
            a_all, b_all = p[f"{frames}_rmse_cm"], p[f"{frames}_filter_rmse_cm"]
        for joint in ARM_JOINTS:
            n = None if frames == "both" else p[f"{frames}_n"][joint][2]
            if n == 0:
                continue
            yield r["name"], joint, a_all[joint], b_all[joint], p is not None, n


def worst_regression(results: list[dict], corrected: str, filt: str, frames: str = "both") -> dict:
    """The largest RMSE increase (cm) of ``corrected`` over ``filt`` on any clip, arm joint and axis.

    On the frames where both estimate (``"paired": True``; a result without paired errors, from before they were
    recorded, compares each method's RMSE over its own frames); with ``frames="seen"`` (``"lost"``), on those of
    them where the joint was seen (lost: :func:`paired_errors`), whose number is then the record's ``frames``.
    """
    worst = {"delta_cm": -math.inf}
    for name, joint, a, b, paired, n in joint_pairs(results, corrected, filt, frames):
        for i, ax in enumerate(AXES):
            dlt = a[i] - b[i]
            if dlt > worst["delta_cm"]:
                worst = {"delta_cm": dlt, "clip": name, "joint": joint, "axis": ax, "paired": paired}
                if n is not None:
                    worst["frames"] = n
    return worst


def norm3(v) -> float:
    """The 3D RMSE from per-axis RMSEs: the root of the sum of the three axes' mean squared errors."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def worst_regression_3d(results: list[dict], corrected: str, filt: str, frames: str = "both") -> dict:
    """The largest 3D RMSE increase (cm) of ``corrected`` over ``filt`` on any clip and arm joint.

    The 3D RMSE is the root of the sum of the three axes' mean squared errors, each axis paired as in
    :func:`worst_regression` (``frames`` too). A corrector that trades one axis for the others (a lost joint's
    depth for its x, y) shows here what the per-axis figure does not.
    """
    worst = {"delta_cm": -math.inf}
    for name, joint, a, b, paired, n in joint_pairs(results, corrected, filt, frames):
        dlt = norm3(a) - norm3(b)
        if dlt > worst["delta_cm"]:
            worst = {"delta_cm": dlt, "clip": name, "joint": joint, "paired": paired}
            if n is not None:
                worst["frames"] = n
    return worst


def lost_joint_gain(results: list[dict], corrected: str, filt: str) -> dict:
    """Mean z RMSE of ``filt`` and ``corrected`` over the (clip, joint) pairs the camera loses (cm).

    Paired as :func:`worst_regression` is; ``filter_3d_cm`` and ``corrected_3d_cm`` are the same pairs' mean 3D RMSE
    (:func:`worst_regression_3d`). ``only_frames`` and ``only_z_cm``: over all clips and arm joints, the frames
    where ``corrected`` gives a depth and ``filt`` none, and the pooled z RMSE of ``corrected`` there (None for
    results without paired errors).
    """
    a, b, a3, b3 = [], [], [], []
    only_n, only_sse, any_paired = 0, 0.0, False
    for r in results:
        if corrected not in r["methods"] or filt not in r["methods"]:
            continue
        a_all, b_all, p = _compared(r, corrected, filt)
        any_paired |= p is not None
        for joint in ARM_JOINTS:
            if r["lost_share"][joint] >= LOST_SHARE:
                a.append(b_all[joint][2])
                b.append(a_all[joint][2])
                a3.append(norm3(b_all[joint]))
                b3.append(norm3(a_all[joint]))
            if p is not None and p["only_n"][joint][2]:
                only_n += p["only_n"][joint][2]
                only_sse += p["only_n"][joint][2] * (p["only_rmse_cm"][joint][2] / 100.0) ** 2
    return {"pairs": len(a), "filter_z_cm": float(np.mean(a)) if a else None,
            "corrected_z_cm": float(np.mean(b)) if b else None,
            "filter_3d_cm": float(np.mean(a3)) if a3 else None,
            "corrected_3d_cm": float(np.mean(b3)) if b3 else None,
            "only_frames": only_n if any_paired else None,
            "only_z_cm": math.sqrt(only_sse / only_n) * 100.0 if only_n else None}


def lost_frames(results: list[dict], corrected: str, filt: str) -> dict:
    """``corrected`` against ``filt`` over every frame where an arm joint was lost (:func:`paired_errors`).

    ``frames``: the joint-frames; ``filter_3d_cm``, ``corrected_3d_cm``: the 3D RMSE pooled over them (the root of
    the three axes' pooled mean squared errors); ``pairs``: the (clip, joint) pairs with such frames, and
    ``pairs_worse_3d`` those where ``corrected``'s 3D RMSE over them exceeds ``filt``'s. Counts of 0 and None
    figures for results recorded without the mask.
    """
    n, sse_a, sse_b, pairs, worse = 0, 0.0, 0.0, 0, 0
    for _, _, a, b, _, k in joint_pairs(results, corrected, filt, "lost"):
        sa, sb = sum(x * x for x in a), sum(x * x for x in b)
        n, sse_a, sse_b, pairs, worse = n + k, sse_a + k * sa, sse_b + k * sb, pairs + 1, worse + (sa > sb)
    return {"frames": n, "filter_3d_cm": math.sqrt(sse_b / n) if n else None,
            "corrected_3d_cm": math.sqrt(sse_a / n) if n else None, "pairs": pairs, "pairs_worse_3d": worse}
