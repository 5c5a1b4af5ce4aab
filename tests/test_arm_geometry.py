import numpy as np
import pytest

from akc_drake.core.arm_geometry import (
    DEFAULT_AXES,
    bends_backwards,
    elbow_angle_deg,
    signed_elbow_angle_deg,
    torso_axes,
)
from akc_drake.core.skeleton import INDEX


def _pose_facing_camera():
    v = np.zeros((12, 3))
    v[INDEX["left_shoulder"]] = [0.18, 0.0, 2.0]
    v[INDEX["right_shoulder"]] = [-0.18, 0.0, 2.0]
    v[INDEX["left_hip"]] = [0.12, 0.5, 2.0]
    v[INDEX["right_hip"]] = [-0.12, 0.5, 2.0]
    return v


def test_torso_axes_of_an_operator_facing_the_camera():
    front, down, lat = torso_axes(_pose_facing_camera().ravel().tolist())
    np.testing.assert_allclose(front, [0, 0, -1], atol=1e-12)  # towards the camera
    np.testing.assert_allclose(down, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(lat, [1, 0, 0], atol=1e-12)
    v = _pose_facing_camera()
    v[INDEX["left_hip"]] = np.nan
    assert torso_axes(v.ravel().tolist()) == DEFAULT_AXES


def test_signed_elbow_angle():
    # Arm hanging down, forearm forward (towards the camera): flexion, 90 deg.
    s, e = np.array([0.2, 0.0, 2.0]), np.array([0.2, 0.3, 2.0])
    assert signed_elbow_angle_deg(s, e, e + [0, 0, -0.25]) == pytest.approx(90.0)
    # Forearm bent backwards by 45 deg: hyperextension, theta = 360 - 135 = 225 deg (outside [40, 180]).
    w = e + 0.25 * np.array([0, np.cos(np.radians(45)), np.sin(np.radians(45))])
    assert elbow_angle_deg(s, e, w) == pytest.approx(135.0)
    assert signed_elbow_angle_deg(s, e, w) == pytest.approx(225.0)
    # Upper arm raised forwards (horizontal, towards the camera): the anterior side is up, so a forearm bent
    # upwards is flexion, whatever the torso's front.
    e2 = s + [0, 0, -0.3]
    assert signed_elbow_angle_deg(s, e2, e2 + [0, -0.25, 0]) == pytest.approx(90.0)
    assert not bends_backwards(0, 0, 1.0, 0, -0.25, 0, 0.25, DEFAULT_AXES)
    assert np.isnan(elbow_angle_deg(s, s, e))
