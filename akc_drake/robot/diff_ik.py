"""Differential inverse kinematics per arm (stage S5's last step: end-effector pose -> joint commands).

Each arm gets Drake's ``DifferentialInverseKinematicsIntegrator`` on a separate, kinematics-only plant of
the robot in which everything except the arm's 7 joints is welded (:func:`make_arm_ik_plant`). The IK's
frame A is the torso frame T, its frame E the arm's ``<side>_ee`` frame, so its input is exactly the teleop
target ``X_TE_desired``. The QP respects the joint position limits (with a small margin), the joint velocity
limits (scaled by 0.98), an end-effector translational and angular speed limit, and pulls the redundant DoF
(the elbow swivel) toward :data:`~akc_drake.robot.model.NOMINAL_ARM_Q` with a joint-centering gain. Drake's
QP scales the commanded spatial velocity down rather than exceed a limit, so a target is approached along the
straight line in SE(3) for as long as the limits allow.

Two guards make the command safe whatever arrives:

* :class:`~akc_drake.robot.pose_target_guard.PoseTargetGuard` (before the integrator): a target that is not
  a finite proper rigid transform is replaced by the current commanded pose (the arm holds still); a target
  out of reach is moved onto the reachable shell around the shoulder (the closest point the arm can get to).
* :class:`~akc_drake.robot.joint_command_guard.JointCommandGuard` (after the integrator): a non-finite command
  is replaced by the last command (and counted); every command is clipped to the joint position limits and to
  ``velocity limit * IK period`` from the previous command. The robot is therefore never commanded with NaN nor
  faster than its limits.
  The integrator linearises around this guarded command, so it always starts from a feasible point.

Then, outside the IK's loop, :class:`~akc_drake.robot.joint_motion_limiter.JointMotionLimiter` turns the guard's
command (a staircase: each camera frame's pose reached at the velocity limits, then held) into one within the
joints' acceleration and jerk limits too (:func:`~akc_drake.robot.model.arm_motion_limits`), which a real arm's
controller accepts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import (
    DifferentialInverseKinematicsIntegrator,
    DifferentialInverseKinematicsParameters,
    DifferentialInverseKinematicsStatus,
)
from pydrake.multibody.plant import MultibodyPlant
from pydrake.solvers import OsqpSolver
from pydrake.systems.framework import Context, DiagramBuilder, InputPort, OutputPort
from pydrake.systems.primitives import AffineSystem, ConstantValueSource, ConstantVectorSource

from akc_drake.robot.ik_fallback_selector import IKFallbackSelector
from akc_drake.robot.joint_command_guard import JointCommandGuard
from akc_drake.robot.joint_motion_limiter import JointMotionLimiter
from akc_drake.robot.joint_space_approach import JointSpaceApproach
from akc_drake.robot.model import (
    HEAD_JOINTS,
    NOMINAL_ARM_Q,
    NUM_ARM_JOINTS,
    SIDES,
    TORSO_JOINT,
    add_dual_arm_robot,
    arm_joint_limits,
    arm_joint_names,
    arm_motion_limits,
    arm_position_indices,
    check_side,
    ee_frame,
    gripper_joint_names,
    torso_frame,
)
from akc_drake.robot.pose_target_guard import PoseTargetGuard

#: Default IK rate: 100 Hz.
DEFAULT_IK_TIME_STEP = 0.01
#: Default joint-centering gain (1/s) pulling the redundant DoF toward the nominal posture.
DEFAULT_CENTERING_GAIN = 1.0
#: Default end-effector translational speed limit per axis (m/s) and angular speed limit (rad/s).
DEFAULT_EE_SPEED_LIMIT = 1.0
DEFAULT_EE_ANGULAR_SPEED_LIMIT = 3.0
#: The IK plans with the joint velocity limits times this factor (the QP solver's tolerance stays inside).
DEFAULT_VELOCITY_LIMIT_SCALE = 0.98
#: The IK keeps this far (rad) inside the joint position limits.
DEFAULT_POSITION_LIMIT_MARGIN = 0.02
#: OSQP iteration cap for the IK's QP.
OSQP_MAX_ITER = 20000
#: The IK keeps the elbow (joint 4) at or below this angle (rad; negative bends it): one elbow branch, away
#: from the straight-arm singularity at 0 and the hyperextension the joint's limit (+1.10 rad) would allow, from
#: which the QP cannot move straight toward a target beside the robot (it reports "stuck").
DEFAULT_ELBOW_MAX = -0.15
#: Targets are kept within this shell around the shoulder centre (metres); the straight arm reaches 0.885 m.
DEFAULT_WORKSPACE_RADII = (0.15, 0.85)


def make_arm_ik_plant(side: str | None = None) -> MultibodyPlant:
    """A finalized, continuous-time plant of the robot for differential IK.

    Args:
        side: ``"left"`` or ``"right"``: only that arm's 7 joints move; ``None``: both arms' 14 joints move.
            Everything else (base, torso lift, head, the other arm, the fingers) is welded at its default
            position; none of those joints changes ``X_TE``.

    Returns:
        The plant; its positions are the free arm joints' angles.
    """
    free_sides = SIDES if side is None else (check_side(side),)
    to_weld = [TORSO_JOINT, *HEAD_JOINTS]
    for s in SIDES:
        to_weld += gripper_joint_names(s)
        if s not in free_sides:
            to_weld += arm_joint_names(s)
    plant = MultibodyPlant(0.0)
    plant.set_name(f"ik_plant_{side or 'both'}")
    add_dual_arm_robot(plant, weld_base=True, weld_joints=to_weld)
    plant.Finalize()
    return plant


def _static_affine(D: np.ndarray, y0: np.ndarray) -> AffineSystem:
    """A stateless affine map ``y = D u + y0``."""
    m, n = D.shape
    return AffineSystem(
        A=np.zeros((0, 0)),
        B=np.zeros((0, n)),
        f0=np.zeros(0),
        C=np.zeros((m, 0)),
        D=D,
        y0=np.asarray(y0, float),
    )


def arm_ik_parameters(
    plant: MultibodyPlant,
    side: str,
    time_step: float,
    *,
    centering_gain: float = DEFAULT_CENTERING_GAIN,
    ee_speed_limit: float = DEFAULT_EE_SPEED_LIMIT,
    ee_angular_speed_limit: float = DEFAULT_EE_ANGULAR_SPEED_LIMIT,
    velocity_limit_scale: float = DEFAULT_VELOCITY_LIMIT_SCALE,
    position_limit_margin: float = DEFAULT_POSITION_LIMIT_MARGIN,
    elbow_max: float = DEFAULT_ELBOW_MAX,
) -> DifferentialInverseKinematicsParameters:
    """Differential-IK parameters for one arm on an IK plant from :func:`make_arm_ik_plant`.

    The arm's joints get its position limits (``margin`` inside), velocity limits (times
    ``velocity_limit_scale``) and a centering gain toward the plant's default (nominal) posture; any other
    free joint of the plant (the other arm) is frozen (zero velocity limits, no centering).

    Args:
        plant: the IK plant.
        side: ``"left"`` or ``"right"``.
        time_step: the IK period, seconds.
        centering_gain: joint-centering gain K (1/s) of the arm's joints.
        ee_speed_limit: end-effector translational speed limit per axis (m/s).
        ee_angular_speed_limit: end-effector angular speed limit (rad/s).
        velocity_limit_scale: factor (0, 1] applied to the joint velocity limits.
        position_limit_margin: distance (rad) kept from the joint position limits.
        elbow_max: upper bound (rad) of the elbow joint (joint 4) for the IK (:data:`DEFAULT_ELBOW_MAX`).

    Returns:
        The parameters.
    """
    for name, v in (
        ("time_step", time_step),
        ("ee_speed_limit", ee_speed_limit),
        ("ee_angular_speed_limit", ee_angular_speed_limit),
        ("velocity_limit_scale", velocity_limit_scale),
    ):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
            raise ValueError(f"arm_ik_parameters: {name} must be a positive number, got {v!r}")
    if velocity_limit_scale > 1.0:
        raise ValueError(f"arm_ik_parameters: velocity_limit_scale must be <= 1, got {velocity_limit_scale!r}")
    if not (isinstance(centering_gain, (int, float)) and math.isfinite(centering_gain) and centering_gain >= 0):
        raise ValueError(f"arm_ik_parameters: centering_gain must be >= 0, got {centering_gain!r}")
    nq, nv = plant.num_positions(), plant.num_velocities()
    if nq != nv:
        raise ValueError(f"arm_ik_parameters: the IK plant must have nq == nv, got {nq} and {nv}")
    idx = arm_position_indices(plant, check_side(side))
    q0 = plant.GetDefaultPositions()
    lower, upper, vel = arm_joint_limits(side)
    q_lo, q_hi = q0 - 1.0, q0 + 1.0
    q_lo[idx], q_hi[idx] = lower + position_limit_margin, upper - position_limit_margin
    q_hi[idx[3]] = min(q_hi[idx[3]], float(elbow_max))
    v_lim = np.zeros(nv)
    v_lim[idx] = vel * velocity_limit_scale
    K = np.zeros((nq, nq))
    K[idx, idx] = centering_gain

    params = DifferentialInverseKinematicsParameters(nq, nv)
    params.set_time_step(time_step)
    params.set_nominal_joint_position(q0)
    params.set_joint_centering_gain(K)
    params.set_joint_position_limits((q_lo, q_hi))
    params.set_joint_velocity_limits((-v_lim, v_lim))
    params.set_end_effector_translational_velocity_limits(np.full(3, -ee_speed_limit), np.full(3, ee_speed_limit))
    params.set_end_effector_angular_speed_limit(ee_angular_speed_limit)
    # OSQP's default iteration cap is too low for the QPs near joint limits (it then reports no solution).
    params.get_mutable_solver_options().SetOption(OsqpSolver.id(), "max_iter", OSQP_MAX_ITER)
    return params


@dataclass
class ArmDifferentialIK:
    """What :func:`AddArmDifferentialIK` added for one arm, and its ports.

    Attributes:
        side: ``"left"`` or ``"right"``.
        time_step: the IK period, seconds.
        plant: the IK plant.
        integrator: Drake's DifferentialInverseKinematicsIntegrator (the full pose).
        fallback: the position-only integrator used when the full-pose one is stuck
            (:class:`IKFallbackSelector`); None without it.
        approach: the :class:`JointSpaceApproach` that moves the joints to a solved pose while the IK is stuck
            far from its target; None without it.
        pose_guard: the :class:`PoseTargetGuard` in front of it.
        command_guard: the :class:`JointCommandGuard` after it.
        X_TE_desired_input: the input port for the desired end-effector pose (AbstractValue RigidTransform,
            in the torso frame T).
        q_commanded_output: the output port of the arm's 7 joint position commands (rad).
        v_commanded_output: the command's velocity (rad/s), a feedforward for the station's
            ``arm_velocity_input``.
        limiter: the :class:`JointMotionLimiter` the command goes through (None without it: the command is the
            guard's, ``v_commanded_output`` its step's velocity).
    """

    side: str
    time_step: float
    plant: MultibodyPlant
    integrator: DifferentialInverseKinematicsIntegrator
    pose_guard: PoseTargetGuard
    command_guard: JointCommandGuard
    X_TE_desired_input: InputPort
    q_commanded_output: OutputPort
    v_commanded_output: OutputPort
    fallback: DifferentialInverseKinematicsIntegrator | None = None
    approach: JointSpaceApproach | None = None
    limiter: JointMotionLimiter | None = None

    def status(self, root_context: Context) -> DifferentialInverseKinematicsStatus:
        """The full-pose integrator's most recent status (solution found, no solution, stuck)."""
        ctx = self.integrator.GetMyContextFromRoot(root_context)
        return DifferentialInverseKinematicsStatus(int(ctx.get_discrete_state(1).get_value()[0]))

    def fallback_status(self, root_context: Context) -> DifferentialInverseKinematicsStatus | None:
        """The position-only integrator's most recent status (None without a fallback)."""
        if self.fallback is None:
            return None
        ctx = self.fallback.GetMyContextFromRoot(root_context)
        return DifferentialInverseKinematicsStatus(int(ctx.get_discrete_state(1).get_value()[0]))

    def approaching(self, root_context: Context) -> bool:
        """Whether the command is the joint-space move to a solved pose (False without the approach)."""
        return self.approach is not None and self.approach.approaching(self.approach.GetMyContextFromRoot(root_context))

    def held_count(self, root_context: Context) -> int:
        """How many IK periods the command guard held the command because the IK output was not finite."""
        return self.command_guard.held_count(self.command_guard.GetMyContextFromRoot(root_context))

    def commanded_pose(self, root_context: Context) -> RigidTransform:
        """``X_TE`` of the integrator's current joint positions (the pose the IK is commanding)."""
        return self.integrator.ForwardKinematics(self.integrator.GetMyContextFromRoot(root_context))


def AddArmDifferentialIK(
    builder: DiagramBuilder,
    plant_for_ik: MultibodyPlant,
    side: str,
    time_step: float = DEFAULT_IK_TIME_STEP,
    *,
    measured_q_port: OutputPort | None = None,
    initial_q: np.ndarray | None = None,
    parameters: DifferentialInverseKinematicsParameters | None = None,
    workspace_radii: tuple[float, float] = DEFAULT_WORKSPACE_RADII,
    position_fallback: bool = True,
    joint_space_approach: bool = True,
    motion_limits: bool | tuple = True,
    **parameter_kwargs,
) -> ArmDifferentialIK:
    """Add differential IK for one arm: target guard -> Drake's integrator -> command guard -> motion limiter.

    The integrator linearises around the guarded command (its ``robot_state`` input is the command guard's
    output and ``use_robot_state`` is true), so each step starts from a command that is inside the joint
    limits and finite: the QP stays feasible and a non-finite step is recovered from on the next one. Nothing
    measured is fed back: the IK is open loop with respect to the robot. The command starts from
    ``measured_q_port`` (e.g. the station's measured arm positions) when given, else from ``initial_q``
    (default :data:`~akc_drake.robot.model.NOMINAL_ARM_Q`).

    Args:
        builder: the diagram builder.
        plant_for_ik: an IK plant from :func:`make_arm_ik_plant` (``side``'s or both arms); it must outlive
            the diagram.
        side: ``"left"`` or ``"right"``.
        time_step: the IK period, seconds (default 0.01 s, 100 Hz).
        measured_q_port: an output port with the arm's 7 measured joint positions, read at initialisation.
        initial_q: the arm's 7 initial joint positions when ``measured_q_port`` is not given.
        parameters: differential-IK parameters (default :func:`arm_ik_parameters` with ``parameter_kwargs``).
        workspace_radii: ``(r_min, r_max)`` of the reachable shell around the shoulder, metres; targets
            outside are moved onto it (see :class:`PoseTargetGuard`).
        position_fallback: add the position-only integrator used when the full-pose IK is stuck
            (:class:`IKFallbackSelector`).
        joint_space_approach: add the :class:`JointSpaceApproach`: when both are stuck far from the target, the
            pose is solved by (global) inverse kinematics and the joints move straight to it.
        motion_limits: the command goes through a :class:`JointMotionLimiter` (outside the IK's loop: the IK
            linearises around the guard's command): True with :func:`~akc_drake.robot.model.arm_motion_limits`,
            ``(acceleration, jerk)`` (rad/s^2, rad/s^3, 7 each) with those, False without (the guard's command
            goes to the robot: it reaches each camera frame's pose at the velocity limits, then stops).
        **parameter_kwargs: passed to :func:`arm_ik_parameters`.

    Returns:
        The :class:`ArmDifferentialIK`: input ``X_TE_desired_input``, output ``q_commanded_output``.
    """
    check_side(side)
    if not (isinstance(time_step, (int, float)) and math.isfinite(time_step) and time_step > 0.0):
        raise ValueError(f"AddArmDifferentialIK: time_step must be a positive number of seconds, got {time_step!r}")
    if parameters is None:
        parameters = arm_ik_parameters(plant_for_ik, side, time_step, **parameter_kwargs)
    elif parameter_kwargs:
        raise ValueError("AddArmDifferentialIK: give either parameters or parameter keyword arguments")
    nq = plant_for_ik.num_positions()
    idx = arm_position_indices(plant_for_ik, side)
    # The IK's position bounds of every plant position (the joint-space move's), and of the arm's (the guard's).
    q_lo_all, q_hi_all = (np.asarray(b, dtype=float) for b in parameters.get_joint_position_limits())
    q_lo, q_hi = q_lo_all[idx], q_hi_all[idx]

    integrator = builder.AddSystem(
        DifferentialInverseKinematicsIntegrator(
            plant_for_ik, torso_frame(plant_for_ik), ee_frame(plant_for_ik, side), time_step, parameters
        )
    )
    integrator.set_name(f"{side}_arm_diff_ik")
    pose_guard = builder.AddSystem(PoseTargetGuard(plant_for_ik, side, *workspace_radii))
    pose_guard.set_name(f"{side}_arm_target_guard")
    # The command stays within the IK's own position limits (inside the joint limits by the margin) and the
    # joint velocity limits.
    _, _, vel = arm_joint_limits(side)
    command_guard = builder.AddSystem(JointCommandGuard(q_lo, q_hi, vel, time_step))
    command_guard.set_name(f"{side}_arm_command_guard")

    # The IK plant's positions -> the arm's 7 (selection), and the arm's 7 -> the IK plant's state [q, v]
    # (the other joints at their defaults, v = 0).
    S = np.zeros((NUM_ARM_JOINTS, nq))
    S[np.arange(NUM_ARM_JOINTS), idx] = 1.0
    select = builder.AddSystem(_static_affine(S, np.zeros(NUM_ARM_JOINTS)))
    select.set_name(f"{side}_arm_ik_select")
    x0 = np.concatenate([plant_for_ik.GetDefaultPositions(), np.zeros(plant_for_ik.num_velocities())])
    x0[idx] = 0.0
    D = np.zeros((len(x0), NUM_ARM_JOINTS))
    D[idx, np.arange(NUM_ARM_JOINTS)] = 1.0
    expand = builder.AddSystem(_static_affine(D, x0))
    expand.set_name(f"{side}_arm_ik_state")
    if measured_q_port is None:
        q_init = np.array(NOMINAL_ARM_Q if initial_q is None else initial_q, dtype=float)
        if q_init.shape != (NUM_ARM_JOINTS,) or not np.all(np.isfinite(q_init)):
            raise ValueError(f"AddArmDifferentialIK: initial_q must be 7 finite joint angles, got {initial_q!r}")
        source = builder.AddSystem(ConstantVectorSource(q_init))
        source.set_name(f"{side}_arm_ik_initial_q")
        measured_q_port = source.get_output_port()
    elif initial_q is not None:
        raise ValueError("AddArmDifferentialIK: give either measured_q_port or initial_q, not both")
    use_state = builder.AddSystem(ConstantValueSource(AbstractValue.Make(True)))
    use_state.set_name(f"{side}_arm_ik_use_command")

    builder.Connect(measured_q_port, command_guard.GetInputPort("q_initial"))
    fallback = None
    if position_fallback:
        fb_params = arm_ik_parameters(plant_for_ik, side, time_step, **parameter_kwargs)
        # Only the translational rows of the end-effector velocity (frame E: wx wy wz vx vy vz).
        fb_params.set_end_effector_velocity_flag([False, False, False, True, True, True])
        fallback = builder.AddSystem(
            DifferentialInverseKinematicsIntegrator(
                plant_for_ik, torso_frame(plant_for_ik), ee_frame(plant_for_ik, side), time_step, fb_params
            )
        )
        fallback.set_name(f"{side}_arm_diff_ik_position")
        chooser = builder.AddSystem(IKFallbackSelector(plant_for_ik, side, time_step))
        chooser.set_name(f"{side}_arm_ik_fallback")
        builder.Connect(integrator.GetOutputPort("joint_positions"), chooser.GetInputPort("q_full"))
        builder.Connect(fallback.GetOutputPort("joint_positions"), chooser.GetInputPort("q_position"))
        ik_q = chooser.get_output_port()
    else:
        ik_q = integrator.GetOutputPort("joint_positions")
    approach = None
    if joint_space_approach:
        v_max = np.asarray(parameters.get_joint_velocity_limits()[1], dtype=float)
        approach = builder.AddSystem(JointSpaceApproach(plant_for_ik, side, time_step, q_lo_all, q_hi_all, v_max))
        approach.set_name(f"{side}_arm_joint_space_approach")
        builder.Connect(ik_q, approach.GetInputPort("q_ik"))
        builder.Connect(pose_guard.GetOutputPort("X_AE_desired"), approach.GetInputPort("X_AE_desired"))
        ik_q = approach.get_output_port()
    builder.Connect(ik_q, select.get_input_port())
    builder.Connect(select.get_output_port(), command_guard.GetInputPort("q"))
    builder.Connect(command_guard.GetOutputPort("q_commanded"), expand.get_input_port())
    builder.Connect(expand.get_output_port(), integrator.GetInputPort("robot_state"))
    builder.Connect(use_state.get_output_port(), integrator.GetInputPort("use_robot_state"))
    builder.Connect(expand.get_output_port(), pose_guard.GetInputPort("ik_state"))
    builder.Connect(pose_guard.GetOutputPort("X_AE_desired"), integrator.GetInputPort("X_AE_desired"))
    if fallback is not None:
        builder.Connect(expand.get_output_port(), fallback.GetInputPort("robot_state"))
        builder.Connect(use_state.get_output_port(), fallback.GetInputPort("use_robot_state"))
        builder.Connect(pose_guard.GetOutputPort("X_AE_desired"), fallback.GetInputPort("X_AE_desired"))
        builder.Connect(pose_guard.GetOutputPort("X_AE_desired"), chooser.GetInputPort("X_AE_desired"))
    q_out, v_out, limiter = command_guard.GetOutputPort("q_commanded"), command_guard.GetOutputPort("v_commanded"), None
    if motion_limits is not False:
        if motion_limits is not True and not (isinstance(motion_limits, (tuple, list)) and len(motion_limits) == 2):
            raise ValueError(f"AddArmDifferentialIK: motion_limits must be True, False or (acceleration, jerk), "
                             f"got {motion_limits!r}")
        acc, jerk = arm_motion_limits(side) if motion_limits is True else motion_limits
        limiter = builder.AddSystem(JointMotionLimiter(q_lo, q_hi, vel, acc, jerk, time_step))
        limiter.set_name(f"{side}_arm_motion_limiter")
        builder.Connect(q_out, limiter.GetInputPort("q"))
        builder.Connect(measured_q_port, limiter.GetInputPort("q_initial"))
        q_out, v_out = limiter.GetOutputPort("q_commanded"), limiter.GetOutputPort("v_commanded")
    return ArmDifferentialIK(
        side=side,
        time_step=float(time_step),
        plant=plant_for_ik,
        integrator=integrator,
        pose_guard=pose_guard,
        command_guard=command_guard,
        X_TE_desired_input=pose_guard.GetInputPort("X_TE_desired"),
        q_commanded_output=q_out,
        v_commanded_output=v_out,
        fallback=fallback,
        approach=approach,
        limiter=limiter,
    )
