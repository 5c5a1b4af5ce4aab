"""How good is the 2D detector on the rendered operator, measured against the exact ground truth.

For a session (:class:`~akc_drake.evaluation.session.Session`: detected pixels, visibility, raw 3D landmarks
and the true joint centres in the camera frame):

* **detection rate**: the share of frames where the detector found a person;
* **2D pixel error** per landmark: distance between the detected pixel and the projected true joint centre,
  separately for frames where the joint is visible and where it is occluded;
* **flags**: how often an occluded joint is flagged by ``visibility < threshold`` and how often by the
  proximity check (the paper's 5 %: a proximal joint whose pixel lies within 5 % of the image width of a
  distal joint's pixel on the same arm loses its depth), both as the pipeline's occlusion filter applies
  them with the paper's rules, and how often a visible joint is flagged by mistake (rejected frames of a
  visible joint, or a visible joint whose depth is dropped);
* **depth error**: the depth read at the detected pixel (the raw landmark's z) minus the true z;
* **by visibility**: the arm joints' pixel error in bands of the detector's own visibility score
  (:data:`VISIBILITY_BANDS`), over every frame the joint was found, seen or hidden: whether the score tells how
  far off a reading is (on the skinned operator MediaPipe's does on some motions and not on others; docs/results.md,
  session 32);
* **by view**: the visible arm joints' pixel error by the angle between the upper arm and the camera ray
  (:func:`upper_arm_ray_angle`). With the upper arm end-on (pointing at the camera) the shoulder and elbow
  project onto one pixel and the image shows no bend: a 2D detector's elbow is least defined there, so the
  figures are also given without those frames (``visible_not_end_on``: the upper arm at least
  :data:`END_ON_DEG` from the ray), beside, never instead of, the figure over all visible frames.

Occlusion ground truth (:func:`true_occlusion`) is geometric and independent of the detector: a landmark is
occluded when a limb segment of either arm (upper arm, forearm, hand; capsules of the radii below) covers its
projected pixel and lies more than ``margin_m`` in front of the landmark's own surface.
"""

from __future__ import annotations

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import INDEX, LANDMARKS, NUM_LANDMARKS, SIDES

#: Capsule radii of the occluding segments (metres): upper arm, forearm, hand.
SEGMENT_RADIUS_M = (0.045, 0.038, 0.040)
#: Radius of the body around each landmark kind (its surface is this much nearer than its centre).
LANDMARK_RADIUS_M = {"shoulder": 0.055, "elbow": 0.045, "wrist": 0.032, "pinky": 0.015, "index": 0.015, "hip": 0.09}
#: An upper arm within this angle of the camera ray (degrees) is "end-on".
END_ON_DEG = 30.0
#: Bins of the upper arm's angle to the camera ray (degrees) for the per-view pixel errors.
ANGLE_BINS_DEG = (0.0, 10.0, END_ON_DEG, 180.0)
#: Bands of the detector's visibility score for the pixel errors by visibility (the last band includes 1).
VISIBILITY_BANDS = (0.0, 0.7, 0.8, 0.9, 0.95, 0.99, 1.0)


def _project(P: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    z = P[..., 2]
    with np.errstate(all="ignore"):
        return np.stack([K.fx * P[..., 0] / z + K.cx, K.fy * P[..., 1] / z + K.cy], axis=-1)


def true_occlusion(truth: np.ndarray, K: CameraIntrinsics, margin_m: float = 0.04, samples: int = 24):
    """``(T, 12)`` bool: which true landmarks an arm segment hides from the camera (see the module doc)."""
    truth = np.asarray(truth, float)
    T = truth.shape[0]
    occ = np.zeros((T, NUM_LANDMARKS), dtype=bool)
    uv = _project(truth, K)
    s = np.linspace(0.0, 1.0, samples)
    for side in SIDES:
        S, E, W = (truth[:, INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
        tip = W + 2.0 * (0.5 * (truth[:, INDEX[f"{side}_index"]] + truth[:, INDEX[f"{side}_pinky"]]) - W)
        for (a, b), r in zip(((S, E), (E, W), (W, tip)), SEGMENT_RADIUS_M, strict=True):
            pts = a[:, None] + s[None, :, None] * (b - a)[:, None]  # (T, n, 3)
            puv = _project(pts, K)
            r_px = K.fx * r / pts[..., 2]
            for j, name in enumerate(LANDMARKS):
                rad = LANDMARK_RADIUS_M[name.split("_", 1)[1]]
                d = np.linalg.norm(puv - uv[:, j][:, None], axis=2)
                front = pts[..., 2] + r < truth[:, j, 2][:, None] - rad - margin_m
                occ[:, j] |= np.any((d < r_px) & front, axis=1)
    return occ


def upper_arm_ray_angle(truth: np.ndarray) -> np.ndarray:
    """``(T, 2)`` degrees, left and right: the angle between each upper arm (shoulder -> elbow) and the ray
    from its elbow to the camera (the origin of the camera frame): 0 when the arm points at the camera,
    90 when it is seen side-on."""
    truth = np.asarray(truth, float)
    out = np.empty((truth.shape[0], len(SIDES)))
    for k, side in enumerate(SIDES):
        S, E = truth[:, INDEX[f"{side}_shoulder"]], truth[:, INDEX[f"{side}_elbow"]]
        u, ray = E - S, -E
        cross = np.linalg.norm(np.cross(u, ray), axis=1)
        out[:, k] = np.degrees(np.arctan2(cross, np.einsum("ij,ij->i", u, ray)))
    return out


def occlusion_flags(session, visibility_threshold: float = 0.7, proximity: float = 0.05):
    """``(visibility_flag, proximity_flag)``, each ``(T, 12)`` bool: what the pipeline's occlusion filter
    (:func:`~akc_drake.core.occlusion.occlusion_filter` with the paper's rules) does to each landmark: rejected
    for low visibility, or its depth dropped by the proximity check."""
    from akc_drake.core.occlusion import PAPER_RULES, occlusion_filter

    raw, pix, vis = np.asarray(session.raw), np.asarray(session.pixels), np.asarray(session.visibility)
    f_vis = np.zeros(vis.shape, dtype=bool)
    f_prox = np.zeros(vis.shape, dtype=bool)
    for k in range(len(vis)):
        _, info = occlusion_filter(
            raw[k],
            pix[k],
            vis[k],
            session.intrinsics.width,
            visibility_threshold=visibility_threshold,
            proximity=proximity,
            **PAPER_RULES,
        )
        f_vis[k], f_prox[k] = info.rejected, info.depth_dropped
    return f_vis, f_prox


def detector_report(session, visibility_threshold: float = 0.7, proximity: float = 0.05) -> dict:
    """The detector's figures on one session (plain JSON types; pixel errors in px, depth errors in cm).

    Returns:
        ``{"frames", "detection_rate", "joints": {name: {"visible": {...}, "occluded": {...}}}}`` where each
        part holds ``frames``, ``px_median``, ``px_p90``, ``depth_err_cm_median`` (|raw z - true z|) and
        ``flag_visibility`` / ``flag_proximity`` / ``flag_any`` (shares of those frames flagged). Arm
        landmarks (not the hips) also have ``visible_not_end_on`` (the same figures over the visible frames
        whose upper arm on that side is at least :data:`END_ON_DEG` from the camera ray) and
        ``visible_by_upper_arm_angle``: ``{"0-10": {"frames", "px_median"}, ...}`` over :data:`ANGLE_BINS_DEG`,
        and ``by_visibility``: ``{"0.99-1": {"frames", "px_median", "px_p90"}, ...}`` over
        :data:`VISIBILITY_BANDS` (every frame the joint was found, with a finite visibility).
    """
    K = session.intrinsics
    truth, pix = np.asarray(session.truth), np.asarray(session.pixels)
    vis = np.asarray(session.visibility, dtype=float)
    raw = np.asarray(session.raw)
    found = np.isfinite(pix).any(axis=(1, 2))
    err = np.linalg.norm(pix - _project(truth, K), axis=2)
    occ = true_occlusion(truth, K)
    f_vis, f_prox = occlusion_flags(session, visibility_threshold, proximity)
    dz = np.abs(raw[..., 2] - truth[..., 2]) * 100.0
    angle = upper_arm_ray_angle(truth)

    def stats(mask: np.ndarray) -> dict:
        m = mask & found
        n = int(m.sum())

        def q(a, p):
            v = a[m & np.isfinite(a)]
            return round(float(np.percentile(v, p)), 2) if v.size else None

        return {
            "frames": n,
            "px_median": q(err_j, 50),
            "px_p90": q(err_j, 90),
            "depth_err_cm_median": q(dz_j, 50),
            "flag_visibility": round(float(fv_j[m].mean()), 3) if n else None,
            "flag_proximity": round(float(fp_j[m].mean()), 3) if n else None,
            "flag_any": round(float((fv_j | fp_j)[m].mean()), 3) if n else None,
        }

    joints = {}
    for j, name in enumerate(LANDMARKS):
        err_j, dz_j, fv_j, fp_j = err[:, j], dz[:, j], f_vis[:, j], f_prox[:, j]
        joints[name] = {"visible": stats(~occ[:, j]), "occluded": stats(occ[:, j])}
        side, kind = name.split("_", 1)
        if kind != "hip":
            a = angle[:, SIDES.index(side)]
            joints[name]["visible_not_end_on"] = stats(~occ[:, j] & (a >= END_ON_DEG))
            joints[name]["visible_by_upper_arm_angle"] = {
                f"{lo:g}-{hi:g}": {k: stats(~occ[:, j] & (a >= lo) & (a < hi))[k] for k in ("frames", "px_median")}
                for lo, hi in zip(ANGLE_BINS_DEG[:-1], ANGLE_BINS_DEG[1:], strict=True)
            }
            v = vis[:, j]
            joints[name]["by_visibility"] = {
                f"{lo:g}-{hi:g}": {k: stats((v >= lo) & ((v < hi) | ((hi == 1.0) & (v == 1.0))))[k]
                                   for k in ("frames", "px_median", "px_p90")}
                for lo, hi in zip(VISIBILITY_BANDS[:-1], VISIBILITY_BANDS[1:], strict=True)
            }
    return {"frames": int(len(found)), "detection_rate": round(float(found.mean()), 4), "joints": joints}


def format_report(name: str, rep: dict) -> str:
    """A Markdown table of :func:`detector_report` for one session."""
    lines = [
        f"Detector on {name}: person found in {100 * rep['detection_rate']:.1f} % of {rep['frames']} frames",
        "",
        "| landmark | frames vis/occ | px median vis / occ | px p90 vis / occ | |dz| cm vis / occ "
        "| occluded flagged: vis<0.7 / proximity / either | visible flagged (false) |",
        "|---|---|---|---|---|---|---|",
    ]

    def f(x, fmt="{:.1f}"):
        return "-" if x is None else fmt.format(x)

    for name_j, r in rep["joints"].items():
        v, o = r["visible"], r["occluded"]
        lines.append(
            f"| {name_j} | {v['frames']}/{o['frames']} | {f(v['px_median'])} / {f(o['px_median'])} "
            f"| {f(v['px_p90'])} / {f(o['px_p90'])} | {f(v['depth_err_cm_median'])} / {f(o['depth_err_cm_median'])} "
            f"| {f(o['flag_visibility'], '{:.0%}')} / {f(o['flag_proximity'], '{:.0%}')} / "
            f"{f(o['flag_any'], '{:.0%}')} | {f(v['flag_any'], '{:.0%}')} |"
        )
    by_view = [r for r in rep["joints"].values() if "visible_by_upper_arm_angle" in r]
    bins = list(by_view[0]["visible_by_upper_arm_angle"]) if by_view else []
    if bins:
        lines += [
            "",
            "Visible arm joints by the angle between the upper arm and the camera ray: px median (frames); "
            f"the last column leaves out the end-on frames (upper arm within {END_ON_DEG:g} deg of the ray).",
            "",
            "| landmark | " + " | ".join(f"{b} deg" for b in bins) + f" | all visible | >= {END_ON_DEG:g} deg |",
            "|---" * (len(bins) + 3) + "|",
        ]
        for name_j, r in rep["joints"].items():
            if "visible_by_upper_arm_angle" not in r or name_j.split("_", 1)[1] not in ("shoulder", "elbow", "wrist"):
                continue
            cells = [f"{f(c['px_median'])} ({c['frames']})" for c in r["visible_by_upper_arm_angle"].values()]
            v, n = r["visible"], r["visible_not_end_on"]
            cells += [f"{f(v['px_median'])} ({v['frames']})", f"{f(n['px_median'])} ({n['frames']})"]
            lines.append(f"| {name_j} | " + " | ".join(cells) + " |")
    by_vis = [r for r in rep["joints"].values() if "by_visibility" in r]
    bands = list(by_vis[0]["by_visibility"]) if by_vis else []
    if bands:
        lines += [
            "",
            "Arm joints by the detector's visibility score: px median (frames), every frame the joint was found.",
            "",
            "| landmark | " + " | ".join(bands) + " |",
            "|---" * (len(bands) + 1) + "|",
        ]
        for name_j, r in rep["joints"].items():
            if "by_visibility" in r and name_j.split("_", 1)[1] in ("shoulder", "elbow", "wrist"):
                cells = [f"{f(c['px_median'])} ({c['frames']})" for c in r["by_visibility"].values()]
                lines.append(f"| {name_j} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def side_by_side(tables_a: list, tables_b: list, label_a: str, label_b: str) -> str:
    """Markdown: every table present in both evaluations, each cell ``a / b (paper)``.

    Args:
        tables_a, tables_b: the :class:`~akc_drake.evaluation.report.Table` lists of two evaluations of the
            same experiment (e.g. the simulated detector and MediaPipe).
        label_a, label_b: their names, in the cells' order.
    """
    by_key = {t.key: t for t in tables_b}
    out = [f"## The tables with both detectors: {label_a} / {label_b} (paper)\n"]
    for ta in tables_a:
        tb = by_key.get(ta.key)
        if tb is None or tb.rows != ta.rows or tb.columns != ta.columns:
            continue
        d = ta.decimals
        out += [f"### {ta.title}\n", "| | " + " | ".join(ta.columns) + " |", "|---" * (len(ta.columns) + 1) + "|"]
        for i, row in enumerate(ta.rows):
            cells = []
            for j in range(len(ta.columns)):
                a, b = float(ta.ours[i, j]), float(tb.ours[i, j])
                p = float(ta.paper[i, j]) if ta.paper is not None else float("nan")
                txt = " / ".join("-" if not np.isfinite(v) else f"{v:.{d}f}" for v in (a, b))
                cells.append(txt + (f" ({p:.{d}f})" if np.isfinite(p) else ""))
            out.append(f"| {row} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out) + "\n"
