"""Watches the teleoperation: targets, commands and the achieved end-effector poses, for the demo's figures."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from akc_drake.robot.model import (
    NUM_ARM_JOINTS,
    arm_joint_limits,
    arm_joint_names,
    arm_motion_limits,
    ee_frame,
    finite_vectors,
    torso_frame,
)

SIDES = ("left", "right")


class TeleopMonitor(LeafSystem):
    """Samples the teleop loop at the IK rate and keeps running statistics (and, optionally, the history).

    .. pydrake_system::

        name: TeleopMonitor
        input_ports:
        - X_TE_desired_left
        - X_TE_desired_right
        - tracking_lost
        - q_commanded_left
        - q_commanded_right
        - robot_state
        output_ports: []

    History (``keep_history``): per sample the wrist targets, the achieved end-effector poses, the commanded arm
    joints (``q_{side}``) and the measured ones (``q_measured_{side}``, ``v_measured_{side}``: the plant's state).

    Statistics: NaN commands, the largest commanded joint speed and acceleration (the second difference of three
    samples) as fractions of the limits (the model's, :func:`~akc_drake.robot.model.arm_joint_limits`; the
    acceleration limits given, else :func:`~akc_drake.robot.model.arm_motion_limits`), commands at a position or
    velocity limit or over 1.05 times an acceleration limit, and the distance between the target and the achieved
    end-effector position.

    Args:
        plant: the station's plant (for forward kinematics of the measured state).
        robot: the robot's model instance.
        period_s: sampling period (the IK period).
        keep_history: keep every sample (for plots); off for long runs, where only statistics are kept
            (memory stays flat).
        acceleration_limits: side -> the arm's joint acceleration limits (rad/s^2, 7 positive numbers) the
            commands are measured against, e.g. those its limiter was given; a side not given: the model's.
    """

    def __init__(self, plant, robot, period_s: float = 0.01, keep_history: bool = True,
                 acceleration_limits: dict | None = None):
        super().__init__()
        self._plant = plant
        self._robot = robot
        self._plant_context = plant.CreateDefaultContext()
        self._ee = {s: ee_frame(plant, s, robot) for s in SIDES}
        self._torso = torso_frame(plant, robot)
        self._limits = {s: arm_joint_limits(s) for s in SIDES}
        given = dict(acceleration_limits or {})
        unknown = set(given) - set(SIDES)
        if unknown:
            raise ValueError(f"TeleopMonitor: acceleration_limits sides must be in {SIDES}, got {sorted(unknown)}")
        acc = {s: finite_vectors("TeleopMonitor", NUM_ARM_JOINTS, **{f"acceleration_limits[{s!r}]": given[s]})[0]
               if s in given else arm_motion_limits(s)[0] for s in SIDES}
        if min(a.min() for a in acc.values()) <= 0.0:
            raise ValueError("TeleopMonitor: acceleration limits must be > 0")
        #: The acceleration limits the commands are measured against, per side (rad/s^2).
        self.acceleration_limits = {s: a.copy() for s, a in acc.items()}
        self._acc = {s: acc[s] * period_s**2 for s in SIDES}  # (per step squared)
        # Where each arm's joints sit in the plant's full q and v (the measured joint state of the history).
        joints = {s: [plant.GetJointByName(n, robot) for n in arm_joint_names(s)] for s in SIDES}
        self._q_index = {s: np.array([j.position_start() for j in joints[s]], dtype=np.intp) for s in SIDES}
        self._v_index = {s: np.array([j.velocity_start() for j in joints[s]], dtype=np.intp) for s in SIDES}
        self._period = period_s
        self._keep = keep_history
        for s in SIDES:
            self.DeclareAbstractInputPort(f"X_TE_desired_{s}", AbstractValue.Make(RigidTransform()))
        self.DeclareVectorInputPort("tracking_lost", 2)
        for s in SIDES:
            self.DeclareVectorInputPort(f"q_commanded_{s}", 7)
        nx = plant.num_positions(robot) + plant.num_velocities(robot)
        self.DeclareVectorInputPort("robot_state", nx)
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._sample)
        self.reset()

    def reset(self) -> None:
        """Forget everything recorded."""
        self.samples = 0
        self.nan_commands = 0
        self.max_speed_ratio = 0.0
        self.position_limit_hits = 0
        self.velocity_limit_hits = 0
        self.max_acceleration_ratio = 0.0
        self.acceleration_limit_hits = 0
        self.tracking_lost_samples = 0
        self._prev_q = {s: None for s in SIDES}
        self._prev_step = {s: None for s in SIDES}
        self._errors = {s: [] for s in SIDES}  # decimated to the camera rate, so tiny even for long runs
        self._error_t = {s: [] for s in SIDES}  # the sample time of each entry of _errors
        self.history = {k: [] for k in ("t", "target_left", "target_right", "ee_left", "ee_right",
                                        "q_left", "q_right", "q_measured_left", "q_measured_right",
                                        "v_measured_left", "v_measured_right", "lost")}

    def _sample(self, context):
        t = context.get_time()
        self.samples += 1
        state = self.GetInputPort("robot_state").Eval(context)
        self._plant.SetPositionsAndVelocities(self._plant_context, self._robot, state)
        lost = self.GetInputPort("tracking_lost").Eval(context)
        if np.any(lost > 0.5):
            self.tracking_lost_samples += 1
        row = {"t": t, "lost": np.array(lost, copy=True)}
        if self._keep:
            q_all = self._plant.GetPositions(self._plant_context)
            v_all = self._plant.GetVelocities(self._plant_context)
        for s in SIDES:
            q = np.array(self.GetInputPort(f"q_commanded_{s}").Eval(context), copy=True)
            lo, hi, vel = self._limits[s]
            if not np.all(np.isfinite(q)):
                self.nan_commands += 1
            else:
                if np.any(q <= lo + 1e-3) or np.any(q >= hi - 1e-3):
                    self.position_limit_hits += 1
                prev = self._prev_q[s]
                if prev is not None:
                    ratio = float(np.max(np.abs(q - prev) / (vel * self._period)))
                    self.max_speed_ratio = max(self.max_speed_ratio, ratio)
                    if ratio >= 0.97:
                        self.velocity_limit_hits += 1
                    step, last = q - prev, self._prev_step[s]
                    if last is not None:
                        ratio = float(np.max(np.abs(step - last) / self._acc[s]))
                        self.max_acceleration_ratio = max(self.max_acceleration_ratio, ratio)
                        self.acceleration_limit_hits += ratio > 1.05
                    self._prev_step[s] = step
                self._prev_q[s] = q
            X_target = self.GetInputPort(f"X_TE_desired_{s}").Eval(context)
            X_ee = self._ee[s].CalcPose(self._plant_context, self._torso)
            err = float(np.linalg.norm(X_target.translation() - X_ee.translation()))
            if self.samples % max(int(round(0.1 / self._period)), 1) == 0 and np.isfinite(err):
                self._errors[s].append(err)
                self._error_t[s].append(t)
            if self._keep:
                row[f"target_{s}"] = X_target.GetAsMatrix4()
                row[f"ee_{s}"] = X_ee.GetAsMatrix4()
                row[f"q_{s}"] = q
                row[f"q_measured_{s}"] = q_all[self._q_index[s]].copy()
                row[f"v_measured_{s}"] = v_all[self._v_index[s]].copy()
        if self._keep:
            for k, v in row.items():
                self.history[k].append(v)

    def ee_errors(self, side: str) -> np.ndarray:
        """Target-to-achieved end-effector distances (m), sampled at ~10 Hz."""
        return np.asarray(self._errors[side])

    def ee_error_times(self, side: str) -> np.ndarray:
        """The simulation time (s) of each entry of :meth:`ee_errors`."""
        return np.asarray(self._error_t[side])

    def history_arrays(self) -> dict[str, np.ndarray]:
        """The recorded history as arrays (empty when ``keep_history`` is off)."""
        return {k: np.asarray(v) for k, v in self.history.items()}
