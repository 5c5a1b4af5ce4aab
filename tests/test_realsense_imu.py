"""A D435i recording's accelerometer gives the world frame's up direction (no camera needed: written with a
pyrealsense2 software device)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.world_frame import up_from_accel
from akc_drake.errors import UserError
from akc_drake.io import realsense

try:
    realsense.import_pyrealsense2()
except UserError as e:  # pragma: no cover - depends on the machine
    pytest.skip(f"pyrealsense2 unusable here: {e}", allow_module_level=True)

K = CameraIntrinsics(width=32, height=24, fx=30.0, fy=30.0, cx=15.5, cy=11.5, depth_scale=0.001, rate_hz=10.0)


def _frames(n):
    rng = np.random.default_rng(0)
    return [CameraFrame(color=rng.integers(0, 256, (K.height, K.width, 3), dtype=np.uint8),
                        depth_m=np.full((K.height, K.width), 2.0), t=0.1 * i, intrinsics=K) for i in range(n)]


def test_gravity_from_a_recorded_accelerometer(tmp_path):
    # A camera pitched down 12 deg and rolled 4 deg, at rest; its IMU aligned with the colour camera (a D435i's;
    # the software recorder cannot store a motion stream's extrinsics, so R reads as identity).
    R_world_color = Rotation.from_euler("xz", [-12.0, 4.0], degrees=True).as_matrix()
    up_color = R_world_color.T @ [0.0, -1.0, 0.0]  # "up" is -y of a level camera
    rng = np.random.default_rng(1)
    accel = 9.81 * up_color + rng.normal(scale=0.05, size=(150, 3))
    path = tmp_path / "imu.db3"
    assert realsense.write_db3(path, _frames(3), K, accel=accel) == 3
    samples, R = realsense.read_bag_accel(path)
    assert samples.shape == (150, 3)
    np.testing.assert_allclose(samples, accel, atol=1e-5)  # float32 on disk
    np.testing.assert_allclose(R, np.eye(3))
    np.testing.assert_allclose(up_from_accel(samples, R), up_color, atol=5e-3)
    assert realsense.read_bag_accel(path, max_samples=40)[0].shape == (40, 3)
    # The video streams still play.
    with realsense.BagReader(path) as reader:
        assert len(list(reader)) == 3


def test_no_accelerometer_stream(tmp_path):
    path = tmp_path / "plain.db3"
    realsense.write_db3(path, _frames(2), K)
    assert realsense.read_bag_accel(path) is None


def test_run_stores_the_imu_up_for_a_bag_source(tmp_path):
    from akc_drake.pipeline.export import imu_up_for_source

    up = np.array([0.0, -0.98, -0.2])
    up /= np.linalg.norm(up)
    path = tmp_path / "imu.db3"
    realsense.write_db3(path, _frames(2), K, accel=np.tile(9.81 * up, (50, 1)))
    np.testing.assert_allclose(imu_up_for_source(f"bag:{path}"), up, atol=1e-6)
    assert imu_up_for_source("sim") is None
    realsense.write_db3(tmp_path / "plain.db3", _frames(2), K)
    assert imu_up_for_source(f"bag:{tmp_path / 'plain.db3'}") is None
