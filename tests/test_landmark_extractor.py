"""Stage S2: detection -> depth lookup -> deprojection, as a function and as a sampled LeafSystem."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detection2D
from akc_drake.core.sim_detector import SimulatedDetector
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.systems import timing
from akc_drake.systems.landmark_extractor import (
    DEFAULT_SURFACE_OFFSET_M,
    LandmarkExtractor,
    extract_landmarks,
    surface_offsets,
    surface_to_centre_depth,
)

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
    points, _, _ = extract_landmarks(_frame(depth), det, surface_offset_m=0)
    assert points[0, 2] == pytest.approx(1.0)
    assert np.all(np.isnan(points[1])) and np.all(np.isnan(points[2]))
    points, _, _ = extract_landmarks(
        _frame(depth), FixedDetector(uv, np.ones(NUM_LANDMARKS)), window=1, surface_offset_m=0
    )
    assert points[0, 2] == pytest.approx(1.0)


def test_nobody_found_gives_nan_and_zero_visibility():
    points, vis, pix = extract_landmarks(_frame(_depth()), FixedDetector(_uv(), np.ones(12), found=False))
    assert np.all(np.isnan(points)) and np.all(np.isnan(pix)) and np.all(vis == 0)


def _fix_images(system, context, depth, with_info=True):
    rgba = ImageRgba8U(K.width, K.height)
    img = ImageDepth32F(K.width, K.height)
    img.mutable_data[:, :, 0] = depth
    system.GetInputPort("color_image").FixValue(context, AbstractValue.Make(rgba))
    system.GetInputPort("depth_image").FixValue(context, AbstractValue.Make(img))
    if with_info:
        system.GetInputPort("camera_info").FixValue(context, AbstractValue.Make(K))


def _step(system, context, t):
    context.SetTime(t)
    values = system.EvalUniquePeriodicDiscreteUpdate(context)
    context.SetDiscreteState(values)


def test_system_ports_timing_and_initial_outputs():
    system = LandmarkExtractor(K, FixedDetector(_uv(), np.ones(12)))
    names_in = [system.get_input_port(i).get_name() for i in range(system.num_input_ports())]
    names_out = [system.get_output_port(i).get_name() for i in range(system.num_output_ports())]
    assert names_in == ["color_image", "depth_image", "camera_info", "label_image", "landmarks_true_C"]
    assert names_out == ["landmarks_C", "visibility", "pixels"]
    assert system.GetOutputPort("landmarks_C").size() == 36 and system.GetOutputPort("pixels").size() == 24
    attr = system.GetUniquePeriodicDiscreteUpdateAttribute()
    assert attr.period_sec() == pytest.approx(0.1)
    assert attr.offset_sec() == pytest.approx(timing.stage_offset("extractor"))
    context = system.CreateDefaultContext()
    assert np.all(np.isnan(system.GetOutputPort("landmarks_C").Eval(context)))
    assert np.all(system.GetOutputPort("visibility").Eval(context) == 0)


def test_system_output_equals_the_function_over_updates():
    uv = _uv()
    det = FixedDetector(uv, np.full(12, 0.8))
    system = LandmarkExtractor(K, det)
    context = system.CreateDefaultContext()
    offset = timing.stage_offset("extractor")
    for k, z in enumerate((1.2, 2.5, 0.9)):
        _fix_images(system, context, _depth(z))
        _step(system, context, 0.1 * k + offset)
        expected, vis, pix = extract_landmarks(_frame(_depth(z)), det)
        np.testing.assert_array_equal(system.GetOutputPort("landmarks_C").Eval(context), expected.ravel())
        np.testing.assert_array_equal(system.GetOutputPort("visibility").Eval(context), vis)
        np.testing.assert_array_equal(system.GetOutputPort("pixels").Eval(context), pix.ravel())
        # The frame the detector saw: time of the camera sample, no label or truth (ports unconnected).
        seen = det.frames[-2]
        assert seen.t == pytest.approx(0.1 * k)
        assert seen.label is None and seen.truth_C is None
        assert seen.depth_m.shape == (K.height, K.width) and seen.color.shape == (K.height, K.width, 3)


def test_optional_inputs_reach_the_detector_and_camera_info_defaults_to_the_constructor():
    det = FixedDetector(_uv(), np.ones(12))
    system = LandmarkExtractor(K, det)
    context = system.CreateDefaultContext()
    _fix_images(system, context, _depth(), with_info=False)
    labels = ImageLabel16I(K.width, K.height)
    labels.mutable_data[:, :, 0] = 7
    truth = np.arange(36.0)
    system.GetInputPort("label_image").FixValue(context, AbstractValue.Make(labels))
    system.GetInputPort("landmarks_true_C").FixValue(context, truth)
    _step(system, context, 0.001)
    frame = det.frames[-1]
    assert frame.intrinsics == K
    assert np.all(frame.label == 7)
    np.testing.assert_array_equal(frame.truth_C, truth.reshape(12, 3))


def test_default_detector_is_the_simulated_one():
    system = LandmarkExtractor(K, seed=5)
    assert isinstance(system.detector, SimulatedDetector) and system.detector.seed == 5
    context = system.CreateDefaultContext()
    _fix_images(system, context, _depth(1.98))
    truth = np.zeros((12, 3))
    truth[:, 0] = np.linspace(-0.5, 0.5, 12)
    truth[:, 2] = 2.0
    system.GetInputPort("landmarks_true_C").FixValue(context, truth.ravel())
    _step(system, context, 0.3 + timing.stage_offset("extractor"))
    points = system.GetOutputPort("landmarks_C").Eval(context).reshape(12, 3)
    # The surface depth 1.98 plus each joint's surface-to-centre offset along its ray (rays within 15 deg).
    off = surface_offsets()
    assert np.all(points[:, 2] > 1.98 + 0.95 * off) and np.all(points[:, 2] <= 1.98 + off + 1e-6)
    frame = _frame(_depth(1.98), t=0.3)
    frame.truth_C = truth
    expected, vis, _ = extract_landmarks(frame, SimulatedDetector(seed=5))
    np.testing.assert_allclose(points, expected, atol=1e-12)
    np.testing.assert_allclose(system.GetOutputPort("visibility").Eval(context), vis, atol=1e-12)
    assert np.all(vis > 0.85)


def test_bad_arguments_and_inputs():
    with pytest.raises(ValueError, match="window"):
        LandmarkExtractor(K, FixedDetector(_uv(), np.ones(12)), window=4)
    with pytest.raises(ValueError, match="Detector protocol"):
        LandmarkExtractor(K, object())
    with pytest.raises(ValueError, match="intrinsics"):
        LandmarkExtractor("640x480")
    system = LandmarkExtractor(K, FixedDetector(_uv(), np.ones(12)))
    context = system.CreateDefaultContext()
    _fix_images(system, context, _depth())
    system.GetInputPort("camera_info").FixValue(context, AbstractValue.Make(CameraIntrinsics()))
    with pytest.raises(ValueError, match="does not match camera_info 640x480"):
        system.frame_from_inputs(context)


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
    with pytest.raises(ValueError, match="surface_offset_m"):
        LandmarkExtractor(K, FixedDetector(_uv(), np.ones(12)), surface_offset_m=2.0)


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


def test_system_uses_its_configured_offsets():
    uv = _uv()
    det = FixedDetector(uv, np.ones(12))
    for spec in (None, 0, {"shoulder": 0.07}):
        system = LandmarkExtractor(K, det, surface_offset_m=spec)
        np.testing.assert_array_equal(system.surface_offset_m, surface_offsets(spec))
        context = system.CreateDefaultContext()
        _fix_images(system, context, _depth(1.7))
        _step(system, context, timing.stage_offset("extractor"))
        expected, _, _ = extract_landmarks(_frame(_depth(1.7)), det, surface_offset_m=spec)
        np.testing.assert_array_equal(system.GetOutputPort("landmarks_C").Eval(context), expected.ravel())
