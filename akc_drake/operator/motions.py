"""Joint-space motions of the simulated operator: T-pose and L-pose holds, the paper's Motion I and Motion II.

A motion is a sampled trajectory of both arms' joint angles (see :mod:`akc_drake.operator.model` for the
joint conventions). Motion I and II follow the paper (§III): 6 s per cycle, N cycles, both arms at once;
each cycle varies a little (seeded), as a person's repetitions do.

* Motion I (forward arm movement): T-pose, horizontal adduction until the arm points at the camera, back
  to T-pose. When the arm points at the camera the hand hides the elbow and shoulder.
* Motion II (elbow flexion-extension): the arm extended toward the camera, elbow flexion to about 90 deg
  (forearm up), back to extension. The upper arm keeps pointing at the camera, so the shoulder stays
  hidden behind the elbow for the whole motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from akc_drake.operator.model import (
    DEFAULT_CAMERA_DISTANCE_M,
    DEFAULT_CAMERA_HEIGHT_M,
    NEUTRAL_FOREARM_ROLL,
    NUM_ARM_DOF,
    OperatorParams,
    full_q,
    landmarks_from_q,
)

#: Period of one cycle of Motion I or II (paper §III).
CYCLE_SECONDS = 6.0
#: Duration of one "cycle" of a held pose: 100 frames at 10 Hz, one calibration's worth (paper §III).
HOLD_SECONDS = 10.0
#: Sampling step of generated motions (the renderer interpolates between samples).
SAMPLE_DT = 0.01
#: Where the generated motions point the arms by default: the default camera position in O
#: (in front of the pelvis at chest height; see ``akc_drake.systems.depth_camera_source.CameraPlacement``).
DEFAULT_TARGET_O = (DEFAULT_CAMERA_DISTANCE_M, 0.0, DEFAULT_CAMERA_HEIGHT_M)

MOTION_NAMES = ("I", "II", "tpose", "lpose", "pick-place")

_DEG = math.pi / 180.0


@dataclass
class OperatorMotion:
    """A sampled joint trajectory of both arms.

    Attributes:
        times: ``(T,)`` strictly increasing sample times in seconds, starting anywhere (usually 0).
        q_left: ``(T, NUM_ARM_DOF)`` left-arm joint angles (radians).
        q_right: ``(T, NUM_ARM_DOF)`` right-arm joint angles.
        name: a label ("I", "II", "tpose", "lpose", or a file name).
        cycle_starts: optional start times of the motion's cycles (for cycle-wise evaluation).
        hand_closed: optional ``(T, 2)`` closure of the left and right hands in [0, 1] (0: open, 1: a closed
            pinch) at the sample times; None: both hands open throughout.
    """

    times: np.ndarray
    q_left: np.ndarray
    q_right: np.ndarray
    name: str = "motion"
    cycle_starts: np.ndarray | None = None
    hand_closed: np.ndarray | None = None

    def __post_init__(self):
        self.times = np.asarray(self.times, dtype=float).reshape(-1)
        T = self.times.shape[0]
        if T < 2:
            raise ValueError(f"OperatorMotion {self.name!r}: needs at least 2 samples, got {T}")
        if not np.all(np.isfinite(self.times)) or np.any(np.diff(self.times) <= 0):
            raise ValueError(f"OperatorMotion {self.name!r}: times must be finite and strictly increasing")
        for attr in ("q_left", "q_right"):
            q = np.asarray(getattr(self, attr), dtype=float)
            if q.shape != (T, NUM_ARM_DOF):
                raise ValueError(
                    f"OperatorMotion {self.name!r}: {attr} must have shape ({T}, {NUM_ARM_DOF}), got {q.shape}"
                )
            if not np.all(np.isfinite(q)):
                k = int(np.flatnonzero(~np.all(np.isfinite(q), axis=1))[0])
                raise ValueError(f"OperatorMotion {self.name!r}: {attr}[{k}] is not finite: {q[k].tolist()}")
            setattr(self, attr, q)
        if self.cycle_starts is not None:
            self.cycle_starts = np.asarray(self.cycle_starts, dtype=float).reshape(-1)
        if self.hand_closed is not None:
            h = np.asarray(self.hand_closed, dtype=float)
            if h.shape != (T, 2) or not np.all((h >= 0.0) & (h <= 1.0)):
                raise ValueError(f"OperatorMotion {self.name!r}: hand_closed must be ({T}, 2) values in [0, 1]")
            self.hand_closed = h

    def closure(self, t) -> np.ndarray:
        """``(len(t), 2)`` hand closure (left, right) at times ``t`` (linear interpolation; 0 without any)."""
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), self.start, self.end)
        if self.hand_closed is None:
            return np.zeros((len(t), 2))
        return np.stack([np.interp(t, self.times, self.hand_closed[:, k]) for k in range(2)], axis=1)

    @property
    def start(self) -> float:
        return float(self.times[0])

    @property
    def end(self) -> float:
        return float(self.times[-1])

    @property
    def duration(self) -> float:
        return self.end - self.start

    def q(self) -> np.ndarray:
        """``(T, 2 * NUM_ARM_DOF)`` samples in the canonical order ``[q_left, q_right]``."""
        return full_q(self.q_left, self.q_right)

    def trajectory(self):
        """A Drake ``PiecewisePolynomial`` (first-order hold) of ``[q_left, q_right]`` over :attr:`times`."""
        from pydrake.trajectories import PiecewisePolynomial

        return PiecewisePolynomial.FirstOrderHold(self.times, self.q().T)

    def sample(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles at times ``t`` (clamped to the motion's span) by linear interpolation.

        Returns:
            ``(q_left, q_right)``, each ``(len(t), NUM_ARM_DOF)`` (interpolated as :meth:`trajectory` does).
        """
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), self.start, self.end)
        ql = np.stack([np.interp(t, self.times, self.q_left[:, k]) for k in range(NUM_ARM_DOF)], axis=1)
        qr = np.stack([np.interp(t, self.times, self.q_right[:, k]) for k in range(NUM_ARM_DOF)], axis=1)
        return ql, qr

    def frame_times(self, rate_hz: float) -> np.ndarray:
        """Camera sample times ``start + k / rate_hz`` within the motion's span."""
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        n = int(math.floor(self.duration * rate_hz + 1e-9)) + 1
        return self.start + np.arange(n) / rate_hz

    def landmarks_O(self, t=None, params: OperatorParams | None = None) -> np.ndarray:
        """True landmarks in O, ``(T, 12, 3)``, at ``t`` (default: the sample times)."""
        if t is None:
            ql, qr = self.q_left, self.q_right
        else:
            ql, qr = self.sample(t)
        return landmarks_from_q(ql, qr, params)


# --------------------------------------------------------------------------------------------------
# Generators
# --------------------------------------------------------------------------------------------------


def _smootherstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _pointing_angles(shoulder_O: np.ndarray, target_O, side: str) -> tuple[float, float]:
    """Shoulder adduction and elevation that point ``side``'s upper arm from its shoulder at ``target_O``."""
    d = np.asarray(target_O, dtype=float) - shoulder_O
    d = d / np.linalg.norm(d)
    if side == "right":
        d = d * np.array([1.0, -1.0, 1.0])
    return math.atan2(d[0], d[1]), math.asin(d[2])


def _cyclic(
    cycles: int,
    seed: int,
    name: str,
    rest_fn,
    peak_fn,
    jitter: float = 1.0,
    start_pose: np.ndarray | None = None,
) -> OperatorMotion:
    """Cycles of rest -> peak -> rest for both arms, with seeded per-cycle variation.

    ``rest_fn(rng, side)`` and ``peak_fn(rng, side)`` draw one pose (NUM_ARM_DOF,) each; ``jitter`` scales
    the per-cycle variation of the timing. The rest pose drifts smoothly from one cycle boundary's draw to
    the next (from ``start_pose`` at t = 0 when given); within a cycle the arm moves from the rest pose to
    that cycle's peak and back with a smooth profile (short holds at both ends, a hold at the peak).
    """
    if not isinstance(cycles, (int, np.integer)) or cycles < 1:
        raise ValueError(f"cycles must be a positive integer, got {cycles!r}")
    rng = np.random.default_rng(seed)
    T = int(round(cycles * CYCLE_SECONDS / SAMPLE_DT)) + 1
    t = np.arange(T) * SAMPLE_DT
    c = np.minimum((t // CYCLE_SECONDS).astype(int), cycles - 1)
    phase = (t - c * CYCLE_SECONDS) / CYCLE_SECONDS
    out = {}
    for side in ("left", "right"):
        rests = np.array([rest_fn(rng, side) for _ in range(cycles + 1)])
        if start_pose is not None:
            rests[0] = start_pose
        peaks = np.array([peak_fn(rng, side) for _ in range(cycles)])
        # Per cycle: when the arm leaves the rest pose, reaches the peak, leaves it, and is back.
        a = 0.05 + jitter * rng.uniform(-0.02, 0.02, cycles)
        b = 0.40 + jitter * rng.uniform(-0.03, 0.03, cycles)
        e = 0.60 + jitter * rng.uniform(-0.03, 0.03, cycles)
        f = 0.95 + jitter * rng.uniform(-0.02, 0.02, cycles)
        up = _smootherstep((phase - a[c]) / (b[c] - a[c]))
        down = _smootherstep((phase - e[c]) / (f[c] - e[c]))
        shape = up * (1.0 - down)
        rest = rests[c] + (rests[c + 1] - rests[c]) * _smootherstep(phase)[:, None]
        out[side] = rest + (peaks[c] - rest) * shape[:, None]
    return OperatorMotion(t, out["left"], out["right"], name, cycle_starts=np.arange(cycles) * CYCLE_SECONDS)


def motion_I(
    cycles: int = 1,
    seed: int = 0,
    *,
    params: OperatorParams | None = None,
    target_O=DEFAULT_TARGET_O,
    variation: float = 1.0,
) -> OperatorMotion:
    """Motion I: T-pose -> horizontal adduction until the arm points at the camera -> T-pose (6 s/cycle).

    Args:
        cycles: number of 6 s cycles.
        seed: seeds the per-cycle variation.
        params: the operator (for the shoulder positions).
        target_O: the point the arms point at (the camera) in O.
        variation: scales the per-cycle variation (0: identical cycles).
    """
    params = params or OperatorParams()
    v = float(variation) * _DEG

    def rest(rng, side):
        return np.array(
            [
                rng.normal(0.0, 3.0) * v,
                rng.normal(0.0, 2.0) * v,
                rng.normal(0.0, 2.0) * v,
                abs(rng.normal(4.0, 2.0)) * v,
                NEUTRAL_FOREARM_ROLL + rng.normal(0.0, 3.0) * v,
            ]
        )

    def peak(rng, side):
        add, elev = _pointing_angles(params.shoulder_O(side), target_O, side)
        return np.array(
            [
                add + rng.normal(0.0, 2.0) * v,
                elev + rng.normal(0.0, 1.5) * v,
                rng.normal(0.0, 2.0) * v,
                abs(rng.normal(4.0, 2.0)) * v,
                NEUTRAL_FOREARM_ROLL + rng.normal(0.0, 3.0) * v,
            ]
        )

    return _cyclic(cycles, seed, "I", rest, peak, jitter=float(variation))


def motion_II(
    cycles: int = 1,
    seed: int = 0,
    *,
    params: OperatorParams | None = None,
    target_O=DEFAULT_TARGET_O,
    flexion_deg: float = 90.0,
    variation: float = 1.0,
    start_from_tpose: bool = True,
) -> OperatorMotion:
    """Motion II: arm extended toward the camera -> elbow flexion to about 90 deg -> extension (6 s/cycle).

    The humerus is rotated so that the forearm rises (palm facing the body's midline) while the upper arm
    keeps pointing at the camera.

    Args:
        cycles: number of 6 s cycles.
        seed: seeds the per-cycle variation.
        params: the operator (for the shoulder positions).
        target_O: the point the arms point at (the camera) in O.
        flexion_deg: mean elbow flexion at the peak.
        variation: scales the per-cycle variation (0: identical cycles).
        start_from_tpose: the first cycle starts from a T-pose (the operator raising the arms into position,
            the shoulders in view) instead of from the extended pose. Without it the shoulders are hidden
            from the very first frame and a filter has nothing to start its track from. The paper uses the
            first cycle only to tune weights.
    """
    params = params or OperatorParams()
    v = float(variation) * _DEG

    def base(rng, side):
        add, elev = _pointing_angles(params.shoulder_O(side), target_O, side)
        return np.array(
            [
                add + rng.normal(0.0, 2.0) * v,
                elev + rng.normal(0.0, 1.5) * v,
                -math.pi / 2 + rng.normal(0.0, 3.0) * v,
                abs(rng.normal(3.0, 1.5)) * v,
                NEUTRAL_FOREARM_ROLL + rng.normal(0.0, 3.0) * v,
            ]
        )

    def peak(rng, side):
        q = base(rng, side)
        q[3] = (flexion_deg * _DEG) + rng.normal(0.0, 4.0) * v
        return q

    start = np.array([0.0, 0.0, -math.pi / 2, 0.0, NEUTRAL_FOREARM_ROLL]) if start_from_tpose else None
    return _cyclic(cycles, seed, "II", base, peak, jitter=float(variation), start_pose=start)


def _hold(pose: np.ndarray, seconds: float, seed: int, name: str, sway_deg: float) -> OperatorMotion:
    if not (isinstance(seconds, (int, float)) and math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number, got {seconds!r}")
    rng = np.random.default_rng(seed)
    T = int(round(seconds / SAMPLE_DT)) + 1
    t = np.arange(T) * SAMPLE_DT
    out = {}
    for side in ("left", "right"):
        # A slow, small sway: two sinusoids per joint with random phases (nobody holds perfectly still).
        freq = rng.uniform(0.1, 0.4, (2, NUM_ARM_DOF))
        phase = rng.uniform(0, 2 * math.pi, (2, NUM_ARM_DOF))
        sway = np.sin(2 * math.pi * freq[0] * t[:, None] + phase[0]) + 0.5 * np.sin(
            2 * math.pi * freq[1] * t[:, None] + phase[1]
        )
        out[side] = pose[None, :] + sway * (sway_deg * _DEG / 1.5)
    return OperatorMotion(t, out["left"], out["right"], name)


def tpose(seconds: float = HOLD_SECONDS, seed: int = 0, *, sway_deg: float = 0.5) -> OperatorMotion:
    """Hold a T-pose (arms straight out to the sides, palms down) for ``seconds``, with a slight sway."""
    pose = np.array([0.0, 0.0, 0.0, 0.0, NEUTRAL_FOREARM_ROLL])
    return _hold(pose, seconds, seed, "tpose", sway_deg)


def lpose(seconds: float = HOLD_SECONDS, seed: int = 0, *, sway_deg: float = 0.5) -> OperatorMotion:
    """Hold an L-pose (upper arms out to the sides, elbows at 90 deg, forearms up, palms forward)."""
    pose = np.array([0.0, 0.0, -math.pi / 2, math.pi / 2, NEUTRAL_FOREARM_ROLL])
    return _hold(pose, seconds, seed, "lpose", sway_deg)


#: The pick-and-place task in the robot torso frame T (metres), matching ``models/teleop_scene.sdf``: the box's
#: centre where it starts and the centre of the marked target, for the right arm.
PICK_BOX_T = (0.55, -0.15, -0.355)
PLACE_TARGET_T = (0.55, -0.40, -0.355)
#: The gripper's tool axis points forward and this far down (degrees) while grasping, fingers closing across
#: the box (along y of T).
GRASP_PITCH_DEG = 60.0


#: A person's joint ranges used when solving the operator's posture (radians): adduction, elevation, humeral
#: rotation, elbow flexion, forearm roll (see :mod:`akc_drake.operator.model`).
ARM_RANGE = (
    np.array([-0.5, -1.6, -1.6, 0.0, -0.2]),
    np.array([2.5, 1.6, 1.6, 2.6, 3.4]),
)


def _mapped_tool_pose(q_left, q_right, side, params, mapping, landmarks=None) -> np.ndarray:
    from akc_drake.core.frames import map_to_robot, wrist_in_torso

    if landmarks is not None:  # the body's own landmarks, e.g. the skinned rig's knuckles
        pose = landmarks(np.concatenate([q_left, q_right])[None])[0]
    else:
        pose = landmarks_from_q(np.atleast_2d(q_left), np.atleast_2d(q_right), params)[0]
    X_l, X_r = wrist_in_torso(pose)
    X = X_l if side == "left" else X_r
    return map_to_robot(X, side, mapping)


def solve_arm_for_tool_pose(
    p_T, R_T, side: str, q_other: np.ndarray, q0: np.ndarray, params: OperatorParams, mapping, landmarks=None
) -> np.ndarray:
    """The operator's arm angles whose wrist frame, through ``mapping``, puts the robot's tool at ``p_T`` with
    rotation ``R_T`` (least squares, scipy): what an operator watching the robot does to put it there.

    Args:
        p_T: ``(3,)`` tool position in T; R_T: ``(3, 3)`` tool rotation in T (rotation error weighted 0.1 m/rad).
        side: the arm; q_other: the other arm's angles; q0: the starting guess.
        landmarks: the body's landmarks for ``(T, 10)`` angles (default: the operator model's,
            :func:`~akc_drake.operator.model.landmarks_from_q`).
    """
    from scipy.optimize import least_squares

    from akc_drake.core.frames import rotation_angle

    p_T, R_T = np.asarray(p_T, dtype=float), np.asarray(R_T, dtype=float)

    def residual(q):
        ql, qr = (q, q_other) if side == "left" else (q_other, q)
        X = _mapped_tool_pose(ql, qr, side, params, mapping, landmarks)
        R_err = R_T.T @ X[:3, :3]
        axis = np.array([R_err[2, 1] - R_err[1, 2], R_err[0, 2] - R_err[2, 0], R_err[1, 0] - R_err[0, 1]])
        n = np.linalg.norm(axis)
        rot = axis / n * rotation_angle(R_err) if n > 1e-12 else np.zeros(3)
        # A small pull toward the starting guess keeps the solution on the branch the arm is on.
        return np.concatenate([X[:3, 3] - p_T, 0.05 * rot, 0.01 * (q - q0)])

    q0 = np.clip(np.asarray(q0, dtype=float), ARM_RANGE[0] + 1e-6, ARM_RANGE[1] - 1e-6)
    return least_squares(residual, q0, bounds=ARM_RANGE, method="trf").x


@dataclass
class ToolPlan:
    """Where a motion means to put the robot's tool (in T), knot by knot: the pick-and-place operator's aims.

    Between two knots the aim moves along the straight line with the same smootherstep timing as the motion's
    joints (so it is still at every knot).

    Attributes:
        times: ``(k,)`` knot times (non-decreasing, seconds); positions: ``(k, 3)``; rotations: ``(k, 3, 3)``.
    """

    times: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        """``(p (3,), R (3, 3), speed m/s)`` of the aim at time ``t`` (clamped to the knots' span)."""
        kt = self.times
        t = float(np.clip(t, kt[0], kt[-1]))
        j = min(int(np.searchsorted(kt, t, side="right")), len(kt) - 1)
        j0 = max(j - 1, 0)
        span = kt[j] - kt[j0]
        if span <= 0:
            return self.positions[j].copy(), self.rotations[j], 0.0
        x = (t - kt[j0]) / span
        u = float(_smootherstep(np.array(x)))
        du = 30.0 * x * x * (x - 1.0) ** 2 / span  # d/dt of 6x^5 - 15x^4 + 10x^3
        d = self.positions[j] - self.positions[j0]
        R = self.rotations[j0] if u < 0.5 else self.rotations[j]
        return self.positions[j0] + u * d, R, float(abs(du) * np.linalg.norm(d))


def pick_place(seed: int = 0, **kwargs) -> OperatorMotion:
    """The pick-and-place motion (:func:`pick_place_plan`'s, without its :class:`ToolPlan`)."""
    return pick_place_plan(seed, **kwargs)[0]


def pick_place_plan(
    seed: int = 0,
    *,
    params: OperatorParams | None = None,
    mapping=None,
    box_T=PICK_BOX_T,
    target_T=PLACE_TARGET_T,
    variation: float = 1.0,
    landmarks=None,
) -> tuple[OperatorMotion, ToolPlan]:
    """Pick and place with the right arm (about 17 s): rest, reach for the box with the arm toward the camera
    (the hand hides the elbow and shoulder), close the hand, lift, carry, lower onto the target, open, retreat.
    The arm holds still for a second at the box and on the target before the hand closes or opens (time to
    line the tool up, :mod:`akc_drake.operator.closed_loop`).

    The waypoints are where the operator must hold the wrist so that the robot's tool, through ``mapping``,
    is at the box, above it, above the target and on the target, with the tool pointing forward and
    :data:`GRASP_PITCH_DEG` down and the palm down (the gripper closing across the box): the operator places the
    robot's hand, as a person watching the robot would. The left arm rests (forearm forward). Per seed the
    timing and the waypoints vary a little (a few mm), as a person's repetitions do.

    Args:
        seed: seeds the variation.
        params: the operator.
        mapping: the operator-to-robot :class:`~akc_drake.core.frames.RobotMapping` the operator works with
            (default: :func:`~akc_drake.core.frames.calibrated_mapping` of the operator's dimensions).
        box_T, target_T: the box's start and the target's centre in T.
        variation: scales the per-seed variation (0: none).
        landmarks: the rendered body's landmarks for ``(T, 10)`` angles (e.g. the skinned operator's
            :meth:`~akc_drake.operator.skinned.SkinnedOperator.landmarks_O`, whose knuckles are the rig's): the
            operator holds *that* hand so the robot's tool is right (default: the operator model's).

    Returns:
        ``(motion, plan)``: the :class:`OperatorMotion` and the right arm's :class:`ToolPlan` (the waypoints the
        postures were solved for; the solve's pull toward the previous posture leaves the motion's mapped tool
        up to ~2 cm from them).
    """
    from akc_drake.core.frames import calibrated_mapping

    params = params or OperatorParams()
    mapping = mapping if mapping is not None else calibrated_mapping(params.dims)
    rng = np.random.default_rng(seed)
    v = float(variation)
    a = math.radians(GRASP_PITCH_DEG)
    y = np.array([-math.cos(a), 0.0, math.sin(a)])  # tool axis, from the tool back toward the wrist
    z = np.array([0.0, 1.0, 0.0])  # the fingers close along y of T
    R_grasp = np.column_stack([np.cross(y, z), y, z])
    box, target = np.asarray(box_T, float), np.asarray(target_T, float)
    lift = np.array([0.0, 0.0, 0.15])

    def jitter() -> np.ndarray:
        return rng.normal(0.0, 0.003 * v, 3)

    # Rest: the robot's tools forward at waist height, palms facing each other (the operator's forearms
    # forward, upper arms down).
    R_rest_r = np.column_stack([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    R_rest_l = np.column_stack([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    guess = np.array([0.5 * math.pi, -0.8, 0.0, 1.2, NEUTRAL_FOREARM_ROLL])
    rest = solve_arm_for_tool_pose([0.45, 0.22, -0.21], R_rest_l, "left", guess, guess, params, mapping, landmarks)
    rest_right = solve_arm_for_tool_pose(
        [0.45, -0.22, -0.21], R_rest_r, "right", rest, guess, params, mapping, landmarks
    )
    waypoints = [
        # (time s, right-arm tool position in T or None for rest, hand closure)
        (0.0, None, 0.0),
        (1.5, None, 0.0),
        (4.0, box + lift + jitter(), 0.0),
        (5.5, box + jitter(), 0.0),
        (6.5, "hold", 0.0),
        (7.1, "hold", 1.0),
        (8.5, box + lift + jitter(), 1.0),
        (11.0, target + lift + jitter(), 1.0),
        (12.5, target + np.array([0.0, 0.0, 0.004]) + jitter(), 1.0),
        (13.4, "hold", 1.0),
        (14.0, "hold", 0.0),
        (15.5, target + lift + jitter(), 0.0),
        (17.0, None, 0.0),
    ]
    q_prev = rest_right
    knots_t, knots_q, knots_h, aims = [], [], [], []
    for k, (t, where, closed) in enumerate(waypoints):
        t = t + (0.0 if k == 0 else rng.uniform(-0.1, 0.1) * v)
        if where is None:
            q = rest_right
            aims.append((np.array([0.45, -0.22, -0.21]), R_rest_r))
        elif isinstance(where, str):
            q = knots_q[-1]
            aims.append(aims[-1])
        else:
            q = solve_arm_for_tool_pose(where, R_grasp, "right", rest, q_prev, params, mapping, landmarks)
            q_prev = q
            aims.append((np.asarray(where, dtype=float), R_grasp))
        knots_t.append(t)
        knots_q.append(np.asarray(q, dtype=float))
        knots_h.append(closed)
    knots_t = np.maximum.accumulate(np.asarray(knots_t))
    T = int(round(knots_t[-1] / SAMPLE_DT)) + 1
    times = np.arange(T) * SAMPLE_DT
    q_right = np.empty((T, NUM_ARM_DOF))
    closure = np.empty(T)
    for i, t in enumerate(times):
        j = min(int(np.searchsorted(knots_t, t, side="right")), len(knots_t) - 1)
        j0 = max(j - 1, 0)
        span = knots_t[j] - knots_t[j0]
        u = float(_smootherstep(np.array((t - knots_t[j0]) / span))) if span > 0 else 1.0
        q_right[i] = knots_q[j0] + u * (knots_q[j] - knots_q[j0])
        closure[i] = knots_h[j0] + u * (knots_h[j] - knots_h[j0])
    q_left = np.tile(rest, (T, 1))
    hand = np.column_stack([np.zeros(T), np.clip(closure, 0.0, 1.0)])
    plan = ToolPlan(knots_t, np.array([a[0] for a in aims]), np.array([a[1] for a in aims]))
    return OperatorMotion(times, q_left, q_right, "pick-place", hand_closed=hand), plan


def make_motion(name: str, cycles: int = 1, seed: int = 0, **kwargs) -> OperatorMotion:
    """A motion by name.

    Args:
        name: "I", "II", "tpose" or "lpose" (case-insensitive; "1"/"2" also accepted).
        cycles: cycles of Motion I/II (6 s each); for holds, the number of :data:`HOLD_SECONDS` periods.
        seed: seeds the variation.
        **kwargs: passed to the generator.

    Raises:
        ValueError: an unknown name or a non-positive cycle count.
    """
    key = str(name).strip().lower()
    if not isinstance(cycles, (int, np.integer)) or cycles < 1:
        raise ValueError(f"cycles must be a positive integer, got {cycles!r}")
    if key in ("i", "1", "motion_i"):
        return motion_I(cycles, seed, **kwargs)
    if key in ("ii", "2", "motion_ii"):
        return motion_II(cycles, seed, **kwargs)
    if key in ("tpose", "t-pose", "t"):
        return tpose(HOLD_SECONDS * cycles, seed, **kwargs)
    if key in ("lpose", "l-pose", "l"):
        return lpose(HOLD_SECONDS * cycles, seed, **kwargs)
    if key in ("pick-place", "pickplace", "pick_place"):
        return pick_place(seed, **kwargs)
    raise ValueError(f"unknown motion {name!r}; choose one of {', '.join(MOTION_NAMES)} (or a motion file)")
