import numpy as np
import pytest

from akc_drake.core.akc_plus_evidence import (
    arm_variances,
    beyond_reach,
    depth_reading_noise,
    followed_rejected,
    forearm_misread,
    fuse_held,
    held_segments,
    hold_blind,
    known_depths,
    unreachable_replacements,
    wrist_misfit,
)

R_XY, R_Z = 0.01**2, 0.05**2
#: One arm's coordinates at flat indices 0-8 (position in the arm, flat index, R, running-NIS index).
SUB = tuple((i, i, (R_XY, R_XY, R_Z)[i % 3], i) for i in range(9))
NAN = float("nan")


def test_unmeasured_coordinates_are_inflated_by_the_running_nis_but_never_shrunk():
    var = [1e-4] * 9
    nis = [3.0, 0.5] + [1.0] * 7
    out = arm_variances(SUB, var, [NAN] * 9, [0.0] * 9, [0.0] * 9, nis, 0.2, 0.01, 9.0)
    assert out[0] == pytest.approx(3e-4, rel=1e-12)  # inflated by the NIS mean of 3
    assert out[1] == 1e-4  # a mean of 0.5 does not shrink a blind axis
    assert nis == [3.0, 0.5] + [1.0] * 7  # nothing measured: the means are unchanged


def test_measured_coordinate_updates_the_running_nis_winsorised_at_the_gate():
    var = [0.0] * 9
    var[2] = 0.0016  # the filter's depth variance: the residual's is R - P = 0.0009
    m = [NAN] * 9
    m[2] = 2.03
    v = [0.0] * 9
    v[2] = 2.0
    nis = [1.0] * 9
    f = [0.0] * 9
    f[2] = 2.0
    out = arm_variances(SUB, var, m, v, f, nis, 0.2, 0.01, 9.0)
    q = 0.03**2 / 0.0009  # this frame's NIS: 1.0
    assert nis[2] == pytest.approx(0.8 * 1.0 + 0.2 * q, rel=1e-12)
    assert out[2] == pytest.approx(0.0016 * nis[2], rel=1e-12)
    assert f[2] == 2.0  # the filter's variance is below R: the filter is kept
    m[2] = 3.0  # an outlier: the NIS of 1111 counts as the gate's 9
    arm_variances(SUB, var, m, v, f, nis, 0.2, 0.01, 9.0)
    assert nis[2] == pytest.approx(0.8 * (0.8 + 0.2 * q) + 0.2 * 9.0, rel=1e-12)


def test_a_lagging_filter_yields_to_a_consistent_measurement():
    # A filter whose running NIS shows an error variance 8 times its P (> R) and a measured depth 10 cm off:
    # within the gate of the excess-error residual, the measurement replaces the filter's depth.
    var = [1e-4] * 9
    nis = [8.0] * 9
    m = [NAN] * 9
    m[5] = 2.10
    v = [0.0] * 9
    v[5] = 2.0
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, nis, 0.0, 0.01, 9.0)  # alpha 0: the mean stays at 8 (8e-4 < R)
    assert f[5] == 2.0 and out[5] == pytest.approx(8e-4, rel=1e-12)
    nis[5] = 40.0  # 4e-3 > R: the filter lags more than a measurement errs
    out = arm_variances(SUB, var, m, v, f, nis, 0.0, 0.01, 9.0)
    assert f[5] == 2.10 and out[5] == R_Z


def test_a_constrained_filter_is_refit_to_the_update_its_nis_shows():
    """``refit``: the estimate and variance of the Kalman update whose prior variance is the one the NIS shows."""
    p0, c, r = 4e-4, 6.0, R_Z  # the filter's prior variance, the factor its true prior variance is off, R
    x0, z = 2.0, 2.09  # the filter's prediction and this frame's measurement
    f_post = x0 + p0 / (p0 + r) * (z - x0)  # what the filter output (its gain from the prior it assumed)
    p_post = p0 * r / (p0 + r)
    k = (c * p0 + r) / (p0 + r)  # the residual's variance over the filter's own R - P, in expectation
    right = x0 + c * p0 / (c * p0 + r) * (z - x0)  # the update with the right prior variance
    right_var = c * p0 * r / (c * p0 + r)
    var = [1e-4] * 9
    var[5] = p_post
    m, v = [NAN] * 9, [0.0] * 9
    m[5], v[5] = z, f_post
    nis = [k] * 9
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, nis, 0.0, 0.01, 9.0, refit=True)  # alpha 0: the mean stays at k
    assert f[5] == pytest.approx(right, abs=1e-12) and out[5] == pytest.approx(right_var, rel=1e-9)
    assert abs(f[5] - z) < abs(f_post - z)  # moved towards the measurement, not onto it
    # Without refit (a plain KF), the covariance-matched variance p k is below R: the filter's estimate stays.
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0)
    assert f[5] == f_post and out[5] == pytest.approx(p_post * k, rel=1e-12)
    # A NIS of 1 or below: the filter is consistent, nothing moves; an outlier outside the gate moves nothing.
    for nis_k, z_k in ((1.0, z), (0.5, z), (k, 3.0)):
        f = list(v)
        m[5] = z_k
        arm_variances(SUB, var, m, v, f, [nis_k] * 9, 0.0, 0.01, 9.0, refit=True)
        assert f[5] == f_post


def test_after_a_constrained_filter_a_seen_depth_is_taken_as_read():
    """``seen_var``: after an EKF, a measured depth passing the innovation test is the reading, at that variance;
    x and y are refitted as before, a depth beyond the gate is not taken, and a plain KF ignores ``seen_var``."""
    var = [5e-5, 5e-5, 4e-4] * 3
    m = [0.10, 0.20, 2.03, NAN, NAN, NAN, 0.31, 0.42, 2.30]  # shoulder and wrist measured; the wrist 30 cm off
    v = [0.10, 0.20, 2.00, 0.0, 0.0, 2.0, 0.30, 0.40, 2.00]
    k = 1.5
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0, refit=True, seen_var=0.015**2)
    assert f[2] == 2.03 and out[2] == pytest.approx(0.015**2, rel=1e-12)  # the depth as read
    assert f[8] == 2.00 and out[8] == pytest.approx(4e-4 * k, rel=1e-12)  # beyond the gate: the filter's
    # x, y are refitted (the update at the prior variance the NIS shows); the elbow, not measured, is the filter's
    assert f[6] == pytest.approx(0.31 - 0.01 / k, abs=1e-12) and f[7] == pytest.approx(0.42 - 0.02 / k, abs=1e-12)
    assert f[0:2] == v[0:2] and f[3:6] == v[3:6]
    # The refit alone (seen_var 0) moves the depth part of the way; a plain KF keeps the filter's (p k < R).
    f = list(v)
    arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0, refit=True)
    assert f[2] == pytest.approx(2.03 - 0.03 / k, abs=1e-12)
    f = list(v)
    arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0, seen_var=0.015**2)
    assert f == v



def _noise_run(readings, filtered, alpha=0.2, prior=0.015**2):
    """``depth_reading_noise`` over a sequence of one arm's depth readings and the filter's (frames x 3: shoulder,
    elbow, wrist; NaN: not read): the noise list after the last frame, the arm's estimate per frame and the three
    joints' running means per frame."""
    noise = [NAN, prior] * 3
    est, means = [], []
    for z, fz in zip(readings, filtered, strict=True):
        m, v = [0.0] * 9, [0.0] * 9
        m[2::3], v[2::3] = list(z), list(fz)
        est.append(depth_reading_noise(SUB, m, v, noise, alpha, prior))
        means.append(noise[1::2])
    return noise, est, np.array(means)


def test_the_reading_noise_is_the_residuals_frame_to_frame_change_and_the_arm_takes_its_stillest():
    rng = np.random.default_rng(0)
    n = 400
    truth = np.stack([np.full(n, 2.0), 2.0 + 0.3 * np.sin(np.arange(n) / 3.0), np.full(n, 2.1)], axis=1)
    # The filter: exact on the still shoulder and wrist, lagging the swinging elbow by a frame (up to 10 cm).
    filtered = truth.copy()
    filtered[1:, 1] = truth[:-1, 1]
    readings = truth + rng.normal(0.0, [0.01, 0.01, 0.03], size=(n, 3))  # (the wrist read 3 times as noisily)
    noise, est, means = _noise_run(readings, filtered)
    settled = means[50:].mean(axis=0)  # (a running mean of weight 0.2 averages about 10 frames: its mean over 350)
    assert settled[0] == pytest.approx(1e-4, rel=0.2)  # the shoulder's white noise, 1 cm: its variance
    assert settled[2] == pytest.approx(9e-4, rel=0.2)  # the wrist's, 3 cm
    assert settled[1] > 3 * settled[0]  # the elbow's residual also changes with the filter's lag (2 cm a frame)
    assert est == [min(row) for row in means.tolist()]  # the arm's estimate: its stillest joint's
    assert noise[4] == pytest.approx(readings[-1, 2] - filtered[-1, 2], abs=1e-15)  # the last residual


def test_the_reading_noise_needs_two_consecutive_readings_and_one_misread_frame_moves_it_at_most_2_6_times():
    prior = 0.015**2
    z = np.full((6, 3), 2.0)
    z[2, 1] = np.nan  # the elbow not read in frame 2: frames 2 and 3 give no change to measure
    noise, est, _ = _noise_run(z, np.full((6, 3), 2.0), alpha=0.5, prior=prior)
    assert noise[3] == pytest.approx(prior * 0.5**3, rel=1e-12)  # three changes (of 0), against the shoulder's five
    assert noise[1] == pytest.approx(prior * 0.5**5, rel=1e-12) == est[-1]
    z[5, 0] = 2.5  # a 50 cm misread: winsorised at 9 times the mean
    noise, _, _ = _noise_run(z, np.full((6, 3), 2.0), alpha=0.5, prior=prior)
    assert noise[1] == pytest.approx(prior * 0.5**4 * (0.5 + 0.5 * 9), rel=1e-12)
    assert depth_reading_noise(SUB, [NAN] * 9, [0.0] * 9, noise, 0.5, prior) == min(noise[1::2])
    assert all(x != x for x in noise[0::2])  # nothing read: no last residual


def _fused_run(readings, filtered, fusion=True, seen_var=0.015**2):
    """One joint's depth (the shoulder) through ``arm_variances`` after a constrained filter, frame by frame, with
    the running NIS and the reading noise carried: the fused depths and their variances."""
    var = [5e-5, 5e-5, 4e-4] * 3
    nis, noise = [1.0] * 9, [NAN, seen_var] * 3
    out, vs = [], []
    for z, fz in zip(readings, filtered, strict=True):
        m, v = [0.0, 0.0, z] + [NAN] * 6, [0.0, 0.0, fz] + [0.0, 0.0, 2.0] * 2
        f = list(v)
        vv = arm_variances(SUB, var, m, v, f, nis, 0.2, 0.01, 9.0, refit=True, seen_var=seen_var,
                           noise=noise if fusion else None)
        out.append(f[2])
        vs.append(vv[2])
    return np.array(out), np.array(vs)


def test_after_a_constrained_filter_a_seen_depth_is_fused_by_the_variances_its_residuals_show():
    """A still joint read with 1.3 cm of white noise, the filter's average within 0.2 cm: fused, the depth keeps
    most of the average; taken as read it is as noisy as the readings. A filter lagging a moving joint by 6 cm,
    read to 0.2 cm: fused, the depth is the reading. The variance is never below ``seen_var``."""
    rng = np.random.default_rng(1)
    n = 300
    truth = np.full(n, 2.0)
    filtered = truth + 0.002 * np.sin(np.arange(n) / 20.0)
    readings = truth + rng.normal(0.0, 0.013, n)
    fused, vs = _fused_run(readings, filtered)
    read, _ = _fused_run(readings, filtered, fusion=False)
    rmse = lambda x: float(np.sqrt(np.mean((x[50:] - truth[50:]) ** 2)))  # noqa: E731 (after the estimates settle)
    assert rmse(read) == pytest.approx(rmse(readings), rel=1e-12) and rmse(read) > 0.012
    assert rmse(fused) < 0.45 * rmse(read)
    assert vs.min() >= 0.015**2
    truth = 2.0 + 0.03 * np.arange(n) / 10.0
    filtered = truth - 0.06
    readings = truth + rng.normal(0.0, 0.002, n)
    fused, vs = _fused_run(readings, filtered)
    assert rmse(fused) < 0.004 and vs.min() >= 0.015**2


def test_after_a_kf_a_depth_that_would_replace_the_filters_is_fused_instead():
    """After a plain KF (no refit), with ``seen_var`` and ``noise``: a depth whose filter's covariance-matched error
    is below R stays the filter's (its residual is recorded for the noise); one that would replace the filter's moves
    ``w = e2 / (e2 + s2)`` of the way, e2 the residual's mean square less the reading noise s2, at the variance of
    that combination in the KF's model (``(1 - w)^2 p k + w^2 R``); without ``noise`` it replaces the filter's."""
    var = [1e-4] * 9
    m, v = [NAN] * 9, [0.0] * 9
    m[5], v[5] = 2.10, 2.0  # the elbow's depth read 10 cm from the filter's
    s2 = 0.08**2  # a noisy camera: every joint's reading noise (8 cm)^2, as measured before this frame
    noise = [NAN, s2] * 3
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, [8.0] * 9, 0.0, 0.01, 9.0, seen_var=0.015**2, noise=noise)
    assert f[5] == 2.0 and out[5] == pytest.approx(8e-4, rel=1e-12)  # p k = 8e-4 < R: the filter's
    assert noise[2] == pytest.approx(0.10, abs=1e-12) and noise[3] == s2  # the residual kept for the next frame
    k = 40.0  # p k = 4e-3 > R: the filter lags more than a measurement errs
    noise = [NAN, s2] * 3
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0, seen_var=0.015**2, noise=noise)
    e2 = k * (R_Z - 1e-4) - s2
    w = e2 / (e2 + s2)
    assert 0.8 < w < 0.95
    assert f[5] == pytest.approx(2.0 + w * 0.10, abs=1e-12)
    assert out[5] == pytest.approx((1.0 - w) ** 2 * 1e-4 * k + w * w * R_Z, rel=1e-12) and out[5] < R_Z
    f = list(v)
    out = arm_variances(SUB, var, m, v, f, [k] * 9, 0.0, 0.01, 9.0, seen_var=0.015**2)  # no noise: replaced
    assert f[5] == 2.10 and out[5] == R_Z


def test_a_seen_depth_misread_for_one_frame_does_not_vouch_for_itself():
    """The filter's error variance is the residuals' before this frame: a still joint read to 0.3 cm, the filter
    within 0.1 cm, then one reading 10 cm off (inside the gate): fused, the depth moves a fraction of it; taken
    as read, all of it."""
    n = 60
    truth = np.full(n, 2.0)
    readings = truth + 0.003 * np.cos(np.arange(n) * 2.0)
    readings[-1] = 2.10
    fused, _ = _fused_run(readings, truth + 0.001)
    read, _ = _fused_run(readings, truth + 0.001, fusion=False)
    assert read[-1] == 2.10
    assert fused[-1] - 2.001 < 0.3 * (2.10 - 2.001)


def test_an_extrapolated_blind_depth_is_held_at_the_last_output():
    prev = (0.1, 0.0, 2.0, 0.2, 0.2, 2.05, 0.3, 0.4, 2.0)
    vs = [1e-4] * 9
    vs[5] = 0.01  # the filter extrapolates the elbow (variance above R)
    p, held = hold_blind((0.21, 0.22, 1.80), vs, 3, (0.2, 0.2, 2.06), prev, R_Z)
    assert held and p == (0.21, 0.22, 2.05)
    # A filter that stayed within one sigma of where it last saw the joint is followed.
    p, held = hold_blind((0.21, 0.22, 2.02), vs, 3, (0.2, 0.2, 2.06), prev, R_Z)
    assert not held and p == (0.21, 0.22, 2.02)
    vs[5] = 1e-4  # a filter as sure as a measurement is followed too
    assert hold_blind((0.21, 0.22, 1.80), vs, 3, None, prev, R_Z) == ((0.21, 0.22, 1.80), False)


def _known(vs, lost, me=False, ms=True, no_prior=frozenset()):
    m = [NAN] * 9
    xy = (0.0, 0.0, 0.1, 0.25, 0.35, 0.3)  # shoulder, elbow, wrist x, y: segments near the image plane
    return known_depths(m, vs, me, ms, 3, 0, 0, 1, 0.29, 0.26, xy, R_Z, 1e-4, no_prior, lost, 3.0)


def test_a_filter_that_moved_towards_a_rejected_reading_followed_it():
    g2r = 9.0 * 0.05**2  # (the gate squared times R: 15 cm)
    prev = [0.0, 0.0, 2.00, 0.0, 0.0, 2.15]
    # The elbow (prev[5] 2.15) read 1.15: the filter moved 30 cm towards it, beyond the gate of R.
    assert followed_rejected(1.15, 1.85, prev, 5, g2r)
    assert not followed_rejected(1.15, 2.05, prev, 5, g2r)  # (10 cm: within what a measurement's noise moves)
    assert not followed_rejected(1.15, 2.45, prev, 5, g2r)  # (moved away from the reading)
    assert not followed_rejected(float("nan"), 1.85, prev, 5, g2r)  # (nothing read)
    assert not followed_rejected(1.15, 1.85, None, 5, g2r)  # (no last output)
    assert followed_rejected(3.50, 2.30, prev, 2, g2r)  # (a shoulder read on the wall behind, followed)


def test_a_dropped_depth_is_known_when_the_filter_knows_it_as_well_as_a_measurement():
    vs = [1e-4] * 9
    vs[5] = 0.002  # < R
    assert _known(vs, [5.0, 0.0]) == (True, True)
    # ... but not when the filter's estimate is no evidence (held or following an occluder).
    assert _known(vs, [5.0, 0.0], no_prior={0}) == (False, True)


def test_a_dropped_depth_is_known_recently_only_if_the_filter_beats_the_rebuild():
    # The forearm is near the image plane: eq. 7 rebuilds the elbow's depth from the wrist with a variance of
    # 5.1e-3 m^2 (the shoulder's depth is not measured either, so there is no second rebuild to fuse).
    vs = [1e-4] * 9
    vs[5] = 0.004  # above R, below the rebuild's variance
    assert _known(vs, [2.0, 0.0], ms=False) == (True, True)
    assert _known(vs, [4.0, 0.0], ms=False)[0] is False  # dropped more than recent_frames ago
    # With the shoulder seen, the fused rebuild (2.1e-3 m^2) beats the filter's 4e-3.
    assert _known(vs, [2.0, 0.0], ms=True)[0] is False
    vs[5] = float("nan")  # a variance the filter does not know counts as above any
    assert _known(vs, [1.0, 0.0], ms=False)[0] is False


def test_a_blind_wrist_is_the_product_of_the_filter_and_the_forearm_held_at_the_elbow():
    # The elbow (seen) at (0.1, 0, 2); the forearm last seen as (0, 0.3, 0) from it; a second blind frame: the
    # held forearm's variance is 2 v_t = 0.02 per axis.
    f = [0.0, 0.0, 2.0, 0.1, 0.0, 2.0, 1.0, 2.0, 3.0]
    vs = [1e-4] * 6 + [0.06, 0.02, NAN]
    blind = [0.0, 0.3, 0.0, 1.0]
    fuse_held(f, vs, blind, f[3:6], 0.01, 6)
    assert blind == [0.0, 0.3, 0.0, 2.0]  # this frame counted
    assert f[6] == pytest.approx((0.02 * 1.0 + 0.06 * 0.1) / 0.08, rel=1e-12)  # weight 1/4 on the filter's
    assert f[7] == pytest.approx((2.0 + 0.3) / 2, rel=1e-12)  # equal variances: the midpoint
    assert vs[6] == pytest.approx(0.06 * 0.02 / 0.08, rel=1e-12)
    assert vs[7] == pytest.approx(0.01, rel=1e-12)
    assert f[8] == 3.0 and vs[8] != vs[8]  # an unknown variance: left as it is
    assert f[:6] == [0.0, 0.0, 2.0, 0.1, 0.0, 2.0] and vs[:6] == [1e-4] * 6  # shoulder and elbow untouched
    # The longer the wrist is lost, the less the held forearm counts: the tenth blind frame.
    f2 = [0.0, 0.0, 2.0, 0.1, 0.0, 2.0, 1.0, 2.0, 3.0]
    fuse_held(f2, [1e-4] * 6 + [0.06, 0.02, NAN], [0.0, 0.3, 0.0, 9.0], f2[3:6], 0.01, 6)
    assert f2[6] == pytest.approx((0.1 * 1.0 + 0.06 * 0.1) / 0.16, rel=1e-12)


def test_after_honest_frames_the_filter_counts_no_surer_than_the_hold():
    # A constrained filter's wrist, lost altogether: it claims 1 cm (1e-4) on each axis. Up to ``honest_frames``
    # blind frames it is believed (weight 0.02 / 0.0201 on it at the second frame); after them its variance
    # counts as at least the hold's (the fifth frame: 0.05 on each axis), so the two are averaged; an axis the filter
    # claims less sure of than the hold keeps its variance, and an unknown one stays as it is.
    def fused(n_before, vz):
        f = [0.0, 0.0, 2.0, 0.1, 0.0, 2.0, 1.0, 2.0, 3.0]
        vs = [1e-4] * 6 + [1e-4, 1e-4, vz]
        fuse_held(f, vs, [0.0, 0.3, 0.0, n_before], f[3:6], 0.01, 6, (0, 1, 2), 3.0)
        return f, vs

    f, vs = fused(1.0, 1e-4)  # the second blind frame: the filter's variance as it claims
    assert f[6] == pytest.approx((0.02 * 1.0 + 1e-4 * 0.1) / 0.0201, rel=1e-12)
    assert vs[6] == pytest.approx(1e-4 * 0.02 / 0.0201, rel=1e-12)
    f, vs = fused(2.0, 1e-4)  # the third: still as it claims (``honest_frames`` = 3)
    assert vs[6] == pytest.approx(1e-4 * 0.03 / 0.0301, rel=1e-12)
    f, vs = fused(3.0, 1e-4)  # the fourth: the hold's 0.04
    assert vs[6] == pytest.approx(0.02, rel=1e-12) and f[6] == pytest.approx(0.55, rel=1e-12)
    f, vs = fused(4.0, 0.2)  # the fifth
    assert f[6] == pytest.approx((1.0 + 0.1) / 2, rel=1e-12) and f[7] == pytest.approx((2.0 + 0.3) / 2, rel=1e-12)
    assert vs[6] == pytest.approx(0.025, rel=1e-12) and vs[7] == pytest.approx(0.025, rel=1e-12)
    assert f[8] == pytest.approx((0.05 * 3.0 + 0.2 * 2.0) / 0.25, rel=1e-12)  # 0.2 > 0.05: its own variance
    f, vs = fused(4.0, NAN)
    assert f[8] == 3.0 and vs[8] != vs[8]
    # The default (inf): the filter's variance whatever the blind frames.
    g = [0.0, 0.0, 2.0, 0.1, 0.0, 2.0, 1.0, 2.0, 3.0]
    fuse_held(g, [1e-4] * 9, [0.0, 0.3, 0.0, 40.0], g[3:6], 0.01, 6)
    assert g[6] == pytest.approx((0.41 * 1.0 + 1e-4 * 0.1) / 0.4101, rel=1e-12)

def test_a_blind_elbow_is_the_product_of_the_filter_and_the_upper_arm_held_at_the_shoulder():
    # The shoulder at (0.2, 0, 2); the upper arm last seen as (0.1, 0.3, -0.1) from it; the first blind frame:
    # the held upper arm's variance is v_t = 0.01 per axis. The wrist (base 6) is not this call's.
    f = [0.2, 0.0, 2.0, 0.5, 0.4, 1.6, 1.0, 2.0, 3.0]
    vs = [1e-4] * 3 + [0.03, 0.01, NAN] + [0.5] * 3
    blind = [0.1, 0.3, -0.1, 0.0]
    fuse_held(f, vs, blind, f[0:3], 0.01, 3)
    assert blind == [0.1, 0.3, -0.1, 1.0]
    assert f[3] == pytest.approx((0.01 * 0.5 + 0.03 * 0.3) / 0.04, rel=1e-12)  # 0.35: weight 1/4 on the filter's
    assert f[4] == pytest.approx(0.35, rel=1e-12)  # equal variances: the midpoint of 0.4 and 0.3
    assert vs[3] == pytest.approx(0.0075, rel=1e-12) and vs[4] == pytest.approx(0.005, rel=1e-12)
    assert f[5] == 1.6 and vs[5] != vs[5]  # an unknown variance: left as it is
    assert f[:3] == [0.2, 0.0, 2.0] and f[6:] == [1.0, 2.0, 3.0] and vs[6:] == [0.5] * 3


def test_a_blind_elbow_whose_filter_followed_an_occluder_is_the_upper_arm_held_alone():
    # As above, but the filter followed a depth judged an occluder's (``no_evidence``): the hold, its variance.
    f = [0.2, 0.0, 2.0, 0.5, 0.4, 1.6, 1.0, 2.0, 3.0]
    vs = [1e-4] * 3 + [0.03, 0.01, NAN] + [0.5] * 3
    blind = [0.1, 0.3, -0.1, 2.0]
    fuse_held(f, vs, blind, f[0:3], 0.01, 3, no_evidence=True)
    assert blind[3] == 3.0 and f[3:6] == pytest.approx([0.3, 0.3, 1.9], abs=1e-15)
    assert vs[3:6] == pytest.approx([0.03] * 3, rel=1e-12)  # (three blind frames of 0.01)
    assert f[:3] == [0.2, 0.0, 2.0] and f[6:] == [1.0, 2.0, 3.0] and vs[6:] == [0.5] * 3


def test_a_dropped_shoulder_is_the_product_of_the_filter_and_the_shoulder_held_on_the_hips():
    # The filter holds the shoulder at depth 2.10 with variance 0.03 (a constant-velocity filter blind for long);
    # it was last seen 0.05 m in front of the hips, which are at 2.00 now; the third blind frame: the held
    # offset's variance is 3 v_s = 3e-4. Weight 0.0003 / 0.0303 on the filter's depth.
    f = [0.1, 0.2, 2.10, 0.1, 0.5, 2.0, 0.1, 0.8, 1.9]
    vs = [1e-4, 1e-4, 0.03] + [1e-3] * 6
    held = [0.15, -0.5, -0.05, 2.0]
    fuse_held(f, vs, held, (0.0, 0.7, 2.0), 1e-4, 0, (2,))
    assert held == [0.15, -0.5, -0.05, 3.0]
    assert f[2] == pytest.approx((3e-4 * 2.10 + 0.03 * 1.95) / 0.0303, rel=1e-12)
    assert abs(f[2] - 1.95) < 0.002
    assert vs[2] == pytest.approx(0.03 * 3e-4 / 0.0303, rel=1e-12)
    assert f[:2] == [0.1, 0.2] and f[3:] == [0.1, 0.5, 2.0, 0.1, 0.8, 1.9]  # only the shoulder's depth
    assert vs[:2] == [1e-4, 1e-4] and vs[3:] == [1e-3] * 6
    # The hips stepped 0.2 m towards the camera: the held shoulder goes with them.
    f2 = [0.1, 0.2, 2.10, 0.1, 0.5, 2.0, 0.1, 0.8, 1.9]
    fuse_held(f2, [1e-4, 1e-4, 0.03] + [1e-3] * 6, [0.15, -0.5, -0.05, 2.0], (0.0, 0.7, 1.8), 1e-4, 0, (2,))
    assert abs(f2[2] - 1.75) < 0.005


def test_a_shoulder_lost_altogether_is_held_on_the_hips_in_x_and_y_too():
    # No x, y either: the filter extrapolated the shoulder 0.3 m off in x (variance 0.04) and holds y well
    # (variance 1e-4, as small as the held offset's after one frame); the hips' centre (0.02, 0.65, 2.0) carries
    # the held offset (0.15, -0.5, -0.05): (0.17, 0.15, 1.95). First blind frame: v_h = 1e-4.
    f = [0.47, 0.16, 2.10, 0.1, 0.5, 2.0, 0.1, 0.8, 1.9]
    vs = [0.04, 1e-4, 0.03] + [1e-3] * 6
    held = [0.15, -0.5, -0.05, 0.0]
    fuse_held(f, vs, held, (0.02, 0.65, 2.0), 1e-4, 0)
    assert held[3] == 1.0
    assert f[0] == pytest.approx((1e-4 * 0.47 + 0.04 * 0.17) / 0.0401, rel=1e-12)  # 0.17075: 7.5 mm off the hold
    assert f[1] == pytest.approx(0.5 * (0.16 + 0.15), rel=1e-12)  # equal variances: the midpoint
    assert f[2] == pytest.approx((1e-4 * 2.10 + 0.03 * 1.95) / 0.0301, rel=1e-12)
    assert vs[:3] == pytest.approx([0.04 * 1e-4 / 0.0401, 0.5e-4, 0.03 * 1e-4 / 0.0301], rel=1e-12)
    assert f[3:] == [0.1, 0.5, 2.0, 0.1, 0.8, 1.9] and vs[3:] == [1e-3] * 6
    # An axis whose variance the filter does not know (NaN) is left as it is.
    g, vg = [0.47, 0.16, 2.10] + [0.0] * 6, [NAN, 1e-4, 0.03] + [1e-3] * 6
    fuse_held(g, vg, [0.15, -0.5, -0.05, 0.0], (0.02, 0.65, 2.0), 1e-4, 0)
    assert g[0] == 0.47 and vg[0] != vg[0] and g[1] == pytest.approx(0.155, rel=1e-12)


def test_a_shoulder_held_on_the_torso_tells_that_an_elbow_and_wrist_on_the_wall_are_unreachable():
    # The shoulder's depth dropped, held on the torso at (0, 0, 2.0). The elbow and the wrist both read the wall
    # 1.5 m behind (a landmark past the silhouette) and replaced the filter's (2.3, 2.4): they agree with each
    # other, and only the held shoulder shows neither is reachable. Restored: the elbow (pair shoulder-elbow),
    # then the wrist (pair shoulder-wrist); the held shoulder itself is never restored, and the caller's
    # measurement is not changed. Without the hold, nothing is.
    lu, lf = 0.3, 0.28
    m = [NAN, NAN, NAN, 0.0, 0.3, 3.5, 0.0, 0.58, 3.6] + [NAN] * 27
    f0 = [0.0, 0.0, 2.4, 0.0, 0.3, 2.3, 0.0, 0.58, 2.4]
    sub_index = [(i, i, 1e-4 if i % 3 < 2 else 2.5e-3, i) for i in range(9)]
    var = [1e-4, 1e-4, 0.04] * 3 + [0.0] * 27
    for held in (True, False):
        f = [0.0, 0.0, 2.0, 0.0, 0.3, 3.5, 0.0, 0.58, 3.6]
        vs = [1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 2.5e-3, 1e-4, 1e-4, 2.5e-3]
        m_before = list(m)
        n = unreachable_replacements(f, vs, f0, m, (0, 3, 6), sub_index, var, [1.0] * 9, 0.01, lu, lf,
                                     (1e-4, 1e-4, 2.5e-3), 1e-4, 9.0, s_held=held)
        assert m == m_before and f[:3] == [0.0, 0.0, 2.0]
        if held:
            assert n == 2 and f[3:] == f0[3:] and vs[5] == pytest.approx(0.04) and vs[8] == pytest.approx(0.04)
        else:
            assert n == 0 and f[5] == 3.5 and f[8] == 3.6


def test_a_replacement_beyond_the_arms_reach_gets_the_filters_point_and_variances_back():
    # Shoulder (0, 0, 2), elbow 0.3 m below, wrist 0.28 m further; lengths 0.3, 0.28. The wrist's measured depth
    # reads 1.4 m behind and replaced the filter's (2.05): the measured elbow is 1.43 m from it. Restored: the
    # filter's point, and its variance times the running NIS (2 here).
    f0 = [0.0, 0.0, 2.0, 0.0, 0.3, 2.0, 0.0, 0.58, 2.05]
    m = [0.0, 0.0, 2.0, 0.0, 0.3, 2.0, 0.0, 0.58 * 3.4 / 2.0, 3.4]
    f = f0[:6] + m[6:]
    vs = [1e-4] * 6 + [R_XY, R_XY, R_Z]
    var = [1e-5] * 9
    nis = [2.0] * 9
    assert unreachable_replacements(f, vs, f0, m, (0, 3, 6), SUB, var, nis, 0.01, 0.3, 0.28, (R_XY, R_XY, R_Z),
                                    1e-4, 9.0) == 1
    assert f == f0
    assert vs[6:] == pytest.approx([2e-5] * 3, rel=1e-12)
    assert vs[:6] == [1e-4] * 6
    # Within reach (the filter's depth 10 cm off, the measured one on the arm): the replacement stays.
    f0[8] = 2.15
    m[7], m[8] = 0.58, 2.05
    f = f0[:6] + m[6:]
    vs = [1e-4] * 6 + [R_XY, R_XY, R_Z]
    assert unreachable_replacements(f, vs, f0, m, (0, 3, 6), SUB, var, nis, 0.01, 0.3, 0.28, (R_XY, R_XY, R_Z),
                                    1e-4, 9.0) == 0
    assert f[6:] == m[6:]
    # A shorter pair (a foreshortened depth error either way) is not tested: only a stretch beyond the reach.
    f = f0[:6] + [0.0, 0.35, 2.0]
    m[6:] = f[6:]
    assert unreachable_replacements(f, vs, f0, m, (0, 3, 6), SUB, var, nis, 0.01, 0.3, 0.28, (R_XY, R_XY, R_Z),
                                    1e-4, 9.0) == 0


def test_a_wrist_read_on_the_wall_behind_a_seen_shoulder_and_elbow_is_the_odd_one():
    # The shoulder and the elbow replaced the filter's (an EKF that had followed the wall) and fit each other; the
    # wrist reads the wall 1.4 m behind and its filter agrees (not replaced). Two against one: the wrist is the odd
    # joint, nothing replaced is undone. (Sequentially, the elbow-wrist pair blamed the replaced elbow, then the
    # shoulder-wrist pair the replaced shoulder.)
    m = [0.0, 0.0, 2.0, 0.0, 0.3, 2.0, 0.0, 0.58 * 3.4 / 2.0, 3.4]
    f0 = [0.0, 0.0, 2.6, 0.0, 0.3, 3.0, 0.0, 0.58 * 3.4 / 2.0, 3.35]
    f = m[:6] + f0[6:]
    vs = [R_XY, R_XY, R_Z] * 2 + [1e-4] * 3
    args = (f0, m, (0, 3, 6), SUB, [1e-5] * 9, [2.0] * 9, 0.01, 0.3, 0.28, (R_XY, R_XY, R_Z), 1e-4, 9.0)
    assert unreachable_replacements(f, vs, *args) == 0 and f[:6] == m[:6]
    # The same joints with the wrist replaced too: only the wrist's replacement is undone.
    f = list(m)
    assert unreachable_replacements(f, vs, *args) == 1 and f[:6] == m[:6] and f[6:] == f0[6:]
    # The odd joint read in front of the two that fit each other (an elbow and a wrist both on the wall, 1.5 m
    # behind, 28 cm apart; the shoulder seen): no majority; the pairs in order undo the elbow's replacement (the
    # outer joint of the stretched shoulder-elbow pair), then, the elbow no reading, the wrist's against the
    # shoulder; the shoulder's stands.
    m2 = [0.0, 0.0, 2.0, 0.0, 0.3, 3.5, 0.0, 0.58, 3.5]
    f0 = [0.0, 0.0, 2.6, 0.0, 0.3, 2.1, 0.0, 0.58, 2.1]
    f = list(m2)
    args = (f0, m2) + args[2:]
    assert unreachable_replacements(f, [R_XY, R_XY, R_Z] * 3, *args) == 2 and f[:3] == m2[:3] and f[3:] == f0[3:]
    # The wrist on the wall alone, with everything replaced and the shoulder read in front of the elbow (no joint
    # odd from both others): the elbow's replacement undone against the shoulder; the wrist's pair with the elbow,
    # no reading now, is not tested; the shoulder-wrist pair undoes the wrist's, and the shoulder's stands.
    m3 = [0.0, 0.0, 1.6, 0.0, 0.3, 2.0, 0.0, 0.58, 3.4]
    f0 = [0.0, 0.0, 2.6, 0.0, 0.3, 2.1, 0.0, 0.58, 2.1]
    f = list(m3)
    args = (f0, m3) + args[2:]
    assert unreachable_replacements(f, [R_XY, R_XY, R_Z] * 3, *args) == 2 and f[:3] == m3[:3] and f[3:] == f0[3:]


def test_the_nearer_wrist_of_a_too_long_forearm_is_the_odd_one():
    # shoulder at the origin, elbow 0.30 m below it (lu = 0.30), wrist 0.40 m from the elbow along -z (towards the
    # camera): a forearm 0.10 m too long (lf = 0.30) whose wrist is its nearer end
    s, e = (0.0, 0.0, 2.0), (0.0, 0.30, 2.0)
    f = (*s, *e, 0.0, 0.30, 1.60)
    vs = [1e-4] * 9  # (the nearer end: the variances are not asked)
    assert wrist_misfit(f, vs, 0.30, 0.30, 0.05, True)
    # the shoulder neither seen nor held: one against one
    assert not wrist_misfit(f, vs, 0.30, 0.30, 0.05, False)
    # the same length with the wrist behind the elbow, known as well as it: the elbow's depth is as likely wrong
    assert not wrist_misfit((*s, *e, 0.0, 0.30, 2.40), vs, 0.30, 0.30, 0.05, True)
    # a forearm within its length, or shorter: nothing to take
    assert not wrist_misfit((*s, *e, 0.0, 0.30, 1.705), vs, 0.30, 0.30, 0.05, True)
    assert not wrist_misfit((*s, *e, 0.0, 0.30, 1.75), vs, 0.30, 0.30, 0.05, True)
    assert wrist_misfit((*s, *e, 0.0, 0.30, 1.695), vs, 0.30, 0.30, 0.05, True)
    # an upper arm 6 cm off its length: the elbow does not fit its shoulder (one against one)
    assert not wrist_misfit(f, vs, 0.36, 0.30, 0.05, True)
    assert wrist_misfit(f, vs, 0.34, 0.30, 0.05, True)


def test_a_wrist_behind_its_seen_elbow_beyond_reach_and_known_worse_is_the_odd_one():
    # The held-out MediaPipe case: the wrist read on the wall 1.65 m behind the seen elbow, the filter following it
    # (its depth variance 100 cm^2 against the elbow's 2.4), the shoulder no anchor.
    s, e = (0.136, -0.097, 2.024), (0.259, -0.063, 1.761)
    vs = [0.6e-5, 0.2e-5, 0.9e-4, 0.45e-4, 0.7e-4, 2.4e-4, 6.5e-4, 6.7e-4, 102.5e-4]
    assert wrist_misfit((*s, *e, 0.545, -0.605, 3.409), vs, 0.29, 0.28, 0.05, False)
    # the elbow known worse than the wrist: as likely the elbow's depth that is wrong
    vs_e = vs[:5] + [200e-4] + vs[6:]
    assert not wrist_misfit((*s, *e, 0.545, -0.605, 3.409), vs_e, 0.29, 0.28, 0.05, False)
    # behind, but within the forearm's reach and the tolerance: a forearm pointing away, nothing to take
    assert not wrist_misfit((*s, *e, 0.259, -0.063, 1.761 + 0.32), vs, 0.29, 0.28, 0.05, False)
    assert wrist_misfit((*s, *e, 0.259, -0.063, 1.761 + 0.34), vs, 0.29, 0.28, 0.05, False)


def test_a_joint_lost_altogether_beyond_the_measured_elbows_reach_is_no_evidence():
    # The arm: shoulder, elbow, wrist; the elbow measured in 3D, the shoulder and the wrist lost altogether.
    prev = [0.18, 0.0, 2.0, 0.2, 0.29, 2.0, 0.2, 0.55, 1.95]
    m = [NAN] * 9
    m[3:6] = [0.2, 0.3, 2.0]
    offsets = (0, 3, 6)
    args = (0.29, 0.26, (1e-4, 1e-4, 2.5e-3), 1e-4, 9.0)
    # A filter that extrapolates both within reach (its variances growing): left as it is.
    f = [0.16, 0.02, 2.03, 0.2, 0.3, 2.0, 0.22, 0.52, 1.9]
    vs = [4e-4] * 9
    beyond_reach(f, vs, m, offsets, prev, *args)
    assert f == [0.16, 0.02, 2.03, 0.2, 0.3, 2.0, 0.22, 0.52, 1.9] and vs == [4e-4] * 9
    # A diverged filter (the paper's per-joint EKF): the shoulder 2.2 m off with a 3 cm sigma, the wrist 1.7 m:
    # both start from our last output, with 1 m^2 per axis.
    f = [-2.2, 1.5, 1.8, 0.2, 0.3, 2.0, -1.7, 4.0, 1.2]
    vs = [1e-3] * 9
    beyond_reach(f, vs, m, offsets, prev, *args)
    assert f[0:3] == prev[0:3] and f[6:9] == prev[6:9] and f[3:6] == [0.2, 0.3, 2.0]
    assert vs == [1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3, 1.0, 1.0, 1.0]
    # x, y detected (depths lost: not lost altogether), no measured elbow, or no last output: nothing to do.
    xy = list(m)
    xy[0:2], xy[6:8] = [-2.2, 1.5], [-1.7, 4.0]
    for m2, p2 in ((xy, prev), ([NAN] * 9, prev), (m, None)):
        f = [-2.2, 1.5, 1.8, 0.2, 0.3, 2.0, -1.7, 4.0, 1.2]
        vs = [1e-3] * 9
        beyond_reach(f, vs, m2, offsets, p2, *args)
        assert f == [-2.2, 1.5, 1.8, 0.2, 0.3, 2.0, -1.7, 4.0, 1.2] and vs == [1e-3] * 9


def test_a_wrist_whose_forearm_misfits_an_arm_that_fits_otherwise_is_misread():
    # An arm measured whole at flat offsets 0, 3, 6: the shoulder, the elbow 0.30 below it, the wrist 0.27 below the
    # elbow (lengths 0.30 / 0.27). The wrist read 6 cm short misfits its forearm by more than the 5 cm tolerance
    # while the upper arm fits: the wrist is the odd one out. 4 cm is within the tolerance; an upper arm that
    # misfits too leaves it open which reading is off (the elbow's, here); a coordinate not measured says nothing.
    arm = [0.0, 0.0, 2.0, 0.0, 0.30, 2.0, 0.0, 0.57, 2.0]
    assert not forearm_misread(arm, 0, 3, 6, 0.30, 0.27, 0.05)

    def read(**moved):
        m = list(arm)
        for k, d in moved.items():
            m[int(k[1:])] += d
        return m

    assert forearm_misread(read(i7=-0.06), 0, 3, 6, 0.30, 0.27, 0.05)
    assert not forearm_misread(read(i8=-0.08), 0, 3, 6, 0.30, 0.27, 0.05)  # (8 cm in front: a 28.2 cm forearm)
    assert forearm_misread(read(i8=-0.25), 0, 3, 6, 0.30, 0.27, 0.05)  # (25 cm in front: 36.8 cm)
    assert not forearm_misread(read(i7=-0.04), 0, 3, 6, 0.30, 0.27, 0.05)
    assert not forearm_misread(read(i4=0.06), 0, 3, 6, 0.30, 0.27, 0.05)  # the elbow's reading: both misfit
    assert not forearm_misread(read(i7=-0.06, i2=NAN), 0, 3, 6, 0.30, 0.27, 0.05)
    assert not forearm_misread(read(i7=-0.06, i8=NAN), 0, 3, 6, 0.30, 0.27, 0.05)


def test_the_held_forearm_is_not_taken_from_a_misread_wrist():
    # The arm output (nine floats) and the measurement at flat offsets 0, 3, 6: an arm measured whole and fitting its
    # lengths gives both holds from the output (the forearm, no blind frames, the upper arm it turns with). With
    # the wrist misread (6 cm short) the forearm held from before is kept and ages a frame, its misread frames count
    # one more (the last entry); the upper arm is taken. A wrist not detected keeps its hold as it is (its blind
    # frames are counted where it is used), and a wrist read right again gives a new hold, no misread frames.
    out = [0.0, 0.0, 2.0, 0.0, 0.30, 2.0, 0.0, 0.57, 2.0]
    blind, blind_e = held_segments(None, None, out, list(out), 0, 3, 6, 0.30, 0.27, 0.05)
    assert blind == pytest.approx([0.0, 0.27, 0.0, 0.0, 0.0, 0.30, 0.0, 0.0])
    assert blind_e == pytest.approx([0.0, 0.30, 0.0, 0.0])
    old = [0.01, 0.26, 0.02, 2.0, 0.0, 0.30, 0.0, 1.0]
    m = list(out)
    m[7] -= 0.06
    blind, blind_e = held_segments(list(old), None, out, m, 0, 3, 6, 0.30, 0.27, 0.05)
    assert blind == pytest.approx([0.01, 0.26, 0.02, 3.0, 0.0, 0.30, 0.0, 2.0])
    assert blind_e == pytest.approx([0.0, 0.30, 0.0, 0.0])
    blind, _ = held_segments(blind, None, out, list(out), 0, 3, 6, 0.30, 0.27, 0.05)
    assert blind == pytest.approx([0.0, 0.27, 0.0, 0.0, 0.0, 0.30, 0.0, 0.0])
    m[6] = m[7] = NAN
    blind, _ = held_segments(list(old), None, out, m, 0, 3, 6, 0.30, 0.27, 0.05)
    assert blind == old
    blind, _ = held_segments(None, None, out, None, 0, 3, 6, 0.30, 0.27, 0.05)  # (no measurement: all detected)
    assert blind[:3] == pytest.approx([0.0, 0.27, 0.0])
