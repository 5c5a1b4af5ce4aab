"""JointCommandGuard: the arm's joint command finite, within its limits and its velocity limits."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from akc_drake.robot.joint_command_guard import JointCommandGuard


def test_joint_command_guard():
    lower, upper = -np.ones(2), np.ones(2)
    vel = np.array([1.0, 2.0])
    guard = JointCommandGuard(lower, upper, vel, 0.1)
    context = guard.CreateDefaultContext()
    guard.GetInputPort("q_initial").FixValue(context, [0.0, 5.0])
    guard.GetInputPort("q").FixValue(context, [0.5, 0.5])
    out = guard.GetOutputPort("q_commanded")
    # Before initialisation: the (clipped) initial positions.
    np.testing.assert_allclose(out.Eval(context), [0.0, 1.0])
    simulator = Simulator(guard, context)
    simulator.Initialize()
    # Steps are limited to vel * period from the last command, positions to the limits.
    np.testing.assert_allclose(out.Eval(context), [0.1, 0.8])
    simulator.AdvanceTo(0.05)  # the update at t = 0 stored [0.1, 0.8]
    np.testing.assert_allclose(out.Eval(context), [0.2, 0.6])
    np.testing.assert_allclose(guard.GetOutputPort("v_commanded").Eval(context), [1.0, -2.0])
    simulator.AdvanceTo(0.25)  # updates at 0.1, 0.2
    np.testing.assert_allclose(out.Eval(context), [0.4, 0.5])
    guard.GetInputPort("q").FixValue(context, [np.nan, 0.0])
    np.testing.assert_allclose(out.Eval(context), [0.3, 0.5])  # the last stored command
    np.testing.assert_allclose(guard.GetOutputPort("v_commanded").Eval(context), [0.0, 0.0])
    simulator.AdvanceTo(0.45)
    assert guard.held_count(context) == 2
    np.testing.assert_allclose(out.Eval(context), [0.3, 0.5])
    with pytest.raises(ValueError):
        JointCommandGuard(lower, upper, np.array([1.0, 0.0]), 0.1)
