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


def _hand(tip_gap_px=(40.0, 0.0, 0.0), centre=(320.0, 240.0)):
    """21 hand landmarks (pixels, z in pixels): the palm around ``centre``, the thumb and index tips apart."""
    from akc_drake.core.gripper import INDEX_TIP, NUM_HAND_LANDMARKS, PALM_LANDMARKS, THUMB_TIP

    h = np.zeros((NUM_HAND_LANDMARKS, 3))
    h[:, :2] = centre
    for k, i in enumerate(PALM_LANDMARKS):
        h[i, :2] = (centre[0] + 4 * k, centre[1] + 20 + 3 * k)
    h[THUMB_TIP] = (centre[0], centre[1] - 30, 0.0)
    h[INDEX_TIP] = h[THUMB_TIP] + np.asarray(tip_gap_px)
    return h


def test_pinch_distance_scales_pixels_by_the_palm_depth():
    from akc_drake.core.camera import CameraIntrinsics
    from akc_drake.core.gripper import pinch_distance_m

    K = CameraIntrinsics(fx=600.0, fy=600.0)
    depth = np.full((K.height, K.width), 1.5)
    # 40 px at 1.5 m with f = 600 px: 0.1 m; a fingertip-sized depth spike at a tip is not read.
    h = _hand((40.0, 0.0, 0.0))
    depth[int(h[8, 1]) - 2 : int(h[8, 1]) + 3, int(h[8, 0]) - 2 : int(h[8, 0]) + 3] = 4.0
    assert pinch_distance_m(h, depth, K) == pytest.approx(0.1, abs=1e-12)
    # MediaPipe's relative depth counts: 30 px across and 40 px along the view axis are 50 px.
    assert pinch_distance_m(_hand((30.0, 0.0, 40.0)), depth, K) == pytest.approx(0.125, abs=1e-12)
    # No valid depth on the palm: unknown.
    assert np.isnan(pinch_distance_m(h, np.zeros_like(depth), K))
    with pytest.raises(ValueError):
        pinch_distance_m(np.zeros((20, 3)), depth, K)


def test_hand_sides_from_labels_and_from_the_pose_wrists():
    from akc_drake.core.gripper import hand_sides

    a, b = _hand(centre=(200.0, 300.0)), _hand(centre=(420.0, 300.0))
    # The Tasks API's labels are the person's own hands on an unmirrored image; mirrored swaps them.
    assert hand_sides(["Right", "Left"], [a, b]) == {"right": 0, "left": 1}
    assert hand_sides(["Right", "Left"], [a, b], mirrored=True) == {"left": 0, "right": 1}
    # Two hands with one label (MediaPipe does this): the image order, the person's right further left.
    assert hand_sides(["Left", "Left"], [a, b]) == {"right": 0, "left": 1}
    assert hand_sides(["Left", "Left"], [b, a]) == {"left": 0, "right": 1}
    assert hand_sides(["Right", "Right"], [a, b], mirrored=True) == {"left": 0, "right": 1}
    # One hand, no pose: its label.
    assert hand_sides(["Left"], [a]) == {"left": 0}
    # The pose's wrists outrank the labels (here both "Left"): each wrist takes the nearest hand.
    wrists = np.array([b[0, :2] + 5.0, a[0, :2] - 5.0])  # left wrist at hand b, right wrist at hand a
    assert hand_sides(["Left", "Left"], [a, b], wrists) == {"left": 1, "right": 0}
    # A pose wrist far from every hand (beyond 1.5 hand sizes) takes none, and the labels are not asked.
    far = np.array([[10.0, 10.0], [630.0, 10.0]])
    assert hand_sides(["Right", "Left"], [a, b], far) == {}
    # One pose wrist unknown (NaN): the other still takes its hand; the other hand is nobody's.
    half = np.array([[np.nan, np.nan], a[0, :2]])
    assert hand_sides(["Left", "Left"], [a, b], half) == {"right": 0}
    # No pose wrist known at all (NaN): the labels and the image order, as without a pose.
    assert hand_sides(["Left", "Left"], [a, b], np.full((2, 2), np.nan)) == {"right": 0, "left": 1}
    assert hand_sides([], [], wrists) == {}


def test_a_foreshortened_right_hand_labelled_left_does_not_command_the_left_gripper():
    """The bug seen in the closed-loop task: the right hand reaching toward the camera, alone in the frame and
    labelled "Left" by MediaPipe, its wrist-to-knuckle length foreshortened to 7 px, 10 px from the pose's right
    wrist: the gate (1.5 x 7 px) failed, the labels took over and its pinch closed the left gripper."""
    from akc_drake.core.gripper import hand_sides, hand_size_px

    h = _hand(centre=(260.0, 300.0))
    h[9, :2] = h[0, :2] + (0.0, -7.0)  # the middle knuckle 7 px from the wrist (end-on)
    h[12, :2] = h[0, :2] + (25.0, -52.0)  # the fingers fanned out across the image
    pose = np.array([[390.0, 297.0], h[0, :2] + (9.0, 9.0)])  # the left wrist far right in the image, right at h
    dist = float(np.linalg.norm(pose[1] - h[0, :2]))
    assert 1.5 * 7.0 < dist < 1.5 * hand_size_px(h)[0]  # outside the wrist-to-knuckle gate, inside the size's
    assert hand_sides(["Left"], [h], pose) == {"right": 0}
    # Even where no pose wrist is near it, a known pose keeps the label from assigning it to the left.
    assert hand_sides(["Left"], [h], np.array([[390.0, 297.0], [600.0, 50.0]])) == {}


def test_gripper_states_and_the_hand_channel_report():
    from akc_drake.core.gripper import gripper_states, hand_channel_report

    t = np.arange(8) * 0.1
    want = np.array([[0, 0], [0, 0], [0, 1], [0, 1], [0, 1], [0, 0], [0, 0], [0, 0]], dtype=bool)
    # The right hand pinches one frame late and opens on time; the left is open but lost in two frames.
    ap = np.array(
        [[0.1, 0.1], [0.1, 0.1], [0.1, 0.04], [np.nan, 0.02], [np.nan, 0.02], [0.1, 0.07], [0.1, 0.1], [0.1, 0.1]]
    )
    truth = np.where(want, 0.015, 0.1)
    states = gripper_states(ap)
    np.testing.assert_array_equal(states[:, 1], [0, 0, 0, 1, 1, 0, 0, 0])
    np.testing.assert_array_equal(states[:, 0], 0)
    r = hand_channel_report(ap, truth, want, t)
    assert r["left"]["found"] == pytest.approx(6 / 8)
    assert r["left"]["state_agreement"] == 1.0 and r["left"]["switch_delay_s"] == []
    assert r["right"]["found"] == 1.0
    assert r["right"]["state_agreement"] == pytest.approx(7 / 8)
    assert r["right"]["switch_delay_s"] == pytest.approx([0.1, 0.0])
    # errors over found frames: 2.5 cm (0.04 vs 0.015), 0.5 cm twice, 3 cm (0.07 vs 0.1), else 0
    assert r["right"]["aperture_error_cm"]["median"] == pytest.approx(0.25)
