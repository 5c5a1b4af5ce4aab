import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.core.akc_plus import STATE_SIZE, AKCPlusConfig, ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_config import HAND_TO_FOREARM
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
    hand = HAND_TO_FOREARM * 0.26  # (the knuckles a hand's length from the wrist: AKC+'s default for this forearm)
    for side in ("left", "right"):
        for k in ("index", "pinky"):
            p[INDEX[f"{side}_{k}"]] = p[INDEX[f"{side}_wrist"]] + [0.0, 0.05, -math.sqrt(hand**2 - 0.05**2)]
    lens = segment_lengths(p[None])
    dims = BodyDimensions(**{k: float(v[0]) for k, v in lens.items()})
    return p, dims


def hand_follows(f, p):
    """The left knuckles moved with ``f``'s left wrist off ``p``'s (the hand read with its wrist: nothing says the hand
    hides the wrist, :func:`~akc_drake.core.arm_geometry.behind_hand`). Returns ``f``."""
    for k in ("left_index", "left_pinky"):
        f[INDEX[k]] = p[INDEX[k]] + f[LW] - p[LW]
    return f


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


# ------------------------------------------------------------------ with the filter's covariance
def kf_var(xy=1e-5, z=1.5e-3) -> np.ndarray:
    """A steady-state KF posterior variance (x, y 3 mm, z 3.9 cm) for every coordinate."""
    v = np.full((12, 3), xy)
    v[:, 2] = z
    return v


def test_unoccluded_noise_free_arm_is_unchanged_with_the_covariance():
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(5):
        r = akc.correct(p, measured=p, variance=kf_var())
        np.testing.assert_allclose(r.pose, p, atol=1e-9, rtol=0)


def test_seen_joint_within_its_covariance_moves_only_along_its_uncertain_axis():
    # The filter's elbow is 3 cm off in depth (its sigma: 3.9 cm), the measurement agrees with the filter
    # (innovation test passed): the projection onto the lengths moves the elbow's depth back, the x, y of every
    # joint and the (surer) shoulder and wrist stay.
    p, dims = arm_pose()
    f = p.copy()
    f[LE, 2] += 0.03
    var = kf_var(xy=1e-7, z=1e-6)
    var[LE, 2] = 1.5e-3
    out = ArmKinematicCorrectorPlus(dims).correct(f, measured=f, variance=var).pose
    # (The landmark offsets' variance, 0.5 cm^2 per axis in the projection's metric, lets the others share < 1 mm.)
    np.testing.assert_allclose(out[[LS, LW]], p[[LS, LW]], atol=1e-3)
    np.testing.assert_allclose(out[LE], p[LE], atol=2e-3)
    assert np.abs(out[LE, :2] - f[LE, :2]).max() < 1e-3
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)


def test_lagging_filter_yields_to_a_consistent_measurement_but_not_to_an_outlier():
    # A fast hand: the filter's wrist lags 6 cm behind consistent measurements frame after frame; the running
    # NIS shows the filter's error above the measurement's, and the measured wrist is used: as read without
    # ``seen_depth_fusion``, fused with the filter by the readings' noise with it (the readings agree frame after
    # frame, so the fusion gives nearly the reading, nearer with every frame).
    p, dims = arm_pose()
    f = p.copy()
    f[LW, 2] += 0.06
    akc = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(seen_depth_fusion=False))
    for _ in range(10):
        out = akc.correct(f, measured=p, variance=kf_var()).pose
    np.testing.assert_allclose(out[LW], p[LW], atol=1e-9)
    np.testing.assert_allclose(out[LE], p[LE], atol=1e-6)
    akc = ArmKinematicCorrectorPlus(dims)
    err = [abs(akc.correct(f, measured=p, variance=kf_var()).pose[LW, 2] - p[LW, 2]) for _ in range(10)]
    assert err[1] < 0.002 and err[-1] < 1e-4 and all(b < a for a, b in zip(err, err[1:], strict=False))
    out = akc.correct(f, measured=p, variance=kf_var()).pose
    np.testing.assert_allclose(out[LE], p[LE], atol=1e-3)
    # An outlier (a depth 50 cm off: far outside the innovation test; deprojected, so the measured point moves
    # along the wrist's pixel ray) against a filter consistent with its measurements so far is not used.
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(10):
        akc.correct(p, measured=p, variance=kf_var())
    m = p.copy()
    m[LW] *= (p[LW, 2] + 0.5) / p[LW, 2]
    out = akc.correct(p, measured=m, variance=kf_var()).pose
    np.testing.assert_allclose(out[LW], p[LW], atol=1e-9)


def test_candidate_choice_does_not_flip_on_a_tempting_sequence_with_the_covariance():
    # The lost elbow depth's filter estimate drifts past the mirror candidate while its variance grows as a
    # blind KF's does: no flip.
    p, dims = arm_pose()
    r2 = dims.LLA**2 - np.sum((p[LE, :2] - p[LW, :2]) ** 2)
    mirror_z = p[LW, 2] - math.sqrt(r2)
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p, variance=kf_var())
    meas = p.copy()
    meas[LE, 2] = np.nan
    zs = []
    for k in range(30):
        filt = p.copy()
        filt[LE, 2] = p[LE, 2] + (mirror_z - 0.05 - p[LE, 2]) * (k + 1) / 30
        var = kf_var()
        var[LE, 2] = (0.04 + 0.03 * (k + 1)) ** 2
        zs.append(akc.correct(filt, measured=meas, variance=var).pose[LE, 2])
    np.testing.assert_allclose(zs, p[LE, 2], atol=1e-9)


def test_fold_test_is_a_finite_penalty_that_a_far_mirror_does_not_beat():
    # An elbow folded to 35 deg (below the 40 deg test; human flexion reaches ~30 deg) costs the same finite
    # penalty as m5's hyperextension (5 sigma squared), no veto: a candidate at the filter's estimate with it
    # still beats a mirror candidate 30 cm away (36 sigma squared at 5 cm).
    from akc_drake.core.arm_geometry import DEFAULT_AXES

    _, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    s, e = (0.18, 0.0, 2.0), (0.18, 0.29, 2.0)
    a = math.radians(35.0)
    w_fold = (0.18 + 0.26 * math.sin(a), 0.29 - 0.26 * math.cos(a), 2.0)
    w_bent = (0.18 + 0.26, 0.29, 2.0)
    pen_fold = akc._penalty(s, e, w_fold, 0.29, 0.26, DEFAULT_AXES)
    assert 0.0 < pen_fold < 100.0
    assert akc._penalty(s, e, w_bent, 0.29, 0.26, DEFAULT_AXES) == 0.0
    right, mirror = (0.2, 0.1, 1.80), (0.2, 0.1, 2.10)
    best, _ = akc._choose([right, mirror], 0.2, 0.1, 1.80, None, 0, extra=[pen_fold, 0.0])
    assert best == right


@settings(max_examples=100, deadline=None)
@given(st.lists(finite, min_size=36, max_size=36), st.lists(finite, min_size=36, max_size=36),
       st.lists(st.floats(1e-8, 1.0), min_size=36, max_size=36))
def test_arm_lengths_exact_for_any_finite_input_with_the_covariance(flat, flat_m, flat_v):
    _, dims = arm_pose()
    pose = np.array(flat).reshape(12, 3)
    meas = np.array(flat_m).reshape(12, 3)
    var = np.array(flat_v).reshape(12, 3)
    akc = ArmKinematicCorrectorPlus(dims)
    for _ in range(2):
        out = akc.correct(pose, measured=meas, variance=var).pose
        for s, e, w, lu, lf in ((LS, LE, LW, dims.LUA, dims.LLA), (RS, RE, RW, dims.RUA, dims.RLA)):
            assert np.linalg.norm(out[e] - out[w]) == pytest.approx(lf, abs=1e-9)
            assert np.linalg.norm(out[s] - out[e]) == pytest.approx(lu, abs=1e-9)


@given(st.lists(finite, min_size=36, max_size=36), st.lists(finite, min_size=36, max_size=36),
       st.lists(st.floats(1e-8, 1.0), min_size=36, max_size=36), st.floats(-0.05, 0.05))
def test_arm_lengths_exact_for_any_finite_input_with_a_remembered_surface(flat, flat_m, flat_v, dz):
    # The same with each elbow judged behind a surface last frame, read dz from this frame's reading
    # (``SurfaceMemory``: the verdict's paths, the radial elbow of a lost wrist, and the lost elbow's hold with
    # the filter as no evidence).
    _, dims = arm_pose()
    pose, meas, var = (np.array(x).reshape(12, 3) for x in (flat, flat_m, flat_v))
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(pose, measured=meas, variance=var)
    state = akc.get_state_vector()
    state[101:103] = meas[[LE, RE], 2] + dz
    rows = np.arange(12)[:, None]
    for m in (meas, np.where(rows == LE, np.nan, meas), np.where(rows == LW, np.nan, meas)):  # (elbow, wrist lost)
        akc.set_state_vector(state)
        out = akc.correct(pose, measured=m, variance=var).pose
        for s, e, w, lu, lf in ((LS, LE, LW, dims.LUA, dims.LLA), (RS, RE, RW, dims.RUA, dims.RLA)):
            assert np.linalg.norm(out[e] - out[w]) == pytest.approx(lf, abs=1e-9)
            assert np.linalg.norm(out[s] - out[e]) == pytest.approx(lu, abs=1e-9)


@pytest.mark.parametrize("z", [1.1754943508222875e-38, 2.2250738585072014e-308, 0.0, -0.5])
def test_a_depth_nearer_than_any_camera_reads_is_no_reading(z):
    # Found by the property tests above: a shoulder read at a subnormal depth, its x, y finite, put on its pixel's
    # ray by the torso's hold, went 1e37 m off (lengths lost, or the elbow's candidates all infinitely costly:
    # None). A depth nearer than MIN_DEPTH_M (1 cm) is no reading: the row counts as not measured.
    from akc_drake.core.arm_geometry import MIN_DEPTH_M

    assert MIN_DEPTH_M == 0.01
    _, dims = arm_pose()
    pose = np.zeros((12, 3))
    pose[[LS, LE, LW, RS, RE, RW], 2] = 1.0
    meas = np.zeros((12, 3))
    meas[RS] = [0.0, 1.0, z]
    outs = []
    for m in (meas, np.where(np.arange(12)[:, None] == RS, np.nan, meas)):
        akc = ArmKinematicCorrectorPlus(dims)
        for _ in range(2):
            out = akc.correct(pose, measured=m, variance=np.full((12, 3), 1e-4)).pose
        assert np.isfinite(out).all() and np.abs(out).max() < 10.0
        for s, e, w, lu, lf in ((LS, LE, LW, dims.LUA, dims.LLA), (RS, RE, RW, dims.RUA, dims.RLA)):
            assert np.linalg.norm(out[e] - out[w]) == pytest.approx(lf, abs=1e-9)
            assert np.linalg.norm(out[s] - out[e]) == pytest.approx(lu, abs=1e-9)
        outs.append(out)
    np.testing.assert_array_equal(outs[0], outs[1])  # (the same as the shoulder not measured at all)


def test_blind_extrapolation_is_held_but_a_holding_filter_is_followed():
    # The elbow lost altogether (no x, y, z) for 5 frames. A filter extrapolating its depth at 3 cm/frame
    # (variance growing past the measurement's) is not followed: our last output is held. A filter holding
    # the depth where it was last seen is followed.
    p, dims = arm_pose()
    meas = p.copy()
    meas[LE] = np.nan
    for drift, want_held in ((0.03, True), (0.0, False)):
        akc = ArmKinematicCorrectorPlus(dims)
        first = akc.correct(p, measured=p, variance=kf_var()).pose
        for k in range(5):
            filt = p.copy()
            filt[LE, 2] += drift * (k + 1)
            var = kf_var()
            var[LE] = [1e-4, 1e-4, (0.06 + 0.03 * k) ** 2]
            out = akc.correct(filt, measured=meas, variance=var).pose
        if want_held:
            np.testing.assert_allclose(out[LE, 2], first[LE, 2], atol=2e-3)
        else:
            np.testing.assert_allclose(out[LE], p[LE], atol=1e-9)


def test_dropped_shoulder_the_filter_knows_better_than_a_rebuild_is_kept():
    # The upper arm lies in the image plane and the shoulder's depth is dropped for a frame (the forearm in
    # front of it): the filter's shoulder is right, with a variance (5.2 cm) above the measurement's (5 cm).
    # The detected elbow sits 1 cm off towards the shoulder, so eq. 8 would rebuild the shoulder ~7 cm off in
    # depth; its variance from the in-plane geometry exceeds the filter's, so the filter's depth is kept.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, 0.0), wrist_dir_l=(0.2, -0.3, -0.9))
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p, variance=kf_var())
    filt = p.copy()
    filt[LE, :2] += 0.01 * (p[LS, :2] - p[LE, :2]) / np.linalg.norm(p[LS, :2] - p[LE, :2])
    meas = filt.copy()
    meas[LS, 2] = np.nan
    var = kf_var(xy=1e-4)
    var[LS, 2] = 0.052**2
    out = akc.correct(filt, measured=meas, variance=var).pose
    assert abs(out[LS, 2] - p[LS, 2]) < 0.01
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    # The same frame with a filter that is no surer than the rebuild (blind for long) and without the shoulder
    # held on the torso: rebuilt, not kept.
    akc2 = ArmKinematicCorrectorPlus(dims, NO_HELD_SHOULDER)
    akc2.correct(p, measured=p, variance=kf_var())
    var[LS, 2] = 0.5**2
    out2 = akc2.correct(filt, measured=meas, variance=var).pose
    assert abs(out2[LS, 2] - p[LS, 2]) > 0.03
    # With it (the default), one frame after the depth was seen: held at its offset from the hips' depth, 1 cm
    # against the filter's 50 cm, so the shoulder stays (the arm is projected: both depths known).
    akc3 = ArmKinematicCorrectorPlus(dims)
    akc3.correct(p, measured=p, variance=kf_var())
    out3 = akc3.correct(filt, measured=meas, variance=var).pose
    assert abs(out3[LS, 2] - p[LS, 2]) < 0.005
    assert np.linalg.norm(out3[LS] - out3[LE]) == pytest.approx(dims.LUA, abs=1e-12)


#: AKC+ without the shoulder held on the torso (the tests of what happens to a dropped shoulder without it).
NO_HELD_SHOULDER = AKCPlusConfig(sigma_shoulder_m=0.0)


def settled_corrector(p, dims, config=None):
    """A corrector that has seen the pose ``p`` measured exactly for five frames (its state settled on it)."""
    akc = ArmKinematicCorrectorPlus(dims, config)
    for _ in range(5):
        akc.correct(p, measured=p, variance=kf_var())
    return akc


def test_a_filter_whose_ray_the_detector_contradicts_yields_to_the_measurement():
    # An EKF's bone constraint moved a seen shoulder 10 cm in y (and its depth 25 cm) while the detector sees it
    # where it is: the filter's point, scaled to the measured depth, is off the measured ray by far more than
    # the image noise, so the measured shoulder replaces the filter's (and is kept: it is seen).
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    f = p.copy()
    f[LS, 1] += 0.10
    f[LS, 2] += 0.25
    out = akc.correct(f, measured=p, variance=kf_var()).pose
    np.testing.assert_allclose(out[LS], p[LS], atol=1e-9)
    # A depth read 25 cm short on the same ray (an occluder's surface) is not the joint's: the filter's stays.
    akc = settled_corrector(p, dims)
    m = p.copy()
    m[LS] *= (p[LS, 2] - 0.25) / p[LS, 2]
    out = akc.correct(p, measured=m, variance=kf_var()).pose
    assert abs(out[LS, 2] - p[LS, 2]) < 0.01


def test_a_wrist_lost_altogether_is_no_anchor():
    # The detector lost the wrist (no x, y) and the filter extrapolates it 20 cm off with a blind variance;
    # the shoulder's and elbow's depths were read 30 cm short along their rays (an occluder's: the innovation
    # test rejects them). The arm is built from the shoulder out: shoulder and elbow stay where the filter
    # has them (exact lengths already), only the wrist moves, onto the forearm length.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    f = p.copy()
    f[LW] += [0.10, 0.10, 0.15]
    var = kf_var()
    var[LW] = 0.3**2
    m = p.copy()
    m[LW] = np.nan
    for j in (LS, LE):
        m[j] *= (p[j, 2] - 0.3) / p[j, 2]
    out = akc.correct(f, measured=m, variance=var).pose
    np.testing.assert_allclose(out[LS], p[LS], atol=1e-9)
    np.testing.assert_allclose(out[LE], p[LE], atol=1e-9)
    assert abs(np.linalg.norm(out[LW] - out[LE]) - dims.LLA) < 1e-9
    # The wrist's prior: the filter's extrapolation fused with the forearm held at the elbow (its last output,
    # the elbow unmoved; variances 0.09 and, the first blind frame, sigma_temporal^2 = 0.01), moved onto the
    # forearm's length in its own metric (equal variances on the three axes: radially from the elbow).
    prior = (0.01 * f[LW] + 0.09 * p[LW]) / 0.1
    want = p[LE] + (prior - p[LE]) * dims.LLA / np.linalg.norm(prior - p[LE])
    np.testing.assert_allclose(out[LW], want, atol=1e-9)


def test_a_wrist_lost_beyond_the_arms_reach_is_no_anchor():
    # A frame of real motion (boxing driven bone by bone; the simulated detector, 10 Hz, after the KF), frame 246.
    # The right elbow and wrist have been lost altogether for frames and the right shoulder's depth reads the fist
    # 51 cm in front (held on the other shoulder). The KF extrapolates the wrist 1.25 m from the shoulder, out of any
    # arm's reach, with a smaller variance than the elbow's, lost longer: the wrist counted as the anchor and the arm
    # rebuilt from it moved the shoulder's detected x, y by 15 cm (y 13.6 cm off the truth, z 25). A wrist the arm
    # cannot reach from the shoulder is no anchor: the arm is built from the shoulder out.
    akc, dims, d = _recorded_frame("sim_boxing_rig_10hz_frame246.npz")
    truth, m, f = d["truth"], d["measured"], d["pose"]
    assert np.isnan(m[[RE, RW]]).all() and np.linalg.norm(f[RW] - f[RS]) > dims.RUA + dims.RLA + 0.5
    assert d["variance"][RW].max() < d["variance"][RE].min()
    out = akc.correct(f, m, d["variance"]).pose
    assert np.linalg.norm(out[RS, :2] - m[RS, :2]) < 0.05 and np.linalg.norm(out[RS] - truth[RS]) < 0.04
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_a_detected_wrist_beyond_the_kept_shoulders_reach_gets_the_straight_arm():
    # A frame of real motion seen from the side (cmu_01_03, the simulated detector, the camera 1 m to the side, 10
    # Hz, after the KF), frame 2. The clip starts in a T-pose; by frame 1 the right arm has swung 35 cm, the elbow's
    # reading is dropped and the KF holds it where it was. The wrist is detected, but the KF's wrist, lagging 5 cm in
    # y, is just beyond the arm's reach from the kept shoulder: no circle of elbows, and the wrist went onto the
    # forearm's sphere about the stale elbow, 25 cm off. Now the arm reaches straight for it: the wrist within 3 cm.
    akc, dims, d = _recorded_frame("sim_cmu_01_03_side_camera_10hz_frame2.npz")
    truth, m, f = d["truth"], d["measured"], d["pose"]
    assert np.isnan(m[RE]).all() and np.isfinite(m[RW]).all()
    assert np.linalg.norm(f[RW] - f[RS]) > dims.RUA + dims.RLA
    out = akc.correct(f, m, d["variance"]).pose
    assert np.linalg.norm(out[RW] - truth[RW]) < 0.03 and np.linalg.norm(out[RE] - truth[RE]) < 0.09
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_a_rebuilt_shoulder_is_fused_with_a_filter_of_the_same_configuration():
    # The upper arm near the image plane, the shoulder's depth dropped (not seen; the filter's estimate right
    # but with a blind sigma of 6 cm: no known depth) and the elbow's image position 1 cm off towards it. Eq. 8
    # from the elbow puts the shoulder 3.2 cm off in depth (the near-plane segment's leverage); the filter's arm
    # bends the same way, so the arm nearest it with the exact lengths is the estimate: 2.5 cm. (Without the
    # shoulder held on the torso, which would keep it within 0.3 cm: see the held-shoulder tests.)
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    akc = settled_corrector(p, dims, NO_HELD_SHOULDER)
    f = p.copy()
    f[LE, 1] -= 0.01
    m = f.copy()
    m[LS, 2] = np.nan
    var = kf_var()
    var[LS, 2] = 0.06**2
    out = akc.correct(f, measured=m, variance=var).pose
    assert 0.02 < out[LS, 2] - p[LS, 2] < 0.027
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def _dropped_shoulder_frame(p, step_m, shoulder_sigma_m):
    """One frame of an operator ``step_m`` nearer the camera than ``p`` whose left shoulder's depth was dropped: the
    filter holds the shoulder where it was (its depth's sigma ``shoulder_sigma_m``), its seen elbow is 2 cm deep of
    the truth and 1 cm towards the shoulder in the image. Returns (truth, filtered, measured, variance)."""
    truth = p.copy()
    truth[:, 2] -= step_m
    f = truth.copy()
    f[LS, 2] = p[LS, 2]  # the filter holds the dropped shoulder
    f[LE, 2] += 0.02
    f[LE, :2] += 0.01 * (p[LS, :2] - p[LE, :2]) / np.linalg.norm(p[LS, :2] - p[LE, :2])
    var = kf_var()
    var[LS, 2] = shoulder_sigma_m**2
    m = f.copy()
    m[LS, 2] = np.nan
    return truth, f, m, var


def test_a_dropped_shoulder_is_held_on_the_torso_and_moves_with_the_hips():
    # The shoulder's depth dropped for 30 frames (a hand across the chest) while the operator steps 1 cm/frame
    # towards the camera (hips, elbow and wrist seen). The filter holds the shoulder where it was with a variance
    # that grows as a constant-velocity model's (sigma 5 cm + 5 cm/frame); the seen elbow is 2 cm deep of the
    # truth and 1 cm towards the shoulder in the image: eq. 8 from it puts the shoulder 4-5.5 cm off. The held
    # shoulder (its last offset from the hips' depth, a random walk of 1 cm/frame) follows the hips.
    # (The elbow's forearm points at the camera here: its covered depth is off, ``forearm_radius_m`` 0, to show
    # the hold alone; its own test is further down.)
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    hips = [INDEX["left_hip"], INDEX["right_hip"]]
    results = {}
    for name, config in (("held", AKCPlusConfig(forearm_radius_m=0.0)),
                         ("not held", AKCPlusConfig(sigma_shoulder_m=0.0, forearm_radius_m=0.0))):
        akc = settled_corrector(p, dims, config)
        errs = []
        for k in range(1, 31):
            truth, f, m, var = _dropped_shoulder_frame(p, 0.01 * k, 0.05 + 0.05 * k)
            out = akc.correct(f, measured=m, variance=var).pose
            np.testing.assert_array_equal(out[hips], f[hips])
            assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
            errs.append(abs(out[LS, 2] - truth[LS, 2]))
        results[name] = np.array(errs)
    # eq. 8 from the elbow: 4-5.5 cm off in every frame; held: 0.4 cm after a frame, 1.3 cm after five, and
    # never worse (its prior's sigma grows as sqrt(n) cm: after 30 frames 5.5 cm, the rebuild's weight rises)
    assert results["not held"].min() > 0.04
    assert results["held"][0] < 0.005 and results["held"][4] < 0.015
    assert np.all(results["held"] < results["not held"])
    # the state carries the held offset and its frame count
    v = akc.get_state_vector()
    assert v.shape == (STATE_SIZE,)


def test_held_shoulder_state_round_trips_and_is_validated():
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    m = p.copy()
    m[LS, 2] = np.nan
    akc.correct(p, measured=m, variance=kf_var())
    v = akc.get_state_vector()
    held = v[70:78]
    # per side the shoulder minus the hips' centre (x, y, z: its depth 2.0 against the hips' 2.02) and the blind
    # frames: the left one blind for one frame, the right one seen
    np.testing.assert_allclose(held, [0.18, -0.5, -0.02, 1.0, -0.18, -0.5, -0.02, 0.0], atol=1e-12)
    other = ArmKinematicCorrectorPlus(dims)
    other.set_state_vector(v)
    np.testing.assert_array_equal(other.get_state_vector(), v)
    f = p.copy()
    f[LS, 2] += 0.3
    var = kf_var()
    var[LS, 2] = 1.0
    np.testing.assert_array_equal(akc.correct(f, measured=m, variance=var).pose,
                                  other.correct(f, measured=m, variance=var).pose)
    bad = v.copy()
    bad[73] = -1.0
    with pytest.raises(ValueError, match="held-shoulder frame count"):
        other.set_state_vector(bad)
    # With the hold off, a restored held offset is not used: the same output as without it in the state.
    off = ArmKinematicCorrectorPlus(dims, NO_HELD_SHOULDER)
    off_clean = ArmKinematicCorrectorPlus(dims, NO_HELD_SHOULDER)
    off.set_state_vector(v)
    clean = v.copy()
    clean[70:78] = np.nan
    off_clean.set_state_vector(clean)
    np.testing.assert_array_equal(off.correct(f, measured=m, variance=var).pose,
                                  off_clean.correct(f, measured=m, variance=var).pose)


def test_a_shoulder_lost_altogether_is_held_on_the_torso_not_where_the_filter_runs_off():
    # The detector loses the left shoulder altogether (no x, y, z) for 10 frames; the constant-velocity filter
    # runs off at the 2.7 cm/frame in x that its last, disturbed, measurements had (30 cm after ten frames: the
    # simulated detector on bvhtools_test 180-239 s), its variance growing. The elbow, the wrist and the hips are
    # seen and still. The shoulder held on the torso stays within 6 mm; without the hold (the filter's x, y and
    # eq. 8 from the elbow) it is 3 cm off after one frame and 22 cm after ten.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    results = {}
    for name, config in (("held", None), ("not held", NO_HELD_SHOULDER)):
        akc = settled_corrector(p, dims, config)
        errs = []
        for k in range(1, 11):
            f = p.copy()
            f[LS, 0] -= 0.027 * k
            f[LS, 1] += 0.009 * k
            var = kf_var()
            var[LS] = [(0.01 + 0.02 * k) ** 2, (0.01 + 0.02 * k) ** 2, (0.04 + 0.02 * k) ** 2]
            m = p.copy()
            m[LS] = np.nan
            out = akc.correct(f, measured=m, variance=var).pose
            assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
            errs.append(np.linalg.norm(out[LS] - p[LS]))
        results[name] = np.array(errs)
    assert results["held"].max() < 0.01
    assert results["not held"][4:].min() > 0.05
    np.testing.assert_array_less(results["held"], results["not held"])


def _hips_unseen(m):
    """``m`` with both hips' depths unmeasured (out of the image: the torso's reference is the other shoulder)."""
    m[[INDEX["left_hip"], INDEX["right_hip"]], 2] = np.nan
    return m


def _settled_without_the_hips(p, dims, frames=None, config=None):
    """A corrector that has seen the pose ``p`` measured exactly, but the hips' depths, for ``frames`` frames
    (default: as long as it takes the other shoulder to become the torso's reference, ``hips_lost_frames``)."""
    akc = ArmKinematicCorrectorPlus(dims, config)
    for _ in range(int(akc.config.hips_lost_frames) + 1 if frames is None else frames):
        akc.correct(p, measured=_hips_unseen(p.copy()), variance=kf_var())
    return akc


def test_a_shoulder_lost_altogether_is_held_on_the_other_shoulder_without_the_hips():
    # The hips out of the image (an operator at a desk): the shoulder held on the torso is carried by the other
    # shoulder, seen. The left shoulder is lost altogether for 10 frames while the filter runs off (2.7 cm/frame
    # in x) and the whole operator steps 1 cm/frame towards the camera; the held shoulder follows the right one.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    akc = _settled_without_the_hips(p, dims)
    errs = []
    for k in range(1, 11):
        truth = p.copy()
        truth[:, 2] -= 0.01 * k
        f = truth.copy()
        f[LS, 0] -= 0.027 * k
        var = kf_var()
        var[LS] = [(0.01 + 0.02 * k) ** 2, (0.01 + 0.02 * k) ** 2, (0.04 + 0.02 * k) ** 2]
        m = _hips_unseen(truth.copy())
        m[LS] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
        errs.append(np.linalg.norm(out[LS] - truth[LS]))
    assert max(errs) < 0.015  # (the filter: 2.7 to 27 cm off)
    # the offset from the other shoulder is part of the state
    b = ArmKinematicCorrectorPlus(dims)
    b.set_state_vector(akc.get_state_vector())
    np.testing.assert_array_equal(b.get_state_vector(), akc.get_state_vector())


def test_a_shoulder_depth_the_torso_and_the_elbow_contradict_is_an_occluders():
    # The left shoulder lost altogether for 20 frames (the filter holds it, its variance growing), then read 25 cm
    # in front (its own upper arm at its pixel) by a filter with no prior left, which follows the reading: the
    # reading passes the innovation test; the wrist is lost. The shoulder held on the torso (hips seen) and the
    # seen elbow both contradict it: the held depth replaces it on the pixel's ray and the elbow stays. Without the hold
    # (sigma_shoulder_m = 0) the reading is kept and the seen elbow is moved to it.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    out = {}
    for name, config in (("held", None), ("not held", NO_HELD_SHOULDER)):
        akc = settled_corrector(p, dims, config)
        for k in range(1, 21):
            var = kf_var()
            var[LS] = (0.02 * k) ** 2
            m = p.copy()
            m[LS] = np.nan
            akc.correct(p, measured=m, variance=var)
        f = p.copy()
        f[LS] *= (p[LS, 2] - 0.25) / p[LS, 2]  # on the shoulder's pixel ray, 25 cm in front
        var = kf_var()
        var[LS, 2] = 0.99 * 0.05**2  # (a posterior from no prior: the measurement's variance)
        m = f.copy()
        m[LW] = np.nan  # (the wrist lost: no two against one of the elbow and the wrist)
        out[name] = akc.correct(f, measured=m, variance=var).pose
        assert np.linalg.norm(out[name][LS] - out[name][LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out["held"][LS] - p[LS]) < 0.01
    assert np.linalg.norm(out["held"][LE] - p[LE]) < 0.005
    assert np.linalg.norm(out["not held"][LS] - p[LS]) > 0.05


def test_a_shoulder_lost_altogether_shares_the_misfit_with_a_seen_elbow():
    # The arm swings up 3 cm/frame and the whole operator leans 3 cm/frame towards the camera while the left
    # shoulder and the left wrist are lost altogether (the filter holds the shoulder; its wrist follows, uncertain).
    # The held shoulder stays behind (the hips are still), the seen elbow moves with the arm. The arm nearest both in
    # their metric keeps the elbow within 3.5 cm; keeping the held shoulder moved the seen elbow onto it (7-15 cm
    # off after the second frame).
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    akc = settled_corrector(p, dims)
    for k in range(1, 5):
        truth = p.copy()
        truth[[LS, RS, LE, LW, INDEX["right_elbow"], INDEX["right_wrist"]], 2] -= 0.03 * k
        truth[[LS, LE, LW], 1] += 0.03 * k
        f = truth.copy()
        f[LS] = p[LS]  # the filter holds the lost shoulder
        var = kf_var()
        var[LS] = (0.05 + 0.05 * k) ** 2
        var[LW] = (0.03 + 0.03 * k) ** 2
        m = truth.copy()
        m[[LS, LW]] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
        assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
        assert np.linalg.norm(out[LE] - truth[LE]) < 0.035


def _assert_the_dropped_shoulder_stays(akc, p, dims):
    """The left shoulder's depth dropped (the filter's held shoulder claims nothing) and a seen elbow 3 cm deep (eq. 8
    from it no better than the held shoulder): the held shoulder stays within 1 cm of its depth in ``p``."""
    f = p.copy()
    f[LE, 2] += 0.03
    m = f.copy()
    m[LS, 2] = np.nan
    var = kf_var()
    var[LS, 2] = 1.0
    out = akc.correct(f, measured=m, variance=var).pose
    assert abs(out[LS, 2] - p[LS, 2]) < 0.01
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)


def test_the_held_shoulder_does_not_learn_from_a_hip_the_camera_loses():
    # A hand hides the left hip: its depth is dropped for 10 frames while the filter runs it 3 cm/frame towards
    # the camera (its velocity from the hand's depth it had read). The shoulders are seen all the while; then the
    # left shoulder's depth is dropped too, the filter holding it where it was. The offsets from the hips are
    # learnt only from frames with both hips' depths measured, so the held shoulder stays at its depth (the
    # drifting hip taught it 11 cm: bvhtools_test 60-120 s, simulated detector).
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    LH = INDEX["left_hip"]
    akc = settled_corrector(p, dims)
    for k in range(1, 11):
        f = p.copy()
        f[LH, 2] -= 0.03 * k
        m = p.copy()
        m[LH, 2] = np.nan
        var = kf_var()
        var[LH, 2] = (0.04 + 0.02 * k) ** 2
        akc.correct(f, measured=m, variance=var)
    _assert_the_dropped_shoulder_stays(akc, p, dims)


def test_the_held_shoulder_does_not_learn_from_a_hip_read_on_the_wall():
    # The left hip's landmark slips off the body's edge: its pixel reads the wall 1.5 m behind for 5 frames, and a
    # filter without a gate follows it part of the way (60 %), then recovers over 5 frames. The shoulders are seen
    # throughout; then the left shoulder's depth is dropped, the filter holding it where it was. Those frames are
    # no torso reference (the hip's measurement fails the innovation test): the held shoulder stays at its depth.
    # Learnt from them, the held offset was 20 cm in front (bvhtools_a1 driven bone by bone, simulated detector).
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    LH = INDEX["left_hip"]
    akc = settled_corrector(p, dims)
    for k in range(10):
        f, m, var = p.copy(), p.copy(), kf_var()
        off = 0.9 if k < 5 else 0.9 * (1.0 - (k - 4) / 5.0)  # the filter's hip, metres behind the truth
        f[LH, 2] += off
        if k < 5:
            m[LH, 2] += 1.5
        var[LH, 2] = 0.04**2
        akc.correct(f, measured=m, variance=var)
    _assert_the_dropped_shoulder_stays(akc, p, dims)


def test_a_seen_shoulder_is_not_outvoted_by_an_elbow_that_fits_the_wrist_worse():
    # All three seen; the upper arm lies in the image plane. The detector's 2D elbow sits 6 cm short of the joint
    # towards the shoulder (MediaPipe: 5 cm on bvhtools_test 60-120 s) and the wrist reads 8 cm deep: the upper arm
    # is 6 cm short, the forearm 8 cm off. The elbow "fits" the wrist within length_tol_m, but worse than the
    # shoulder fits the elbow: two against one does not hold, the seen shoulder stays (eq. 8 from that elbow put
    # it 11 cm off). A 6 cm upper arm against a 5 mm forearm does not outvote it either: the rebuild lies behind
    # the reading, and nothing of the arm covers the shoulder's pixel (``arm_cover_deg``). With that test off
    # (90 degrees) it outvotes the shoulder, unless the shoulder's depth agrees with the shoulder held on the
    # torso (two against two): the hips' depths measured, or, without them for a second (out of the image), the
    # other shoulder seen.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.05), wrist_dir_l=(0.2, -0.3, -0.9))
    u = (p[LS, :2] - p[LE, :2]) / np.linalg.norm(p[LS, :2] - p[LE, :2])
    moved, off = {}, AKCPlusConfig(arm_cover_deg=90.0)
    for dwz, torso in ((0.08, "hips"), (0.0, None), (0.0, "none, test off"), (0.0, "hips"), (0.0, "other shoulder")):
        if torso == "hips":
            akc = settled_corrector(p, dims, off)
        else:  # (the hips lost for half a second: no reference yet; for a second: the other shoulder)
            akc = _settled_without_the_hips(p, dims, None if torso == "other shoulder" else 5,
                                            None if torso is None else off)
        f = p.copy()
        f[LE, :2] += 0.06 * u
        f[LW, 2] += dwz
        hand_follows(f, p)
        m = f.copy()
        if torso != "hips":
            m[[INDEX["left_hip"], INDEX["right_hip"]], 2] = np.nan
        out = akc.correct(f, measured=m, variance=kf_var()).pose
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
        assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
        moved[dwz, torso] = np.linalg.norm(out[LS] - f[LS])
    assert moved[0.08, "hips"] < 1e-9
    assert moved[0.0, None] < 1e-9
    assert moved[0.0, "none, test off"] > 0.1
    assert moved[0.0, "hips"] < 1e-9
    assert moved[0.0, "other shoulder"] < 1e-9


def test_a_wrist_lost_altogether_moves_with_the_seen_elbow():
    # The detector loses the wrist (no x, y) for 4 frames while the whole arm translates 2 cm/frame in x (the
    # elbow and the shoulder seen); the filter's wrist runs the other way, 3 cm/frame (a constant-velocity
    # extrapolation of a hand that turned), its blind sigma 10 cm/frame. The wrist's prior is the forearm held
    # at the seen elbow (4 frames: variance 4 sigma_temporal^2 = 0.04) times the filter's (0.16): weight 1/5 on
    # the filter's 20 cm error, 4 cm; the wrist moved +4 cm with the arm where the filter's moved -12.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    for k in range(1, 5):
        truth = p.copy()
        truth[[LS, LE, LW], 0] += 0.02 * k
        f = truth.copy()
        f[LW, 0] -= 0.05 * k
        var = kf_var()
        var[LW] = (0.1 * k) ** 2
        m = truth.copy()
        m[LW] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
    assert np.linalg.norm(f[LW] - truth[LW]) == pytest.approx(0.2)
    assert np.linalg.norm(out[LW] - truth[LW]) == pytest.approx(0.04, abs=0.005)
    assert out[LW, 0] - p[LW, 0] == pytest.approx(0.04, abs=0.005)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def _swing_with_the_wrist_lost(elbow_lost_at=None, frames=4, deg=6.0):
    """The left arm swings as one piece about its shoulder (6 deg per frame, about an axis across the upper arm) while
    the detector loses its wrist and hand altogether (no x, y); the shoulder and the elbow are seen (but the elbow in
    frame ``elbow_lost_at``). The filter holds the wrist where it was last seen, its blind sigma 10 cm per frame."""
    from scipy.spatial.transform import Rotation

    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    axis = np.cross(p[LE] - p[LS], [1.0, 0.0, 0.0])
    hand = [LW, INDEX["left_index"], INDEX["left_pinky"]]
    for k in range(1, frames + 1):
        truth = p.copy()
        turn = Rotation.from_rotvec(np.radians(deg * k) * axis / np.linalg.norm(axis))
        truth[[LE, *hand]] = p[LS] + turn.apply(p[[LE, *hand]] - p[LS])
        f = truth.copy()
        f[LW] = p[LW]
        var = kf_var()
        var[LW] = (0.1 * k) ** 2
        m = truth.copy()
        m[hand] = np.nan
        if k == elbow_lost_at:
            m[LE] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
    return akc, dims, out, truth, f


def test_a_wrist_lost_altogether_turns_with_its_swinging_upper_arm():
    # The held forearm turns with the upper arm since the wrist was last seen, so its prior at the seen elbow is the
    # true forearm: only the filter's share (variance 4 sigma_temporal^2 = 0.04 against its 0.16: 1/5) of the
    # filter's 19 cm error is left. Held fixed in the camera frame instead (the turn stopped by the elbow lost in
    # the first frame), the forearm lags the 24 deg swing and the wrist is 9 cm off.
    akc, dims, out, truth, f = _swing_with_the_wrist_lost()
    filter_error = np.linalg.norm(f[LW] - truth[LW])
    assert filter_error == pytest.approx(0.19, abs=0.005)
    assert np.linalg.norm(out[LW] - truth[LW]) == pytest.approx(filter_error / 5, abs=0.002)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    p, _ = arm_pose()  # (the upper arm when the wrist was last seen, which the forearm turns from)
    np.testing.assert_allclose(akc.get_state_vector()[78:81], p[LE] - p[LS], atol=1e-9)
    akc, _, out, truth, _ = _swing_with_the_wrist_lost(elbow_lost_at=1)
    assert np.linalg.norm(out[LW] - truth[LW]) > 0.08
    assert np.isnan(akc.get_state_vector()[78:81]).all()  # (the turn stops for the rest of this hold)


def test_an_elbow_lost_altogether_moves_with_the_seen_shoulder():
    # The detector loses the (right) elbow and the wrist (no x, y) for 4 frames while the whole arm translates
    # (2, 0, -3) cm/frame (the shoulder seen); the filter's elbow and wrist run off (-3, 4, -5) cm/frame, their blind
    # sigma 10 cm/frame. The elbow's prior is the upper arm held at the seen shoulder (4 frames: variance 0.04) times
    # the filter's (0.16), the wrist's the forearm held at that elbow: both stay near the arm (1.6 and 6.4 cm off).
    # Held on the filter's x, y instead (the depth alone held at our last output, as before), the elbow was 13 cm
    # off and the wrist 23.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    for k in range(1, 5):
        truth = p.copy()
        truth[[RS, RE, RW]] += np.array([0.02, 0.0, -0.03]) * k
        f = truth.copy()
        f[[RE, RW]] += np.array([-0.03, 0.04, -0.05]) * k
        var = kf_var()
        var[[RE, RW]] = (0.1 * k) ** 2
        m = truth.copy()
        m[[RE, RW]] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
    assert np.linalg.norm(f[RE] - truth[RE]) == pytest.approx(np.linalg.norm([0.12, 0.16, 0.2]))
    assert np.linalg.norm(out[RE] - truth[RE]) < 0.03
    assert np.linalg.norm(out[RW] - truth[RW]) < 0.08
    # The fused elbow is the elbow's prior in the candidate choice (not also held at our last output's depth, which
    # would leave the filter's prior out as an extrapolation).
    assert 2 not in akc._no_prior  # (the right elbow's key: the right arm is corrected last)
    np.testing.assert_allclose(out[RS], truth[RS], atol=1e-9)  # the seen shoulder kept
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_a_filter_counts_as_following_a_rejected_depth_only_if_it_moved_towards_it():
    # The upper arm points at the camera (shoulder within 8 cm of its elbow in the image: the shoulder's depth,
    # read 13 cm short, is rejected by our proximity rule; it passes the 3-sigma test, R = 25 cm^2, P = 1 cm^2).
    # A filter that moved 4 cm towards that depth since the shoulder was last seen followed it: no prior. One
    # that stayed (e.g. an EKF whose bone constraint holds it) did not: it stays the shoulder's prior.
    p, dims = arm_pose(elbow_dir_l=(0.05, 0.1, -1.0))
    ks = 3  # the right shoulder's key (the right arm is corrected last: its set is the one left)
    for moved, no_prior in ((0.04, True), (0.0, False)):
        akc = ArmKinematicCorrectorPlus(dims)
        var = kf_var(z=1e-4)
        akc.correct(p, measured=p, variance=var)
        m = p.copy()
        m[RS] *= (p[RS, 2] - 0.13) / p[RS, 2]
        f = p.copy()
        f[RS, 2] -= moved
        akc.correct(f, measured=m, variance=var)
        assert (ks in akc._no_prior) is no_prior


def _elbow_off_its_image_position(wrist_depth_measured):
    """Elbow depth dropped (a blind variance), its image position 7 cm off the true one and the wrist 3 cm off:
    no elbow at its image x, y closes the arm from the seen shoulder. Returns (truth, filtered, output, dims)."""
    p, dims = arm_pose()
    akc = ArmKinematicCorrectorPlus(dims)
    akc.correct(p, measured=p, variance=kf_var())
    f = p.copy()
    f[LE] += [0.004, 0.069, 0.0]
    f[LW] += [-0.031, 0.023, -0.008]
    m = hand_follows(f, p).copy()
    m[LE, 2] = np.nan
    if not wrist_depth_measured:
        m[LW, 2] = np.nan
    var = kf_var()
    var[LE, 2] = 0.25
    return p, f, akc.correct(f, measured=m, variance=var).pose, dims


def test_a_lost_elbow_goes_on_the_circle_between_the_kept_shoulder_and_the_measured_wrist():
    # The wrist measured in 3D: the shoulder and the wrist keep their positions exactly and the elbow goes on the
    # circle between them, off its image position: 1.4 cm from its true centre (its image position is 6.9 cm
    # off; moving the measured wrist instead carried the 2D error into the depths).
    p, f, out, dims = _elbow_off_its_image_position(wrist_depth_measured=True)
    np.testing.assert_allclose(out[LS], f[LS], atol=1e-12)
    np.testing.assert_allclose(out[LW], f[LW], atol=1e-12)
    assert np.linalg.norm(f[LE] - p[LE]) > 0.068
    assert np.linalg.norm(out[LE] - p[LE]) < 0.02
    assert abs(np.linalg.norm(out[LS] - out[LE]) - dims.LUA) < 1e-9
    assert abs(np.linalg.norm(out[LE] - out[LW]) - dims.LLA) < 1e-9


def test_a_lost_elbow_that_cannot_close_the_arm_at_its_image_position_moves_in_depth():
    # The wrist's depth not measured this frame: the correction is shared by the elbow and the wrist in the
    # filter's metric: both keep their image x, y (to 1 cm: the landmark offsets' variance lets the 7 cm off
    # elbow move 7 mm towards the shoulder; it moved 2.9 cm in x, y when the wrist alone followed) and the
    # depths, which the filter knows least, move.
    _, f, out, dims = _elbow_off_its_image_position(wrist_depth_measured=False)
    np.testing.assert_allclose(out[LS], f[LS], atol=1e-12)
    np.testing.assert_allclose(out[LE, :2], f[LE, :2], atol=1e-2)
    np.testing.assert_allclose(out[LW, :2], f[LW, :2], atol=1e-2)
    assert abs(np.linalg.norm(out[LS] - out[LE]) - dims.LUA) < 1e-9
    assert abs(np.linalg.norm(out[LE] - out[LW]) - dims.LLA) < 1e-9


def test_a_length_mismatch_near_the_image_plane_is_shared_with_the_landmarks_offsets():
    # The upper arm lies near the image plane (dz / l = 0.12) and the elbow's landmark sits 1 cm off its joint
    # centre towards the shoulder (a persistent landmark offset, which the filter's x, y variances do not
    # contain): the filter's upper arm is 1 cm short. The shoulder is seen (its depth agrees with the filter's),
    # the elbow's depth is not measured but known (filter variance within the measurement's), both variances a
    # few cm. Without the offsets in the projection's metric, the 1 cm of length went into the depth of the
    # joint the filter is least sure of, the seen shoulder: 2.8 cm off (the near-plane segment's leverage);
    # with them (variance length_sigma^2 / 2 per axis) the landmarks' x, y share it: 1.5 cm.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, 0.12))
    f = p.copy()
    d = (p[LS, :2] - p[LE, :2]) / np.linalg.norm(p[LS, :2] - p[LE, :2])
    f[LE, :2] += 0.01 * d
    m = f.copy()
    m[LE, 2] = np.nan
    var = kf_var(xy=0.005**2)
    var[LS, 2] = 0.045**2
    var[LE, 2] = 0.03**2
    out = ArmKinematicCorrectorPlus(dims).correct(f, measured=m, variance=var).pose
    assert abs(out[LS, 2] - p[LS, 2]) < 0.02
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_an_elbow_landmark_off_its_joint_takes_the_length_misfits_not_the_seen_shoulder():
    # The elbow's landmark sits 2.5 cm up the upper arm on every frame (MediaPipe's 2D elbow off the joint), the
    # arm swings slowly, every joint is seen and the filter follows the measurements: the upper arm reads 2.5 cm
    # short and the forearm long. Sharing the misfits equally moved the seen shoulder 0.9 cm; the elbow's offset,
    # learnt from the two misfits' product, takes them (the shoulder within 2 mm, the elbow within 3 mm).
    moved = {}
    for alpha in (AKCPlusConfig().elbow_offset_alpha, 0.0):
        akc = ArmKinematicCorrectorPlus(arm_pose()[1], AKCPlusConfig(elbow_offset_alpha=alpha))
        for k in range(60):
            a = 0.3 * math.sin(k / 5.0)
            p, _ = arm_pose(elbow_dir_l=(0.3, 0.9, -0.3 + a), wrist_dir_l=(0.25, 0.8, -0.5 + a))
            f = p.copy()
            f[LE] += 0.025 * (p[LS] - p[LE]) / np.linalg.norm(p[LS] - p[LE])
            out = akc.correct(f, measured=f, variance=kf_var(z=4e-4)).pose
        moved[alpha] = np.linalg.norm(out[LS] - p[LS]), np.linalg.norm(out[LE] - p[LE])
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(akc.dims.LUA, abs=1e-9)
    assert moved[0.05][0] < 0.002 and moved[0.05][1] < 0.003
    assert moved[0.0][0] > 0.007 and moved[0.0][1] > 0.008


def test_a_wrist_lost_altogether_is_pulled_back_from_the_filters_extrapolation():
    # The detector loses the wrist altogether for six frames; the hand has stopped, the KF runs on at 3 cm a
    # frame in x with its variance growing. The filter's wrist fused with our last output (the temporal prior)
    # before the arm is corrected: 10.8 cm off after six frames; the filter's alone, put at the forearm length
    # from the elbow, 13.8 cm.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    m = p.copy()
    m[LW] = np.nan
    for k in range(1, 7):
        f = p.copy()
        f[LW, 0] += 0.03 * k
        var = kf_var()
        var[LW] = (0.03 * k) ** 2 + 1e-4
        out = akc.correct(f, measured=m, variance=var).pose
        assert abs(np.linalg.norm(out[LW] - out[LE]) - dims.LLA) < 1e-9
    assert np.linalg.norm(out[LW] - p[LW]) < 0.12


def test_a_measured_depth_beyond_the_arms_reach_does_not_replace_the_filters():
    # The wrist's depth pixel reads the wall 1.4 m behind (a landmark off the body's edge), on the wrist's ray; a
    # filter that followed it 15 cm is off that ray, so the ray test would take the measurement for the truth
    # (the arm then rebuilt: the wrist 46 cm off). But the measured shoulder and elbow are over 1.2 m from it,
    # farther than the arm reaches: the filter's wrist stays (the arm corrected from it, within 2 cm).
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    m = p.copy()
    m[LW] *= (p[LW, 2] + 1.4) / p[LW, 2]
    f = p.copy()
    f[LW, 2] += 0.15
    out = akc.correct(f, measured=m, variance=kf_var()).pose
    assert np.linalg.norm(out[LW] - p[LW]) < 0.02
    assert np.linalg.norm(out[LE] - p[LE]) < 0.02
    np.testing.assert_allclose(out[LS], p[LS], atol=0.02)
    assert abs(np.linalg.norm(out[LE] - out[LW]) - dims.LLA) < 1e-9
    # The same depth read within the arm's reach (a filter 10 cm off the measured ray) still replaces it.
    akc = settled_corrector(p, dims)
    m = p.copy()
    f = p.copy()
    f[LW, 1] += 0.10
    f[LW, 2] += 0.20
    out = akc.correct(f, measured=m, variance=kf_var()).pose
    np.testing.assert_allclose(out[LW], p[LW], atol=1e-6)


def test_a_wrist_whose_measured_depth_is_rejected_is_no_anchor_for_the_seen_joints():
    # A KF that followed a depth read on the wall behind the wrist 90 cm of the way: the measured depth (1.4 m
    # behind) is beyond the arm's reach and the filter's fails the innovation test against it. Either is wrong
    # about the wrist; the seen shoulder and elbow are kept (before: the arm rebuilt from the filter's wrist, the
    # elbow 80 cm behind) and the wrist follows at the forearm's length.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims)
    m = p.copy()
    m[LW] *= (p[LW, 2] + 1.4) / p[LW, 2]
    f = p.copy()
    f[LW, 2] += 0.9
    out = akc.correct(f, measured=m, variance=kf_var()).pose
    np.testing.assert_allclose(out[LS], p[LS], atol=1e-9)
    np.testing.assert_allclose(out[LE], p[LE], atol=1e-6)
    assert abs(np.linalg.norm(out[LE] - out[LW]) - dims.LLA) < 1e-9
    np.testing.assert_allclose(out[RW], p[RW], atol=1e-9)  # the other arm untouched


def test_a_wrist_read_in_front_of_a_seen_elbow_that_fits_the_shoulder_takes_the_correction():
    # The forearm points towards the camera and the wrist's depth is read 15 cm in front (the hand over it), the
    # filter following: the forearm is 14 cm too long, the seen shoulder and elbow fit the upper arm. The nearer
    # end of a too-long segment is the likelier error (a depth camera reads occluders in front, rarely behind):
    # the elbow stays and the wrist goes back to the forearm's length (before: the elbow moved 3-6 cm with it).
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.9, -0.2), wrist_dir_l=(0.1, -0.3, -0.95))
    akc = settled_corrector(p, dims)
    f = p.copy()
    f[LW, 2] -= 0.15
    hand_follows(f, p)  # (the hand's own evidence that it hides the wrist: tested below)
    assert np.linalg.norm(f[LE] - f[LW]) > dims.LLA + 0.1
    out = akc.correct(f, measured=f.copy(), variance=kf_var()).pose
    np.testing.assert_allclose(out[[LS, LE]], p[[LS, LE]], atol=1e-9)
    np.testing.assert_allclose(out[LW], p[LW], atol=5e-4)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_shoulder_behind_its_foreshortened_upper_arm_does_not_count_as_seen():
    # The upper arm points at the camera (18 degrees off the line of sight, the elbow 9 cm from the shoulder in
    # the image): the shoulder's pixel shows the arm's surface, here 6 cm in front, the filter following. Not
    # seen (arm_radius_m), the shoulder is rebuilt from the seen elbow and wrist; counted as seen (the rule off),
    # the kept shoulder pulls the seen elbow 2.7 cm off.
    p, dims = arm_pose(elbow_dir_l=(0.1, 0.3, -0.95), wrist_dir_l=(0.2, -0.9, -0.3))
    assert np.linalg.norm(p[LS, :2] - p[LE, :2]) < 0.10
    f = p.copy()
    f[LS, 2] -= 0.06
    errs = {}
    for name, config in (("rule", None), ("off", AKCPlusConfig(arm_radius_m=0.0))):
        akc = settled_corrector(p, dims, config)
        out = akc.correct(f, measured=f.copy(), variance=kf_var()).pose
        errs[name] = np.abs(out[[LS, LE]] - p[[LS, LE]]).max()
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert errs["rule"] < 1e-6
    assert errs["off"] > 0.02
    # the same shoulder reading on an upper arm across the image (the elbow 15 cm away): the rule does not act
    q, dims = arm_pose(elbow_dir_l=(0.3, 0.5, -0.8))
    assert np.linalg.norm(q[LS, :2] - q[LE, :2]) > 0.15
    g = q.copy()
    g[LS, 2] -= 0.06
    outs = [settled_corrector(q, dims, c).correct(g, measured=g.copy(), variance=kf_var()).pose
            for c in (None, AKCPlusConfig(arm_radius_m=0.0))]
    np.testing.assert_array_equal(outs[0], outs[1])


def test_a_lost_elbow_guessed_in_front_does_not_unsee_its_shoulder():
    # The same upper arm pointing at the camera, then the detector loses the elbow, the wrist and the hand
    # altogether (no x, y) while the operator steps back 1 cm a frame; the shoulder is read at its true depth and
    # its filter follows 5 mm behind. The elbow's estimate (the upper arm held as last seen) stays in front of
    # the shoulder, foreshortened, but nothing measured it: it is no evidence that the shoulder's pixel reads the
    # arm, and the shoulder stays where its filter has it. (When the rule took the guess for evidence, the
    # shoulder was rebuilt from the lost joints and drifted 0.5 -> 2.1 cm off; on MediaPipe's boxing clip at 30
    # Hz, 47 cm.)
    p, dims = arm_pose(elbow_dir_l=(0.1, 0.3, -0.95), wrist_dir_l=(0.2, -0.9, -0.3))
    akc = settled_corrector(p, dims)
    lost = [LE, LW, INDEX["left_index"], INDEX["left_pinky"]]
    var = kf_var()
    var[lost] = 0.09
    for k in range(1, 6):
        truth = p.copy()
        truth[:, 2] += 0.01 * k
        m = truth.copy()
        m[lost] = np.nan
        f = p.copy()
        f[LS, 2] = truth[LS, 2] - 0.005
        out = akc.correct(f, measured=m, variance=var).pose
        np.testing.assert_allclose(out[LS], f[LS], rtol=0, atol=1e-9)
        assert out[LE, 2] < out[LS, 2] - 0.2  # (the held elbow still in front: the rule would have acted)
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)


def test_a_rebuilt_shoulder_is_weighed_against_the_held_torso_depth():
    # An operator leaning back: the shoulders 25 cm behind the hips' depth. The rebuilt shoulder's torso term is
    # the hips' depth plus our outputs' running-mean offset (the shoulder held on the torso), with the held
    # shoulder's variance; without the hold (sigma_shoulder_m = 0), the hips' depth with sigma_torso_m.
    p, dims = arm_pose(elbow_dir_l=(0.1, 0.3, -0.95), wrist_dir_l=(0.2, -0.9, -0.3))
    p[[INDEX["left_hip"], INDEX["right_hip"]], 2] = 1.75
    f = p.copy()
    f[LS, 2] -= 0.06  # read on the upper arm: not seen, rebuilt (as above)
    for config, target, inv_var in ((None, 2.0, 1.0 / 0.01**2),
                                    (NO_HELD_SHOULDER, 1.75, 1.0 / AKCPlusConfig().sigma_torso_m**2)):
        akc = settled_corrector(p, dims, config)
        out = akc.correct(f, measured=f.copy(), variance=kf_var()).pose
        assert akc._tz == pytest.approx(target, abs=1e-12)
        assert akc._inv_tz2 == pytest.approx(inv_var, rel=1e-12)
        np.testing.assert_allclose(out[LS], p[LS], atol=1e-6)


def test_a_wrist_its_own_hand_hides_is_put_behind_the_hand():
    # The forearm points at the camera (the elbow's depth dropped: its pixel is near the wrist's), the hand too:
    # the depth at the wrist's pixel is the hand's, at the knuckles' depth (8 cm in front), the filter following.
    # The knuckles are measured where they are: the wrist goes a hand's length behind them (hand_length_m = the
    # true one here), and the elbow on the circle from the kept shoulder to it. With the rule off, the elbow goes
    # to the wrist read in front and both are 5+ cm off.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.9, -0.2), wrist_dir_l=(0.1, -0.3, -0.95))
    d = np.array([0.1, -0.3, -0.95])
    c = p[LW] + 0.085 * d / np.linalg.norm(d)
    p[INDEX["left_index"]] = c + [0.02, 0.0, 0.0]
    p[INDEX["left_pinky"]] = c - [0.02, 0.0, 0.0]
    m = p.copy()
    m[LW] *= c[2] / p[LW, 2]  # (deprojected at the hand's depth: on the wrist's pixel ray)
    f = p.copy()
    f[LW] = m[LW]
    m[LE, 2] = np.nan
    var = kf_var()
    var[LE, 2] = 0.04
    err = {}
    for length in (0.085, 0.0):
        akc = settled_corrector(p, dims, AKCPlusConfig(hand_length_m=length))
        out = akc.correct(f, measured=m, variance=var).pose
        assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
        assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
        err[length] = np.linalg.norm(out[[LE, LW]] - p[[LE, LW]], axis=1)
    assert err[0.085].max() < 0.01
    assert err[0.0].min() > 0.05


def _held_shoulder_error(rate_hz, period_s, config=None):
    """The dropped shoulder of :func:`test_a_dropped_shoulder_is_held_on_the_torso_and_moves_with_the_hips`, as a
    motion in time sampled at ``rate_hz``: the operator steps 0.1 m/s towards the camera for 3 s, the filter's held
    shoulder's sigma grows 0.5 m/s; AKC+ built for frame period ``period_s`` (the elbow's covered depth off, as
    there). The shoulder's z error at 0.5, 1, 2 and 3 s."""
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.25))
    config = dataclasses.replace(config or AKCPlusConfig(), forearm_radius_m=0.0)
    akc = ArmKinematicCorrectorPlus(dims, config, period_s)
    for _ in range(int(round(rate_hz / 2))):  # (settled on the pose for 0.5 s)
        akc.correct(p, measured=p, variance=kf_var())
    errs = []
    for k in range(1, int(round(3 * rate_hz)) + 1):
        t = k / rate_hz
        truth, f, m, var = _dropped_shoulder_frame(p, 0.1 * t, 0.05 + 0.5 * t)
        errs.append(abs(akc.correct(f, measured=m, variance=var).pose[LS, 2] - truth[LS, 2]))
    n = int(round(rate_hz))
    return np.array([errs[n // 2 - 1], errs[n - 1], errs[2 * n - 1], errs[3 * n - 1]])


def test_per_frame_settings_follow_the_frame_period():
    # The same motion at 10 Hz and at 30 Hz: with the settings scaled to the period (the random walk of the held
    # shoulder per frame a third, its running mean's weight per frame smaller) the estimates at the same instants
    # are the same; with the 10 Hz values per frame, the held shoulder's prior widens three times as fast. The
    # running NIS's weight stays per frame (its noise is set by how many innovations it averages), so here it is
    # given the same time constant in seconds too.
    at_10 = _held_shoulder_error(10.0, 0.1)
    assert at_10.max() > 0.005  # (a test of something: eq. 8 from the biased elbow pulls the shoulder off)
    same_in_seconds = AKCPlusConfig(nis_alpha=1.0 - (1.0 - AKCPlusConfig().nis_alpha) ** (1.0 / 3.0))
    np.testing.assert_allclose(_held_shoulder_error(30.0, 1.0 / 30.0, same_in_seconds), at_10, atol=1e-9, rtol=0)
    assert np.abs(_held_shoulder_error(30.0, 1.0 / 30.0) - at_10).max() > 1e-3  # (the NIS per frame: sooner)
    assert np.abs(_held_shoulder_error(30.0, None) - at_10).max() > 0.01
    # None is the reference period, bit for bit.
    np.testing.assert_array_equal(_held_shoulder_error(10.0, None), at_10)
    with pytest.raises(ValueError, match="period_s"):
        ArmKinematicCorrectorPlus(arm_pose()[1], None, 0.0)


def test_a_shoulder_read_in_front_with_the_hips_is_held_on_the_other_shoulder():
    # A torso bending forward: from one frame to the next the left shoulder's pixel reads 30 cm in front (the head)
    # and the hips' pixels the belly, as far in front; the filter follows both; the left elbow and wrist are lost
    # altogether (below the image), the filter holding them. The shoulder held on the hips agrees with the reading;
    # the right shoulder, seen where it was, does not: the left one stays within 1 cm for 10 frames, the lengths
    # exact, and follows the reading again when it comes back. Without the shoulder hold (sigma_shoulder_m = 0)
    # the reading is kept, 30 cm off.
    p, dims = arm_pose()
    hips = [INDEX["left_hip"], INDEX["right_hip"]]
    for config, worst in ((None, 0.01), (NO_HELD_SHOULDER, 0.29)):
        akc = settled_corrector(p, dims, config)
        f = p.copy()
        f[LS] *= (p[LS, 2] - 0.3) / p[LS, 2]
        f[hips, 2] -= 0.3
        m = f.copy()
        m[[LE, LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan
        err = []
        for _ in range(10):
            r = akc.correct(f, measured=m, variance=kf_var())
            err.append(np.linalg.norm(r.pose[LS] - p[LS]))
            assert np.linalg.norm(r.pose[LS] - r.pose[LE]) == pytest.approx(dims.LUA, abs=1e-12)
        assert (max(err) < worst) if config is None else (min(err) > worst)
        if config is None:
            r = akc.correct(p, measured=p, variance=kf_var())
            assert np.linalg.norm(r.pose[LS] - p[LS]) < 1e-9 and akc._pair_z[0][1] == 0.0


def test_an_ekf_that_swings_a_seen_shoulder_each_frame_does_not_swing_the_lost_wrist():
    # The paper's per-joint EKF on mocapbank: its seen shoulder and elbow swing 25 cm behind, then in front, on
    # alternate frames, on their measured rays (no ray test catches them), while the detector reads them where they
    # are; the wrist is lost altogether. The measured depths agree with our last output against a filter that jumped
    # beyond the gate: they replace the filter's, and the held forearm, carried by them, stays within 6 cm (the
    # refit of an EKF's high-NIS coordinates takes over from the fourth frame). Carried by the filter's upper arm,
    # every joint was 25-39 cm off and the wrist moved 30-60 cm a frame.
    p, dims = arm_pose()
    akc = settled_corrector(p, dims, AKCPlusConfig(constrained_filter=True))
    prev_w = None
    for k in range(1, 7):
        f = p.copy()
        for j, dz in ((LS, 0.25), (LE, 0.3)):
            z = p[j, 2] + dz * (-1) ** k
            f[j] *= z / p[j, 2]
        var = kf_var()
        var[LW] = 1.0  # (the filter's extrapolation of the lost wrist: no evidence)
        m = p.copy()
        m[[LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
        assert max(np.linalg.norm(out[j] - p[j]) for j in (LS, LE, LW)) < (0.001 if k < 4 else 0.06)
        if prev_w is not None:
            assert np.linalg.norm(out[LW] - prev_w) < 0.08
        prev_w = out[LW]


def test_after_an_ekf_the_lengths_test_is_of_the_arm_as_measured():
    # MediaPipe's 2D wrist 6 cm off the joint towards the elbow (at the wrist's depth) reads the forearm 5 cm short;
    # an EKF's bone constraint moved the seen wrist 6.5 cm in depth until its forearm is 1 cm short, and that arm
    # passes the lengths' test. After an EKF the test is of the arm as measured, which fails it: the arm is rebuilt
    # from the seen shoulder, kept where it was read (a KF's posterior, which holds no lengths, is projected and
    # moves it 1.5 mm), and the wrist stays nearer its measured depth.
    p, dims = arm_pose(wrist_dir_l=(0.5, -0.75, -0.45))
    m = p.copy()
    d = p[LE, :2] - p[LW, :2]
    m[LW, :2] += 0.06 * d / np.linalg.norm(d)
    f = m.copy()
    dxy = np.linalg.norm(f[LW, :2] - f[LE, :2])
    f[LW, 2] = f[LE, 2] + math.copysign(math.sqrt((dims.LLA - 0.01) ** 2 - dxy**2), f[LW, 2] - f[LE, 2])
    for k in ("left_index", "left_pinky"):  # (the hand read with the wrist)
        m[INDEX[k]] += m[LW] - p[LW]
        f[INDEX[k]] += f[LW] - p[LW]
    assert dims.LLA - np.linalg.norm(m[LE] - m[LW]) > 0.05 and m[LW, 2] - f[LW, 2] > 0.06
    out = {}
    for constrained in (True, False):
        akc = settled_corrector(p, dims, AKCPlusConfig(constrained_filter=constrained))
        out[constrained] = akc.correct(f, measured=m, variance=kf_var(z=2e-4)).pose
        assert np.linalg.norm(out[constrained][LE] - out[constrained][LW]) == pytest.approx(dims.LLA, abs=1e-12)
    assert np.linalg.norm(out[True][LS] - p[LS]) < 1e-12 and np.linalg.norm(out[False][LS] - p[LS]) > 1e-3
    assert abs(out[True][LW, 2] - m[LW, 2]) < abs(out[False][LW, 2] - m[LW, 2]) - 0.005


def _elbow_read_in_front(elbow_dir_l, wrist_dir_l, elbow_front_m, wrist_behind_m):
    """An exact left arm (``arm_pose``), and its reading with the elbow that far in front and the wrist that far
    behind (the hand read with the wrist): ``(p, dims, f)``, ``f`` the filter's pose and the measurement."""
    p, dims = arm_pose(elbow_dir_l=elbow_dir_l, wrist_dir_l=wrist_dir_l)
    f = p.copy()
    f[LE, 2] -= elbow_front_m
    f[LW, 2] += wrist_behind_m
    return p, dims, hand_follows(f, p)


def _corrected_near_the_truth(p, dims, f, var):
    """A corrector settled on ``p`` corrects ``f`` (measured as read): the elbow within 2 cm of the truth, the wrist
    within 2.5, the lengths exact. Returns the pose."""
    out = settled_corrector(p, dims).correct(f, measured=f, variance=var).pose
    assert np.linalg.norm(out[LE] - p[LE]) < 0.02 and np.linalg.norm(out[LW] - p[LW]) < 0.025
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    return out

def test_a_seen_elbow_projected_in_front_of_its_reading_is_put_behind_it():
    # The elbow 9 cm behind the shoulder, the forearm toward the camera; the elbow read (and filtered) 15 cm in
    # front, on a surface before it, the wrist 4 cm behind: the forearm nearly parallel to the image plane, 8 cm
    # short. The projection tipped to the mirror (the elbow 23 cm in front of the truth, the wrist 7 cm behind);
    # a camera reads the first surface on the ray, so the elbow is put behind its reading, in the configuration
    # our last output had. With our last output's elbow in front, the mirror stays (no switch without evidence).
    p, dims, f = _elbow_read_in_front((-0.15, 0.94, 0.31), (-0.15, 0.6, -0.78), 0.15, 0.04)
    out = _corrected_near_the_truth(p, dims, f, kf_var())
    assert out[LE, 2] > f[LE, 2] + 0.1
    akc = settled_corrector(p, dims)
    state = akc.get_state_vector()
    state[5] = p[LE, 2] - 0.25  # (the left elbow's depth in our last output)
    akc.set_state_vector(state)
    out = akc.correct(f, measured=f, variance=kf_var()).pose
    assert out[LE, 2] < f[LE, 2] - 0.05


def test_a_projected_arm_whose_elbow_is_in_front_of_its_reading_takes_the_configuration_behind_it():
    # As above with a filter twice as unsure of the depths (7 cm): the arm passes the lengths' test and the whole arm
    # is projected (the shoulder too), tipping to the mirror (the elbow 21 cm in front of the truth, 5.3 in front of
    # its reading); the projection from the elbow's candidate behind the shoulder puts it within 2 cm of the truth.
    p, dims, f = _elbow_read_in_front((-0.2, 0.94, 0.43), (-0.07, 0.58, -0.41), 0.16, 0.05)
    out = _corrected_near_the_truth(p, dims, f, kf_var(z=5e-3))
    assert 0.005 < np.linalg.norm(out[LS] - p[LS]) < 0.015  # (projected with the arm, not kept)


def _lost_and_drifting(lost, joint):
    """The arm still, the detector losing ``lost`` altogether for 8 frames while the filter runs them on at 3 cm a
    frame in x claiming 7 cm on each axis: ``{constrained_filter: [joint's error per frame]}`` (lengths exact). The
    seen joints' depths are refitted as a KF's are (``seen_depth_sigma_m`` 0), so that the two differ in the holds
    alone."""
    p, dims = arm_pose()
    m = p.copy()
    m[lost] = np.nan
    err = {}
    for constrained in (True, False):
        akc = settled_corrector(p, dims, AKCPlusConfig(constrained_filter=constrained, seen_depth_sigma_m=0.0))
        err[constrained] = []
        for k in range(1, 9):
            f = p.copy()
            f[lost, 0] += 0.03 * k
            var = kf_var()
            var[lost] = 0.07**2
            out = akc.correct(f, measured=m, variance=var).pose
            err[constrained].append(np.linalg.norm(out[joint] - p[joint]))
            assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
            assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    return err

def test_after_an_ekf_a_long_lost_elbow_counts_the_filter_no_surer_than_the_held_upper_arm():
    # The elbow and the wrist lost altogether, the arm still; the EKF runs both on at 3 cm a frame in x, claiming
    # 7 cm. From the fourth frame the elbow's filter counts no surer than the upper arm held at the seen shoulder:
    # the eighth frame 11.0 cm off, not 17.1.
    err = _lost_and_drifting([LE, LW], LE)
    assert err[True][:3] == err[False][:3]
    assert err[False][7] == pytest.approx(0.171, abs=0.005) and err[True][7] == pytest.approx(0.110, abs=0.005)


def test_after_an_ekf_a_long_lost_wrist_counts_the_filter_no_surer_than_the_hold():
    # The hand stops while the detector loses it; an EKF's wrist runs on at 3 cm a frame in x, claiming 7 cm on
    # each axis (its bone constraints shrink the posterior of a joint nothing measures). For recent_frames (3)
    # frames its variance is believed, as a KF's; then it counts no surer than the forearm held at the seen elbow:
    # the eighth frame 10 cm off, not 16.
    err = _lost_and_drifting([LW], LW)
    assert err[True][:3] == err[False][:3]
    assert err[False][7] == pytest.approx(0.160, abs=0.005) and err[True][7] == pytest.approx(0.101, abs=0.005)


def recorded_state(d, seen_depth_sigma_m=None):
    """A recorded frame's state vector, extended to today's layout: a state recorded before the held forearms'
    misread frames were kept (103 floats) has none since each forearm was taken (0; NaN without one); one
    recorded before the depth reading noise was measured (105) has no residual and the noise assumed before any
    frame; one recorded before the elbow's offset was learnt (117) has its prior (AKC+'s reset)."""
    state = d["state"]
    if state.size == 103:
        state = np.concatenate([state, np.where(np.isfinite(state[[57, 61]]), 0.0, np.nan)])
    if state.size == 105:
        sd = AKCPlusConfig().seen_depth_sigma_m if seen_depth_sigma_m is None else seen_depth_sigma_m
        state = np.concatenate([state, [np.nan, sd**2] * 6])
    if state.size == 117:
        v0 = 0.5 * AKCPlusConfig().length_sigma_m**2
        state = np.concatenate([state, [0.5 * v0, 0.5] * 2])
    return state


def _recorded_frame(name, constrained_filter=False, **settings):
    """A frame of real data (tests/data/akc_plus/NAME: a MediaPipe evaluation clip's frame, after the KF, or after
    the EKF with ``constrained_filter``) and AKC+ in the state it had after the frames before: ``(corrector, dims,
    data)``; ``data`` holds ``pose``, ``measured``, ``variance`` (the corrector's inputs) and ``truth``. Recorded
    with ``get_state_vector`` while the evaluation ran; a state that grew since is extended with the new entries'
    values before any frame (``[101:103]``, the elbows' remembered readings: NaN; ``[103:105]``, the held forearms'
    misread frames: 0, or NaN without a held forearm; ``[105:117]``, no depth residual and the reading noise
    assumed), and a reordered one needs them recorded again."""
    d = np.load(Path(__file__).parent / "data" / "akc_plus" / name)
    dims = BodyDimensions(**dict(zip(("LUA", "LLA", "RUA", "RLA", "SW"), d["dims"].tolist(), strict=True)))
    akc = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=constrained_filter, **settings),
                                    period_s=1.0 / float(d["rate_hz"]))
    akc.set_state_vector(recorded_state(d, akc.config.seen_depth_sigma_m))
    return akc, dims, d


def test_a_wrist_lost_altogether_goes_radially_onto_the_forearm_sphere():
    # A frame of real data: MediaPipe's mocapbank clip (the skinned body, 30 Hz, after the KF), the first frame its
    # left wrist is lost altogether, with AKC+'s state after the frames before (tests/data/akc_plus). The wrist's
    # guess (the KF's extrapolation fused with the held forearm) falls 12 cm short of the forearm's length in the
    # image, and its variance in depth is five times that in x, y (the KF's, from before the loss). Put on the
    # forearm's sphere in that metric, the shortfall went into depth: the wrist 19 cm in front of the truth (22 cm
    # off in 3D; the KF's 14). Its x, y are guesses no better than its depth: moved radially, it is 7 cm off.
    akc, dims, d = _recorded_frame("mediapipe_mocapbank_30hz_frame104.npz")
    assert np.all(np.isnan(d["measured"][LW])) and np.all(np.isfinite(d["measured"][[LS, LE]]))
    out = akc.correct(d["pose"], d["measured"], d["variance"]).pose
    truth = d["truth"]
    assert np.linalg.norm(d["pose"][LW] - truth[LW]) == pytest.approx(0.138, abs=0.001)
    assert np.linalg.norm(out[LW] - truth[LW]) < 0.075
    assert abs(out[LW, 2] - truth[LW, 2]) < 0.075
    assert np.linalg.norm(out[[LS, LE]] - truth[[LS, LE]], axis=1).max() < 0.02  # (seen: MediaPipe's landmarks)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_after_an_ekf_a_seen_arm_keeps_the_depths_it_read():
    # A frame of real data: MediaPipe's mocapbank clip (the skinned body, 10 Hz, after the EKF), frame 40. The
    # right arm is seen whole, its three depths read within 1 cm of the joints; the EKF, lagging the arm as it
    # swings away and held by its bone constraints, has them 2.5, 3.5 and 4.2 cm off. MediaPipe's 2D wrist is 4 cm
    # off in y, so the arm as read has a forearm 5 cm short. Refitted by the running NIS (``seen_depth_sigma_m``
    # 0), the depths stayed near the EKF's and the projection put the shortfall into depth: the wrist 6.6 cm in
    # front. Fused with the EKF's at the reading noise the frames before measured (the right arm's stillest joint
    # 0.28 cm, recorded with the frame), the depths stay within 1.3 cm and the shortfall goes to the wrist's y.
    z_err = {}
    for sd in (0.015, 0.0):
        akc, dims, d = _recorded_frame("mediapipe_mocapbank_ekf_10hz_frame40.npz", True, seen_depth_sigma_m=sd)
        truth = d["truth"]
        assert np.abs(d["measured"][[RS, RE, RW], 2] - truth[[RS, RE, RW], 2]).max() < 0.01
        assert np.abs(d["pose"][[RS, RE, RW], 2] - truth[[RS, RE, RW], 2]).min() > 0.02
        out = akc.correct(d["pose"], d["measured"], d["variance"]).pose
        z_err[sd] = np.abs(out[[RS, RE, RW], 2] - truth[[RS, RE, RW], 2])
        assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
        assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)
    assert z_err[0.015].max() < 0.013
    assert z_err[0.0][2] > 0.06


def test_after_an_ekf_a_seen_depth_follows_the_reading_as_far_as_its_measured_noise_allows():
    # The frame above with the reading noise not yet measured (assumed 1.5 cm, as before any frame): against the
    # EKF's error the residuals showed before this frame, the reading weighs less and the shoulder's and elbow's
    # depths stay nearer the EKF's (2.5, 3.0 cm off, against its 2.5, 3.5); measured (0.28 cm), they follow the
    # readings (0.5, 1.2 cm off). The same state without the fusion (``seen_depth_fusion`` False) takes them as read.
    errs = {}
    for noise, fusion in ((None, True), (0.015, True), (0.015, False)):
        akc, dims, d = _recorded_frame("mediapipe_mocapbank_ekf_10hz_frame40.npz", True, seen_depth_fusion=fusion)
        state = akc.get_state_vector()
        assert np.sqrt(state[106::2]).min() == pytest.approx(0.0028, abs=1e-4)  # (the recorded right shoulder's)
        if noise is not None:
            state[105:117] = [np.nan, noise**2] * 6
            akc.set_state_vector(state)
        out = akc.correct(d["pose"], d["measured"], d["variance"]).pose
        errs[noise, fusion] = np.abs(out[[RS, RE], 2] - d["truth"][[RS, RE], 2])
    assert errs[None, True].max() < 0.013 and errs[0.015, False].max() < 0.013
    assert errs[0.015, True].min() > 0.02


def test_an_elbow_judged_behind_the_chest_stays_behind_it_once_its_wrist_is_lost():
    # A frame of real data: MediaPipe's bvhtools_a2 window (the skinned body, 10 Hz, after the EKF), frame 488. The
    # left elbow, 10 cm behind the shoulder with its pixel inside the torso's outline, has been read 18-19 cm in
    # front for two frames: the chest. With the wrist seen the arm's lengths contradicted the reading and AKC+ put
    # the elbow behind it (``behind_surface``); the state remembers the chest's depth. Now the wrist is lost
    # altogether and the EKF has followed the reading halfway: the elbow rebuilt radially towards it went 21 cm in
    # front, the wrist 16 cm. The verdict holds (the same surface, the body covers the pixel): within 7 cm.
    akc, dims, d = _recorded_frame("mediapipe_bvhtools_a2_window_ekf_10hz_frame488.npz", True)
    truth, m, state = d["truth"], d["measured"], recorded_state(d)
    assert np.isnan(m[LW]).all() and m[LE, 2] < truth[LE, 2] - 0.18 and abs(state[101] - m[LE, 2]) < 0.05
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert abs(out[LE, 2] - truth[LE, 2]) < 0.07 and abs(out[LW, 2] - truth[LW, 2]) < 0.02
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    assert akc.get_state_vector()[101] == m[LE, 2]  # (still judged behind this frame's reading)
    forgot = state.copy()
    forgot[101] = np.nan  # no memory: the old output
    akc.set_state_vector(forgot)
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert out[LE, 2] < truth[LE, 2] - 0.18 and out[LW, 2] < truth[LW, 2] - 0.12


def test_an_elbow_lost_after_an_occluders_reading_is_held_on_the_upper_arm_not_on_the_filter():
    # A frame of real data: MediaPipe's held-out cmu_01_06 clip with the camera 1 m to the side (the skinned body,
    # 10 Hz, after the KF), frame 180. The right arm, the far one, was behind the body for four frames and its
    # elbow read 30-41 cm in front; AKC+ kept it behind (the state remembers the reading), but the KF followed it.
    # Now the detector loses the elbow and the wrist altogether; the KF runs on 50 cm in front. Fused with it, the
    # elbow went 40 cm in front and the wrist with it; the filter that followed the occluder is no evidence, and
    # the upper arm held at the shoulder leaves them within 13 and 22 cm.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_06_side_camera_10hz_frame180.npz")
    truth, m, pose, state = d["truth"], d["measured"], d["pose"], recorded_state(d)
    assert np.isnan(m[[RE, RW]]).all() and np.isfinite(state[102]) and pose[RE, 2] < truth[RE, 2] - 0.45
    out = akc.correct(pose, m, d["variance"]).pose
    err = np.abs(out[[RE, RW], 2] - truth[[RE, RW], 2])
    assert err[0] < 0.13 and err[1] < 0.22
    assert akc.get_state_vector()[102] == state[102]  # (the memory stays through the loss)
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    forgot = state.copy()
    forgot[102] = np.nan
    akc.set_state_vector(forgot)
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.all(out[[RE, RW], 2] < truth[[RE, RW], 2] - 0.35)


def test_the_seen_wrist_anchor_keeps_a_measured_wrist_that_the_forearm_fit_would_move():
    # A frame of the teleop demo's pick-and-place (MediaPipe on the skinned body, seed 0, AKC+(KF) with the teleop
    # filter, t = 5.4 s): the right arm reaches down and towards the camera. MediaPipe's 2D elbow is 13 cm below
    # the joint, on the forearm, and reads its depth; the shoulder reads the upper arm 17 cm in front. The two fit
    # each other (the upper arm within 1 cm of its length) and the shoulder is kept as seen; the forearm measures
    # 11 cm against 27. Fitting the forearm in the filter's metric moved the seen wrist 10 cm down, and the robot's
    # tool went into the box. With ``seen_wrist_anchor`` (the teleop diagram's) the wrist stays where it was read
    # and the elbow goes on the circle between the kept shoulder and it.
    RS, RE, RW = 1, 3, 5
    off, dims, d = _recorded_frame("mediapipe_pick_place_seed0_teleop_10hz_frame54.npz")
    on, _, _ = _recorded_frame("mediapipe_pick_place_seed0_teleop_10hz_frame54.npz", seen_wrist_anchor=True)
    truth, m = d["truth"], d["measured"]
    assert np.all(np.isfinite(m[[RS, RE, RW]]))
    assert abs(np.linalg.norm(d["pose"][RE] - d["pose"][RW]) - dims.RLA) > 0.15  # (the forearm's misfit)
    a = off.correct(d["pose"], m, d["variance"]).pose
    b = on.correct(d["pose"], m, d["variance"]).pose
    assert np.linalg.norm(a[RW, :2] - m[RW, :2]) > 0.08 and np.linalg.norm(a[RW] - truth[RW]) > 0.10
    assert np.linalg.norm(b[RW, :2] - m[RW, :2]) < 0.01 and np.linalg.norm(b[RW] - truth[RW]) < 0.035
    for out in (a, b):  # (exact lengths either way; the shoulder kept)
        assert np.linalg.norm(out[RE] - out[RS]) == pytest.approx(dims.RUA, abs=1e-9)
        assert np.linalg.norm(out[RW] - out[RE]) == pytest.approx(dims.RLA, abs=1e-9)
        np.testing.assert_allclose(out[RS], d["pose"][RS], atol=1e-12)
    np.testing.assert_array_equal(a[[0, 2, 4]], b[[0, 2, 4]])  # (the other arm as it was)


def test_a_seen_shoulder_is_not_outvoted_into_a_rebuild_in_front_of_its_own_reading():
    # A frame of real data: MediaPipe's cmu_01_01 (the skinned body driven by the rig, 30 Hz, after the KF). The
    # left shoulder, elbow and wrist are all seen; the shoulder's depth reads 0.2 cm from the truth, but MediaPipe's
    # 2D landmarks put the upper arm 5.7 cm short in the image. The seen elbow fits the wrist better than the
    # shoulder fits the elbow (two against one), and eq. 8 from the elbow put the shoulder 17.5 cm in front of its
    # own reading. An occluder reads in front of a joint, never behind it: a rebuild in front contradicts the
    # reason to outvote the reading, and the shoulder is kept.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_01_rig_30hz_frame470.npz")
    truth, m = d["truth"], d["measured"]
    assert np.all(np.isfinite(m[[LS, LE, LW]]))
    assert abs(m[LS, 2] - truth[LS, 2]) < 0.005
    assert np.linalg.norm(m[LS, :2] - m[LE, :2]) < dims.LUA - 0.05  # (the upper arm short in the image)
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert abs(out[LS, 2] - truth[LS, 2]) < 0.02
    assert np.linalg.norm(out[[LS, LE]] - truth[[LS, LE]], axis=1).max() < 0.03
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)


def test_a_rebuild_in_front_of_a_seen_shoulder_is_judged_by_a_seen_readings_error():
    # A frame of real data: MediaPipe on bvhtools_a2's held-out window (the skinned body, 10 Hz, after the KF),
    # frame 52. The left shoulder's depth reads 1.2 cm from the truth; MediaPipe's 2D elbow is 6 cm off the joint and
    # the hip under the hand reads 21 cm in front, so the shoulder held on the torso disagrees with the reading too.
    # The seen elbow fits the wrist and outvotes the shoulder; eq. 8 from it puts the shoulder 12 cm in front of its
    # reading: inside the gate of the filter's R (15 cm), outside a seen reading's (the body's radius behind, where
    # the pixel is at the body's edge, plus 3 seen_depth_sigma_m: 9.5 cm). The shoulder is kept; the elbow, whose
    # x, y are off, takes the misfit (9.6 cm behind the joint on this frame: over the window, its z RMSE moved by
    # 0.05 cm, the shoulder's seen z by 0.4).
    akc, dims, d = _recorded_frame("mediapipe_bvhtools_a2_window_10hz_frame52.npz")
    truth, m = d["truth"], d["measured"]
    assert abs(m[LS, 2] - truth[LS, 2]) < 0.015 and np.linalg.norm(m[LE, :2] - truth[LE, :2]) > 0.05
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert abs(out[LS, 2] - truth[LS, 2]) < 0.015
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    akc, dims, d = _recorded_frame("mediapipe_bvhtools_a2_window_10hz_frame52.npz", seen_depth_sigma_m=0.0)
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert 0.10 < m[LS, 2] - out[LS, 2] < 0.15  # (the gate of R: the rebuild in front taken)


def test_a_wrist_that_reads_its_forearm_goes_behind_its_reading():
    # A frame of real motion held out of AKC+'s design (CMU subject 01, trial 06; the primitive body, the simulated
    # detector, 10 Hz, after the KF). The right forearm points away from the camera, nearly along the ray: the
    # wrist's pixel is 5 cm from the elbow's and reads the forearm's surface, 12 cm in front of the wrist, and the
    # occlusion filter dropped the elbow's depth. The circle between the seen shoulder and that wrist reading put
    # the elbow 12 cm off its image position in y. The wrist is then no anchor: the elbow goes from the shoulder at
    # its image x, y and the wrist at the forearm's length behind its reading (``behind_reading``).
    akc, dims, d = _recorded_frame("sim_cmu_01_06_10hz_frame346.npz")
    truth, m = d["truth"], d["measured"]
    assert np.isnan(m[RE, 2]) and np.all(np.isfinite(m[RE, :2])) and np.all(np.isfinite(m[[RS, RW]]))
    assert m[RW, 2] < truth[RW, 2] - 0.10  # (the forearm's surface)
    assert np.linalg.norm(m[RE, :2] - m[RW, :2]) < 0.3 * dims.RLA  # (the forearm along the ray)
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert np.linalg.norm(out[RE, :2] - m[RE, :2]) < 0.01
    assert np.linalg.norm(out[RE] - truth[RE]) < 0.03
    assert out[RW, 2] > m[RW, 2] and abs(out[RW, 2] - truth[RW, 2]) < 0.04
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_a_wrist_read_on_the_wall_behind_its_seen_elbow_is_no_anchor():
    # A frame of real motion held out of AKC+'s design (CMU subject 13, trial 26, driven bone by bone; MediaPipe on
    # the skinned body, 10 Hz, after the KF). The left wrist's pixel read the wall 1.7 m behind two frames running;
    # the KF followed the second (its depth variance 100 cm^2 against the seen elbow's 2.4). The upper arm points at
    # the camera, so the seen shoulder is no anchor (the proximity rule). Taken as the anchor, that wrist rebuilt the
    # whole arm on the wall: shoulder and elbow 1.4-1.7 m off. A wrist beyond its seen elbow's reach and known worse
    # than it is no anchor (``wrist_misfit``): the shoulder and the elbow stay where the filter has them.
    akc, dims, d = _recorded_frame("mediapipe_cmu_13_26_rig_10hz_frame19.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert np.all(np.isfinite(m[[LS, LE, LW]]))
    assert m[LW, 2] > truth[LW, 2] + 1.5 and pose[LW, 2] > pose[LE, 2] + dims.LLA + 1.0  # (the wall, followed)
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.linalg.norm(out[[LS, LE]] - truth[[LS, LE]], axis=1).max() < 0.04
    assert np.linalg.norm(out[[LS, LE]] - pose[[LS, LE]], axis=1).max() < 0.005
    assert out[LW, 2] < truth[LW, 2] + 0.3  # (off the wall: the forearm's length from the elbow)
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_an_elbow_whose_2d_position_no_depth_fits_goes_on_the_circle_nearest_its_x_y():
    # A frame of real motion held out of AKC+'s design (CMU subject 13, trial 26, driven bone by bone; MediaPipe on
    # the skinned body, 10 Hz, after the KF), frame 190. The left elbow's depth has been dropped since frame 185; the
    # shoulder and the wrist are seen. MediaPipe's 2D elbow is 3.6 cm short of the joint, so it lies farther from
    # the wrist's x, y than the forearm is long: eq. 7-8 give no depth from the wrist. The shoulder's two Pythagorean
    # depths are 18 cm either side of it, and the arm built from the one in front put the elbow 24.5 cm in front of
    # the truth. On the circle between the shoulder and the wrist, the points nearest its x, y (two here; one 22 cm
    # in front) are the candidates: within 5 cm.
    from akc_drake.core.arm_geometry import circle_xy_pair

    akc, dims, d = _recorded_frame("mediapipe_cmu_13_26_rig_10hz_frame190.npz")
    truth, m = d["truth"], d["measured"]
    assert np.isnan(m[LE, 2]) and np.isfinite(m[[LS, LW]]).all() and np.isfinite(m[LE, :2]).all()
    assert math.hypot(*(m[LE, :2] - m[LW, :2])) > dims.LLA  # (no depth at l_f from the wrist)
    pair = circle_xy_pair(*m[LW], *m[LS], dims.LLA, dims.LUA, *m[LE, :2])
    assert min(p[2] for p in pair) < truth[LE, 2] - 0.18  # (a mirror to choose against)
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert np.abs(out[LE] - truth[LE]).max() < 0.05
    assert np.abs(out[[LS, LW]] - truth[[LS, LW]]).max() < 0.04
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_seen_upper_arm_longer_in_the_image_than_its_length_shares_the_misfit_while_the_wrist_is_lost():
    # The upper arm near the image plane, the shoulder and the elbow seen, the wrist and the hand lost altogether. The
    # detector's shoulder sits 4 cm off the joint, away from the elbow: the two are 33 cm apart in x, y against a
    # 29 cm upper arm, so no depth closes the arm and one of the two x, y is off. Nothing (no wrist) tells which: the
    # arm nearest both in their metric shares the 4 cm, each 2 cm off, where keeping the seen shoulder moved the
    # elbow by the whole misfit (both 4 cm off).
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.05))
    akc = settled_corrector(p, dims)
    u = (p[LS, :2] - p[LE, :2]) / np.linalg.norm(p[LS, :2] - p[LE, :2])
    f = p.copy()
    f[LS, :2] += 0.04 * u
    m = f.copy()
    m[[LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan
    assert np.linalg.norm(m[LS, :2] - m[LE, :2]) > dims.LUA + 0.035
    out = akc.correct(f, measured=m, variance=kf_var()).pose
    for j in (LS, LE):
        assert np.linalg.norm(out[j] - p[j]) == pytest.approx(0.02, abs=0.002)
        assert abs(out[j, 2] - p[j, 2]) < 0.002  # (the misfit is in x, y: the depths stay)
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_recorded_upper_arm_longer_in_the_image_than_its_length_shares_the_misfit():
    # A frame of real motion (mocapbank driven bone by bone; MediaPipe on the skinned body, 10 Hz, after the KF),
    # frame 57. The left wrist has been lost altogether for 12 frames; MediaPipe's shoulder is 8 cm off the joint
    # in x, y, the elbow 2.3 cm: 31.6 cm apart in the image against a 29.4 cm upper arm. The seen shoulder kept, the
    # elbow moved radially 5.3 cm (8.3 cm off, the shoulder 8.9); the arm nearest both in their metric leaves each
    # 6.6 cm off.
    akc, dims, d = _recorded_frame("mediapipe_mocapbank_rig_10hz_frame57.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert np.isnan(m[LW]).all() and np.isfinite(m[[LS, LE]]).all()
    assert np.linalg.norm(m[LS, :2] - m[LE, :2]) > dims.LUA + 0.02
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.linalg.norm(out[LS] - truth[LS]) < 0.07 and np.linalg.norm(out[LE] - truth[LE]) < 0.07
    assert np.linalg.norm(out[LS] - pose[LS]) > 0.02  # (the seen shoulder took part of the misfit)
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_wrist_misread_before_it_is_lost_is_not_the_forearm_held():
    # The arm hangs in the image plane. On the frame before the detector loses the wrist altogether it reads the
    # wrist 8 cm short in 2D and 6 cm in front (a hand going behind the body: MediaPipe on bvhtools_c, 7 cm and 11
    # cm), a 20 cm forearm against 26 while the upper arm fits: the wrist is the odd one out. The arm output there
    # makes the forearm's length up in depth, 7 cm in front. Held from that output, the lost wrist stayed 6-9 cm off
    # over the next five frames; held from the frame before, it came back to within 2.5 cm with the filter's
    # extrapolation, 5 cm in front, fused. The filter took the misread, so it is left out: the hold alone, exact.
    p, dims = arm_pose(elbow_dir_l=(0.3, 0.95, -0.05), wrist_dir_l=(0.1, 0.95, -0.1))
    akc = settled_corrector(p, dims)
    u = (p[LE, :2] - p[LW, :2]) / np.linalg.norm(p[LE, :2] - p[LW, :2])
    m = p.copy()
    m[LW, :2] += 0.08 * u
    m[LW, 2] -= 0.06
    hand_follows(m, p)
    f = p.copy()
    f[LW] += 0.5 * (m[LW] - p[LW])
    assert np.linalg.norm(m[LE] - m[LW]) < dims.LLA - 0.05 and np.linalg.norm(m[LS] - m[LE]) == pytest.approx(dims.LUA)
    out = akc.correct(f, measured=m, variance=kf_var()).pose
    assert out[LW, 2] < p[LW, 2] - 0.06
    for k in range(1, 6):
        f = p.copy()
        f[LW, 2] -= 0.05
        var = kf_var()
        var[LW] = (0.05 * k) ** 2
        m = p.copy()
        m[[LW, INDEX["left_index"], INDEX["left_pinky"]]] = np.nan
        out = akc.correct(f, measured=m, variance=var).pose
        assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
        assert np.linalg.norm(out[LW] - p[LW]) < 1e-9


def test_a_wrist_lost_after_misread_frames_is_held_without_the_filter_that_took_them():
    # A frame of real data: MediaPipe's mocapbank clip (the skinned body, 10 Hz, after the KF), the second frame its
    # left wrist is lost altogether, with AKC+'s state after the frames before. On the three frames before the loss
    # MediaPipe read the wrist with a forearm of 17-23 cm against 28.1 while the upper arm fitted: misread, so the
    # held forearm is the one from before them (state [103]: 3 misread frames). The KF took those readings and
    # extrapolates their error, 19 cm off; the lost wrist is the hold alone, 3.5 cm off. The same state with the
    # misread frames forgotten fuses the hold with that KF: 27 cm off.
    akc, dims, d = _recorded_frame("mediapipe_mocapbank_10hz_frame37.npz")
    truth, m, pose, var = d["truth"], d["measured"], d["pose"], d["variance"]
    assert np.all(np.isnan(m[LW])) and np.all(np.isfinite(m[[LS, LE]])) and d["state"][103] == 3.0
    assert np.linalg.norm(pose[LW] - truth[LW]) > 0.18
    out = akc.correct(pose, m, var).pose
    assert np.linalg.norm(out[LW] - truth[LW]) < 0.04
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)
    forgot = recorded_state(d).copy()
    forgot[103] = 0.0
    akc.set_state_vector(forgot)
    out = akc.correct(pose, m, var).pose
    assert np.linalg.norm(out[LW] - truth[LW]) > 0.25


def test_a_filter_that_followed_a_rejected_depth_is_no_prior_for_the_elbow():
    # A frame of a held-out motion (CMU subject 05, trial 11, driven bone by bone; the simulated detector on the
    # skinned body, 30 Hz, after the KF), frame 29. The left arm reaches back, the elbow 23 cm behind the shoulder;
    # its pixel reads an occluder 1.08 m in front (the 2D 18 cm off too), and the shoulder is lost altogether. The
    # innovation test rejects the reading, but the KF, which has no gate, followed it 30 cm, with a 4 cm variance;
    # as the prior it chose the elbow candidate in front, 53 cm in front of the truth, against our last output and
    # the wrist. A filter that followed a rejected depth is no evidence (``followed_rejected``): within 2 cm.
    akc, dims, d = _recorded_frame("sim_cmu_05_11_rig_30hz_frame29.npz")
    truth, m, pose, state = d["truth"], d["measured"], d["pose"], recorded_state(d)
    assert m[LE, 2] < truth[LE, 2] - 1.0 and pose[LE, 2] < state[5] - 0.25 and np.isnan(m[LS]).all()
    out = akc.correct(pose, m, d["variance"]).pose
    assert abs(out[LE, 2] - truth[LE, 2]) < 0.02 and np.linalg.norm(out[LE] - truth[LE]) < 0.10
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_an_elbow_read_on_its_own_forearm_does_not_carry_a_held_shoulder_in_front():
    # A frame of real data: MediaPipe's bvhtools_a4 window (the skinned body, 10 Hz, after the KF), frame 558. The
    # left arm reaches towards the camera: the upper arm points at it (the shoulder's depth is dropped by the
    # proximity rule and held on the torso, 4.4 cm sd) and so does the forearm, whose surface the elbow's pixel reads
    # 3.6 cm in front of the joint, a depth the running NIS believed to 0.4 cm. The projection onto the exact lengths
    # put the misfit into the held shoulder, 4.7 cm in front; the KF holds it 0.3 cm off. The elbow's depth may be
    # ``covered_excess`` nearer (its forearm at ~25 degrees to the line of sight): with that variance the shoulder
    # is 2.1 cm off in depth and the elbow within 0.5 cm.
    akc, dims, d = _recorded_frame("mediapipe_bvhtools_a4_window_10hz_frame558.npz")
    truth, m = d["truth"], d["measured"]
    assert np.isnan(m[LS, 2]) and m[LW, 2] < m[LE, 2] - 0.2 and m[LE, 2] < truth[LE, 2] - 0.03
    out = akc.correct(d["pose"], m, d["variance"]).pose
    assert abs(out[LS, 2] - truth[LS, 2]) < 0.025 and abs(out[LE, 2] - truth[LE, 2]) < 0.005
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_seen_elbow_is_not_moved_to_a_shoulder_its_own_reading_contradicts():
    # A frame of real motion held out of AKC+'s design (CMU subject 01, trial 06, driven bone by bone; MediaPipe on
    # the skinned body, 10 Hz, after the KF). The left shoulder's pixel read the wall for six frames; the KF followed
    # and lags 90 cm behind now that the reading is back on the body, so the reading fails its innovation test.
    # The wrist is lost altogether (no anchor), which used to keep that lagging shoulder and move the seen elbow,
    # 2 cm from its reading, 85 cm back to the upper arm's length from it. The seen elbow is the anchor now.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_06_rig_10hz_frame368.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert np.all(np.isnan(m[LW])) and np.all(np.isfinite(m[[LS, LE]]))
    assert pose[LS, 2] > m[LS, 2] + 0.5 and abs(pose[LE, 2] - m[LE, 2]) < 0.03  # (the lagging shoulder)
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.linalg.norm(out[LE] - pose[LE]) < 1e-9  # (the seen elbow kept)
    assert abs(out[LS, 2] - truth[LS, 2]) < 0.06 and np.linalg.norm(out[LE] - truth[LE]) < 0.05
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_shoulders_read_beyond_the_shoulder_widths_bound_keep_our_last_output():
    # A frame of real motion held out of AKC+'s design (CMU subject 01, trial 06, driven bone by bone; MediaPipe on
    # the skinned body, 30 Hz, after the KF). Both shoulders read the wall at 3.5 m (the truth 1.8 m), the KF has
    # followed the left one, the hips are no reference (their filter lags) and the left elbow and wrist are lost.
    # The angle between the shoulders' rays bounds their range to (SW + consistency_m) / sin t, 2.9 m here: the
    # left shoulder stays on its ray at our last output's depth, and the arm is not rebuilt on the wall.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_06_rig_30hz_frame665.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert m[LS, 2] > truth[LS, 2] + 1.5 and m[RS, 2] > truth[RS, 2] + 1.5 and pose[LS, 2] > 3.5
    assert np.all(np.isnan(m[[LE, LW]]))
    u, v = m[LS] / np.linalg.norm(m[LS]), m[RS] / np.linalg.norm(m[RS])
    bound = (dims.SW + 0.05) / np.linalg.norm(np.cross(u, v))
    assert truth[LS, 2] < bound < m[LS, 2]
    out = akc.correct(pose, m, d["variance"]).pose
    assert out[LS, 2] < bound and np.linalg.norm(out[LS] - truth[LS]) < 0.6  # (the KF's: 2.0 m)
    assert out[LS, :2] / out[LS, 2] == pytest.approx(m[LS, :2] / m[LS, 2], abs=1e-9)  # (on the measured ray)
    assert np.linalg.norm(out[[LE, LW]] - truth[[LE, LW]], axis=1).max() < 0.2
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_shoulder_read_behind_its_elbow_beyond_the_upper_arm_is_no_arm_surface():
    # A frame of real motion (CMU subject 01, trial 03, driven bone by bone; MediaPipe on the skinned body, 10 Hz,
    # after the KF). The right forearm crosses in front of the elbow: its depth reads 31 cm in front, and the KF has
    # followed it. The upper arm points towards the camera, so our proximity rule doubted the shoulder's reading
    # (the arm's surface?), and the shoulder was rebuilt from that elbow, 26 cm in front of the truth. Read 54 cm
    # behind the elbow, farther than the upper arm reaches, it is no surface of that arm: the shoulder is kept.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_03_rig_10hz_frame115.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert np.all(np.isnan(m[RW])) and truth[RE, 2] - m[RE, 2] > 0.3 and abs(m[RS, 2] - truth[RS, 2]) < 0.005
    assert m[RS, 2] - pose[RE, 2] > dims.RUA + 0.05
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.linalg.norm(out[RS] - pose[RS]) < 1e-9  # (kept: the old rule put it at 1.36, truth 1.63)
    assert abs(out[RE, 2] - truth[RE, 2]) < 0.06  # (the filter's elbow: 30 cm in front)
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


@pytest.mark.parametrize("cover_deg, kept", [(37.0, True), (90.0, False)])
def test_a_seen_shoulder_is_outvoted_only_where_its_own_arm_can_cover_its_pixel(cover_deg, kept):
    # A frame of real motion (CMU subject 01, trial 03, driven bone by bone; MediaPipe on the skinned body, 10 Hz,
    # after the KF). Shoulder, elbow and wrist are all seen, the shoulder within 0.3 cm of the truth; MediaPipe's
    # 2D elbow lies 6 cm short of the joint, so the upper arm is 7 cm short and the forearm fits. Two against one
    # rebuilt the shoulder 17 cm behind. But the upper arm lies 49 degrees from the line of sight and the forearm
    # passes 21 cm from the shoulder's pixel: nothing of the arm covers it, and the reading stays
    # (``arm_cover_deg``; 90 turns the test off and shows the old rebuild).
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_03_rig_10hz_frame213.npz")
    akc = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=False, arm_cover_deg=cover_deg),
                                    period_s=1.0 / float(d["rate_hz"]))
    akc.set_state_vector(recorded_state(d))
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert np.all(np.isfinite(m[[RS, RE, RW]])) and abs(m[RS, 2] - truth[RS, 2]) < 0.005
    out = akc.correct(pose, m, d["variance"]).pose
    if kept:
        assert np.linalg.norm(out[RS] - pose[RS]) < 1e-9
        assert np.linalg.norm(out[RE] - truth[RE]) < 0.04
    else:
        assert out[RS, 2] - truth[RS, 2] > 0.15
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)


def test_a_kf_lagging_behind_a_reading_our_last_output_took_is_the_filters_error():
    # A frame of real motion held out of AKC+'s design (CMU subject 05, trial 11, driven bone by bone; MediaPipe on
    # the skinned body, 30 Hz, after the KF). Two frames ago the right wrist's pixel read the wall; the KF followed
    # and lags 84 cm behind the reading, back on the body, that our last output took the frame before. On the
    # filter's ray, the reading looked like an occluder's: the wrist was rejected, and the arm rebuilt behind
    # (elbow 43 cm, wrist 96 cm off). Our last output agrees with the reading: two against one, the filter lags.
    akc, dims, d = _recorded_frame("mediapipe_cmu_05_11_rig_30hz_frame48.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert pose[RW, 2] - m[RW, 2] > 0.8 and abs(m[RW, 2] - truth[RW, 2]) < 0.01 and np.isnan(m[RE, 2])
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.linalg.norm(out[RW] - truth[RW]) < 0.04 and abs(out[RE, 2] - truth[RE, 2]) < 0.03
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_a_shoulder_reading_the_torso_confirms_is_not_undone_by_an_elbow_and_a_wrist_on_the_wall():
    # MediaPipe, bvhtools_b2's window at 30 Hz, after the EKF (tests/data/akc_plus): the left elbow's and wrist's
    # pixels read the wall 1.5 m behind; the EKF, pulled behind by them, took the shoulder 29 cm behind its reading
    # (its bone constraints), which is right and agrees with the torso. The ray test took the shoulder's and the
    # wrist's readings; the reach test then undid the shoulder's, as out of the wall wrist's reach, and the arm
    # rebuilt from that wrist put the shoulder on the wall, 1.5 m behind. Two against one: the reading and the
    # torso; the wall wrist is the one undone.
    akc, dims, d = _recorded_frame("mediapipe_bvhtools_b2_window_30hz_frame636.npz", constrained_filter=True)
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    LS, LE, LW = INDEX["left_shoulder"], INDEX["left_elbow"], INDEX["left_wrist"]
    assert abs(m[LS, 2] - truth[LS, 2]) < 0.03 and pose[LS, 2] - m[LS, 2] > 0.25
    assert m[LE, 2] - truth[LE, 2] > 1.0 and m[LW, 2] - truth[LW, 2] > 1.0
    out = akc.correct(pose, m, d["variance"]).pose
    assert abs(out[LS, 2] - m[LS, 2]) < 1e-9
    assert abs(out[LE, 2] - truth[LE, 2]) < 0.1 and abs(out[LW, 2] - truth[LW, 2]) < 0.1
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
    assert np.linalg.norm(out[LE] - out[LW]) == pytest.approx(dims.LLA, abs=1e-12)


def test_a_shoulder_held_on_the_torso_out_of_the_seen_wrists_reach_is_not_held():
    # The simulated detector on boxing driven bone by bone, after the EKF (tests/data/akc_plus): the trunk leant
    # back 40 cm in four frames while the right shoulder was hidden; lost altogether, it was held on the torso at
    # its old offset, 38 cm in front and 80 cm from the seen wrist, farther than the arm reaches. The EKF's
    # shoulder, within reach, was 2 cm off: the hold is not taken.
    akc, dims, d = _recorded_frame("sim_boxing_rig_10hz_frame242.npz", constrained_filter=True)
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    RS, RW = INDEX["right_shoulder"], INDEX["right_wrist"]
    assert np.isnan(m[RS]).all() and np.isfinite(m[RW]).all() and abs(m[RW, 2] - truth[RW, 2]) < 0.03
    reach = dims.RUA + dims.RLA
    assert np.linalg.norm(pose[RS] - m[RW]) < reach and abs(pose[RS, 2] - truth[RS, 2]) < 0.03
    out = akc.correct(pose, m, d["variance"]).pose
    assert abs(out[RS, 2] - truth[RS, 2]) < 0.15  # (held: 38 cm in front)
    assert np.linalg.norm(out[RS] - out[INDEX["right_elbow"]]) == pytest.approx(dims.RUA, abs=1e-12)


def test_hips_wider_apart_than_the_shoulders_hold_no_hidden_shoulder():
    # MediaPipe on cmu_01_06 driven bone by bone, after the KF (tests/data/akc_plus), frame 216: the torso leans
    # towards the camera and each hip's pixel reads the body one frame and the wall 1.5 m behind the next; the KF
    # follows, so both hips pass their own innovation test, 1.6 m apart in depth. The right shoulder's depth is
    # dropped. Held on those hips at the offset learnt from them, it went 80-90 cm behind (the filter's was 1 cm
    # off), and the arm with it. Hips farther apart than the shoulders are no torso reference.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_06_rig_10hz_frame216.npz")
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    LH, RH = INDEX["left_hip"], INDEX["right_hip"]
    assert np.isnan(m[RS, 2]) and np.isfinite(m[RS, :2]).all() and abs(pose[RS, 2] - truth[RS, 2]) < 0.02
    assert m[LH, 2] > truth[LH, 2] + 1.0 and np.linalg.norm(pose[LH] - pose[RH]) > 1.5  # (a hip on the wall)
    out = akc.correct(pose, m, d["variance"]).pose
    assert np.isnan(akc._hips).all()  # (no reference: the shoulders carry each other after a second without)
    assert abs(out[RS, 2] - truth[RS, 2]) < 0.03  # (held on the hips: 0.9 m behind)
    assert abs(out[RE, 2] - truth[RE, 2]) < 0.06  # (the seen elbow's reading is 3 cm off; rebuilt: 0.9 m)
    assert np.linalg.norm(out[RS] - out[RE]) == pytest.approx(dims.RUA, abs=1e-12)
    assert np.linalg.norm(out[RE] - out[RW]) == pytest.approx(dims.RLA, abs=1e-12)


def test_hips_within_the_shoulder_width_are_the_hidden_shoulders_reference():
    # The other side of the rule above: the same frame with both hips at the depth that carries the seen left
    # shoulder at its learnt offset, and the filter's right shoulder (its depth still dropped) 10 cm behind the
    # depth the hips carry: the hips are the reference, and the held right shoulder goes there.
    akc, dims, d = _recorded_frame("mediapipe_cmu_01_06_rig_10hz_frame216.npz")
    m, pose, var = d["measured"].copy(), d["pose"].copy(), d["variance"]
    LH, RH = INDEX["left_hip"], INDEX["right_hip"]
    off_l, off_r = list(akc._held_sh[0]), list(akc._held_sh[1])
    hz = m[LS, 2] - off_l[2]
    m[[LH, RH], 2] = pose[[LH, RH], 2] = hz
    pose[RS, 2] = hz + off_r[2] + 0.10
    out = akc.correct(pose, m, var).pose
    assert akc._hips[2] == pytest.approx(hz) and akc._anchor[1][0] == akc._hips
    assert abs(out[RS, 2] - (hz + off_r[2])) < 0.03


def test_a_held_shoulder_keeps_its_hold_while_the_other_shoulders_reading_agrees_with_our_output():
    # MediaPipe on boxing driven bone by bone, after the EKF (tests/data/akc_plus), frame 244: the left arm reads
    # the right glove 50-70 cm in front, and the left shoulder's jump was held last frame (``_shoulder_jumped``).
    # The EKF's right shoulder, pulled towards the glove's readings, is 17 cm off its own correct reading and fails
    # the innovation test; that reading, within consistency_m of our last output, still carries the hold.
    akc, dims, d = _recorded_frame("mediapipe_boxing_rig_10hz_frame244.npz", constrained_filter=True)
    truth, m, pose = d["truth"], d["measured"], d["pose"]
    assert m[LS, 2] < truth[LS, 2] - 0.4 and akc._pair_z[0][1] > 0  # (read on the glove; held last frame)
    assert abs(m[RS, 2] - truth[RS, 2]) < 0.01 and abs(pose[RS, 2] - m[RS, 2]) > 0.15
    out = akc.correct(pose, m, d["variance"]).pose
    assert abs(out[LS, 2] - truth[LS, 2]) < 0.05  # (the glove taken: 44 cm in front)
    assert np.linalg.norm(out[LS] - out[LE]) == pytest.approx(dims.LUA, abs=1e-12)
