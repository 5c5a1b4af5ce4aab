"""A joint-space move for an arm whose differential IK is stuck far from its target (:mod:`akc_drake.robot.diff_ik`).

Differential IK moves the tool along the straight line in SE(3) toward the target; when a joint limit blocks that
line it cannot move at all, and its position-only fallback is often blocked too. Leaving the home pose for an
operator standing in a T-pose (the target straight out to the side) the arm sat there for 0.3-0.8 s and reached the
target after about 1.2 s (0.8 s with this move). A robot arm is not confined to that line: this system solves the
pose with Drake's (global, nonlinear) :class:`~pydrake.multibody.inverse_kinematics.InverseKinematics` from the
current command and moves the joints straight to that solution, then gives the arm back to the differential IK as
soon as the tool is near the target (chasing a moving operator by solving the pose again, the move lagged the
differential IK: 14.1 cm mean tool error over the first 3 s of seed 1's left arm, against 12.3 with the hand-over,
15.3 without any move). Like the differential IK, it checks no collisions.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.solvers import Solve
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from akc_drake.robot.model import ToolPoint, check_side, finite_vectors

#: Weight of the orientation error in the IK's cost (times 1 - cos(angle)) against the joints' travel (see below).
ORIENTATION_WEIGHT = 10.0
#: Weight of the joints' travel (rad^2) from the current command in the IK's cost: the nearest solution is chosen.
TRAVEL_WEIGHT = 0.01

# The state vector: [mode, path speed, stuck steps, cooldown steps, moves started, q_out (nq), goal (nq), the
# previous command's tool point (3), the target position the goal was solved for (3)].
_MODE, _RHO, _STUCK, _COOL, _MOVES, _HEAD = 0, 1, 2, 3, 4, 5


class JointSpaceApproach(LeafSystem):
    """Passes the differential IK's command through, or moves the joints straight to a solved pose when it is stuck.

    *Tracking* (the default): the output is the input ``q_ik``. At each IK step the tool's progress toward the
    current target over the last step is measured (the previous command's distance to it minus this one's, so a
    target moving away faster than the arm may follow is no stall). When the tool is more than ``min_error_m`` from
    the target and has progressed less than ``min_progress_m`` for ``stuck_steps`` steps in a row, the target pose is
    solved by :class:`~pydrake.multibody.inverse_kinematics.InverseKinematics` (the tool point within
    ``position_tol_m`` of the target's position; the orientation error and the joints' travel from the current
    command as costs, :data:`ORIENTATION_WEIGHT` and :data:`TRAVEL_WEIGHT`; the IK's own joint bounds) and, when the
    solution brings the tool at least twice as near, the system switches to:

    *Approaching*: the output moves along the straight line in joint space to the solution, every joint arriving
    together, at most at the joints' velocity limits, its speed ramped up and down over ``accel_time_s``. A target
    that moves more than ``replan_m`` from the one solved for is solved again (from the current solution). On
    arrival, or as soon as the tool is within ``min_error_m`` of the (moving) target, the differential IK takes
    over again from there. A solve that fails, or that does not bring the tool twice as near, leaves the
    differential IK in charge and waits ``cooldown_steps`` steps before the next attempt.

    .. pydrake_system::

        name: JointSpaceApproach
        input_ports:
        - q_ik
        - X_AE_desired
        output_ports:
        - q

    ``q_ik`` and ``q`` are the IK plant's positions; ``X_AE_desired`` the (guarded) target of the end effector in
    the torso frame. The output depends on ``q_ik`` and the state only (the target is read at the updates), so the
    loop through the target guard, which reads the command, is not algebraic.
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        side: str,
        time_step: float,
        q_lower: np.ndarray,
        q_upper: np.ndarray,
        v_max: np.ndarray,
        *,
        min_error_m: float = 0.05,
        min_progress_m: float = 0.001,
        stuck_steps: int = 3,
        replan_m: float = 0.02,
        accel_time_s: float = 0.2,
        position_tol_m: float = 0.001,
        cooldown_steps: int = 10,
    ):
        """Args:
        plant: the IK plant (:func:`~akc_drake.robot.diff_ik.make_arm_ik_plant`).
        side: ``"left"`` or ``"right"``.
        time_step: the IK period, seconds.
        q_lower, q_upper: the IK's joint position bounds, one per plant position.
        v_max: the joints' velocity limits (rad/s), one per plant position; a joint with 0 stays where it is.
        min_error_m, min_progress_m, stuck_steps: when the differential IK counts as stuck (see above); the move
            also hands over once the tool is within min_error_m of the target.
        replan_m: a target moved this far from the one solved for is solved again.
        accel_time_s: the time to reach (and to leave) the full speed of the move.
        position_tol_m: the solved tool point's tolerance around the target's position.
        cooldown_steps: steps without a new attempt after a solve that did not help.
        """
        super().__init__()
        check_side(side)
        nq = plant.num_positions()
        self._lo, self._hi, self._v = _check_bounds(nq, q_lower, q_upper, v_max)
        _check_settings(time_step=time_step, min_error_m=min_error_m, replan_m=replan_m, accel_time_s=accel_time_s,
                        position_tol_m=position_tol_m, min_progress_m=min_progress_m, stuck_steps=stuck_steps,
                        cooldown_steps=cooldown_steps)
        self._plant, self._tool = plant, ToolPoint(plant, side)
        self._h, self._nq, self._stuck_steps, self._cool = float(time_step), nq, stuck_steps, cooldown_steps
        self._min_error, self._min_progress, self._replan = float(min_error_m), float(min_progress_m), float(replan_m)
        self._t_acc, self._tol = float(accel_time_s), float(position_tol_m)
        self._q_in = self.DeclareVectorInputPort("q_ik", nq)
        self._target = self.DeclareAbstractInputPort("X_AE_desired", AbstractValue.Make(RigidTransform()))
        init = np.concatenate([np.zeros(_HEAD), np.full(2 * nq + 6, np.nan)])
        self._state = self.DeclareDiscreteState(init)
        self.DeclareVectorOutputPort("q", nq, self._calc, {self._q_in.ticket(), self.all_state_ticket()})
        self.DeclarePeriodicDiscreteUpdateEvent(self._h, 0.0, self._update)

    def solve(self, X_target: RigidTransform, q_start: np.ndarray) -> np.ndarray | None:
        """:func:`solve_arm_pose` with this system's plant, bounds and tolerance."""
        t = self._tool
        return solve_arm_pose(self._plant, t.frame_E, t.frame_T, X_target, q_start, self._lo, self._hi, self._v,
                              self._tol)

    # ---------------------------------------------------------------- system
    def approaching(self, context: Context) -> bool:
        """Whether the output is the joint-space move (else the differential IK's command)."""
        return bool(context.get_discrete_state(self._state).get_value()[_MODE] == 1.0)

    def moves(self, context: Context) -> int:
        """How many joint-space moves have started."""
        return int(context.get_discrete_state(self._state).get_value()[_MOVES])

    def _calc(self, context: Context, output: BasicVector) -> None:
        s = context.get_discrete_state(self._state).get_value()
        output.SetFromVector(s[_HEAD : _HEAD + self._nq] if s[_MODE] == 1.0 else self._q_in.Eval(context))

    def _update(self, context: Context, discrete_state) -> None:
        s = context.get_discrete_state(self._state).get_value().copy()
        nq = self._nq  # (the slices below are views of s: writing them writes the new state)
        q_out, goal = s[_HEAD : _HEAD + nq], s[_HEAD + nq : _HEAD + 2 * nq]
        prev, p_goal = s[_HEAD + 2 * nq : _HEAD + 2 * nq + 3], s[_HEAD + 2 * nq + 3 :]
        X = self._target.Eval(context)
        p = X.translation()
        if s[_MODE] == 1.0:
            if np.linalg.norm(p - p_goal) > self._replan:
                new = self.solve(X, goal)
                if new is not None:
                    goal[:], p_goal[:] = new, p
            q_out[:], s[_RHO] = joint_space_step(q_out, goal, s[_RHO], self._v, self._h, self._t_acc)
            prev[:] = self._tool(q_out)
            if np.max(np.abs(goal - q_out)) <= 1e-9 or np.linalg.norm(prev - p) < self._min_error:
                s[_MODE] = 0.0  # arrived, or near the target: the differential IK takes over from here
        else:
            cur = np.asarray(self._q_in.Eval(context), dtype=float)
            s[_COOL] = max(0.0, s[_COOL] - 1.0)
            tool = self._tool(cur) if np.all(np.isfinite(cur)) else np.full(3, np.nan)
            if np.all(np.isfinite(prev)) and np.all(np.isfinite(tool)) and np.all(np.isfinite(p)):
                # (The progress toward this step's target: a target moving away faster than the arm is no stall.)
                err = float(np.linalg.norm(tool - p))
                progress = float(np.linalg.norm(prev - p)) - err
                s[_STUCK] = s[_STUCK] + 1.0 if (err > self._min_error and progress < self._min_progress) else 0.0
                if s[_STUCK] >= self._stuck_steps and s[_COOL] == 0.0:
                    s[_STUCK] = 0.0
                    new = self.solve(X, cur)
                    if new is not None and np.linalg.norm(self._tool(new) - p) < 0.5 * err:
                        s[_MODE], s[_MOVES] = 1.0, s[_MOVES] + 1.0
                        goal[:], p_goal[:] = new, p
                        q_out[:], s[_RHO] = joint_space_step(cur, goal, 0.0, self._v, self._h, self._t_acc)
                    else:
                        s[_COOL] = float(self._cool)
            prev[:] = tool
        discrete_state.get_mutable_vector(self._state).SetFromVector(s)


def _check_bounds(nq, q_lower, q_upper, v_max):
    """The bounds and velocity limits as float arrays of ``nq``; ValueError unless finite, ordered, v_max >= 0."""
    lo, hi, v = finite_vectors("JointSpaceApproach", nq, q_lower=q_lower, q_upper=q_upper, v_max=v_max)
    if np.any(lo > hi) or np.any(v < 0.0):
        raise ValueError("JointSpaceApproach: need q_lower <= q_upper and v_max >= 0")
    return lo, hi, v


def _check_settings(*, min_progress_m, stuck_steps, cooldown_steps, **positive) -> None:
    """ValueError unless each of ``positive`` is a positive number, ``min_progress_m`` a non-negative one and the
    step counts positive integers."""
    for name, v in positive.items():
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
            raise ValueError(f"JointSpaceApproach: {name} must be a positive number, got {v!r}")
    if not (isinstance(min_progress_m, (int, float)) and math.isfinite(min_progress_m) and min_progress_m >= 0.0):
        raise ValueError(f"JointSpaceApproach: min_progress_m must be a non-negative number, got {min_progress_m!r}")
    for name, v in (("stuck_steps", stuck_steps), ("cooldown_steps", cooldown_steps)):
        if not (isinstance(v, int) and v >= 1):
            raise ValueError(f"JointSpaceApproach: {name} must be a positive integer, got {v!r}")


def solve_arm_pose(plant, frame_E, frame_T, X_target, q_start, q_lower, q_upper, v_max, position_tol_m):
    """The plant's positions that put ``frame_E`` at ``X_target`` in ``frame_T``: the origin within a box of
    half-width ``position_tol_m`` around the target's position, the orientation as near as the arm allows (a
    cost, :data:`ORIENTATION_WEIGHT`), nearest ``q_start`` (:data:`TRAVEL_WEIGHT`), within ``[q_lower, q_upper]``;
    positions with ``v_max`` 0 stay at ``q_start``. Drake's :class:`InverseKinematics` from ``q_start``; None
    when the solver finds no solution."""
    ik = InverseKinematics(plant, with_joint_limits=False)
    q = ik.q()
    prog = ik.get_mutable_prog()
    p = X_target.translation()
    ik.AddPositionConstraint(frame_E, np.zeros(3), frame_T, p - position_tol_m, p + position_tol_m)
    ik.AddOrientationCost(frame_T, X_target.rotation(), frame_E, RotationMatrix(), ORIENTATION_WEIGHT)
    frozen = v_max <= 0.0
    lo, hi = q_lower.copy(), q_upper.copy()
    lo[frozen] = hi[frozen] = q_start[frozen]
    prog.AddBoundingBoxConstraint(lo, hi, q)
    prog.AddQuadraticErrorCost(TRAVEL_WEIGHT * np.eye(len(q_start)), q_start, q)
    prog.SetInitialGuess(q, np.clip(q_start, lo, hi))
    result = Solve(prog)
    return np.clip(result.GetSolution(q), lo, hi) if result.is_success() else None


def joint_space_step(q, goal, rho, v_max, h, accel_time_s):
    """One period ``h`` of the straight joint-space move from ``q`` to ``goal``: ``(new q, new path speed)``.

    Every joint arrives together (the move's duration at full speed ``tau`` is the slowest joint's at its
    ``v_max``); the path speed ``rho`` (a fraction of full speed) rises by ``h / accel_time_s`` per period and is
    capped at ``sqrt(2 tau / accel_time_s)``, so that it falls to 0 on arrival. Joints with ``v_max`` 0 do not move.
    """
    moving = v_max > 0.0
    d = np.where(moving, goal - q, 0.0)
    tau = float(np.max(np.abs(d[moving]) / v_max[moving])) if np.any(moving) else 0.0
    if tau <= 1e-12:
        return q + d, 0.0
    rho = min(1.0, rho + h / accel_time_s, math.sqrt(2.0 * tau / accel_time_s))
    return q + min(1.0, rho * h / tau) * d, rho
