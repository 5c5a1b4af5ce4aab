"""Counting the differential IK's outcomes during a simulation, and quieting Drake's per-step notices about them.

:class:`IKStatusCounter` is a simulator monitor: each IK update of each arm counted once, and those without a
solution. The teleoperation demo and ``akc-drake run --teleop`` both use it, inside :func:`quiet_drake_warnings`
(Drake logs a warning each time an arm's IK starts or stops finding solutions: dozens of lines on a run whose
targets leave the robot's reach, where the counts say the same in one).
"""

from __future__ import annotations

import contextlib
import logging
import math


@contextlib.contextmanager
def quiet_drake_warnings():
    """Silence Drake's per-step warnings (the IK's "stuck" notices) while an :class:`IKStatusCounter` counts them."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


class IKStatusCounter:
    """A simulator monitor counting the differential-IK steps per arm and those without a solution.

    :meth:`~akc_drake.robot.diff_ik.ArmDifferentialIK.status` is only the latest step's status, so it is
    read after every IK update: the simulator calls the monitor at the end of each step, and at a call at time
    ``t`` the latest IK update is the one at ``ceil(t / h) - 1`` periods (updates at ``t`` itself are applied
    at the start of the next step). Each update is counted once; the diagram's plant steps (2 ms) are
    shorter than the IK period (10 ms), so no update is missed.

    Args:
        ik: ``{"left": ArmDifferentialIK, "right": ArmDifferentialIK}``.
        time_step: the IK period, seconds.
        start_time: the run's start time; IK updates before it are not counted.

    Attributes:
        steps: per side, IK updates seen.
        failures: per side, updates where neither the full-pose IK nor its position-only fallback found a
            solution and no joint-space move drove the arm (the command is held).
        relaxed: per side, updates where the full-pose IK was stuck and the position-only fallback moved the
            arm (the orientation is then left to the joint centering).
        joint_space: per side, updates where the joint-space move to a solved pose drove the arm (both IKs
            stuck far from the target: :class:`~akc_drake.robot.joint_space_approach.JointSpaceApproach`).
        kinds: per status name ("no solution", "stuck"), updates with it (both arms).
    """

    _NAMES = {1: "no solution", 2: "stuck"}

    def __init__(self, ik: dict, time_step: float, start_time: float = 0.0):
        from pydrake.multibody.inverse_kinematics import DifferentialInverseKinematicsStatus

        self._ik = ik
        self._h = float(time_step)
        if not (math.isfinite(self._h) and self._h > 0):
            raise ValueError(f"time_step must be a positive number of seconds, got {time_step!r}")
        self._first = math.ceil(float(start_time) / self._h - 1e-6)
        self._ok = DifferentialInverseKinematicsStatus.kSolutionFound
        self._last = {s: None for s in ik}
        self.steps = dict.fromkeys(ik, 0)
        self.failures = dict.fromkeys(ik, 0)
        self.kinds: dict[str, int] = {}
        self.relaxed = dict.fromkeys(ik, 0)
        self.joint_space = dict.fromkeys(ik, 0)

    def __call__(self, root_context):
        from pydrake.systems.framework import EventStatus

        t = root_context.get_time()
        j = math.ceil(t / self._h - 1e-6) - 1
        if j < self._first:
            return EventStatus.Succeeded()
        for side, arm in self._ik.items():
            last = self._last[side]
            if last is not None and j <= last:
                continue
            self._last[side] = j
            self.steps[side] += 1
            if hasattr(arm, "approaching") and arm.approaching(root_context):
                # The joint-space move drives the arm (whatever the differential IKs report): not a failure.
                self.joint_space[side] += 1
                continue
            status = arm.status(root_context)
            if status == self._ok:
                continue
            fallback = arm.fallback_status(root_context) if hasattr(arm, "fallback_status") else None
            if fallback == self._ok:
                # The full pose was stuck, the position-only IK moved the arm: not a failure, counted apart.
                self.relaxed[side] += 1
                continue
            self.failures[side] += 1
            name = self._NAMES.get(int(status), str(status))
            self.kinds[name] = self.kinds.get(name, 0) + 1
        return EventStatus.Succeeded()

    @property
    def total_failures(self) -> int:
        return int(sum(self.failures.values()))

    def counts(self) -> dict:
        """The counts as plain data (copies): ``steps``, ``failures``, ``relaxed``, ``joint_space``, ``kinds``."""
        return {
            "steps": dict(self.steps),
            "failures": dict(self.failures),
            "relaxed": dict(self.relaxed),
            "joint_space": dict(self.joint_space),
            "kinds": dict(self.kinds),
        }
