"""The simulated robot station of stage S5: plant + scene graph + scene, the robot position-controlled.

:func:`AddRobotStation` follows RussTedrake/manipulation's ``AddX(builder, ...)`` style: it adds a discrete
MultibodyPlant and SceneGraph holding the dual-arm robot and the teleop scene (floor, table, a small box) to
the caller's builder, wires the controllers and returns a :class:`RobotStation` with the ports to connect.

Control: every robot joint has a PD-controlled actuator (Drake's ``PdControllerGains``, solved implicitly by
the discrete SAP solver, torques clamped to the joint's effort limit) tracking the desired state assembled by
:class:`RobotCommandAssembler`, plus a gravity-compensation feedforward (``InverseDynamics`` in
``kGravityCompensation`` mode on the same plant). Gravity is on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import (
    Context,
    DiagramBuilder,
    InputPort,
    LeafSystem,
    OutputPort,
)
from pydrake.systems.primitives import MatrixGain

from akc_drake.resources import model_path
from akc_drake.robot.model import (
    BASE_JOINTS,
    HEAD_JOINTS,
    SCENE_MODEL_FILE,
    SIDES,
    TORSO_JOINT,
    add_dual_arm_robot,
    arm_joint_names,
    ee_frame,
    gripper_joint_names,
    torso_frame,
)

#: PD gains (p in N m/rad or N/m, d in N m s/rad or N s/m) of each joint group. Arm joints 1-7 in order.
ARM_GAINS: tuple[tuple[float, float], ...] = (
    (1500.0, 80.0),
    (1500.0, 80.0),
    (600.0, 30.0),
    (600.0, 30.0),
    (200.0, 8.0),
    (150.0, 5.0),
    (100.0, 3.0),
)
BASE_GAINS: tuple[tuple[float, float], ...] = ((2.0e4, 4.0e3), (2.0e4, 4.0e3), (5.0e3, 1.0e3))
TORSO_GAINS: tuple[float, float] = (2.0e4, 2.0e3)
HEAD_GAINS: tuple[float, float] = (50.0, 2.0)
#: Fingers: closed on a 5 cm box (each finger 2 cm short of its closed command) they squeeze with the effort limit
#: (20 N); 1000 N/m reaches it at 2 cm.
FINGER_GAINS: tuple[float, float] = (1000.0, 20.0)


def _joint_gains() -> dict[str, tuple[float, float]]:
    gains: dict[str, tuple[float, float]] = {}
    for side in SIDES:
        gains.update(zip(arm_joint_names(side), ARM_GAINS, strict=True))
        for name in gripper_joint_names(side):
            gains[name] = FINGER_GAINS
    gains.update(zip(BASE_JOINTS, BASE_GAINS, strict=True))
    gains[TORSO_JOINT] = TORSO_GAINS
    for name in HEAD_JOINTS:
        gains[name] = HEAD_GAINS
    return gains


class RobotCommandAssembler(LeafSystem):
    """Assembles the plant's desired state ``[q_d, v_d]`` (one entry per PD-controlled actuator) from per-part
    commands. Stateless, direct feedthrough.

    Every input is optional: a part whose input is not connected (or not fixed) holds its default position
    (the plant's default positions) with zero desired velocity.

    .. pydrake_system::

        name: RobotCommandAssembler
        input_ports:
        - left_arm.position
        - left_arm.velocity
        - right_arm.position
        - right_arm.velocity
        - left_gripper.position
        - right_gripper.position
        - torso_lift.position
        - base.position
        output_ports:
        - desired_state

    ``<side>_arm.position`` / ``.velocity``: the arm's joints 1-7 (rad, rad/s); positions are clipped to the
    joint limits. ``<side>_gripper.position``: the opening of each finger (m, 0-0.04), applied to both
    fingers. ``torso_lift.position``: m. ``base.position``: x, y (m), yaw (rad) when the base is not welded.
    A non-finite command raises ``ValueError`` naming the port: the pipeline must never command NaN.
    """

    def __init__(self, plant: MultibodyPlant, robot: ModelInstanceIndex):
        """Args:
        plant: the finalized station plant.
        robot: the robot's model instance in ``plant``.
        """
        super().__init__()
        actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices(robot)]
        self._nu = len(actuators)
        # Actuator slot of each actuated joint, by name.
        slot = {a.joint().name(): k for k, a in enumerate(actuators)}
        default_context = plant.CreateDefaultContext()
        self._q_default = np.array([a.joint().GetOnePosition(default_context) for a in actuators])
        self._lower = np.array([a.joint().position_lower_limits()[0] for a in actuators])
        self._upper = np.array([a.joint().position_upper_limits()[0] for a in actuators])
        self._parts: list[tuple[InputPort, np.ndarray, InputPort | None]] = []
        for side in SIDES:
            idx = np.array([slot[n] for n in arm_joint_names(side)], dtype=np.intp)
            q_port = self.DeclareVectorInputPort(f"{side}_arm.position", 7)
            v_port = self.DeclareVectorInputPort(f"{side}_arm.velocity", 7)
            self._parts.append((q_port, idx, v_port))
        for side in SIDES:
            idx = np.array([slot[n] for n in gripper_joint_names(side)], dtype=np.intp)
            self._parts.append((self.DeclareVectorInputPort(f"{side}_gripper.position", 1), idx, None))
        self._parts.append(
            (self.DeclareVectorInputPort("torso_lift.position", 1), np.array([slot[TORSO_JOINT]]), None)
        )
        base_idx = [slot[n] for n in BASE_JOINTS if n in slot]
        self._base_port = None
        if base_idx:
            self._base_port = self.DeclareVectorInputPort("base.position", len(base_idx))
            self._parts.append((self._base_port, np.array(base_idx, dtype=np.intp), None))
        self.DeclareVectorOutputPort(
            "desired_state", 2 * self._nu, self._calc_desired_state, {self.all_input_ports_ticket()}
        )

    def _calc_desired_state(self, context: Context, output) -> None:
        q_d = self._q_default.copy()
        v_d = np.zeros(self._nu)
        for q_port, idx, v_port in self._parts:
            if q_port.HasValue(context):
                q = q_port.Eval(context)
                if not np.all(np.isfinite(q)):
                    raise ValueError(f"RobotCommandAssembler: input '{q_port.get_name()}' is not finite: {q}")
                # A 1-value gripper command drives both fingers.
                q_d[idx] = q if len(q) == len(idx) else q[0]
            if v_port is not None and v_port.HasValue(context):
                v = v_port.Eval(context)
                if not np.all(np.isfinite(v)):
                    raise ValueError(f"RobotCommandAssembler: input '{v_port.get_name()}' is not finite: {v}")
                v_d[idx] = v
        q_d = np.clip(q_d, self._lower, self._upper)
        output.SetFromVector(np.concatenate([q_d, v_d]))


@dataclass
class RobotStation:
    """What :func:`AddRobotStation` added to the builder, and the ports to wire.

    Attributes:
        plant: the discrete MultibodyPlant (robot + scene), finalized.
        scene_graph: its SceneGraph.
        robot: the robot's model instance.
        scene: the scene's model instance (floor, table, ``object``), None without the scene.
        command: the :class:`RobotCommandAssembler` feeding the PD-controlled actuators.
        arm_position_input: per side, the input port for the arm's desired joint positions (7, rad).
        arm_velocity_input: per side, the optional input port for desired joint velocities (7, rad/s).
        gripper_input: per side, the optional input port for the finger opening (1, m).
        torso_lift_input: the optional input port for the torso lift (1, m).
        arm_position_output: per side, the measured arm joint positions (7, rad).
        arm_velocity_output: per side, the measured arm joint velocities (7, rad/s).
        robot_state_output: the robot's full measured state ``[q, v]``.
        meshcat_visualizer: the MeshcatVisualizer when a Meshcat was given, else None.
    """

    plant: MultibodyPlant
    scene_graph: SceneGraph
    robot: ModelInstanceIndex
    scene: ModelInstanceIndex | None
    command: RobotCommandAssembler
    arm_position_input: dict[str, InputPort] = field(default_factory=dict)
    arm_velocity_input: dict[str, InputPort] = field(default_factory=dict)
    gripper_input: dict[str, InputPort] = field(default_factory=dict)
    torso_lift_input: InputPort | None = None
    arm_position_output: dict[str, OutputPort] = field(default_factory=dict)
    arm_velocity_output: dict[str, OutputPort] = field(default_factory=dict)
    robot_state_output: OutputPort | None = None
    meshcat_visualizer: MeshcatVisualizer | None = None

    def ee_pose(self, plant_context: Context, side: str) -> RigidTransform:
        """Measured ``X_TE`` of ``side``'s end effector in the robot torso frame T.

        Args:
            plant_context: the plant's context (``plant.GetMyContextFromRoot(root_context)``).
            side: ``"left"`` or ``"right"``.
        """
        return ee_frame(self.plant, side, self.robot).CalcPose(
            plant_context, torso_frame(self.plant, self.robot)
        )


def _selector(rows: np.ndarray, n: int) -> np.ndarray:
    S = np.zeros((len(rows), n))
    S[np.arange(len(rows)), rows] = 1.0
    return S


def AddRobotStation(
    builder: DiagramBuilder,
    time_step: float = 0.002,
    meshcat: Meshcat | None = None,
    *,
    weld_base: bool = False,
    add_scene: bool = True,
) -> RobotStation:
    """Add the position-controlled dual-arm robot and its scene to ``builder``.

    Args:
        builder: the diagram builder to add to.
        time_step: the plant's discrete time step, seconds (> 0: PD-controlled actuators need a discrete
            plant).
        meshcat: if given, a MeshcatVisualizer (illustration geometry) is added.
        weld_base: weld the base to the world instead of holding it with its position-controlled x, y, yaw
            joints.
        add_scene: add ``models/teleop_scene.sdf`` (floor, table, a small box).

    Returns:
        The :class:`RobotStation` (plant, scene graph, model instances and the ports to connect).
    """
    if not (isinstance(time_step, (int, float)) and math.isfinite(time_step) and time_step > 0.0):
        raise ValueError(
            f"AddRobotStation: time_step must be a positive number of seconds, got {time_step!r}"
        )
    config = MultibodyPlantConfig(time_step=float(time_step), discrete_contact_approximation="lagged")
    plant, scene_graph = AddMultibodyPlant(config, builder)
    plant.set_name("robot_station_plant")
    robot = add_dual_arm_robot(plant, weld_base=weld_base)
    scene = None
    if add_scene:
        (scene,) = Parser(plant).AddModels(str(model_path(SCENE_MODEL_FILE)))
    gains = _joint_gains()
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        if actuator.model_instance() == robot:
            p, d = gains[actuator.joint().name()]
            actuator.set_controller_gains(PdControllerGains(p=p, d=d))
    plant.Finalize()

    command = builder.AddSystem(RobotCommandAssembler(plant, robot))
    command.set_name("robot_command")
    builder.Connect(command.get_output_port(), plant.get_desired_state_input_port(robot))

    # Gravity compensation: u = B^T (-tau_g(q)); the actuators are 1-DoF with unit gear ratio, so B^T B = I.
    gravity = builder.AddSystem(
        InverseDynamics(plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation)
    )
    gravity.set_name("gravity_compensation")
    builder.Connect(plant.get_state_output_port(), gravity.get_input_port_estimated_state())
    B = plant.MakeActuationMatrix()
    robot_u = [plant.get_joint_actuator(i).input_start() for i in plant.GetJointActuatorIndices(robot)]
    to_u = builder.AddSystem(MatrixGain(B[:, robot_u].T))
    to_u.set_name("gravity_to_actuation")
    builder.Connect(gravity.get_output_port_generalized_force(), to_u.get_input_port())
    builder.Connect(to_u.get_output_port(), plant.get_actuation_input_port(robot))

    # Measured arm positions/velocities, selected from the robot instance's state [q_r, v_r].
    nq_r, nv_r = plant.num_positions(robot), plant.num_velocities(robot)
    q_global = plant.GetPositionsFromArray(robot, np.arange(plant.num_positions(), dtype=float)).astype(int)
    v_global = plant.GetVelocitiesFromArray(robot, np.arange(plant.num_velocities(), dtype=float)).astype(int)
    station = RobotStation(plant=plant, scene_graph=scene_graph, robot=robot, scene=scene, command=command)
    for side in SIDES:
        joints = [plant.GetJointByName(n, robot) for n in arm_joint_names(side)]
        q_rows = np.array([int(np.flatnonzero(q_global == j.position_start())[0]) for j in joints])
        v_rows = np.array([nq_r + int(np.flatnonzero(v_global == j.velocity_start())[0]) for j in joints])
        for rows, outputs, label in (
            (q_rows, station.arm_position_output, "position"),
            (v_rows, station.arm_velocity_output, "velocity"),
        ):
            sel = builder.AddSystem(MatrixGain(_selector(rows, nq_r + nv_r)))
            sel.set_name(f"{side}_arm_{label}_measured")
            builder.Connect(plant.get_state_output_port(robot), sel.get_input_port())
            outputs[side] = sel.get_output_port()
        station.arm_position_input[side] = command.GetInputPort(f"{side}_arm.position")
        station.arm_velocity_input[side] = command.GetInputPort(f"{side}_arm.velocity")
        station.gripper_input[side] = command.GetInputPort(f"{side}_gripper.position")
    station.torso_lift_input = command.GetInputPort("torso_lift.position")
    station.robot_state_output = plant.get_state_output_port(robot)
    if meshcat is not None:
        station.meshcat_visualizer = MeshcatVisualizer.AddToBuilder(
            builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration)
        )
    return station
