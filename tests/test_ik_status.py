"""``akc_drake.robot.ik_status``: the differential IK's outcomes counted once per update, Drake's notices quieted."""

from __future__ import annotations

import logging

import pytest
from pydrake.multibody.inverse_kinematics import DifferentialInverseKinematicsStatus as Status

from akc_drake.robot.ik_status import IKStatusCounter, quiet_drake_warnings


class _Context:
    def __init__(self, t):
        self.t = t

    def get_time(self):
        return self.t


class _Arm:
    """An arm whose IK reports ``status[j]`` (and the fallback ``fallback[j]``) for update ``j``; ``approach``: the
    updates where the joint-space move drives it."""

    def __init__(self, status, fallback=None, approach=()):
        self.s, self.f, self.a = status, fallback or {}, set(approach)

    def _j(self, ctx):
        return round(ctx.get_time() / 0.01 - 0.5)

    def status(self, ctx):
        return self.s.get(self._j(ctx), Status.kSolutionFound)

    def fallback_status(self, ctx):
        return self.f.get(self._j(ctx), Status.kStuck)

    def approaching(self, ctx):
        return self._j(ctx) in self.a


def test_each_update_is_counted_once_and_by_its_outcome():
    left = _Arm({2: Status.kStuck, 3: Status.kNoSolutionFound, 4: Status.kStuck},
                fallback={4: Status.kSolutionFound}, approach={5})
    right = _Arm({})
    c = IKStatusCounter({"left": left, "right": right}, 0.01)
    # The simulator calls the monitor after every 2 ms plant step: update j is read at times in (j h, (j + 1) h].
    for k in range(1, 41):  # 80 ms: updates 0..7
        c(_Context(k * 0.002))
    assert c.steps == {"left": 8, "right": 8}
    assert c.failures == {"left": 2, "right": 0}  # updates 2 (stuck) and 3 (no solution); 4 the fallback moved
    assert c.relaxed == {"left": 1, "right": 0} and c.joint_space == {"left": 1, "right": 0}
    assert c.kinds == {"stuck": 1, "no solution": 1} and c.total_failures == 2
    counts = c.counts()  # (plain copies, as run --json writes them)
    assert counts == {"steps": {"left": 8, "right": 8}, "failures": {"left": 2, "right": 0},
                      "relaxed": {"left": 1, "right": 0}, "joint_space": {"left": 1, "right": 0},
                      "kinds": {"stuck": 1, "no solution": 1}}
    counts["steps"]["left"] = 0
    assert c.steps["left"] == 8


def test_updates_before_the_start_are_not_counted():
    c = IKStatusCounter({"left": _Arm({0: Status.kStuck})}, 0.01, start_time=0.03)
    for k in range(1, 41):
        c(_Context(k * 0.002))
    assert c.steps == {"left": 5} and c.failures == {"left": 0}  # updates 3..7


def test_a_time_step_must_be_positive():
    with pytest.raises(ValueError, match="positive number of seconds"):
        IKStatusCounter({}, 0.0)


def test_quiet_drake_warnings_silences_warnings_not_errors_and_restores_the_level(caplog):
    log = logging.getLogger("drake")
    with caplog.at_level(logging.DEBUG, logger="drake"):
        with quiet_drake_warnings():
            assert log.level == logging.ERROR
            log.warning('Differential IK started returning status:"stuck"')
            log.error("a real error")
        assert log.level == logging.DEBUG  # (the level before, restored)
        log.warning("after")
    assert [r.getMessage() for r in caplog.records] == ["a real error", "after"]
