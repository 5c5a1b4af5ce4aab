"""The closed-loop operator of the pick-and-place task: a person who watches the robot's tool and corrects it.

The open-loop pick-and-place motion (:func:`~akc_drake.operator.motions.pick_place`) puts the operator's *true*
wrist where the robot's tool would be at the box through the mapping. A real detector's landmarks are not the
joint centres (MediaPipe's wrist sits centimetres off the rig's), so the robot's tool then misses the box and
nobody corrects it. A person teleoperating a robot watches the robot and corrects. This module models that
person, deliberately simply (no model of the pipeline, no access to any corrector's internals: only the robot's
tool, as a person sees it):

* **The plan.** The open-loop motion is the operator's plan, and its waypoints (a
  :class:`~akc_drake.operator.motions.ToolPlan`: the box, above it, the target, ...) are where the operator
  aims the robot's tool: at time ``t`` the tool should be at ``p_plan(t)`` (:meth:`ClosedLoopOperator.plan_tool`;
  without a ToolPlan, the motion's own mapped tool pose).
* **What the operator sees.** The tool's position error ``e(t) = p_plan(t) - p_tool(t)``, seen
  :data:`VISUAL_DELAY_S` late (a person's visuomotor reaction delay).
* **How the operator corrects.** An offset ``c`` added to the wrist target, integrated from the seen error with a
  limited gain (``dc/dt = gain * w * e(t - delay)``, :data:`CORRECTION_GAIN_PER_S`), its speed limited
  (:data:`MAX_CORRECTION_SPEED_M_S`) and its size bounded (:data:`MAX_CORRECTION_M`: a target the robot cannot
  reach does not wind the operator up without end). ``w`` weighs the correction by how still the plan is
  (1 when the plan holds still, 0 at or above :data:`STILL_SPEED_M_S`): the two-component model of aimed
  movements (Woodworth 1899; Meyer et al. 1988): a fast transport with the offset the operator has learned so
  far, and visually guided corrections as the hand homes in on a target. A lag of the robot while it moves is
  therefore not "corrected" into an overshoot.
* **The posture.** The operator then solves the arm's posture that puts the mapped tool at ``p_plan(t) + c``
  with the plan's rotation (:func:`~akc_drake.operator.motions.solve_arm_for_tool_pose`, started from the plan's
  posture at ``t``) and the aim's rotation (corrected as below). With the tool on target the offset stays zero
  and the posture is the plan's.
* **The rotation.** Given the tool's pose, the operator corrects its rotation the same way (a rotation vector
  offset applied to the aim's rotation, the same delay, gain and weight; deadband :data:`ROTATION_DEADBAND_RAD`,
  speed :data:`ROTATION_MAX_SPEED_RAD_S`, bound :data:`ROTATION_MAX_RAD`): a gripper turned against the box's
  edges lands its fingers on the box instead of around it.
* **The box where it is.** Until the plan's hand first closes, the aims over the box (at it and above it) move with
  the box as the operator sees it (``object_T``, :meth:`ClosedLoopOperator.object_shift`): a box the robot nudged
  on its way is reached for where it now is.
* **What the operator watches.** The robot's tool while the plan's hand is open; the carried object (the box)
  while it is closed: a person placing an object with a robot looks at the object against the target, so an
  object held off-centre in the gripper is placed where it should be (only an object within
  :data:`CARRY_RADIUS_M` of the tool is carried: a missed grasp leaves the operator watching the tool).
* **What is "on target".** Errors within :data:`DEADBAND_M` are not corrected (what a person can tell from a
  couple of metres), and the operator corrects a tool that has settled (the weight is also the tool's own
  stillness): a robot still on its way, or jumping from its home pose at the start, is watched, not corrected;
  a tool held off by contact (the fingers on the table) within the deadband does not wind the operator up.
  Within :data:`GRIP_HOLD_S` of a change of the hand's closure (grasping, releasing) the operator holds the
  correction: a person attends to the hand and keeps the arm still.
* **A robot that follows.** The operator corrects only once the robot's tool has moved :data:`ENGAGE_M` from
  where it was first seen: a robot held in its home pose (its tracking not yet acquired) does not respond to the
  operator's hand, and integrating its error would only wind the correction up to its bound (measured: KF, seed 0,
  the offset at its 20 cm bound before the robot first moved, 2.5 s into the run).

Parameters (assumptions, stated as such): the delay 0.25 s is in the range of the visual feedback loop times
measured for aimed hand movements (Keele and Posner 1968: ~190-260 ms; Carlton 1981: ~135-290 ms; a simple
visual reaction time is ~0.2-0.25 s); the gain 3 /s (time constant 0.33 s) keeps the delayed loop well damped
(``gain * delay = 0.75 rad`` of phase lag at crossover, a phase margin of ~47 deg) and corrects a constant offset
to 10 % within about a second, like a person's corrective submovements (a few hundred ms each).

The correction's dynamics (:class:`VisualCorrection`) are numpy only; :class:`ClosedLoopOperator` adds the plan
and the posture solve; :class:`~akc_drake.systems.operator_controller.OperatorController` wraps it in Drake.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: The operator's visual reaction delay (seconds): the tool's error is acted on this late.
VISUAL_DELAY_S = 0.25
#: Integral gain of the correction (1/s): the offset moves at ``gain`` x the seen error.
CORRECTION_GAIN_PER_S = 3.0
#: Plan speed (m/s) at and above which the operator does not correct (transport).
STILL_SPEED_M_S = 0.05
#: Largest speed of the correction (m/s): a person's corrective movement, not a jump.
MAX_CORRECTION_SPEED_M_S = 0.25
#: Largest correction (m).
MAX_CORRECTION_M = 0.20
#: Errors within this distance (m) are not corrected: the tool is "at" the target as far as a person watching a
#: robot arm from a couple of metres can tell (~0.4 deg of visual angle at 2 m).
DEADBAND_M = 0.015
#: The object counts as carried (watched instead of the tool) while the hand is closed and it is this close to
#: the tool (m); a missed grasp leaves it on the table and the operator watches the tool.
CARRY_RADIUS_M = 0.06
#: The rotation's correction (a rotation vector, radians) has the position's delay and gain, this deadband
#: (a person sees a gripper turned by more than ~5 deg against the box's edges), speed limit and bound.
ROTATION_DEADBAND_RAD = 0.09
ROTATION_MAX_SPEED_RAD_S = 1.0
ROTATION_MAX_RAD = 0.6
#: The operator starts correcting once the robot's tool has moved this far (m) from where it was first seen: a
#: robot that has not started following the operator (tracking not yet acquired, held in its home pose) is waited
#: for, not chased (integrating the error of a robot that does not respond winds the correction up to its bound).
ENGAGE_M = 0.03
#: Aims over the object's planned place (within this horizontal distance, m: at the box and above it) move with
#: the object until the first grasp (:meth:`ClosedLoopOperator.object_shift`).
OBJECT_AIM_RADIUS_M = 0.05
#: The operator holds its correction from this long (seconds) before a change of its hand's closure until
#: :data:`GRIP_SETTLE_S` after it: a person grasping or releasing attends to the hand and keeps the arm still.
GRIP_HOLD_S = 0.2
GRIP_SETTLE_S = 0.5


@dataclass(frozen=True)
class CorrectionParams:
    """The correction's parameters (see the module docstring)."""

    delay_s: float = VISUAL_DELAY_S
    gain_per_s: float = CORRECTION_GAIN_PER_S
    still_speed_m_s: float = STILL_SPEED_M_S
    max_speed_m_s: float = MAX_CORRECTION_SPEED_M_S
    max_offset_m: float = MAX_CORRECTION_M
    deadband_m: float = DEADBAND_M

    def __post_init__(self):
        for name in ("delay_s", "gain_per_s", "still_speed_m_s", "max_speed_m_s", "max_offset_m", "deadband_m"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0) or (name == "still_speed_m_s" and v == 0):
                raise ValueError(f"CorrectionParams.{name} must be a finite number >= 0 (> 0 for the speed), got {v!r}")


@dataclass(frozen=True)
class CorrectionState:
    """The operator's correction: the offset ``c`` (3,) and what was seen, ``(t, error (3,), weight)`` per
    observation, oldest first (only what the delay still needs is kept)."""

    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    seen: tuple = ()
    t_last: float | None = None
    tool_last: np.ndarray | None = None
    rotation: CorrectionState | None = None
    tool_first: np.ndarray | None = None
    engaged: bool = False


class VisualCorrection:
    """The delayed, gain-limited correction of the tool's position error (numpy).

    Args:
        params: the :class:`CorrectionParams`.
    """

    def __init__(self, params: CorrectionParams | None = None):
        self.params = params or CorrectionParams()

    def step(self, state: CorrectionState, t: float, error: np.ndarray, weight: float) -> CorrectionState:
        """Observe the tool's ``error`` (3,) at time ``t`` (``weight`` in [0, 1]: how still the plan is) and
        advance the offset from the last step to ``t`` with the error seen ``delay`` ago.

        A non-finite error (the tool unknown) is not seen. Before anything was seen ``delay`` ago, the offset
        holds.
        """
        p = self.params
        t = float(t)
        error = np.asarray(error, dtype=float).reshape(3)
        seen = state.seen
        if np.all(np.isfinite(error)):
            seen = seen + ((t, error.copy(), float(np.clip(weight, 0.0, 1.0))),)
        # The observation acted on: the latest one at or before t - delay.
        k = -1
        for i, (ti, _, _) in enumerate(seen):
            if ti <= t - p.delay_s + 1e-9:
                k = i
        offset = state.offset
        if k >= 0 and state.t_last is not None and t > state.t_last:
            dt = t - state.t_last
            _, e, w = seen[k]
            n = float(np.linalg.norm(e))
            e = e * max(0.0, 1.0 - p.deadband_m / n) if n > 0 else e  # the deadband: only what is beyond it
            step = p.gain_per_s * w * e * dt
            n = float(np.linalg.norm(step))
            if n > p.max_speed_m_s * dt:
                step = step * (p.max_speed_m_s * dt / n)
            offset = offset + step
            n = float(np.linalg.norm(offset))
            if n > p.max_offset_m:
                offset = offset * (p.max_offset_m / n)
        return CorrectionState(offset, seen[max(k, 0):], t, state.tool_last)


class ClosedLoopOperator:
    """The closed-loop operator: the plan, the correction and the posture (see the module docstring).

    Args:
        plan: the open-loop :class:`~akc_drake.operator.motions.OperatorMotion` (e.g.
            :func:`~akc_drake.operator.motions.pick_place`), its time starting at the run's start.
        mapping: the operator-to-robot :class:`~akc_drake.core.frames.RobotMapping` the operator works with.
        side: the arm the operator corrects ("right" for the pick-and-place); the other arm plays the plan.
        params: the operator's dimensions; landmarks: the rendered body's landmarks (as
            :func:`~akc_drake.operator.motions.pick_place`'s).
        correction: the :class:`CorrectionParams`.
        plan_dt: the plan's tool pose is tabulated at this step (seconds).
        tool_plan: the :class:`~akc_drake.operator.motions.ToolPlan` the operator aims at (None: the motion's
            mapped tool pose).
        object_T: where the plan expects the object to pick (its centre in T; None: the aims are absolute).
            Until the plan's hand first closes, the aims over it (:data:`OBJECT_AIM_RADIUS_M`) move with the
            object as the operator sees it (``p_object_T`` of :meth:`step`): a person reaches for the box where it
            is, not where it was (measured: KF, seed 0, the robot's swing on its way pushed the box 7 cm before
            the grasp and the operator, aiming at the box's starting place, closed the gripper on air).
    """

    def __init__(self, plan, mapping, *, side: str = "right", params=None, landmarks=None,
                 correction: CorrectionParams | None = None, plan_dt: float = 0.02, tool_plan=None, object_T=None):
        from akc_drake.operator.model import OperatorParams
        from akc_drake.operator.motions import _mapped_tool_pose

        if side not in ("left", "right"):
            raise ValueError(f"side must be left or right, got {side!r}")
        self.plan, self.mapping, self.side = plan, mapping, side
        self.params = params or OperatorParams()
        self.landmarks = landmarks
        self.correction = VisualCorrection(correction)
        cp = self.correction.params
        self.rotation = VisualCorrection(CorrectionParams(
            delay_s=cp.delay_s, gain_per_s=cp.gain_per_s, still_speed_m_s=cp.still_speed_m_s,
            max_speed_m_s=ROTATION_MAX_SPEED_RAD_S, max_offset_m=ROTATION_MAX_RAD, deadband_m=ROTATION_DEADBAND_RAD))
        self.tool_plan = tool_plan
        self.object_T = None if object_T is None else np.asarray(object_T, dtype=float).reshape(3)
        k = 1 if side == "right" else 0
        closed = np.flatnonzero(plan.closure(plan.times)[:, k] > 1e-6)
        #: The plan's first closing of the hand (seconds; inf: never): the object's aims follow it until then.
        self.first_grasp_t = float(plan.times[closed[0]]) if closed.size else float("inf")
        if tool_plan is None:
            self._t = np.arange(plan.start, plan.end + 1e-9, float(plan_dt))
            ql, qr = plan.sample(self._t)
            X = np.array([_mapped_tool_pose(a, b, side, self.params, mapping, landmarks)
                          for a, b in zip(ql, qr, strict=True)])
            self._p, self._R = X[:, :3, 3], X[:, :3, :3]
            self._speed = np.linalg.norm(np.gradient(self._p, self._t, axis=0), axis=1)

    def initial_state(self) -> CorrectionState:
        return CorrectionState(rotation=CorrectionState())

    def plan_tool(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        """``(p (3,), R (3, 3), speed m/s)``: where the plan puts the robot's tool at ``t`` (in T)."""
        if self.tool_plan is not None:
            return self.tool_plan.at(t)
        t = float(np.clip(t, self._t[0], self._t[-1]))
        p = np.array([np.interp(t, self._t, self._p[:, k]) for k in range(3)])
        j = int(np.argmin(np.abs(self._t - t)))
        return p, self._R[j], float(np.interp(t, self._t, self._speed))

    def object_shift(self, t: float, aim, p_object_T) -> np.ndarray:
        """``(3,)`` how far the aim at ``t`` moves with the object: its seen displacement from :attr:`object_T`
        before the plan's first grasp, for aims over it (horizontally within :data:`OBJECT_AIM_RADIUS_M`; zero
        otherwise)."""
        if self.object_T is None or p_object_T is None or t >= self.first_grasp_t:
            return np.zeros(3)
        seen = np.asarray(p_object_T, dtype=float).reshape(3)
        far = float(np.linalg.norm((np.asarray(aim, dtype=float) - self.object_T)[:2])) > OBJECT_AIM_RADIUS_M
        if far or not np.all(np.isfinite(seen)):
            return np.zeros(3)
        return seen - self.object_T

    def weight(self, speed: float) -> float:
        """How much the operator corrects at plan speed ``speed`` (1 still, 0 at or above the still speed)."""
        return float(np.clip(1.0 - speed / self.correction.params.still_speed_m_s, 0.0, 1.0))

    def step(self, state: CorrectionState, t: float, p_tool_T, p_object_T=None) -> CorrectionState:
        """See the robot's tool at ``p_tool_T`` (3,) (in T; NaN: not seen) at time ``t``; the new state.
        ``p_tool_T`` may be the tool's pose ``X_TE`` (4, 4): the operator then also corrects its rotation (the
        rotation vector taking the tool's rotation to the aim's, the same delay, gain and weight).

        While the plan's hand is closed (carrying) the operator watches the carried object, ``p_object_T`` (its
        centre in T; None: the tool), against the aim (the plan's tool aim is the object's centre). The weight is
        the plan's stillness times the watched point's (its speed since the last step): the operator corrects a
        tool that has settled near a target the plan holds, not one still on its way."""
        p, R_aim, speed = self.plan_tool(t)
        R_tool = None
        if np.shape(p_tool_T) == (4, 4):
            X = np.asarray(p_tool_T, dtype=float)
            p_tool_T, R_tool = X[:3, 3], X[:3, :3]
        k = 1 if self.side == "right" else 0
        carrying = p_object_T is not None and float(self.plan.closure([t])[0, k]) > 0.5 and float(
            np.linalg.norm(np.asarray(p_object_T, float) - np.asarray(p_tool_T, float))) < CARRY_RADIUS_M
        tool = np.asarray(p_object_T if carrying else p_tool_T, dtype=float).reshape(3)
        p = p + self.object_shift(t, p, p_object_T)
        w = self.weight(speed)
        grip = self.plan.closure([t - GRIP_SETTLE_S, t, t + GRIP_HOLD_S])[:, k]
        if np.ptp(grip) > 1e-6:  # grasping or releasing: the arm is held
            w = 0.0
        if state.tool_last is not None and state.t_last is not None and t > state.t_last:
            w *= self.weight(float(np.linalg.norm(tool - state.tool_last)) / (t - state.t_last))
        seen_tool = np.asarray(p_tool_T, dtype=float).reshape(3)
        first = state.tool_first if state.tool_first is not None else (
            seen_tool.copy() if np.all(np.isfinite(seen_tool)) else None)
        engaged = state.engaged or (first is not None and np.all(np.isfinite(seen_tool))
                                    and float(np.linalg.norm(seen_tool - first)) > ENGAGE_M)
        if not engaged:  # the robot has not started following: wait for it
            w = 0.0
        new = self.correction.step(state, t, p - tool, w)
        rot = state.rotation
        if R_tool is not None:
            from scipy.spatial.transform import Rotation

            e_rot = Rotation.from_matrix(R_aim @ R_tool.T).as_rotvec() if np.all(np.isfinite(R_tool)) else np.full(
                3, np.nan)
            rot = self.rotation.step(rot or CorrectionState(), t, e_rot, w)
        return CorrectionState(new.offset, new.seen, new.t_last, tool.copy() if np.all(np.isfinite(tool)) else None,
                               rot, first, bool(engaged))

    def posture(self, state: CorrectionState, t: float) -> np.ndarray:
        """``(2 * NUM_ARM_DOF,)`` the operator's ``[q_left, q_right]`` at ``t``: the plan's, the corrected arm
        solved for the plan's tool pose shifted by the offset."""
        from akc_drake.operator.motions import solve_arm_for_tool_pose

        ql, qr = (q[0] for q in self.plan.sample([t]))
        w = np.zeros(3) if state.rotation is None else state.rotation.offset
        if float(np.linalg.norm(state.offset)) < 1e-6 and float(np.linalg.norm(w)) < 1e-6:
            return np.concatenate([ql, qr])
        p, R, _ = self.plan_tool(t)
        if float(np.linalg.norm(w)) > 0:
            from scipy.spatial.transform import Rotation

            R = Rotation.from_rotvec(w).as_matrix() @ R
        mine, other = (ql, qr) if self.side == "left" else (qr, ql)
        q = solve_arm_for_tool_pose(p + state.offset, R, self.side, other, mine, self.params, self.mapping,
                                    self.landmarks)
        return np.concatenate([q, qr]) if self.side == "left" else np.concatenate([ql, q])
