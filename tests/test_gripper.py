"""The pinch detector (akc_drake.core.gripper): closes on a closed hand, opens on an open one, hysteresis."""

import numpy as np
import pytest

from akc_drake.core.gripper import (
    OPEN_HAND_APERTURE_M,
    PINCH_APERTURE_M,
    GripperHysteresis,
    aperture_from_closure,
)


def test_closes_on_a_closed_hand_and_opens_on_an_open_one():
    h = GripperHysteresis()
    assert h.step(False, PINCH_APERTURE_M) is True
    assert h.step(True, OPEN_HAND_APERTURE_M) is False
    assert h.opening(True) == h.closed_m and h.opening(False) == h.open_m


def test_hysteresis_and_missing_measurements_keep_the_state():
    h = GripperHysteresis(close_below_m=0.035, open_above_m=0.055)
    between = 0.045
    assert h.step(False, between) is False and h.step(True, between) is True
    assert h.step(True, float("nan")) is True and h.step(False, float("nan")) is False
    # Noise of 4 mm around a half-closed hand (4.5 cm) never toggles the gripper.
    rng = np.random.default_rng(3)
    state = True
    for d in between + rng.normal(0.0, 0.003, 500):
        state = h.step(state, float(d))
    assert state is True


def test_aperture_of_a_closing_hand_and_bad_parameters():
    d = aperture_from_closure([0.0, 0.5, 1.0])
    np.testing.assert_allclose(
        d, [OPEN_HAND_APERTURE_M, 0.5 * (OPEN_HAND_APERTURE_M + PINCH_APERTURE_M), PINCH_APERTURE_M]
    )
    noisy = aperture_from_closure(np.ones(1000), np.random.default_rng(0), noise_m=0.004)
    assert abs(float(np.std(noisy)) - 0.004) < 0.0005
    with pytest.raises(ValueError, match="close_below_m"):
        GripperHysteresis(close_below_m=0.06, open_above_m=0.05)
    with pytest.raises(ValueError, match="open_m"):
        GripperHysteresis(open_m=-0.01)
