import json

import numpy as np
import pytest

from akc_drake.core.camera import (
    CameraIntrinsics,
    Detection2D,
    deproject,
    depth_lookup,
    nearest_surface_depth,
    project,
)


def test_project_deproject_round_trip():
    K = CameraIntrinsics(width=640, height=480, fx=600.0, fy=610.0, cx=320.0, cy=240.0)
    rng = np.random.default_rng(0)
    p = rng.uniform([-0.5, -0.4, 1.0], [0.5, 0.4, 3.0], size=(100, 3))
    uv = project(p, K)
    np.testing.assert_allclose(deproject(uv, p[:, 2], K), p, atol=1e-12)
    # A point on the optical axis lands on the principal point.
    np.testing.assert_allclose(project(np.array([0.0, 0.0, 2.0]), K), [320.0, 240.0])
    # A point 1 m right at 2 m depth: u = cx + fx * 0.5.
    np.testing.assert_allclose(project(np.array([1.0, 0.0, 2.0]), K), [620.0, 240.0])


def test_project_behind_camera_and_nan_depth():
    K = CameraIntrinsics()
    assert np.isnan(project(np.array([0.0, 0.0, -1.0]), K)).all()
    assert np.isnan(deproject(np.array([[10.0, 10.0]]), np.array([np.nan]), K)).all()


def test_depth_lookup_median_and_invalid():
    d = np.zeros((20, 30))
    d[5:10, 5:10] = 2.0
    d[7, 7] = 9.0  # outlier within the window: the median ignores it
    d[15:, 20:] = 50.0  # out of range -> invalid
    z = depth_lookup(d, np.array([[7, 7], [25, 17], [np.nan, 1.0], [100.0, 5.0], [1.0, 1.0]]), window=5)
    assert z[0] == 2.0
    assert np.isnan(z[1]) and np.isnan(z[2]) and np.isnan(z[3]) and np.isnan(z[4])


def test_nearest_surface_is_the_nearest_cluster_holding_a_quarter():
    rng = np.random.default_rng(3)
    body = 1.80 + 0.01 * rng.standard_normal(30)  # stereo noise within a surface: one cluster
    wall = 3.30 + 0.01 * rng.standard_normal(70)
    assert nearest_surface_depth(np.concatenate([wall, body])) == pytest.approx(np.median(body))
    assert np.median(np.concatenate([wall, body])) > 3.2  # (the median reads the wall)
    # Fewer than a quarter (20 of 90), or fewer than 3 pixels: the next surface decides.
    assert nearest_surface_depth(np.concatenate([wall, body[:20]])) == pytest.approx(np.median(wall))
    assert nearest_surface_depth(np.array([1.0, 1.05, 2.0, 2.01, 2.02])) == pytest.approx(2.01)
    # Surfaces closer than the gap (20 cm) are one: a forearm 15 cm in front of the chest is not split off.
    both = np.concatenate([np.full(40, 1.65), np.full(60, 1.80)])
    assert nearest_surface_depth(both) == pytest.approx(np.median(both))
    # No cluster holds enough (many thin surfaces): the median of all.
    spread = np.arange(10) * 0.5 + 1.0
    assert nearest_surface_depth(spread) == pytest.approx(np.median(spread))
    assert nearest_surface_depth(np.array([2.5])) == 2.5


def test_depth_lookup_nearest_rule():
    d = np.full((40, 40), 3.3)
    d[:, :20] = 1.8  # the body's edge at column 20
    uv = np.array([[21.0, 20.0], [25.0, 20.0], [5.0, 5.0]])
    z_med = depth_lookup(d, uv, window=9)
    z_near = depth_lookup(d, uv, window=9, rule="nearest")
    assert z_med[0] == pytest.approx(3.3) and z_near[0] == pytest.approx(1.8)  # 4 of 9 columns are the body
    assert z_near[1] == pytest.approx(3.3)  # 0 of 9: the wall
    assert z_near[2] == z_med[2] == pytest.approx(1.8)
    with pytest.raises(ValueError, match="rule"):
        depth_lookup(d, uv, rule="min")


def test_intrinsics_validation_and_load(tmp_path):
    with pytest.raises(ValueError, match="fx"):
        CameraIntrinsics(fx=-1.0)
    with pytest.raises(ValueError, match="width"):
        CameraIntrinsics(width=0)
    f = tmp_path / "intrinsics.json"
    f.write_text(json.dumps({"width": 640, "height": 480, "fx": 600, "fy": 600, "cx": 320, "cy": 240}))
    K = CameraIntrinsics.load(f)
    assert K.fx == 600 and K.rate_hz == 10.0
    np.testing.assert_allclose(K.K(), [[600, 0, 320], [0, 600, 240], [0, 0, 1]])
    f.write_text(json.dumps({"width": 640, "height": 480, "fx": 600, "fy": 600, "cx": 320}))
    with pytest.raises(ValueError, match="intrinsics.json: missing cy"):
        CameraIntrinsics.load(f)
    f.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        CameraIntrinsics.load(f)


def test_empty_detection():
    det = Detection2D.empty()
    assert det.uv.shape == (12, 2) and np.isnan(det.uv).all() and not det.person_found
