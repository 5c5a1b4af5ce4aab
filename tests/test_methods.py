"""The method runner's plumbing of the filter's covariance into AKC+ (evaluation/methods.py)."""

import numpy as np

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.kalman import ConstantVelocityKF
from akc_drake.core.skeleton import BodyDimensions
from akc_drake.evaluation.methods import MethodRunner, run_akc, run_filter
from tests.test_evaluation import synthetic_session


def test_run_filter_records_the_posterior_variance_of_every_step():
    s = synthetic_session("I", cycles=1, seed=3)
    z = s.raw.copy()
    z[10:20, 2, 2] = np.nan  # a lost depth: its variance grows while the others stay
    var = np.empty_like(z)
    est, dt = run_filter(ConstantVelocityKF(), z, s.t, var)
    again, _ = run_filter(ConstantVelocityKF(), z, s.t)
    np.testing.assert_array_equal(est, again)  # recording does not change the filter
    kf = ConstantVelocityKF()
    steps = np.diff(s.t, prepend=s.t[0] - (s.t[1] - s.t[0]))
    for k in range(15):
        kf.step(z[k], float(steps[k]))
    np.testing.assert_allclose(var[14], kf.position_variance, rtol=0, atol=0)
    assert np.all(np.diff(var[10:20, 2, 2]) > 0) and var[19, 2, 2] > 4 * var[9, 2, 2]
    assert dt.shape == (s.num_frames,)


def test_akc_plus_method_gets_the_filter_variance():
    s = synthetic_session("I", cycles=1, seed=4)
    dims = BodyDimensions.paper_participant()
    runner = MethodRunner(s, dims)
    res = runner.run("AKC+(KF)")
    kf_est, _ = runner.filtered("KF")
    var = runner.filter_variance("KF")
    assert var.shape == kf_est.shape and np.all(var[np.isfinite(kf_est)] > 0)
    accepted, _ = runner.occlusion()
    want, _, _ = run_akc(ArmKinematicCorrectorPlus(dims), kf_est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    without, _, _ = run_akc(ArmKinematicCorrectorPlus(dims), kf_est, accepted)
    assert not np.array_equal(np.nan_to_num(without), np.nan_to_num(want))


def test_akc_plus_after_an_ekf_refits_its_constrained_posterior():
    """AKC+(EKF) runs with ``constrained_filter`` (the EKF's posterior holds bone lengths), AKC+(KF) without."""
    from akc_drake.core.akc_plus_config import AKCPlusConfig

    s = synthetic_session("II", cycles=1, seed=5)
    dims = BodyDimensions.paper_participant()
    runner = MethodRunner(s, dims)
    res = runner.run("AKC+(EKF)")
    ekf_est, _ = runner.filtered("EKF")
    var = runner.filter_variance("EKF")
    accepted, _ = runner.occlusion()
    refit = ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=True))
    want, _, _ = run_akc(refit, ekf_est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    plain, _, _ = run_akc(ArmKinematicCorrectorPlus(dims), ekf_est, accepted, var)
    assert not np.array_equal(np.nan_to_num(plain), np.nan_to_num(want))
