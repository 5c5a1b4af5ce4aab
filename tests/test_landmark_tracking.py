"""core/landmark_tracking.py: the filter stage's per-frame rules (filter choice, swaps, lost landmarks, period)."""

from __future__ import annotations

import numpy as np
import pytest

from akc_drake.core.ekf import ExtendedKalmanFilterCV
from akc_drake.core.kalman import LEFT_RIGHT_SWAP, LOST, TRACKING, ConstantVelocityKF, EKFConfig, KFConfig
from akc_drake.core.landmark_tracking import (
    MAX_SWAP_FRAMES,
    MODES,
    filter_period,
    make_filter,
    taken_measurement,
    track_step,
)
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS, BodyDimensions

DIMS = BodyDimensions.paper_participant()


def _clone(f, cfg=None):
    """A filter in the same state as ``f`` (through its state vector)."""
    g = ConstantVelocityKF(NUM_LANDMARKS, cfg)
    g.set_state_vector(f.get_state_vector())
    return g


def _pose():
    """A person 2 m away, left side at x = +0.2 m, right at -0.2 m, joints spread in y."""
    p = np.zeros((NUM_LANDMARKS, 3))
    for j, name in enumerate(LANDMARKS):
        p[j] = [0.2 if name.startswith("left") else -0.2, -0.3 + 0.05 * j, 2.0]
    return p


def test_make_filter_picks_the_core_filter_and_names_bad_options():
    mode, f = make_filter("kf")
    assert mode == "KF" and isinstance(f, ConstantVelocityKF) and MODES == ("KF", "EKF")
    mode, f = make_filter("EKF", DIMS, EKFConfig(max_predict_s=0.4))
    assert mode == "EKF" and isinstance(f, ExtendedKalmanFilterCV)
    _, f = make_filter("KF", None, EKFConfig(max_predict_s=0.4))  # an EKFConfig gives the KF its KF part
    assert isinstance(f, ConstantVelocityKF) and f.config.max_predict_s == 0.4
    for args, match in ((("UKF",), "mode must be one of KF, EKF, got 'UKF'"), (("EKF",), "needs the body dim"),
                        (("EKF", DIMS, KFConfig()), "needs an EKFConfig, got KFConfig"),
                        (("KF", None, {"q": 1}), "needs a KFConfig, got dict")):
        with pytest.raises(ValueError, match=match):
            make_filter(*args)


def test_filter_period_from_a_period_a_rate_or_the_default():
    assert filter_period(0.05) == 0.05 and filter_period(rate_hz=20) == 0.05
    assert filter_period(default_rate_hz=30.0) == pytest.approx(1 / 30) and filter_period() == 0.1
    for kw, match in (({"period_s": 0.1, "rate_hz": 10}, "not both"), ({"rate_hz": -1}, "rate_hz"),
                      ({"period_s": float("nan")}, "period_s"), ({"period_s": "0.1"}, "period_s")):
        with pytest.raises(ValueError, match=match):
            filter_period(**kw)


def test_step_without_the_rules_is_the_core_filter_step():
    rng = np.random.default_rng(3)
    f = ConstantVelocityKF()
    ref = ConstantVelocityKF()
    for _ in range(8):
        z = _pose() + rng.normal(scale=0.01, size=(NUM_LANDMARKS, 3))
        est, status, swaps = track_step(f, z, 0.1, 2.0, nan_when_lost=False)
        np.testing.assert_array_equal(est, ref.step(z, 0.1))
        np.testing.assert_array_equal(status, ref.status)
        assert swaps == 2.0  # untouched without fix_swaps
    assert (status == TRACKING).all()


def test_a_lost_landmark_reads_nan_only_with_nan_when_lost():
    cfg = KFConfig(max_predict_s=0.3)
    z = _pose()
    f = ConstantVelocityKF(NUM_LANDMARKS, cfg)
    for _ in range(3):
        track_step(f, z, 0.1)
    g = _clone(f, cfg)
    gone = z.copy()
    gone[4] = np.nan  # the left wrist leaves the image
    for _ in range(4):  # 0.4 s > max_predict_s
        est, status, _ = track_step(f, gone, 0.1)
        held, status_g, _ = track_step(g, gone, 0.1, nan_when_lost=False)
    assert status[4] == LOST and status_g[4] == LOST and (np.delete(status, 4) == TRACKING).all()
    assert np.isnan(est[4]).all() and np.isfinite(np.delete(est, 4, axis=0)).all()
    np.testing.assert_allclose(held[4], z[4], atol=1e-9)  # a still landmark held where it was
    np.testing.assert_array_equal(np.delete(est, 4, axis=0), np.delete(held, 4, axis=0))


def test_a_swapped_frame_is_used_exchanged_for_at_most_max_swap_frames():
    z = _pose()
    f = ConstantVelocityKF()
    for _ in range(5):
        track_step(f, z, 0.1, fix_swaps=True)
    ref = _clone(f)
    swaps = 0.0
    mirrored = z[LEFT_RIGHT_SWAP]
    for k in range(MAX_SWAP_FRAMES):
        est, _, swaps = track_step(f, mirrored, 0.1, swaps, fix_swaps=True)
        np.testing.assert_array_equal(est, ref.step(z, 0.1))  # read as if unswapped
        assert swaps == k + 1
    # One more: a "swap" this long is the filter's own labelling; the frame is used as labelled.
    est, _, swaps = track_step(f, mirrored, 0.1, swaps, fix_swaps=True)
    assert swaps == MAX_SWAP_FRAMES
    np.testing.assert_array_equal(est, ref.step(mirrored, 0.1))
    # Without the rule the mirrored frame is used as labelled from the start.
    g = ConstantVelocityKF()
    for _ in range(5):
        track_step(g, z, 0.1)
    est, _, swaps = track_step(g, mirrored, 0.1, 0.0)
    assert swaps == 0.0 and est[0, 0] < 0.2  # pulled toward the mirrored (right-side) measurement
    # A normal frame resets the count.
    _, _, swaps = track_step(f, f.position + 0.1 * f.velocity, 0.1, 3.0, fix_swaps=True)
    assert swaps == 0.0


def test_taken_is_the_measurement_as_the_filter_took_it():
    """``taken``: exchanged where the swap rule exchanged the sides; NaN where the gate rejected a reading."""
    f = ConstantVelocityKF(NUM_LANDMARKS, KFConfig(gate_sigma=5.0, gate_whole_landmark=True))
    z = _pose()
    taken = np.empty((NUM_LANDMARKS, 3))
    for _ in range(10):
        track_step(f, z, 0.1, fix_swaps=True, taken=taken)
        np.testing.assert_array_equal(taken, z)
    track_step(f, z[LEFT_RIGHT_SWAP], 0.1, fix_swaps=True, taken=taken)
    np.testing.assert_array_equal(taken, z)  # the mislabelled frame, taken as the person's sides
    jump = z.copy()
    jump[3, 1] += 1.0
    track_step(f, jump, 0.1, taken=taken)
    assert np.isnan(taken[3]).all()
    np.testing.assert_array_equal(np.delete(taken, 3, axis=0), np.delete(z, 3, axis=0))
    np.testing.assert_array_equal(np.isnan(taken_measurement(f, jump)), np.isnan(taken))
