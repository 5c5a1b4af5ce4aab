"""Operator motions: the paper's T/L poses, Motion I and Motion II, their timing, variation and trajectory."""

import math

import numpy as np
import pytest

from akc_drake.core.skeleton import INDEX
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams, landmarks_from_q
from akc_drake.operator.motions import (
    CYCLE_SECONDS,
    DEFAULT_TARGET_O,
    HOLD_SECONDS,
    OperatorMotion,
    lpose,
    make_motion,
    motion_I,
    motion_II,
    tpose,
)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _angle_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.sum(_unit(a) * _unit(b), axis=-1), -1, 1)))


def _elbow_flexion_deg(lm, side):
    s, e, w = (INDEX[f"{side}_{j}"] for j in ("shoulder", "elbow", "wrist"))
    return _angle_deg(lm[:, e] - lm[:, s], lm[:, w] - lm[:, e])


def test_motion_I_goes_from_t_pose_to_pointing_at_the_camera_and_back():
    m = motion_I(cycles=3, seed=1)
    assert m.duration == pytest.approx(3 * CYCLE_SECONDS)
    lm = m.landmarks_O()
    target = np.array(DEFAULT_TARGET_O)
    for side, lateral in (("left", 1.0), ("right", -1.0)):
        s, e, w = (INDEX[f"{side}_{j}"] for j in ("shoulder", "elbow", "wrist"))
        to_camera = _angle_deg(lm[:, w] - lm[:, s], target - lm[:, s])
        out_to_side = _angle_deg(lm[:, e] - lm[:, s], np.array([0.0, lateral, 0.0]))
        for c in range(3):
            in_cycle = (m.times >= c * CYCLE_SECONDS) & (m.times < (c + 1) * CYCLE_SECONDS)
            # Once per cycle the arm points at the camera (within a few degrees) ...
            assert to_camera[in_cycle].min() < 7.0
            # ... and at the cycle's start it is in a T-pose (out to the side).
            assert out_to_side[in_cycle][0] < 10.0
        # Mid-cycle (3 s) it is at the camera-pointing peak, the elbow nearly straight.
        mid = np.argmin(np.abs(m.times - 3.0))
        assert to_camera[mid] < 7.0
        assert _elbow_flexion_deg(lm, side)[mid] < 15.0


def test_motion_II_flexes_the_elbow_to_about_90_deg_with_the_upper_arm_on_the_camera():
    m = motion_II(cycles=2, seed=4)
    lm = m.landmarks_O()
    target = np.array(DEFAULT_TARGET_O)
    for side in ("left", "right"):
        s, e = INDEX[f"{side}_shoulder"], INDEX[f"{side}_elbow"]
        flex = _elbow_flexion_deg(lm, side)
        upper_to_camera = _angle_deg(lm[:, e] - lm[:, s], target - lm[:, s])
        # After the first cycle's start from a T-pose the upper arm keeps pointing at the camera: the
        # shoulder stays hidden behind the elbow.
        assert upper_to_camera[m.times >= 2.5].max() < 10.0
        lateral = np.array([0.0, 1.0 if side == "left" else -1.0, 0.0])
        assert _angle_deg(lm[0, e] - lm[0, s], lateral) < 1e-9
        for c in range(2):
            in_cycle = (m.times >= c * CYCLE_SECONDS) & (m.times < (c + 1) * CYCLE_SECONDS)
            assert 75.0 < flex[in_cycle].max() < 105.0
            assert flex[in_cycle][0] < 10.0  # starts extended
        # Flexion raises the forearm (wrist above the elbow at the peak).
        w = INDEX[f"{side}_wrist"]
        peak = np.argmax(flex)
        assert lm[peak, w, 2] - lm[peak, e, 2] > 0.2


def test_motion_II_can_start_extended():
    m = motion_II(1, seed=0, start_from_tpose=False)
    lm = m.landmarks_O()
    s, e = INDEX["left_shoulder"], INDEX["left_elbow"]
    assert _angle_deg(lm[0, e] - lm[0, s], np.array(DEFAULT_TARGET_O) - lm[0, s]) < 10.0


def test_cycles_vary_a_little_and_the_seed_reproduces_them():
    a, b, c = motion_I(4, seed=7), motion_I(4, seed=7), motion_I(4, seed=8)
    np.testing.assert_array_equal(a.q_left, b.q_left)
    assert np.max(np.abs(a.q_left - c.q_left)) > 1e-3
    # Peak adduction per cycle differs between cycles by a few degrees, not tens.
    peaks = [np.degrees(a.q_left[(a.times >= k * 6) & (a.times < (k + 1) * 6), 0].max()) for k in range(4)]
    assert np.std(peaks) > 0.2
    assert max(peaks) - min(peaks) < 15.0
    flat = motion_I(4, seed=7, variation=0.0)
    per_cycle = [flat.q_left[(flat.times >= k * 6) & (flat.times < (k + 1) * 6)] for k in range(4)]
    for k in range(1, 4):
        np.testing.assert_allclose(per_cycle[k][: len(per_cycle[0]) - 1], per_cycle[0][:-1], atol=1e-12)


def test_motions_are_smooth():
    for m in (motion_I(3, seed=2), motion_II(3, seed=2)):
        q = m.q()
        step = np.abs(np.diff(q, axis=0)).max()
        # 0.01 s samples: joint speeds below 3 rad/s, a human pace.
        assert step / (m.times[1] - m.times[0]) < 3.0


def test_holds():
    t = tpose(seconds=10.0, seed=0)
    assert t.duration == pytest.approx(10.0)
    lm = t.landmarks_O()
    for side, sign in (("left", 1), ("right", -1)):
        s, w = INDEX[f"{side}_shoulder"], INDEX[f"{side}_wrist"]
        # Arms straight out to the sides (sway below a degree or two).
        assert _angle_deg(lm[:, w] - lm[:, s], np.array([0.0, sign, 0.0])).max() < 3.0
        # Palms down: the index knuckle is level with the pinky knuckle, not above it.
        assert np.abs(lm[:, INDEX[f"{side}_index"], 2] - lm[:, INDEX[f"{side}_pinky"], 2]).max() < 0.02
    lp = lpose(seconds=5.0, seed=0).landmarks_O()
    for side in ("left", "right"):
        e, w = INDEX[f"{side}_elbow"], INDEX[f"{side}_wrist"]
        assert _angle_deg(lp[:, w] - lp[:, e], np.array([0.0, 0.0, 1.0])).max() < 3.0  # forearm up
        assert np.abs(_elbow_flexion_deg(lp, side) - 90.0).max() < 3.0


def test_trajectory_matches_samples_and_interpolation():
    m = motion_II(1, seed=0)
    traj = m.trajectory()
    assert traj.rows() == 2 * NUM_ARM_DOF
    for t in (0.0, 1.234, 3.0, 5.999):
        ql, qr = m.sample(t)
        np.testing.assert_allclose(traj.value(t).ravel(), np.r_[ql[0], qr[0]], atol=1e-12)
    np.testing.assert_allclose(m.frame_times(10.0), np.arange(61) / 10.0)


def test_make_motion_names_and_errors():
    assert make_motion("i", 1, 0).name == "I"
    assert make_motion("II", 2, 0).duration == pytest.approx(12.0)
    assert make_motion("tpose", 1, 0).duration == pytest.approx(HOLD_SECONDS)
    assert make_motion("lpose", 2, 0).name == "lpose"
    with pytest.raises(ValueError, match="unknown motion 'III'"):
        make_motion("III")
    with pytest.raises(ValueError, match="cycles"):
        make_motion("I", 0)
    with pytest.raises(ValueError, match="seconds"):
        tpose(seconds=-1.0)


def test_operator_motion_validates_its_arrays():
    t = np.linspace(0, 1, 5)
    q = np.zeros((5, NUM_ARM_DOF))
    with pytest.raises(ValueError, match="q_right must have shape"):
        OperatorMotion(t, q, q[:4])
    with pytest.raises(ValueError, match="strictly increasing"):
        OperatorMotion(t[::-1], q, q)
    bad = q.copy()
    bad[2, 1] = math.nan
    with pytest.raises(ValueError, match=r"q_left\[2\]"):
        OperatorMotion(t, bad, q)


def test_target_follows_a_custom_camera():
    params = OperatorParams()
    target = (1.5, 0.3, 0.6)
    m = motion_I(1, seed=0, target_O=target, variation=0.0)
    lm = landmarks_from_q(*m.sample(3.0), params)[0]
    s, w = INDEX["left_shoulder"], INDEX["left_wrist"]
    assert _angle_deg(lm[w] - lm[s], np.array(target) - lm[s]) < 5.0
