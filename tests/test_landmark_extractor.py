"""Stage S2 as a sampled LeafSystem (systems/landmark_extractor.py) over core/landmark_extraction.py."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core import landmark_extraction
from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.sim_detector import SimulatedDetector
from akc_drake.systems import landmark_extractor, timing
from akc_drake.systems.landmark_extractor import LandmarkExtractor, extract_landmarks, surface_offsets
from tests.test_landmark_extraction import FixedDetector, K, _depth, _frame, _uv


def test_the_core_names_stay_importable_from_the_system_module():
    for name in ("DEFAULT_SURFACE_OFFSET_M", "extract_landmarks", "surface_offsets", "surface_to_centre_depth"):
        assert getattr(landmark_extractor, name) is getattr(landmark_extraction, name)


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


def test_bad_surface_offsets_are_refused():
    with pytest.raises(ValueError, match="surface_offset_m"):
        LandmarkExtractor(K, FixedDetector(_uv(), np.ones(12)), surface_offset_m=2.0)


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


def test_system_uses_its_configured_depth_lookup():
    # Landmark 0 on the body's edge: a third of its 15-pixel window is the body at 1.8 m, the rest the wall.
    uv = np.full((12, 2), 40.0)
    depth = _depth(3.3)
    depth[:, :38] = 1.8
    det = FixedDetector(uv, np.ones(12))
    read = {}
    for rule, window in (("nearest", 15), ("median", 15), ("median", 5)):
        system = LandmarkExtractor(K, det, surface_offset_m=0, depth_rule=rule, window=window)
        assert (system.depth_rule, system.window) == (rule, window)
        context = system.CreateDefaultContext()
        _fix_images(system, context, depth)
        _step(system, context, timing.stage_offset("extractor"))
        read[rule, window] = system.GetOutputPort("landmarks_C").Eval(context)[2]
    assert read["nearest", 15] == pytest.approx(1.8) and read["median", 15] == pytest.approx(3.3)
    assert read["median", 5] == pytest.approx(3.3)
    assert (LandmarkExtractor(K, det).depth_rule, LandmarkExtractor(K, det).window) == ("nearest", 1)  # (fx 70)
    assert LandmarkExtractor(CameraIntrinsics(), det).window == 15
    with pytest.raises(ValueError, match="depth_rule"):
        LandmarkExtractor(K, det, depth_rule="closest")
