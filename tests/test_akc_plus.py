import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.core.akc_plus import STATE_SIZE, AKCPlusConfig, ArmKinematicCorrectorPlus
from akc_drake.core.skeleton import INDEX, BodyDimensions, segment_lengths

LS, RS, LE, RE, LW, RW = (INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
                                              "left_wrist", "right_wrist"))


def arm_pose(elbow_dir_l=(0.3, 0.5, -0.8), wrist_dir_l=(0.2, -0.3, -0.9)) -> tuple[np.ndarray, BodyDimensions]:
    """An exact operator facing the camera 2 m away, and its true dimensions."""
    p = np.zeros((12, 3))
    p[LS] = [0.18, 0.0, 2.0]
    p[RS] = [-0.18, 0.0, 2.0]
    for _side, (s, e, w), sign in ((0, (LS, LE, LW), 1.0), (1, (RS, RE, RW), -1.0)):
        de = np.array(elbow_dir_l) * [sign, 1, 1]
        dw = np.array(wrist_dir_l) * [sign, 1, 1]
        p[e] = p[s] + 0.29 * de / np.linalg.norm(de)
        p[w] = p[e] + 0.26 * dw / np.linalg.norm(dw)
    p[INDEX["left_hip"]] = [0.12, 0.5, 2.02]
    p[INDEX["right_hip"]] = [-0.12, 0.5, 2.02]
    for side in ("left", "right"):
        for k in ("index", "pinky"):
            p[INDEX[f"{side}_{k}"]] = p[INDEX[f"{side}_wrist"]] + [0.0, 0.05, -0.04]
    lens = segment_lengths(p[None])
    dims = BodyDimensions(**{k: float(v[0]) for k, v in lens.items()})
    return p, dims


def test_unoccluded_noise_free_arm_is_unchanged():
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(3):
        r = akc.correct(p, measured=p)
        np.testing.assert_allclose(r.pose, p, atol=1e-9, rtol=0)
    assert list(r.held) == [False, False]


def test_trusted_joint_keeps_its_position_and_lengths_are_exact():
    p, dims = arm_pose()
    noisy = p.copy()
    noisy[LE] += [0.004, -0.003, 0.01]  # a filtered elbow slightly off the circle
    r = ArmKinematicCorrectorPlus(dims).correct(noisy, measured=noisy)
    # The wrist and the (trusted) shoulder are unchanged; the elbow moves only onto the length circle.
    np.testing.assert_allclose(r.pose[[LS, LW]], noisy[[LS, LW]], atol=1e-12)
    assert np.linalg.norm(r.pose[LE] - noisy[LE]) < 0.012
    assert np.linalg.norm(r.pose[LE] - r.pose[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    assert np.linalg.norm(r.pose[LS] - r.pose[LE]) == pytest.approx(dims.LUA, abs=1e-12)


def test_lost_elbow_depth_is_rebuilt():
    p, dims = arm_pose()
    filt = p.copy()
    filt[LE, 2] += 0.25  # the filter's elbow depth is the occluding forearm's / a drift
    meas = p.copy()
    meas[LE, 2] = np.nan  # the occlusion filter dropped it
    r = ArmKinematicCorrectorPlus(dims).correct(filt, measured=meas)
    np.testing.assert_allclose(r.pose[LE], p[LE], atol=1e-9)


def test_candidate_choice_does_not_flip_on_a_tempting_sequence():
    # A still arm whose elbow depth is lost: the filter's elbow depth drifts towards, and past, the mirror
    # candidate (the other sign of eq. 7), as a constant-velocity KF extrapolating a lost depth does. The
    # paper's AKC with a strong m1 would follow it; AKC+ keeps the configuration (no evidence in the data).
    p, dims = arm_pose()
    r2 = dims.LLA**2 - np.sum((p[LE, :2] - p[LW, :2]) ** 2)
    mirror_z = p[LW, 2] - math.sqrt(r2)
    assert mirror_z < p[LE, 2]
    akc = ArmKinematicCorrectorPlus(dims)
    meas = p.copy()
    meas[LE, 2] = np.nan
    akc.correct(p, measured=p)
    zs = []
    for k in range(30):
        filt = p.copy()
        filt[LE, 2] = p[LE, 2] + (mirror_z - 0.05 - p[LE, 2]) * (k + 1) / 30  # drifts to beyond the mirror
        zs.append(akc.correct(filt, measured=meas).pose[LE, 2])
    np.testing.assert_allclose(zs, p[LE, 2], atol=1e-9)


def test_mirror_switch_happens_with_evidence():
    # The arm measured (seen, consistent depths) on the mirror side: a one-frame jump is an occluder's, but
    # evidence that persists for gate_frames frames and fits the arm's lengths is followed.
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p)
    q = p.copy()
    r2 = dims.LLA**2 - np.sum((p[LE, :2] - p[LW, :2]) ** 2)
    q[LE, 2] = p[LW, 2] - math.sqrt(r2)
    q[LS] = q[LE] + (p[LS] - p[LE]) * [1, 1, -1]
    first = akc.correct(q, measured=q).pose
    assert abs(first[LE, 2] - p[LE, 2]) < 1e-9  # not on a single frame
    for _ in range(int(akc.config.gate_frames) + 1):
        out = akc.correct(q, measured=q).pose
    np.testing.assert_allclose(out[LE], q[LE], atol=1e-9)


finite = st.floats(-3.0, 3.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None)
@given(st.lists(finite, min_size=36, max_size=36), st.lists(finite, min_size=36, max_size=36),
       st.booleans())
def test_arm_lengths_exact_for_any_finite_input(flat, flat_m, with_measurement):
    _, dims = arm_pose()
    pose = np.array(flat).reshape(12, 3)
    meas = np.array(flat_m).reshape(12, 3) if with_measurement else None
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(2):
        out = akc.correct(pose, measured=meas).pose
        for s, e, w, lu, lf in ((LS, LE, LW, dims.LUA, dims.LLA), (RS, RE, RW, dims.RUA, dims.RLA)):
            assert np.linalg.norm(out[e] - out[w]) == pytest.approx(lf, abs=1e-9)
            assert np.linalg.norm(out[s] - out[e]) == pytest.approx(lu, abs=1e-9)
            if meas is None:  # nothing seen: the wrist is the anchor (a seen shoulder may move it)
                np.testing.assert_array_equal(out[w], pose[w])


def test_missing_wrist_holds_and_state_round_trips():
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    first = akc.correct(p, measured=p).pose
    q = p.copy()
    q[LW] = np.nan
    r = akc.correct(q, measured=q)
    assert list(r.held) == [True, False]
    np.testing.assert_allclose(r.pose[[LS, LE, LW]], first[[LS, LE, LW]])
    v = akc.get_state_vector()
    assert v.shape == (STATE_SIZE,)
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    with pytest.raises(ValueError, match="shape"):
        other.set_state_vector(np.zeros(3))
    with pytest.raises(ValueError, match="consistency_m"):
        AKCPlusConfig(consistency_m=-1.0)
    with pytest.raises(ValueError, match="measured"):
        akc.correct(p, measured=np.zeros((3, 3)))


def test_seen_elbow_is_not_pulled_onto_a_lagging_filter_wrist():
    # Every joint measured; the filter's wrist lags 8 cm in depth (a constant-velocity KF on a fast hand).
    # The seen shoulder and elbow keep their positions; the wrist takes the length, its x, y kept.
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p)
    filt = p.copy()
    filt[LW, 2] += 0.08
    out = akc.correct(filt, measured=p).pose
    np.testing.assert_allclose(out[[LS, LE]], p[[LS, LE]], atol=1e-9)
    np.testing.assert_allclose(out[LW, :2], p[LW, :2], atol=1e-9)
    assert abs(out[LW, 2] - p[LW, 2]) < abs(filt[LW, 2] - p[LW, 2])
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_lost_shoulder_stays_with_a_filter_that_fits_the_lengths():
    # The shoulder's depth is lost for 60 frames while a wrong depth (the forearm's surface, 20 cm nearer)
    # is measured there; the filter holds the right depth, consistent with the arm's lengths. AKC+ stays with
    # the filter (no drift growth of its uncertainty, no switch to the mirror candidate), whatever the time.
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p)
    meas = p.copy()
    meas[LS, 2] -= 0.20
    for _ in range(60):
        out = akc.correct(p, measured=meas).pose
        np.testing.assert_allclose(out[[LS, LE, LW]], p[[LS, LE, LW]], atol=1e-9)
