"""akc_drake.core.akc_plus_torso: the torso references of AKC+'s held shoulders (unit tests on one corrector; the
rules' effects on whole sequences are in test_akc_plus.py)."""

import math

import numpy as np
import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_torso import learn_offset
from akc_drake.core.skeleton import INDEX, BodyDimensions

LS, RS, LE = INDEX["left_shoulder"], INDEX["right_shoulder"], INDEX["left_elbow"]
LH, RH = INDEX["left_hip"], INDEX["right_hip"]
R_Z = 0.05**2


def _pose():
    p = np.zeros((12, 3))
    p[:, 2] = 2.0
    p[LS, :2], p[RS, :2] = [0.18, 0.0], [-0.18, 0.0]
    p[LE] = [0.2, 0.29, 2.0]
    p[LH, :2], p[RH, :2] = [0.12, 0.5], [-0.12, 0.5]
    return p


def _corrector(**settings):
    from akc_drake.core.akc_plus_config import AKCPlusConfig

    dims = BodyDimensions(LUA=0.29, LLA=0.26, RUA=0.29, RLA=0.26, SW=0.36)
    akc = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(**settings))
    akc._var = [1.5e-3] * 36  # (a steady KF's depth variance on every coordinate: R - P = 1e-3)
    return akc


def _flat(a):
    return a.reshape(-1).tolist()


def test_learn_offset_starts_at_the_first_frame_then_is_a_running_mean():
    held = [None, None]
    learn_offset(held, 1, (1.0, 2.0, 3.0), (0.5, 0.5, 0.5), 0.2)
    assert held[1] == [0.5, 1.5, 2.5, 0.0] and held[0] is None
    held[1][3] = 7.0  # blind frames counted by the hold
    learn_offset(held, 1, (2.0, 2.0, 3.0), (0.5, 0.5, 0.5), 0.2)
    assert held[1][0] == pytest.approx(0.5 + 0.2 * (1.5 - 0.5)) and held[1][1:] == [1.5, 2.5, 0.0]


def test_the_hips_count_only_when_both_depths_pass_the_innovation_test():
    akc, p = _corrector(), _pose()
    v, m = _flat(p), _flat(p)
    assert akc._hips_consistent(v, m)
    m[3 * LH + 2] += 3.0 * math.sqrt(1e-3) * 0.99  # within the gate (3 sigma of R - P)
    assert akc._hips_consistent(v, m)
    m[3 * RH + 2] += 1.5  # the wall behind the body's edge
    assert not akc._hips_consistent(v, m)


def test_the_other_shoulder_is_a_reference_only_seen_and_as_last_corrected():
    akc, p = _corrector(), _pose()
    v, m = _flat(p), _flat(p)
    assert akc._other_anchor(v, m, 1) is None  # never corrected
    akc._prev[1] = tuple(_flat(p[[RS, INDEX["right_elbow"], INDEX["right_wrist"]]]))
    assert akc._other_anchor(v, m, 1) == tuple(p[RS])
    akc._lost[3] = 1.0  # not seen when last corrected
    assert akc._other_anchor(v, m, 1) is None
    akc._lost[3] = 0.0
    m[3 * RS + 2] = float("nan")  # not measured this frame
    assert akc._other_anchor(v, m, 1) is None
    # a filter that followed an occluder's depth, 25 cm in front: it passes the innovation test, but is 25 cm from
    # our last output of that shoulder
    v[3 * RS + 2] = m[3 * RS + 2] = 1.75
    assert akc._other_anchor(v, m, 1) is None


def test_the_other_shoulder_carries_the_held_one_after_the_hips_are_lost_for_hips_lost_frames():
    akc, p = _corrector(hips_lost_frames=3.0), _pose()
    akc._prev = [tuple(_flat(p[[LS, LE, INDEX["left_wrist"]]])),
                 tuple(_flat(p[[RS, INDEX["right_elbow"], INDEX["right_wrist"]]]))]
    akc._held_sh = [[0.06, -0.5, 0.0, 0.0], None]
    akc._held_ss = [[0.36, 0.0, 0.0, 0.0], None]
    v, m = _flat(p), _flat(p)
    hold, hips, others = akc._torso_anchors(v, m)
    assert hold and akc._anchor[0] == (hips, akc._held_sh[0]) and akc._anchor[1] is None
    assert hips == pytest.approx((0.0, 0.5, 2.0))
    m[3 * LH + 2] = float("nan")  # the hips lost
    for k in range(1, 4):
        hold, hips, others = akc._torso_anchors(v, m)
        assert not hold and math.isnan(hips[2]) and akc._hips_lost == k
        assert akc._anchor[0] == ((others[1], akc._held_ss[0]) if k >= 3 else None)
    assert others[1] == tuple(p[RS])


def test_a_shoulder_depth_the_torso_and_the_elbow_contradict_is_put_back_on_its_ray():
    akc, p = _corrector(), _pose()
    akc._anchor = [((0.0, 0.5, 2.0), [0.18, -0.5, 0.0, 2.0]), None]  # the held shoulder at 2.0 m deep
    f = _flat(p[[LS, LE, INDEX["left_wrist"]]])
    vs = [1e-4] * 9
    m = _flat(p)
    k = 1.75 / 2.0  # the shoulder read 25 cm in front on its pixel's ray, the filter following it
    m[3 * LS : 3 * LS + 3] = f[0:3] = [0.18 * k, 0.0, 1.75]
    assert akc._torso_outvotes(f, vs, m, 0)
    assert f[0:3] == pytest.approx([0.18, 0.0, 2.0]) and vs[2] == pytest.approx(1e-4 * 3.0)
    # read 3 cm in front: within the gate of the hold's and the measurement's variances, kept
    f2 = _flat(p[[LS, LE, INDEX["left_wrist"]]])
    m[3 * LS : 3 * LS + 3] = f2[0:3] = [0.18 * 1.97 / 2.0, 0.0, 1.97]
    assert not akc._torso_outvotes(f2, [1e-4] * 9, m, 0) and f2[2] == 1.97
    # an elbow not seen (its depth off its filter's by far more than the gate) is no second vote
    m[3 * LS : 3 * LS + 3] = f[0:3] = [0.18 * k, 0.0, 1.75]
    m[3 * LE + 2] += 0.5
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 1.75


def test_a_shoulder_depth_read_on_its_own_hand_is_put_back_on_its_ray():
    # The arm points at the camera: the shoulder's pixel reads the hand, 25 cm in front, and the elbow's depth is
    # lost. The measured wrist is nearer the measured shoulder than the arm can fold: the hand's depth.
    akc, p = _corrector(), _pose()
    akc._anchor = [((0.0, 0.5, 2.0), [0.18, -0.5, 0.0, 2.0]), None]  # the held shoulder at 2.0 m deep
    lw = INDEX["left_wrist"]
    p[lw] = [0.12, 0.02, 1.76]
    p[LE, 2] = np.nan
    m = _flat(p)
    k = 1.75 / 2.0
    fold = math.sqrt(0.29**2 + 0.26**2 - 2 * 0.29 * 0.26 * math.cos(math.radians(40.0))) - 0.05
    m[3 * LS : 3 * LS + 3] = [0.18 * k, 0.0, 1.75]
    assert math.dist(m[3 * LS : 3 * LS + 3], p[lw]) < fold
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 2.3] + _flat(p[[lw]])
    vs = [1e-4] * 9
    assert akc._torso_outvotes(f, vs, m, 0)
    assert f[0:3] == pytest.approx([0.18, 0.0, 2.0]) and vs[2] == pytest.approx(1e-4 * 3.0)
    # the same depth with the wrist as far from the shoulder as the arm reaches (arms in the image plane, a
    # T-pose at the shoulder's depth): no vote, the elbow lost, the measurement kept
    m[3 * lw : 3 * lw + 3] = [0.18 * k + 0.5, 0.0, 1.75]
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 2.3] + m[3 * lw : 3 * lw + 3]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 1.75
    # a shoulder read behind the held one is no hand's depth (occluders are in front)
    m[3 * lw : 3 * lw + 3] = [0.18 * 2.3 / 2.0 - 0.05, 0.02, 2.28]
    m[3 * LS : 3 * LS + 3] = [0.18 * 2.3 / 2.0, 0.0, 2.3]
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 2.3] + m[3 * lw : 3 * lw + 3]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 2.3



def test_a_shoulder_depth_out_of_its_measured_wrists_reach_is_put_back_on_its_ray():
    # MediaPipe's shoulder landmark off the body's edge reads the wall, 1.75 m behind; the elbow is lost and the
    # filter followed the reading. The measured wrist is farther from it than the arm reaches (l_u + l_f +
    # consistency_m) and within reach of the shoulder held on the torso: no arm puts the shoulder there.
    akc, p = _corrector(), _pose()
    akc._anchor = [((0.0, 0.5, 2.0), [0.18, -0.5, 0.0, 2.0]), None]  # the held shoulder at 2.0 m deep
    lw = INDEX["left_wrist"]
    p[lw] = [0.15, -0.2, 1.75]
    p[LE, 2] = np.nan
    m = _flat(p)
    k = 3.75 / 2.0
    m[3 * LS : 3 * LS + 3] = [0.18 * k, 0.0, 3.75]
    assert math.dist(m[3 * LS : 3 * LS + 3], p[lw]) > 0.29 + 0.26 + 0.05 > math.dist([0.18, 0.0, 2.0], p[lw])
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + _flat(p[[lw]])
    vs = [1e-4] * 9
    assert akc._torso_outvotes(f, vs, m, 0)
    assert f[0:3] == pytest.approx([0.18, 0.0, 2.0]) and vs[2] == pytest.approx(1e-4 * 3.0)
    # a wrist out of the held shoulder's reach too (itself read on the wall, or the torso's hold gone stale): no
    # vote, the measurement kept
    m[3 * lw : 3 * lw + 3] = [0.15 * 2.9 / 1.75, -0.2 * 2.9 / 1.75, 2.9]
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + m[3 * lw : 3 * lw + 3]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 3.75
    # a wrist not measured: no vote
    m[3 * lw : 3 * lw + 3] = [np.nan] * 3
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + [0.15, -0.2, 1.75]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 3.75



def test_a_shoulder_depth_farther_from_our_last_output_than_the_arm_reaches_is_put_back_on_its_ray():
    # The same wall, the elbow and the wrist lost too: no measured joint votes. The measurement is farther from our
    # last output's shoulder than the arm reaches, where the held shoulder is within that reach: no shoulder moves
    # that far in a frame.
    akc, p = _corrector(), _pose()
    akc._anchor = [((0.0, 0.5, 2.0), [0.18, -0.5, 0.0, 2.0]), None]  # the held shoulder at 2.0 m deep
    lw = INDEX["left_wrist"]
    p[[LE, lw]] = np.nan
    m = _flat(p)
    m[3 * LS : 3 * LS + 3] = [0.18 * 3.75 / 2.0, 0.0, 3.75]
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + [0.15, -0.2, 3.4]
    assert not akc._torso_outvotes(f[:], [1e-4] * 9, m, 0)  # (no last output yet: no vote)
    akc._prev[0] = (0.18, 0.0, 2.02, 0.2, 0.29, 2.0, 0.15, -0.2, 1.8)
    vs = [1e-4] * 9
    assert akc._torso_outvotes(f, vs, m, 0)
    assert f[0:3] == pytest.approx([0.18, 0.0, 2.0]) and vs[2] == pytest.approx(1e-4 * 3.0)
    # a last output itself out of the held shoulder's reach (one of them wrong): no vote
    akc._prev[0] = (0.18, 0.0, 2.7, 0.2, 0.29, 2.7, 0.15, -0.2, 2.5)
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + [0.15, -0.2, 3.4]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 3.75
    # a depth within the arm's reach of our last output (a torso that moved): no vote
    akc._prev[0] = (0.18, 0.0, 3.3, 0.2, 0.29, 3.3, 0.15, -0.2, 3.1)
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 3.75


def test_a_shoulder_depth_beyond_the_shoulder_widths_bound_keeps_our_last_output_without_a_torso_reference():
    # Both shoulders read on the wall at 3.75 m, on their own pixels' rays, and no torso reference (no anchor). Rays
    # at angle t put a point at range r at least r sin t from the other ray: at sin t = 0.179 the shoulders are at
    # most (0.36 + 0.05) / 0.179 = 2.3 m away, and 3.75 m is the background. Our last output (2.02 m) is within
    # the bound: the shoulder stays at its depth on the measured ray.
    akc, p = _corrector(), _pose()
    assert akc._anchor == [None, None]
    m = _flat(p)
    m[3 * LS : 3 * LS + 3] = [0.18 * 3.75 / 2.0, 0.0, 3.75]
    m[3 * RS : 3 * RS + 3] = [-0.18 * 3.75 / 2.0, 0.0, 3.75]
    a, b = np.array([0.09, 0.0, 1.0]), np.array([-0.09, 0.0, 1.0])
    sin_t = np.linalg.norm(np.cross(a, b)) / (a @ a)
    assert 3.76 * sin_t > 0.41 > 2.03 * sin_t and 2.2 * sin_t < 0.41 < 2.5 * sin_t
    wall = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 3.5] + [0.15, -0.2, 3.4]
    f = list(wall)
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0)  # (no last output yet: nothing to keep)
    akc._prev[0] = (0.18, 0.0, 2.02, 0.2, 0.29, 2.0, 0.15, -0.2, 1.8)
    vs = [1e-4] * 9
    assert akc._torso_outvotes(f, vs, m, 0)
    assert f[0:3] == pytest.approx([0.18 * 2.02 / 2.0, 0.0, 2.02]) and vs[2] == pytest.approx(R_Z)
    # our last output beyond the bound too: nothing to keep
    akc._prev[0] = (0.18, 0.0, 2.5, 0.2, 0.29, 2.5, 0.15, -0.2, 2.3)
    f = list(wall)
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 3.75
    # a reading within the bound (2.2 m) is never outvoted so, whatever our last output
    akc._prev[0] = (0.18, 0.0, 1.6, 0.2, 0.29, 1.6, 0.15, -0.2, 1.4)
    m[3 * LS : 3 * LS + 3] = [0.18 * 2.2 / 2.0, 0.0, 2.2]
    f = m[3 * LS : 3 * LS + 3] + [0.2, 0.29, 2.0] + [0.15, -0.2, 1.8]
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0) and f[2] == 2.2
    # shoulders far apart in the image (a wide angle) bound the depth far less: 3.75 m is then possible
    m[3 * LS : 3 * LS + 3] = [0.05 * 3.75, 0.0, 3.75]
    m[3 * RS : 3 * RS + 3] = [-0.05 * 3.75, 0.0, 3.75]
    f = list(wall)
    assert not akc._torso_outvotes(f, [1e-4] * 9, m, 0)


def _jump_frame(akc, p, left_z, right_z=2.0):
    """One frame of ``_shoulder_jumped`` for the left shoulder: the filter and the measurement agree (the filter
    followed), the left shoulder read at ``left_z`` on its pixel's ray; returns (held, the left shoulder after)."""
    q = p.copy()
    q[LS] *= left_z / q[LS, 2]
    q[RS] *= right_z / q[RS, 2]
    akc._v = _flat(q)
    m = _flat(q)
    f = _flat(q[[LS, LE, INDEX["left_wrist"]]])
    vs = [1e-4] * 9
    held = akc._shoulder_jumped(f, vs, m, 0, False)
    akc._shoulder_jumped(_flat(q[[RS, INDEX["right_elbow"], INDEX["right_wrist"]]]), [1e-4] * 9, m, 1, False)
    return held, f[0:3], vs[2]


def test_a_shoulder_depth_that_jumps_in_front_of_the_other_shoulders_is_held_until_it_agrees_again():
    akc, p = _corrector(), _pose()
    for _ in range(5):
        assert not _jump_frame(akc, p, 2.0)[0]
    assert akc._pair_z[0][:2] == [0.0, 0.0] and akc._pair_z[0][2] == 2.0
    # read 30 cm in front from one frame to the next, the other shoulder where it was: held at the other's depth
    # plus the learnt difference, on the measured pixel's ray, with the walk's variance
    for n in range(1, 4):
        held, s, v = _jump_frame(akc, p, 1.7)
        assert held and s == pytest.approx([0.18, 0.0, 2.0]) and akc._pair_z[0][1] == n
        assert v == pytest.approx(0.05**2 + 0.01**2 * n)
    # the reading back within the gate: the hold ends, the difference learns again
    held, s, _ = _jump_frame(akc, p, 2.01)
    assert not held and akc._pair_z[0][1] == 0.0 and akc._pair_z[0][0] == pytest.approx(0.2 * 0.01)
    # the walk's variance ends a long hold: the frame n held before is held while d^2 > 9 (R + (n + 1) v), d the
    # 30 cm plus the difference learnt (2 mm): 76 frames
    frames = 0
    while _jump_frame(akc, p, 1.7)[0]:
        frames += 1
    assert frames == math.floor((0.302**2 / 9.0 - 0.05**2) / 0.01**2) == 76


def test_a_shoulder_depth_that_jumps_behind_beyond_the_shoulder_width_is_held():
    # MediaPipe read a shoulder on the wall behind a landmark off the body's edge (bvhtools_b driven by the rig, 30
    # Hz: 1.6 m behind for three frames). No turn of the torso puts a shoulder farther from the other than the
    # shoulder width (36 cm here, its gate 22 cm): held at the other's depth plus the learnt difference, like a
    # jump in front. A depth behind within that reach is a torso that turns: kept.
    akc, p = _corrector(), _pose()
    for _ in range(5):
        assert not _jump_frame(akc, p, 2.0)[0]
    for n in range(1, 4):
        held, s, _ = _jump_frame(akc, p, 3.6)
        assert held and s == pytest.approx([0.18, 0.0, 2.0]) and akc._pair_z[0][1] == n
    held, s, _ = _jump_frame(akc, p, 2.01)
    assert not held and akc._pair_z[0][1] == 0.0
    for _ in range(5):
        _jump_frame(akc, p, 2.0)
    held, s, _ = _jump_frame(akc, p, 2.3)  # (30 cm behind: 49 cm from the other shoulder, within 36 + 22)
    assert not held and s[2] == pytest.approx(2.3)


def test_a_difference_without_a_jump_of_its_own_is_not_held():
    # The right shoulder read 25 cm in front for a long time (a hand over it): the left one's difference from it
    # learnt +25 cm. The hand leaves: the left shoulder, where it always was, is now 25 cm in front of that
    # difference, but its own depth did not jump: kept. Nor is a shoulder whose other one is itself held.
    akc, p = _corrector(), _pose()
    for _ in range(40):
        assert not _jump_frame(akc, p, 2.0, right_z=1.75)[0]
    assert akc._pair_z[0][0] == pytest.approx(0.25)
    assert not _jump_frame(akc, p, 2.0)[0]
    akc._pair_z[1][1] = 1.0  # the right shoulder held by the rule: no reference
    akc._pair_z[0][0] = 0.0
    assert not _jump_frame(akc, p, 1.7)[0]


def test_the_jump_rule_is_off_without_the_shoulder_hold_and_records_a_depth_another_rule_holds():
    akc, p = _corrector(sigma_shoulder_m=0.0), _pose()
    for _ in range(3):
        _jump_frame(akc, p, 2.0)
    assert not _jump_frame(akc, p, 1.7)[0]
    akc, p = _corrector(), _pose()
    m, f = _flat(p), _flat(p[[LS, LE, INDEX["left_wrist"]]])
    akc._v = _flat(p)
    assert akc._shoulder_jumped(f, [1e-4] * 9, m, 0, True)  # (held by another rule: True, f unchanged)
    assert f == _flat(p[[LS, LE, INDEX["left_wrist"]]]) and akc._pair_z[0][2:] == [2.0, 0.0]
    m[3 * LS + 2] = float("nan")
    assert not akc._shoulder_jumped(f, [1e-4] * 9, m, 0, False) and akc._pair_z[0][2:] == [2.0, 1.0]


@pytest.mark.parametrize("constrained", [False, True])
def test_after_an_ekf_a_long_blind_shoulder_counts_the_filter_no_surer_than_the_hold(constrained):
    # The left shoulder's depth dropped for 10 frames; the filter's has drifted 20 cm behind, claiming 1 cm. The hold
    # (2.0 m, its walk at 11 frames: 11e-4) and the filter fused by their variances: a KF's is believed (2.183 m);
    # after an EKF, blind beyond recent_frames (3), its variance counts no less than the hold's (2.1 m).
    akc, p = _corrector(constrained_filter=constrained), _pose()
    anchor = ((0.0, 0.5, 2.0), [0.18, -0.5, 0.0, 10.0])
    f = _flat(p[[LS, LE, INDEX["left_wrist"]]])
    f[2] = 2.2
    vs = [1e-4] * 9
    m = _flat(p)
    m[3 * LS + 2] = float("nan")  # the depth dropped, x and y measured
    m[3 * INDEX["left_wrist"]:3 * INDEX["left_wrist"] + 3] = [float("nan")] * 3
    assert akc._hold_on_torso(f, vs, m, 0, anchor)
    vh = 1e-4 * 11
    v = vh if constrained else 1e-4
    assert anchor[1][3] == 11.0 and f[:2] == pytest.approx([0.18, 0.0], abs=1e-12)  # (x, y measured: depth only)
    assert f[2] == pytest.approx((vh * 2.2 + v * 2.0) / (v + vh), abs=1e-12)
    assert f[2] == pytest.approx(2.1 if constrained else 2.1833, abs=1e-4)
    assert vs[2] == pytest.approx(v * vh / (v + vh), abs=1e-15)
