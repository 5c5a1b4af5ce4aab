"""Stage S2's numpy part (core/landmark_extraction.py): depth lookup, surface-to-centre correction, deprojection."""

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detection2D
from akc_drake.core.landmark_extraction import (
    DEFAULT_SURFACE_OFFSET_M,
    black_image,
    camera_frame,
    check_extractor_options,
    default_depth_window,
    extract_landmarks,
    surface_offsets,
    surface_to_centre_depth,
)
from akc_drake.core.skeleton import NUM_LANDMARKS

K = CameraIntrinsics(width=80, height=60, fx=70.0, fy=72.0, cx=39.5, cy=29.5, rate_hz=10.0)


class FixedDetector:
    """Returns fixed pixels and visibility, and remembers the frames it saw."""

    name = "fixed"

    def __init__(self, uv, vis, found=True):
        self.uv, self.vis, self.found = uv, vis, found
        self.frames = []

    def detect(self, frame):
        self.frames.append(frame)
        if not self.found:
            return Detection2D.empty()
        return Detection2D(self.uv.copy(), self.vis.copy(), True)


def _uv():
    rng = np.random.default_rng(0)
    return np.stack([rng.uniform(5, 75, NUM_LANDMARKS), rng.uniform(5, 55, NUM_LANDMARKS)], axis=1)


def _depth(z=1.5):
    return np.full((K.height, K.width), z, dtype=np.float32)


def _frame(depth, t=0.0):
    return CameraFrame(color=np.zeros((K.height, K.width, 3), np.uint8), depth_m=depth, t=t, intrinsics=K)


def test_extract_deprojects_the_detected_pixels_at_the_looked_up_depth():
    uv = _uv()
    vis = np.linspace(0.1, 1.0, NUM_LANDMARKS)
    points, v, pix = extract_landmarks(_frame(_depth(1.5)), FixedDetector(uv, vis), surface_offset_m=0)
    np.testing.assert_allclose(points[:, 0], (uv[:, 0] - K.cx) * 1.5 / K.fx, atol=1e-12)
    np.testing.assert_allclose(points[:, 1], (uv[:, 1] - K.cy) * 1.5 / K.fy, atol=1e-12)
    np.testing.assert_allclose(points[:, 2], 1.5, atol=1e-6)
    np.testing.assert_array_equal(v, vis)
    np.testing.assert_array_equal(pix, uv)

def test_depth_is_the_window_median_and_nan_without_valid_depth():
    uv = np.full((NUM_LANDMARKS, 2), 20.0)
    uv[1] = [60.0, 40.0]
    uv[2] = [np.nan, np.nan]
    depth = _depth(2.0)
    depth[18:23, 18:23] = 1.0  # 25 pixels at 1 m under landmark 0's 5x5 window ...
    depth[18, 18] = 3.0  # ... but one is an outlier: the median ignores it
    depth[38:43, 58:63] = 0.0  # no valid depth under landmark 1
    det = FixedDetector(uv, np.ones(NUM_LANDMARKS))
    points, _, _ = extract_landmarks(_frame(depth), det, surface_offset_m=0, window=5, depth_rule="median")
    assert points[0, 2] == pytest.approx(1.0)
    assert np.all(np.isnan(points[1])) and np.all(np.isnan(points[2]))
    points, _, _ = extract_landmarks(
        _frame(depth), FixedDetector(uv, np.ones(NUM_LANDMARKS)), window=1, surface_offset_m=0, depth_rule="median"
    )
    assert points[0, 2] == pytest.approx(1.0)


def test_the_default_lookup_reads_the_body_on_its_edge_not_the_wall_behind():
    # A wrist on the body's edge: its 15x15 window is a third body (1.8 m), two thirds wall (3.3 m).
    uv = np.full((NUM_LANDMARKS, 2), 40.0)
    depth = _depth(3.3)
    depth[:, :38] = 1.8  # columns 33..37 of the window (5 of 15) are the body
    det = FixedDetector(uv, np.ones(NUM_LANDMARKS))
    nearest, _, _ = extract_landmarks(_frame(depth), det, surface_offset_m=0, window=15)
    assert nearest[0, 2] == pytest.approx(1.8)
    median, _, _ = extract_landmarks(_frame(depth), det, surface_offset_m=0, window=15, depth_rule="median")
    assert median[0, 2] == pytest.approx(3.3)
    # A body covering less than a quarter of the window (3 of 15 columns) is an edge, not the landmark's surface.
    depth[:, 36:38] = 3.3
    nearest, _, _ = extract_landmarks(_frame(depth), det, surface_offset_m=0, window=15)
    assert nearest[0, 2] == pytest.approx(3.3)


def test_the_default_window_scales_with_the_focal_length():
    # 15 pixels at the D435's 615-pixel focal length (640x480): the same patch of a body at the same distance.
    assert default_depth_window(CameraIntrinsics()) == default_depth_window() == 15
    assert default_depth_window(CameraIntrinsics(width=1280, height=720, fx=920.0, fy=920.0, cx=640, cy=360)) == 23
    assert default_depth_window(CameraIntrinsics(width=160, height=120, fx=153.7, fy=153.7, cx=80, cy=60)) == 3
    assert default_depth_window(K) == 1  # (this file's 80x60 camera: one pixel)
    for fx in np.linspace(30.0, 3000.0, 50):
        w = default_depth_window(CameraIntrinsics(fx=float(fx)))
        assert w % 2 == 1 and abs(w - 15.0 * fx / 615.0) <= 1.0 + 1e-9


def test_an_unknown_depth_rule_is_refused():
    det = FixedDetector(_uv(), np.ones(NUM_LANDMARKS))
    with pytest.raises(ValueError, match="rule must be one of median, nearest"):
        extract_landmarks(_frame(_depth()), det, depth_rule="mean")
    with pytest.raises(ValueError, match="depth_rule must be one of"):
        check_extractor_options(det, K, 5, None, "mean")

def test_nobody_found_gives_nan_and_zero_visibility():
    points, vis, pix = extract_landmarks(_frame(_depth()), FixedDetector(_uv(), np.ones(12), found=False))
    assert np.all(np.isnan(points)) and np.all(np.isnan(pix)) and np.all(vis == 0)

def test_surface_offsets_spec_forms_and_errors():
    d = surface_offsets()
    assert d.shape == (NUM_LANDMARKS,)
    assert d[0] == DEFAULT_SURFACE_OFFSET_M["shoulder"] and d[4] == DEFAULT_SURFACE_OFFSET_M["wrist"]
    assert d[10] == DEFAULT_SURFACE_OFFSET_M["hip"] == d[11]
    np.testing.assert_array_equal(surface_offsets(0), np.zeros(NUM_LANDMARKS))
    np.testing.assert_array_equal(surface_offsets(0.03), np.full(NUM_LANDMARKS, 0.03))
    mixed = surface_offsets({"hip": 0.1, "left_wrist": 0.0})
    assert mixed[10] == mixed[11] == 0.1 and mixed[4] == 0.0 and mixed[5] == d[5] and mixed[0] == d[0]
    np.testing.assert_array_equal(surface_offsets(np.arange(12) / 100), np.arange(12) / 100)
    with pytest.raises(ValueError, match="unknown joint 'knee'"):
        surface_offsets({"knee": 0.05})
    with pytest.raises(ValueError, match="'left_shoulder'.*-0.01"):
        surface_offsets(-0.01)
    with pytest.raises(ValueError, match="shape \\(3,\\)"):
        surface_offsets([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match="left_elbow"):
        surface_offsets({"left_elbow": float("nan")})

def test_correction_moves_a_sphere_surface_reading_to_its_centre():
    """A sphere of radius r centred at c: the ray through c meets it at range |c| - r; + r is the centre."""
    r = 0.05
    for c in ([0.0, 0.0, 2.0], [0.6, -0.4, 1.7], [-0.9, 0.5, 1.2]):
        c = np.array(c)
        uv = np.array([[K.fx * c[0] / c[2] + K.cx, K.fy * c[1] / c[2] + K.cy]])
        z_surface = c[2] * (np.linalg.norm(c) - r) / np.linalg.norm(c)
        z = surface_to_centre_depth(uv, np.array([z_surface]), np.array([r]), K)
        assert z[0] == pytest.approx(c[2], abs=1e-12)
    # Near the image centre the correction is just + offset; NaN stays NaN.
    centre = np.array([[K.cx, K.cy], [K.cx, K.cy]])
    z = surface_to_centre_depth(centre, np.array([1.5, np.nan]), np.array([0.05, 0.05]), K)
    assert z[0] == pytest.approx(1.55, abs=1e-12) and np.isnan(z[1])

def test_extract_applies_the_offsets_before_deprojection():
    uv = np.tile([K.cx, K.cy], (NUM_LANDMARKS, 1)) + np.linspace(-20, 20, NUM_LANDMARKS)[:, None]
    det = FixedDetector(uv, np.ones(NUM_LANDMARKS))
    off = np.linspace(0.0, 0.11, NUM_LANDMARKS)
    plain, _, _ = extract_landmarks(_frame(_depth(1.5)), det, surface_offset_m=0)
    corr, _, _ = extract_landmarks(_frame(_depth(1.5)), det, surface_offset_m=off)
    # Each point moves along its own pixel ray, by exactly its offset.
    moved = np.linalg.norm(corr - plain, axis=1)
    np.testing.assert_allclose(moved, off, atol=1e-6)
    np.testing.assert_allclose(np.cross(plain, corr), 0.0, atol=1e-9)
    assert np.all(corr[:, 2] >= plain[:, 2])
    default, _, _ = extract_landmarks(_frame(_depth(1.5)), det)
    expected_default, _, _ = extract_landmarks(_frame(_depth(1.5)), det, surface_offset_m=surface_offsets())
    np.testing.assert_array_equal(default, expected_default)


def test_options_give_the_period_and_name_the_bad_one():
    det = FixedDetector(_uv(), np.ones(12))
    assert check_extractor_options(det, K, 5, None) == 0.1
    assert check_extractor_options(det, None, 1, None) == 1.0 / CameraIntrinsics().rate_hz
    assert check_extractor_options(det, K, 3, 0.25) == 0.25
    for args, match in (((object(), K, 5, None), "Detector protocol"), ((det, "640x480", 5, None), "intrinsics"),
                        ((det, K, 4, None), "window"), ((det, K, 0, None), "window"), ((det, K, 5, 0.0), "period_s")):
        with pytest.raises(ValueError, match=match):
            check_extractor_options(*args)


def test_camera_frame_checks_sizes_and_shares_one_black_image():
    depth = _depth(1.2)
    frame = camera_frame(None, depth, 0.3, K, truth=np.ones((12, 3)), label=None)
    assert frame.color.shape == (60, 80, 3) and frame.color.dtype == np.uint8 and not frame.color.any()
    assert not frame.color.flags.writeable and frame.color is black_image(80, 60)
    assert frame.t == 0.3 and frame.intrinsics is K and frame.depth_m is depth and frame.truth_C.sum() == 36
    color = np.full((60, 80, 3), 9, np.uint8)
    assert camera_frame(color, depth, 0.0, K).color is color
    with pytest.raises(ValueError, match=r"80x60 \(depth\), 80x60 \(colour\) does not match camera_info 640x480"):
        camera_frame(color, depth, 0.0, CameraIntrinsics())
    with pytest.raises(ValueError, match="camera_info must hold a CameraIntrinsics, got str"):
        camera_frame(color, depth, 0.0, "K")
