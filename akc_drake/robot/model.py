"""The dual-arm mobile manipulator (after the PAL Robotics TIAGo Pro): loading it and naming its parts.

The model is ``models/dual_arm_manipulator.urdf``, built from primitives (no meshes, no ``package://``
URIs). Conventions (also written at the top of the URDF):

* ``torso`` is the body whose frame is the robot torso frame T: x forward, y left, z up, origin at the
  shoulder midpoint; the shoulders sit at y = +/-0.20 m. The torso rides on ``torso_lift_joint`` (0-0.35 m)
  on a holonomic base (``base_x_joint``, ``base_y_joint`` prismatic, ``base_yaw_joint`` revolute, relative to
  the world).
* Each arm has joints ``arm_<side>_1_joint`` ... ``arm_<side>_7_joint`` (shoulder 1-2-3, elbow 4, wrist
  5-6-7), shoulder-elbow 0.34 m, elbow-wrist 0.35 m, wrist centre to tool point 0.195 m. The right arm is the
  mirror image of the left, so one joint vector (e.g. :data:`NOMINAL_ARM_Q`) gives mirror-image postures.
* End-effector frames ``left_ee`` / ``right_ee``: at the tool point between the finger pads, y pointing from
  the tool back toward the wrist, x the palm normal, z = x cross y; the two frames are mirror images (the
  teleop mapping of :mod:`akc_drake.core.frames` produces poses of exactly these frames relative to T).
* Every moving joint has an actuator (base, torso, head, arms, the four fingers); self-collisions are
  filtered.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex, WeldJoint

from akc_drake.resources import model_path

#: The robot model file in ``models/``.
ROBOT_MODEL_FILE = "dual_arm_manipulator.urdf"
#: The scene (floor, table, a small box) in ``models/``.
SCENE_MODEL_FILE = "teleop_scene.sdf"

SIDES = ("left", "right")
#: Number of joints per arm.
NUM_ARM_JOINTS = 7
#: Names of the base joints (x, y prismatic; yaw revolute).
BASE_JOINTS = ("base_x_joint", "base_y_joint", "base_yaw_joint")
TORSO_JOINT = "torso_lift_joint"
HEAD_JOINTS = ("head_1_joint", "head_2_joint")
#: Name of the torso body (its body frame is the torso frame T).
TORSO_BODY = "torso"

#: A comfortable arm posture (radians, joints 1-7, the same values on both arms as they are mirror images):
#: upper arm slightly forward and out, elbow bent 100 deg, forearm and gripper pointing forward, palms facing
#: each other; the wrist is pitched 0.25 rad so that joints 5 and 7 are not aligned (no wrist singularity).
#: The tool points are then at about (0.58, +/-0.23, -0.21) m in T.
NOMINAL_ARM_Q: np.ndarray = np.array([0.15, -0.10, 0.0, -1.75, 0.0, 0.25, 0.0])
NOMINAL_ARM_Q.flags.writeable = False
#: Default torso lift (metres): T is then 1.10 m above the floor.
NOMINAL_TORSO_LIFT = 0.15
#: Default opening of each finger (metres, 0 = closed, 0.04 = fully open).
NOMINAL_FINGER_OPENING = 0.02


def check_side(side: str) -> str:
    """``side`` if it is ``"left"`` or ``"right"``; else ValueError."""
    if side not in SIDES:
        raise ValueError(f"side must be 'left' or 'right', got {side!r}")
    return side


def arm_joint_names(side: str) -> list[str]:
    """Names of the 7 joints of one arm, proximal to distal.

    Args:
        side: ``"left"`` or ``"right"``.

    Returns:
        ``["arm_<side>_1_joint", ..., "arm_<side>_7_joint"]``.
    """
    check_side(side)
    return [f"arm_{side}_{i}_joint" for i in range(1, NUM_ARM_JOINTS + 1)]


def gripper_joint_names(side: str) -> list[str]:
    """Names of the two finger joints of one gripper (0 = closed, positive opens)."""
    check_side(side)
    return [f"gripper_{side}_left_finger_joint", f"gripper_{side}_right_finger_joint"]


def ee_frame_name(side: str) -> str:
    """Name of the end-effector frame of ``side`` (``"left_ee"`` or ``"right_ee"``)."""
    return f"{check_side(side)}_ee"


# Published TIAGo Pro arm limits (degrees) and the velocity limits of the brief (rad/s), joints 1-7.
_ARM_LOWER_DEG = np.array([-148.97, -139.8, -148.97, -139.8, -148.97, -114.59, -139.8])
_ARM_UPPER_DEG = np.array([148.97, 63.03, 148.97, 63.03, 148.97, 114.59, 139.8])
_ARM_VEL = np.array([1.95, 1.95, 3.95, 3.95, 3.95, 3.95, 3.95])


def arm_joint_limits(side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position and velocity limits of one arm's joints 1-7 (the values written in the model file).

    Args:
        side: ``"left"`` or ``"right"`` (both arms have the same limits: they are mirror images).

    Returns:
        ``(lower, upper, velocity)``: radians, radians, rad/s, each of shape ``(7,)``.
    """
    check_side(side)
    return np.deg2rad(_ARM_LOWER_DEG), np.deg2rad(_ARM_UPPER_DEG), _ARM_VEL.copy()


# Acceleration (rad/s^2) and jerk (rad/s^3) limits, joints 1-7. PAL publishes none for the TIAGo Pro; these are of
# the order a collaborative 7-DoF arm's controller accepts (Franka Emika's published limits: 7.5-20 rad/s^2 and
# 3750-10000 rad/s^3), the shoulder and elbow (1-4) below the wrist (5-7).
_ARM_ACCEL = np.array([15.0, 15.0, 15.0, 15.0, 20.0, 20.0, 20.0])
_ARM_JERK = 500.0 * _ARM_ACCEL


def finite_vectors(owner: str, n: int, **arrays) -> list[np.ndarray]:
    """Each of ``arrays`` (joint limits, bounds) as a flat float array, in order; ValueError naming ``owner`` and
    the argument unless it holds ``n`` finite numbers."""
    out = []
    for name, a in arrays.items():
        a = np.array(a, dtype=float).reshape(-1)
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise ValueError(f"{owner}: {name} must be {n} finite numbers, got shape {a.shape}")
        out.append(a)
    return out


def arm_motion_limits(side: str) -> tuple[np.ndarray, np.ndarray]:
    """Acceleration and jerk limits of one arm's joints 1-7, for the command
    (:class:`~akc_drake.robot.joint_motion_limiter.JointMotionLimiter`).

    Not in the model file (URDF has no field for them) and not published for the TIAGo Pro: values of the order
    a collaborative 7-DoF arm's controller accepts, the wrist's (5-7) above the shoulder's and the elbow's.

    Returns:
        ``(acceleration, jerk)``: rad/s^2 and rad/s^3, each of shape ``(7,)``.
    """
    check_side(side)
    return _ARM_ACCEL.copy(), _ARM_JERK.copy()


def _weld_joint_in_place(plant: MultibodyPlant, joint_name: str, model: ModelInstanceIndex) -> None:
    """Replace a 1-DoF joint (and its actuator) by a weld at the joint's default position."""
    joint = plant.GetJointByName(joint_name, model)
    q0 = joint.default_positions()
    # (Before Finalize() only the plant-wide list of actuators is available.)
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        if actuator.model_instance() == model and actuator.joint().index() == joint.index():
            plant.RemoveJointActuator(actuator)
    frame_P, frame_C = joint.frame_on_parent(), joint.frame_on_child()
    if joint.type_name() == "prismatic":
        X_PC = RigidTransform(np.asarray(joint.translation_axis()) * float(q0[0]))
    elif joint.type_name() == "revolute":
        X_PC = RigidTransform(
            RotationMatrix(AngleAxis(float(q0[0]), np.asarray(joint.revolute_axis()))), np.zeros(3)
        )
    else:
        raise ValueError(f"cannot weld joint {joint_name!r} of type {joint.type_name()!r}")
    plant.RemoveJoint(joint)
    # The weld keeps the joint's name, so the model's joint names stay the same whatever is welded.
    plant.AddJoint(WeldJoint(joint_name, frame_P, frame_C, X_PC))


def add_dual_arm_robot(
    plant: MultibodyPlant,
    *,
    weld_base: bool = False,
    weld_joints: tuple[str, ...] | list[str] = (),
    torso_lift: float = NOMINAL_TORSO_LIFT,
    model_name: str | None = None,
) -> ModelInstanceIndex:
    """Parse the robot into ``plant`` (not finalized) and set its default posture.

    The default positions are :data:`NOMINAL_ARM_Q` on both arms, ``torso_lift`` on the torso,
    :data:`NOMINAL_FINGER_OPENING` on every finger and zero on the base and the head.

    Args:
        plant: a MultibodyPlant that is not finalized yet.
        weld_base: weld the base to the world at the origin (the three base joints and their actuators are
            replaced by welds) instead of leaving it on its planar x, y, yaw joints.
        weld_joints: names of further 1-DoF joints to replace by welds at their default positions (used to
            build the arm-only plants of differential IK).
        torso_lift: default torso lift in metres, within [0, 0.35].
        model_name: a model instance name (default: the model's own, ``dual_arm_manipulator``); needed to add
            two robots to one plant.

    Returns:
        The robot's model instance.
    """
    if plant.is_finalized():
        raise ValueError("add_dual_arm_robot needs a plant that is not finalized yet")
    torso_lift = float(torso_lift)
    if not (0.0 <= torso_lift <= 0.35):
        raise ValueError(f"torso_lift must be within [0, 0.35] m, got {torso_lift!r}")
    parser = Parser(plant, model_name) if model_name else Parser(plant)
    (model,) = parser.AddModels(str(model_path(ROBOT_MODEL_FILE)))
    for side in SIDES:
        for name, q in zip(arm_joint_names(side), NOMINAL_ARM_Q, strict=True):
            plant.GetJointByName(name, model).set_default_angle(float(q))
        for name in gripper_joint_names(side):
            plant.GetJointByName(name, model).set_default_translation(NOMINAL_FINGER_OPENING)
    plant.GetJointByName(TORSO_JOINT, model).set_default_translation(torso_lift)
    to_weld = list(BASE_JOINTS) if weld_base else []
    to_weld += [j for j in weld_joints if j not in to_weld]
    for name in to_weld:
        if not plant.HasJointNamed(name, model):
            raise ValueError(f"weld_joints: the robot has no joint named {name!r}")
        _weld_joint_in_place(plant, name, model)
    return model


def ee_frame(plant: MultibodyPlant, side: str, model: ModelInstanceIndex | None = None) -> Frame:
    """The end-effector frame ``<side>_ee`` of the robot in ``plant``."""
    name = ee_frame_name(side)
    return plant.GetFrameByName(name) if model is None else plant.GetFrameByName(name, model)


def torso_frame(plant: MultibodyPlant, model: ModelInstanceIndex | None = None) -> Frame:
    """The torso frame T (the body frame of ``torso``) of the robot in ``plant``."""
    body = plant.GetBodyByName(TORSO_BODY) if model is None else plant.GetBodyByName(TORSO_BODY, model)
    return body.body_frame()


class ToolPoint:
    """The end effector's origin in the torso frame T as a function of the plant's positions ``q``.

    Holds a context of its own, so a system may evaluate it for any ``q`` (its input, its state) without touching
    the diagram's. ``frame_E`` and ``frame_T`` are the two frames.
    """

    def __init__(self, plant: MultibodyPlant, side: str):
        self._plant, self._ctx = plant, plant.CreateDefaultContext()
        self.frame_E, self.frame_T = ee_frame(plant, side), torso_frame(plant)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        self._plant.SetPositions(self._ctx, q)
        return self.frame_E.CalcPose(self._ctx, self.frame_T).translation()


def arm_position_indices(
    plant: MultibodyPlant, side: str, model: ModelInstanceIndex | None = None
) -> np.ndarray:
    """Indices of one arm's 7 joint positions in the plant's full position vector ``q``."""
    joints = [
        plant.GetJointByName(n) if model is None else plant.GetJointByName(n, model)
        for n in arm_joint_names(side)
    ]
    return np.array([j.position_start() for j in joints], dtype=np.intp)


def nominal_ee_pose(side: str) -> RigidTransform:
    """``X_TE`` of ``side``'s end effector at :data:`NOMINAL_ARM_Q` (the robot's home pose for teleop)."""
    plant = MultibodyPlant(0.0)
    add_dual_arm_robot(plant, weld_base=True)
    plant.Finalize()
    context = plant.CreateDefaultContext()
    return ee_frame(plant, side).CalcPose(context, torso_frame(plant))
