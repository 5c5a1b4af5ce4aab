"""The closed-loop operator's core (akc_drake/operator/closed_loop.py): a step in the tool's error decays with
the stated delay and gain, nothing is corrected on target, and the posture is the plan's when nothing is."""

import numpy as np
import pytest

from akc_drake.operator.closed_loop import (
    ClosedLoopOperator,
    CorrectionParams,
    CorrectionState,
    VisualCorrection,
)

DT = 0.02


def _loop(params: CorrectionParams, e0, seconds: float = 3.0):
    """A robot that follows the operator perfectly, off by ``e0`` from t = 0: the error is e0 - offset."""
    vc = VisualCorrection(params)
    state = CorrectionState()
    t_all, e_all, c_all = [], [], []
    for k in range(int(round(seconds / DT)) + 1):
        t = k * DT
        e = np.asarray(e0, float) - state.offset
        state = vc.step(state, t, e, 1.0)
        t_all.append(t), e_all.append(e), c_all.append(state.offset.copy())
    return np.array(t_all), np.array(e_all), np.array(c_all)


def test_a_step_error_decays_with_the_stated_delay_and_gain():
    p = CorrectionParams()
    e0 = np.array([0.06, 0.0, 0.0])
    t, e, c = _loop(p, e0)
    before = t < p.delay_s - 1e-9
    assert np.all(c[before] == 0.0)  # nothing is seen before the delay has passed
    # the first step acting is the first at or after the delay; from it on the offset moves at
    # gain x (error - deadband) = 3 /s x 4.5 cm = 13.5 cm/s
    first = int(np.flatnonzero(c[:, 0] > 0)[0])
    assert t[first] >= p.delay_s and t[first] - DT < p.delay_s
    k = first + 5
    assert c[k, 0] == pytest.approx(p.gain_per_s * (0.06 - p.deadband_m) * (t[k] - t[first] + DT), rel=1e-9)
    assert np.all(c[:, 1:] == 0.0)  # along the error only
    # the error ends within the deadband, without a large overshoot (the delayed loop is damped)
    assert abs(e[-1, 0]) <= p.deadband_m + 1e-3
    assert np.min(e[:, 0]) > -0.25 * 0.06
    # a slower operator (half the gain) has corrected less at the same time
    _, e_slow, _ = _loop(CorrectionParams(gain_per_s=p.gain_per_s / 2), e0)
    j = int(np.flatnonzero(t >= 0.8)[0])
    assert abs(e_slow[j, 0]) > abs(e[j, 0]) + 0.005


def test_no_correction_on_target_within_the_deadband_or_while_not_still():
    p = CorrectionParams()
    for e0 in ([0.0, 0.0, 0.0], [0.9 * p.deadband_m, 0.0, 0.0]):
        _, _, c = _loop(p, e0)
        assert np.all(c == 0.0)
    vc, state = VisualCorrection(p), CorrectionState()
    for k in range(100):  # a large error seen while the plan or the tool moves (weight 0)
        state = vc.step(state, k * DT, np.array([0.1, 0.1, 0.0]), 0.0)
    assert np.all(state.offset == 0.0)


def test_the_correction_is_speed_limited_and_bounded():
    p = CorrectionParams()
    t, _, c = _loop(p, [1.0, 0.0, 0.0], seconds=2.0)  # a metre off: the operator does not jump
    speed = np.linalg.norm(np.diff(c, axis=0), axis=1) / DT
    assert speed.max() <= p.max_speed_m_s + 1e-9
    assert np.linalg.norm(c[-1]) <= p.max_offset_m + 1e-12
    with pytest.raises(ValueError, match="gain_per_s"):
        CorrectionParams(gain_per_s=-1.0)


@pytest.fixture(scope="module")
def planned():
    from akc_drake.core.frames import calibrated_mapping
    from akc_drake.operator.model import OperatorParams
    from akc_drake.operator.motions import pick_place_plan

    mapping = calibrated_mapping(OperatorParams().dims)
    motion, plan = pick_place_plan(0, mapping=mapping)
    return motion, plan, mapping


def test_operator_on_target_plays_the_plan_and_aims_at_the_waypoints(planned):
    from akc_drake.operator.motions import PICK_BOX_T

    motion, plan, mapping = planned
    op = ClosedLoopOperator(motion, mapping, tool_plan=plan)
    state = op.initial_state()
    for t in np.arange(0.0, 2.0, DT):  # the robot's tool exactly where the operator aims it
        state = op.step(state, t, op.plan_tool(t)[0])
    assert np.all(state.offset == 0.0)
    q = op.posture(state, 1.0)
    np.testing.assert_array_equal(q, motion.q()[int(round(1.0 / 0.01))])
    # the aim at the grasp is the box's centre, still
    t_grasp = plan.times[4]
    p, _, speed = op.plan_tool(t_grasp)
    assert np.linalg.norm(p - PICK_BOX_T) < 0.01 and speed == 0.0
    # a tool 5 cm short of the box is corrected: the operator moves its wrist target toward the box
    state = op.step(op.initial_state(), t_grasp - 1.0, op.plan_tool(t_grasp)[0] + [0.0, 0.0, 0.2])  # on its way
    for t in np.arange(t_grasp - 0.9, t_grasp - 0.2, DT):
        state = op.step(state, t, op.plan_tool(t)[0] - [0.05, 0.0, 0.0] + state.offset)
    assert state.offset[0] > 0.02 and abs(state.offset[1]) < 1e-9
    q_moved = op.posture(state, t_grasp)
    assert np.max(np.abs(q_moved[5:] - motion.sample([t_grasp])[1][0])) > 0.02  # the right arm
    np.testing.assert_array_equal(q_moved[:5], motion.sample([t_grasp])[0][0])  # the left arm plays the plan


def test_a_robot_that_has_not_started_following_is_waited_for(planned):
    """A tool held in its home pose 12 cm from the aim (tracking not yet acquired) is not chased: no correction
    until it has moved 3 cm; then the operator corrects as usual."""
    from akc_drake.operator.closed_loop import ENGAGE_M

    motion, plan, mapping = planned
    op = ClosedLoopOperator(motion, mapping, tool_plan=plan)
    p0, _, _ = op.plan_tool(0.5)
    home = p0 + [0.12, 0.0, 0.0]
    state = op.initial_state()
    for t in np.arange(0.0, 1.4, DT):  # the plan rests (still); the robot does not move
        state = op.step(state, t, home)
    assert np.all(state.offset == 0.0) and not state.engaged
    # the robot starts following: it comes to rest 5 cm short of the aim, and the operator corrects that
    state = op.step(state, 1.4, home - [ENGAGE_M + 0.01, 0.0, 0.0])
    assert state.engaged
    for t in np.arange(1.42, 2.4, DT):
        state = op.step(state, t, p0 + [0.05, 0.0, 0.0] + state.offset)
    assert state.offset[0] < -0.01


def test_until_the_grasp_the_operator_reaches_for_the_box_where_it_is(planned):
    """A box pushed 7 cm along x before the grasp: the operator's aim at the box moves with it (the tool, on the
    box's starting place, is corrected toward the box); after the plan's hand closes the aims are the plan's."""
    from akc_drake.operator.motions import PICK_BOX_T

    motion, plan, mapping = planned
    op = ClosedLoopOperator(motion, mapping, tool_plan=plan, object_T=PICK_BOX_T)
    t_grasp = plan.times[4]
    assert op.first_grasp_t == pytest.approx(t_grasp, abs=0.011)  # the motion is sampled at 10 ms
    pushed = np.asarray(PICK_BOX_T) + [0.07, 0.0, 0.0]
    aim = op.plan_tool(t_grasp - 0.5)[0]
    np.testing.assert_allclose(op.object_shift(t_grasp - 0.5, aim, pushed), [0.07, 0.0, 0.0])
    assert np.all(op.object_shift(t_grasp + 0.1, aim, pushed) == 0.0)  # grasped: no longer
    assert np.all(op.object_shift(0.5, op.plan_tool(0.5)[0], pushed) == 0.0)  # the rest pose: far from the box
    state = op.step(op.initial_state(), t_grasp - 1.0, aim + [0.0, 0.0, 0.2], pushed)  # on its way
    for t in np.arange(t_grasp - 0.9, t_grasp - 0.2, DT):  # the tool on the box's starting place, following
        state = op.step(state, t, op.plan_tool(t)[0] + state.offset, pushed)
    assert state.offset[0] > 0.03 and abs(state.offset[1]) < 1e-9
    # the same operator without object_T aims at the starting place: nothing to correct
    op0 = ClosedLoopOperator(motion, mapping, tool_plan=plan)
    state = op0.step(op0.initial_state(), t_grasp - 1.0, aim + [0.0, 0.0, 0.2], pushed)
    for t in np.arange(t_grasp - 0.9, t_grasp - 0.2, DT):
        state = op0.step(state, t, op0.plan_tool(t)[0] + state.offset, pushed)
    assert np.all(state.offset == 0.0)
