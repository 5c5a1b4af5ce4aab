"""BVH export: the 12-landmark skeleton as a rigid-arm hierarchy with the calibrated bone lengths.

Used by :mod:`akc_drake.pipeline.export` (``akc-drake export --format bvh``).

Hierarchy (BVH axes: Y up, the character facing +Z, its left along +X; centimetres)::

    Hips (root: position + rotation, at the hip midpoint)
      LeftHip, RightHip            position channels (the hip width is not calibrated)
      Chest                        position + rotation, at the shoulder midpoint
        LeftShoulder               position + rotation (the shoulders come from the filter)
          LeftElbow                rotation only, OFFSET = the calibrated upper arm LUA along +X
            LeftWrist              rotation only, OFFSET = the calibrated forearm LLA along +X
              LeftIndex, LeftPinky position channels (hand landmarks, not calibrated)
        RightShoulder ...          mirrored, along -X

The rest pose is a T-pose. Each rotation is the one that turns the bone's rest direction onto the measured
direction, with the twist taken from the parent (``y`` axis of the parent projected off the bone; the hand's
from the knuckles), written as ``Zrotation Xrotation Yrotation`` Euler angles (intrinsic, the order Blender and
most tools use). The elbow and wrist are therefore at the calibrated distances along the measured directions:
for AKC's corrected skeleton (which has exactly the calibrated lengths) the file reproduces every landmark; for a
raw or filtered skeleton it is that skeleton with its arms re-placed at the calibrated lengths.

BVH has no "missing": a landmark missing in a frame holds its last (else its next) position; one never seen sits
at its rest offset from its parent.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.fileio import atomic_write_text
from akc_drake.operator.bvh import BVHJoint, BVHMotion, format_bvh

POS = ("Xposition", "Yposition", "Zposition")
ROT = ("Zrotation", "Xrotation", "Yrotation")

#: BVH joint name of each landmark.
BVH_NAMES: dict[str, str] = {
    "left_hip": "LeftHip",
    "right_hip": "RightHip",
    "left_shoulder": "LeftShoulder",
    "right_shoulder": "RightShoulder",
    "left_elbow": "LeftElbow",
    "right_elbow": "RightElbow",
    "left_wrist": "LeftWrist",
    "right_wrist": "RightWrist",
    "left_index": "LeftIndex",
    "right_index": "RightIndex",
    "left_pinky": "LeftPinky",
    "right_pinky": "RightPinky",
}


def _fill(P: np.ndarray) -> np.ndarray:
    """Forward-fill then backward-fill each landmark's missing frames (a frame counts when all 3 axes exist)."""
    P = P.copy()
    T = len(P)
    ok = np.isfinite(P).all(axis=2)
    P[~ok] = np.nan
    for j in range(P.shape[1]):
        idx = np.where(ok[:, j], np.arange(T), -1)
        np.maximum.accumulate(idx, out=idx)
        has = idx >= 0
        P[has, j] = P[idx[has], j]
        if has.any() and not has.all():
            P[~has, j] = P[int(np.argmax(has)), j]
    return P


def _median_len(a: np.ndarray, b: np.ndarray, default: float) -> float:
    d = np.linalg.norm(a - b, axis=-1)
    d = d[np.isfinite(d)]
    return float(np.median(d)) if d.size else default


def _frames(d: np.ndarray, ref: np.ndarray, rest_d: np.ndarray, rest_y: np.ndarray) -> np.ndarray:
    """Global rotations ``(T, 3, 3)`` taking the rest frame ``[rest_d, rest_y, rest_d x rest_y]`` to
    ``[d, y, d x y]`` with ``y`` = ``ref`` made orthogonal to ``d`` (falls back to rest where degenerate)."""
    T = len(d)
    n = np.linalg.norm(d, axis=1, keepdims=True)
    dd = np.where(n > 1e-9, d / np.where(n > 1e-9, n, 1.0), rest_d)
    y = ref - np.sum(ref * dd, axis=1, keepdims=True) * dd
    ny = np.linalg.norm(y, axis=1, keepdims=True)
    bad = ny[:, 0] < 1e-6
    if bad.any():  # reference along the bone: use the rest up (or forward) axis instead
        alt = np.broadcast_to(rest_y, (T, 3)).copy()
        alt[np.abs(np.sum(alt * dd, axis=1)) > 0.99] = np.cross(rest_d, rest_y)
        alt = alt - np.sum(alt * dd, axis=1, keepdims=True) * dd
        y[bad] = alt[bad]
        ny = np.linalg.norm(y, axis=1, keepdims=True)
    y = y / ny
    cur = np.stack([dd, y, np.cross(dd, y)], axis=2)
    rest = np.column_stack([rest_d, rest_y, np.cross(rest_d, rest_y)])
    return cur @ rest.T


def build_bvh_motion(points: np.ndarray, dims: BodyDimensions, *, frame_time: float, name: str = "akc") -> BVHMotion:
    """The :class:`~akc_drake.operator.bvh.BVHMotion` of ``points`` ``(T, 12, 3)`` in BVH axes, metres.

    Args:
        points: landmarks in BVH axes (Y up, operator facing +Z), metres, NaN where missing.
        dims: the calibrated arm lengths and shoulder width (the hierarchy's bone lengths).
        frame_time: seconds per frame.
        name: the motion's label.
    """
    raw = np.asarray(points, dtype=float)
    P = _fill(raw)
    T = len(P)
    X, Y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])

    def L(n):
        return P[:, INDEX[n]]

    half_hip = 0.5 * _median_len(raw[:, INDEX["left_hip"]], raw[:, INDEX["right_hip"]], 0.2)
    torso = _median_len(
        0.5 * (raw[:, INDEX["left_hip"]] + raw[:, INDEX["right_hip"]]),
        0.5 * (raw[:, INDEX["left_shoulder"]] + raw[:, INDEX["right_shoulder"]]),
        0.5,
    )
    # Rest offsets (metres, rest axes) of every joint from its parent; landmarks never seen get them too.
    rest = {"Hips": np.zeros(3), "LeftHip": half_hip * X, "RightHip": -half_hip * X, "Chest": torso * Y}
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        lo = side[0]
        sd = side.lower()
        hand_i = _median_len(raw[:, INDEX[f"{sd}_index"]], raw[:, INDEX[f"{sd}_wrist"]], 0.09)
        hand_p = _median_len(raw[:, INDEX[f"{sd}_pinky"]], raw[:, INDEX[f"{sd}_wrist"]], 0.08)
        rest[f"{side}Shoulder"] = s * 0.5 * dims.SW * X
        rest[f"{side}Elbow"] = s * getattr(dims, f"{lo}UA") * X
        rest[f"{side}Wrist"] = s * getattr(dims, f"{lo}LA") * X
        rest[f"{side}Index"] = s * hand_i * X + np.array([0.0, 0.0, 0.02])
        rest[f"{side}Pinky"] = s * hand_p * X - np.array([0.0, 0.0, 0.02])

    # Positions of the non-landmark joints (hip and shoulder midpoints); never-seen landmarks from rest offsets.
    mid_hip = 0.5 * (L("left_hip") + L("right_hip"))
    chest = 0.5 * (L("left_shoulder") + L("right_shoulder"))
    if not np.isfinite(chest).all():
        raise ValueError("BVH export needs both shoulders in at least one frame")
    if not np.isfinite(mid_hip).all():
        mid_hip = chest - torso * Y
    pos = {"Hips": mid_hip, "Chest": chest}
    for lm, jn in BVH_NAMES.items():
        pos[jn] = L(lm)

    # Global rotations.
    trunk = chest - mid_hip
    hip_x = L("left_hip") - L("right_hip")
    if not np.isfinite(hip_x).all():
        hip_x = L("left_shoulder") - L("right_shoulder")
    Rg = {"Hips": _frames(hip_x, trunk, X, Y)}
    Rg["Chest"] = _frames(L("left_shoulder") - L("right_shoulder"), trunk, X, Y)
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        sd = side.lower()
        for jn in ("Index", "Pinky"):
            if not np.isfinite(pos[side + jn]).all():
                pos[side + jn] = None  # placed from the wrist below
        sh, el, wr = L(f"{sd}_shoulder"), L(f"{sd}_elbow"), L(f"{sd}_wrist")
        if not np.isfinite(el).all():
            el = sh + s * X * getattr(dims, f"{side[0]}UA")
        if not np.isfinite(wr).all():
            wr = el + s * X * getattr(dims, f"{side[0]}LA")
        Rg[f"{side}Shoulder"] = _frames(el - sh, Rg["Chest"][:, :, 1], s * X, Y)
        Rg[f"{side}Elbow"] = _frames(wr - el, Rg[f"{side}Shoulder"][:, :, 1], s * X, Y)
        if pos[side + "Index"] is not None and pos[side + "Pinky"] is not None:
            hand = 0.5 * (pos[side + "Index"] + pos[side + "Pinky"]) - wr
            knuckles = pos[side + "Index"] - pos[side + "Pinky"]  # rest: +Z; its cross with the hand is the y ref
            ref = s * np.cross(knuckles, hand)
        else:
            hand, ref = wr - el, Rg[f"{side}Elbow"][:, :, 1]
        Rg[f"{side}Wrist"] = _frames(hand, ref, s * X, Y)
        for jn in ("Index", "Pinky"):
            if pos[side + jn] is None:
                pos[side + jn] = wr + np.einsum("tij,j->ti", Rg[f"{side}Wrist"], rest[side + jn])
        pos[f"{side}Elbow"] = el
        pos[f"{side}Wrist"] = wr

    # name, parent name, channels, child End Site offset (for leaf joints, so bones have a length in Blender)
    spec = [("Hips", None, POS + ROT, None), ("LeftHip", "Hips", POS, -0.1 * Y), ("RightHip", "Hips", POS, -0.1 * Y),
            ("Chest", "Hips", POS + ROT, None)]
    for side, s in (("Left", 1.0), ("Right", -1.0)):
        spec += [(f"{side}Shoulder", "Chest", POS + ROT, None), (f"{side}Elbow", f"{side}Shoulder", ROT, None),
                 (f"{side}Wrist", f"{side}Elbow", ROT, None), (f"{side}Index", f"{side}Wrist", POS, 0.02 * s * X),
                 (f"{side}Pinky", f"{side}Wrist", POS, 0.02 * s * X)]
    joints: list[BVHJoint] = []
    index: dict[str, int] = {}
    cols: list[np.ndarray] = []
    cm = 100.0
    for jn, parent, chans, end in spec:
        index[jn] = len(joints)
        joints.append(BVHJoint(jn, -1 if parent is None else index[parent], rest[jn] * cm + 0.0, chans))
        R_par = np.broadcast_to(np.eye(3), (T, 3, 3)) if parent is None else Rg[parent]
        p_par = np.zeros((T, 3)) if parent is None else pos[parent]
        if chans[0] == "Xposition":
            cols.append(np.einsum("tji,tj->ti", R_par, pos[jn] - p_par) * cm)  # R_parent^T (p - p_parent)
        if "Zrotation" in chans:
            R_loc = np.einsum("tji,tjk->tik", R_par, Rg[jn])  # R_parent^T R_global
            cols.append(Rotation.from_matrix(R_loc).as_euler("ZXY", degrees=True))
        else:
            Rg[jn] = np.array(R_par)
        if end is not None:
            joints.append(BVHJoint(f"{jn}_end", index[jn], end * cm + 0.0, (), end_site=True))
    return BVHMotion(joints, frame_time, np.concatenate(cols, axis=1), units="cm", name=name)


def write_bvh_export(path, points: np.ndarray, dims: BodyDimensions, *, frame_time: float) -> Path:
    """Write the BVH of ``points`` (BVH axes, metres) atomically; 6 decimals (1e-8 m, 1e-6 degrees)."""
    motion = build_bvh_motion(points, dims, frame_time=frame_time, name=Path(path).stem)
    return atomic_write_text(path, format_bvh(motion, precision=6))
