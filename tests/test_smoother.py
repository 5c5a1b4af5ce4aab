"""RTS smoother: its forward pass is our KF, its backward pass filterpy's RTS, and it beats the KF offline."""

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother

from akc_drake.core.akc import ArmKinematicCorrector
from akc_drake.core.kalman import ConstantVelocityKF, KFConfig
from akc_drake.core.skeleton import SEGMENT_NAMES, BodyDimensions, segment_lengths
from akc_drake.core.smoother import kf_forward, rts_gain, rts_smooth, smoothed_stages

DT = 0.1


def session(T=150, seed=0, gap=(60, 64)):
    rng = np.random.default_rng(seed)
    t = np.arange(T) * DT
    truth = np.empty((T, 12, 3))
    for j in range(12):
        for a in range(3):
            truth[:, j, a] = 0.25 * np.sin(2 * np.pi * t / 6 + j + 2 * a) + 0.1 * j + (2.0 if a == 2 else 0.0)
    z = truth + rng.normal(size=truth.shape) * np.array([0.01, 0.01, 0.05])
    z[rng.random((T, 12)) < 0.2, 2] = np.nan  # the occlusion filter drops depths
    z[gap[0]:gap[1]] = np.nan  # a short dropout (< max_predict_s)
    return truth, z


def test_forward_pass_is_our_kf():
    _, z = session(gap=(40, 55))  # one gap longer than max_predict_s: the KF re-initialises after it
    kf = ConstantVelocityKF()
    ours, held = [], []
    for zk in z:
        ours.append(kf.step(zk, DT))
        held.append(kf.axis_age > kf.config.max_predict_s - DT + 1e-9)
    ours, held = np.array(ours), np.array(held)
    f = kf_forward(z, DT, reinit_after_gap=True)
    # The KF reads NaN on an axis never measured yet; an axis 1 s into a gap it holds (zero velocity), where
    # kf_forward keeps predicting (those frames are not used: the next measurement re-initialises both).
    seen = np.isfinite(ours) & ~held
    assert seen.mean() > 0.95
    np.testing.assert_allclose(f["p"].reshape(ours.shape)[seen], ours[seen], rtol=0, atol=1e-12)


def test_backward_pass_matches_filterpy_textbook_rts():
    _, z = session(T=60)
    cfg = KFConfig()
    series = z[:, 3, 0]  # one axis; filterpy needs a measurement each step: fill the dropout by a big R instead
    series = np.where(np.isfinite(series), series, 0.0)
    missing = ~np.isfinite(z[:, 3, 0])
    # The same filter in filterpy (6 lines of textbook matrices), initialised as ours at the first measurement.
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.F = np.array([[1, DT], [0, 1]])
    kf.H = np.array([[1.0, 0.0]])
    q = cfg.accel_psd[0]
    kf.Q = q * np.array([[DT**3 / 3, DT**2 / 2], [DT**2 / 2, DT]])
    kf.x = np.array([series[0], 0.0])
    kf.P = np.diag([cfg.sigma_x**2, cfg.init_vel_var])
    xs, Ps, Fs, Qs = [kf.x.copy()], [kf.P.copy()], [kf.F], [kf.Q]
    for k in range(1, len(series)):
        kf.predict()
        if not missing[k]:
            kf.update(series[k], R=cfg.sigma_x**2)
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
        Fs.append(kf.F)
        Qs.append(kf.Q)
    xs_s, _, _, _ = rts_smoother(np.array(xs), np.array(Ps), np.array(Fs), np.array(Qs))
    zz = np.full((len(series), 1, 3), np.nan)
    zz[:, 0, 0] = np.where(missing, np.nan, series)
    ours = rts_smooth(zz, DT, cfg)[:, 0, 0]
    np.testing.assert_allclose(ours, xs_s[:, 0], rtol=0, atol=1e-10)


def test_rts_is_more_accurate_and_interpolates_gaps():
    truth, z = session()
    kf = ConstantVelocityKF()
    fwd = np.array([kf.step(zk, DT) for zk in z])
    sm = rts_smooth(z, DT)
    rmse = lambda e: np.sqrt(np.nanmean(e**2, axis=(0, 1)))  # noqa: E731
    assert np.all(rmse(sm - truth) < 0.8 * rmse(fwd - truth))
    # Inside the dropout the smoother interpolates between both sides: far better than the KF's extrapolation.
    g = slice(60, 64)
    assert np.sqrt(np.mean((sm[g] - truth[g]) ** 2)) < 0.6 * np.sqrt(np.mean((fwd[g] - truth[g]) ** 2))


def test_long_gaps_are_bridged_and_the_ends_not_extrapolated():
    truth, z = session(gap=(40, 70))  # 3 s > max_predict_s = 1 s
    sm = rts_smooth(z, DT, KFConfig(max_predict_s=1.0))
    assert np.all(np.isfinite(sm[:, :, :2]))  # x, y are measured up to the last frame: every gap bridged
    # Inside the 3 s gap the smoother interpolates (the real-time KF holds after 1 s): bounded by both ends.
    kf = ConstantVelocityKF(config=KFConfig(max_predict_s=1.0))
    fwd = np.array([kf.step(zk, DT) for zk in z])
    g = slice(50, 70)
    assert np.sqrt(np.mean((sm[g] - truth[g]) ** 2)) < np.sqrt(np.nanmean((fwd[g] - truth[g]) ** 2))
    # An axis that stops being measured: NaN more than max_predict_s after its last measurement.
    z2 = z.copy()
    z2[100:, 0, 2] = np.nan
    sm2 = rts_smooth(z2, DT, KFConfig(max_predict_s=1.0))
    last = np.flatnonzero(np.isfinite(z2[:, 0, 2]))[-1]
    assert np.all(np.isfinite(sm2[: last + 10, 0, 2])) and np.all(np.isnan(sm2[last + 11 :, 0, 2]))


def test_smoothed_stages_keep_akc_lengths_and_report_gain():
    dims = BodyDimensions.paper_participant()
    truth, z = session()
    out = smoothed_stages(z, DT, dims)
    seg = segment_lengths(out["corrected"])
    for name, length in zip(SEGMENT_NAMES[:4], dims.as_array()[:4], strict=True):
        np.testing.assert_allclose(seg[name][np.isfinite(seg[name])], length, atol=1e-9)
    kf, akc = ConstantVelocityKF(), ArmKinematicCorrector(dims)
    fwd = np.array([kf.step(zk, DT) for zk in z])
    forward = {"filtered": fwd, "corrected": np.array([akc.correct(p).pose for p in fwd])}
    gain = rts_gain(truth, forward, out)
    assert gain["filtered"]["rts_rmse_cm"] < gain["filtered"]["forward_rmse_cm"]
    assert gain["filtered"]["gain_percent"] > 20


def test_bad_input():
    with pytest.raises(ValueError, match="shape"):
        rts_smooth(np.zeros((5, 3)), DT)
    with pytest.raises(ValueError, match="dt"):
        rts_smooth(np.zeros((5, 2, 3)), 0.0)
