"""The arm's joint command within its velocity, acceleration and jerk limits, by Ruckig's online trajectory generation.

The camera's targets change ten times a second, in steps, and the differential IK (:mod:`akc_drake.robot.diff_ik`)
runs at 100 Hz: it reaches each step's pose within a few IK periods at the joints' velocity limits, then stops.
Its joint command is a staircase, its speed a train of pulses: replaying Motions I and II (3 cycles, simulated
detector, AKC(KF)) the commanded accelerations reached 280-750 rad/s^2 (99th percentile 140-450), and the jerk
2-8 x 10^4 rad/s^3 at the 99th percentile. A real arm's controller refuses such a command (a collaborative arm
accepts 7.5-20 rad/s^2); the simulated one followed it only because its actuators have no torque limit. This
system turns the command into one the arm can follow: each period Ruckig (the time-optimal, jerk-limited
trajectory generator that robot arms' own motion generators use) plans from the current commanded position,
velocity and acceleration to the differential IK's command, arriving at rest with every joint at once, and the
output is that trajectory one period on.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, LeafSystem
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Synchronization, Trajectory

from akc_drake.robot.model import finite_vectors

_OK = (Result.Working, Result.Finished)
_POSITION, _VELOCITY = ControlInterface.Position, ControlInterface.Velocity
# Time synchronisation (every joint arrives together); where Ruckig fails numerically (seen once, on a move of
# 1e-15 rad from rest: "error in step 2"), each joint on its own time-optimal profile; failing that, to rest.
_ATTEMPTS = ((None, Synchronization.Time), (None, Synchronization.No), (_VELOCITY, Synchronization.No))


class JointMotionLimiter(LeafSystem):
    """Follows the joint command ``q`` with the joints' position, velocity, acceleration and jerk within limits.

    Each period the state (the commanded position, velocity and acceleration) moves one period along Ruckig's
    time-optimal trajectory to ``q`` at rest (all joints arriving together), within the velocity, acceleration
    and jerk limits; the position is then clipped into ``[lower, upper]`` (``q`` is within them: the
    :class:`~akc_drake.robot.joint_command_guard.JointCommandGuard`'s command is). A non-finite ``q`` is no new
    target: the arm stops where the trajectory brings it to rest. Where Ruckig fails numerically, each joint gets
    its own time-optimal profile, and failing that the arm is brought to rest. The state starts at ``q_initial``
    (clipped), at rest, by an initialisation event; until then the output is ``q_initial`` (clipped) at rest.

    .. pydrake_system::

        name: JointMotionLimiter
        input_ports:
        - q
        - q_initial
        output_ports:
        - q_commanded
        - v_commanded
        - a_commanded

    The outputs are the state (after this period's update): the command the arm is to be at, its velocity (a
    feedforward for the position controller) and its acceleration.
    """

    def __init__(self, lower, upper, velocity, acceleration, jerk, period: float):
        """Args:
        lower, upper: joint position limits (rad), shape ``(n,)``.
        velocity, acceleration, jerk: the joints' limits (rad/s, rad/s^2, rad/s^3, each > 0), shape ``(n,)``.
        period: the update period, seconds (> 0).
        """
        super().__init__()
        n = np.size(lower)
        self._lower, self._upper, vel, acc, jerk = finite_vectors("JointMotionLimiter", n, lower=lower, upper=upper,
                                                                  velocity=velocity, acceleration=acceleration,
                                                                  jerk=jerk)
        if np.any(self._lower > self._upper):
            raise ValueError(f"JointMotionLimiter: lower limits above upper limits: {self._lower}, {self._upper}")
        if min(vel.min(), acc.min(), jerk.min()) <= 0.0:
            raise ValueError("JointMotionLimiter: velocity, acceleration and jerk limits must be > 0")
        if not (isinstance(period, (int, float)) and np.isfinite(period) and period > 0.0):
            raise ValueError(f"JointMotionLimiter: period must be a positive number of seconds, got {period!r}")
        self._n, self._period = n, float(period)
        self._limits = (vel, acc, jerk)
        self._lo, self._hi = self._lower.tolist(), self._upper.tolist()
        self._limit_lists = (vel.tolist(), acc.tolist(), jerk.tolist())
        self._q_in = self.DeclareVectorInputPort("q", n)
        self._q_init = self.DeclareVectorInputPort("q_initial", n)
        self._state = self.DeclareDiscreteState(3 * n + 1)  # [position, velocity, acceleration, initialised]
        # The outputs depend on the state only (``q_initial`` is read before the initialisation event alone; it
        # is typically the measured robot state, which changes every plant step).
        deps = {self.xd_ticket()}
        for i, name in enumerate(("q_commanded", "v_commanded", "a_commanded")):
            self.DeclareVectorOutputPort(name, n, lambda c, o, i=i: self._calc(c, o, i), deps)
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, 0.0, self._update)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)

    @property
    def limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(velocity, acceleration, jerk)`` limits, copies."""
        return tuple(a.copy() for a in self._limits)

    def _initial(self, context: Context) -> np.ndarray:
        q0 = self._q_init.Eval(context)
        if not np.all(np.isfinite(q0)):
            raise ValueError(f"JointMotionLimiter: initial joint positions are not finite: {q0}")
        return np.concatenate([np.clip(q0, self._lower, self._upper), np.zeros(2 * self._n), [1.0]])

    def _calc(self, context: Context, output: BasicVector, i: int) -> None:
        x = context.get_discrete_state(self._state).get_value()
        if x[-1] == 0.0:
            x = self._initial(context)
        output.SetFromVector(x[i * self._n : (i + 1) * self._n])

    def step(self, q, v, a, target) -> tuple[list, list, list]:
        """One period from ``(q, v, a)`` towards ``target`` at rest: the new ``(q, v, a)``, lists of floats.

        (Plain lists: Ruckig's inputs take a list five times faster than an array, and ``np.clip`` on 7 numbers
        costs 12 µs: the whole step takes about 25 µs, against 54 with arrays.)
        """
        # New Ruckig objects every step (about 5 µs): ``calculate`` then plans from this input alone, a function of
        # the context, and no extension object outlives the system (nanobind reports those held at exit as leaks).
        n, lo, hi = self._n, self._lo, self._hi
        otg, inp, traj = Ruckig(n), InputParameter(n), Trajectory(n)
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = self._limit_lists
        q = list(map(float, q))
        # (Rounding's residue of a stop, 1e-18 rad/s, is rest: such values made Ruckig's synchronisation fail.)
        v, a = ([x if abs(x) > 1e-12 else 0.0 for x in map(float, y)] for y in (v, a))
        inp.current_position, inp.current_velocity, inp.current_acceleration = q, v, a
        target = list(map(float, target))
        if all(map(math.isfinite, target)):
            inp.control_interface = _POSITION
            inp.target_position = [min(max(x, lo[i]), hi[i]) for i, x in enumerate(target)]
        else:  # no new target: to rest as soon as the limits allow (velocity control to 0)
            inp.control_interface = _VELOCITY
            inp.target_position = q
        inp.target_velocity = inp.target_acceleration = [0.0] * n
        for interface, sync in _ATTEMPTS:
            if interface is not None:
                inp.control_interface = interface
            inp.synchronization = sync
            try:
                result = otg.calculate(inp, traj)
            except RuckigError as e:
                result = str(e).strip().splitlines()[0]
            if result in _OK:
                break
        else:
            raise RuntimeError(f"JointMotionLimiter: Ruckig could not plan ({result}) from q={q}, v={v}, a={a}")
        qn, vn, an = traj.at_time(self._period)
        return [min(max(x, lo[i]), hi[i]) for i, x in enumerate(qn)], list(vn), list(an)

    def _update(self, context: Context, discrete_state) -> None:
        x = context.get_discrete_state(self._state).get_value()
        if x[-1] == 0.0:
            x = self._initial(context)
        n = self._n
        q, v, a = self.step(x[:n], x[n : 2 * n], x[2 * n : 3 * n], self._q_in.Eval(context))
        discrete_state.get_mutable_vector(self._state).SetFromVector(q + v + a + [1.0])

    def _initialize(self, context: Context, discrete_state) -> None:
        discrete_state.get_mutable_vector(self._state).SetFromVector(self._initial(context))
