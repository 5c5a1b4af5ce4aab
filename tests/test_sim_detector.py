"""The simulated detector: projected pixels with noise, visibility from the depth image's occlusion."""

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detector, depth_lookup, project
from akc_drake.core.sim_detector import DEFAULT_SURFACE_RADIUS_M, SimulatedDetector
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS

K = CameraIntrinsics(width=160, height=120, fx=150.0, fy=150.0, cx=79.5, cy=59.5)
Z = 2.0


def _scene():
    """12 landmarks on a 4 x 3 grid of pixels at depth Z, each on its own surface (depth Z - radius)."""
    u, v = np.meshgrid([20.0, 60.0, 100.0, 140.0], [20.0, 60.0, 100.0])
    uv = np.stack([u.ravel(), v.ravel()], axis=1)
    truth = np.stack([(uv[:, 0] - K.cx) * Z / K.fx, (uv[:, 1] - K.cy) * Z / K.fy, np.full(12, Z)], axis=1)
    depth = np.full((K.height, K.width), Z + 1.0, dtype=np.float32)  # a wall behind
    det = SimulatedDetector()
    for j in range(NUM_LANDMARKS):
        iu, iv = int(uv[j, 0]), int(uv[j, 1])
        depth[iv - 12 : iv + 13, iu - 12 : iu + 13] = Z - det.surface_radius_m[j]
    return uv, truth, depth


def _frame(depth, truth, t=0.0):
    return CameraFrame(
        color=np.zeros((K.height, K.width, 3), np.uint8), depth_m=depth, t=t, intrinsics=K, truth_C=truth
    )


def test_is_a_detector_and_projects_exactly_without_noise():
    uv, truth, depth = _scene()
    det = SimulatedDetector(pixel_noise_px=0.0, score_noise=0.0)
    assert isinstance(det, Detector)
    out = det.detect(_frame(depth, truth))
    assert out.person_found
    np.testing.assert_allclose(out.uv, uv, atol=1e-9)
    np.testing.assert_allclose(out.visibility, det.visible_score)


def test_a_fully_hidden_landmark_scores_low():
    uv, truth, depth = _scene()
    j = INDEX["left_elbow"]
    iu, iv = int(uv[j, 0]), int(uv[j, 1])
    depth[iv - 12 : iv + 13, iu - 12 : iu + 13] = 1.5  # a forearm 50 cm in front covers it all
    det = SimulatedDetector(pixel_noise_px=0.0, score_noise=0.0)
    share = det.occluded_share(_frame(depth, truth))
    assert share[j] == 1.0
    assert np.all(np.delete(share, j) == 0.0)
    vis = det.detect(_frame(depth, truth)).visibility
    assert vis[j] == pytest.approx(det.occluded_score)
    assert vis[j] < 0.7 and np.all(np.delete(vis, j) > 0.9)


def test_a_limb_seen_end_on_hides_the_depth_but_not_the_visibility():
    """The case the paper's proximity check exists for: visibility above 0.7, depth of the occluder."""
    uv, truth, depth = _scene()
    j = INDEX["left_shoulder"]
    iu, iv = int(uv[j, 0]), int(uv[j, 1])
    depth[iv - 2 : iv + 3, iu - 2 : iu + 3] = 1.6  # a forearm end-on, 5 x 5 px, over the joint
    det = SimulatedDetector(pixel_noise_px=0.0, score_noise=0.0)
    share = det.occluded_share(_frame(depth, truth))
    assert 0.1 < share[j] < 0.3
    out = det.detect(_frame(depth, truth))
    assert out.visibility[j] > 0.7
    z = depth_lookup(depth, out.uv)
    assert z[j] == pytest.approx(1.6)  # the raw depth is the occluder's: 40 cm off
    assert truth[j, 2] - z[j] > 0.1


def test_surfaces_just_in_front_do_not_count_as_occlusion():
    uv, truth, depth = _scene()
    j = INDEX["right_wrist"]
    iu, iv = int(uv[j, 0]), int(uv[j, 1])
    # The landmark's own surface plus 3 cm of bumps: within the margin.
    depth[iv - 12 : iv + 13, iu - 12 : iu + 13] = Z - DEFAULT_SURFACE_RADIUS_M["wrist"] - 0.03
    assert SimulatedDetector().occluded_share(_frame(depth, truth))[j] == 0.0


def test_pixel_noise_statistics_and_reproducibility():
    uv, truth, depth = _scene()
    det = SimulatedDetector(pixel_noise_px=2.0, seed=3)
    errs = np.array([det.detect(_frame(depth, truth, t=0.1 * k)).uv - uv for k in range(300)])
    assert errs.std() == pytest.approx(2.0, rel=0.08)
    assert abs(errs.mean()) < 0.1
    a = det.detect(_frame(depth, truth, t=1.0))
    b = SimulatedDetector(pixel_noise_px=2.0, seed=3).detect(_frame(depth, truth, t=1.0))
    c = SimulatedDetector(pixel_noise_px=2.0, seed=4).detect(_frame(depth, truth, t=1.0))
    np.testing.assert_array_equal(a.uv, b.uv)
    np.testing.assert_array_equal(a.visibility, b.visibility)
    assert np.any(a.uv != c.uv)


def test_hidden_landmarks_get_noisier_pixels():
    uv, truth, depth = _scene()
    j = INDEX["left_elbow"]
    iu, iv = int(uv[j, 0]), int(uv[j, 1])
    depth[iv - 12 : iv + 13, iu - 12 : iu + 13] = 1.5
    det = SimulatedDetector(pixel_noise_px=1.0, hidden_noise_gain=1.0)
    errs = np.array([det.detect(_frame(depth, truth, t=0.1 * k)).uv - uv for k in range(400)])
    assert errs[:, j].std() == pytest.approx(2.0, rel=0.12)
    assert np.delete(errs, j, axis=1).std() == pytest.approx(1.0, rel=0.08)


def test_landmarks_outside_the_image_or_behind_the_camera_are_missing():
    uv, truth, depth = _scene()
    truth = truth.copy()
    truth[0, 0] = 5.0  # far right, outside the image
    truth[1, 2] = -1.0  # behind the camera
    out = SimulatedDetector().detect(_frame(depth, truth))
    assert np.all(np.isnan(out.uv[:2])) and np.all(out.visibility[:2] == 0)
    assert np.all(np.isfinite(out.uv[2:]))
    truth[:, 0] = 50.0
    assert not SimulatedDetector().detect(_frame(depth, truth)).person_found


def test_miss_rate_drops_landmarks():
    uv, truth, depth = _scene()
    det = SimulatedDetector(miss_rate=0.3, seed=1)
    missing = np.array([np.isnan(det.detect(_frame(depth, truth, t=0.1 * k)).uv[:, 0]) for k in range(200)])
    assert missing.mean() == pytest.approx(0.3, abs=0.04)
    assert not SimulatedDetector(miss_rate=1.0).detect(_frame(depth, truth)).person_found


def test_errors_name_the_problem():
    uv, truth, depth = _scene()
    with pytest.raises(ValueError, match="truth_C"):
        SimulatedDetector().detect(_frame(depth, None))
    with pytest.raises(ValueError, match="truth_C must have shape"):
        SimulatedDetector().detect(_frame(depth, truth[:5]))
    with pytest.raises(ValueError, match="visible_score"):
        SimulatedDetector(visible_score=1.5)
    with pytest.raises(ValueError, match="pixel_noise_px"):
        SimulatedDetector(pixel_noise_px=-1.0)
    with pytest.raises(ValueError, match="surface_radius_m"):
        SimulatedDetector(surface_radius_m=np.ones(3))


def test_uses_the_projection_of_the_camera_module():
    _, truth, depth = _scene()
    out = SimulatedDetector(pixel_noise_px=0.0).detect(_frame(depth, truth))
    np.testing.assert_allclose(out.uv, project(truth, K))


def test_hiding_by_the_landmarks_own_arm_counts_partly():
    """BlazePose-like: a joint hidden behind its own forearm scores higher than behind anything else."""
    uv, truth, depth = _scene()
    s = INDEX["left_shoulder"]
    iu, iv = int(uv[s, 0]), int(uv[s, 1])
    depth[iv - 12 : iv + 13, iu - 12 : iu + 13] = 1.5  # something 50 cm in front hides the shoulder
    det = SimulatedDetector(pixel_noise_px=0.0, score_noise=0.0)
    other = det.detect(_frame(depth, truth)).visibility[s]
    assert other == pytest.approx(det.occluded_score)
    # Now that something is the left arm itself: elbow, wrist and hand on the camera ray of the shoulder.
    ray = truth[s] / truth[s, 2]
    arm = truth.copy()
    arm[INDEX["left_elbow"]] = ray * 1.75
    arm[INDEX["left_wrist"]] = ray * 1.55
    arm[INDEX["left_index"]] = ray * 1.50 + [0.0, 0.02, 0.0]
    arm[INDEX["left_pinky"]] = ray * 1.50 - [0.0, 0.02, 0.0]
    total, own = det.occlusion_shares(_frame(depth, arm))
    assert total[s] == 1.0 and own[s] == 1.0
    vis = det.detect(_frame(depth, arm)).visibility[s]
    expected = det.visible_score - (det.visible_score - det.occluded_score) * det.self_occlusion_weight
    assert vis == pytest.approx(expected)
    assert vis > other
    # The right arm's landmarks do not count the left arm as their own.
    assert own[INDEX["right_shoulder"]] == 0.0
