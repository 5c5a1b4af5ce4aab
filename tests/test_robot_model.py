"""The dual-arm robot model (models/dual_arm_manipulator.urdf) and akc_drake.robot.model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import PrismaticJoint, RevoluteJoint, SpatialInertia, UnitInertia

from akc_drake.core import frames
from akc_drake.resources import model_path
from akc_drake.robot.model import (
    BASE_JOINTS,
    HEAD_JOINTS,
    NOMINAL_ARM_Q,
    NOMINAL_TORSO_LIFT,
    ROBOT_MODEL_FILE,
    SCENE_MODEL_FILE,
    SIDES,
    TORSO_JOINT,
    ToolPoint,
    add_dual_arm_robot,
    arm_joint_limits,
    arm_joint_names,
    arm_motion_limits,
    arm_position_indices,
    ee_frame,
    finite_vectors,
    gripper_joint_names,
    nominal_ee_pose,
    torso_frame,
)

MIRROR = np.diag([1.0, -1.0, 1.0])
FLIP_Z = np.diag([1.0, 1.0, -1.0])


@pytest.fixture(scope="module")
def robot():
    plant = MultibodyPlant(0.0)
    model = add_dual_arm_robot(plant)
    plant.Finalize()
    return plant, model


def _set_arm(plant, context, side, q):
    for name, value in zip(arm_joint_names(side), q, strict=True):
        plant.GetJointByName(name).set_angle(context, float(value))


def test_model_file_is_self_contained():
    text = model_path(ROBOT_MODEL_FILE).read_text()
    # No external files at all (no meshes, no package:// or file URIs).
    assert "filename=" not in text
    assert "<mesh" not in text
    # Parses with a bare Parser (no package map, no network) into a fresh plant.
    plant = MultibodyPlant(0.001)
    (model,) = Parser(plant).AddModels(str(model_path(ROBOT_MODEL_FILE)))
    plant.Finalize()
    assert plant.num_positions(model) == 24  # 3 base + torso + 2 head + 2 x 7 arm + 4 fingers


def test_arm_joints_and_limits(robot):
    plant, model = robot
    expected_vel = [1.95, 1.95, 3.95, 3.95, 3.95, 3.95, 3.95]
    expected_deg = [
        (-148.97, 148.97),
        (-139.8, 63.03),
        (-148.97, 148.97),
        (-139.8, 63.03),
        (-148.97, 148.97),
        (-114.59, 114.59),
        (-139.8, 139.8),
    ]
    for side in SIDES:
        names = arm_joint_names(side)
        assert names == [f"arm_{side}_{i}_joint" for i in range(1, 8)]
        lower, upper, vel = arm_joint_limits(side)
        for i, name in enumerate(names):
            joint = plant.GetJointByName(name, model)
            assert isinstance(joint, RevoluteJoint)
            assert joint.velocity_upper_limits()[0] == pytest.approx(expected_vel[i])
            assert joint.velocity_lower_limits()[0] == pytest.approx(-expected_vel[i])
            lo, hi = expected_deg[i]
            assert math.degrees(joint.position_lower_limits()[0]) == pytest.approx(lo, abs=1e-3)
            assert math.degrees(joint.position_upper_limits()[0]) == pytest.approx(hi, abs=1e-3)
            # arm_joint_limits() reports what the file says.
            assert lower[i] == pytest.approx(joint.position_lower_limits()[0], abs=1e-10)
            assert upper[i] == pytest.approx(joint.position_upper_limits()[0], abs=1e-10)
            assert vel[i] == pytest.approx(expected_vel[i])


def test_torso_base_head_gripper_joints(robot):
    plant, model = robot
    torso = plant.GetJointByName(TORSO_JOINT, model)
    assert isinstance(torso, PrismaticJoint)
    assert torso.position_lower_limits()[0] == 0.0
    assert torso.position_upper_limits()[0] == pytest.approx(0.35)
    np.testing.assert_allclose(torso.translation_axis(), [0, 0, 1])
    x, y, yaw = (plant.GetJointByName(n, model) for n in BASE_JOINTS)
    assert isinstance(x, PrismaticJoint) and isinstance(y, PrismaticJoint) and isinstance(yaw, RevoluteJoint)
    np.testing.assert_allclose(x.translation_axis(), [1, 0, 0])
    np.testing.assert_allclose(y.translation_axis(), [0, 1, 0])
    np.testing.assert_allclose(yaw.revolute_axis(), [0, 0, 1])
    assert x.frame_on_parent().body().index() == plant.world_body().index()
    for name in HEAD_JOINTS:
        assert isinstance(plant.GetJointByName(name, model), RevoluteJoint)
    for side in SIDES:
        for name in gripper_joint_names(side):
            finger = plant.GetJointByName(name, model)
            assert isinstance(finger, PrismaticJoint)
            assert finger.position_lower_limits()[0] == 0.0
            assert finger.position_upper_limits()[0] == pytest.approx(0.04)


def test_every_moving_joint_is_actuated(robot):
    plant, model = robot
    actuated = {}
    for i in plant.GetJointActuatorIndices(model):
        a = plant.get_joint_actuator(i)
        actuated[a.joint().name()] = a.effort_limit()
    moving = [
        plant.get_joint(i).name()
        for i in plant.GetJointIndices(model)
        if plant.get_joint(i).num_velocities() > 0
    ]
    assert sorted(actuated) == sorted(moving)
    assert len(moving) == 24
    assert all(e > 0 and math.isfinite(e) for e in actuated.values())
    assert actuated["arm_left_1_joint"] == pytest.approx(43.0)
    assert actuated["arm_right_7_joint"] == pytest.approx(26.0)


def test_inertias_are_physically_valid(robot):
    plant, model = robot
    context = plant.CreateDefaultContext()
    total = 0.0
    for index in plant.GetBodyIndices(model):
        body = plant.get_body(index)
        M = body.CalcSpatialInertiaInBodyFrame(context)
        assert M.IsPhysicallyValid(), body.name()
        assert M.get_mass() > 0.0, body.name()
        # Principal moments about the centre of mass: positive and satisfying the triangle inequality.
        I = M.Shift(M.get_com()).CalcRotationalInertia().CopyToFullMatrix3()
        m = np.linalg.eigvalsh(I)
        assert m[0] > 0.0 and m[0] + m[1] >= m[2] - 1e-12, body.name()
        total += M.get_mass()
    # The composite about the torso frame (everything downstream of the world) is valid too.
    bodies = [b for b in plant.GetBodyIndices(model)]
    composite = plant.CalcSpatialInertia(context, torso_frame(plant), bodies)
    assert composite.IsPhysicallyValid()
    assert composite.get_mass() == pytest.approx(total)
    assert 60.0 < total < 80.0


def test_inertia_matches_the_primitive(robot):
    plant, _ = robot
    context = plant.CreateDefaultContext()
    # Upper arm: a solid cylinder r = 0.05 m, l = 0.34 m, m = 1.6 kg, centred 0.17 m below the shoulder.
    M = plant.GetBodyByName("arm_left_3_link").CalcSpatialInertiaInBodyFrame(context)
    expected = SpatialInertia.MakeFromCentralInertia(
        1.6, [0, 0, -0.17], UnitInertia.SolidCylinder(0.05, 0.34, [0, 0, 1]) * 1.6
    )
    np.testing.assert_allclose(M.CopyToFullMatrix6(), expected.CopyToFullMatrix6(), atol=1e-6)
    # Torso: a solid box 0.22 x 0.32 x 0.60 m, 10 kg.
    M = plant.GetBodyByName("torso").CalcSpatialInertiaInBodyFrame(context)
    expected = SpatialInertia.MakeFromCentralInertia(
        10.0, [0, 0, -0.26], UnitInertia.SolidBox(0.22, 0.32, 0.60) * 10.0
    )
    np.testing.assert_allclose(M.CopyToFullMatrix6(), expected.CopyToFullMatrix6(), atol=1e-6)


def test_geometry_has_collision_and_coloured_visuals():
    plant = MultibodyPlant(0.001)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    model = add_dual_arm_robot(plant)
    plant.Finalize()
    inspector = scene_graph.model_inspector()
    n_collision = n_visual = 0
    colours = set()
    for index in plant.GetBodyIndices(model):
        body = plant.get_body(index)
        n_collision += len(plant.GetCollisionGeometriesForBody(body))
        for gid in plant.GetVisualGeometriesForBody(body):
            n_visual += 1
            props = inspector.GetIllustrationProperties(gid)
            colours.add(tuple(props.GetProperty("phong", "diffuse").rgba))
    assert n_collision >= 15
    assert n_visual >= 30
    assert len(colours) >= 4


def test_frames_torso_shoulders_and_segment_lengths(robot):
    plant, model = robot
    context = plant.CreateDefaultContext()
    T = torso_frame(plant)
    assert T.body().name() == "torso"
    # T is 0.95 m + the torso lift above the floor, level.
    X_WT = T.CalcPoseInWorld(context)
    np.testing.assert_allclose(X_WT.translation(), [0, 0, 0.95 + NOMINAL_TORSO_LIFT], atol=1e-12)
    for side, sign in (("left", 1.0), ("right", -1.0)):
        names = arm_joint_names(side)

        def p(name, ctx=context):
            return plant.GetJointByName(name).frame_on_child().CalcPose(ctx, T).translation()

        np.testing.assert_allclose(p(names[0]), [0, sign * 0.20, 0], atol=1e-12)
        assert np.linalg.norm(p(names[3]) - p(names[0])) == pytest.approx(0.34)
        assert np.linalg.norm(p(names[5]) - p(names[3])) == pytest.approx(0.35)
        p_ee = ee_frame(plant, side).CalcPose(context, T).translation()
        assert np.linalg.norm(p_ee - p(names[5])) == pytest.approx(0.195, abs=1e-9)


def test_ee_frames_at_zero_posture(robot):
    plant, _ = robot
    context = plant.CreateDefaultContext()
    for side in SIDES:
        _set_arm(plant, context, side, np.zeros(7))
    T = torso_frame(plant)
    X_right = ee_frame(plant, "right").CalcPose(context, T)
    X_left = ee_frame(plant, "left").CalcPose(context, T)
    # Arms hanging, palms facing the body: y back up the arm, x the palm normal (toward the body).
    np.testing.assert_allclose(X_right.rotation().matrix(), [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-9)
    np.testing.assert_allclose(X_left.rotation().matrix(), [[0, 0, -1], [-1, 0, 0], [0, 1, 0]], atol=1e-9)
    np.testing.assert_allclose(X_right.translation(), [0, -0.2, -0.885], atol=1e-9)
    np.testing.assert_allclose(X_left.translation(), [0, 0.2, -0.885], atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-2.0, 0.9), min_size=7, max_size=7))
def test_arms_are_mirror_images(robot, q):
    """The same joint values give mirror-image end-effector frames: p_L = M p_R, R_L = M R_R diag(1,1,-1)."""
    plant, _ = robot
    context = plant.CreateDefaultContext()
    for side in SIDES:
        _set_arm(plant, context, side, q)
    T = torso_frame(plant)
    X_L = ee_frame(plant, "left").CalcPose(context, T)
    X_R = ee_frame(plant, "right").CalcPose(context, T)
    np.testing.assert_allclose(X_L.translation(), MIRROR @ X_R.translation(), atol=1e-9)
    np.testing.assert_allclose(X_L.rotation().matrix(), MIRROR @ X_R.rotation().matrix() @ FLIP_Z, atol=1e-9)


def test_nominal_posture(robot):
    plant, model = robot
    for side in SIDES:
        lower, upper, _ = arm_joint_limits(side)
        assert np.all(NOMINAL_ARM_Q > lower + 0.1) and np.all(NOMINAL_ARM_Q < upper - 0.1)
        q = plant.GetDefaultPositions()[arm_position_indices(plant, side)]
        np.testing.assert_allclose(q, NOMINAL_ARM_Q)
        X = nominal_ee_pose(side)
        R = X.rotation().matrix()
        sign = 1.0 if side == "left" else -1.0
        # In front of the torso, below the shoulder, on its own side.
        assert 0.4 < X.translation()[0] < 0.7
        assert -0.35 < X.translation()[2] < -0.1
        assert sign * X.translation()[1] > 0.15
        # Gripper pointing forward (y back toward the wrist), palm facing the other hand.
        assert R[:, 1] @ [-1, 0, 0] > 0.95
        assert R[:, 0] @ [0, -sign, 0] > 0.95
        # Elbow bent and wrist away from its singularity (joint 6 not at 0).
        assert NOMINAL_ARM_Q[3] < -1.0 and abs(NOMINAL_ARM_Q[5]) > 0.2


def test_nominal_pose_agrees_with_the_teleop_mapping():
    """The operator's rest posture mapped by core.frames points the gripper the same way as the robot's
    nominal posture (forward, palms facing each other): the mapping and the model share one E convention."""
    for side in SIDES:
        R_map = frames.default_home_pose(side)[:3, :3]
        R_nom = nominal_ee_pose(side).rotation().matrix()
        assert frames.rotation_angle(R_map.T @ R_nom) < 0.25


def test_weld_base_and_weld_joints():
    plant = MultibodyPlant(0.0)
    model = add_dual_arm_robot(plant, weld_base=True, weld_joints=[TORSO_JOINT])
    plant.Finalize()
    for name in (*BASE_JOINTS, TORSO_JOINT):
        assert plant.GetJointByName(name, model).type_name() == "weld"
    assert plant.num_positions() == 20
    assert plant.num_actuators() == 20
    context = plant.CreateDefaultContext()
    np.testing.assert_allclose(
        torso_frame(plant).CalcPoseInWorld(context).translation(),
        [0, 0, 0.95 + NOMINAL_TORSO_LIFT],
        atol=1e-12,
    )


def test_add_robot_rejects_bad_input():
    with pytest.raises(ValueError, match="torso_lift"):
        add_dual_arm_robot(MultibodyPlant(0.0), torso_lift=0.5)
    with pytest.raises(ValueError, match="no joint named 'elbow'"):
        add_dual_arm_robot(MultibodyPlant(0.0), weld_joints=["elbow"])
    finalized = MultibodyPlant(0.0)
    finalized.Finalize()
    with pytest.raises(ValueError, match="not finalized"):
        add_dual_arm_robot(finalized)
    with pytest.raises(ValueError, match="side"):
        arm_joint_names("middle")


def test_two_robots_in_one_plant():
    plant = MultibodyPlant(0.0)
    a = add_dual_arm_robot(plant, weld_base=True)
    b = add_dual_arm_robot(plant, weld_base=True, model_name="robot_b")
    plant.Finalize()
    assert a != b
    assert ee_frame(plant, "left", b).model_instance() == b


def test_scene_loads_with_a_free_object():
    plant = MultibodyPlant(0.001)
    (scene,) = Parser(plant).AddModels(str(model_path(SCENE_MODEL_FILE)))
    plant.Finalize()
    assert plant.num_positions(scene) == 7  # the box is the only free body
    obj = plant.GetBodyByName("object", scene)
    assert obj.is_floating_base_body()
    context = plant.CreateDefaultContext()
    X_WO = plant.EvalBodyPoseInWorld(context, obj)
    # Resting on the table top (z = 0.72) with half its 5 cm side below its centre.
    assert X_WO.translation()[2] == pytest.approx(0.72 + 0.025)
    table = plant.GetBodyByName("table", scene)
    assert plant.EvalBodyPoseInWorld(context, table).IsNearlyEqualTo(RigidTransform([0.75, 0, 0.70]), 1e-12)
    assert obj.default_mass() == pytest.approx(0.1)


def test_tool_point_is_the_ee_origin_in_the_torso_frame_for_any_q(robot):
    plant, _ = robot
    ctx = plant.CreateDefaultContext()
    rng = np.random.default_rng(3)
    for side in SIDES:
        tool = ToolPoint(plant, side)
        lo, hi, _ = arm_joint_limits(side)
        for _ in range(3):
            q = plant.GetPositions(ctx).copy()
            q[arm_position_indices(plant, side)] = rng.uniform(lo, hi)
            plant.SetPositions(ctx, q)
            want = ee_frame(plant, side).CalcPose(ctx, torso_frame(plant)).translation()
            np.testing.assert_allclose(tool(q), want, rtol=0, atol=1e-12)
        # Its own context: the caller's is untouched.
        before = plant.GetPositions(ctx).copy()
        tool(np.zeros(plant.num_positions()))
        np.testing.assert_array_equal(plant.GetPositions(ctx), before)


def test_arm_motion_limits():
    for side in ("left", "right"):
        acc, jerk = arm_motion_limits(side)
        assert acc.shape == jerk.shape == (7,)
        # A collaborative arm's order (7.5-20 rad/s^2), the wrist's above the shoulder's and the elbow's; the
        # jerk reaches the acceleration limit in 2 ms.
        assert np.all((7.5 <= acc) & (acc <= 20.0)) and np.all(acc[4:] > acc[:4].max())
        np.testing.assert_allclose(acc / jerk, 0.002)
        acc[0] = 0.0  # a copy
        assert arm_motion_limits(side)[0][0] > 0.0
    with pytest.raises(ValueError):
        arm_motion_limits("middle")


def test_finite_vectors():
    lo, v = finite_vectors("Owner", 2, lower=[[0, -1]], velocity=(1, 2.5))
    assert lo.dtype == np.float64 and lo.tolist() == [0.0, -1.0] and v.tolist() == [1.0, 2.5]
    with pytest.raises(ValueError, match=r"Owner: velocity must be 2 finite numbers, got shape \(3,\)"):
        finite_vectors("Owner", 2, lower=[0, 1], velocity=[1, 2, 3])
    with pytest.raises(ValueError, match="Owner: lower must be 2 finite numbers"):
        finite_vectors("Owner", 2, lower=[0, np.nan])
