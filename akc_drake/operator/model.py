"""The simulated operator: a human upper body built from primitives, its parameters and its arm kinematics.

Its SDF and the plant helpers are in :mod:`akc_drake.operator.sdf`.

Operator frame O: origin at the pelvis (midpoint of the two hip joint centres), x forward (the way the
person faces), y to the person's left, z up. The camera looks at the operator from the front, so its
optical axis is -x of O.

Each arm has :data:`NUM_ARM_DOF` = 5 revolute joints, in this order::

    q[0] shoulder horizontal adduction  (0: arm out to the side, +90 deg: arm points forward)
    q[1] shoulder elevation             (+: arm raised toward the head)
    q[2] humeral rotation               (roll of the upper arm about its own axis)
    q[3] elbow flexion                  (0: straight, +: forearm folds toward the palm side)
    q[4] forearm roll (pronation/supination, about the forearm axis)

At q = 0 the arm points straight out to the side (T-pose), the elbow would flex forward and the palm faces
forward with the thumb up. The left arm's rotation is ``Rz(-q0) Rx(q1) Ry(q2) . Rz(-q3) . Ry(q4)``
(each factor about an axis fixed in the previous body, all frames aligned with O at q = 0). The right arm
is the mirror image of the left one through the sagittal plane (y -> -y), so equal q give mirrored poses:
its joint axes are the left axes mirrored and negated.

The hand has no joint of its own: it sits on the forearm in a fixed, natural wrist posture,
:attr:`OperatorParams.wrist_extension_deg` of extension (the fingers bent toward the back of the hand about
the wrist's radio-ulnar axis, the thumb axis of the hand frame). A person holding the arm out does not keep
the hand as a rigid, straight extension of the forearm; the relaxed "functional" wrist is extended by about
20-30 deg (our estimate; the position of function used in hand splinting). It matters for the camera:
with a straight hand, a forearm pointing at the camera puts the fingers exactly in front of the wrist, and
the wrist's depth reads the fingertips (10-18 cm short); with the wrist extended, the wrist's pixel sees the
wrist and the base of the palm. ``wrist_extension_deg = 0`` gives the straight hand.

The five joint angles are exactly what the 12 landmarks can tell: the upper-arm direction (2), the
forearm direction (elbow flexion + humeral rotation) and the palm orientation (forearm roll), which
:func:`arm_angles_from_directions` inverts in closed form.

Landmarks are joint centres (shoulder, elbow, wrist, hip) and knuckle points (index and pinky MCP) inside
the body; the camera sees the limb surfaces around them (capsules with realistic radii), so a landmark's
rendered depth is its surface depth, or an occluder's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS, SIDES, BodyDimensions

#: Revolute joints per arm (3 shoulder, elbow flexion, forearm roll).
NUM_ARM_DOF = 5

#: Joint name suffixes per arm, in the order of an arm's q vector.
ARM_JOINT_SUFFIXES: tuple[str, ...] = (
    "shoulder_adduction",
    "shoulder_elevation",
    "humeral_rotation",
    "elbow_flexion",
    "forearm_roll",
)

#: Name of the operator's model instance.
MODEL_INSTANCE_NAME = "operator"

#: Default camera position in O: this far in front of the pelvis (along +x of O) ...
DEFAULT_CAMERA_DISTANCE_M = 2.0
#: ... at chest height above the pelvis. The camera looks back along -x of O.
DEFAULT_CAMERA_HEIGHT_M = 0.45

#: Forearm roll that puts the palm down in a T-pose (and thumb up with the arm forward, elbow flexed up).
NEUTRAL_FOREARM_ROLL = math.pi / 2

# Joint axes of the left arm in the (zero-configuration) body frames; the right arm uses -M a with
# M = diag(1, -1, 1), so that R_right(q) = M R_left(q) M.
_LEFT_AXES = np.array(
    [
        [0.0, 0.0, -1.0],  # shoulder adduction
        [1.0, 0.0, 0.0],  # shoulder elevation
        [0.0, 1.0, 0.0],  # humeral rotation (upper-arm long axis)
        [0.0, 0.0, -1.0],  # elbow flexion
        [0.0, 1.0, 0.0],  # forearm roll (forearm long axis)
    ]
)
_MIRROR = np.array([1.0, -1.0, 1.0])


def arm_joint_names(side: str) -> tuple[str, ...]:
    """Names of ``side``'s arm joints in the order of its q vector."""
    if side not in SIDES:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    return tuple(f"{side}_{s}" for s in ARM_JOINT_SUFFIXES)


def arm_joint_axes(side: str) -> np.ndarray:
    """``(NUM_ARM_DOF, 3)`` joint axes of ``side``'s arm, each in its body frame (aligned with O at q = 0)."""
    if side == "left":
        return _LEFT_AXES.copy()
    if side == "right":
        return -_LEFT_AXES * _MIRROR
    raise ValueError(f"side must be 'left' or 'right', got {side!r}")


@dataclass(frozen=True)
class OperatorParams:
    """Dimensions of the simulated operator, in metres (defaults: the paper's participant).

    Attributes:
        dims: arm segment lengths and shoulder width (joint centre to joint centre).
        torso_height: hip-joint centre line to shoulder-joint centre line.
        hip_width: distance between the two hip joint centres.
        upper_arm_radius: radius of the upper-arm capsule.
        forearm_radius: radius of the forearm capsule.
        deltoid_radius: radius of the sphere around each shoulder joint.
        hand_length: wrist to fingertips.
        hand_width: palm width at the knuckles.
        hand_thickness: palm thickness.
        knuckle_distance: wrist to the index MCP along the hand.
        knuckle_offset: half the distance between the index and pinky MCP, across the palm.
        wrist_extension_deg: the fixed wrist posture: extension (+, fingers toward the back of the hand)
            or flexion (-) of the hand relative to the forearm, degrees, in [-60, 70].
        chest_depth, chest_width: front-back and left-right size of the chest.
        pelvis_depth, pelvis_width: same for the pelvis.
        neck_radius, head_radius: neck cylinder and head sphere radii.
        thigh_radius, thigh_length: the upper legs (so the pelvis does not float).
        shirt_rgba, skin_rgba, trousers_rgba: colours (RGBA in [0, 1]).
    """

    dims: BodyDimensions = field(default_factory=BodyDimensions.paper_participant)
    torso_height: float = 0.50
    hip_width: float = 0.18
    upper_arm_radius: float = 0.045
    forearm_radius: float = 0.035
    deltoid_radius: float = 0.055
    hand_length: float = 0.185
    hand_width: float = 0.085
    hand_thickness: float = 0.03
    knuckle_distance: float = 0.09
    knuckle_offset: float = 0.03
    wrist_extension_deg: float = 20.0
    chest_depth: float = 0.21
    chest_width: float = 0.30
    pelvis_depth: float = 0.19
    pelvis_width: float = 0.32
    neck_radius: float = 0.055
    head_radius: float = 0.105
    thigh_radius: float = 0.075
    thigh_length: float = 0.40
    shirt_rgba: tuple[float, float, float, float] = (0.20, 0.35, 0.65, 1.0)
    skin_rgba: tuple[float, float, float, float] = (0.87, 0.70, 0.58, 1.0)
    trousers_rgba: tuple[float, float, float, float] = (0.22, 0.22, 0.25, 1.0)

    def __post_init__(self):
        if not isinstance(self.dims, BodyDimensions):
            raise ValueError(f"OperatorParams.dims must be a BodyDimensions, got {type(self.dims).__name__}")
        for f in fields(self):
            if f.name == "dims":
                continue
            if f.name == "wrist_extension_deg":
                v = self.wrist_extension_deg
                if not isinstance(v, (int, float)) or not math.isfinite(v) or not -60.0 <= v <= 70.0:
                    raise ValueError(
                        f"OperatorParams.wrist_extension_deg must be in [-60, 70] degrees, got {v!r}"
                    )
                continue
            v = getattr(self, f.name)
            if f.name.endswith("_rgba"):
                a = np.asarray(v, dtype=float)
                if a.shape != (4,) or not np.all((a >= 0) & (a <= 1)):
                    raise ValueError(f"OperatorParams.{f.name} must be 4 numbers in [0, 1], got {v!r}")
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v) or not 0.0 < v <= 1.5:
                raise ValueError(f"OperatorParams.{f.name} must be a length in (0, 1.5] m, got {v!r}")
        if self.knuckle_distance >= self.hand_length:
            raise ValueError(
                f"OperatorParams.knuckle_distance ({self.knuckle_distance}) must be shorter than "
                f"hand_length ({self.hand_length})"
            )
        if 2 * self.knuckle_offset >= self.hand_width:
            raise ValueError(
                f"OperatorParams.knuckle_offset ({self.knuckle_offset}) must be less than half of "
                f"hand_width ({self.hand_width})"
            )

    def scaled(self, k: float) -> OperatorParams:
        """The same operator with every length times ``k`` (a smaller or taller person of the same build; angles
        and colours kept): ``evaluate --body-scale``.

        Raises:
            ValueError: ``k`` not a positive finite number, or a length it puts out of range.
        """
        if isinstance(k, bool) or not isinstance(k, (int, float)) or not math.isfinite(k) or k <= 0.0:
            raise ValueError(f"OperatorParams.scaled: the factor must be a positive number, got {k!r}")
        lengths = {f.name: getattr(self, f.name) * k for f in fields(self)
                   if f.name != "dims" and f.name != "wrist_extension_deg" and not f.name.endswith("_rgba")}
        dims = BodyDimensions(**{n: v * k for n, v in self.dims.as_dict().items()})
        return replace(self, dims=dims, **lengths)

    def shoulder_O(self, side: str) -> np.ndarray:
        """Shoulder joint centre of ``side`` in O."""
        s = side_sign(side)
        return np.array([0.0, s * self.dims.SW / 2.0, self.torso_height])

    def hip_O(self, side: str) -> np.ndarray:
        """Hip joint centre of ``side`` in O."""
        s = side_sign(side)
        return np.array([0.0, s * self.hip_width / 2.0, 0.0])

    def R_H_hand(self, side: str) -> np.ndarray:
        """Rotation of ``side``'s hand (palm, fingers, knuckles) in its hand frame: the wrist posture.

        The hand frame (origin at the wrist) is aligned with O at q = 0; the hand itself is turned about
        the frame's z axis (the thumb axis, across the wrist) by ``wrist_extension_deg``, so that the fingers
        bend toward the back of the hand (-x of the hand frame, the palm facing +x) on both sides.
        """
        a = math.radians(self.wrist_extension_deg) * side_sign(side)
        c, sn = math.cos(a), math.sin(a)
        return np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])

    def index_H(self, side: str) -> np.ndarray:
        """Index MCP in ``side``'s hand frame (origin at the wrist, aligned with O at q = 0)."""
        s = side_sign(side)
        return self.R_H_hand(side) @ np.array([0.0, s * self.knuckle_distance, self.knuckle_offset])

    def pinky_H(self, side: str) -> np.ndarray:
        """Pinky MCP in ``side``'s hand frame (a little closer to the wrist than the index MCP)."""
        s = side_sign(side)
        p = np.array([0.0, s * (self.knuckle_distance - 0.008), -self.knuckle_offset])
        return self.R_H_hand(side) @ p


def side_sign(side: str) -> float:
    if side == "left":
        return 1.0
    if side == "right":
        return -1.0
    raise ValueError(f"side must be 'left' or 'right', got {side!r}")


# --------------------------------------------------------------------------------------------------
# Forward and inverse kinematics (pure numpy).
# --------------------------------------------------------------------------------------------------


def _rot(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotations ``(T, 3, 3)`` about a coordinate ``axis`` (signed unit basis vector) by angles ``q`` (T,)."""
    q = np.asarray(q, dtype=float)
    c, s = np.cos(q), np.sin(q)
    k = int(np.argmax(np.abs(axis)))
    s = s * np.sign(axis[k])
    R = np.zeros(q.shape + (3, 3))
    i, j = (k + 1) % 3, (k + 2) % 3
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def arm_rotations(side: str, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orientations in O of ``side``'s upper arm, forearm and hand for joint angles ``q`` (T, NUM_ARM_DOF).

    Returns:
        ``(R_OU, R_OF, R_OH)``, each ``(T, 3, 3)``.
    """
    q = _check_q(q, f"q_{side}")
    axes = arm_joint_axes(side)
    R_OU = _rot(axes[0], q[:, 0]) @ _rot(axes[1], q[:, 1]) @ _rot(axes[2], q[:, 2])
    R_OF = R_OU @ _rot(axes[3], q[:, 3])
    R_OH = R_OF @ _rot(axes[4], q[:, 4])
    return R_OU, R_OF, R_OH


def arm_forward_kinematics(side: str, q: np.ndarray, params: OperatorParams | None = None) -> np.ndarray:
    """Landmark positions in O of one arm.

    Args:
        side: "left" or "right".
        q: ``(T, NUM_ARM_DOF)`` or ``(NUM_ARM_DOF,)`` joint angles in radians.
        params: the operator's dimensions (default: the paper's participant).

    Returns:
        ``(T, 5, 3)`` positions of shoulder, elbow, wrist, index MCP, pinky MCP (``(5, 3)`` for a single q).
    """
    params = params or OperatorParams()
    single = np.ndim(q) == 1
    q2 = np.atleast_2d(np.asarray(q, dtype=float))
    s = side_sign(side)
    R_OU, R_OF, R_OH = arm_rotations(side, q2)
    p_S = params.shoulder_O(side)
    y = np.array([0.0, s, 0.0])
    p_E = p_S + params.dims.upper(side) * (R_OU @ y)
    p_W = p_E + params.dims.lower(side) * (R_OF @ y)
    p_I = p_W + R_OH @ params.index_H(side)
    p_P = p_W + R_OH @ params.pinky_H(side)
    out = np.stack([np.broadcast_to(p_S, p_E.shape), p_E, p_W, p_I, p_P], axis=1)
    return out[0] if single else out


def landmarks_from_q(
    q_left: np.ndarray, q_right: np.ndarray, params: OperatorParams | None = None
) -> np.ndarray:
    """All 12 landmarks in O, ``(T, 12, 3)`` in :data:`~akc_drake.core.skeleton.LANDMARKS` order."""
    params = params or OperatorParams()
    ql = np.atleast_2d(np.asarray(q_left, dtype=float))
    qr = np.atleast_2d(np.asarray(q_right, dtype=float))
    if ql.shape != qr.shape:
        raise ValueError(f"q_left and q_right must have the same shape, got {ql.shape} and {qr.shape}")
    T = ql.shape[0]
    out = np.empty((T, NUM_LANDMARKS, 3))
    for side, q in (("left", ql), ("right", qr)):
        fk = arm_forward_kinematics(side, q, params)
        for k, name in enumerate(("shoulder", "elbow", "wrist", "index", "pinky")):
            out[:, LANDMARKS.index(f"{side}_{name}")] = fk[:, k]
        out[:, LANDMARKS.index(f"{side}_hip")] = params.hip_O(side)
    return out


def _check_q(q, name: str) -> np.ndarray:
    a = np.atleast_2d(np.asarray(q, dtype=float))
    if a.ndim != 2 or a.shape[1] != NUM_ARM_DOF:
        raise ValueError(f"{name} must have shape (T, {NUM_ARM_DOF}), got {np.shape(q)}")
    return a


def _unit_rows(v, name: str, T: int | None = None) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3 or (T is not None and a.shape[0] != T):
        want = f"({T if T is not None else 'T'}, 3)"
        raise ValueError(f"{name} must have shape {want}, got {np.shape(v)}")
    n = np.linalg.norm(a, axis=1)
    bad = ~np.isfinite(n) | (n < 1e-12)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}[{k}] must be a finite non-zero direction, got {a[k].tolist()}")
    return a / n[:, None]


def _fill_undetermined(values: np.ndarray, ok: np.ndarray, default: float) -> np.ndarray:
    """Replace values where ``ok`` is False by the nearest earlier determined value (else the next one)."""
    out = values.copy()
    if not np.any(ok):
        out[:] = default
        return out
    idx = np.where(ok, np.arange(len(values)), -1)
    idx = np.maximum.accumulate(idx)
    first = int(np.flatnonzero(ok)[0])
    idx[idx < 0] = first
    return out[idx]


def _nearest_turn(a: float, ref: float) -> float:
    """``a + 2 pi k`` closest to ``ref``."""
    return a + 2.0 * math.pi * round((ref - a) / (2.0 * math.pi))


def _shoulder_branch(q0a: np.ndarray, q1a: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Continuous shoulder angles from the principal solution ``(q0a, q1a)`` (q1a in [-pi/2, pi/2]).

    Every direction has two solutions, ``(q0, q1)`` and ``(q0 + pi, pi - q1)``; frame by frame the one
    closest to the previous frame's angles is taken (both unwrapped), so an arm passing over the top keeps
    continuous angles. Where the arm is vertical (``ok`` False) the adduction angle is held (taken from the
    first determined frame before any).
    """
    T = len(q0a)
    out0, out1 = np.empty(T), np.empty(T)
    first = np.flatnonzero(ok)
    prev0 = float(q0a[first[0]]) if len(first) else 0.0
    prev1 = None
    a0, a1, oks = q0a.tolist(), q1a.tolist(), ok.tolist()
    for t in range(T):
        if oks[t]:
            cands = ((a0[t], a1[t]), (a0[t] + math.pi, math.pi - a1[t]))
        else:
            cands = ((prev0, a1[t]),)
        best = None
        for c0, c1 in cands:
            c0 = _nearest_turn(c0, prev0)
            c1 = c1 if prev1 is None else _nearest_turn(c1, prev1)
            cost = abs(c0 - prev0) + (0.0 if prev1 is None else abs(c1 - prev1))
            if best is None or cost < best[0] - 1e-12:
                best = (cost, c0, c1)
        _, prev0, prev1 = best
        out0[t], out1[t] = prev0, prev1
    return out0, out1


def arm_angles_from_directions(
    side: str,
    upper_dir_O: np.ndarray,
    fore_dir_O: np.ndarray,
    palm_normal_O: np.ndarray | None = None,
    *,
    singular_tol: float = 1e-6,
) -> np.ndarray:
    """Joint angles that point ``side``'s upper arm and forearm along the given directions (closed form).

    The exact inverse of :func:`arm_forward_kinematics` for the directions: ``R_OU y`` is the upper-arm
    direction, ``R_OF y`` the forearm direction (``y`` = +y for the left arm, -y for the right) and the palm
    normal is ``R_OH x``.

    The angles are continuous across frames: every upper-arm direction has two shoulder solutions and the one
    closest to the previous frame is taken; where an angle is undetermined (the upper arm vertical: shoulder
    adduction; the elbow straight: humeral rotation) it is held from the nearest frame where it is
    determined; angles that wrap are unwrapped along time. The elbow flexion stays anatomical (>= 0), so
    an elbow that straightens and then bends the other way turns the humerus in one frame.

    Args:
        side: "left" or "right".
        upper_dir_O: ``(T, 3)`` shoulder-to-elbow directions in O (normalised here).
        fore_dir_O: ``(T, 3)`` elbow-to-wrist directions in O.
        palm_normal_O: optional ``(T, 3)`` palm normals in O (out of the palm); only its component
            perpendicular to the forearm matters. None: the neutral forearm roll
            (:data:`NEUTRAL_FOREARM_ROLL`: palm down in a T-pose).
        singular_tol: below this sine an angle counts as undetermined.

    Returns:
        ``(T, NUM_ARM_DOF)`` joint angles in radians.

    Raises:
        ValueError: a wrong shape, or a non-finite or zero direction (naming the argument and frame).
    """
    s = side_sign(side)
    u = _unit_rows(upper_dir_O, "upper_dir_O")
    T = u.shape[0]
    f = _unit_rows(fore_dir_O, "fore_dir_O", T)
    n = None if palm_normal_O is None else _unit_rows(palm_normal_O, "palm_normal_O", T)
    # Solve the left arm's equations on the mirrored directions (R_right = M R_left M).
    if s < 0:
        u, f = u * _MIRROR, f * _MIRROR
        n = None if n is None else n * _MIRROR
    # Upper arm: u = Rz(-q0) Rx(q1) y = (sin q0 cos q1, cos q0 cos q1, sin q1).
    horiz = np.hypot(u[:, 0], u[:, 1])
    q0, q1 = _shoulder_branch(np.arctan2(u[:, 0], u[:, 1]), np.arctan2(u[:, 2], horiz), horiz > singular_tol)
    # Elbow flexion: the angle between u and f.
    cross = np.cross(u, f)
    sin4 = np.linalg.norm(cross, axis=1)
    q3 = np.arctan2(sin4, np.einsum("ij,ij->i", u, f))
    # Humeral rotation: g = (Rz(-q0) Rx(q1))^T f = (sin q3 cos q2, cos q3, -sin q3 sin q2).
    axes = _LEFT_AXES
    R12 = _rot(axes[0], q0) @ _rot(axes[1], q1)
    g = np.einsum("tji,tj->ti", R12, f)
    q2 = _fill_undetermined(np.arctan2(-g[:, 2], g[:, 0]), sin4 > singular_tol, 0.0)
    q2 = np.unwrap(q2)
    # Forearm roll: palm normal in the forearm frame = (cos q4, 0, -sin q4).
    if n is None:
        q4 = np.full(T, NEUTRAL_FOREARM_ROLL)
    else:
        R_OF = R12 @ _rot(axes[2], q2) @ _rot(axes[3], q3)
        nF = np.einsum("tji,tj->ti", R_OF, n)
        ok = np.hypot(nF[:, 0], nF[:, 2]) > singular_tol
        q4 = np.unwrap(_fill_undetermined(np.arctan2(-nF[:, 2], nF[:, 0]), ok, NEUTRAL_FOREARM_ROLL))
    return np.stack([q0, q1, q2, q3, q4], axis=1)


def full_q(q_left: np.ndarray, q_right: np.ndarray) -> np.ndarray:
    """The operator's joint vector in our canonical order: ``[q_left, q_right]``, ``(T, 2 * NUM_ARM_DOF)``."""
    ql = _check_q(q_left, "q_left")
    qr = _check_q(q_right, "q_right")
    if ql.shape != qr.shape:
        raise ValueError(f"q_left and q_right must have the same shape, got {ql.shape} and {qr.shape}")
    return np.concatenate([ql, qr], axis=1)
