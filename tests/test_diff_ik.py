"""Differential IK per arm (akc_drake.robot.diff_ik): reaching, limits, unreachable and invalid targets."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.inverse_kinematics import DifferentialInverseKinematicsStatus
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from akc_drake.robot.diff_ik import (
    DEFAULT_POSITION_LIMIT_MARGIN,
    DEFAULT_VELOCITY_LIMIT_SCALE,
    AddArmDifferentialIK,
    arm_ik_parameters,
    make_arm_ik_plant,
)
from akc_drake.robot.model import (
    NOMINAL_ARM_Q,
    arm_joint_limits,
    arm_motion_limits,
    arm_position_indices,
    ee_frame,
    nominal_ee_pose,
    torso_frame,
)

IK_DT = 0.01


@pytest.fixture(scope="module")
def ik_plants():
    return {side: make_arm_ik_plant(side) for side in ("left", "right")}


class IKRig:
    """One arm's IK alone, its target a fixed input value, its commands logged at the IK period: the guard's
    (``q``, ``v_log``: the IK's loop) and the motion limiter's (``q_out``: what the robot gets)."""

    def __init__(self, plant, side, **kwargs):
        builder = DiagramBuilder()
        self.ik = AddArmDifferentialIK(builder, plant, side, IK_DT, **kwargs)
        self.target_port = builder.ExportInput(self.ik.X_TE_desired_input, "X_TE_desired")
        guard = self.ik.command_guard
        self.q_log = LogVectorOutput(guard.GetOutputPort("q_commanded"), builder, publish_period=IK_DT)
        self.raw_log = LogVectorOutput(self.ik.integrator.GetOutputPort("joint_positions"), builder, IK_DT)
        self.v_log = LogVectorOutput(guard.GetOutputPort("v_commanded"), builder, publish_period=IK_DT)
        self.out_log = LogVectorOutput(self.ik.q_commanded_output, builder, publish_period=IK_DT)
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()

    def run(self, X_TE_desired, until):
        self.diagram.get_input_port(self.target_port).FixValue(self.context, AbstractValue.Make(X_TE_desired))
        self.simulator.AdvanceTo(until)
        return self.ik.commanded_pose(self.context)

    def q(self):
        return self.q_log.FindLog(self.context).data().T

    def q_out(self):
        return self.out_log.FindLog(self.context).data().T


def pose_error(X, Y):
    return (
        float(np.linalg.norm(X.translation() - Y.translation())),
        float(X.rotation().InvertAndCompose(Y.rotation()).ToAngleAxis().angle()),
    )


def test_ik_plants():
    both = make_arm_ik_plant(None)
    assert both.num_positions() == 14
    for side in ("left", "right"):
        plant = make_arm_ik_plant(side)
        assert plant.num_positions() == 7
        np.testing.assert_array_equal(np.sort(arm_position_indices(plant, side)), np.arange(7))
        np.testing.assert_allclose(
            plant.GetDefaultPositions()[arm_position_indices(plant, side)], NOMINAL_ARM_Q
        )
        # X_TE in the IK plant equals the full robot's at the same arm posture.
        context = plant.CreateDefaultContext()
        X = ee_frame(plant, side).CalcPose(context, torso_frame(plant))
        assert X.IsNearlyEqualTo(nominal_ee_pose(side), 1e-12)


@pytest.mark.parametrize(
    "side, dp, rpy",
    [
        ("left", [0.05, 0.10, 0.15], [0.2, 0.1, -0.3]),
        ("right", [-0.20, 0.10, -0.10], [0.0, -0.4, 0.3]),
        ("right", [-0.15, -0.10, 0.05], [0.3, 0.0, 0.2]),
    ],
)
def test_reaches_a_reachable_pose_within_1cm(ik_plants, side, dp, rpy):
    X0 = nominal_ee_pose(side)
    target = RigidTransform(RollPitchYaw(rpy).ToRotationMatrix() @ X0.rotation(), X0.translation() + dp)
    rig = IKRig(ik_plants[side], side)
    X = rig.run(target, 2.0)
    dist, angle = pose_error(X, target)
    assert dist < 0.01 and angle < 0.02, (dist, angle)
    assert rig.ik.status(rig.context) == DifferentialInverseKinematicsStatus.kSolutionFound
    # It starts at the nominal posture and actually moved there.
    q = rig.q()
    np.testing.assert_allclose(q[0], NOMINAL_ARM_Q, atol=1e-12)
    assert np.linalg.norm(q[-1] - q[0]) > 0.1


@settings(max_examples=6, deadline=None)
@given(st.lists(st.floats(-0.5, 0.5), min_size=7, max_size=7))
def test_reaches_forward_kinematics_of_nearby_postures(ik_plants, dq):
    """Any pose the arm itself takes at a posture near the nominal one is reached within 1 cm, 0.02 rad."""
    side = "left"
    plant = ik_plants[side]
    lower, upper, _ = arm_joint_limits(side)
    q = np.clip(NOMINAL_ARM_Q + np.array(dq), lower + 0.05, upper - 0.05)
    context = plant.CreateDefaultContext()
    positions = plant.GetDefaultPositions()
    positions[arm_position_indices(plant, side)] = q
    plant.SetPositions(context, positions)
    target = ee_frame(plant, side).CalcPose(context, torso_frame(plant))
    rig = IKRig(plant, side)
    dist, angle = pose_error(rig.run(target, 2.0), target)
    assert dist < 0.01 and angle < 0.02, (dist, angle)


def test_unreachable_target_respects_velocity_and_position_limits(ik_plants):
    side = "right"
    rig = IKRig(ik_plants[side], side)
    X0 = nominal_ee_pose(side)
    shoulder = rig.ik.pose_guard.p_TS
    far = RigidTransform(X0.rotation(), [1.2, -0.5, 0.3])
    X = rig.run(far, 3.0)
    q = rig.q()
    lower, upper, vel = arm_joint_limits(side)
    assert np.all(np.isfinite(q))
    # Commands (logged every IK period) never move faster than the joint velocity limits ...
    speed = np.abs(np.diff(q, axis=0)) / IK_DT
    assert np.all(speed <= vel * (1 + 1e-9)), speed.max(axis=0) / vel
    # ... and the IK's own steps (before the guard) keep its 0.98-scaled limits up to the QP tolerance.
    raw = rig.raw_log.FindLog(rig.context).data().T
    raw_speed = np.abs(raw[1:] - q[:-1]) / IK_DT  # each IK step starts from the previous command
    assert np.all(raw_speed <= vel * DEFAULT_VELOCITY_LIMIT_SCALE + 0.01)
    # It moved as fast as it was allowed to at some point, so the limit was actually active.
    assert np.any(speed >= vel * DEFAULT_VELOCITY_LIMIT_SCALE * 0.999)
    assert np.all(q >= lower + DEFAULT_POSITION_LIMIT_MARGIN - 1e-12)
    assert np.all(q <= upper - DEFAULT_POSITION_LIMIT_MARGIN + 1e-12)
    # The arm ends as close as its reach allows: on the 0.85 m shell, on the ray toward the target.
    d_far = far.translation() - shoulder
    d_got = X.translation() - shoulder
    assert np.linalg.norm(d_got) == pytest.approx(0.85, abs=0.01)
    assert d_got @ d_far / np.linalg.norm(d_got) / np.linalg.norm(d_far) > 0.999
    # The v_commanded feedforward is the command's finite difference.
    v = rig.v_log.FindLog(rig.context).data().T
    np.testing.assert_allclose(v[1:], np.diff(q, axis=0) / IK_DT, atol=1e-9)


def test_the_robot_gets_the_command_within_its_acceleration_limits(ik_plants):
    side = "left"
    X0 = nominal_ee_pose(side)
    target = RigidTransform(X0.rotation(), X0.translation() + [0.15, 0.1, 0.1])
    rig = IKRig(ik_plants[side], side)
    assert rig.ik.limiter is not None
    rig.run(target, 1.5)
    q, out = rig.q(), rig.q_out()
    acc, _ = arm_motion_limits(side)
    # The guard's command starts at the velocity limits (hundreds of rad/s^2); the limiter's stays within them,
    # and arrives where the IK ended.
    assert np.max(np.abs(np.diff(q, 2, axis=0)) / IK_DT**2 / acc) > 10.0
    assert np.max(np.abs(np.diff(out, 2, axis=0)) / IK_DT**2 / acc) <= 1.0 + 1e-9
    np.testing.assert_allclose(out[-1], q[-1], atol=1e-4)  # (the IK still creeps: the limiter is a step behind)
    np.testing.assert_allclose(out[0], NOMINAL_ARM_Q, atol=1e-12)
    # Without it the robot gets the guard's command.
    plain = IKRig(ik_plants[side], side, motion_limits=False)
    assert plain.ik.limiter is None
    plain.run(target, 0.5)
    np.testing.assert_array_equal(plain.q_out(), plain.q())
    with pytest.raises(ValueError, match="motion_limits"):
        IKRig(ik_plants[side], side, motion_limits=None)
    with pytest.raises(ValueError, match="JointMotionLimiter: jerk"):
        IKRig(ik_plants[side], side, motion_limits=(np.full(7, 10.0), np.full(6, 1e3)))


def test_leaving_home_for_a_target_beside_the_robot_takes_a_joint_space_move(ik_plants):
    # The demo's first target for the right arm (the operator in a T-pose, MediaPipe, seed 0): from the home pose
    # the differential IK's straight line runs into a joint limit and both IKs are stuck (they reach it after 1.2 s).
    side = "right"
    X = RigidTransform(RollPitchYaw(0.03, 0.85, 0.17), [0.25, -0.88, 0.03])
    stuck = IKRig(ik_plants[side], side, joint_space_approach=False)
    assert pose_error(stuck.run(X, 0.6), X)[0] > 0.4
    rig = IKRig(ik_plants[side], side)
    assert rig.ik.approach is not None and not rig.ik.approaching(rig.context)
    rig.run(X, 0.4)
    assert rig.ik.approaching(rig.context)
    dist, angle = pose_error(rig.run(X, 0.8), X)
    assert dist < 0.01 and angle < np.radians(2.0), (dist, angle)
    assert not rig.ik.approaching(rig.context)  # arrived: the differential IK again
    q = rig.q()
    lower, upper, vel = arm_joint_limits(side)
    assert np.all(np.abs(np.diff(q, axis=0)) / IK_DT <= vel * (1 + 1e-9))
    assert np.all(q >= lower + DEFAULT_POSITION_LIMIT_MARGIN - 1e-12)
    assert np.all(q <= upper - DEFAULT_POSITION_LIMIT_MARGIN + 1e-12)


def test_invalid_target_holds_then_recovers(ik_plants):
    side = "left"
    rig = IKRig(ik_plants[side], side)
    X0 = nominal_ee_pose(side)
    moved = RigidTransform(X0.rotation(), X0.translation() + [0.0, 0.0, 0.1])
    rig.run(moved, 1.0)
    q_before = rig.q()[-1]
    nan_target = RigidTransform(RotationMatrix(), [np.nan, 0.0, 0.0])
    rig.run(nan_target, 1.5)
    skewed = RigidTransform(RotationMatrix(np.diag([1.0, 1.0, 2.0])), [0.5, 0.2, -0.2])
    rig.run(skewed, 2.0)
    q = rig.q()
    held = q[len(q) - 100 :]
    assert np.all(np.isfinite(q))
    # Held still (only the null-space centering may move the elbow, which keeps the end effector fixed).
    X_held = rig.ik.commanded_pose(rig.context)
    dist, angle = pose_error(X_held, moved)
    assert dist < 1e-3 and angle < 1e-3
    assert np.max(np.abs(held[-1] - q_before)) < 0.05
    back = rig.run(X0, 4.0)
    dist, angle = pose_error(back, X0)
    assert dist < 1e-3 and angle < 1e-3


def test_starts_from_measured_or_given_posture(ik_plants):
    side = "right"
    q0 = NOMINAL_ARM_Q + np.array([0.2, -0.1, 0.3, 0.2, -0.2, 0.1, 0.3])
    rig = IKRig(ik_plants[side], side, initial_q=q0)
    plant = ik_plants[side]
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q0)  # the IK plant's positions are exactly this arm's 7
    X_start = ee_frame(plant, side).CalcPose(context, torso_frame(plant))
    X = rig.run(X_start, 0.5)
    assert pose_error(X, X_start)[0] < 1e-6
    np.testing.assert_allclose(rig.q()[0], q0, atol=1e-9)
    with pytest.raises(ValueError, match="initial_q"):
        IKRig(plant, side, initial_q=[0.0, 1.0])


def test_parameters(ik_plants):
    plant = make_arm_ik_plant(None)
    params = arm_ik_parameters(plant, "right", 0.01, centering_gain=2.0)
    idx_r = arm_position_indices(plant, "right")
    idx_l = arm_position_indices(plant, "left")
    lo_v, hi_v = params.get_joint_velocity_limits()
    _, _, vel = arm_joint_limits("right")
    np.testing.assert_allclose(hi_v[idx_r], vel * DEFAULT_VELOCITY_LIMIT_SCALE)
    np.testing.assert_allclose(hi_v[idx_l], 0.0)  # the other arm is frozen
    K = params.get_joint_centering_gain()
    np.testing.assert_allclose(np.diag(K)[idx_r], 2.0)
    np.testing.assert_allclose(np.diag(K)[idx_l], 0.0)
    assert params.get_time_step() == 0.01
    for bad in (dict(ee_speed_limit=0.0), dict(velocity_limit_scale=1.5), dict(centering_gain=-1.0)):
        with pytest.raises(ValueError):
            arm_ik_parameters(plant, "right", 0.01, **bad)
    with pytest.raises(ValueError, match="side"):
        arm_ik_parameters(plant, "up", 0.01)
    with pytest.raises(ValueError, match="time_step"):
        AddArmDifferentialIK(DiagramBuilder(), plant, "left", 0.0)


def test_both_arms_on_one_ik_plant():
    """Two IKs may share a 14-DoF IK plant: each moves only its own arm."""
    plant = make_arm_ik_plant(None)
    builder = DiagramBuilder()
    iks = {s: AddArmDifferentialIK(builder, plant, s, IK_DT) for s in ("left", "right")}
    ports = {s: builder.ExportInput(iks[s].X_TE_desired_input, s) for s in iks}
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    targets = {}
    for s, dz in (("left", 0.1), ("right", -0.1)):
        X0 = nominal_ee_pose(s)
        targets[s] = RigidTransform(X0.rotation(), X0.translation() + [0.0, 0.0, dz])
        diagram.get_input_port(ports[s]).FixValue(context, AbstractValue.Make(targets[s]))
    simulator.AdvanceTo(1.5)
    for s in iks:
        dist, angle = pose_error(iks[s].commanded_pose(context), targets[s])
        assert dist < 1e-3 and angle < 1e-3


@pytest.mark.parametrize(
    "side, p, rpy",
    [
        ("right", [1.4, -0.9, 0.5], [0.0, -1.2, 0.8]),  # far away and twisted
        ("right", [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]),  # across the body: joint limits stop it
        ("left", [0.1, 0.2, -0.05], [3.0, 0.0, 0.0]),  # inside the shoulder, upside down
    ],
)
def test_any_target_gives_finite_commands_within_limits(ik_plants, side, p, rpy):
    rig = IKRig(ik_plants[side], side)
    X0 = nominal_ee_pose(side)
    rig.run(RigidTransform(RotationMatrix(RollPitchYaw(rpy)) @ X0.rotation(), p), 3.0)
    q = rig.q()
    lower, upper, vel = arm_joint_limits(side)
    assert np.all(np.isfinite(q))
    assert np.all(np.abs(np.diff(q, axis=0)) / IK_DT <= vel * (1 + 1e-9))
    assert np.all((q >= lower) & (q <= upper))
    assert rig.ik.held_count(rig.context) == 0
