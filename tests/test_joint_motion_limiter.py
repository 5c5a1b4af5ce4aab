"""JointMotionLimiter: the joint command within its velocity, acceleration and jerk limits (Ruckig)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from akc_drake.robot.joint_motion_limiter import JointMotionLimiter

H = 0.01


class Rig:
    """The limiter alone, its target a fixed input value, its three outputs logged every period."""

    def __init__(self, lower, upper, vel, acc, jerk, q0):
        builder = DiagramBuilder()
        self.lim = builder.AddSystem(JointMotionLimiter(lower, upper, vel, acc, jerk, H))
        self.q_port = builder.ExportInput(self.lim.GetInputPort("q"), "q")
        self.q0_port = builder.ExportInput(self.lim.GetInputPort("q_initial"), "q_initial")
        self.logs = [LogVectorOutput(self.lim.GetOutputPort(n), builder, H)
                     for n in ("q_commanded", "v_commanded", "a_commanded")]
        self.diagram = builder.Build()
        self.sim = Simulator(self.diagram)
        self.ctx = self.sim.get_mutable_context()
        self.diagram.get_input_port(self.q0_port).FixValue(self.ctx, np.asarray(q0, dtype=float))

    def run(self, target, until):
        self.diagram.get_input_port(self.q_port).FixValue(self.ctx, np.asarray(target, dtype=float))
        self.sim.AdvanceTo(until)

    def out(self, name="q_commanded"):
        return self.lim.GetOutputPort(name).Eval(self.lim.GetMyContextFromRoot(self.ctx))

    def log(self, i):
        return self.logs[i].FindLog(self.ctx).data().T


def _limits(n, v=1.0, a=10.0, j=1e6):
    return -np.full(n, 3.0), np.full(n, 3.0), np.full(n, v), np.full(n, a), np.full(n, j)


def test_a_rest_to_rest_move_takes_the_time_optimal_trapezoid():
    # 1 rad at v 1 rad/s, a 10 rad/s^2 and a jerk high enough not to count: 0.1 s up, 0.9 s cruise, 0.1 s down.
    rig = Rig(*_limits(1), q0=[0.0])
    np.testing.assert_allclose(rig.out(), [0.0])  # before initialisation: q_initial, at rest
    rig.run([1.0], 1.09)
    assert 0.99 < rig.out()[0] < 1.0 - 1e-5
    rig.run([1.0], 1.2)
    np.testing.assert_allclose(rig.out(), [1.0], atol=1e-9)
    np.testing.assert_allclose(rig.out("v_commanded"), [0.0], atol=1e-9)
    q, v, a = (rig.log(i)[:, 0] for i in range(3))
    assert np.max(np.abs(v)) == pytest.approx(1.0, abs=1e-9)  # cruising at the velocity limit
    assert np.max(np.abs(a)) == pytest.approx(10.0, abs=1e-6)
    # The outputs are one trajectory: the position's differences are its velocity, their differences within a.
    assert np.max(np.abs(np.diff(q, 2) / H**2)) <= 10.0 * (1 + 1e-9)
    assert np.max(np.abs(np.diff(q) / H)) <= 1.0 + 1e-9


def test_jerk_limit_and_joints_arriving_together():
    lo, hi, vel, acc, _ = _limits(2, v=2.0, a=10.0)
    rig = Rig(lo, hi, vel, acc, np.full(2, 200.0), q0=[0.0, 0.0])
    rig.run([1.0, -0.25], 2.0)
    q, v, a = (rig.log(i) for i in range(3))
    assert np.max(np.abs(np.diff(a, axis=0) / H)) <= 200.0 * (1 + 1e-9)  # a ramps: 0.05 s to reach 10
    assert abs(a[1, 0]) < 3.0
    # Time synchronisation: the shorter move is stretched to end with the longer one.
    done = [int(np.argmax(np.abs(q[:, i] - q[-1, i]) < 1e-9)) for i in range(2)]
    # 0.2 s to 2 rad/s and 0.2 s back (0.4 rad), 0.3 s cruising, plus the jerk's ramps (0.05 s).
    assert done[0] == done[1] and 0.74 <= done[0] * H <= 0.78, done
    np.testing.assert_allclose(q[-1], [1.0, -0.25], atol=1e-9)


def test_follows_a_staircase_within_the_limits_where_the_staircase_is_far_outside():
    # The differential IK's command: each 0.1 s a new pose, reached in two IK steps at the velocity limit.
    t = np.arange(0.0, 3.0, H)
    stairs = 0.3 * np.sin(2.0 * np.pi * 0.5 * np.floor(t / 0.1) * 0.1)
    raw_acc = np.max(np.abs(np.diff(stairs, 2) / H**2))
    rig = Rig(*_limits(1, v=2.0, a=15.0, j=7500.0), q0=[0.0])
    q = []
    for k, s in enumerate(stairs):
        rig.run([s], k * H)
        q.append(rig.out()[0])
    q = np.array(q)
    acc = np.max(np.abs(np.diff(q, 2) / H**2))
    assert raw_acc > 100.0 and acc <= 15.0 * (1 + 1e-9), (raw_acc, acc)
    # ... and stays near it: within the staircase's own step (0.1 s of the sine, 0.094 rad) after the first second.
    assert np.max(np.abs(q - stairs)[t > 1.0]) < 0.1


def test_no_target_brakes_to_rest_and_limits_clip():
    rig = Rig(*_limits(1, a=5.0), q0=[5.0])  # q_initial above the upper limit: clipped
    np.testing.assert_allclose(rig.out(), [3.0])
    rig.run([-10.0], 0.5)  # a target below the lower limit: towards -3
    v0, q1 = rig.out("v_commanded")[0], rig.out()[0]
    # 0.2 s to reach 1 rad/s (0.1 rad), 0.3 s at it.
    assert v0 == pytest.approx(-1.0, abs=1e-9) and q1 == pytest.approx(3.0 - 0.1 - 0.3, abs=0.01)
    rig.run([np.nan], 1.0)  # no target: to rest within v^2 / 2a (0.1 rad) without exceeding a
    stop = rig.out()[0]
    assert stop == pytest.approx(q1 - 0.1, abs=1e-4)
    rig.run([np.nan], 1.5)
    np.testing.assert_allclose(rig.out(), [stop])
    np.testing.assert_allclose(rig.out("v_commanded"), [0.0], atol=1e-12)
    q = rig.log(0)[:, 0]
    assert np.max(np.abs(np.diff(q, 2) / H**2)) <= 5.0 * (1 + 1e-9)


@pytest.mark.parametrize("bad", [
    dict(velocity=[0.0]), dict(acceleration=[-1.0]), dict(jerk=[np.inf]), dict(lower=[1.0], upper=[0.0]),
    dict(period=0.0), dict(velocity=[1.0, 1.0]),
])
def test_bad_arguments(bad):
    args = dict(lower=[-1.0], upper=[1.0], velocity=[1.0], acceleration=[1.0], jerk=[1.0], period=H) | bad
    with pytest.raises(ValueError, match="JointMotionLimiter"):
        JointMotionLimiter(**args)


def test_a_move_of_rounding_residue_from_rest():
    # Seen in the pick-and-place task: Ruckig's time synchronisation failed ("error in step 2") on a move of
    # 1e-15 rad with velocities of 1e-18 rad/s; the limiter takes such residue as rest, or plans each joint alone.
    from akc_drake.robot.model import arm_joint_limits, arm_motion_limits

    lo, hi, vel = arm_joint_limits("left")
    lim = JointMotionLimiter(lo, hi, vel, *arm_motion_limits("left"), H)
    for got, want in zip(lim.limits, (vel, *arm_motion_limits("left")), strict=True):
        np.testing.assert_array_equal(got, want)
    q = [0.5573932559430769, -0.8727401746534799, -0.3465196945084862, -1.690033214064407, -2.580016986695953,
         -1.312728570694101, 2.172219925411454]
    v = [0.0, -8.258571235729428e-19, 3.21630723046312e-18, 1.387778780781446e-17, 0.0, -3.469446951953614e-18, 0.0]
    a = [0.0, 0.0, -5.551115123125783e-16, 0.0, 0.0, 0.0, 0.0]
    target = [0.5573932559430776, -0.8727401746534799, -0.3465196945084855, -1.690033214064405, -2.580016986695953,
              -1.312728570694101, 2.172219925411398]
    qn, vn, an = lim.step(q, v, a, target)
    np.testing.assert_allclose(qn, target, atol=1e-12)
    assert max(map(abs, vn)) < 1e-9 and max(map(abs, an)) < 1e-6
