"""A clip drives the skinned body's CMU-MB rig directly, bone by bone (numpy + scipy).

The default path (:mod:`akc_drake.operator.retarget`) reduces a clip to the operator's 10 arm angles with the
torso fixed, so a real person's spine, clavicle (shrug, protraction), neck and head motion never reaches the
renderer and the true shoulders never move. Here every bone the clip has turns the rig's bone of the same name
(a rig with other names, Mixamo's, the Biovision-era ``LeftCollar``/``LeftShoulder``/``LeftElbow``, Blender's
``upper_arm.L``..., is mapped onto the rig's by role first: :func:`rig_names_by_role`):

1. *Clip rotations.* A BVH joint's global rotation (cgspeed/CMU names: ``Hips``, ``LowerBack``, ``Spine``,
   ``Spine1``, ``Neck``, ``Neck1``, ``Head``, ``LeftShoulder``, ``LeftArm``, ``LeftForeArm``, ``LeftHand``...)
   or an ASF bone's (CMU names ``root``, ``lowerback``, ``upperback``, ``thorax``, ``lclavicle``, ``lhumerus``,
   ``lradius``...: :data:`ASF_TO_RIG`) is the rotation of that body segment from the clip's rest pose (all
   channels zero), in the clip's world. The segment of a rig bone runs from its clip joint to the clip joint of
   the rig child that starts at the bone's tail (or the joint's End Site), so its rest direction in the clip
   is known too (through joints a conversion put at their parent's origin, down the chain).
2. *Into the operator frame O.* The clip's world (Y up) turns into O (x forward, y left, z up) by the rest
   pose's own axes: z the up axis, y from the right to the left upper-arm joint. Each frame's heading (the
   rest body's forward, :func:`body_frame`, turned by the root, about z) is taken out of every bone, so the
   operator keeps facing the camera; the root stays at the operator's place (positions are not used).
3. *Retarget by direction and twist.* The rig's rest (A-pose) differs from the clip's (a T-pose for CMU
   data; some rigs rest lying along one axis). The root's ``A`` takes the rig's rest body axes (up the spine,
   across the hips) onto the clip's; another bone's ``A`` takes the rig's rest direction (head -> tail) onto the
   clip's rest direction, turning the body's left axis about it onto the clip's (the smallest rotation for
   rests a small turn apart: :func:`rest_alignments`); the bone's posed world rotation is ``G = D A``, ``D``
   the clip's rotation in O. So the posed bone points where the clip's segment points, with the clip's twist
   about it, whatever the clip's rest posture. A rig bone the clip lacks moves rigidly with its parent; a bone
   without a direction (zero length in the clip: a joint at its parent's origin) keeps its parent's ``A``,
   i.e. its rig rest pose relative to the parent.
4. *Rig maps.* From the root down, each bone's head is carried by its parent's map, and the bone's map is the
   rigid ``v -> G (v - head_rest) + head_posed`` (:func:`rig_maps`): the ``(B, 3, 4)`` rest -> posed maps that
   :class:`~akc_drake.operator.skinned.SkinnedOperator` skins with, and whose joint centres are the truth.

Rotations (resampling by Slerp, heading, alignment) go through :class:`scipy.spatial.transform.Rotation`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from akc_drake.errors import UserError

#: CMU ASF bone names -> the CMU-MB rig's (the cgspeed BVH conversion's) names.
ASF_TO_RIG = {
    "root": "Hips",
    "lowerback": "LowerBack",
    "upperback": "Spine",
    "thorax": "Spine1",
    "lowerneck": "Neck",
    "upperneck": "Neck1",
    "head": "Head",
    "lhipjoint": "LHipJoint",
    "rhipjoint": "RHipJoint",
    "lthumb": "LThumb",
    "rthumb": "RThumb",
}
for _s, _S in (("l", "Left"), ("r", "Right")):
    for _asf, _rig in (("femur", "UpLeg"), ("tibia", "Leg"), ("foot", "Foot"), ("toes", "ToeBase"),
                       ("clavicle", "Shoulder"), ("humerus", "Arm"), ("radius", "ForeArm"), ("wrist", "Hand"),
                       ("hand", "FingerBase"), ("fingers", "HandFinger1")):
        ASF_TO_RIG[f"{_s}{_asf}"] = f"{_S}{_rig}"
#: BVH names of other CMU conversions -> the rig's.
BVH_ALIASES = {
    "LFingers": "LeftHandFinger1",
    "RFingers": "RightHandFinger1",
    "LeftHandIndex1": "LeftHandFinger1",
    "RightHandIndex1": "RightHandFinger1",
}
def rig_names_by_role(joint_names, parents, end_site, roles: dict | None = None, *, source: str = "clip") -> dict:
    """Clip joint name -> CMU-MB rig bone name for a BVH rig without CMU names (Mixamo, the Biovision-era
    ``LeftCollar``/``LeftShoulder``/``LeftElbow``/``LeftWrist`` rigs, Blender's ``upper_arm.L``...).

    The arms and hips are found by role as the 10-angle path finds them
    (:func:`~akc_drake.operator.retarget.find_arm_joints`, ``roles`` as ``--joint-names``): the upper-arm joint
    drives ``LeftArm``, the elbow's ``LeftForeArm``, the wrist's ``LeftHand`` (a wrist that is an End Site ends
    the forearm instead); an upper arm's parent below the chest is the clavicle (``LeftShoulder``). The chest is
    the joint the two arms branch from (``Spine1``); the joints between it and the hips drive ``Spine`` then
    ``LowerBack``, from the top. A hand's child named "finger" drives ``LeftFingerBase`` (its child
    ``LeftHandFinger1``), one named "thumb" ``LThumb``; other finger bones move with the hand. The chest's other
    child (and its children named so) is the neck (``Neck``, ``Neck1``) and a joint named "head" the ``Head``.
    A leg from its hip role: ``UpLeg``, ``Leg``, ``Foot``, ``ToeBase`` down the first child (an ``UpLeg``'s
    parent below the hips: ``LHipJoint``).

    Args:
        joint_names: the clip's joint names (End Sites included); ``parents``: their parents (-1 the root);
        end_site: whether each joint is an End Site.
        roles: optional role -> joint name map (``left_shoulder`` ... ``hips``).
        source: the file, for messages.

    Raises:
        UserError: an arm or the hips not found (naming the joints), or arms that do not branch above the hips.
    """
    from akc_drake.operator.retarget import find_arm_joints

    names = [str(n) for n in joint_names]
    index = {n: i for i, n in enumerate(names)}
    r = find_arm_joints(names, roles, source=source)

    def chain(j):  # j and its ancestors, up to the root
        out = []
        while j >= 0:
            out.append(j)
            j = int(parents[j])
        return out

    def first_child(j):
        return next((k for k in range(len(names)) if parents[k] == j and not end_site[k]), None)

    hips = index[r["hips"]]
    arms = {S: [index[r[f"{side}_{part}"]] for part in ("shoulder", "elbow", "wrist")]
            for side, S in (("left", "Left"), ("right", "Right"))}
    left_up = chain(arms["Left"][0])
    chest = next((j for j in chain(arms["Right"][0]) if j in left_up), None)
    if chest is None or chest == hips or hips not in chain(chest):
        raise UserError(f"{source}: the arms do not branch from a chest above the hips ({names[hips]}); "
                        "the rig drive needs a spine")
    out = {names[hips]: "Hips", names[chest]: "Spine1"}
    up = chain(chest)
    spine = up[1:up.index(hips)]  # below the chest, above the hips, top first
    for j, bone in zip(spine, ("Spine", "LowerBack"), strict=False):
        out[names[j]] = bone
    for S, (sh, el, wr) in arms.items():
        out[names[sh]], out[names[el]] = f"{S}Arm", f"{S}ForeArm"
        if not end_site[wr]:
            out[names[wr]] = f"{S}Hand"
            for k in range(len(names)):  # the hand's finger and thumb bones, where named so
                if parents[k] == wr and not end_site[k]:
                    n = names[k].lower()
                    if "thumb" in n:
                        out[names[k]] = f"{S[0]}Thumb"
                    elif "finger" in n:
                        out[names[k]] = f"{S}FingerBase"
                        c = first_child(k)
                        if c is not None:
                            out[names[c]] = f"{S}HandFinger1"
        if int(parents[sh]) != chest:
            out[names[int(parents[sh])]] = f"{S}Shoulder"
    arm_joints = {int(parents[a[0]]) for a in arms.values()} | {a[0] for a in arms.values()}
    neck = next((k for k in range(len(names)) if parents[k] == chest and not end_site[k] and k not in arm_joints),
                None)
    while neck is not None and "neck" in names[neck].lower() and "Neck1" not in out.values():
        out[names[neck]] = "Neck" if "Neck" not in out.values() else "Neck1"
        neck = first_child(neck)
    head = next((n for n in names if "head" in n.lower() and n not in out
                 and not end_site[index[n]] and chest in chain(index[n])), None)
    if head is not None:
        out[head] = "Head"
    for side, S, s in (("left", "Left", "L"), ("right", "Right", "R")):
        j = index[r[f"{side}_hip"]] if r.get(f"{side}_hip") else None
        if j is None or j == hips:
            continue
        if int(parents[j]) not in (hips, -1) and names[int(parents[j])] not in out:
            out[names[int(parents[j])]] = f"{s}HipJoint"
        for bone in ("UpLeg", "Leg", "Foot", "ToeBase"):
            if j is None:
                break
            out[names[j]] = f"{S}{bone}"
            j = first_child(j)
    return out


#: Bones a clip must have to drive the rig (the upper body the camera sees).
REQUIRED_BONES = (
    "Hips",
    "Spine1",
    "LeftShoulder",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
    "RightShoulder",
    "RightArm",
    "RightForeArm",
    "RightHand",
)
#: A clip with all of these as joint names has CMU's (cgspeed's) names; another is mapped by role
#: (:func:`rig_names_by_role`), and needs only these, each hand or its forearm's End Site (a clavicle or a bone
#: the clip lacks moves rigidly with its parent).
_ROLE_BONES = frozenset(REQUIRED_BONES)
_DRIVING_BONES = ("Hips", "Spine1", "LeftArm", "LeftForeArm", "RightArm", "RightForeArm")
#: Segments shorter than this (metres) have no direction (the root's, a joint at its parent's origin).
_MIN_SEGMENT_M = 1e-4


@dataclass(frozen=True)
class ClipRotations:
    """A clip's bone rotations on the rig's bone names, in O, heading removed, at the camera's sample times.

    Attributes:
        times: ``(T,)`` sample times (seconds, from 0).
        bones: the rig bone names the clip drives.
        rotations: ``(T, n, 3, 3)`` each bone's world rotation in O from the clip's rest pose.
        rest_dirs: ``(n, 3)`` each bone's unit rest direction (head -> tail) in O; NaN: no direction.
        name: the clip's label.
        source: the file, for messages.
        body_frame: ``(3, 3)`` the clip's rest body axes in O (columns: forward, left, up; :func:`body_frame`),
            or None (then the root aligns as the identity and every bone by its direction alone).
        lateral: the joint pair the body frame's left axis runs between (``"UpLeg"``: the hips', or ``"Arm"``).
    """

    times: np.ndarray
    bones: tuple[str, ...]
    rotations: np.ndarray
    rest_dirs: np.ndarray
    name: str = "clip"
    source: str = "clip"
    body_frame: np.ndarray | None = None
    lateral: str = "UpLeg"

    def window(self, window_s, name: str | None = None) -> ClipRotations:
        """The samples within ``window_s = [t0, t1]`` seconds, restarting at t = 0 (as the 10-angle path's
        :func:`~akc_drake.evaluation.cache.window_motion`)."""
        t = self.times - self.times[0]
        sel = (t >= float(window_s[0]) - 1e-9) & (t <= float(window_s[1]) + 1e-9)
        if sel.sum() < 2:
            raise UserError(f"{self.source}: window {list(window_s)} s holds no frames (the clip lasts {t[-1]:.1f} s)")
        return replace(self, times=t[sel] - t[sel][0], rotations=self.rotations[sel], name=name or self.name)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > _MIN_SEGMENT_M else np.full(3, np.nan)


def body_frame(up: np.ndarray, left: np.ndarray) -> np.ndarray | None:
    """``(3, 3)`` orthonormal axes (columns: forward, left, up) from an up vector (hips -> upper spine) and a
    left vector (right -> left joint); None when they are parallel or zero."""
    z = _unit(np.asarray(up, float))
    if not np.all(np.isfinite(z)):
        return None
    y = _unit(left - (left @ z) * z)
    if not np.all(np.isfinite(y)):
        return None
    return np.column_stack([np.cross(y, z), y, z])


def clip_skeleton(motion, names: dict | None = None, roles: dict | None = None, source: str | None = None):
    """A parsed clip as joints: ``(rig_names, parents, R, p, times)``.

    ``rig_names`` ``(J,)``: each joint's rig bone name (None: no rig bone; End Sites ``"<name>_end"``);
    ``parents`` ``(J,)``; ``R`` ``(F, J, 3, 3)`` global rotations from the rest pose (identity at rest);
    ``p`` ``(F, J, 3)`` joint positions (a BVH joint's origin, an ASF bone's start; an ASF leaf bone's end is an
    extra ``"<name>_end"`` joint), clip world, metres.

    Args:
        motion: a :class:`~akc_drake.operator.bvh.BVHMotion` or an :class:`~akc_drake.operator.asf_amc.AMCMotion`.
        names: optional clip joint name -> rig bone name overrides.
        roles: optional role -> joint name map (``--joint-names``) for a BVH rig without CMU names
            (:func:`rig_names_by_role`).
        source: the file, for messages (default: the motion's name).
    """
    from akc_drake.operator.asf_amc import AMCMotion
    from akc_drake.operator.bvh import BVHMotion

    names = dict(names or {})
    if isinstance(motion, BVHMotion):
        R, p = motion.global_transforms()
        parents = np.array([j.parent for j in motion.joints])
        own = {BVH_ALIASES.get(j.name, j.name) for j in motion.joints if not j.end_site}
        if roles or not own.issuperset(_ROLE_BONES):  # (not CMU's names: found by role)
            by_role = rig_names_by_role([j.name for j in motion.joints], parents,
                                        [j.end_site for j in motion.joints], roles,
                                        source=source or getattr(motion, "name", "clip"))
            names = {**by_role, **names}
            rig = [None if j.end_site else names.get(j.name) for j in motion.joints]
        else:
            rig = [None if j.end_site else names.get(j.name, BVH_ALIASES.get(j.name, j.name))
                   for j in motion.joints]
        rig = [f"{rig[j.parent]}_end" if j.end_site and rig[j.parent] else r
               for j, r in zip(motion.joints, rig, strict=True)]
    elif isinstance(motion, AMCMotion):
        R, start, end = motion.global_transforms()
        clip_names = list(motion.joint_names)
        skel = motion.skeleton
        parents = [-1] + [clip_names.index(skel.parents[b]) for b in clip_names[1:]]
        has_child = {skel.parents[b] for b in clip_names[1:]}
        leaves = [i for i, b in enumerate(clip_names) if i > 0 and b not in has_child]
        R = np.concatenate([R, R[:, leaves]], axis=1)  # a leaf bone's end joint (its rotation is not used)
        p = np.concatenate([start, end[:, leaves]], axis=1)
        rig = [names.get(b, ASF_TO_RIG.get(b.lower())) for b in clip_names]
        rig += [f"{rig[i]}_end" if rig[i] else None for i in leaves]
        parents = np.array(parents + leaves)
    else:
        raise TypeError(f"motion must be a BVHMotion or an AMCMotion, got {type(motion).__name__}")
    return rig, parents, R, p, motion.frame_time


def clip_rotations(
    motion,
    *,
    rate_hz: float = 10.0,
    names: dict | None = None,
    up: str = "y",
    source: str | None = None,
    rig_children: dict | None = None,
    roles: dict | None = None,
) -> ClipRotations:
    """The rig bones' rotations of a parsed clip (steps 1-2 of the module's recipe), resampled to ``rate_hz``.

    Args:
        motion: a BVHMotion or an AMCMotion (CMU names, or ``names`` mapping them to the rig's).
        rate_hz: the camera rate (sample times ``k / rate_hz``, as
            :func:`~akc_drake.operator.retarget.retarget_positions`).
        names: optional clip name -> rig bone name overrides.
        up: the clip's up axis ("x", "y" or "z"; BVH and CMU data are Y up).
        source: the file, for messages.
        rig_children: ``{bone: child}``: which rig child's joint ends each bone's segment (default:
            :data:`RIG_TAIL_CHILD`, the CMU-MB rig's).
        roles: optional role -> joint name map (``--joint-names``; a BVH rig without CMU names is mapped by
            role, :func:`rig_names_by_role`).

    Raises:
        UserError: the clip lacks a bone of :data:`REQUIRED_BONES` (naming the file and the bone), or is
            shorter than one sample period.
    """
    from akc_drake.operator.retarget import resample_times

    source = source or getattr(motion, "name", "clip")
    rig, parents, R, p, frame_time = clip_skeleton(motion, names, roles, source)
    index = {r: i for i, r in enumerate(rig) if r}
    if _ROLE_BONES.issubset(index):
        missing = []
    else:
        missing = [b for b in _DRIVING_BONES if b not in index] + [
            f"{S}Hand" for S in ("Left", "Right") if f"{S}Hand" not in index and f"{S}ForeArm_end" not in index]
    if missing:
        raise UserError(
            f"{source}: no bone {missing[0]} (nor its CMU ASF name) to drive the CMU-MB rig with; "
            "use the default --drive angles, or a clip with CMU bone names"
        )
    children = RIG_TAIL_CHILD if rig_children is None else rig_children
    # The clip's world -> O, from its rest pose (R = identity): z up, y from the right to the left shoulder.
    rest = np.zeros((len(rig), 3))
    for j, par in enumerate(parents):
        if par >= 0:
            rest[j] = rest[par] + R[0, par].T @ (p[0, j] - p[0, par])
    z = np.eye(3)["xyz".index(str(up).lower())]
    y = rest[index["LeftArm"]] - rest[index["RightArm"]]
    y = y - (y @ z) * z
    if np.linalg.norm(y) < _MIN_SEGMENT_M:
        raise UserError(f"{source}: the rest pose's shoulders coincide; cannot tell the body's left")
    y /= np.linalg.norm(y)
    P = np.stack([np.cross(y, z), y, z])  # rows: O's axes in the clip's world
    bones = tuple(r for r in rig if r and not r.endswith("_end"))
    dirs = np.full((len(bones), 3), np.nan)

    def tail_of(j):  # the clip joint ending the segment of rig bone rig[j] (a child of j), or None
        t = index.get(children.get(rig[j], ""), index.get(f"{rig[j]}_end"))
        return t if t is not None and parents[t] == j else None

    for k, b in enumerate(bones):
        j = index[b]
        tail = tail_of(j)
        # A conversion may put the tail joint at the bone's own origin (cgspeed: Spine1's Neck, LeftHand's
        # LeftFingerBase): the rest direction is then the next joint down that chain that lies elsewhere.
        while tail is not None and np.linalg.norm(rest[tail] - rest[j]) < _MIN_SEGMENT_M and rig[tail] in index:
            tail = tail_of(tail)
        if tail is not None:
            dirs[k] = _unit(P @ (rest[tail] - rest[j]))
    # The rest body's own axes (up the spine, across the hips): what a rest posture other than the rig's
    # standing one (a rig built lying along x, say) is aligned by, and what the heading is read from.
    lateral = "UpLeg" if "LeftUpLeg" in index and "RightUpLeg" in index else "Arm"
    frame = body_frame(P @ (rest[index["Spine1"]] - rest[index["Hips"]]),
                       P @ (rest[index[f"Left{lateral}"]] - rest[index[f"Right{lateral}"]]))
    # Resample every bone's rotation at the camera's times (Slerp), then into O without the heading.
    t_in = np.arange(R.shape[0]) * float(frame_time)
    t_out = resample_times(t_in[-1], rate_hz)
    if len(t_out) < 2:
        raise UserError(
            f"{source}: the motion lasts {t_in[-1]:.3g} s, shorter than one sample period at {rate_hz:g} Hz"
        )
    rots = []
    for b in bones:
        r = Rotation.from_matrix(R[:, index[b]])
        rots.append((Slerp(t_in, r)(t_out) if len(t_in) > 1 else r).as_matrix())
    G = np.einsum("ij,tnjk,lk->tnil", P, np.stack(rots, axis=1), P)
    fwd = G[:, bones.index("Hips")] @ (np.eye(3)[0] if frame is None else frame[:, 0])  # the body's forward
    heading = Rotation.from_euler("z", -np.arctan2(fwd[:, 1], fwd[:, 0])[:, None]).as_matrix()
    G = np.einsum("tij,tnjk->tnik", heading, G)
    name = getattr(motion, "name", "clip")
    return ClipRotations(t_out, bones, G, dirs, name, source, frame, lateral)


#: The CMU-MB rig's bone -> the child whose head is the bone's tail (where a clip's segment of it ends).
RIG_TAIL_CHILD = {
    "Hips": "LowerBack",
    "LowerBack": "Spine",
    "Spine": "Spine1",
    "Spine1": "Neck",
    "Neck": "Neck1",
    "Neck1": "Head",
    **{
        f"{S}{bone}": child.format(S=S, s=S[0])
        for S in ("Left", "Right")
        for bone, child in (
            ("Shoulder", "{S}Arm"),
            ("Arm", "{S}ForeArm"),
            ("ForeArm", "{S}Hand"),
            ("Hand", "{S}FingerBase"),
            ("FingerBase", "{S}HandFinger1"),
            ("UpLeg", "{S}Leg"),
            ("Leg", "{S}Foot"),
            ("Foot", "{S}ToeBase"),
        )
    },
    "LHipJoint": "LeftUpLeg",
    "RHipJoint": "RightUpLeg",
}


def read_clip(path, skeleton=None, *, rate_hz: float = 10.0, names: dict | None = None, window_s=None,
              name: str | None = None, roles: dict | None = None) -> ClipRotations:
    """:func:`clip_rotations` of a ``.bvh`` file, or an ``.amc`` file with its ``.asf`` ``skeleton``
    (``names``, ``roles``: as :func:`clip_rotations`; ``window_s``, ``name``: :meth:`ClipRotations.window`).

    Raises:
        UserError: an unreadable file, a wrong suffix, or a clip the rig cannot take (naming the file).
    """
    from akc_drake.operator.asf_amc import read_amc, read_asf
    from akc_drake.operator.bvh import read_bvh

    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".bvh":
        motion = read_bvh(path)
    elif suffix == ".amc":
        if skeleton is None:
            raise UserError(f"{path}: an AMC motion needs its ASF skeleton (--skeleton FILE.asf)")
        motion = read_amc(path, read_asf(skeleton))
    else:
        raise UserError(f"{path}: the rig drive reads .bvh, or .amc with an .asf, not {suffix or '(none)'!r}")
    clip = clip_rotations(motion, rate_hz=rate_hz, names=names, source=path, roles=roles)
    return clip.window(window_s, name) if window_s else clip


def _align(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit ``u`` onto unit ``v`` (3, 3)."""
    if np.dot(u, v) < -1.0 + 1e-12:  # opposite: half a turn about any axis across u
        axis = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        return Rotation.from_rotvec(math.pi * axis / np.linalg.norm(axis)).as_matrix()
    rot, _ = Rotation.align_vectors(v[None], u[None])
    return rot.as_matrix()


def _frame_about(d: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Columns: unit ``d``, the part of ``s`` across it, and their cross product."""
    e = s - (s @ d) * d
    e /= np.linalg.norm(e)
    return np.column_stack([d, e, np.cross(d, e)])


def rest_alignments(clip: ClipRotations, bones, parents, rest_heads, rest_tails) -> np.ndarray:
    """``(B, 3, 3)`` each rig bone's rest alignment ``A``, taking the rig's rest posture onto the clip's.

    The root: the rotation taking the rig's rest body axes onto the clip's (:func:`body_frame`: up the spine,
    across the hips). Another bone: the rotation taking its rest direction onto the clip's rest direction of the
    same bone and, about it, the body's left axis (up for a bone along it) onto the clip's, so a clip whose rest
    posture is not standing (a rig built lying, arms forward...) turns each segment about its own axis as the
    body does; between postures that differ by a small turn this is the smallest rotation. A bone without a
    direction (in the rig or in the clip) keeps its parent's (so it keeps its rest pose relative to the parent).
    Without the clip's body frame (``clip.body_frame`` None): the root the identity, each bone the smallest
    rotation.
    """
    def head(name):
        return rest_heads[list(bones).index(name)]

    F_rig = None
    if clip.body_frame is not None and "Spine1" in bones:
        F_rig = body_frame(head("Spine1") - head(bones[0]),
                           head(f"Left{clip.lateral}") - head(f"Right{clip.lateral}"))
    A = np.empty((len(bones), 3, 3))
    for b, name in enumerate(bones):
        if parents[b] < 0:
            A[b] = np.eye(3) if F_rig is None else clip.body_frame @ F_rig.T
            continue
        A[b] = A[parents[b]]
        if name in clip.bones:
            v = clip.rest_dirs[clip.bones.index(name)]
            u = rest_tails[b] - rest_heads[b]
            if np.all(np.isfinite(v)) and np.linalg.norm(u) > _MIN_SEGMENT_M:
                u = u / np.linalg.norm(u)
                if F_rig is None:
                    A[b] = _align(u, v)
                    continue
                k = 1 if max(abs(u @ F_rig[:, 1]), abs(v @ clip.body_frame[:, 1])) < 0.9 else 2
                A[b] = _frame_about(v, clip.body_frame[:, k]) @ _frame_about(u, F_rig[:, k]).T
    return A


def rig_world_rotations(clip: ClipRotations, bones, parents, rest_heads, rest_tails) -> np.ndarray:
    """``(T, B, 3, 3)`` each rig bone's world rotation from the rig's rest (step 3 of the module's recipe):
    ``G = D A`` (:func:`rest_alignments`); a rig bone the clip lacks moves rigidly with its parent.

    Args:
        clip: the clip's rotations.
        bones: the rig's bone names (parents first); ``parents`` ``(B,)`` their parents (-1: the root).
        rest_heads, rest_tails: ``(B, 3)`` the rig's rest bone ends in O.
    """
    A = rest_alignments(clip, bones, parents, rest_heads, rest_tails)
    G = np.empty((len(clip.times), len(bones), 3, 3))
    for b, name in enumerate(bones):
        if name in clip.bones:
            G[:, b] = clip.rotations[:, clip.bones.index(name)] @ A[b]
        else:
            G[:, b] = G[:, parents[b]] if parents[b] >= 0 else np.eye(3)
    return G


def rig_maps(G: np.ndarray, parents, rest_heads) -> np.ndarray:
    """``(T, B, 3, 4)`` rest -> posed bone maps from world rotations ``G`` ``(T, B, 3, 3)`` (step 4): the root's
    head stays where it is at rest, every other head is carried by its parent's map."""
    T, B = G.shape[:2]
    maps = np.empty((T, B, 3, 4))
    heads = np.empty((T, B, 3))
    for b in range(B):
        par = parents[b]
        h = rest_heads[b]
        heads[:, b] = h if par < 0 else np.einsum("tij,j->ti", maps[:, par, :, :3], h) + maps[:, par, :, 3]
        maps[:, b, :, :3] = G[:, b]
        maps[:, b, :, 3] = heads[:, b] - G[:, b] @ h
    return maps


class RigDrive:
    """A clip's rig maps and true landmarks on one :class:`~akc_drake.operator.skinned.SkinnedOperator`.

    Args:
        clip: the clip's rotations (:func:`read_clip`).
        body: the skinned operator (its reshaped rest rig).

    Attributes:
        times: ``(T,)`` sample times (from 0).
        maps: ``(T, B, 3, 4)`` rest -> posed bone maps.
        landmarks_O: ``(T, 12, 3)`` true landmarks in O (the posed rig's joint centres and knuckles).
    """

    def __init__(self, clip: ClipRotations, body):
        a = body.assets
        heads, tails = body.rest_bones()
        G = rig_world_rotations(clip, a.bones, a.parents, heads, tails)
        self.clip = clip
        self.times = clip.times
        self.maps = rig_maps(G, a.parents, heads)
        self.landmarks_O = body.landmarks_from_maps(self.maps)

    def index(self, t: float) -> int:
        """The sample nearest to time ``t`` (seconds from the clip's start, clamped)."""
        period = float(self.times[1] - self.times[0])
        return int(np.clip(np.rint((float(t) - self.times[0]) / period), 0, len(self.times) - 1))

    def maps_at(self, t: float) -> np.ndarray:
        """``(B, 3, 4)`` the bone maps of the sample nearest to ``t``."""
        return self.maps[self.index(t)]

