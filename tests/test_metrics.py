import math
import warnings

import numpy as np
import pytest
import scipy.stats
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from akc_drake.core.metrics import (
    arm_length_range,
    joint_errors,
    l2_norm,
    pearson,
    pearson_per_axis,
    rms_euclidean,
    rmse_per_axis,
    segment_length_series,
)
from akc_drake.core.skeleton import INDEX


def test_rmse_hand_computed_with_nan_frames_excluded():
    true = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [3.0, 3.0, 3.0]])
    est = true + np.array([[0.1, 0.0, -0.3], [-0.1, 0.2, 0.4], [9.0, 9.0, np.nan], [0.1, -0.2, 0.0]])
    rmse, n = rmse_per_axis(est, true)
    assert n == 3
    # x: (0.01 + 0.01 + 0.01) / 3; y: (0 + 0.04 + 0.04) / 3; z: (0.09 + 0.16 + 0) / 3
    np.testing.assert_allclose(rmse, [0.1, math.sqrt(0.08 / 3), math.sqrt(0.25 / 3)], rtol=1e-12)
    # A NaN in the truth excludes the frame as well.
    true2 = true.copy()
    true2[0, 1] = np.nan
    assert rmse_per_axis(est, true2)[1] == 2
    r, n = rmse_per_axis(np.full((3, 3), np.nan), np.zeros((3, 3)))
    assert n == 0 and np.all(np.isnan(r))


def test_rms_euclidean_and_l2_norm_by_hand():
    true = np.zeros((2, 3))
    est = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
    assert rms_euclidean(est, true) == pytest.approx(math.sqrt((25 + 1) / 2), rel=1e-15)
    # Table IX, Vicon column: L2 of (10.7, 8.5, 4.0, 6.9) = 15.8 cm.
    assert l2_norm({"LELB": 10.7, "RELB": 8.5, "LSHO": 4.0, "RSHO": 6.9}) == pytest.approx(15.8, abs=0.05)
    assert l2_norm([3.0, 4.0]) == 5.0
    assert math.isnan(l2_norm([1.0, float("nan")]))
    assert math.isnan(rms_euclidean(np.full((2, 3), np.nan), true))


@settings(max_examples=60, deadline=None)
@given(
    st.integers(3, 40).flatmap(
        lambda n: st.tuples(
            st.lists(st.floats(-10, 10, allow_nan=False), min_size=n, max_size=n),
            st.lists(st.floats(-10, 10, allow_nan=False), min_size=n, max_size=n),
        )
    )
)
def test_pearson_equals_scipy(xy):
    x, y = (np.array(v) for v in xy)
    r, p = pearson(x, y)
    if np.ptp(x) < 1e-6 or np.ptp(y) < 1e-6:
        assume(False)  # near-constant series: scipy warns and both are ill-conditioned
    ref = scipy.stats.pearsonr(x, y)
    assert r == pytest.approx(ref.statistic, abs=1e-10)
    # p is ill-conditioned as |r| -> 1 (for n = 3, r = 1 - 1e-16 gives p ~ 1e-8 where scipy says 0).
    assert p == pytest.approx(ref.pvalue, abs=1e-6)


def test_pearson_per_axis_matches_scipy_on_a_trajectory_with_nan_frames():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 6, 80)
    true = np.stack([np.sin(t), np.cos(t), 0.1 * t], axis=1)
    est = true + rng.normal(0, [0.05, 0.3, 0.5], (80, 3))
    est[[4, 17, 50], 2] = np.nan
    true[60, 0] = np.inf
    r, p, n = pearson_per_axis(est, true)
    assert n == 76
    keep = np.isfinite(est).all(axis=1) & np.isfinite(true).all(axis=1)
    for k in range(3):
        ref = scipy.stats.pearsonr(est[keep, k], true[keep, k])
        assert r[k] == pytest.approx(ref.statistic, abs=1e-12)
        assert p[k] == pytest.approx(ref.pvalue, rel=1e-9, abs=1e-300)
    assert r[0] > r[1] > r[2] > 0.3


def test_pearson_degenerate_cases():
    # Constant series: r is NaN and p is defined as 1.0.
    r, p = pearson([1.0, 1.0, 1.0], [1.0, 2.0, 3.0])
    assert math.isnan(r) and p == 1.0
    r, p, n = pearson_per_axis(np.ones((5, 3)), np.arange(15.0).reshape(5, 3))
    assert n == 5 and np.all(np.isnan(r)) and np.all(p == 1.0)
    # Two samples: r = +-1, p = 1 (as scipy).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ref = scipy.stats.pearsonr([0.0, 1.0], [2.0, 1.0])
    assert pearson([0.0, 1.0], [2.0, 1.0]) == (pytest.approx(ref.statistic), ref.pvalue)
    # Perfect correlation: p = 0.
    r, p = pearson(np.arange(10.0), 2 * np.arange(10.0) + 1)
    assert r == pytest.approx(1.0) and p == 0.0
    r, p = pearson([1.0], [2.0])
    assert math.isnan(r) and p == 1.0


def straight_arm_trajectory(T: int = 5) -> np.ndarray:
    traj = np.zeros((T, 12, 3))
    for k in range(T):
        traj[k, INDEX["left_shoulder"]] = [0.15, 0, 2]
        traj[k, INDEX["left_elbow"]] = [0.15 + 0.30 + 0.01 * k, 0, 2]
        traj[k, INDEX["left_wrist"]] = [0.15 + 0.30 + 0.01 * k + 0.25, 0, 2]
        traj[k, INDEX["right_shoulder"]] = [-0.15, 0, 2]
        traj[k, INDEX["right_elbow"]] = [-0.45, 0, 2 - 0.02 * k]
        traj[k, INDEX["right_wrist"]] = [-0.45, 0.25, 2 - 0.02 * k]
    return traj


def test_arm_length_range_and_series():
    traj = straight_arm_trajectory()
    traj[2, INDEX["right_wrist"]] = np.nan
    rng_ = arm_length_range(traj)
    assert set(rng_) == {"LUA", "LLA", "RUA", "RLA"}
    assert rng_["LUA"] == pytest.approx(0.04, abs=1e-12)
    assert rng_["LLA"] == pytest.approx(0.0, abs=1e-12)
    assert rng_["RUA"] == pytest.approx(math.hypot(0.30, 0.08) - 0.30, abs=1e-12)
    assert rng_["RLA"] == pytest.approx(0.0, abs=1e-12)
    series = segment_length_series(traj)
    assert series["SW"].shape == (5,) and np.allclose(series["SW"], 0.30)
    assert math.isnan(series["RLA"][2])
    assert arm_length_range(traj, segments=["SW"]) == {"SW": pytest.approx(0.0, abs=1e-12)}
    traj[:, INDEX["left_wrist"]] = np.inf
    assert math.isnan(arm_length_range(traj)["LLA"])
    with pytest.raises(ValueError, match="'LXX'"):
        arm_length_range(traj, segments=["LXX"])


def test_joint_errors_table():
    rng = np.random.default_rng(0)
    true = np.repeat(straight_arm_trajectory(40)[:1], 40, axis=0) + rng.normal(0, 0.05, (40, 12, 3))
    est = true.copy()
    est[:, INDEX["left_elbow"]] += [0.01, -0.02, 0.0]  # constant bias: rmse = |bias|, r = 1
    est[7, INDEX["left_elbow"], 1] = np.nan
    table = joint_errors(est, true)
    assert list(table) == ["left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
                           "right_wrist"]
    le = table["left_elbow"]
    assert le["valid_frames"] == 39 and table["left_wrist"]["valid_frames"] == 40
    assert le["rmse_cm"] == pytest.approx({"x": 1.0, "y": 2.0, "z": 0.0}, abs=1e-9)
    assert le["corr"] == pytest.approx({"x": 1.0, "y": 1.0, "z": 1.0}, abs=1e-12)
    assert le["rms_euclidean_cm"] == pytest.approx(math.sqrt(5.0), abs=1e-9)
    assert table["left_wrist"]["rmse_cm"] == {"x": 0.0, "y": 0.0, "z": 0.0}
    assert list(joint_errors(est, true, joints=["left_hip"])) == ["left_hip"]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: rmse_per_axis(np.zeros((4, 2)), np.zeros((4, 2))), r"est must have shape \(T, 3\)"),
        (lambda: rmse_per_axis(np.zeros((4, 3)), np.zeros((5, 3))), "same shape"),
        (lambda: pearson_per_axis(np.zeros((4, 3)), np.zeros(4)), "true must have shape"),
        (lambda: joint_errors(np.zeros((4, 12, 3)), np.zeros((4, 12, 3)), ["nose"]), "'nose'"),
        (lambda: joint_errors(np.zeros((12, 3)), np.zeros((12, 3))), r"\(T, 12, 3\)"),
        (lambda: arm_length_range(np.zeros((4, 11, 3))), "trajectory must have shape"),
    ],
)
def test_bad_shapes_raise_naming_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
