"""JointSpaceApproach: the differential IK's command passed through, or a joint-space move to a solved pose."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator

from akc_drake.robot.diff_ik import arm_ik_parameters, make_arm_ik_plant
from akc_drake.robot.joint_space_approach import JointSpaceApproach, joint_space_step
from akc_drake.robot.model import NOMINAL_ARM_Q, ee_frame, torso_frame

DT = 0.01


@pytest.fixture(scope="module")
def plant():
    return make_arm_ik_plant("left")


@pytest.fixture(scope="module")
def limits(plant):
    params = arm_ik_parameters(plant, "left", DT)
    lo, hi = (np.asarray(b, float) for b in params.get_joint_position_limits())
    return lo, hi, np.asarray(params.get_joint_velocity_limits()[1], float)


def _pose(plant, q) -> RigidTransform:
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q)
    return ee_frame(plant, "left").CalcPose(ctx, torso_frame(plant))


class Rig:
    """The system alone, stepped one IK period at a time. ``q_ik`` and the target are fixed input values; with
    ``stuck``, ``q_ik`` is the system's own last output before each step (a differential IK that linearises around
    the command and cannot move)."""

    def __init__(self, plant, limits, q_ik, X, stuck=False, **kwargs):
        self.sys = JointSpaceApproach(plant, "left", DT, *limits, **kwargs)
        self.sim = Simulator(self.sys)
        self.ctx = self.sim.get_mutable_context()
        self.stuck = stuck
        self.set(q_ik, X)
        self.t = 0.0

    def set(self, q_ik, X=None):
        self.sys.GetInputPort("q_ik").FixValue(self.ctx, np.asarray(q_ik, float))
        if X is not None:
            self.sys.GetInputPort("X_AE_desired").FixValue(self.ctx, AbstractValue.Make(X))

    def out(self) -> np.ndarray:
        return self.sys.get_output_port().Eval(self.ctx).copy()

    def step(self) -> np.ndarray:
        """Run one IK update; the output after it."""
        if self.stuck:
            self.set(self.out())
        self.t += DT
        self.sim.AdvanceTo(self.t - 0.5 * DT)
        return self.out()


def test_solve_reaches_a_reachable_pose_from_far_away(plant, limits):
    q_goal = np.array([0.6, -0.4, 0.8, -1.0, 0.5, -0.6, 0.9])
    X = _pose(plant, q_goal)
    sys = JointSpaceApproach(plant, "left", DT, *limits)
    q = sys.solve(X, np.asarray(NOMINAL_ARM_Q, float))
    assert q is not None
    lo, hi, _ = limits
    assert np.all(q >= lo - 1e-12) and np.all(q <= hi + 1e-12)
    Xq = _pose(plant, q)
    assert np.linalg.norm(Xq.translation() - X.translation()) <= 1e-3 * np.sqrt(3) + 1e-9
    assert X.rotation().InvertAndCompose(Xq.rotation()).ToAngleAxis().angle() < np.radians(1.0)


def test_tracking_passes_the_ik_command_through(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    X = _pose(plant, q0 + 0.3)  # far, but the IK's command moves toward it each step
    rig = Rig(plant, limits, q0, X)
    for k in range(6):
        q_ik = q0 + 0.3 * (k + 1) / 6
        rig.set(q_ik, X)
        np.testing.assert_array_equal(rig.sys.get_output_port().Eval(rig.ctx), q_ik)
        rig.step()
        assert not rig.sys.approaching(rig.ctx)
    assert rig.sys.moves(rig.ctx) == 0


def test_a_stuck_ik_far_from_a_reachable_target_gets_a_joint_space_move(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    q_goal = np.array([0.6, -0.4, 0.8, -1.0, 0.5, -0.6, 0.9])
    X = _pose(plant, q_goal)
    assert np.linalg.norm(X.translation() - _pose(plant, q0).translation()) > 0.2
    # (min_error_m 1 mm: the move goes all the way to the solved pose; by default it ends 5 cm from the target.)
    rig = Rig(plant, limits, q0, X, stuck=True, min_error_m=0.001)
    out = [rig.step() for _ in range(3)]
    # The first update has no previous command to measure progress from; two stalled steps are not three.
    assert not rig.sys.approaching(rig.ctx)
    np.testing.assert_array_equal(out[-1], q0)
    out.append(rig.step())
    assert rig.sys.approaching(rig.ctx) and rig.sys.moves(rig.ctx) == 1
    v_max = limits[2]
    prev = out[-2]
    steps = []
    for _ in range(300):
        q = rig.step()
        steps.append(q - prev)
        prev = q
        if not rig.sys.approaching(rig.ctx):
            break
    assert not rig.sys.approaching(rig.ctx), "the move did not end within 3 s"
    steps = np.array(steps)
    # Within the velocity limits, and one straight line in joint space (every joint arriving together).
    assert np.all(np.abs(steps) <= v_max * DT * (1 + 1e-9))
    direction = (q - out[-1]) / np.linalg.norm(q - out[-1])
    for d in steps[np.linalg.norm(steps, axis=1) > 1e-6]:
        assert abs(float(d @ direction) / np.linalg.norm(d)) > 1 - 1e-9
    # Ramped: the first and last steps are slower than the fastest.
    speed = np.linalg.norm(steps, axis=1)
    assert speed[0] < 0.2 * speed.max() and speed[-1] < 0.5 * speed.max()
    # It arrived at the pose (the tool point within the solve's 1 mm box, up to the solver's tolerance).
    Xq = _pose(plant, q)
    assert np.linalg.norm(Xq.translation() - X.translation()) < 3e-3
    # And then the differential IK's command is the output again.
    rig.set(q + 0.01)
    np.testing.assert_array_equal(rig.sys.get_output_port().Eval(rig.ctx), q + 0.01)


def test_a_moving_target_is_solved_again(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    X1 = _pose(plant, np.array([0.6, -0.4, 0.8, -1.0, 0.5, -0.6, 0.9]))
    rig = Rig(plant, limits, q0, X1, stuck=True, min_error_m=0.001)
    for _ in range(10):
        rig.step()
    assert rig.sys.approaching(rig.ctx)
    X2 = RigidTransform(X1.rotation(), X1.translation() + np.array([0.0, 0.0, 0.1]))
    rig.set(rig.out(), X2)
    for _ in range(300):
        q = rig.step()
        if not rig.sys.approaching(rig.ctx):
            break
    assert np.linalg.norm(_pose(plant, q).translation() - X2.translation()) < 3e-3
    assert rig.sys.moves(rig.ctx) == 1  # solved again, not a new move


def test_the_move_hands_over_once_the_tool_is_near_the_target(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    X = _pose(plant, np.array([0.6, -0.4, 0.8, -1.0, 0.5, -0.6, 0.9]))
    rig = Rig(plant, limits, q0, X, stuck=True)  # min_error_m 5 cm
    last = None
    for _ in range(300):
        q = rig.step()
        if rig.sys.approaching(rig.ctx):
            last = q
        elif last is not None:
            break
    assert last is not None and not rig.sys.approaching(rig.ctx)
    # The last command of the move is the one before the tool came within 5 cm (the differential IK's step from it
    # is the next command; this rig's IK stays where it is), far from the solved pose.
    d_last = np.linalg.norm(_pose(plant, last).translation() - X.translation())
    assert 0.05 <= d_last < 0.08


def test_an_unreachable_target_leaves_the_ik_in_charge(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    far = RigidTransform(RollPitchYaw(0.0, 0.0, 0.0), np.array([2.0, 1.0, 0.0]))  # 2 m away: no solution
    rig = Rig(plant, limits, q0, far, stuck=True, cooldown_steps=10)
    for _ in range(30):
        np.testing.assert_array_equal(rig.step(), q0)
        assert not rig.sys.approaching(rig.ctx)
    assert rig.sys.moves(rig.ctx) == 0


def test_near_target_is_no_stall(plant, limits):
    q0 = np.asarray(NOMINAL_ARM_Q, float)
    p = _pose(plant, q0)
    near = RigidTransform(p.rotation(), p.translation() + np.array([0.04, 0.0, 0.0]))  # within min_error_m
    rig = Rig(plant, limits, q0, near, stuck=True)
    for _ in range(10):
        rig.step()
    assert not rig.sys.approaching(rig.ctx)


def test_frozen_joints_stay_where_they_are():
    plant = make_arm_ik_plant(None)  # both arms: the right arm's joints are frozen for the left arm's IK
    params = arm_ik_parameters(plant, "left", DT)
    lo, hi = (np.asarray(b, float) for b in params.get_joint_position_limits())
    v = np.asarray(params.get_joint_velocity_limits()[1], float)
    assert np.count_nonzero(v == 0.0) == 7
    q0 = plant.GetDefaultPositions()
    ctx = plant.CreateDefaultContext()
    q_goal = q0.copy()
    q_goal[v > 0] = [0.6, -0.4, 0.8, -1.0, 0.5, -0.6, 0.9]
    plant.SetPositions(ctx, q_goal)
    X = ee_frame(plant, "left").CalcPose(ctx, torso_frame(plant))
    sys = JointSpaceApproach(plant, "left", DT, lo, hi, v)
    q = sys.solve(X, q0)
    assert q is not None
    np.testing.assert_array_equal(q[v == 0], q0[v == 0])


def test_rejects_bad_arguments(plant, limits):
    lo, hi, v = limits
    with pytest.raises(ValueError, match="q_lower"):
        JointSpaceApproach(plant, "left", DT, lo[:3], hi, v)
    with pytest.raises(ValueError, match="q_lower <= q_upper"):
        JointSpaceApproach(plant, "left", DT, hi, lo, v)
    with pytest.raises(ValueError, match="time_step"):
        JointSpaceApproach(plant, "left", 0.0, lo, hi, v)
    with pytest.raises(ValueError, match="stuck_steps"):
        JointSpaceApproach(plant, "left", DT, lo, hi, v, stuck_steps=0)
    with pytest.raises(ValueError, match="side"):
        JointSpaceApproach(plant, "middle", DT, lo, hi, v)


def test_joint_space_step_arrives_exactly_and_keeps_frozen_joints():
    q, goal = np.zeros(3), np.array([0.5, -0.2, 0.3])
    v = np.array([2.0, 1.0, 0.0])  # the third joint frozen
    rho, n = 0.0, 0
    while not np.array_equal(q[:2], goal[:2]):
        q, rho = joint_space_step(q, goal, rho, v, DT, 0.2)
        n += 1
        assert q[2] == 0.0 and rho <= 1.0
        assert n < 100
    # 0.25 s at full speed for the slowest (first) joint, plus the ramps: between 0.25 and 0.25 + 0.2 s.
    assert 25 <= n <= 45
    assert joint_space_step(q, goal, rho, v, DT, 0.2)[1] == 0.0  # there: no more motion
