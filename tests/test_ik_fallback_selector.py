"""IKFallbackSelector: the position-only IK's command while the full-pose IK is stuck, the full pose otherwise."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from akc_drake.robot.diff_ik import make_arm_ik_plant
from akc_drake.robot.ik_fallback_selector import IKFallbackSelector
from akc_drake.robot.model import NOMINAL_ARM_Q, ee_frame, torso_frame

DT = 0.01


@pytest.fixture(scope="module")
def plant():
    return make_arm_ik_plant("left")


def _tool(plant, q) -> np.ndarray:
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q)
    return ee_frame(plant, "left").CalcPose(ctx, torso_frame(plant)).translation()


def _selector(plant, prev, target, q_full, q_pos, desired=None):
    sel = IKFallbackSelector(plant, "left", DT)
    ctx = sel.CreateDefaultContext()
    ctx.SetDiscreteState(np.concatenate([prev, target]))
    sel.GetInputPort("q_full").FixValue(ctx, q_full)
    sel.GetInputPort("q_position").FixValue(ctx, q_pos)
    sel.GetInputPort("X_AE_desired").FixValue(ctx, RigidTransform(target if desired is None else desired))
    return sel, ctx


def test_stuck_full_pose_gives_way_to_the_position_only_command(plant):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    q_pos = q0 + np.array([0.05, 0.05, 0.0, 0.05, 0.0, 0.0, 0.0])
    far = _tool(plant, q0) + np.array([0.2, 0.0, 0.0])
    # The full-pose step barely moves the tool (< a tenth of the position-only step): the position-only command.
    q_stuck = q0 + 1e-4
    p0 = _tool(plant, q0)
    assert np.linalg.norm(_tool(plant, q_stuck) - p0) < 0.1 * np.linalg.norm(_tool(plant, q_pos) - p0)
    sel, ctx = _selector(plant, q0, far, q_stuck, q_pos)
    np.testing.assert_array_equal(sel.get_output_port().Eval(ctx), q_pos)
    # A full-pose step that moves as far as the position-only one is kept.
    q_moving = q0 + np.array([0.0, 0.05, 0.05, 0.05, 0.0, 0.0, 0.0])
    sel, ctx = _selector(plant, q0, far, q_moving, q_pos)
    np.testing.assert_array_equal(sel.get_output_port().Eval(ctx), q_moving)


def test_full_pose_when_converged_or_before_the_first_step(plant):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    q_pos = q0 + 0.05
    near = _tool(plant, q0) + np.array([0.004, 0.0, 0.0])  # within min_error_m = 5 mm of the tool
    sel, ctx = _selector(plant, q0, near, q0, q_pos)
    np.testing.assert_array_equal(sel.get_output_port().Eval(ctx), q0)
    # No previous step yet (NaN state): the full pose.
    sel, ctx = _selector(plant, np.full(7, np.nan), np.full(3, np.nan), q0, q_pos)
    np.testing.assert_array_equal(sel.get_output_port().Eval(ctx), q0)


def test_update_latches_the_choice_and_the_target(plant):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    target = _tool(plant, q0) + np.array([0.0, 0.0, 0.3])
    sel, ctx = _selector(plant, np.full(7, np.nan), np.full(3, np.nan), q0 + 0.01, q0 + 0.02, desired=target)
    sim = Simulator(sel, ctx)
    sim.AdvanceTo(0.5 * DT)  # the update at t = 0
    state = ctx.get_discrete_state_vector().CopyToVector()
    np.testing.assert_array_equal(state[:7], q0 + 0.01)  # no previous step: the full pose was chosen
    np.testing.assert_allclose(state[7:], target, atol=1e-15)
