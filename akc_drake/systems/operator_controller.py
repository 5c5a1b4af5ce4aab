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
        - plant_state
        output_ports:
        - q_operator

    ``plant_state`` is the station plant's full state ``[q, v]`` (``plant.get_state_output_port()``): from it
    the system computes the robot tool's position in the torso frame T and the watched object's (the box), which
    is all the operator sees (no corrector's internals). ``q_operator`` is ``[q_left, q_right]``
    (``2 * NUM_ARM_DOF``), the operator's posture for the renderer, held between updates (a pure function of the
    state).

    Args:
        operator: the :class:`~akc_drake.operator.closed_loop.ClosedLoopOperator`.
        plant, robot: the robot station's plant and the robot's model instance.
        watched: the object the operator watches while carrying it, a ``(body name, model instance)`` of
            ``plant`` (None: the tool only).
        period_s: update period; offset_s: its offset (between two camera frames by default).
    """

    def __init__(self, operator, plant, robot, *, watched=None, period_s: float = OPERATOR_PERIOD_S,
                 offset_s: float | None = None):
        super().__init__()
        self._op = operator
        self._plant = plant
        self._robot = robot
        self._plant_context = plant.CreateDefaultContext()
        self._ee = ee_frame(plant, operator.side, robot)
        self._torso = torso_frame(plant, robot)
        self._object = None if watched is None else plant.GetBodyByName(*watched).body_frame()
        self.DeclareVectorInputPort("plant_state", plant.num_positions() + plant.num_velocities())
        start = operator.plan.start
        q0 = operator.posture(operator.initial_state(), start)
        self._state = self.DeclareAbstractState(AbstractValue.Make((operator.initial_state(), q0)))
        self.DeclareVectorOutputPort("q_operator", 2 * NUM_ARM_DOF, self._calc_q,
                                     prerequisites_of_calc={self.abstract_state_ticket(self._state)})
        offset = 0.5 * period_s if offset_s is None else float(offset_s)
        self.DeclarePeriodicUnrestrictedUpdateEvent(period_s, offset, self._update)
        #: (t, offset (3,)) after each update, for the report.
        self.trace: list[tuple[float, np.ndarray]] = []
        #: (t, tool position (3,), object position (3,), NaN without one) as seen at each update, for the report.
        self.seen_trace: list[tuple[float, np.ndarray, np.ndarray]] = []

    def tool_position(self, context) -> np.ndarray:
        """The robot's tool position in T (3,) from the ``plant_state`` input."""
        return self.seen(context)[0][:3, 3]

    def seen(self, context) -> tuple[np.ndarray, np.ndarray | None]:
        """``(X_TE (4, 4), object (3,) or None)``: the tool's pose and the watched object's position in T."""
        self._plant.SetPositionsAndVelocities(self._plant_context, self.get_input_port(0).Eval(context))
        tool = self._ee.CalcPose(self._plant_context, self._torso).GetAsMatrix4()
        obj = None if self._object is None else self._object.CalcPose(self._plant_context, self._torso).translation()
        return tool, obj

    def _update(self, context, state):
        t = self._op.plan.start + context.get_time()
        core, _ = context.get_abstract_state(self._state).get_value()
        X, obj = self.seen(context)
        core = self._op.step(core, t, X, obj)
        q = self._op.posture(core, t)
        state.get_mutable_abstract_state(self._state).set_value((core, q))
        self.trace.append((context.get_time(), core.offset.copy()))
        self.seen_trace.append((context.get_time(), X[:3, 3].copy(), np.full(3, np.nan) if obj is None else obj.copy()))

    def _calc_q(self, context, output):
        _, q = context.get_abstract_state(self._state).get_value()
        output.SetFromVector(q)

    def offsets(self) -> tuple[np.ndarray, np.ndarray]:
        """``(times (n,), offsets (n, 3))`` the operator's correction after each update."""
        if not self.trace:
            return np.zeros(0), np.zeros((0, 3))
        t, c = zip(*self.trace, strict=True)
        return np.array(t), np.array(c)

    def watched(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(times (n,), tool (n, 3), object (n, 3))`` what the operator saw at each update (in T; the object NaN
        without a watched object)."""
        if not self.seen_trace:
            return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
        t, p, o = zip(*self.seen_trace, strict=True)
        return np.array(t), np.array(p), np.array(o)

    def grasp_time(self) -> float:
        """When (diagram time, seconds) the plan's hand first closes (inf: never)."""
        return float(self._op.first_grasp_t - self._op.plan.start)
