"""Retarget motion-capture files (BVH, CMU ASF/AMC, C3D markers) onto the simulated operator's arm joints.

The operator (:mod:`akc_drake.operator.model`) has its own fixed dimensions, so what is carried over from a
file is the *direction* of each upper arm and forearm, expressed in the person's own body frame O
(x forward = the way the person faces, y = the person's left, z up):

1. Find the shoulder, elbow and wrist joints of each side by name (aliases cover the usual BVH
   exporters and the CMU skeleton, with the side first or last: "LeftArm", "lShldr", "upper_arm.L",
   "upperarm_l", "ElbowLeft"; an explicit ``names`` map overrides them).
2. Build O in each frame: z is the file's up axis (by default the file's axis nearest the clip's mean
   hips-to-shoulders direction: Y for BVH and CMU data, Z for a Z-up export; or, with ``up=None``, each
   frame's hips-to-shoulders direction), y is the right-to-left shoulder line made perpendicular
   to z, and ``x = y x z``.
3. Express the unit directions shoulder->elbow and elbow->wrist in O, resample them to the camera rate
   by linear interpolation (renormalised), and turn them into joint angles with
   :func:`akc_drake.operator.model.arm_angles_from_directions`. When the file has index and pinky
   knuckle joints, the palm normal sets the forearm roll; otherwise the neutral roll is used.

Joint positions mean the *proximal* joint of the named segment: a BVH joint's origin (``LeftArm`` is the
shoulder), and for ASF the start of a bone (``lhumerus`` starts at the shoulder, ``lradius`` at the
elbow, ``lwrist`` at the wrist).
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.errors import UserError
from akc_drake.operator.asf_amc import AMCMotion, ASFSkeleton, read_amc, read_asf
from akc_drake.operator.bvh import BVHMotion, read_bvh
from akc_drake.operator.model import arm_angles_from_directions
from akc_drake.operator.motions import OperatorMotion, make_motion
from akc_drake.option_maps import read_option_map

#: Default camera rate the retargeted motion is sampled at.
DEFAULT_RATE_HZ = 10.0

#: Roles a name map may set.
ROLES: tuple[str, ...] = tuple(
    f"{side}_{part}"
    for side in ("left", "right")
    for part in ("shoulder", "elbow", "wrist", "hip", "index", "pinky")
) + ("hips",)
REQUIRED_ROLES: tuple[str, ...] = tuple(
    f"{side}_{part}" for side in ("left", "right") for part in ("shoulder", "elbow", "wrist")
)

# Aliases per body part, best first, as normalised names (lower case, letters and digits only).
# "{S}" is "left"/"right", "{s}" is "l"/"r". A BVH "LeftShoulder" is the clavicle in most exporters
# (Mixamo, CMU conversions), so it only counts as the shoulder when no upper-arm joint exists.
_ALIASES: dict[str, tuple[str, ...]] = {
    "shoulder": (
        "{S}arm",
        "{S}uparm",
        "{S}upperarm",
        "{s}upperarm",
        "{s}uparm",
        "{s}shldr",
        "{s}humerus",
        "{s}uarm",
        "{s}shoulder",
        "{S}shoulder",
    ),
    "elbow": (
        "{S}forearm",
        "{S}lowarm",
        "{S}lowerarm",
        "{s}forearm",
        "{s}lowerarm",
        "{s}lowarm",
        "{s}radius",
        "{s}farm",
        "{s}elbow",
        "{S}elbow",
    ),
    "wrist": ("{S}hand", "{s}wrist", "{S}wrist", "{s}hand"),
    "hip": ("{S}upleg", "{S}upperleg", "{S}thigh", "{s}thigh", "{s}femur", "{s}upleg", "{s}hip", "{S}hip"),
    "index": ("{S}handindex1", "{S}index1", "{s}index1", "{s}handindex1", "{S}indexproximal", "{S}index01"),
    "pinky": (
        "{S}handpinky1",
        "{S}pinky1",
        "{s}pinky1",
        "{s}handpinky1",
        "{S}littleproximal",
        "{S}pinkyproximal",
        "{S}pinky01",
    ),
}
_PREFIXES = ("bip001", "bip01", "mixamorig")

_AXES = {"x": 0, "y": 1, "z": 2}


def _normalise(name: str) -> str:
    n = name.rsplit(":", 1)[-1].lower()
    n = re.sub(r"[^a-z0-9]", "", n)
    for p in _PREFIXES:
        if n.startswith(p) and len(n) > len(p):
            n = n[len(p) :]
            break
    return n


def _aliases(role: str) -> list[str]:
    side, part = role.split("_")
    return [a.format(S=side, s=side[0]) for a in _ALIASES[part]]


#: Side words a joint name may end with, as a token of its own ("upper_arm.L", "UpperArm_L") or, spelled out,
#: at the end of a word ("ElbowLeft").
_SIDE_TOKENS = {"l": "left", "left": "left", "r": "right", "right": "right"}


def _side_last(name: str) -> tuple[str, str] | None:
    """``(side, part)`` of a name whose side comes last, the part normalised as :func:`_normalise` does, or None.

    Blender and Rigify ("upper_arm.L", "forearm.L", "hand.L"), Unreal ("upperarm_l", "lowerarm_l", "hand_l"),
    Bandai Namco's dataset ("UpperArm_L") and Kinect ("ElbowLeft") put the side after the part.
    """
    tokens = [t for t in re.split(r"[^A-Za-z0-9]+", name.rsplit(":", 1)[-1]) if t]
    if len(tokens) >= 2 and tokens[-1].lower() in _SIDE_TOKENS:
        return _SIDE_TOKENS[tokens[-1].lower()], _normalise("".join(tokens[:-1]))
    n = _normalise(name)
    for word in ("left", "right"):
        if n.endswith(word) and len(n) > len(word):
            return word, n[: -len(word)]
    return None


def _side_last_aliases(role: str) -> list[str]:
    """The part names of ``role`` without their side, best first (from the same aliases; a "wrist" before a
    "hand": Kinect's skeleton has both, the hand's joint at its centre)."""
    part = role.split("_")[1]
    out: list[str] = ["wrist"] if part == "wrist" else []
    for a in _ALIASES[part]:
        if a.startswith("{S}") or a.startswith("{s}"):
            p = a[3:]
            if p and p not in out:
                out.append(p)
    return out


def find_arm_joints(
    joint_names, names: dict | None = None, *, source: str = "motion"
) -> dict[str, str | None]:
    """Find the joints for each role (``left_shoulder``, ... ``right_pinky``, ``hips``) by name.

    Args:
        joint_names: the file's joint names.
        names: optional explicit map role -> joint name; overrides the aliases.
        source: the file name for error messages.

    Returns:
        role -> joint name; optional roles (hips, hip, index, pinky) may be None.

    Raises:
        UserError: an arm joint cannot be found, a name in ``names`` is not in the file, or ``names``
            has an unknown role.
    """
    joint_names = [str(n) for n in joint_names]
    names = dict(names or {})
    unknown = [k for k in names if k not in ROLES]
    if unknown:
        raise UserError(
            f"{source}: unknown role(s) {', '.join(map(repr, unknown))} in the joint name map; "
            f"known: {', '.join(ROLES)}"
        )
    normal: dict[str, list[str]] = {}
    for n in joint_names:
        normal.setdefault(_normalise(n), []).append(n)
    side_last = [(n, sp) for n in joint_names if (sp := _side_last(n)) is not None]
    out: dict[str, str | None] = {}
    for role in ROLES:
        if role in names:
            if names[role] not in joint_names:
                raise UserError(
                    f"{source}: the name map sets {role} = {names[role]!r}, which is not a joint "
                    f"of the file (joints: {', '.join(joint_names)})"
                )
            out[role] = names[role]
            continue
        if role == "hips":
            found = next((normal[a][0] for a in ("hips", "hip", "pelvis", "root") if a in normal), None)
            out[role] = found if found is not None else (joint_names[0] if joint_names else None)
            continue
        found = None
        for alias in _aliases(role):
            if alias in normal:
                found = normal[alias][0]
                break
        if found is None:
            # The side after the part ("upper_arm.L", "upperarm_l", "ElbowLeft"): the same aliases, best first.
            side = role.split("_")[0]
            for alias in _side_last_aliases(role):
                hits = [n for n, sp in side_last if sp == (side, alias)]
                if hits:
                    found = hits[0]
                    break
        if found is None:
            # Namespaced or prefixed names ("Character1_LeftArm"): a unique suffix match.
            for alias in _aliases(role):
                hits = [n for n in joint_names if _normalise(n).endswith(alias)]
                if len(hits) == 1:
                    found = hits[0]
                    break
        if found is None and role in REQUIRED_ROLES:
            raise UserError(
                f"{source}: no joint for {role} (tried {', '.join(_aliases(role))}); pass a name map, "
                f"joints are: {', '.join(joint_names)}"
            )
        out[role] = found
    for side in ("left", "right"):
        chain = [out[f"{side}_{p}"] for p in ("shoulder", "elbow", "wrist")]
        if len(set(chain)) != 3:
            raise UserError(
                f"{source}: {side} shoulder, elbow and wrist must be different joints, got {chain}"
            )
    return out


def _up_vector(up) -> np.ndarray:
    if isinstance(up, str):
        s = up.strip().lower()
        sign = -1.0 if s.startswith("-") else 1.0
        s = s.lstrip("+-")
        if s not in _AXES:
            raise UserError(f"up axis must be x, y, z (optionally signed), a 3-vector or None, got {up!r}")
        v = np.zeros(3)
        v[_AXES[s]] = sign
        return v
    v = np.asarray(up, dtype=float).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise UserError(f"up axis must be x, y, z (optionally signed), a 3-vector or None, got {up!r}")
    return v / np.linalg.norm(v)


def auto_up_axis(torso) -> str:
    """The file's signed axis ("y", "-z", ...) nearest the mean of ``torso`` ``(F, 3)``, the unit hips-to-shoulders
    directions: the up axis of a clip of a person who is mostly upright, whatever the exporter's convention (BVH
    is Y-up by convention, but Blender, 3ds Max and MotionBuilder write Z-up files too)."""
    m = np.nanmean(np.asarray(torso, dtype=float).reshape(-1, 3), axis=0)
    k = int(np.argmax(np.abs(m)))
    return ("-" if m[k] < 0 else "") + "xyz"[k]


def _is_auto(up) -> bool:
    """Whether ``up`` asks for the up axis found from the torso (:func:`auto_up_axis`)."""
    return isinstance(up, str) and up.strip().lower() == "auto"


@dataclass
class ArmDirections:
    """Unit arm-segment directions in the operator frame O, per frame.

    Attributes:
        upper: side -> ``(F, 3)`` shoulder-to-elbow directions.
        fore: side -> ``(F, 3)`` elbow-to-wrist directions.
        palm: side -> ``(F, 3)`` palm normals (out of the palm), or None without knuckle joints.
        R_FO: ``(F, 3, 3)`` orientation of O in the file's frame (columns: O's x, y, z).
        joints: role -> the file's joint used for it.
    """

    upper: dict[str, np.ndarray]
    fore: dict[str, np.ndarray]
    palm: dict[str, np.ndarray | None]
    R_FO: np.ndarray
    joints: dict[str, str | None]

    @property
    def num_frames(self) -> int:
        return int(self.R_FO.shape[0])


def _unit(v: np.ndarray, what: str, source: str) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1)
    bad = ~np.isfinite(n) | (n < 1e-9)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise UserError(f"{source}: frame {k}: {what} has zero length or is not finite")
    return v / n[:, None]


def arm_directions_from_positions(
    positions,
    joint_names,
    *,
    names: dict | None = None,
    up="auto",
    source: str = "motion",
) -> ArmDirections:
    """Upper-arm and forearm directions in the operator frame O from global joint positions.

    Args:
        positions: ``(F, J, 3)`` global positions of the joints (any length unit).
        joint_names: the J names.
        names: optional role -> joint name map (see :func:`find_arm_joints`).
        up: the file's up axis ("y", "-z", a 3-vector, ...); "auto" (the default) for the signed axis nearest
            the clip's mean hips-to-shoulders direction (:func:`auto_up_axis`); or None to use each frame's
            hips-to-shoulders direction as z.
        source: the file name for error messages.

    Returns:
        The directions.

    Raises:
        UserError: joints not found, or a degenerate frame (zero-length segment, shoulders on the up axis).
    """
    P = np.asarray(positions, dtype=float)
    joint_names = list(joint_names)
    if P.ndim != 3 or P.shape[1:] != (len(joint_names), 3):
        raise ValueError(f"positions must have shape (F, {len(joint_names)}, 3), got {P.shape}")
    if P.shape[0] == 0:
        raise UserError(f"{source}: the motion has no frames")
    roles = find_arm_joints(joint_names, names, source=source)
    index = {n: i for i, n in enumerate(joint_names)}

    def pos(role: str) -> np.ndarray:
        return P[:, index[roles[role]]]

    lateral = pos("left_shoulder") - pos("right_shoulder")

    auto = _is_auto(up)
    if auto or up is None:  # (the hips-to-shoulders line, only where it is read)
        if roles["left_hip"] and roles["right_hip"]:
            pelvis = 0.5 * (pos("left_hip") + pos("right_hip"))
        else:
            pelvis = pos("hips")
        torso = 0.5 * (pos("left_shoulder") + pos("right_shoulder")) - pelvis
    if auto:
        n = np.linalg.norm(torso, axis=1)
        ok = np.isfinite(n) & (n > 1e-9)
        # (No frame with a torso, e.g. the hips' joint at the shoulders: the BVH convention, Y.)
        up = auto_up_axis(torso[ok] / n[ok, None]) if ok.any() else "y"
    if up is None:
        z = _unit(torso, "the hips-to-shoulders line", source)
    else:
        z = np.broadcast_to(_up_vector(up), P.shape[:1] + (3,))
    y = lateral - np.einsum("fi,fi->f", lateral, z)[:, None] * z
    y = _unit(y, "the shoulder line (perpendicular to the up axis)", source)
    x = np.cross(y, z)
    R_FO = np.stack([x, y, z], axis=-1)

    def in_O(v: np.ndarray) -> np.ndarray:
        return np.einsum("fji,fj->fi", R_FO, v)

    upper, fore, palm = {}, {}, {}
    for side in ("left", "right"):
        s, e, w = (pos(f"{side}_{p}") for p in ("shoulder", "elbow", "wrist"))
        upper[side] = in_O(
            _unit(
                e - s,
                f"the {side} upper arm ({roles[side + '_shoulder']} -> {roles[side + '_elbow']})",
                source,
            )
        )
        f_dir = _unit(
            w - e, f"the {side} forearm ({roles[side + '_elbow']} -> {roles[side + '_wrist']})", source
        )
        fore[side] = in_O(f_dir)
        palm[side] = None
        if roles[f"{side}_index"] and roles[f"{side}_pinky"]:
            across = pos(f"{side}_index") - pos(f"{side}_pinky")
            # Left hand: forearm x (index - pinky) points out of the palm; the right hand is its mirror image.
            n = np.cross(f_dir, across) if side == "left" else np.cross(across, f_dir)
            norms = np.linalg.norm(n, axis=1)
            if np.all(np.isfinite(norms)) and np.all(norms > 1e-9):
                palm[side] = in_O(n / norms[:, None])
    return ArmDirections(upper=upper, fore=fore, palm=palm, R_FO=R_FO, joints=roles)


def resample_times(duration: float, rate_hz: float) -> np.ndarray:
    """Sample times ``k / rate_hz`` covering ``[0, duration]``."""
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise UserError(f"rate_hz must be a positive number, got {rate_hz!r}")
    n = int(math.floor(duration * rate_hz + 1e-9)) + 1
    return np.arange(n) / rate_hz


def resample_directions(times: np.ndarray, dirs: np.ndarray, new_times: np.ndarray) -> np.ndarray:
    """Unit vectors ``(F, 3)`` sampled at ``times``, interpolated linearly at ``new_times``, renormalised."""
    out = np.stack([np.interp(new_times, times, dirs[:, k]) for k in range(3)], axis=1)
    n = np.linalg.norm(out, axis=1)
    # Two consecutive samples pointing in opposite directions would interpolate through zero.
    n[n < 1e-9] = np.nan
    return out / n[:, None]


def retarget_positions(
    positions,
    joint_names,
    frame_time: float,
    *,
    rate_hz: float = DEFAULT_RATE_HZ,
    names: dict | None = None,
    up="auto",
    name: str = "mocap",
    source: str = "motion",
) -> OperatorMotion:
    """Retarget global joint positions sampled every ``frame_time`` seconds onto the operator.

    Args:
        positions: ``(F, J, 3)`` global joint positions.
        joint_names: the J names.
        frame_time: seconds between frames.
        rate_hz: the output's sample rate (the camera's).
        names: optional role -> joint name map.
        up: the file's up axis (see :func:`arm_directions_from_positions`).
        name: the motion's label.
        source: the file name for error messages.

    Returns:
        The operator motion, times from 0 at ``1 / rate_hz`` spacing.

    Raises:
        UserError: missing joints, degenerate frames, or a motion shorter than one output period.
    """
    d = arm_directions_from_positions(positions, joint_names, names=names, up=up, source=source)
    F = d.num_frames
    t_in = np.arange(F) * float(frame_time)
    t_out = resample_times(t_in[-1], rate_hz)
    if t_out.shape[0] < 2:
        raise UserError(
            f"{source}: the motion lasts {t_in[-1]:.3g} s ({F} frames), shorter than one sample period at "
            f"{rate_hz:g} Hz"
        )
    q = {}
    for side in ("left", "right"):
        u = resample_directions(t_in, d.upper[side], t_out)
        f = resample_directions(t_in, d.fore[side], t_out)
        n = None if d.palm[side] is None else resample_directions(t_in, d.palm[side], t_out)
        for what, v in (("upper arm", u), ("forearm", f), ("palm", n)):
            if v is not None and not np.all(np.isfinite(v)):
                k = int(np.flatnonzero(~np.all(np.isfinite(v), axis=1))[0])
                raise UserError(
                    f"{source}: the {side} {what} reverses between two frames around "
                    f"t = {t_out[k]:.3f} s; resample at a higher rate"
                )
        q[side] = arm_angles_from_directions(side, u, f, n)
    return OperatorMotion(t_out, q["left"], q["right"], name)


def load_motion_file(
    path,
    skeleton=None,
    rate_hz: float = DEFAULT_RATE_HZ,
    *,
    units: str = "cm",
    up="auto",
    names: dict | None = None,
    frame_rate: float = 120.0,
) -> OperatorMotion:
    """Load a motion-capture file and retarget it onto the operator's arms.

    Args:
        path: a ``.bvh`` file, a ``.c3d`` file (markers: :mod:`akc_drake.operator.c3d_motion`), or an ``.amc``
            file (then ``skeleton`` is required).
        skeleton: the ``.asf`` skeleton of an AMC file (a path or an :class:`ASFSkeleton`).
        rate_hz: the output's sample rate (the camera's, 10 Hz by default).
        units: a BVH file's length unit (directions do not depend on it).
        up: the file's up axis; "auto" (the default) takes the file's axis nearest the clip's torso (Y for BVH
            and CMU data, which are Y-up by convention; Z for a Z-up export), None the torso's per frame.
        names: optional role -> joint name map (roles: ``left_shoulder`` ... ``right_wrist``, ``hips``).
        frame_rate: an AMC file's frame rate (CMU: 120 Hz).

    Returns:
        The operator motion, named after the file's stem.

    Raises:
        UserError: an unknown suffix, an AMC without a skeleton, or any problem in the files.
    """
    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".bvh":
        motion: BVHMotion | AMCMotion = read_bvh(path, units=units)
    elif suffix == ".amc":
        if skeleton is None:
            raise UserError(f"{path}: an AMC motion needs its ASF skeleton (--skeleton FILE.asf)")
        if not isinstance(skeleton, ASFSkeleton):
            if os.path.splitext(os.fspath(skeleton))[1].lower() != ".asf":
                raise UserError(f"{os.fspath(skeleton)}: a skeleton file must end in .asf")
            skeleton = read_asf(skeleton)
        motion = read_amc(path, skeleton, frame_rate=frame_rate)
    elif suffix == ".c3d":
        from akc_drake.operator.c3d_motion import c3d_joint_positions, read_c3d

        if skeleton is not None:
            raise UserError(f"{path}: a C3D file needs no skeleton file")
        data = read_c3d(path)
        if not data["rate_hz"] > 0 or data["points"].shape[0] < 2:
            raise UserError(f"{path}: no motion in the file ({data['points'].shape[0]} frames at "
                            f"{data['rate_hz']:g} Hz)")
        positions, joints = c3d_joint_positions(data["labels"], data["points"], names, source=path)
        if "hips" not in joints and _is_auto(up):
            up = "z"  # (no torso to find it from: the laboratory convention of C3D files)
        return retarget_positions(positions, joints, 1.0 / data["rate_hz"], rate_hz=rate_hz, up=up,
                                  name=os.path.splitext(os.path.basename(path))[0], source=path)
    elif suffix == ".asf":
        raise UserError(f"{path}: an ASF file is a skeleton; pass the AMC motion file with this skeleton")
    else:
        raise UserError(
            f"{path}: unknown motion file type {suffix or '(none)'!r}; use .bvh, .c3d, or .amc with an .asf"
        )
    return retarget_motion(motion, rate_hz=rate_hz, names=names, up=up, source=path)


def retarget_motion(
    motion: BVHMotion | AMCMotion,
    *,
    rate_hz: float = DEFAULT_RATE_HZ,
    names: dict | None = None,
    up="auto",
    source: str | None = None,
) -> OperatorMotion:
    """Retarget a parsed BVH or AMC motion onto the operator's arms (see :func:`retarget_positions`).

    Args:
        motion: the motion; BVH joints are used at their origins, ASF bones at their proximal ends.
        rate_hz: the output's sample rate.
        names: optional role -> joint name map.
        up: the file's up axis, "auto" (the default: the axis nearest the torso's) or None (the torso's, per
            frame; see :func:`arm_directions_from_positions`).
        source: the file name for error messages (default: the motion's name).

    Returns:
        The operator motion, named after ``motion``.
    """
    if isinstance(motion, BVHMotion):
        positions = motion.global_positions()
    elif isinstance(motion, AMCMotion):
        positions = motion.bone_start_positions()
    else:
        raise TypeError(f"motion must be a BVHMotion or an AMCMotion, got {type(motion).__name__}")
    return retarget_positions(
        positions,
        motion.joint_names,
        motion.frame_time,
        rate_hz=rate_hz,
        names=names,
        up=up,
        name=motion.name,
        source=source or motion.name,
    )


MOTION_FILE_SUFFIXES = (".bvh", ".amc", ".c3d")


def parse_joint_names(text: str) -> dict[str, str]:
    """A joint-name map (role -> the file's joint) from ``--joint-names``: a JSON file holding an object, or
    ``role=joint[,role=joint...]`` inline (roles: :data:`ROLES`; :func:`~akc_drake.option_maps.read_option_map`).

    Raises:
        UserError: an unreadable file, not an object of strings, an entry without "=", or an unknown role.
    """
    names = read_option_map(text, "--joint-names", "role=joint", "left_shoulder=upper_arm.L",
                            "role -> joint name strings")
    if not all(isinstance(v, str) for v in names.values()):
        raise UserError(f"--joint-names {str(text).strip()}: expected a JSON object of role -> joint name strings")
    unknown = [k for k in names if k not in ROLES]
    if unknown:
        raise UserError(f"--joint-names: unknown role(s) {', '.join(map(repr, unknown))}; known: {', '.join(ROLES)}")
    return dict(names)


def motion_from_spec(spec: str, *, cycles: int = 1, seed: int = 0, skeleton: str | None = None, rate_hz=10.0,
                     names: dict | None = None):
    """An :class:`~akc_drake.operator.motions.OperatorMotion` from a name (I, II, tpose, lpose) or a BVH/AMC file
    (``names``: its joint-name map, :func:`find_arm_joints`; not used with a name)."""
    if str(spec).lower().endswith(MOTION_FILE_SUFFIXES) or os.sep in str(spec):
        path = Path(spec)
        if not path.is_file():
            raise UserError(f"{path}: motion file not found")
        if skeleton is not None and not Path(skeleton).is_file():
            raise UserError(f"{skeleton}: skeleton file not found")
        return load_motion_file(path, skeleton, rate_hz=rate_hz, names=names or None)
    try:
        return make_motion(spec, cycles, seed)
    except ValueError as e:
        raise UserError(str(e)) from None
