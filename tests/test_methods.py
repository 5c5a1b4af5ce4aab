"""The method runner's plumbing of the filter's covariance into AKC+ (evaluation/methods.py)."""

import numpy as np
import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_config import AKCPlusConfig
from akc_drake.core.kalman import ConstantVelocityKF
from akc_drake.core.skeleton import BodyDimensions
from akc_drake.evaluation.methods import MethodOptions, MethodRunner, run_akc, run_filter
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


@pytest.mark.parametrize("filt, refit", [("KF", False), ("EKF", True)])
def test_akc_plus_method_gets_the_filter_variance(filt, refit):
    """AKC+ gets the filter's variance; after an EKF, whose posterior holds bone lengths, it refits it
    (``constrained_filter``), after the KF not."""
    s = synthetic_session("II" if refit else "I", cycles=1, seed=5 if refit else 4)
    dims = BodyDimensions.paper_participant()
    runner = MethodRunner(s, dims)
    res = runner.run(f"AKC+({filt})")
    est, _ = runner.filtered(filt)
    var = runner.filter_variance(filt)
    assert var.shape == est.shape and np.all(var[np.isfinite(est)] > 0)
    accepted, _ = runner.occlusion()
    want, _, _ = run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig(constrained_filter=refit)), est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    # Without the variance (KF), or without the refit (EKF), the output differs: each is used.
    other = (run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig()), est, accepted, var) if refit
             else run_akc(ArmKinematicCorrectorPlus(dims), est, accepted))[0]
    assert not np.array_equal(np.nan_to_num(other), np.nan_to_num(want))


def test_akc_plus_settings_reach_the_method():
    """``MethodOptions.akc_plus_config`` as plain data (what ``--akc-plus`` and the workers carry): a switch it sets
    wins over the one made from the filter, and the other fields reach the corrector."""
    s = synthetic_session("II", cycles=1, seed=5)
    dims = BodyDimensions.paper_participant()
    settings = {"constrained_filter": False, "gate_sigma": 2.0}
    runner = MethodRunner(s, dims, options=MethodOptions(akc_plus_config=settings))
    res = runner.run("AKC+(EKF)")
    est, _ = runner.filtered("EKF")
    accepted, _ = runner.occlusion()
    var = runner.filter_variance("EKF")
    want, _, _ = run_akc(ArmKinematicCorrectorPlus(dims, AKCPlusConfig(gate_sigma=2.0, constrained_filter=False)),
                         est, accepted, var)
    np.testing.assert_array_equal(res.estimates, want)
    default = MethodRunner(s, dims).run("AKC+(EKF)").estimates
    assert not np.array_equal(np.nan_to_num(default), np.nan_to_num(want))
