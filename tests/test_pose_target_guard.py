"""PoseTargetGuard: an invalid target holds the arm, an unreachable one is moved onto the reachable shell."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from akc_drake.robot.diff_ik import make_arm_ik_plant
from akc_drake.robot.model import NOMINAL_ARM_Q, ee_frame, torso_frame
from akc_drake.robot.pose_target_guard import PoseTargetGuard


@pytest.fixture(scope="module")
def ik_plants():
    return {"left": make_arm_ik_plant("left")}


def test_pose_target_guard(ik_plants):
    side = "left"
    plant = ik_plants[side]
    guard = PoseTargetGuard(plant, side, 0.15, 0.85)
    np.testing.assert_allclose(guard.p_TS, [0.0, 0.2, 0.0], atol=1e-12)
    context = guard.CreateDefaultContext()
    q = NOMINAL_ARM_Q + 0.1
    guard.GetInputPort("ik_state").FixValue(context, np.concatenate([q, np.zeros(7)]))
    out = guard.GetOutputPort("X_AE_desired")
    R = RotationMatrix(RollPitchYaw(0.1, 0.2, 0.3))
    inside = RigidTransform(R, [0.4, 0.3, -0.2])
    guard.GetInputPort("X_TE_desired").FixValue(context, inside)
    assert out.Eval(context).IsExactlyEqualTo(inside)
    guard.GetInputPort("X_TE_desired").FixValue(context, RigidTransform(R, [2.0, 0.2, 0.0]))
    X = out.Eval(context)
    np.testing.assert_allclose(X.translation(), [0.85, 0.2, 0.0], atol=1e-12)
    np.testing.assert_array_equal(X.rotation().matrix(), R.matrix())
    guard.GetInputPort("X_TE_desired").FixValue(context, RigidTransform(R, [0.0, 0.25, 0.0]))
    np.testing.assert_allclose(out.Eval(context).translation(), [0.0, 0.35, 0.0], atol=1e-12)
    guard.GetInputPort("X_TE_desired").FixValue(context, RigidTransform(R, [0.1, np.inf, 0.0]))
    plant_context = plant.CreateDefaultContext()
    plant.SetPositions(plant_context, q)
    expected = ee_frame(plant, side).CalcPose(plant_context, torso_frame(plant))
    assert out.Eval(context).IsNearlyEqualTo(expected, 1e-12)
    with pytest.raises(ValueError, match="r_min"):
        PoseTargetGuard(plant, side, 0.9, 0.85)
