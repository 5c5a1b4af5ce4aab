"""The stereo depth-noise model: sigma_z = z^2 sigma_d / (f b), invalid pixels at edges and out of range."""

import numpy as np
import pytest

from akc_drake.core.depth_noise import StereoDepthNoise, frame_rng

F = 615.0


@pytest.mark.parametrize("z", [0.6, 1.5, 3.0])
def test_sigma_matches_the_formula_statistically(z):
    model = StereoDepthNoise(baseline_m=0.05, sigma_disparity_px=0.1)
    flat = np.full((300, 400), z, dtype=np.float32)
    noisy = model.apply(flat, F, frame_rng(1, 0))
    expected = z * z * 0.1 / (F * 0.05)
    assert model.sigma_z(z, F) == pytest.approx(expected, rel=1e-12)
    err = noisy.astype(float) - z
    assert np.all(noisy > 0)  # a flat plane has no edges
    # 120 000 samples: the sample std is within 1 % of sigma, the mean within 4 standard errors of 0.
    assert err.std() == pytest.approx(expected, rel=0.01)
    assert abs(err.mean()) < 4 * expected / np.sqrt(err.size)


def test_sigma_grows_with_the_square_of_depth():
    model = StereoDepthNoise()
    s1, s2 = model.sigma_z(1.0, F), model.sigma_z(2.0, F)
    assert s2 / s1 == pytest.approx(4.0)
    # A D435-like magnitude: a few millimetres at 1 m, about a centimetre at 2 m.
    assert 0.001 < s1 < 0.01
    assert 0.004 < s2 < 0.03


def test_depth_edges_and_range_read_zero():
    model = StereoDepthNoise(sigma_disparity_px=0.0, edge_width_px=1)
    z = np.full((40, 60), 2.0, dtype=np.float32)
    z[10:30, 20:40] = 1.2  # a box in front of a wall
    z[:, :3] = 0.1  # too close
    z[:, -3:] = np.inf  # nothing hit
    out = model.apply(z, F, None)
    assert np.all(out[:, :3] == 0) and np.all(out[:, -3:] == 0)
    # Both sides of the box's outline are invalid ...
    assert out[20, 19] == 0 and out[20, 20] == 0 and out[20, 39] == 0 and out[20, 40] == 0
    assert out[9, 30] == 0 and out[10, 30] == 0
    # ... the inside and the wall away from the edges are untouched.
    assert out[20, 30] == pytest.approx(1.2) and out[20, 10] == pytest.approx(2.0)
    assert np.count_nonzero(out == 0) < 0.4 * out.size
    wider = StereoDepthNoise(sigma_disparity_px=0.0, edge_width_px=3).apply(z, F, None)
    assert wider[20, 17] == 0 and out[20, 17] != 0


def test_small_depth_steps_on_a_surface_are_not_edges():
    model = StereoDepthNoise(sigma_disparity_px=0.0)
    # A slanted plane: 1 mm per pixel is far below a one-pixel disparity step at 1.5 m.
    z = (1.5 + 0.001 * np.arange(50))[None, :].repeat(20, axis=0).astype(np.float32)
    assert np.all(model.apply(z, F, None) > 0)


def test_noise_is_reproducible_per_frame():
    model = StereoDepthNoise()
    z = np.full((20, 30), 1.7, dtype=np.float32)
    a = model.apply(z, F, frame_rng(5, 12))
    b = model.apply(z, F, frame_rng(5, 12))
    c = model.apply(z, F, frame_rng(5, 13))
    np.testing.assert_array_equal(a, b)
    assert np.any(a != c)
    assert a.dtype == np.float32
    np.testing.assert_array_equal(z, np.float32(1.7))  # the input is not modified


def test_ideal_model_passes_depth_through():
    z = np.random.default_rng(0).uniform(0.5, 4.0, (10, 10)).astype(np.float32)
    np.testing.assert_array_equal(StereoDepthNoise.ideal().apply(z, F, frame_rng(0, 0)), z)


def test_parameter_validation():
    with pytest.raises(ValueError, match="baseline_m"):
        StereoDepthNoise(baseline_m=0.0)
    with pytest.raises(ValueError, match="sigma_disparity_px"):
        StereoDepthNoise(sigma_disparity_px=-1.0)
    with pytest.raises(ValueError, match="min_depth_m"):
        StereoDepthNoise(min_depth_m=5.0, max_depth_m=2.0)
    with pytest.raises(ValueError, match="edge_width_px"):
        StereoDepthNoise(edge_width_px=1.5)
    with pytest.raises(ValueError, match="depth_m"):
        StereoDepthNoise().apply(np.zeros(5), F, None)


def test_correlated_noise_keeps_its_rms_and_survives_a_window_median():
    """``correlation_px``: the per-pixel RMS is still ``sigma_z``, but a joint's 15-pixel median window no longer
    averages it away (independent noise: about a tenth of it left)."""
    z = np.full((240, 320), 2.0, dtype=np.float32)
    sigma = StereoDepthNoise().sigma_z(2.0, F)
    medians = {}
    for corr in (0.0, 4.0):
        model = StereoDepthNoise(correlation_px=corr)
        errs, meds = [], []
        for k in range(40):
            err = model.apply(z, F, frame_rng(3, k)).astype(float) - 2.0
            errs.append(err[20:-20, 20:-20].ravel())
            meds.append(np.median(err[113:128, 153:168]))  # one joint's window
        assert np.concatenate(errs).std() == pytest.approx(sigma, rel=0.05), corr
        medians[corr] = np.std(meds)
    assert medians[0.0] < 0.15 * sigma
    assert 0.45 * sigma < medians[4.0] < 1.0 * sigma
    # Correlated: neighbours 2 px apart nearly agree, 30 px apart do not.
    err = StereoDepthNoise(correlation_px=4.0).apply(z, F, frame_rng(3, 99)).astype(float) - 2.0
    near = np.corrcoef(err[:, :-2].ravel(), err[:, 2:].ravel())[0, 1]
    far = np.corrcoef(err[:, :-30].ravel(), err[:, 30:].ravel())[0, 1]
    assert near > 0.8 and abs(far) < 0.1


def test_independent_noise_is_unchanged_by_the_correlation_field():
    """``correlation_px`` 0 (the default) draws exactly what the model drew before it had the field."""
    z = np.full((20, 30), 1.7, dtype=np.float32)
    model = StereoDepthNoise()
    scale = model.sigma_disparity_px / (F * model.baseline_m)
    rng = frame_rng(5, 12)
    expected = z + z * z * np.float32(scale) * rng.standard_normal(z.shape, dtype=np.float32)
    np.testing.assert_array_equal(model.apply(z, F, frame_rng(5, 12)), expected)
    with pytest.raises(ValueError, match="correlation_px"):
        StereoDepthNoise(correlation_px=-1.0)
    with pytest.raises(ValueError, match="correlation_px"):
        StereoDepthNoise(correlation_px=float("nan"))
