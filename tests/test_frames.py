import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.core import frames as F
from akc_drake.core.skeleton import INDEX

# Operator torso axes (x forward, y left, z up) expressed in the camera frame C (x right, y down, z forward)
# for an operator facing the camera: forward = -z_C, left = +x_C, up = -y_C.
R_C_TORSO_FACING = np.column_stack([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def t_pose_facing_camera(depth: float = 2.0, sw: float = 0.33, reach: float = 0.57) -> np.ndarray:
    """T-pose in the camera frame, arms straight out sideways, palms down, operator facing the camera."""
    pose = np.zeros((12, 3))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        s = np.array([sign * sw / 2, -0.3, depth])
        pose[INDEX[f"{side}_shoulder"]] = s
        pose[INDEX[f"{side}_elbow"]] = s + [sign * 0.29, 0.0, 0.0]
        w = s + [sign * reach, 0.0, 0.0]
        pose[INDEX[f"{side}_wrist"]] = w
        # Palms down, fingers pointing away from the body: the index MCP is on the forward side (toward the
        # camera, -z_C), the pinky on the back side.
        pose[INDEX[f"{side}_index"]] = w + [sign * 0.08, 0.0, -0.03]
        pose[INDEX[f"{side}_pinky"]] = w + [sign * 0.07, 0.0, 0.03]
        pose[INDEX[f"{side}_hip"]] = [sign * 0.1, 0.2, depth]
    return pose


def assert_rotation(R, tol=1e-9):
    assert R.shape == (3, 3) and np.all(np.isfinite(R))
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=tol)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=tol)
    np.testing.assert_allclose(np.cross(R[:, 0], R[:, 1]), R[:, 2], atol=tol)


def test_torso_frame_of_a_t_pose_facing_the_camera():
    pose = t_pose_facing_camera()
    R, origin = F.torso_frame(
        pose[INDEX["left_shoulder"]],
        pose[INDEX["right_shoulder"]],
        pose[INDEX["left_hip"]],
        pose[INDEX["right_hip"]],
    )
    np.testing.assert_allclose(R, R_C_TORSO_FACING, atol=1e-12)
    np.testing.assert_allclose(origin, [0.0, -0.3, 2.0], atol=1e-12)
    # Expressed in the torso frame itself it is the identity; the shoulders lie on its y axis.
    np.testing.assert_allclose(R.T @ R_C_TORSO_FACING, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R.T @ (pose[INDEX["left_shoulder"]] - origin), [0.0, 0.165, 0.0], atol=1e-12)


def test_wrist_in_torso_for_a_t_pose():
    X_l, X_r = F.wrist_in_torso(t_pose_facing_camera())
    # Wrists straight out sideways at shoulder height: (0, +-(sw/2 + reach), 0) in the torso frame.
    np.testing.assert_allclose(X_l[:3, 3], [0.0, 0.165 + 0.57, 0.0], atol=1e-12)
    np.testing.assert_allclose(X_r[:3, 3], [0.0, -(0.165 + 0.57), 0.0], atol=1e-12)
    # Left: y = elbow - wrist = -y_T (toward the body); index - pinky = forward; z = (-y) x (+x) = +z (up);
    # x = y x z = (-y) x z = -x.
    np.testing.assert_allclose(X_l[:3, :3], np.column_stack([[-1, 0, 0], [0, -1, 0], [0, 0, 1]]), atol=1e-12)
    # Right: y = +y_T; z = y x x = -z (down); x = y x (-z) = -x.
    np.testing.assert_allclose(X_r[:3, :3], np.column_stack([[-1, 0, 0], [0, 1, 0], [0, 0, -1]]), atol=1e-12)
    np.testing.assert_array_equal(X_l[3], [0, 0, 0, 1])


def test_wrist_frame_for_a_forearm_pointing_forward_palm_down():
    # Camera frame; the left forearm points toward the camera (the operator's forward), palm down; the index
    # MCP is medial (the operator's right = -x_C).
    p_e = np.array([0.3, 0.0, 2.0])
    p_w = np.array([0.3, 0.0, 1.72])
    p_i = np.array([0.27, 0.0, 1.65])
    p_p = np.array([0.33, 0.0, 1.65])
    R = F.wrist_frame(p_e, p_w, p_i, p_p)
    # y = (0, 0, 1) (back toward the elbow); z = y x (-1, 0, 0) = (0, -1, 0) (up); x = y x z = (1, 0, 0).
    np.testing.assert_allclose(R, np.column_stack([[1, 0, 0], [0, 0, 1], [0, -1, 0]]), atol=1e-12)
    assert_rotation(R)


def test_mapped_frame_rotation_is_minus_90_about_y():
    R1 = F.rotation_z(0.3) @ F.rotation_x(-1.1)
    R1p = R1 @ F.R_WRIST_TO_MAPPED
    np.testing.assert_allclose(R1p[:, 0], R1[:, 2], atol=1e-15)  # x' = z
    np.testing.assert_allclose(R1p[:, 1], R1[:, 1], atol=1e-15)  # y' = y
    np.testing.assert_allclose(R1p[:, 2], -R1[:, 0], atol=1e-15)  # z' = -x


@pytest.mark.parametrize(
    "p_e, p_w, p_i, p_p",
    [
        ([0, 0, 1], [0, 0, 1], [0.1, 0, 1], [0, 0, 1]),  # zero-length forearm
        ([0, 0, 1.3], [0, 0, 1], [0, 0, 0.9], [0, 0, 0.95]),  # hand vector parallel to the forearm
        ([0, 0, 1.3], [0, 0, 1], [0.05, 0, 1], [0.05, 0, 1]),  # index == pinky
        ([0, 0, 1.3], [0, np.nan, 1], [0.05, 0, 1], [0, 0, 1]),  # NaN
        ([0, 0, 1.3], [0, 0, 1], [np.inf, 0, 1], [0, 0, 1]),  # inf
    ],
)
def test_degenerate_wrist_frames_are_none(p_e, p_w, p_i, p_p):
    assert F.wrist_frame(p_e, p_w, p_i, p_p) is None


def test_degenerate_torso_gives_no_frames():
    pose = t_pose_facing_camera()
    bad = pose.copy()
    bad[INDEX["right_shoulder"]] = bad[INDEX["left_shoulder"]]
    assert F.wrist_in_torso(bad) == (None, None)
    bad = pose.copy()  # hips on the shoulder line: trunk parallel to the shoulders
    bad[INDEX["left_hip"]] = pose[INDEX["left_shoulder"]] + [0.5, 0, 0]
    bad[INDEX["right_hip"]] = pose[INDEX["right_shoulder"]] + [0.5, 0, 0]
    assert F.wrist_in_torso(bad) == (None, None)
    bad = pose.copy()
    bad[INDEX["left_hip"]] = np.nan
    assert F.wrist_in_torso(bad) == (None, None)
    one = pose.copy()
    one[INDEX["right_wrist"]] = np.nan
    X_l, X_r = F.wrist_in_torso(one)
    assert X_l is not None and X_r is None
    with pytest.raises(ValueError, match="p_e must be a 3-vector"):
        F.wrist_frame([0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0])


finite = st.floats(-2.0, 2.0, allow_nan=False)
point = st.tuples(finite, finite, finite).map(np.array)


@settings(max_examples=200, deadline=None)
@given(p_e=point, p_w=point, p_i=point, p_p=point)
def test_property_wrist_frame_is_a_right_handed_rotation_or_none(p_e, p_w, p_i, p_p):
    R = F.wrist_frame(p_e, p_w, p_i, p_p)
    if R is None:
        return
    assert_rotation(R)
    fore = (p_e - p_w) / np.linalg.norm(p_e - p_w)
    np.testing.assert_allclose(R[:, 1], fore, atol=1e-9)
    hand = p_i - p_p
    assert abs(R[:, 2] @ hand) <= 1e-9 * max(1.0, np.linalg.norm(hand))
    # x lies in the plane of the forearm and the hand vector, on the same side as the hand vector.
    assert R[:, 0] @ hand <= 1e-9


@settings(max_examples=200, deadline=None)
@given(a=point, b=point, c=point, d=point)
def test_property_torso_frame_is_a_right_handed_rotation_or_none(a, b, c, d):
    out = F.torso_frame(a, b, c, d)
    if out is None:
        return
    R, origin = out
    assert_rotation(R)
    np.testing.assert_allclose(origin, 0.5 * (a + b), atol=1e-12)
    np.testing.assert_allclose(R[:, 1], (a - b) / np.linalg.norm(a - b), atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(
    angles=st.tuples(*[st.floats(-math.pi, math.pi)] * 3),
    shift=st.tuples(*[st.floats(-3.0, 3.0)] * 3),
    noise_seed=st.integers(0, 1000),
)
def test_property_wrist_in_torso_is_invariant_to_moving_the_camera(angles, shift, noise_seed):
    rng = np.random.default_rng(noise_seed)
    pose = t_pose_facing_camera() + rng.normal(0.0, 0.05, (12, 3))
    R = F.rotation_z(angles[0]) @ F.rotation_y(angles[1]) @ F.rotation_x(angles[2])
    moved = pose @ R.T + np.array(shift)
    for X, Y in zip(F.wrist_in_torso(pose), F.wrist_in_torso(moved), strict=True):
        np.testing.assert_allclose(X, Y, atol=1e-9)


def test_map_to_robot_of_the_rest_posture():
    m = F.RobotMapping.from_shoulders()
    scale = 0.69 / 0.57
    assert m.scale == pytest.approx(scale)
    # The operator's shoulders (0, +-0.165, 0) land on the robot's shoulders (0, +-0.20, 0).
    for side, sign in (("left", 1.0), ("right", -1.0)):
        X = F.transform(np.eye(3), [0.0, sign * 0.165, 0.0])
        np.testing.assert_allclose(F.map_to_robot(X, side, m)[:3, 3], [0.0, sign * 0.20, 0.0], atol=1e-12)

    pose = F.rest_operator_pose(upper_arm_m=0.3, lower_arm_m=0.25)
    X_l, X_r = F.wrist_in_torso(pose)
    # Rest posture (forearms forward, palms facing each other, thumbs up), by hand:
    # left {1}: y = back (-x), index - pinky = up, z = (-x) x z = +y, x = y x z = (-x) x (+y) = -z;
    # {1'} = (x' = z = +y, y' = -x, z' = -x = +z); E_left = {1'} turned 180 deg about y: (-y, -x, -z).
    np.testing.assert_allclose(X_l[:3, :3], np.column_stack([[0, 0, -1], [-1, 0, 0], [0, 1, 0]]), atol=1e-12)
    XE_l = F.map_to_robot(X_l, "left", m)
    np.testing.assert_allclose(
        XE_l[:3, :3], np.column_stack([[0, -1, 0], [-1, 0, 0], [0, 0, -1]]), atol=1e-12
    )
    np.testing.assert_allclose(XE_l[:3, 3], [scale * 0.25, 0.20, -scale * 0.3], atol=1e-12)
    # right {1'}: x' = +y (the palmar normal of the right hand), y' = -x, z' = +z; no extra rotation.
    XE_r = F.map_to_robot(X_r, "right", m)
    np.testing.assert_allclose(XE_r[:3, :3], np.column_stack([[0, 1, 0], [-1, 0, 0], [0, 0, 1]]), atol=1e-12)
    np.testing.assert_allclose(XE_r[:3, 3], [scale * 0.25, -0.20, -scale * 0.3], atol=1e-12)
    # Both E frames are mirror images: x (palmar normal) points medially on both sides.
    assert XE_l[1, 0] == pytest.approx(-1.0) and XE_r[1, 0] == pytest.approx(1.0)
    np.testing.assert_allclose(
        F.default_home_pose("left", m, upper_arm_m=0.3, lower_arm_m=0.25), XE_l, atol=1e-15
    )


def test_tool_offset_moves_the_target_beyond_the_wrist():
    m0 = F.RobotMapping.from_shoulders()
    m1 = F.RobotMapping.from_shoulders(tool_offset_m=0.195)
    X_l, X_r = F.wrist_in_torso(F.rest_operator_pose())
    for X, side in ((X_l, "left"), (X_r, "right")):
        a, b = F.map_to_robot(X, side, m0), F.map_to_robot(X, side, m1)
        np.testing.assert_array_equal(a[:3, :3], b[:3, :3])
        # Forearm forward: y_E points back (-x_T), so the tool point is 0.195 m further forward.
        np.testing.assert_allclose(b[:3, 3] - a[:3, 3], [0.195, 0.0, 0.0], atol=1e-12)
    with pytest.raises(ValueError, match="tool_offset_m"):
        F.RobotMapping(tool_offset_m=-0.1)


def test_robot_targets_and_identity_extra_rotation():
    m = F.RobotMapping(scale=2.0, offset_left=[0.1, 0.2, 0.3], R_extra_left=np.eye(3))
    pose = t_pose_facing_camera()
    X_l = F.wrist_in_torso(pose)[0]
    XE_l, _ = F.robot_targets(pose, m)
    np.testing.assert_allclose(XE_l[:3, :3], X_l[:3, :3] @ F.R_WRIST_TO_MAPPED, atol=1e-15)
    np.testing.assert_allclose(XE_l[:3, 3], 2.0 * X_l[:3, 3] + [0.1, 0.2, 0.3], atol=1e-15)


def test_mapping_validation():
    with pytest.raises(ValueError, match="scale"):
        F.RobotMapping(scale=0.0)
    with pytest.raises(ValueError, match="offset_right"):
        F.RobotMapping(offset_right=[0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="R_extra_left"):
        F.RobotMapping(R_extra_left=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="human_reach_m"):
        F.RobotMapping.from_shoulders(human_reach_m=-1.0)
    with pytest.raises(ValueError, match="side"):
        F.map_to_robot(np.eye(4), "middle")
    with pytest.raises(ValueError, match="X_TorsoWrist"):
        F.map_to_robot(np.eye(3), "left")


def test_frame_jitter_on_known_motion():
    dt, w, v = 0.1, 0.5, np.array([0.03, -0.04, 0.0])  # rad/s about z, m/s
    X = np.stack([F.transform(F.rotation_z(w * k * dt), v * k * dt) for k in range(20)])
    ang, lin = F.frame_jitter(X, dt)
    assert ang == pytest.approx(0.5, abs=1e-12)
    assert lin == pytest.approx(0.05, abs=1e-12)
    assert F.frame_jitter(np.repeat(np.eye(4)[None], 5, axis=0), dt) == (0.0, 0.0)
    # Non-finite frames are skipped, pairs across them too: jumps 0->1 (0.1 rad), 3->4 (0.3 rad) are left.
    Y = np.stack([F.transform(F.rotation_x(a), [0, 0, 0]) for a in (0.0, 0.1, 0.5, 0.9, 1.2)])
    Y[2] = np.nan
    ang, lin = F.frame_jitter(Y, 1.0)
    assert ang == pytest.approx(math.sqrt((0.1**2 + 0.3**2) / 2), abs=1e-12) and lin == 0.0
    assert all(math.isnan(x) for x in F.frame_jitter(np.full((3, 4, 4), np.nan), dt))
    with pytest.raises(ValueError, match="dt"):
        F.frame_jitter(X, 0.0)
    with pytest.raises(ValueError, match="X_seq"):
        F.frame_jitter(np.zeros((3, 3, 3)), dt)


def test_rotation_angle_is_accurate_for_small_and_large_angles():
    for a in (1e-9, 1e-4, 0.5, 3.0, math.pi):
        assert F.rotation_angle(F.rotation_y(a)) == pytest.approx(a, rel=1e-9, abs=1e-15)




def test_resolve_wrist_flip_keeps_the_mirror_off_only_when_the_depth_sign_matters():
    previous = F.wrist_frame(np.array([0.0, 0.0, 2.3]), np.array([0.0, 0.0, 2.0]), np.array([0.03, 0.0, 2.0]),
                             np.array([-0.03, 0.0, 2.0]))
    # Forearm along the camera ray (elbow behind the wrist): the hand's image part is across the forearm, so the
    # frame does not depend on the depth's sign; it is trusted even with an image share of only 0.45.
    p_e, p_w = np.array([0.0, 0.0, 2.3]), np.array([0.0, 0.0, 2.0])
    h = np.array([-0.027, 0.0, 0.054])  # image share 0.45 (< HAND_VECTOR_RELIABLE_SHARE)
    R = F.wrist_frame(p_e, p_w, p_w + h, p_w)
    assert F.rotation_angle(previous.T @ R) > np.radians(170.0)  # (a reversed image part: taken as measured)
    np.testing.assert_allclose(F.resolve_wrist_flip(R, h, previous), R)
    # Forearm across the image, the same hand vector: it points mostly along the ray, its depth's sign sets the
    # frame; the one nearer the previous frame (its mirror) is kept.
    p_e2 = np.array([0.3, 0.0, 2.0])
    prev2 = F.wrist_frame(p_e2, p_w, p_w + h * [1, 1, -1], p_w)
    R2 = F.wrist_frame(p_e2, p_w, p_w + h, p_w)
    out = F.resolve_wrist_flip(R2, h, prev2)
    np.testing.assert_allclose(out, R2 @ F.R_FLIP_Y)
    assert F.rotation_angle(prev2.T @ out) < F.rotation_angle(prev2.T @ R2)
    # A hand vector in the image plane is trusted as measured, whatever the previous frame.
    h3 = np.array([0.0, 0.06, 0.01])
    R3 = F.wrist_frame(p_e2, p_w, p_w + h3, p_w)
    np.testing.assert_allclose(F.resolve_wrist_flip(R3, h3, R3 @ F.R_FLIP_Y), R3)
