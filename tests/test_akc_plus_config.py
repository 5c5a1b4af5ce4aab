import math

import pytest

from akc_drake.core.akc_plus import AKCPlusConfig as ReExported
from akc_drake.core.akc_plus_config import REFERENCE_PERIOD_S, AKCPlusConfig, akc_plus_config, per_frame


def test_defaults_are_the_measurement_model_of_the_kf():
    c = AKCPlusConfig()
    assert ReExported is AKCPlusConfig
    assert c.depth_sigma_m == 0.05 and c.image_sigma_m == 0.01 and c.length_sigma_m == 0.01
    assert c.gate_sigma == 3.0 and c.recent_frames == 3.0
    assert c.sigma_shoulder_m == 0.01 and c.shoulder_alpha == 0.2 and c.arm_radius_m == 0.05
    assert AKCPlusConfig(sigma_shoulder_m=0).sigma_shoulder_m == 0.0  # 0 turns the held shoulder off
    assert isinstance(AKCPlusConfig(gate_frames=4).gate_frames, float)
    # None: set from the filter AKC+ follows (``akc_plus_config``); True / False force it.
    assert c.constrained_filter is None and AKCPlusConfig(constrained_filter=True).constrained_filter is True
    # None: set by where AKC+ runs (on in the teleop diagram); True / False force it.
    assert c.seen_wrist_anchor is None and AKCPlusConfig(seen_wrist_anchor=False).seen_wrist_anchor is False
    # A seen depth after an EKF: fused with the filter's at the measured reading noise (False: taken as read).
    assert c.seen_depth_fusion is True and c.seen_depth_sigma_m == 0.015


@pytest.mark.parametrize("field, value", [("recent_frames", -1.0), ("gate_sigma", math.nan),
                                          ("sigma_temporal_m", 0.0), ("elbow_min_deg", 180.0),
                                          ("nis_alpha", True), ("nis_alpha", 0.0), ("nis_alpha", 1.2),
                                          ("shoulder_alpha", 0.0), ("elbow_offset_alpha", 1.5),
                                          ("elbow_offset_alpha", -0.1),
                                          ("shoulder_alpha", 1.5), ("sigma_shoulder_m", -0.01),
                                          ("arm_radius_m", -0.05), ("arm_cover_deg", 90.5), ("constrained_filter", 1),
                                          ("constrained_filter", "yes"), ("seen_wrist_anchor", 0.0),
                                          ("seen_depth_fusion", "no")])
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        AKCPlusConfig(**{field: value})


def test_settings_resolve_for_the_filter_they_follow():
    # None: the defaults, the switch set from the filter (on after the EKF, whose posterior holds bone lengths).
    assert akc_plus_config() == AKCPlusConfig()
    assert akc_plus_config(None, "EKF").constrained_filter is True
    assert akc_plus_config(None, "KF").constrained_filter is False
    # A mapping (plain data: a YAML map, --akc-plus, a worker's task) sets the fields it names.
    c = akc_plus_config({"gate_sigma": 2.5, "nis_alpha": 0.1}, "EKF")
    assert (c.gate_sigma, c.nis_alpha, c.constrained_filter) == (2.5, 0.1, True)
    assert c.depth_sigma_m == AKCPlusConfig().depth_sigma_m
    # A switch the settings give is kept whatever the filter; 1 / 0 stand for it in a map of numbers.
    assert akc_plus_config({"constrained_filter": False}, "EKF").constrained_filter is False
    assert akc_plus_config({"constrained_filter": 1.0}, "KF").constrained_filter is True
    assert akc_plus_config(AKCPlusConfig(constrained_filter=True), "KF").constrained_filter is True
    given = AKCPlusConfig(gate_sigma=2.0)
    assert akc_plus_config(given) is given
    # The seen wrist's anchor: set by ``teleop`` when left at None, kept when given (1 / 0 too); None leaves it.
    assert akc_plus_config(None, "KF", True).seen_wrist_anchor is True
    assert akc_plus_config(None, "KF", False).seen_wrist_anchor is False
    assert akc_plus_config(None, "KF").seen_wrist_anchor is None
    assert akc_plus_config({"seen_wrist_anchor": 0}, "KF", True).seen_wrist_anchor is False
    assert akc_plus_config(AKCPlusConfig(seen_wrist_anchor=True), "EKF", False).seen_wrist_anchor is True
    assert akc_plus_config({"seen_depth_fusion": 0}, "EKF").seen_depth_fusion is False


@pytest.mark.parametrize("settings, match", [({"gate_sgima": 2.5}, "unknown AKC\\+ setting.*'gate_sgima'.*gate_sigma"),
                                             ({"gate_sigma": -1.0}, "gate_sigma"),
                                             ({"constrained_filter": 2.0}, "constrained_filter"),
                                             ("gate_sigma=2.5", "mapping")])
def test_bad_settings_are_one_clear_error(settings, match):
    with pytest.raises(ValueError, match=match):
        akc_plus_config(settings)


def test_per_frame_settings_are_the_configs_at_ten_hertz():
    c = AKCPlusConfig()
    for period in (None, REFERENCE_PERIOD_S, 0.30000000000000004 - 0.2):  # (the last: 0.1 one ulp off)
        pf = per_frame(c, period)
        assert pf.step_sigma_m == c.sigma_temporal_m and pf.temporal_walk_var == c.sigma_temporal_m**2
        assert pf.shoulder_walk_var == c.sigma_shoulder_m**2
        assert pf.shoulder_alpha == c.shoulder_alpha and pf.nis_alpha == c.nis_alpha  # exactly, not 1 - (1 - a)
        assert pf.recent_frames == c.recent_frames and pf.gate_frames == c.gate_frames
        assert pf.hips_lost_frames == c.hips_lost_frames
        assert pf.jump_m == c.jump_m and pf.drift_m_per_frame == c.drift_m_per_frame


@pytest.mark.parametrize("rate_hz", [30.0, 15.0, 5.0])
def test_per_frame_settings_mean_the_same_in_seconds(rate_hz):
    """Motions, random walks, the shoulders' running means and frame counts; the running NIS per innovation."""
    c = AKCPlusConfig(nis_alpha=0.3)
    pf, n = per_frame(c, 1.0 / rate_hz), rate_hz / 10.0  # n frames at this rate per frame at 10 Hz
    # A motion between two frames (speed x period), and over one second:
    assert pf.step_sigma_m * rate_hz == pytest.approx(c.sigma_temporal_m * 10.0)
    assert pf.jump_m * n == pytest.approx(c.jump_m) and pf.drift_m_per_frame * n == pytest.approx(c.drift_m_per_frame)
    # A random walk's variance accumulated over one second:
    assert pf.temporal_walk_var * rate_hz == pytest.approx(c.sigma_temporal_m**2 * 10.0)
    assert pf.shoulder_walk_var * rate_hz == pytest.approx(c.sigma_shoulder_m**2 * 10.0)
    # The shoulders' running means forget as much per second: (1 - a')^n == 1 - a.
    assert (1.0 - pf.shoulder_alpha) ** n == pytest.approx(1.0 - c.shoulder_alpha)
    assert 0.0 < pf.shoulder_alpha <= 1.0
    # The running NIS averages as many innovations at every rate (its noise is set by their number).
    assert pf.nis_alpha == 0.3
    # Frame counts: as many seconds.
    assert pf.recent_frames / rate_hz == pytest.approx(c.recent_frames / 10.0)
    assert pf.gate_frames / rate_hz == pytest.approx(c.gate_frames / 10.0)
    assert pf.hips_lost_frames / rate_hz == pytest.approx(c.hips_lost_frames / 10.0)


@pytest.mark.parametrize("period", [0.0, -0.1, math.inf, math.nan, True, "0.1"])
def test_per_frame_rejects_a_bad_period(period):
    with pytest.raises(ValueError, match="period_s"):
        per_frame(AKCPlusConfig(), period)


def test_the_hand_rules_length_follows_the_operators_forearm():
    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
    from akc_drake.core.akc_plus_config import HAND_TO_FOREARM, hand_lengths
    from akc_drake.core.skeleton import BodyDimensions

    # The default: a share of each calibrated forearm, 8.5 cm on the rendered adult's 27.5 cm forearm.
    assert AKCPlusConfig().hand_length_m is None and HAND_TO_FOREARM == pytest.approx(0.30909, abs=1e-5)
    assert hand_lengths(AKCPlusConfig(), (0.275, 0.275)) == pytest.approx((0.085, 0.085))
    assert hand_lengths(AKCPlusConfig(), (0.32, 0.34)) == pytest.approx((0.102, 0.102))  # (1.2 times as large)
    assert hand_lengths(AKCPlusConfig(hand_length_m=0.09), (0.275, 0.33)) == (0.09, 0.09)
    # One hand size for both arms (the forearms' mean: a calibration's asymmetry is not the hands'); 0: off.
    dims = BodyDimensions(LUA=0.3, LLA=0.22, RUA=0.3, RLA=0.26, SW=0.36)
    hands = [h[-1] for h in ArmKinematicCorrectorPlus(dims)._hand]
    assert hands == pytest.approx([0.24 * HAND_TO_FOREARM, 0.24 * HAND_TO_FOREARM])
    assert ArmKinematicCorrectorPlus(dims, AKCPlusConfig(hand_length_m=0.0))._hand == ()
    with pytest.raises(ValueError, match="hand_length_m must be a finite number >= 0"):
        AKCPlusConfig(hand_length_m=-0.08)
