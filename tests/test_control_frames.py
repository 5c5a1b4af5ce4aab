"""ControlFrameTracker (akc_drake.core.control_frames), the hip-borne TorsoModel, the Workspace and the mapping
calibrated from the T-pose (akc_drake.core.frames)."""

import numpy as np
import pytest

from akc_drake.core import frames as F
from akc_drake.core import smoothing as sm
from akc_drake.core.control_frames import ControlFrameTracker
from akc_drake.core.skeleton import INDEX, BodyDimensions

R_C_TORSO = np.column_stack([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def camera_pose(shift=(0.0, 0.0, 0.0)) -> np.ndarray:
    return F.rest_operator_pose() @ R_C_TORSO.T + np.array([0.0, -0.2, 2.0]) + np.asarray(shift)


def test_torso_model_reproduces_the_calibrated_torso_and_ignores_the_shoulders():
    pose = camera_pose()
    model = F.TorsoModel.calibrate(np.stack([pose] * 3))
    R, o = model.torso(pose)
    R_ref, o_ref = F.torso_of(pose)
    np.testing.assert_allclose(R, R_ref, atol=1e-12)
    np.testing.assert_allclose(o, o_ref, atol=1e-12)
    moved = pose.copy()
    moved[INDEX["left_shoulder"], 2] += 0.2  # a shoulder put at a wrong depth
    np.testing.assert_allclose(model.torso(moved)[0], R_ref, atol=1e-12)
    # The operator steps 0.3 m to the side: the torso follows the hips.
    R2, o2 = model.torso(camera_pose(shift=(0.3, 0.0, 0.0)))
    np.testing.assert_allclose(o2, o_ref + [0.3, 0.0, 0.0], atol=1e-12)
    gone = pose.copy()
    gone[INDEX["left_hip"]] = np.nan
    assert model.torso(gone) is None
    with pytest.raises(ValueError, match="shoulders and both hips"):
        F.TorsoModel.calibrate(np.full((2, 12, 3), np.nan))


def test_workspace_clip_keeps_targets_inside():
    ws = F.Workspace.for_side("right")
    rng = np.random.default_rng(1)
    for p in rng.uniform(-1.5, 1.5, (500, 3)):
        q, clipped = ws.clip(p)
        assert ws.contains(q, tol=1e-6)
        assert clipped == (not ws.contains(p))
        if not clipped:
            np.testing.assert_array_equal(q, p)
    inside = ws.shoulder + [0.5, 0.0, -0.2]
    assert ws.clip(inside) == (pytest.approx(inside), False) or not ws.clip(inside)[1]


def test_calibrated_mapping_scales_the_operator_reach_to_the_robot():
    dims = BodyDimensions(LUA=0.30, LLA=0.27, RUA=0.30, RLA=0.27, SW=0.36)
    m = F.calibrated_mapping(dims)
    assert m.scale == pytest.approx(F.DEFAULT_ROBOT_REACH_M / 0.57)
    # The operator's left shoulder (0, SW/2, 0) in {0} lands on the robot's left shoulder.
    X = np.eye(4)
    X[:3, 3] = [0.0, 0.18, 0.0]
    np.testing.assert_allclose(F.map_to_robot(X, "left", m)[:3, 3], [0.0, F.DEFAULT_ROBOT_SHOULDER_Y_M, 0.0])


def test_tracker_without_smoothing_is_the_plain_mapping_and_with_it_converges():
    pose = camera_pose()
    m = F.RobotMapping.default()
    plain = ControlFrameTracker(m, wrist_smoothing=None, torso_smoothing=None, robust_wrist=False)
    _, targets, lost, clipped = plain.step(plain.initial_state(), 0.0, pose)
    expected = F.robot_targets(pose, m)
    for X, E in zip(targets, expected, strict=True):
        np.testing.assert_allclose(X, E, atol=1e-12)
    np.testing.assert_array_equal(lost, [0.0, 0.0])
    np.testing.assert_array_equal(clipped, [0.0, 0.0])
    smooth = ControlFrameTracker(m, wrist_smoothing=sm.WRIST_SMOOTHING, torso_smoothing=sm.TORSO_SMOOTHING,
                                 robust_wrist=False)
    s = smooth.initial_state()
    moved = camera_pose()
    moved[INDEX["left_wrist"]] += [0.0, -0.05, 0.0]
    moved[INDEX["left_index"]] += [0.0, -0.05, 0.0]
    moved[INDEX["left_pinky"]] += [0.0, -0.05, 0.0]
    s, first, _, _ = smooth.step(s, 0.0, pose)
    s, second, _, _ = smooth.step(s, 0.1, moved)
    target = F.robot_targets(moved, m)[0]
    # Part of the way after one frame, all of it after a while (a step response, no overshoot).
    d1 = np.linalg.norm(second[0][:3, 3] - first[0][:3, 3])
    assert 0.2 * 0.0605 < d1 < 0.0605
    for k in range(2, 40):
        s, last, _, _ = smooth.step(s, 0.1 * k, moved)
    np.testing.assert_allclose(last[0][:3, 3], target[:3, 3], atol=1e-4)


def test_tracker_keeps_the_wrist_frame_off_its_mirror_when_the_hand_vector_is_unreliable():
    """Palms down with the forearm sideways (a T-pose): the hand vector points along the camera ray; when the
    index and pinky depths swap, the eq. (17) frame flips by pi about y, and the tracker keeps the previous side."""
    pose = camera_pose()
    for side, sign in (("left", 1.0), ("right", -1.0)):
        w = pose[INDEX[f"{side}_wrist"]]
        pose[INDEX[f"{side}_elbow"]] = w + [-sign * 0.28, 0.0, 0.0]  # forearm along x_C (sideways)
        pose[INDEX[f"{side}_index"]] = w + [sign * 0.08, 0.0, -0.02]  # index nearer the camera
        pose[INDEX[f"{side}_pinky"]] = w + [sign * 0.08, 0.0, 0.02]
    swapped = pose.copy()
    for side in ("left", "right"):
        swapped[INDEX[f"{side}_index"], 2], swapped[INDEX[f"{side}_pinky"], 2] = (
            pose[INDEX[f"{side}_pinky"], 2],
            pose[INDEX[f"{side}_index"], 2],
        )
    m = F.RobotMapping.default()
    t = ControlFrameTracker(m, wrist_smoothing=None, torso_smoothing=None)
    s, a, _, _ = t.step(t.initial_state(), 0.0, pose)
    s, b, _, _ = t.step(s, 0.1, swapped)
    raw = F.robot_targets(swapped, m)
    for k in range(2):
        assert F.rotation_angle(raw[k][:3, :3].T @ a[k][:3, :3]) > 2.5  # the raw frame flipped
        assert F.rotation_angle(b[k][:3, :3].T @ a[k][:3, :3]) < 0.3  # the tracked one did not


def test_hand_vector_is_rebuilt_from_its_image_part_and_the_hand_width():
    # Image part 3 cm, hand 7 cm wide: the depth part is sqrt(7^2 - 3^2) cm, with the measured sign...
    h = F.reconstruct_hand_vector([0.03, 0.0, -0.01], 0.07)
    np.testing.assert_allclose(h, [0.03, 0.0, -np.sqrt(0.07**2 - 0.03**2)])
    # ... unless the tracker's filter gives one, whatever the noisy depth says.
    assert F.reconstruct_hand_vector([0.03, 0.0, -0.02], 0.07, h, None, 1.0)[2] > 0
    # An image part as long as the hand: no depth part.
    np.testing.assert_allclose(F.reconstruct_hand_vector([0.0, 0.08, -0.05], 0.07, h), [0.0, 0.08, 0.0], atol=1e-8)
    # A knuckle line three hands long is a failed landmark: the previous vector is kept.
    np.testing.assert_array_equal(F.reconstruct_hand_vector([0.2, 0.1, 0.0], 0.07, h), h)


def test_hand_vector_sign_from_the_forearm():
    # Forearm f = (0.9, 0, 0.43), partly along the camera ray: of (3, 0, +6.3) and (3, 0, -6.3) cm, the second
    # is perpendicular to it (|cos| 0.0 against 0.77): it wins over the filter's sign and the measured depth.
    f = np.array([0.9, 0.0, 0.43])
    assert F.forearm_depth_sign([0.03, 0.0, 0.05], np.sqrt(0.07**2 - 0.03**2), f) == -1.0
    assert F.reconstruct_hand_vector([0.03, 0.0, 0.05], 0.07, None, f, 1.0)[2] < 0
    # A forearm in the image plane says nothing about the depth sign: the filter's is taken.
    assert F.forearm_depth_sign([0.03, 0.0, -0.05], 0.063, [0.0, 1.0, 0.0]) == 0.0
    assert F.reconstruct_hand_vector([0.03, 0.0, -0.05], 0.07, None, np.array([0.0, 1.0, 0.0]), 1.0)[2] > 0


def _t_pose_arm(roll_deg: float):
    """A left arm held out sideways in the image plane (torso facing the camera, C: x right, y down, z forward;
    the operator's left is +x), its knuckle line rolled ``roll_deg`` about the forearm from the palms-down
    neutral (index toward the camera: -z), toward up (-y)."""
    R_torso = np.column_stack([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # forward -z, left +x, up -y
    p_s, p_e, p_w = np.array([0.17, 0.0, 2.0]), np.array([0.45, 0.0, 2.0]), np.array([0.73, 0.0, 2.0])
    a = np.radians(roll_deg)
    h = 0.07 * np.array([0.0, -np.sin(a), -np.cos(a)])
    return R_torso, p_s, p_e, p_w, h


def test_neutral_hand_direction_is_the_palm_down_t_pose_and_thumbs_up_on_a_bent_elbow():
    from akc_drake.core.control_frames import NEUTRAL_STRAIGHT_WEIGHT as W
    from akc_drake.core.control_frames import neutral_hand_direction

    R_torso, p_s, p_e, p_w, _ = _t_pose_arm(0.0)  # a straight arm: half the weight of a bent one
    np.testing.assert_allclose(neutral_hand_direction(p_s, p_e, p_w, R_torso), [0.0, 0.0, -W], atol=1e-9)
    # Hanging (wrist below the elbow, +y): forward, the index in front of the pinky with the palm toward the thigh.
    np.testing.assert_allclose(neutral_hand_direction(p_s, p_s + [0, 0.28, 0], p_s + [0, 0.56, 0], R_torso),
                               [0.0, 0.0, -W], atol=1e-9)
    # Upper arm hanging, forearm forward (elbow at 90 deg): thumbs up, whatever the torso says.
    n = neutral_hand_direction(p_s, p_s + [0, 0.28, 0], p_s + [0, 0.28, -0.28], R_torso)
    np.testing.assert_allclose(n, [0.0, -1.0, 0.0], atol=1e-9)
    # Straight arm overhead: the swing from hanging is undefined, no prior.
    assert np.linalg.norm(neutral_hand_direction(p_s, p_s - [0, 0.28, 0], p_s - [0, 0.56, 0], R_torso)) < 1e-9


def test_depth_sign_takes_the_anatomical_sign_only_when_nothing_measured_decides():
    from akc_drake.core.control_frames import depth_sign_step, neutral_hand_direction

    # The demo's failure (issue 13): a T-pose arm, its knuckle line 40 deg from palms down, mostly along the camera
    # ray; the forearm in the image plane does not decide, Hands' relative depth reads ~0 (+1 mm). Before: the
    # measured (or a carried-over 1 nm) sign, here the mirror (the index behind the pinky), kept by continuity.
    R_torso, p_s, p_e, p_w, h = _t_pose_arm(40.0)
    dz = abs(h[2])
    measured = np.array([h[0], h[1], 0.001])
    assert F.forearm_depth_sign(measured, dz, p_e - p_w) == 0.0
    neutral = neutral_hand_direction(p_s, p_e, p_w, R_torso)
    sign, belief = depth_sign_step(np.nan, measured, dz, p_e - p_w, None, neutral, 0.07, 0.1)
    assert sign == -1.0 and 0.5 < belief  # the index toward the camera
    # A measured depth that says enough (2 cm the other way) wins over the prior on a first frame.
    sign, _ = depth_sign_step(np.nan, measured * [1, 1, 20], dz, p_e - p_w, None, neutral, 0.07, 0.1)
    assert sign == 1.0
    # A real turn is followed, not fought: the hand held at 160 deg (the index behind the pinky, far from the
    # prior) while Hands' depth says so (2 cm) for 0.5 s, then silent (0.5 mm) while the hand rolls to 110 deg and
    # back to 170 deg at 1-2 rad/s over a second: the branch continues the roll.
    belief, previous = np.nan, None
    rolls = [160.0] * 5 + list(np.linspace(160.0, 110.0, 5)) + list(np.linspace(110.0, 170.0, 5))
    for k, roll in enumerate(rolls):
        _, _, _, _, h = _t_pose_arm(roll)
        meas = np.array([h[0], h[1], 0.02 if k < 5 else 0.0005])
        sign, belief = depth_sign_step(belief, meas, abs(h[2]), p_e - p_w, previous, neutral, 0.07, 0.1)
        assert sign == 1.0, (k, roll)
        previous = np.array([0.0, h[1], sign * abs(h[2])])  # the chosen hand across the forearm (along x)


def test_tracker_puts_a_t_pose_knuckle_line_along_the_ray_on_the_anatomical_side():
    # Issue 13: both arms held out sideways in the image plane, each knuckle line 40 deg up from palms down (mostly
    # along the camera ray, the index toward the camera); Hands' relative depth reads ~0 (+1 mm). The wrist frames
    # must be those a decisive depth (2 cm, the right sign) gives, not their mirrors (100 deg off).
    pose = np.zeros((12, 3))
    for side, sx in (("left", 1.0), ("right", -1.0)):
        pose[INDEX[f"{side}_shoulder"]] = [0.17 * sx, -0.05, 2.0]
        pose[INDEX[f"{side}_elbow"]] = [0.45 * sx, -0.05, 2.0]
        pose[INDEX[f"{side}_wrist"]] = [0.73 * sx, -0.05, 2.0]
        pose[INDEX[f"{side}_hip"]] = [0.09 * sx, 0.45, 2.0]
        h = 0.07 * np.array([0.0, -np.sin(np.radians(40.0)), -np.cos(np.radians(40.0))])
        c = np.array([0.82 * sx, -0.05, 2.0])
        pose[INDEX[f"{side}_index"]], pose[INDEX[f"{side}_pinky"]] = c + h / 2, c - h / 2
    targets = {}
    for z in (0.001, -0.02):
        knuckles = np.array([[h[0], h[1], z]] * 2) / 2.0  # normalised image units at 2 m
        t = ControlFrameTracker(F.RobotMapping.default(), wrist_smoothing=None, torso_smoothing=None)
        s = t.initial_state()
        for k in range(5):
            s, targets[z], _, _ = t.step(s, 0.1 * k, pose, knuckles)
    for k in range(2):
        assert F.rotation_angle(targets[0.001][k][:3, :3].T @ targets[-0.02][k][:3, :3]) < np.radians(2.0)


def test_a_wrist_hidden_by_its_own_hand_is_put_behind_the_hand():
    from akc_drake.core.control_frames import wrist_behind_hand

    # Forearm pointing at the camera, the hand continuing it: knuckles 8.5 cm nearer than the wrist, 2 cm
    # aside in the image. The depth camera reads the back of the hand at the wrist's pixel (1 cm behind the
    # knuckles); the wrist goes back on its pixel ray to sqrt(8.5^2 - 2^2) cm behind them.
    w = np.array([0.10, 0.05, 1.50])
    e = w + [0.0, 0.02, 0.28]
    c = w + [0.02, 0.0, -np.sqrt(0.085**2 - 0.02**2)]
    i, p = c + [0.0, 0.035, 0.0], c - [0.0, 0.035, 0.0]
    seen = w * (c[2] + 0.01) / w[2]  # the back of the hand, on the wrist's ray
    fixed = wrist_behind_hand(e, seen, i, p, 0.085)
    assert np.linalg.norm(seen - w) > 0.07
    # Within 2 mm (the image part is read at the nearer point of the ray, 1.4 mm off here).
    np.testing.assert_allclose(fixed, w, atol=2e-3)
    np.testing.assert_allclose(np.cross(fixed, w), 0.0, atol=1e-12)  # on the wrist's pixel ray
    # The depth read past the hand's edge, 6 cm behind the wrist: forward to the same point; 15 cm behind: a hand's
    # length forward at most.
    far = w * (w[2] + 0.06) / w[2]
    np.testing.assert_allclose(wrist_behind_hand(e, far, i, p, 0.085), w, atol=2e-3)
    very_far = w * (w[2] + 0.15) / w[2]
    assert wrist_behind_hand(e, very_far, i, p, 0.085)[2] == pytest.approx(very_far[2] - 0.085, abs=1e-9)
    # A wrist seen where it is, a forearm across the image, a hand seen side-on: unchanged.
    np.testing.assert_array_equal(wrist_behind_hand(e, w, i, p, 0.085), w)
    np.testing.assert_array_equal(wrist_behind_hand(w + [0.28, 0.0, 0.0], seen, i, p, 0.085), seen)
    # Knuckles read 20 cm behind the wrist (their depth hit the body behind): their depth failed, no move.
    np.testing.assert_array_equal(wrist_behind_hand(e, seen, i + [0, 0, 0.3], p + [0, 0, 0.3], 0.085), seen)
    side_on = seen + [0.0, 0.0, 0.0]
    np.testing.assert_array_equal(wrist_behind_hand(e, side_on, seen + [0.09, 0.035, 0.0], seen + [0.09, -0.035, 0.0],
                                                    0.085), side_on)


def test_the_torso_is_held_while_the_detector_moves_the_hips_and_follows_a_step():
    """The detector moves its hips 6 cm up while the arms rise (the operator stands still): the targets do not
    move. The operator steps 0.4 m aside: the torso follows, at a bounded speed, and is held again."""
    pose = camera_pose()
    model = F.TorsoModel.calibrate(np.stack([pose] * 3))
    m = F.RobotMapping.default()
    t = ControlFrameTracker(m, torso_model=model, wrist_smoothing=None, torso_smoothing=sm.TORSO_SMOOTHING,
                            torso_hold=sm.TORSO_HOLD, robust_wrist=False)
    s = t.initial_state()
    for k in range(20):  # the operator stands still: the torso is settled (the mean of its first second)
        s, first, _, _ = t.step(s, 0.1 * k, pose)
    shifted = pose.copy()
    shifted[[INDEX["left_hip"], INDEX["right_hip"]], 1] -= 0.06  # 6 cm up in the image (y_C down)
    for k in range(20, 60):
        s, X, _, _ = t.step(s, 0.1 * k, shifted)
        for a, b in zip(X, first, strict=True):
            np.testing.assert_allclose(a, b, atol=1e-12)
    stepped = camera_pose(shift=(0.4, 0.0, 0.0))
    moves = []
    for k in range(60, 200):
        s, X, _, _ = t.step(s, 0.1 * k, stepped)
        if X[0] is not None:  # None: the first frame of the step, stopped by the speed gate
            moves.append(X[0][:3, 3].copy())
    steps = np.linalg.norm(np.diff(moves, axis=0), axis=1)
    # Never a jump: the hold moves at 0.3 m/s; the One Euro filter after it may briefly outpace it (cutoff rising).
    assert steps.max() <= 1.5 * m.scale * sm.TORSO_HOLD.speed_m_s * 0.1
    assert np.count_nonzero(steps > 1e-6) >= 0.4 / (sm.TORSO_HOLD.speed_m_s * 0.1)
    expected = F.robot_targets(stepped, m, torso=model.torso(stepped))[0]
    np.testing.assert_allclose(moves[-1], expected[:3, 3], atol=m.scale * sm.TORSO_HOLD.settle_m + 1e-6)
    assert s[t.state_size - sm.HOLD_STATE_SIZE + 9] == 0.0  # held again


def test_hands_knuckles_replace_the_pose_hand_points_and_a_missed_frame_keeps_the_last():
    from akc_drake.core.camera import CameraIntrinsics

    K = CameraIntrinsics()
    pose = camera_pose()
    m = F.RobotMapping.default()
    truth = F.robot_targets(pose, m)
    wrong = pose.copy()  # the pose model's hand points turned 90 deg about the forearm
    for side in ("left", "right"):
        w = pose[INDEX[f"{side}_wrist"]]
        i, p = pose[INDEX[f"{side}_index"]] - w, pose[INDEX[f"{side}_pinky"]] - w
        c, d = 0.5 * (i + p), 0.5 * (i - p)
        wrong[INDEX[f"{side}_index"]] = w + c + [d[2], 0.0, 0.0]
        wrong[INDEX[f"{side}_pinky"]] = w + c - [d[2], 0.0, 0.0]
    knuckles = true_knuckle_vectors(pose, K)
    t = ControlFrameTracker(m, wrist_smoothing=None, torso_smoothing=None)
    s, with_hands, _, _ = t.step(t.initial_state(), 0.0, wrong, knuckles)
    _, without, _, _ = ControlFrameTracker(m, wrist_smoothing=None, torso_smoothing=None).step(
        t.initial_state(), 0.0, wrong)
    for k in range(2):
        assert F.rotation_angle(truth[k][:3, :3].T @ with_hands[k][:3, :3]) < np.radians(3.0)
        assert F.rotation_angle(truth[k][:3, :3].T @ without[k][:3, :3]) > np.radians(30.0)
    # Hands misses both hands in the next frame: the last hand vector is kept (not the pose's wrong points).
    s, missed, _, _ = t.step(s, 0.1, wrong, np.full((2, 3), np.nan))
    for k in range(2):
        assert F.rotation_angle(truth[k][:3, :3].T @ missed[k][:3, :3]) < np.radians(3.0)


def true_knuckle_vectors(pose, K):
    """The ``(2, 3)`` knuckle vectors of MediaPipe Hands' landmarks 5 and 17 put on the pose's true knuckles:
    pixels, and a relative depth on u's scale (pixels)."""
    from akc_drake.core.control_frames import hands_knuckle_vector

    knuckles = np.zeros((2, 3))
    for k, side in enumerate(("left", "right")):
        hand = np.full((21, 3), np.nan)
        for j, name in ((5, "index"), (17, "pinky")):
            x, y, z = pose[INDEX[f"{side}_{name}"]]
            hand[j] = [K.fx * x / z + K.cx, K.fy * y / z + K.cy, K.fx * (z - 2.0) / 2.0]
        knuckles[k] = hands_knuckle_vector(hand, K)
    return knuckles


def test_hands_swapped_needs_a_reversed_long_image_part():
    from akc_drake.core.control_frames import hands_swapped

    ref = np.array([0.05, 0.0])
    assert hands_swapped(np.array([-0.05, 0.01, 0.0]), ref, 0.06)
    assert not hands_swapped(np.array([0.04, 0.03, 0.02]), ref, 0.06)  # 37 deg: a turn a person makes
    assert not hands_swapped(np.array([-0.02, 0.0, 0.05]), ref, 0.06)  # image part 1/3 of the width: no direction
    assert not hands_swapped(np.array([np.nan, 0.0, 0.0]), ref, 0.06)


def test_hands_index_pinky_swap_is_held_off_until_it_persists():
    from akc_drake.core.camera import CameraIntrinsics
    from akc_drake.core.control_frames import HANDS_HOLD_S

    K = CameraIntrinsics()
    pose = camera_pose()
    m = F.RobotMapping.default()
    truth = F.robot_targets(pose, m)
    knuckles = true_knuckle_vectors(pose, K)
    t = ControlFrameTracker(m, wrist_smoothing=None, torso_smoothing=None)
    s = t.initial_state()
    for k in range(3):
        s, X, _, _ = t.step(s, 0.1 * k, pose, knuckles)
    # Hands swaps index and pinky on both hands (its knuckle line reversed): the wrist frames do not flip ...
    errors = []
    for k in range(3, 3 + int(round(HANDS_HOLD_S / 0.1)) + 3):
        s, X, _, _ = t.step(s, 0.1 * k, pose, -knuckles)
        errors.append([F.rotation_angle(truth[j][:3, :3].T @ X[j][:3, :3]) for j in range(2)])
    errors = np.degrees(errors)
    held = int(round(HANDS_HOLD_S / 0.1))
    assert np.all(errors[:held] < 3.0)
    # ... until the reversal has lasted HANDS_HOLD_S: then it is a real turn, followed.
    assert np.all(errors[held + 1 :] > 150.0)


def test_calibrate_torso_takes_the_vertical_from_the_trunk_not_the_shoulder_line():
    from akc_drake.core.control_frames import calibrate_torso

    pose = camera_pose()
    R_ref, o_ref = F.torso_of(pose)
    level = calibrate_torso(np.stack([pose] * 3))  # level shoulders: the same frame as eq. (17)'s
    np.testing.assert_allclose(level.torso(pose)[0], R_ref, atol=1e-9)
    np.testing.assert_allclose(level.torso(pose)[1], o_ref, atol=1e-9)
    # A detector puts the left shoulder 1 cm low (image y down) in the T-pose: eq. (17)'s frame rolls by
    # atan(0.01 / shoulder width), calibrate_torso's by the trunk's tilt only (its top moved 0.5 cm along it: none).
    low = pose.copy()
    low[INDEX["left_shoulder"], 1] += 0.01
    width = float(np.linalg.norm(pose[INDEX["left_shoulder"]] - pose[INDEX["right_shoulder"]]))

    def roll_deg(model):
        R = model.torso(pose)[0]
        return float(np.degrees(np.arccos(np.clip(R[:, 2] @ R_ref[:, 2], -1.0, 1.0))))

    assert roll_deg(F.TorsoModel.calibrate(low[None])) == pytest.approx(np.degrees(np.arctan(0.01 / width)), rel=0.05)
    assert roll_deg(calibrate_torso(low[None])) < 0.01
    # The shoulder 1 cm outward instead (along the line): eq. (17) does not roll, the trunk's top moves 0.5 cm
    # sideways, a tilt of atan(0.005 / trunk length), a third of a vertical error's roll in eq. (17).
    out = pose.copy()
    out[INDEX["left_shoulder"], 0] += 0.01
    trunk = float(np.linalg.norm(F.torso_of(pose)[1] - 0.5 * (pose[INDEX["left_hip"]] + pose[INDEX["right_hip"]])))
    assert roll_deg(calibrate_torso(out[None])) == pytest.approx(np.degrees(np.arctan(0.005 / trunk)), rel=0.05)
    assert roll_deg(calibrate_torso(out[None])) < 0.4 * roll_deg(F.TorsoModel.calibrate(low[None]))
    # The origin is still the measured shoulder midpoint; frames missing a torso landmark are skipped.
    np.testing.assert_allclose(calibrate_torso(low[None]).torso(pose)[1], o_ref + [0.0, 0.005, 0.0], atol=1e-9)
    gap = np.stack([pose, pose])
    gap[0, INDEX["right_hip"]] = np.nan
    np.testing.assert_allclose(calibrate_torso(gap).torso(pose)[0], R_ref, atol=1e-9)
    with pytest.raises(ValueError, match="shoulders and both hips"):
        calibrate_torso(np.full((2, 12, 3), np.nan))
