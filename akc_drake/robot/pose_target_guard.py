"""The pose target guard in front of each arm's differential IK (:mod:`akc_drake.robot.diff_ik`): a target that is
not a finite proper rigid transform becomes the current commanded pose; a target out of reach is moved onto the
reachable shell around the shoulder.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, LeafSystem

from akc_drake.robot.model import arm_joint_names, check_side, ee_frame, torso_frame


def _is_valid_pose(X: RigidTransform) -> bool:
    M = X.GetAsMatrix4()
    if not np.all(np.isfinite(M)):
        return False
    R = M[:3, :3]
    return bool(np.allclose(R.T @ R, np.eye(3), atol=1e-6) and abs(np.linalg.det(R) - 1.0) < 1e-6)


class PoseTargetGuard(LeafSystem):
    """Makes the end-effector target safe for the IK: valid, and within the arm's reach.

    A target that is not a finite proper rigid transform (non-finite entries, or a rotation that is not
    orthonormal with determinant +1) is replaced by the pose of the current command, so the arm holds still.
    A valid target whose position lies outside the spherical shell ``r_min <= |p - p_shoulder| <= r_max``
    around the arm's shoulder is moved radially onto the shell (the closest point of the shell; its rotation
    is kept), so an unreachable target is approached as closely as the arm allows without stretching it into
    the singular straight-arm configuration. Stateless, direct feedthrough.

    .. pydrake_system::

        name: PoseTargetGuard
        input_ports:
        - X_TE_desired
        - ik_state
        output_ports:
        - X_AE_desired

    ``ik_state`` is the IK plant's state ``[q, v]`` of the current command (only read for an invalid target).
    """

    def __init__(self, plant: MultibodyPlant, side: str, r_min: float, r_max: float):
        """Args:
        plant: the IK plant.
        side: ``"left"`` or ``"right"``.
        r_min, r_max: the reachable shell around the shoulder, metres (0 <= r_min < r_max).
        """
        super().__init__()
        if not (0.0 <= r_min < r_max and math.isfinite(r_max)):
            raise ValueError(f"PoseTargetGuard: need 0 <= r_min < r_max, got r_min={r_min!r}, r_max={r_max!r}")
        self._plant = plant
        self._plant_context = plant.CreateDefaultContext()
        self._frame_T = torso_frame(plant)
        self._frame_E = ee_frame(plant, check_side(side))
        shoulder = plant.GetJointByName(arm_joint_names(side)[0]).frame_on_child()
        #: Shoulder centre in T (the first joint's origin; joints 1-3 intersect there).
        self.p_TS = shoulder.CalcPose(self._plant_context, self._frame_T).translation().copy()
        self._r_min, self._r_max = float(r_min), float(r_max)
        self._target = self.DeclareAbstractInputPort("X_TE_desired", AbstractValue.Make(RigidTransform()))
        self._x = self.DeclareVectorInputPort("ik_state", plant.num_multibody_states())
        self.DeclareAbstractOutputPort(
            "X_AE_desired",
            lambda: AbstractValue.Make(RigidTransform()),
            self._calc_target,
            {self.all_input_ports_ticket()},
        )

    def project(self, X: RigidTransform) -> RigidTransform:
        """``X`` with its position moved radially into the reachable shell around the shoulder."""
        d = X.translation() - self.p_TS
        r = float(np.linalg.norm(d))
        if r > self._r_max:
            return RigidTransform(X.rotation(), self.p_TS + d * (self._r_max / r))
        if r < self._r_min:
            # Straight ahead when the target sits on the shoulder centre itself.
            u = d / r if r > 1e-9 else np.array([1.0, 0.0, 0.0])
            return RigidTransform(X.rotation(), self.p_TS + u * self._r_min)
        return X

    def _calc_target(self, context: Context, output: AbstractValue) -> None:
        X = self._target.Eval(context)
        if _is_valid_pose(X):
            X = self.project(X)
        else:
            self._plant.SetPositions(self._plant_context, self._x.Eval(context)[: self._plant.num_positions()])
            X = self._frame_E.CalcPose(self._plant_context, self._frame_T)
        output.set_value(X)
