"""The choice between the full-pose and the position-only differential IK of an arm (:mod:`akc_drake.robot.diff_ik`),
per IK step: the position-only command while the full-pose IK is stuck at a joint limit.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from akc_drake.robot.model import ToolPoint


class IKFallbackSelector(LeafSystem):
    """Chooses, per IK step, the full-pose IK's command or, when that one is stuck, the position-only IK's.

    Drake's differential IK moves the end effector along the straight line in SE(3) toward the target, scaled
    down to the limits; when a joint limit blocks that exact direction it cannot move at all ("stuck") and the
    arm would freeze while the operator moves on. A second integrator solves for the position alone (the
    orientation left to the joint centering) from the same guarded command. The position-only command is used
    when the tool point is more than ``min_error_m`` from the target and the full-pose step moved it less than a
    tenth of what the position-only step would; otherwise (tracking, or converged) the full pose is used, and
    it takes over again as soon as it can move.

    .. pydrake_system::

        name: IKFallbackSelector
        input_ports:
        - q_full
        - q_position
        - X_AE_desired
        output_ports:
        - q

    ``q_*`` are the IK plant's positions; ``X_AE_desired`` the (guarded) target of the end effector in the torso
    frame. State: the previous IK step's choice and target position (NaN before the first), updated every
    ``time_step``.
    """

    def __init__(self, plant: MultibodyPlant, side: str, time_step: float, min_error_m: float = 0.005):
        super().__init__()
        self._p = ToolPoint(plant, side)
        self._min_error = float(min_error_m)
        nq = plant.num_positions()
        self._full = self.DeclareVectorInputPort("q_full", nq)
        self._pos = self.DeclareVectorInputPort("q_position", nq)
        self._target = self.DeclareAbstractInputPort("X_AE_desired", AbstractValue.Make(RigidTransform()))
        # [previous choice (nq), target position latched at the previous step (3)]
        self._prev = self.DeclareDiscreteState(np.full(nq + 3, np.nan))
        self._nq = nq
        # The output does not depend on the target input (it is latched), so the loop through the target guard
        # (which reads the command) is not algebraic.
        self.DeclareVectorOutputPort(
            "q",
            nq,
            self._calc,
            {self._full.ticket(), self._pos.ticket(), self.all_state_ticket()},
        )
        self.DeclarePeriodicDiscreteUpdateEvent(time_step, 0.0, self._update)

    def _choose(self, context: Context) -> np.ndarray:
        full, pos = self._full.Eval(context), self._pos.Eval(context)
        state = context.get_discrete_state(self._prev).get_value()
        prev, target = state[: self._nq], state[self._nq :]
        if not (np.all(np.isfinite(prev)) and np.all(np.isfinite(pos)) and np.all(np.isfinite(full))):
            return full
        p0 = self._p(prev)
        if not np.all(np.isfinite(target)) or np.linalg.norm(target - p0) <= self._min_error:
            return full
        d_full = float(np.linalg.norm(self._p(full) - p0))
        d_pos = float(np.linalg.norm(self._p(pos) - p0))
        return pos if d_full < 0.1 * d_pos else full

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._choose(context))

    def _update(self, context: Context, discrete_state) -> None:
        target = self._target.Eval(context).translation()
        discrete_state.get_mutable_vector(self._prev).SetFromVector(np.concatenate([self._choose(context), target]))
