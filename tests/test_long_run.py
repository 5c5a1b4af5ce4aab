"""Long runs (issue 9, part 5): a simulated teleop session with random dropouts keeps memory flat, never
commands NaN or exceeds a joint velocity limit, and keeps the filter covariances bounded.

CI runs a 30 s session; the full 30-minute one is ``-m slow`` (or ``akc-drake soak --minutes 30``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from akc_drake import cli
from akc_drake.commands.soak import MAX_RSS_GROWTH_MB, run_soak, soak_measurements
from akc_drake.core.kalman import (
    LOST,
    MAX_HELD_POSITION_VAR,
    ConstantVelocityKF,
    EKFConfig,
    ExtendedKalmanFilterCV,
    KFConfig,
)
from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.faults import inject_dropouts


def _check_summary(s: dict, minutes: float) -> None:
    assert s["simulated_s"] == pytest.approx(60.0 * minutes)
    assert s["nan_commands"] == 0
    assert s["max_joint_speed_ratio"] <= 1.0 + 1e-9 and not s["joint_velocity_limit_exceeded"]
    assert 0.0 < s["max_joint_acceleration_ratio"] <= 1.0 + 1e-9
    assert s["rss_growth_mb"] < 10.0 <= MAX_RSS_GROWTH_MB
    variances = np.asarray(s["max_position_variance_m2"]["value"])
    assert np.isfinite(variances).all() and variances.max() <= MAX_HELD_POSITION_VAR * (1 + 1e-9)
    assert 0.15 < s["tracking_lost_share"] < 0.6  # the robot is told when the person is gone
    assert s["ok"] and all(c["ok"] for c in s["checks"].values())


def test_soak_command_30_s(tmp_path, capsys):
    out = tmp_path / "soak.json"
    rc = cli.main(["soak", "--minutes", "0.5", "--dropout", "0.3", "--garbage", "0.05", "--sample-s", "2.5",
                   "--json", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert "all checks passed" in captured.out
    s = json.loads(out.read_text())
    _check_summary(s, 0.5)
    assert s["frames"] == 300 and abs(s["dropout_share"] - 0.3 * 290 / 300) < 0.01
    assert 0.04 < s["garbage_share"] < 0.06
    assert len(s["rss_mb"]["rss"]) == 13


@pytest.mark.slow
def test_soak_30_minutes():
    s = run_soak(30.0, dropout=0.3, garbage=0.02, seed=1, sample_s=30.0)
    _check_summary(s, 30.0)


def test_soak_measurements_repeat_one_rendered_cycle():
    meas, info = soak_measurements(0.25, dropout=0.0)
    assert info["frames"] == 150 and meas.num_frames == 150
    np.testing.assert_array_equal(meas.landmarks_C[60:120], meas.landmarks_C[:60])
    lost, info = soak_measurements(0.25, dropout=0.5, seed=4)
    assert info["bursts"] >= 1 and abs(info["dropout_share"] - 0.5 * 140 / 150) < 0.01
    assert np.isfinite(lost.landmarks_C[:10]).any(axis=2).all()  # the first second is clean


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["soak", "--minutes", "-1"], "--minutes"),
        (["soak", "--minutes", "nan"], "--minutes"),
        (["soak", "--dropout", "1.5"], "--dropout"),
        (["soak", "--garbage", "-0.1"], "--garbage"),
    ],
)
def test_soak_bad_options(capsys, argv, expected):
    assert cli.main(argv) == 2
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and expected in lines[0]


@pytest.mark.parametrize("mode", ["KF", "EKF"])
def test_filter_covariance_stays_bounded_over_30_minutes_of_dropouts(mode):
    """Core filters over 30 simulated minutes (18000 frames): landmarks lost in random bursts, and the hips
    lost for good after the first minute. Every variance stays finite and bounded."""
    rng = np.random.default_rng(0)
    T = 18000
    t = 0.1 * np.arange(T)
    base = np.array([[0.17, -0.2, 2.0], [-0.17, -0.2, 2.0], [0.3, 0.0, 1.9], [-0.3, 0.0, 1.9],
                     [0.35, 0.25, 1.7], [-0.35, 0.25, 1.7], [0.37, 0.3, 1.65], [-0.37, 0.3, 1.65],
                     [0.36, 0.32, 1.64], [-0.36, 0.32, 1.64], [0.12, 0.3, 2.0], [-0.12, 0.3, 2.0]])
    swing = 0.1 * np.sin(2 * np.pi * t / 6.0)[:, None, None] * np.array([0.0, 1.0, -1.0])
    z = base + swing + rng.normal(scale=[0.005, 0.005, 0.03], size=(T, 12, 3))

    class _M:  # what inject_dropouts needs
        landmarks_C, visibility, pixels = z, np.ones((T, 12)), np.zeros((T, 12, 2))

    z = inject_dropouts(_M(), 0.3, seed=1, start_frame=10)[0].landmarks_C
    z[600:, [INDEX["left_hip"], INDEX["right_hip"]]] = np.nan
    z[rng.random((T, 12)) < 0.2, 2] = np.nan  # depth dropped now and then (the occlusion filter's proximity)
    f = (ConstantVelocityKF(config=KFConfig(max_predict_s=0.3, gate_sigma=5.0, gate_whole_landmark=True))
         if mode == "KF" else
         ExtendedKalmanFilterCV(BodyDimensions.paper_participant(),
                                EKFConfig(max_predict_s=0.3, gate_sigma=5.0, gate_whole_landmark=True)))
    worst = 0.0
    for k in range(T):
        f.step(z[k], 0.1)
        if k % 600 == 599:
            var = f.position_variance
            assert np.isfinite(var).all()
            worst = max(worst, float(var.max()))
            if hasattr(f, "arm_covariance"):
                P = f.arm_covariance
                assert np.isfinite(P).all() and np.linalg.eigvalsh(0.5 * (P + P.T)).min() > -1e-9
    assert np.isfinite(f.get_state_vector()).all()
    assert (f.status[[INDEX["left_hip"], INDEX["right_hip"]]] == LOST).all()
    assert worst <= MAX_HELD_POSITION_VAR
    if mode == "KF":
        assert worst == pytest.approx(MAX_HELD_POSITION_VAR)  # the held hips reached the cap and stayed
