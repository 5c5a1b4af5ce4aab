"""TeleopMonitor: counts NaN commands and limit hits, measures target-to-end-effector distances."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from akc_drake.robot.model import NOMINAL_ARM_Q, arm_joint_limits, arm_motion_limits, nominal_ee_pose
from akc_drake.robot.station import AddRobotStation
from akc_drake.systems.teleop_monitor import TeleopMonitor


def _run(q_left, target_offset=(0.0, 0.0, 0.0), seconds=0.3, acceleration_limits=None):
    builder = DiagramBuilder()
    station = AddRobotStation(builder, time_step=0.005, weld_base=True)
    mon = builder.AddSystem(TeleopMonitor(station.plant, station.robot, period_s=0.01,
                                          acceleration_limits=acceleration_limits))
    for side in ("left", "right"):
        X = nominal_ee_pose(side)
        X = RigidTransform(X.rotation(), X.translation() + np.asarray(target_offset))
        tgt = builder.AddSystem(ConstantValueSource(AbstractValue.Make(X)))
        builder.Connect(tgt.get_output_port(), mon.GetInputPort(f"X_TE_desired_{side}"))
        q = q_left if side == "left" else NOMINAL_ARM_Q
        cmd = builder.AddSystem(TrajectorySource(q) if isinstance(q, PiecewisePolynomial) else ConstantVectorSource(q))
        builder.Connect(cmd.get_output_port(), mon.GetInputPort(f"q_commanded_{side}"))
        builder.Connect(station.arm_position_output[side], station.arm_position_input[side])  # hold still
    lost = builder.AddSystem(ConstantVectorSource(np.zeros(2)))
    builder.Connect(lost.get_output_port(), mon.GetInputPort("tracking_lost"))
    builder.Connect(station.robot_state_output, mon.GetInputPort("robot_state"))
    Simulator(builder.Build()).AdvanceTo(seconds)
    return mon


def test_nominal_posture_tracks_its_own_pose_with_no_faults():
    mon = _run(np.asarray(NOMINAL_ARM_Q, dtype=float))
    assert mon.samples == 31 and mon.nan_commands == 0 and mon.position_limit_hits == 0
    assert mon.max_speed_ratio == 0.0 and mon.max_acceleration_ratio == 0.0  # constant commands
    assert np.max(mon.ee_errors("left")) < 0.01  # the robot holds its nominal pose: target = achieved
    h = mon.history_arrays()
    assert h["q_left"].shape == (31, 7) and h["target_right"].shape == (31, 4, 4)
    # The measured joint state (the plant's), held at the nominal posture, at rest.
    assert h["q_measured_left"].shape == (31, 7) and h["v_measured_right"].shape == (31, 7)
    np.testing.assert_allclose(h["q_measured_left"], np.tile(NOMINAL_ARM_Q, (31, 1)), atol=1e-3)
    assert np.max(np.abs(h["v_measured_right"])) < 1e-2


def test_counts_nan_commands_limit_hits_and_target_distance():
    q = np.asarray(NOMINAL_ARM_Q, dtype=float).copy()
    q[0] = np.nan
    assert _run(q).nan_commands == 31
    lo, _, _ = arm_joint_limits("left")
    q = np.asarray(NOMINAL_ARM_Q, dtype=float).copy()
    q[3] = lo[3]
    assert _run(q).position_limit_hits == 31
    far = _run(np.asarray(NOMINAL_ARM_Q, dtype=float), target_offset=(0.0, 0.0, 0.1))
    np.testing.assert_allclose(far.ee_errors("right"), 0.1, atol=0.01)


def test_commanded_acceleration_against_its_limit():
    n = np.asarray(NOMINAL_ARM_Q, dtype=float)
    acc = arm_motion_limits("left")[0][0]
    # Joint 1 at half its acceleration limit from rest (samples of the parabola, exact at the 10 ms knots).
    t = np.arange(0.0, 0.31, 0.01)
    q = np.tile(n[:, None], (1, len(t)))
    q[0] += 0.25 * acc * t**2
    mon = _run(PiecewisePolynomial.FirstOrderHold(t, q))
    assert mon.max_acceleration_ratio == pytest.approx(0.5, rel=1e-6) and mon.acceleration_limit_hits == 0
    # Held, then moving at 0.5 rad/s from one 10 ms step to the next: 50 rad/s^2, once.
    q = np.tile(n[:, None], (1, 3))
    q[0, 2] += 0.1
    mon = _run(PiecewisePolynomial.FirstOrderHold([0.0, 0.1, 0.3], q))
    assert mon.max_acceleration_ratio == pytest.approx(0.5 / 0.01 / acc, rel=1e-6)
    assert mon.acceleration_limit_hits == 1


def test_measures_against_the_acceleration_limits_given():
    n = np.asarray(NOMINAL_ARM_Q, dtype=float)
    acc = arm_motion_limits("left")[0]
    t = np.arange(0.0, 0.31, 0.01)
    q = np.tile(n[:, None], (1, len(t)))
    q[0] += 0.25 * acc[0] * t**2  # half the model's limit
    # The left arm's limits halved: the same commands read a full limit; the right arm keeps the model's.
    mon = _run(PiecewisePolynomial.FirstOrderHold(t, q), acceleration_limits={"left": acc / 2})
    assert mon.max_acceleration_ratio == pytest.approx(1.0, rel=1e-6) and mon.acceleration_limit_hits == 0
    np.testing.assert_array_equal(mon.acceleration_limits["left"], acc / 2)
    np.testing.assert_array_equal(mon.acceleration_limits["right"], arm_motion_limits("right")[0])
    mon = _run(PiecewisePolynomial.FirstOrderHold(t, q), acceleration_limits={"left": acc / 4})
    assert mon.max_acceleration_ratio == pytest.approx(2.0, rel=1e-6) and mon.acceleration_limit_hits > 0


@pytest.mark.parametrize("limits, match", [({"middle": np.ones(7)}, "sides must be in"),
                                           ({"left": np.ones(6)}, r"acceleration_limits\['left'\] must be 7 finite"),
                                           ({"right": np.zeros(7)}, "must be > 0")])
def test_refuses_bad_acceleration_limits(limits, match):
    builder = DiagramBuilder()
    station = AddRobotStation(builder, time_step=0.005, weld_base=True)
    with pytest.raises(ValueError, match=match):
        TeleopMonitor(station.plant, station.robot, period_s=0.01, acceleration_limits=limits)
