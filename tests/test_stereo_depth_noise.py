"""StereoDepthNoiseSystem: the stereo depth-noise model applied to depth images inside a diagram."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.sensors import ImageDepth32F

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.depth_noise import StereoDepthNoise, frame_rng
from akc_drake.systems.stereo_depth_noise import StereoDepthNoiseSystem

K = CameraIntrinsics(width=40, height=30, fx=38.0, fy=38.0, cx=19.5, cy=14.5, rate_hz=10.0)


def _ideal():
    z = np.full((K.height, K.width), 2.0, np.float32)
    z[:, 25:] = 3.0  # a step: edge pixels become invalid
    z[0, 0] = np.inf  # nothing hit
    return z


def _output(system, t, ideal):
    ctx = system.CreateDefaultContext()
    img = ImageDepth32F(K.width, K.height)
    img.mutable_data[:, :, 0] = ideal
    system.get_input_port().FixValue(ctx, AbstractValue.Make(img))
    ctx.SetTime(t)
    return system.get_output_port().Eval(ctx).data[:, :, 0].copy()


def test_output_is_the_noise_model_of_the_frame_index_at_the_time():
    noise = StereoDepthNoise()
    system = StereoDepthNoiseSystem(K, noise, seed=7)
    ideal = _ideal()
    out = _output(system, 0.3, ideal)
    expected = noise.apply(ideal, K.fx, frame_rng(7, 3))
    np.testing.assert_array_equal(out, expected)
    np.testing.assert_array_equal(system.noisy_depth(ideal, 0.3), expected)
    # The frame index is round(t * rate): a time a little off the sample gives the same frame's noise.
    np.testing.assert_array_equal(_output(system, 0.3 + 1e-4, ideal), expected)
    assert np.any(_output(system, 0.4, ideal) != expected)
    assert np.any(_output(StereoDepthNoiseSystem(K, noise, seed=8), 0.3, ideal) != expected)
    # Invalid where nothing was hit; noisy where something was, with the model's sigma at 2 m.
    assert out[0, 0] == 0.0
    flat = out[5:25, 2:20]
    assert np.all(flat > 0) and np.std(flat - 2.0) == pytest.approx(noise.sigma_z(2.0, K.fx), rel=0.3)


def test_ideal_noise_passes_the_depth_through():
    ideal = _ideal()
    out = _output(StereoDepthNoiseSystem(K, StereoDepthNoise.ideal()), 0.0, ideal)
    np.testing.assert_array_equal(out, StereoDepthNoise.ideal().apply(ideal, K.fx, frame_rng(0, 0)))
    np.testing.assert_array_equal(out[5:25, 2:20], 2.0)
