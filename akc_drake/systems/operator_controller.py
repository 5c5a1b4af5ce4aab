"""The closed-loop operator as a Drake system: it watches the robot's tool and outputs its own posture.

A thin wrapper over :class:`~akc_drake.operator.closed_loop.ClosedLoopOperator` (the model, its parameters and
their sources are documented there).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from akc_drake.operator.model import NUM_ARM_DOF
from akc_drake.robot.model import ee_frame, torso_frame

#: The operator's update period (seconds): it looks at the tool and moves its arm this often.
OPERATOR_PERIOD_S = 0.02


class OperatorController(LeafSystem):
    """The operator watching the robot: input the robot's state, output the operator's joint angles.

    .. pydrake_system::

        name: OperatorController
        input_ports:
        - robot_state
        output_ports:
        - q_operator

    ``robot_state`` is the robot's measured ``[q, v]`` (the station's ``robot_state_output``): from it the
    system computes the tool's pose in the torso frame T, which is all the operator sees (no corrector's
    internals). ``q_operator`` is ``[q_left, q_right]`` (``2 * NUM_ARM_DOF``), the operator's posture for the
    renderer, held between updates (a pure function of the state).

    Args:
        operator: the :class:`~akc_drake.operator.closed_loop.ClosedLoopOperator`.
        plant, robot: the robot station's plant and the robot's model instance.
        period_s: update period; offset_s: its offset (between two camera frames by default).
    """

    def __init__(self, operator, plant, robot, *, period_s: float = OPERATOR_PERIOD_S, offset_s: float | None = None):
        super().__init__()
        self._op = operator
        self._plant = plant
        self._robot = robot
        self._plant_context = plant.CreateDefaultContext()
        self._ee = ee_frame(plant, operator.side, robot)
        self._torso = torso_frame(plant, robot)
        nx = plant.num_positions(robot) + plant.num_velocities(robot)
        self.DeclareVectorInputPort("robot_state", nx)
        start = operator.plan.start
        q0 = operator.posture(operator.initial_state(), start)
        self._state = self.DeclareAbstractState(AbstractValue.Make((operator.initial_state(), q0)))
        self.DeclareVectorOutputPort("q_operator", 2 * NUM_ARM_DOF, self._calc_q,
                                     prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        offset = 0.5 * period_s if offset_s is None else float(offset_s)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, offset, self._update)
        #: (t, offset (3,)) after each update, for the report.
        self.trace: list[tuple[float, np.ndarray]] = []

    def tool_position(self, context) -> np.ndarray:
        """The robot's tool position in T (3,) from the ``robot_state`` input."""
        x = self.get_input_port(0).Eval(context)
        self._plant.SetPositionsAndVelocities(self._plant_context, self._robot, x)
        return self._ee.CalcPose(self._plant_context, self._torso).translation()

    def _update(self, context, state):
        t = self._op.plan.start + context.get_time()
        core, _ = context.get_abstract_state(self._state).get_value()
        core = self._op.step(core, t, self.tool_position(context))
        q = self._op.posture(core, t)
        state.get_mutable_abstract_state(self._state).set_value((core, q))
        self.trace.append((context.get_time(), core.offset.copy()))

    def _calc_q(self, context, output):
        _, q = context.get_abstract_state(self._state).get_value()
        output.SetFromVector(q)

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """``(times (n,), offsets (n, 3))`` the operator's correction after each update."""
        if not self.trace:
            return np.zeros(0), np.zeros((0, 3))
        t, c = zip(*self.trace)
        return np.array(t), np.array(c)
