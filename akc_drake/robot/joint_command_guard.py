"""The joint command guard after each arm's differential IK (:mod:`akc_drake.robot.diff_ik`): every command finite,
within the position limits and never more than ``velocity limit * period`` from the previous one.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem


class JointCommandGuard(LeafSystem):
    """Makes the arm's joint position command safe: finite, within the position limits, and never more than
    ``velocity limit * period`` from the previous command.

    A non-finite input holds the previous command and increments ``held_count``. The previous command is
    discrete state, updated at the IK period (offset 0, the same instants as the integrator) and initialised
    from ``q_initial`` by an initialisation event; until then the output is ``q_initial`` (clipped).

    .. pydrake_system::

        name: JointCommandGuard
        input_ports:
        - q
        - q_initial
        output_ports:
        - q_commanded
        - v_commanded

    ``v_commanded`` is the velocity of the current command step, ``(q_commanded - previous) / period``: a
    velocity feedforward for the position controller (zero before the first step and while holding).
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, velocity: np.ndarray, period: float):
        """Args:
        lower, upper: joint position limits (rad), shape ``(n,)``.
        velocity: joint velocity limits (rad/s, > 0), shape ``(n,)``.
        period: the command period, seconds (> 0).
        """
        super().__init__()
        self._lower = np.asarray(lower, dtype=float)
        self._upper = np.asarray(upper, dtype=float)
        self._step = np.asarray(velocity, dtype=float) * float(period)
        n = len(self._lower)
        if not (len(self._upper) == n == len(self._step)) or np.any(self._step <= 0) or period <= 0:
            raise ValueError("JointCommandGuard: limits must have equal lengths, velocities and period > 0")
        if np.any(self._lower > self._upper):
            raise ValueError(f"JointCommandGuard: lower limits above upper limits: {self._lower}, {self._upper}")
        self._q_in = self.DeclareVectorInputPort("q", n)
        self._q_init = self.DeclareVectorInputPort("q_initial", n)
        self._last = self.DeclareDiscreteState(n)
        # [held count, initialised flag]
        self._info = self.DeclareDiscreteState(2)
        self._period = float(period)
        # The outputs depend on the IK's output and the discrete state only (not on time, and not on
        # ``q_initial``, which is read once by the initialisation event and is typically the measured
        # robot state that changes every plant step), so they stay cached between IK steps.
        deps = {self.xd_ticket(), self._q_in.ticket()}
        self.DeclareVectorOutputPort("q_commanded", n, self._calc_command, deps)
        self.DeclareVectorOutputPort("v_commanded", n, self._calc_velocity, deps)
        self.DeclarePeriodicDiscreteUpdateEvent(float(period), 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)

    def _initial(self, context: Context) -> np.ndarray:
        q0 = self._q_init.Eval(context)
        if not np.all(np.isfinite(q0)):
            raise ValueError(f"JointCommandGuard: initial joint positions are not finite: {q0}")
        return np.clip(q0, self._lower, self._upper)

    def _command(self, context: Context) -> tuple[np.ndarray, bool]:
        if context.get_discrete_state(self._info).get_value()[1] == 0.0:
            return self._initial(context), False
        last = context.get_discrete_state(self._last).get_value()
        q = self._q_in.Eval(context)
        if not np.all(np.isfinite(q)):
            return last.copy(), True
        lo = np.maximum(self._lower, last - self._step)
        hi = np.minimum(self._upper, last + self._step)
        return np.clip(q, lo, hi), False

    def _calc_command(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._command(context)[0])

    def _calc_velocity(self, context: Context, output: BasicVector) -> None:
        q, held = self._command(context)
        if held or context.get_discrete_state(self._info).get_value()[1] == 0.0:
            output.SetFromVector(np.zeros(len(q)))
            return
        output.SetFromVector((q - context.get_discrete_state(self._last).get_value()) / self._period)

    def _update(self, context: Context, discrete_state) -> None:
        q, held = self._command(context)
        discrete_state.get_mutable_vector(self._last).SetFromVector(q)
        count = context.get_discrete_state(self._info).get_value()[0]
        discrete_state.get_mutable_vector(self._info).SetFromVector([count + (1.0 if held else 0.0), 1.0])

    def _initialize(self, context: Context, discrete_state) -> None:
        discrete_state.get_mutable_vector(self._last).SetFromVector(self._initial(context))
        discrete_state.get_mutable_vector(self._info).SetFromVector([0.0, 1.0])

    def held_count(self, context: Context) -> int:
        """How many IK periods the command was held because the IK output was not finite."""
        return int(context.get_discrete_state(self._info).get_value()[0])
