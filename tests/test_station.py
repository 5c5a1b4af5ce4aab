"""The robot station (akc_drake.robot.station): holding, step tracking, grippers, torso, with IK."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from akc_drake.robot.diff_ik import AddArmDifferentialIK, make_arm_ik_plant
from akc_drake.robot.model import (
    NOMINAL_ARM_Q,
    NOMINAL_FINGER_OPENING,
    SIDES,
    arm_joint_limits,
    arm_joint_names,
    gripper_joint_names,
    nominal_ee_pose,
    torso_frame,
)
from akc_drake.robot.station import AddRobotStation, RobotCommandAssembler


def build(**kwargs):
    builder = DiagramBuilder()
    station = AddRobotStation(builder, **kwargs)
    return builder, station


def arm_q(station, side, root_context):
    port = station.arm_position_output[side]
    return port.Eval(port.get_system().GetMyContextFromRoot(root_context))


def test_holds_nominal_posture_under_gravity():
    builder, station = build()
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    plant_context = station.plant.GetMyContextFromRoot(context)
    # Gravity is on and acts on the arms: without control they would fall.
    tau_g = station.plant.CalcGravityGeneralizedForces(plant_context)
    assert np.max(np.abs(tau_g)) > 5.0
    simulator.AdvanceTo(1.5)
    for side in SIDES:
        q = arm_q(station, side, context)
        assert np.max(np.abs(q - NOMINAL_ARM_Q)) < 1e-3
        drift = np.linalg.norm(
            station.ee_pose(plant_context, side).translation() - nominal_ee_pose(side).translation()
        )
        assert drift < 0.003  # within a few mm
    # The box still rests on the table, the torso at its default height.
    obj = station.plant.GetBodyByName("object", station.scene)
    assert station.plant.EvalBodyPoseInWorld(plant_context, obj).translation()[2] == pytest.approx(
        0.745, abs=2e-3
    )
    z_T = torso_frame(station.plant, station.robot).CalcPoseInWorld(plant_context).translation()[2]
    assert z_T == pytest.approx(1.10, abs=2e-3)


def test_tracks_a_step_command():
    builder, station = build(weld_base=True)
    log = LogVectorOutput(station.arm_position_output["left"], builder, publish_period=0.01)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    step = np.array([0.3, -0.2, 0.3, -0.3, 0.4, -0.3, 0.4])
    q_cmd = NOMINAL_ARM_Q + step
    station.arm_position_input["left"].FixValue(station.command.GetMyContextFromRoot(context), q_cmd)
    simulator.AdvanceTo(1.5)
    q = log.FindLog(context).data().T
    t = log.FindLog(context).sample_times()
    err = np.abs(q - q_cmd)
    # Settles within 5 mrad of the command on every joint by 1 s, and stays there.
    assert np.all(err[t >= 1.0] < 5e-3), err[t >= 1.0].max(axis=0)
    # Rises quickly: at least 80 % of the way on every joint after 0.5 s.
    k = np.searchsorted(t, 0.5)
    assert np.all((q[k] - NOMINAL_ARM_Q) / step > 0.8)
    # Overshoot stays small.
    overshoot = np.max((q - NOMINAL_ARM_Q) / step, axis=0) - 1.0
    assert np.all(overshoot < 0.15), overshoot
    # The other arm did not move.
    assert np.max(np.abs(arm_q(station, "right", context) - NOMINAL_ARM_Q)) < 2e-3


def test_gripper_and_torso_commands():
    builder, station = build()
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    command_context = station.command.GetMyContextFromRoot(context)
    station.gripper_input["left"].FixValue(command_context, [0.035])
    station.torso_lift_input.FixValue(command_context, [0.30])
    simulator.AdvanceTo(2.0)
    plant_context = station.plant.GetMyContextFromRoot(context)
    for name in gripper_joint_names("left"):
        assert station.plant.GetJointByName(name).get_translation(plant_context) == pytest.approx(
            0.035, abs=2e-3
        )
    for name in gripper_joint_names("right"):
        assert station.plant.GetJointByName(name).get_translation(plant_context) == pytest.approx(
            NOMINAL_FINGER_OPENING, abs=2e-3
        )
    z_T = torso_frame(station.plant, station.robot).CalcPoseInWorld(plant_context).translation()[2]
    assert z_T == pytest.approx(0.95 + 0.30, abs=5e-3)


def test_station_with_differential_ik_reaches_targets():
    """Both arms' IK at 100 Hz on the station at 2 ms: the measured end effectors reach the targets."""
    builder, station = build(time_step=0.002, weld_base=True)
    ik_plant = make_arm_ik_plant(None)
    targets = {}
    for side, dp, rpy in (
        ("left", [-0.05, 0.05, 0.10], [0.2, 0.0, 0.2]),
        ("right", [0.05, 0.0, -0.1], [0, 0.3, 0]),
    ):
        ik = AddArmDifferentialIK(
            builder, ik_plant, side, 0.01, measured_q_port=station.arm_position_output[side]
        )
        builder.Connect(ik.q_commanded_output, station.arm_position_input[side])
        builder.Connect(ik.v_commanded_output, station.arm_velocity_input[side])
        X0 = nominal_ee_pose(side)
        targets[side] = RigidTransform(
            RollPitchYaw(rpy).ToRotationMatrix() @ X0.rotation(), X0.translation() + dp
        )
        builder.ExportInput(ik.X_TE_desired_input, f"{side}_X_TE_desired")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    for side in SIDES:
        diagram.GetInputPort(f"{side}_X_TE_desired").FixValue(context, AbstractValue.Make(targets[side]))
    simulator.AdvanceTo(2.0)
    plant_context = station.plant.GetMyContextFromRoot(context)
    for side in SIDES:
        X = station.ee_pose(plant_context, side)
        assert np.linalg.norm(X.translation() - targets[side].translation()) < 0.01
        assert X.rotation().InvertAndCompose(targets[side].rotation()).ToAngleAxis().angle() < 0.03


def test_command_assembler():
    builder, station = build(weld_base=True, add_scene=False)
    assert station.scene is None
    assembler = station.command
    assert isinstance(assembler, RobotCommandAssembler)
    context = assembler.CreateDefaultContext()
    nu = station.plant.num_actuators(station.robot)
    xd = assembler.get_output_port().Eval(context)
    assert xd.shape == (2 * nu,)
    assert np.all(xd[nu:] == 0.0)
    lower, upper, _ = arm_joint_limits("right")
    assembler.GetInputPort("right_arm.position").FixValue(context, upper + 1.0)
    xd = assembler.get_output_port().Eval(context)
    names = [
        station.plant.get_joint_actuator(i).joint().name()
        for i in station.plant.GetJointActuatorIndices(station.robot)
    ]
    slots = [names.index(n) for n in arm_joint_names("right")]
    # The request beyond the limits is clipped to them; the other arm holds its default posture.
    np.testing.assert_allclose(xd[slots], upper)
    np.testing.assert_allclose(xd[[names.index(n) for n in arm_joint_names("left")]], NOMINAL_ARM_Q)
    assembler.GetInputPort("right_arm.position").FixValue(context, np.full(7, np.nan))
    with pytest.raises(ValueError, match="right_arm.position"):
        assembler.get_output_port().Eval(context)
    assert not assembler.HasInputPort("base.position")
    _, mobile = build(add_scene=False)
    assert mobile.command.HasInputPort("base.position")


def test_rejects_bad_time_step():
    for bad in (0.0, -0.001, float("nan")):
        with pytest.raises(ValueError, match="time_step"):
            AddRobotStation(DiagramBuilder(), time_step=bad)
