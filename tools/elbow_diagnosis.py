"""Where MediaPipe's elbow goes on the skinned body, and why (issue 12's Motion II elbow figure).

Renders, with the same camera and body as ``akc-drake evaluate --body skinned --detector mediapipe``:

1. a controlled sweep: both upper arms turn (horizontal adduction) from out to the side to pointing at the
   camera, the elbow held at 90 deg with the forearm up (Motion II's peak) or at 45 deg. The skin around
   the elbow is then the same shape in every frame (upper arm, forearm and hand move rigidly together), so
   only the view changes;
2. Motion I and Motion II (``--cycles``, seed 0, as ``evaluate``).

For every frame it writes the elbow's pixel error against the angle between the upper arm and the camera
ray (``elbow_vs_angle.csv``, ``elbow_vs_angle.png``), overlays of the worst visible-elbow frames of Motion
II and of the sweep at chosen angles (``overlay_*.png``: crosses the projected truth, circles MediaPipe,
green left, magenta right), and checks the truth against the mesh: the rig elbow's distance to the mesh's
upper-arm and forearm centre lines and to the skin in the worst frames, and whether the first surface on
the camera ray to a "visible" elbow is the elbow's own skin (``summary.md``); ``elbow_section.png`` cuts the
mesh in the arm's plane at rest, extended and in the worst frame.

``--lights`` renders under another light set than the renderer's default (Drake's single white headlight at
the camera) to show how much the end-on elbow depends on shading cues; it replaces the renderer's parameters
in this process only (an experiment, not the project's scene).

``--pose-model heavy`` runs MediaPipe's heavy model instead of the full one (see :mod:`akc_drake.io.pose_models`).

Usage: .venv/bin/python tools/elbow_diagnosis.py OUT_DIR [--cycles N] [--lights NAME] [--pose-model M]
(about 40 s a cycle)
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import INDEX, LANDMARKS, SIDES
from akc_drake.core.skinning import distance_to_line, limb_axis, plane_section
from akc_drake.evaluation.detector_metrics import LANDMARK_RADIUS_M, _project, true_occlusion, upper_arm_ray_angle
from akc_drake.evaluation.report import save_png
from akc_drake.fileio import atomic_write_text
from akc_drake.operator.motions import SAMPLE_DT, OperatorMotion, make_motion
from akc_drake.operator.skinned import skinned_operator
from akc_drake.systems.session_render import render_session

_D = math.pi / 180.0


def _lights(name: str) -> list:
    """Directional light sets (world = the operator frame O: x toward the camera, z up)."""
    from pydrake.geometry import LightParameter, Rgba

    def light(d, i, frame="world"):
        return LightParameter(type="directional", color=Rgba(1, 1, 1), intensity=i, frame=frame, direction=d)

    head = [0.0, 0.0, 1.0]  # along the camera's view
    return {
        "headlight": [],  # the renderer's default: one white light at the camera
        "overhead": [light([0, 0, -1], 1.0), light(head, 0.4, "camera")],
        "overhead_front": [light([-0.5, 0, -0.866], 1.0), light(head, 0.4, "camera")],
        "two_ceiling": [light([-0.5, 0.5, -0.707], 0.6), light([-0.5, -0.5, -0.707], 0.6), light(head, 0.3, "camera")],
    }[name]


LIGHT_SETS = ("headlight", "overhead", "overhead_front", "two_ceiling")


def use_lights(name: str) -> None:
    """Make this process's renderers use the light set ``name`` (see :func:`_lights`)."""
    if name == "headlight":
        return
    from pydrake.geometry import RenderEngineVtkParams

    import akc_drake.systems.camera_scene as scene

    def params():
        p = RenderEngineVtkParams()
        p.lights = _lights(name)
        return p

    scene.RenderEngineVtkParams = params


def sweep_motion(flexion_deg: float, seconds: float = 8.0) -> OperatorMotion:
    """Both upper arms from the side (adduction 0) to the camera (93 deg), elbow fixed, forearm up."""
    t = np.arange(0.0, seconds + 1e-9, SAMPLE_DT)
    s = t / seconds
    q = np.stack([93.0 * _D * s, *(np.full_like(s, v * _D) for v in (-1.5, -90.0, flexion_deg, 90.0))], axis=1)
    return OperatorMotion(t, q, q.copy(), f"sweep{flexion_deg:g}")


def render(motion: OperatorMotion) -> dict:
    """MediaPipe on the skinned body for every frame: colours, pixels, truth (C), poses."""
    colors = []
    s = render_session(motion, detector="mediapipe", body="skinned", frame_callback=lambda f: colors.append(f.color))
    ql, qr = motion.sample(s.t)
    return {
        "name": motion.name,
        "colors": np.array(colors),
        "pixels": s.pixels,
        "truth": s.truth,
        "q": np.hstack([ql, qr]),
        "X_OC": s.X_OC,
    }


def elbow_rows(run: dict, K: CameraIntrinsics) -> list[dict]:
    """Per frame and side: upper arm angle to the ray, flexion, visible?, px error, its part along the forearm."""
    proj = _project(run["truth"], K)
    err = np.linalg.norm(run["pixels"] - proj, axis=2)
    occ = true_occlusion(run["truth"], K)
    ang = upper_arm_ray_angle(run["truth"])
    rows = []
    for k in range(len(err)):
        for i, side in enumerate(SIDES):
            j, w = INDEX[f"{side}_elbow"], INDEX[f"{side}_wrist"]
            pe, pw = proj[k, j], proj[k, w]
            fore = (pw - pe) / np.linalg.norm(pw - pe)
            along = float((run["pixels"][k, j] - pe) @ fore)
            rows.append(
                {
                    "run": run["name"],
                    "frame": k,
                    "side": side,
                    "angle_deg": float(ang[k, i]),
                    "flexion_deg": float(np.degrees(run["q"][k, 5 * i + 3])),
                    "visible": bool(not occ[k, j]),
                    "px": float(err[k, j]),
                    "px_along_forearm": along,
                    "cm": float(err[k, j] * run["truth"][k, j, 2] / K.fx * 100.0),
                }
            )
    return rows


def overlay(run: dict, frames: list[int], K: CameraIntrinsics, path: Path, title: str) -> None:
    """The rendered frames with the projected truth (crosses) and MediaPipe (circles), cropped to the arms."""
    fig = Figure(figsize=(3.0 * len(frames), 2.9), layout="constrained")
    for n, k in enumerate(frames):
        ax = fig.add_subplot(1, len(frames), n + 1)
        ax.imshow(run["colors"][k])
        tp, dp = _project(run["truth"][k], K), run["pixels"][k]
        for j, name in enumerate(LANDMARKS):
            if not name.endswith(("shoulder", "elbow", "wrist")):
                continue
            c = "lime" if name.startswith("left") else "magenta"
            ax.plot(*tp[j], "+", color=c, ms=12, mew=2)
            ax.plot(*dp[j], "o", mfc="none", color="red" if "elbow" in name else c, ms=9, mew=1.5)
            ax.plot([tp[j, 0], dp[j, 0]], [tp[j, 1], dp[j, 1]], "-", color="yellow", lw=0.8)
        ax.set_xlim(160, 480)
        ax.set_ylim(330, 60)
        ax.set_xticks([])
        ax.set_yticks([])
        a = upper_arm_ray_angle(run["truth"][k : k + 1])[0]
        e = np.linalg.norm(dp - tp, axis=1)
        ax.set_title(
            f"{run['name']} frame {k}: upper arm {a[0]:.0f}/{a[1]:.0f} deg\n"
            f"elbow error L/R {e[INDEX['left_elbow']]:.0f}/{e[INDEX['right_elbow']]:.0f} px",
            fontsize=8,
        )
    fig.suptitle(title, fontsize=9)
    save_png(fig, path)


def mesh_checks(run: dict, frames: list[int]) -> list[str]:
    """For each frame: the rig elbow against the posed mesh (centre lines, skin) and the first surface hit on
    the camera ray to the true elbow (what makes it "visible")."""
    body = skinned_operator()
    V, tri = body.num_vertices, body.triangles
    R, p = run["X_OC"][:3, :3], run["X_OC"][:3, 3]
    lines = []
    for k in frames:
        P_O = body.posed_points(run["q"][k])[:V]
        lm = body.landmarks_O(run["q"][k][None])[0]
        P_C = (P_O - p) @ R
        for side in SIDES:
            S, E, W = (lm[INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
            du = distance_to_line(E, *limb_axis(P_O, tri, S, E, (0.4, 0.5, 0.6, 0.7)))
            df = distance_to_line(E, *limb_axis(P_O, tri, E, W, (0.3, 0.4, 0.5, 0.6)))
            skin = np.min(np.linalg.norm(P_O - E, axis=1))
            e_C = run["truth"][k, INDEX[f"{side}_elbow"]]
            hit, owner = _first_hit(P_C, tri, e_C, body)
            lines.append(
                f"| {run['name']} {k} | {side} | {1000 * du:.1f} | {1000 * df:.1f} | {1000 * skin:.1f} "
                f"| {100 * (np.linalg.norm(e_C) - hit):.1f} | {owner} | "
                f"{'visible' if np.linalg.norm(e_C) - hit < LANDMARK_RADIUS_M['elbow'] + 0.04 else 'hidden'} |"
            )
    return lines


def mesh_occlusion(run: dict, margin_m: float = 0.04) -> np.ndarray:
    """``(T, 12)`` bool for the shoulders, elbows and wrists (False elsewhere): hidden by the posed mesh itself,
    by :func:`~akc_drake.evaluation.detector_metrics.true_occlusion`'s rule (the first surface on the camera ray
    lies more than the landmark's radius plus ``margin_m`` in front of its centre), instead of its capsules."""
    body = skinned_operator()
    V, tri = body.num_vertices, body.triangles
    R, p = run["X_OC"][:3, :3], run["X_OC"][:3, 3]
    out = np.zeros(run["truth"].shape[:2], dtype=bool)
    for k in range(len(out)):
        P_C = (body.posed_points(run["q"][k])[:V] - p) @ R
        for j, name in enumerate(LANDMARKS):
            kind = name.split("_", 1)[1]
            if kind in ("shoulder", "elbow", "wrist"):
                hit, _ = _first_hit(P_C, tri, run["truth"][k, j], body)
                out[k, j] = np.linalg.norm(run["truth"][k, j]) - hit > LANDMARK_RADIUS_M[kind] + margin_m
    return out


def label_lines(run: dict, K: CameraIntrinsics) -> list[str]:
    """Markdown rows: each arm joint's visible px median with the capsule labels and with the mesh's."""
    err = np.linalg.norm(run["pixels"] - _project(run["truth"], K), axis=2)
    caps, mesh = true_occlusion(run["truth"], K), mesh_occlusion(run)
    rows = []
    for j, name in enumerate(LANDMARKS):
        if name.split("_", 1)[1] not in ("shoulder", "elbow", "wrist"):
            continue
        a, b = ~caps[:, j], ~mesh[:, j]
        rows.append(
            f"| {run['name']} | {name} | {np.median(err[a, j]):.1f} ({a.sum()}) | {np.median(err[b, j]):.1f} "
            f"({b.sum()}) | {int((a != b).sum())} |"
        )
    return rows


def _first_hit(P: np.ndarray, tri: np.ndarray, target: np.ndarray, body) -> tuple[float, str]:
    """Distance from the camera (origin) to the first triangle on the ray toward ``target``, and the bone
    that carries most of that triangle (Moller-Trumbore, every triangle at once)."""
    d = target / np.linalg.norm(target)
    A, B, C = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
    e1, e2 = B - A, C - A
    h = np.cross(d, e2)
    a = np.einsum("ij,ij->i", e1, h)
    ok = np.abs(a) > 1e-12
    f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
    s = -A
    u = f * np.einsum("ij,ij->i", s, h)
    q = np.cross(s, e1)
    v = f * (q @ d)
    t = f * np.einsum("ij,ij->i", e2, q)
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    if not hit.any():
        return math.inf, "-"
    i = np.flatnonzero(hit)[np.argmin(t[hit])]
    w = body.lbs.weights[tri[i]].mean(axis=0)
    return float(t[i]), body.assets.bones[int(np.argmax(w[: len(body.assets.bones)]))]


def section_figure(poses: list[tuple[str, np.ndarray | None]], path: Path, side: str = "left") -> None:
    """The skinned mesh cut by the plane of the arm (shoulder, elbow, wrist), in the arm's own 2D frame (x along
    the upper arm, origin at the elbow), with the rig's joint centres and the mesh's limb centre lines (dashed):
    where the skin is around the truth's elbow, and whether it pinches. ``q`` None: the rest body."""
    body = skinned_operator()
    V, tri = body.num_vertices, body.triangles
    fig = Figure(figsize=(3.2 * len(poses), 3.4), layout="constrained")
    for n, (label, q) in enumerate(poses):
        if q is None:
            P = body.points_rest[:V]
            S, E, W = body._rest_joints[side][:3]
        else:
            P = body.posed_points(q)[:V]
            lm = body.landmarks_O(q[None])[0]
            S, E, W = (lm[INDEX[f"{side}_{j}"]] for j in ("shoulder", "elbow", "wrist"))
        u = (E - S) / np.linalg.norm(E - S)
        nrm = np.cross(u, W - E)
        nrm = nrm / np.linalg.norm(nrm) if np.linalg.norm(nrm) > 1e-9 else np.cross(u, [0.0, 0.0, 1.0])
        nrm /= np.linalg.norm(nrm)
        v = np.cross(nrm, u)
        xy = lambda X, E=E, u=u, v=v: np.stack([(X - E) @ u, (X - E) @ v], axis=-1)  # noqa: E731
        ax = fig.add_subplot(1, len(poses), n + 1)
        for seg in xy(plane_section(P, tri, E, nrm)):
            ax.plot(seg[:, 0], seg[:, 1], "k-", lw=0.7)
        for (a, b, fr), c in (((S, E, (0.4, 0.5, 0.6, 0.7)), "b"), ((E, W, (0.3, 0.4, 0.5, 0.6)), "g")):
            m, d = limb_axis(P, tri, a, b, fr)
            ends = xy(np.array([m - 0.25 * d, m + 0.25 * d]))
            ax.plot(ends[:, 0], ends[:, 1], "--", color=c, lw=0.8)
        for X, c in ((S, "b"), (E, "r"), (W, "g")):
            ax.plot(*xy(X), "o", color=c, ms=5)
        ax.set_xlim(-0.33, 0.12)
        ax.set_ylim(-0.12, 0.33)
        ax.set_aspect("equal")
        ax.grid(True, lw=0.3)
        ax.set_title(label, fontsize=8)
    fig.suptitle(f"{side} arm: skin in the arm's plane (m), rig shoulder/elbow/wrist, mesh centre lines", fontsize=9)
    save_png(fig, path)


def angle_figure(rows: list[dict], path: Path) -> None:
    fig = Figure(figsize=(7.5, 4.2), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    style = {"I": ("tab:blue", "o"), "II": ("tab:red", "o"), "sweep90": ("k", "x"), "sweep45": ("tab:gray", "+")}
    for name, (c, m) in style.items():
        r = [x for x in rows if x["run"] == name and x["visible"]]
        if r:
            ax.plot([x["angle_deg"] for x in r], [x["px"] for x in r], m, color=c, ms=4, mfc="none", label=name)
    ax.axhline(8.0, color="g", lw=0.8, ls="--", label="8 px target")
    ax.axvline(30.0, color="0.5", lw=0.8, ls=":")
    ax.set_xlabel("angle between the upper arm and the camera ray (deg)")
    ax.set_ylabel("visible elbow: MediaPipe - projected truth (px)")
    ax.set_title("MediaPipe's elbow on the skinned body, visible elbows only", fontsize=9)
    ax.legend(fontsize=8)
    save_png(fig, path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--cycles", type=int, default=1)
    ap.add_argument("--lights", choices=LIGHT_SETS, default="headlight")
    ap.add_argument("--pose-model", default=None,
                    help="full | heavy | lite | PATH (default: $AKC_DRAKE_POSE_MODEL, else heavy)")
    args = ap.parse_args()
    use_lights(args.lights)
    if args.pose_model:
        from akc_drake.io.mediapipe_detector import find_pose_model
        from akc_drake.io.pose_models import POSE_MODEL_ENV

        find_pose_model(args.pose_model)  # a missing model: its one-line message now
        os.environ[POSE_MODEL_ENV] = args.pose_model
    K = CameraIntrinsics()
    runs = [render(sweep_motion(90.0)), render(sweep_motion(45.0))]
    runs += [render(make_motion(name, cycles=args.cycles, seed=0)) for name in ("I", "II")]
    rows = [r for run in runs for r in elbow_rows(run, K)]
    keys = list(rows[0])
    atomic_write_text(
        args.out / "elbow_vs_angle.csv",
        "\n".join(
            [",".join(keys)]
            + [",".join(f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys) for r in rows]
        )
        + "\n",
    )
    angle_figure(rows, args.out / "elbow_vs_angle.png")
    md = [
        f"# MediaPipe's elbow on the skinned body (lights: {args.lights}, pose model: "
        f"{args.pose_model or os.environ.get('AKC_DRAKE_POSE_MODEL') or 'full'})\n",
        "Visible elbows, px median (frames) by the upper arm's angle to the camera ray:\n",
        "| run | 0-10 deg | 10-30 deg | 30-60 deg | >= 60 deg |",
        "|---|---|---|---|---|",
    ]
    for run in runs:
        cells = []
        for lo, hi in ((0, 10), (10, 30), (30, 60), (60, 181)):
            px = [r["px"] for r in rows if r["run"] == run["name"] and r["visible"] and lo <= r["angle_deg"] < hi]
            cells.append(f"{np.median(px):.1f} ({len(px)})" if px else "- (0)")
        md.append(f"| {run['name']} | " + " | ".join(cells) + " |")
    ii = runs[3]
    vis = [r for r in rows if r["run"] == "II" and r["visible"]]
    worst = sorted(
        {r["frame"] for r in sorted(vis, key=lambda r: -r["px"])[:40]},
        key=lambda k: -max(r["px"] for r in vis if r["frame"] == k),
    )[:3]
    overlay(ii, sorted(worst), K, args.out / "overlay_motionII_worst.png", "Motion II, worst visible elbows")
    sw = runs[0]
    pick = [int(np.argmin(np.abs(upper_arm_ray_angle(sw["truth"])[:, 0] - a))) for a in (90, 30, 13, 5)]
    overlay(
        sw, pick, K, args.out / "overlay_sweep90.png", "Sweep: same elbow (90 deg), upper arm turning to the camera"
    )
    md += [
        "",
        "The rig elbow against the posed mesh (mm) and the first surface on the camera ray to it:\n",
        "| frame | side | to upper-arm axis | to forearm axis | to skin | ray hit in front of it (cm) | hit bone | "
        "label |",
        "|---|---|---|---|---|---|---|---|",
    ]
    md += mesh_checks(ii, sorted(worst)) + mesh_checks(sw, pick[-2:])
    md += [
        "",
        "Visible arm joints, px median (frames), with the evaluation's capsule occlusion labels and with labels "
        "from the posed mesh (ray cast, same rule):\n",
        "| run | landmark | capsule labels | mesh labels | frames labelled differently |",
        "|---|---|---|---|---|",
    ]
    md += label_lines(runs[2], K) + label_lines(ii, K)
    extended = int(np.argmin(ii["q"][len(ii["q"]) // 2 :, 3])) + len(ii["q"]) // 2
    section_figure(
        [("rest (reshaped)", None), (f"II frame {extended} (extended)", ii["q"][extended])]
        + [(f"II frame {k} (worst)", ii["q"][k]) for k in sorted(worst)[:1]],
        args.out / "elbow_section.png",
    )
    atomic_write_text(args.out / "summary.md", "\n".join(md) + "\n")
    print("\n".join(md))
    print(f"wrote {args.out}/summary.md, elbow_vs_angle.csv/.png, overlay_*.png, elbow_section.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
