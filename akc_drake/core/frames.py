"""Stage S5's control frames (paper eq. 17) and their mapping to the robot's end-effector frames.

Frames and conventions:

* Camera frame C: x right, y down, z forward (metres). The operator faces the camera, so the operator's left
  is +x_C, up is -y_C and forward (toward the camera) is -z_C.
* Operator torso frame {0} (eq. 17): y = ps_l - ps_r (to the operator's left), x = (ph_m - ps_m) x y
  (forward), z = x x y (up), origin at the shoulder midpoint ps_m. All functions here work in any coordinates
  the landmarks are given in; with camera-frame landmarks the rotation returned by :func:`torso_frame` is
  ``R_CTorso``.
* Wrist frame {1}/{2} (eq. 17): y = p_e - p_w (from the wrist back toward the elbow), z = y x (p_i - p_p),
  x = y x z. Note that eq. (17) uses ``p_i - p_p`` on both hands, so z (and x) point to opposite anatomical
  sides on the two hands: with the forearm forward and the palm down, z points up on the left hand and down on
  the right hand.
* Mapped wrist frame {1'}: {1} rotated by -90 deg about its own y axis: x' = z, y' = y, z' = -x.
* Robot torso frame T: x forward, y left, z up. Robot end-effector frame E (``left_ee``/``right_ee``): y from
  the tool back toward the wrist/elbow, x along the palm normal; E is the mapped frame {1'} followed by the
  per-side extra rotation of :class:`RobotMapping`. By default the right side uses {1'} as it is (its x' is
  the palmar normal, out of the palm) and the left side is turned 180 deg about y so that its x is also the
  palmar normal (eq. 17's x' on the left hand is the back-of-hand normal); both E frames are then mirror
  images.

Degenerate input (a zero-length vector, parallel vectors, NaN or inf) gives ``None``, never NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from akc_drake.core.skeleton import INDEX, SIDES, check_pose

#: Vectors shorter than this (metres) are degenerate.
MIN_NORM_M = 1e-6
#: Two directions whose angle has a sine below this are treated as parallel.
MIN_SIN = 1e-6

#: Robot arm reach (shoulder-elbow + elbow-wrist, metres) used by the default mapping (0.34 + 0.35).
DEFAULT_ROBOT_REACH_M = 0.69
#: Operator arm reach (upper + lower arm, metres) used by the default mapping (the paper's participant).
DEFAULT_HUMAN_REACH_M = 0.57
#: Operator shoulder width (metres) used to put the human shoulder on the robot's shoulder.
DEFAULT_HUMAN_SHOULDER_WIDTH_M = 0.33
#: Robot shoulder position in the robot torso frame T: x, |y|, z (metres); left at +y, right at -y.
DEFAULT_ROBOT_SHOULDER_X_M = 0.0
DEFAULT_ROBOT_SHOULDER_Y_M = 0.20
DEFAULT_ROBOT_SHOULDER_Z_M = 0.0


def rotation_x(angle: float) -> np.ndarray:
    """Rotation matrix about x by ``angle`` radians."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(angle: float) -> np.ndarray:
    """Rotation matrix about y by ``angle`` radians."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(angle: float) -> np.ndarray:
    """Rotation matrix about z by ``angle`` radians."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: {1} -> {1'}: -90 deg about the wrist frame's own y axis (right-multiplied): x' = z, y' = y, z' = -x.
R_WRIST_TO_MAPPED: np.ndarray = rotation_y(-math.pi / 2.0)


def transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """4x4 homogeneous transform from a rotation ``R`` (3x3) and a translation ``p`` (3,)."""
    X = np.eye(4)
    X[:3, :3] = R
    X[:3, 3] = p
    return X


def _vec(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {a.shape}")
    return a


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """3-vector cross product (np.cross costs ~10x more for single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _unit(v: np.ndarray) -> np.ndarray | None:
    n = float(np.linalg.norm(v))
    if not math.isfinite(n) or n < MIN_NORM_M:
        return None
    return v / n


def _unit_cross(a: np.ndarray, b: np.ndarray) -> np.ndarray | None:
    """Normalised ``a x b`` for unit ``a``, or None when ``b`` is too short or parallel to ``a``."""
    nb = float(np.linalg.norm(b))
    if not math.isfinite(nb) or nb < MIN_NORM_M:
        return None
    c = _cross(a, b)
    nc = float(np.linalg.norm(c))
    if nc < MIN_SIN * nb:
        return None
    return c / nc


def wrist_frame(p_e, p_w, p_i, p_p) -> np.ndarray | None:
    """The wrist frame of eq. (17) as a rotation matrix whose columns are its x, y, z axes.

    Args:
        p_e, p_w, p_i, p_p: elbow, wrist, index MCP and pinky MCP positions (3,).

    Returns:
        3x3 right-handed orthonormal ``R`` with y = unit(p_e - p_w), z = unit(y x (p_i - p_p)), x = y x z;
        None when the forearm or the hand vector is degenerate, they are parallel, or an input is not finite.
    """
    p_e, p_w, p_i, p_p = (_vec(v, n) for v, n in ((p_e, "p_e"), (p_w, "p_w"), (p_i, "p_i"), (p_p, "p_p")))
    # Eq. (17): f_w,y = p_e - p_w
    y = _unit(p_e - p_w)
    if y is None:
        return None
    # Eq. (17): f_w,z = f_w,y x (p_i - p_p)
    z = _unit_cross(y, p_i - p_p)
    if z is None:
        return None
    # Eq. (17): f_w,x = f_w,y x f_w,z
    x = _cross(y, z)
    return np.column_stack([x, y, z])


def torso_frame(ps_l, ps_r, ph_l, ph_r) -> tuple[np.ndarray, np.ndarray] | None:
    """The torso frame {0} of eq. (17).

    Args:
        ps_l, ps_r: left and right shoulder positions (3,).
        ph_l, ph_r: left and right hip positions (3,).

    Returns:
        ``(R, origin)``: 3x3 right-handed orthonormal ``R`` with y = unit(ps_l - ps_r),
        x = unit((ph_m - ps_m) x y), z = x x y, and the origin at the shoulder midpoint ps_m; None when the
        shoulders coincide, the trunk (ph_m - ps_m) is degenerate or parallel to the shoulder line, or an
        input is not finite.
    """
    ps_l, ps_r, ph_l, ph_r = (_vec(v, n) for v, n in ((ps_l, "ps_l"), (ps_r, "ps_r"), (ph_l, "ph_l"), (ph_r, "ph_r")))
    ps_m = 0.5 * (ps_l + ps_r)
    ph_m = 0.5 * (ph_l + ph_r)
    # Eq. (17): f_t,y = p_s,l - p_s,r
    y = _unit(ps_l - ps_r)
    if y is None or not np.all(np.isfinite(ps_m)):
        return None
    # Eq. (17): f_t,x = (p_h,m - p_s,m) x f_t,y   (computed as -(f_t,y x (p_h,m - p_s,m)))
    x = _unit_cross(y, ph_m - ps_m)
    if x is None:
        return None
    x = -x
    # Eq. (17): f_t,z = f_t,x x f_t,y
    z = _cross(x, y)
    return np.column_stack([x, y, z]), ps_m


def _landmark(pose: np.ndarray, name: str) -> np.ndarray:
    return pose[INDEX[name]]


def torso_of(pose) -> tuple[np.ndarray, np.ndarray] | None:
    """The torso frame ``(R, origin)`` of a landmark pose ``(12, 3)`` (eq. 17), None when degenerate."""
    pose = check_pose(pose)
    return torso_frame(
        _landmark(pose, "left_shoulder"),
        _landmark(pose, "right_shoulder"),
        _landmark(pose, "left_hip"),
        _landmark(pose, "right_hip"),
    )


def wrist_in_torso(pose, torso=None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Both wrist frames {1}, {2} relative to the torso frame {0}.

    Args:
        pose: ``(12, 3)`` landmarks (any frame, e.g. the camera frame C); NaN where missing.

    Returns:
        ``(X_left, X_right)``: 4x4 homogeneous transforms ``X_TorsoWrist`` (rotation of the wrist frame and
        position of the wrist in {0}), each None when that wrist frame (or the torso frame) is degenerate.
    """
    pose = check_pose(pose)
    if torso is None:
        torso = torso_of(pose)
    if torso is None:
        return None, None
    R_0, origin = torso
    out = []
    for side in SIDES:
        p_w = _landmark(pose, f"{side}_wrist")
        R_w = wrist_frame(
            _landmark(pose, f"{side}_elbow"),
            p_w,
            _landmark(pose, f"{side}_index"),
            _landmark(pose, f"{side}_pinky"),
        )
        if R_w is None:
            out.append(None)
            continue
        out.append(transform(R_0.T @ R_w, R_0.T @ (p_w - origin)))
    return out[0], out[1]


def _check_rotation(R, name: str) -> np.ndarray:
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError(f"{name} must be a finite 3x3 rotation matrix, got shape {R.shape}")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0.0:
        raise ValueError(f"{name} must be a proper rotation matrix (orthonormal, det +1), got {R.tolist()}")
    return R


def _check_point(p, name: str) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{name} must be a finite 3-vector in metres, got {np.asarray(p).tolist()}")
    return p


@dataclass(frozen=True)
class RobotMapping:
    """How an operator wrist pose in the torso frame {0} becomes a robot end-effector pose in T.

    ``R_TE = R_0W @ R_WRIST_TO_MAPPED @ R_extra_side`` and
    ``p_TE = scale * p_0W + offset_side - tool_offset_m * R_TE[:, 1]``.

    Attributes:
        scale: position scale (robot arm reach / operator arm reach).
        offset_left, offset_right: translations added in the robot torso frame T, metres.
        R_extra_left, R_extra_right: rotations applied about the mapped frame {1'}'s own axes.
        tool_offset_m: distance from the robot's wrist centre to its tool point E (along -y_E). With 0 (the
            default) the scaled operator wrist is the target of E itself; with the robot's wrist-to-tool
            distance (0.195 m for ``models/dual_arm_manipulator.urdf``) the robot's wrist centre follows the
            scaled operator wrist and the tool point sits that far beyond it.

    Use :meth:`from_shoulders` (or :meth:`default`) for offsets that put the operator's shoulder on the
    robot's.
    """

    scale: float = DEFAULT_ROBOT_REACH_M / DEFAULT_HUMAN_REACH_M
    offset_left: np.ndarray = field(default_factory=lambda: np.zeros(3))
    offset_right: np.ndarray = field(default_factory=lambda: np.zeros(3))
    R_extra_left: np.ndarray = field(default_factory=lambda: rotation_y(math.pi))
    R_extra_right: np.ndarray = field(default_factory=lambda: np.eye(3))
    tool_offset_m: float = 0.0

    def __post_init__(self):
        s = float(self.scale)
        if not math.isfinite(s) or s <= 0.0:
            raise ValueError(f"RobotMapping.scale must be a positive number, got {self.scale!r}")
        object.__setattr__(self, "scale", s)
        tool = float(self.tool_offset_m)
        if not math.isfinite(tool) or tool < 0.0:
            raise ValueError(f"RobotMapping.tool_offset_m must be a length >= 0 in metres, got {self.tool_offset_m!r}")
        object.__setattr__(self, "tool_offset_m", tool)
        for name in ("offset_left", "offset_right"):
            object.__setattr__(self, name, _check_point(getattr(self, name), f"RobotMapping.{name}"))
        for name in ("R_extra_left", "R_extra_right"):
            object.__setattr__(self, name, _check_rotation(getattr(self, name), f"RobotMapping.{name}"))

    @classmethod
    def from_shoulders(
        cls,
        *,
        robot_reach_m: float = DEFAULT_ROBOT_REACH_M,
        human_reach_m: float = DEFAULT_HUMAN_REACH_M,
        human_shoulder_width_m: float = DEFAULT_HUMAN_SHOULDER_WIDTH_M,
        robot_shoulder_x_m: float = DEFAULT_ROBOT_SHOULDER_X_M,
        robot_shoulder_y_m: float = DEFAULT_ROBOT_SHOULDER_Y_M,
        robot_shoulder_z_m: float = DEFAULT_ROBOT_SHOULDER_Z_M,
        R_extra_left: np.ndarray | None = None,
        R_extra_right: np.ndarray | None = None,
        tool_offset_m: float = 0.0,
    ) -> RobotMapping:
        """A mapping whose offsets put the operator's shoulder (at ``(0, ±width/2, 0)`` in {0}) on the
        robot's shoulder (at ``(x, ±y, z)`` in T), with ``scale = robot_reach_m / human_reach_m``.

        Defaults: reach 0.69 m robot / 0.57 m operator, operator shoulder width 0.33 m, robot shoulders at
        ``(0, ±0.20, 0)`` m; extra rotations as the class defaults (left 180 deg about y, right identity).
        """
        for name, v in (
            ("robot_reach_m", robot_reach_m),
            ("human_reach_m", human_reach_m),
            ("human_shoulder_width_m", human_shoulder_width_m),
        ):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise ValueError(f"RobotMapping.from_shoulders: {name} must be a positive length, got {v!r}")
        scale = robot_reach_m / human_reach_m
        human_y = 0.5 * human_shoulder_width_m
        offsets = {}
        for side, sign in (("left", 1.0), ("right", -1.0)):
            robot_shoulder = np.array([robot_shoulder_x_m, sign * robot_shoulder_y_m, robot_shoulder_z_m])
            offsets[side] = robot_shoulder - scale * np.array([0.0, sign * human_y, 0.0])
        kwargs = {}
        if R_extra_left is not None:
            kwargs["R_extra_left"] = R_extra_left
        if R_extra_right is not None:
            kwargs["R_extra_right"] = R_extra_right
        return cls(
            scale=scale,
            offset_left=offsets["left"],
            offset_right=offsets["right"],
            tool_offset_m=tool_offset_m,
            **kwargs,
        )

    @classmethod
    def default(cls) -> RobotMapping:
        """:meth:`from_shoulders` with all defaults."""
        return cls.from_shoulders()

    def offset(self, side: str) -> np.ndarray:
        return self.offset_left if _side(side) == "left" else self.offset_right

    def R_extra(self, side: str) -> np.ndarray:
        return self.R_extra_left if _side(side) == "left" else self.R_extra_right


def _side(side: str) -> str:
    if side not in SIDES:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    return side


def _check_transform(X, name: str) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 homogeneous transform, got shape {X.shape}")
    return X


def map_to_robot(X_TorsoWrist, side: str, mapping: RobotMapping | None = None) -> np.ndarray:
    """Map an operator wrist frame in the torso frame {0} to the robot end-effector pose ``X_TE``.

    Args:
        X_TorsoWrist: 4x4 wrist frame {1}/{2} in {0} (from :func:`wrist_in_torso`).
        side: ``"left"`` or ``"right"``.
        mapping: the robot mapping (default :meth:`RobotMapping.default`).

    Returns:
        4x4 ``X_TE``: ``R_TE = R_0W R_y(-90 deg) R_extra_side``,
        ``p_TE = scale p_0W + offset_side - tool_offset_m y_E``.
    """
    X = _check_transform(X_TorsoWrist, "X_TorsoWrist")
    side = _side(side)
    m = mapping if mapping is not None else RobotMapping.default()
    R = X[:3, :3] @ R_WRIST_TO_MAPPED @ m.R_extra(side)
    p = m.scale * X[:3, 3] + m.offset(side) - m.tool_offset_m * R[:, 1]
    return transform(R, p)


def robot_targets(pose, mapping: RobotMapping | None = None, torso=None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(X_TE_left, X_TE_right)`` for a landmark pose ``(12, 3)``; None for a side whose frame is
    degenerate. ``torso``: a torso frame ``(R, origin)`` to use instead of the pose's own (e.g. smoothed)."""
    m = mapping if mapping is not None else RobotMapping.default()
    X_l, X_r = wrist_in_torso(pose, torso)
    return (
        None if X_l is None else map_to_robot(X_l, "left", m),
        None if X_r is None else map_to_robot(X_r, "right", m),
    )


#: Fastest plausible speed (m/s) of the landmarks a robot target is built from (wrist, hand, hips). In the
#: rendered Motions I and II, after the filter and AKC, wrists and hands move at up to 1.2 m/s and hips at
#: 0.2 m/s; a landmark that would have to move faster than this is a detector or depth fault, not a motion.
#: (Shoulders and elbows are not gated: AKC's choice between mirror candidates moves them by up to 3 m/s.)
DEFAULT_MAX_LANDMARK_SPEED = 4.0

#: Per side, the landmarks :func:`plausible_step` checks before a target is accepted.
SPEED_GATED_LANDMARKS: dict[str, tuple[str, ...]] = {
    side: (f"{side}_wrist", f"{side}_index", f"{side}_pinky", "left_hip", "right_hip") for side in SIDES
}


def plausible_step(p_prev, p_new, dt: float, max_speed: float) -> bool:
    """Whether points ``(3,)`` or ``(N, 3)`` can go from ``p_prev`` to ``p_new`` in ``dt`` s at ``max_speed``.

    The speed gate of the robot targets: a frame whose landmarks would need a faster motion is treated as a
    fault. Since ``dt`` is the time since the last accepted frame, points that really moved are accepted as
    soon as enough time has passed (the gate cannot lock a track out).

    Returns:
        False when a point is not finite or moved further than ``max_speed * dt`` (plus 1 um).
    """
    a = np.asarray(p_prev, dtype=float)
    b = np.asarray(p_new, dtype=float)
    if a.shape != b.shape or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return False
    d = np.linalg.norm(np.atleast_2d(b - a), axis=1)
    return bool(np.all(d <= max_speed * max(float(dt), 0.0) + 1e-6))


def rest_operator_pose(
    *,
    upper_arm_m: float = 0.288,
    lower_arm_m: float = 0.28,
    shoulder_width_m: float = DEFAULT_HUMAN_SHOULDER_WIDTH_M,
) -> np.ndarray:
    """A ``(12, 3)`` operator rest posture in its own torso frame {0} (x forward, y left, z up): upper arms
    hanging down, forearms horizontal and pointing forward, palms facing each other (thumbs up), hips 0.45 m
    below the shoulders."""
    pose = np.zeros((12, 3))
    hand = 0.08
    for side, sign in (("left", 1.0), ("right", -1.0)):
        s = np.array([0.0, sign * 0.5 * shoulder_width_m, 0.0])
        e = s + np.array([0.0, 0.0, -upper_arm_m])
        w = e + np.array([lower_arm_m, 0.0, 0.0])
        pose[INDEX[f"{side}_shoulder"]] = s
        pose[INDEX[f"{side}_elbow"]] = e
        pose[INDEX[f"{side}_wrist"]] = w
        pose[INDEX[f"{side}_index"]] = w + np.array([hand, 0.0, 0.02])
        pose[INDEX[f"{side}_pinky"]] = w + np.array([hand, 0.0, -0.02])
        pose[INDEX[f"{side}_hip"]] = np.array([0.0, sign * 0.1, -0.45])
    return pose


def default_home_pose(side: str, mapping: RobotMapping | None = None, **rest_kwargs) -> np.ndarray:
    """The 4x4 ``X_TE`` of :func:`rest_operator_pose` mapped to the robot on ``side``: the FrameMapper's home
    pose when no robot-specific nominal pose is given."""
    side = _side(side)
    X_l, X_r = wrist_in_torso(rest_operator_pose(**rest_kwargs))
    return map_to_robot(X_l if side == "left" else X_r, side, mapping)


def rotation_angle(R: np.ndarray) -> float:
    """Angle (radians, in [0, pi]) of the rotation ``R``, accurate for small angles."""
    sin_vec = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    cos_t = 0.5 * (float(np.trace(R)) - 1.0)
    return math.atan2(float(np.linalg.norm(sin_vec)), cos_t)


def frame_jitter(X_seq, dt: float) -> tuple[float, float]:
    """Jitter of a sequence of frames: RMS angular and linear speed between consecutive frames.

    Args:
        X_seq: ``(T, 4, 4)`` homogeneous transforms; frames with any non-finite entry are skipped (a pair
            counts only when both of its frames are finite).
        dt: time between consecutive frames, seconds (> 0).

    Returns:
        ``(rms angular speed rad/s, rms linear speed m/s)``; NaN when there is no valid consecutive pair.
    """
    X = np.asarray(X_seq, dtype=float)
    if X.ndim != 3 or X.shape[1:] != (4, 4):
        raise ValueError(f"X_seq must have shape (T, 4, 4), got {X.shape}")
    dt = float(dt)
    if not math.isfinite(dt) or dt <= 0.0:
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    finite = np.all(np.isfinite(X), axis=(1, 2))
    ang, lin = [], []
    for k in range(len(X) - 1):
        if not (finite[k] and finite[k + 1]):
            continue
        ang.append(rotation_angle(X[k, :3, :3].T @ X[k + 1, :3, :3]) / dt)
        lin.append(float(np.linalg.norm(X[k + 1, :3, 3] - X[k, :3, 3])) / dt)
    if not ang:
        return float("nan"), float("nan")
    return float(np.sqrt(np.mean(np.square(ang)))), float(np.sqrt(np.mean(np.square(lin))))


# ------------------------------------------------------------------------------------------------------------
# The torso from the hips (calibrated) and the robot's workspace


def _hip_frame(ph_l: np.ndarray, ph_r: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """Rotation (columns x forward, y left, z up) of the hip line ``ph_l - ph_r`` with ``up`` as the vertical
    (orthogonalised); None when degenerate."""
    y = _unit(ph_l - ph_r)
    if y is None:
        return None
    x = _unit_cross(y, up)  # y x up = forward for a person facing the camera
    if x is None:
        return None
    z = _cross(x, y)
    return np.column_stack([x, y, z])


@dataclass(frozen=True)
class TorsoModel:
    """The operator's torso as a rigid body carried by the hips, calibrated from a held pose (the T-pose).

    Why: eq. (17) builds the torso frame from the shoulders, the landmarks most often occluded in teleoperation
    (the arms reach toward the camera and hide them), and a corrector may put a hidden shoulder at the wrong
    depth (its mirror candidate), which yaws the frame and moves every wrist target. The hips stay in view. At
    calibration the whole torso is seen: the torso frame {0} of eq. (17) is stored relative to a hip frame
    (hip line + the camera-frame vertical ``up_C`` of the calibrated torso). During teleoperation the torso is
    the hip frame times that fixed transform: it follows the operator stepping and turning (translation, yaw)
    but not bending at the waist or twisting the shoulders against the hips (the limitation of the model).

    Attributes:
        R_hip_torso: ``(3, 3)`` rotation of {0} in the hip frame.
        p_hip_torso: ``(3,)`` position of {0}'s origin (the shoulder midpoint) in the hip frame, metres.
        up_C: ``(3,)`` unit vertical of the calibrated torso ({0}'s z) in the camera frame.
    """

    R_hip_torso: np.ndarray
    p_hip_torso: np.ndarray
    up_C: np.ndarray

    @classmethod
    def calibrate(cls, poses) -> TorsoModel:
        """Calibrate from ``(T, 12, 3)`` camera-frame poses of a held pose (frames with missing torso landmarks
        are skipped; the landmarks are averaged first).

        Raises:
            ValueError: no frame with all four torso landmarks, or a degenerate mean torso.
        """
        P = np.asarray(poses, dtype=float).reshape(-1, 12, 3)
        idx = [INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_hip", "right_hip")]
        ok = np.all(np.isfinite(P[:, idx]), axis=(1, 2))
        if not ok.any():
            raise ValueError("TorsoModel.calibrate: no frame shows both shoulders and both hips")
        mean = np.mean(P[ok], axis=0)
        torso = torso_of(np.where(np.isfinite(mean), mean, 0.0))
        if torso is None:
            raise ValueError("TorsoModel.calibrate: the mean torso is degenerate")
        R_C0, o_C = torso
        up = R_C0[:, 2]
        ph_l, ph_r = mean[INDEX["left_hip"]], mean[INDEX["right_hip"]]
        R_Ch = _hip_frame(ph_l, ph_r, up)
        if R_Ch is None:
            raise ValueError("TorsoModel.calibrate: the hips are degenerate")
        hip_o = 0.5 * (ph_l + ph_r)
        return cls(R_hip_torso=R_Ch.T @ R_C0, p_hip_torso=R_Ch.T @ (o_C - hip_o), up_C=up)

    def torso(self, pose) -> tuple[np.ndarray, np.ndarray] | None:
        """The torso frame ``(R, origin)`` of a ``(12, 3)`` pose from its hips; None when they are missing."""
        pose = np.asarray(pose, dtype=float)
        ph_l, ph_r = pose[INDEX["left_hip"]], pose[INDEX["right_hip"]]
        if not (np.all(np.isfinite(ph_l)) and np.all(np.isfinite(ph_r))):
            return None
        R_Ch = _hip_frame(ph_l, ph_r, self.up_C)
        if R_Ch is None:
            return None
        return R_Ch @ self.R_hip_torso, 0.5 * (ph_l + ph_r) + R_Ch @ self.p_hip_torso


#: The robot's reachable shell per arm, around its shoulder (metres, tool point E): the arm reaches 0.885 m
#: (0.34 + 0.35 + 0.195) fully stretched; targets are kept within 0.80 m (away from the stretched-arm
#: singularity) and beyond 0.25 m (the gripper folded onto the shoulder).
WORKSPACE_MAX_M = 0.80
WORKSPACE_MIN_M = 0.25
#: Targets are kept at least this far in front of the torso plane (x in T), so the gripper never aims into
#: the robot's own body.
WORKSPACE_MIN_X_M = 0.25


@dataclass(frozen=True)
class Workspace:
    """The reachable region of one arm's tool point in T: a spherical shell around the shoulder, cut by a
    plane in front of the torso. :meth:`clip` projects a target position into it.

    Attributes:
        shoulder: ``(3,)`` the arm's shoulder in T.
        r_min, r_max: the shell's radii, metres.
        x_min: the cutting plane (x in T), metres.
    """

    shoulder: np.ndarray
    r_min: float = WORKSPACE_MIN_M
    r_max: float = WORKSPACE_MAX_M
    x_min: float = WORKSPACE_MIN_X_M

    @classmethod
    def for_side(cls, side: str) -> Workspace:
        sign = 1.0 if _side(side) == "left" else -1.0
        return cls(
            shoulder=np.array(
                [DEFAULT_ROBOT_SHOULDER_X_M, sign * DEFAULT_ROBOT_SHOULDER_Y_M, DEFAULT_ROBOT_SHOULDER_Z_M]
            )
        )

    def contains(self, p, tol: float = 1e-9) -> bool:
        p = np.asarray(p, dtype=float)
        r = float(np.linalg.norm(p - self.shoulder))
        return self.r_min - tol <= r <= self.r_max + tol and p[0] >= self.x_min - tol

    def clip(self, p) -> tuple[np.ndarray, bool]:
        """``(p_clipped, clipped)``: ``p`` projected into the workspace (unchanged when inside)."""
        p = np.asarray(p, dtype=float).copy()
        if self.contains(p):
            return p, False
        p[0] = max(p[0], self.x_min)  # onto the half-space in front of the torso
        d = p - self.shoulder
        r = float(np.linalg.norm(d))
        if r > self.r_max:
            q = self.shoulder + d * (self.r_max / r)
            if q[0] < self.x_min:
                # The radial point leaves the half-space: the closest point is on the circle where the sphere
                # meets the plane x = x_min, toward p.
                rho = math.sqrt(max(self.r_max**2 - (self.x_min - self.shoulder[0]) ** 2, 0.0))
                yz = d[1:]
                n = float(np.linalg.norm(yz))
                u = yz / n if n > 1e-12 else np.array([0.0, 1.0])
                q = np.concatenate([[self.x_min], self.shoulder[1:] + rho * u])
            p = q
        elif r < self.r_min:
            # Outward from the shoulder: x only grows (d_x >= x_min - shoulder_x > 0), so p stays in front.
            u = d / r if r > 1e-9 else np.array([1.0, 0.0, 0.0])
            p = self.shoulder + u * self.r_min
        return p, True


def calibrated_mapping(dims, **kwargs) -> RobotMapping:
    """The operator-to-robot mapping calibrated from the operator's T-pose dimensions.

    ``scale = robot reach / operator reach`` where the operator reach is the mean of the two calibrated arms
    (upper + lower arm, so both robot arms move alike and the mapping stays a mirror image), and the operator's
    shoulders (calibrated width ``SW``) are put on the robot's. Further keyword arguments go to
    :meth:`RobotMapping.from_shoulders`.

    Args:
        dims: the calibrated :class:`~akc_drake.core.skeleton.BodyDimensions`.
    """
    reach = 0.5 * (dims.LUA + dims.LLA + dims.RUA + dims.RLA)
    return RobotMapping.from_shoulders(human_reach_m=float(reach), human_shoulder_width_m=float(dims.SW), **kwargs)


#: A hand vector ``p_i - p_p`` with this image-plane share (forearm in the image plane) is trusted (resolve_wrist_flip).
HAND_VECTOR_RELIABLE_SHARE = 0.6
#: Rotation about the wrist frame's y axis by pi: the mirror configuration of eq. (17) (z and x negated).
R_FLIP_Y: np.ndarray = np.diag([-1.0, 1.0, -1.0])


def resolve_wrist_flip(R_C, hand_vector_C, R_previous_C) -> np.ndarray:
    """Keep a camera-frame wrist frame of eq. (17) on the same side as the previous one when its hand vector
    is unreliable: when ``p_i - p_p`` points mostly along the camera ray (the palm seen edge-on, e.g. palms down in a
    T-pose), its sign comes from two noisy (and self-occluded) depths and the frame flips by pi about its y axis from
    one frame to the next; of the measured frame and its mirror (``R_C @ R_FLIP_Y``), the one closer to the previous
    frame is taken. A hand vector whose depth's sign barely matters is taken as measured (and re-seeds the branch):
    its parts across the forearm (the frame's y) with either sign are at most ``acos(2 s^2 - 1)`` apart, ``s`` =
    :data:`HAND_VECTOR_RELIABLE_SHARE` (forearm in the image plane: image share >= ``s``; a forearm toward the camera
    sees the hand across it in the image, where the image share alone held a mirrored frame 1.5 s).

    Args:
        R_C: ``(3, 3)`` the measured wrist frame in C; hand_vector_C: ``(3,)`` ``p_i - p_p`` in C;
        R_previous_C: the previous frame in C, or None.
    """
    if R_previous_C is None:
        return R_C
    h = np.asarray(hand_vector_C, dtype=float)
    y, g = np.asarray(R_C, dtype=float)[:, 1], h * np.array([1.0, 1.0, -1.0])  # g: the other sign of the depth
    a, b = h - float(h @ y) * y, g - float(g @ y) * y
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if na > MIN_NORM_M and nb > MIN_NORM_M and float(a @ b) >= (2 * HAND_VECTOR_RELIABLE_SHARE**2 - 1) * na * nb:
        return R_C
    mirror = R_C @ R_FLIP_Y
    if rotation_angle(R_previous_C.T @ mirror) < rotation_angle(R_previous_C.T @ R_C):
        return mirror
    return R_C


#: Initial estimate of the index-to-pinky knuckle distance (metres) before it is learnt from the operator.
DEFAULT_HAND_WIDTH_M = 0.07
#: The knuckle line is ~perpendicular to the forearm (ulnar/radial deviation <= ~30 deg): the depth sign more
#: perpendicular to it wins when their |cos| differ by this much. Image part > HAND_OUTLIER_WIDTHS widths: failed.
FOREARM_SIGN_MARGIN, HAND_OUTLIER_WIDTHS = 0.6, 1.5


def forearm_depth_sign(h_C, dz: float, forearm_C) -> float:
    """+1 / -1: the sign of the depth part ``dz`` whose hand vector is more perpendicular to the forearm
    ``p_e - p_w`` by :data:`FOREARM_SIGN_MARGIN` in |cos|; 0 when undecided (e.g. a forearm in the image plane)."""
    h, f = np.asarray(h_C, dtype=float), np.asarray(forearm_C if forearm_C is not None else np.full(3, np.nan), float)
    nf, dxy2 = float(np.linalg.norm(f)), float(h[0] ** 2 + h[1] ** 2)
    if not (math.isfinite(nf) and nf > MIN_NORM_M):
        return 0.0
    c_p, c_m = (abs(float(h[:2] @ f[:2]) + sg * dz * f[2]) / (nf * math.sqrt(dxy2 + dz**2)) for sg in (1, -1))
    return 0.0 if abs(c_p - c_m) < FOREARM_SIGN_MARGIN else (1.0 if c_p < c_m else -1.0)


def reconstruct_hand_vector(h_C, width_m: float, h_previous_C=None, forearm_C=None, sign=None) -> np.ndarray:
    """The hand vector ``p_i - p_p`` (camera frame) rebuilt from its image-plane part and the hand's width.

    AKC's idea applied to the hand: the knuckles' image coordinates (x, y of C) are reliable, their depths are not,
    their distance is a constant of the hand: ``dz = +/- sqrt(width^2 - |h_xy|^2)``. The sign comes from the forearm
    (:func:`forearm_depth_sign`), else ``sign`` (the tracker's filter over frames,
    :func:`~akc_drake.core.control_frames.depth_sign_step`), else the measured depth. An image part over
    :data:`HAND_OUTLIER_WIDTHS` hand widths is a failed landmark: the previous vector ``h_previous_C`` is kept.

    Args:
        h_C: ``(3,)`` the measured ``p_i - p_p`` in C; width_m: the hand's knuckle distance;
        h_previous_C: the previous reconstructed vector, or None; forearm_C: ``p_e - p_w`` in C, or None;
        sign: +1 / -1, the depth's sign when the forearm does not decide, or None.
    """
    h, dxy2 = np.asarray(h_C, dtype=float), float(h_C[0] ** 2 + h_C[1] ** 2)
    if h_previous_C is not None and np.all(np.isfinite(h_previous_C)) and dxy2 > (HAND_OUTLIER_WIDTHS * width_m) ** 2:
        return np.asarray(h_previous_C, dtype=float).copy()
    dz = max(math.sqrt(max(width_m**2 - dxy2, 0.0)), 1e-9)
    s = forearm_depth_sign(h, dz, forearm_C) or sign or float(h[2])
    return np.array([h[0], h[1], dz if s >= 0.0 else -dz])
