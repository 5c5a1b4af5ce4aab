"""The world frame W: gravity-aligned, floor at z = 0, from an upright operator's body or an accelerometer."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, BodyDimensions
from akc_drake.core.world_frame import (
    BVH_FROM_W,
    HIP_HEIGHT_RATIO,
    SHOULDER_HEIGHT_RATIO,
    Y_UP_FROM_W,
    WorldFrame,
    estimate_world_frame,
    stature_from_dims,
    up_from_accel,
)

DIMS = BodyDimensions.paper_participant()


def standing_operator_W(T: int = 20, seed: int = 0) -> np.ndarray:
    """An upright operator in a T-pose 2.5 m in front of the camera, in W (z up), with Winter's proportions."""
    rng = np.random.default_rng(seed)
    H = stature_from_dims(DIMS)
    P = np.full((T, NUM_LANDMARKS, 3), np.nan)
    x0 = 2.5
    for k in range(T):
        sway = rng.normal(scale=0.005, size=3)
        sh_z, hip_z = SHOULDER_HEIGHT_RATIO * H, HIP_HEIGHT_RATIO * H
        for side, s in (("left", -1.0), ("right", 1.0)):  # operator faces -x: their left is -y
            sh = np.array([x0, s * DIMS.SW / 2, sh_z]) + sway
            P[k, INDEX[f"{side}_shoulder"]] = sh
            P[k, INDEX[f"{side}_hip"]] = np.array([x0, s * 0.1, hip_z]) + sway
            P[k, INDEX[f"{side}_elbow"]] = sh + [0, s * DIMS.upper(side), 0]
            P[k, INDEX[f"{side}_wrist"]] = sh + [0, s * (DIMS.upper(side) + DIMS.lower(side)), 0]
    return P


def camera_pose(pitch_deg: float, roll_deg: float, height: float):
    """R_WC, p_WC of a camera at ``height`` above the W origin, looking along +x, pitched down and rolled."""
    R_W_Cnom = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)  # C: x right, y down, z forward
    R = Rotation.from_euler("y", pitch_deg, degrees=True).as_matrix() @ R_W_Cnom
    R = R @ Rotation.from_euler("z", roll_deg, degrees=True).as_matrix()
    return R, np.array([0.0, 0.0, height])


def to_camera(P_W, R_WC, p_WC):
    return (P_W - p_WC) @ R_WC


@pytest.mark.parametrize("pitch,roll,height", [(0.0, 0.0, 1.2), (15.0, 3.0, 1.6), (-10.0, -5.0, 0.9)])
def test_body_estimate_recovers_gravity_and_floor(pitch, roll, height):
    R_WC, p_WC = camera_pose(pitch, roll, height)
    P_W = standing_operator_W()
    W = estimate_world_frame(to_camera(P_W, R_WC, p_WC), DIMS)
    P_est = W.to_world(to_camera(P_W, R_WC, p_WC))
    # Up and the floor are exact for an operator with Winter's proportions (sway: 5 mm noise, median).
    np.testing.assert_allclose(W.R_CW[:, 2], R_WC.T @ [0, 0, 1], atol=2e-3)
    assert W.camera_height_m == pytest.approx(height, abs=5e-3)
    np.testing.assert_allclose(P_est[..., 2], P_W[..., 2], atol=1.5e-2)
    # x_W is the optical axis on the floor: the operator, straight ahead of the camera, is at y = 0.
    mid = 0.5 * (P_est[:, INDEX["left_shoulder"]] + P_est[:, INDEX["right_shoulder"]])
    assert np.all(np.abs(mid[:, 1]) < 0.02) and np.all(mid[:, 0] > 2.4)
    # Round trip and a proper rotation.
    np.testing.assert_allclose(W.to_camera(P_est), to_camera(P_W, R_WC, p_WC), atol=1e-12)
    assert np.linalg.det(W.R_CW) == pytest.approx(1.0)


def test_imu_up_overrides_the_body():
    R_WC, p_WC = camera_pose(20.0, 0.0, 1.4)
    P_C = to_camera(standing_operator_W(), R_WC, p_WC)
    P_C_leaning = P_C.copy()
    P_C_leaning[:, INDEX["left_shoulder"]] += [0.0, 0.0, 0.15]  # a twisted trunk biases the body's up vector
    accel_C = 9.81 * (R_WC.T @ [0, 0, 1])  # specific force at rest points up
    noisy = accel_C + np.random.default_rng(1).normal(scale=0.05, size=(200, 3))
    up = up_from_accel(noisy)
    W = estimate_world_frame(P_C_leaning, DIMS, up_C=up, source="imu")
    np.testing.assert_allclose(W.R_CW[:, 2], R_WC.T @ [0, 0, 1], atol=2e-3)
    assert W.source == "imu"
    # An IMU mounted rotated: its readings are rotated into C first.
    R_C_imu = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    np.testing.assert_allclose(up_from_accel(noisy @ R_C_imu, R_C_imu), up, atol=1e-12)
    with pytest.raises(ValueError, match="not at rest"):
        up_from_accel([[0.0, 0.1, 0.2]])


def test_axis_maps_are_rotations_with_the_documented_axes():
    for M in (Y_UP_FROM_W, BVH_FROM_W):
        np.testing.assert_allclose(M @ M.T, np.eye(3))
        assert np.linalg.det(M) == pytest.approx(1.0)
        np.testing.assert_allclose(M @ [0, 0, 1], [0, 1, 0])  # up is Y
    np.testing.assert_allclose(Y_UP_FROM_W @ [-1, 0, 0], [1, 0, 0])  # operator forward (towards camera) is X
    np.testing.assert_allclose(Y_UP_FROM_W @ [0, 1, 0], [0, 0, 1])  # operator right is Z
    np.testing.assert_allclose(BVH_FROM_W @ [0, -1, 0], [1, 0, 0])  # operator left is X in BVH


def test_bad_inputs():
    with pytest.raises(ValueError, match="shape"):
        estimate_world_frame(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="shoulders and both hips"):
        estimate_world_frame(np.full((4, NUM_LANDMARKS, 3), np.nan), DIMS)
    with pytest.raises(ValueError, match="rotation"):
        WorldFrame(np.ones((3, 3)), np.zeros(3))
    assert WorldFrame.camera().camera_height_m == 0.0
