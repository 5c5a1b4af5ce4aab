"""The operator model: SDF file in sync with its generator, Drake kinematics == numpy kinematics, the
closed-form arm inverse, and parameter validation."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.geometry import SceneGraph
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from akc_drake.core.skeleton import INDEX, LANDMARKS, BodyDimensions, segment_lengths
from akc_drake.operator.model import (
    NEUTRAL_FOREARM_ROLL,
    NUM_ARM_DOF,
    OperatorParams,
    arm_angles_from_directions,
    arm_forward_kinematics,
    arm_rotations,
    landmarks_from_q,
)
from akc_drake.operator.sdf import (
    MESH_FOLDER,
    MESHES,
    add_operator,
    landmark_positions,
    operator_position_indices,
    operator_sdf,
)
from akc_drake.resources import MODELS_DIR

_KEEP_ALIVE = []  # the plant keeps a raw pointer to its SceneGraph


def _plant(params=None):
    plant = MultibodyPlant(0.0)
    scene_graph = SceneGraph()
    _KEEP_ALIVE.append(scene_graph)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    instance = add_operator(plant, params)
    plant.Finalize()
    return plant, instance


def _directions(side, q):
    y = np.array([0.0, 1.0 if side == "left" else -1.0, 0.0])
    R_OU, R_OF, R_OH = arm_rotations(side, q)
    return R_OU @ y, R_OF @ y, R_OH @ np.array([1.0, 0.0, 0.0])


def test_models_file_is_the_generator_output():
    sdf = MODELS_DIR / "operator.sdf"
    assert sdf.read_text(encoding="utf-8") == operator_sdf(OperatorParams()), (
        "akc_drake/models/operator.sdf is stale: regenerate it with "
        "python -c 'from akc_drake.operator.sdf import write_operator_sdf; "
        'write_operator_sdf("akc_drake/models/operator.sdf")\''
    )
    for name, gen in MESHES.items():
        assert (MODELS_DIR / MESH_FOLDER / name).read_text(encoding="utf-8") == gen()


def test_models_file_loads_with_plain_drake_parser():
    plant = MultibodyPlant(0.0)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    (instance,) = Parser(plant).AddModels(str(MODELS_DIR / "operator.sdf"))
    plant.Finalize()
    assert plant.num_positions() == 2 * NUM_ARM_DOF + 7  # the pelvis floats when nobody welds it
    names = {plant.get_body(b).name() for b in plant.GetBodyIndices(instance)}
    assert {"pelvis", "torso", "left_upper_arm", "right_forearm", "left_hand"} <= names


def test_drake_and_numpy_kinematics_agree():
    plant, instance = _plant()
    ctx = plant.CreateDefaultContext()
    idx = operator_position_indices(plant, instance)
    rng = np.random.default_rng(3)
    for _ in range(5):
        ql, qr = rng.uniform(-3, 3, NUM_ARM_DOF), rng.uniform(-3, 3, NUM_ARM_DOF)
        q = np.zeros(plant.num_positions())
        q[idx] = np.r_[ql, qr]
        plant.SetPositions(ctx, q)
        np.testing.assert_allclose(landmark_positions(plant, ctx), landmarks_from_q(ql, qr)[0], atol=1e-12)


def test_zero_configuration_is_a_t_pose_with_the_paper_dimensions():
    p = OperatorParams()
    d = BodyDimensions.paper_participant()
    lm = landmarks_from_q(np.zeros(NUM_ARM_DOF), np.zeros(NUM_ARM_DOF), p)[0]
    np.testing.assert_allclose(lm[INDEX["left_shoulder"]], [0, d.SW / 2, p.torso_height], atol=1e-15)
    np.testing.assert_allclose(
        lm[INDEX["left_wrist"]], [0, d.SW / 2 + d.LUA + d.LLA, p.torso_height], atol=1e-15
    )
    np.testing.assert_allclose(
        lm[INDEX["right_wrist"]], [0, -d.SW / 2 - d.RUA - d.RLA, p.torso_height], atol=1e-15
    )
    # Thumb up with the palm forward: the index knuckle is above the pinky knuckle.
    assert lm[INDEX["left_index"], 2] > lm[INDEX["left_pinky"], 2] + 0.05
    assert lm[INDEX["left_hip"], 1] == pytest.approx(p.hip_width / 2)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-6, 6), min_size=NUM_ARM_DOF, max_size=NUM_ARM_DOF))
def test_segment_lengths_are_constant_for_any_q(q):
    q = np.array(q)
    lm = landmarks_from_q(q, -q)
    lengths = segment_lengths(lm)
    d = BodyDimensions.paper_participant()
    for seg in ("LUA", "LLA", "RUA", "RLA", "SW"):
        assert lengths[seg][0] == pytest.approx(getattr(d, seg), abs=1e-12)


def test_equal_angles_give_mirrored_arms():
    rng = np.random.default_rng(0)
    q = rng.uniform(-2, 2, (20, NUM_ARM_DOF))
    symmetric = OperatorParams(dims=BodyDimensions(LUA=0.3, LLA=0.27, RUA=0.3, RLA=0.27, SW=0.34))
    left = arm_forward_kinematics("left", q, symmetric)
    right = arm_forward_kinematics("right", q, symmetric)
    np.testing.assert_allclose(right, left * np.array([1.0, -1.0, 1.0]), atol=1e-14)


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(["left", "right"]),
    st.floats(-3.0, 3.0),
    st.floats(-1.5, 1.5),
    st.floats(-3.0, 3.0),
    st.floats(0.05, 3.0),
    st.floats(-3.0, 3.0),
)
def test_inverse_reproduces_directions_and_palm(side, a, b, c, d, e):
    q = np.array([[a, b, c, d, e]])
    u, f, n = _directions(side, q)
    q2 = arm_angles_from_directions(side, u, f, n)
    u2, f2, n2 = _directions(side, q2)
    np.testing.assert_allclose(u2, u, atol=1e-9)
    np.testing.assert_allclose(f2, f, atol=1e-9)
    np.testing.assert_allclose(n2, n, atol=1e-9)
    np.testing.assert_allclose(arm_forward_kinematics(side, q2), arm_forward_kinematics(side, q), atol=1e-9)


def test_inverse_without_palm_uses_the_neutral_roll_and_ignores_direction_length():
    q = np.array([[0.4, 0.2, -0.7, 1.1, 0.0]])
    u, f, _ = _directions("left", q)
    q2 = arm_angles_from_directions("left", 3.0 * u, 0.5 * f)
    np.testing.assert_allclose(q2[0, :4], q[0, :4], atol=1e-12)
    assert q2[0, 4] == NEUTRAL_FOREARM_ROLL


def test_inverse_is_continuous_through_singular_frames():
    # Upper arm swinging from the side up through vertical and over, elbow straight for a while.
    T = 200
    elev = np.linspace(0.0, math.pi, T)  # passes through straight up at T/2
    u = np.stack([np.zeros(T), np.cos(elev), np.sin(elev)], axis=1)
    bend = np.clip(np.linspace(-0.5, 1.0, T), 0.0, None)  # straight elbow for the first third
    # Forearm bends forward (+x) from the upper-arm direction.
    f = np.cos(bend)[:, None] * u + np.sin(bend)[:, None] * np.array([1.0, 0.0, 0.0])
    q = arm_angles_from_directions("left", u, f)
    assert np.all(np.isfinite(q))
    # Continuity: no jumps between frames beyond what the motion itself needs (pi / T per frame here).
    assert np.max(np.abs(np.diff(q, axis=0))) < 0.1
    u2, f2, _ = _directions("left", q)
    np.testing.assert_allclose(u2, u, atol=1e-6)
    np.testing.assert_allclose(f2, f, atol=1e-6)


def test_inverse_unwraps_angles():
    t = np.linspace(0, 4 * math.pi, 400)
    q = np.zeros((400, NUM_ARM_DOF))
    q[:, 0] = t  # the arm circles horizontally twice
    q[:, 3] = 0.5
    u, f, n = _directions("right", q)
    q2 = arm_angles_from_directions("right", u, f, n)
    assert np.max(np.abs(np.diff(q2[:, 0]))) < 0.05
    assert q2[-1, 0] - q2[0, 0] == pytest.approx(4 * math.pi, abs=1e-9)


def test_inverse_rejects_bad_input():
    u = np.tile([1.0, 0.0, 0.0], (3, 1))
    with pytest.raises(ValueError, match="fore_dir_O"):
        arm_angles_from_directions("left", u, np.ones((2, 3)))
    bad = u.copy()
    bad[1] = 0.0
    with pytest.raises(ValueError, match=r"upper_dir_O\[1\]"):
        arm_angles_from_directions("left", bad, u)
    with pytest.raises(ValueError, match="side"):
        arm_angles_from_directions("middle", u, u)
    nan = u.copy()
    nan[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"palm_normal_O\[2\]"):
        arm_angles_from_directions("left", u, u, nan)


def test_params_validation_and_custom_dimensions():
    with pytest.raises(ValueError, match="upper_arm_radius"):
        OperatorParams(upper_arm_radius=-0.01)
    with pytest.raises(ValueError, match="knuckle_distance"):
        OperatorParams(knuckle_distance=0.3)
    with pytest.raises(ValueError, match="dims"):
        OperatorParams(dims={"LUA": 0.3})
    dims = BodyDimensions(LUA=0.31, LLA=0.25, RUA=0.30, RLA=0.26, SW=0.40)
    params = OperatorParams(dims=dims)
    plant, instance = _plant(params)
    ctx = plant.CreateDefaultContext()
    lm = landmark_positions(plant, ctx)
    lengths = segment_lengths(lm)
    for seg in ("LUA", "LLA", "RUA", "RLA", "SW"):
        assert lengths[seg] == pytest.approx(getattr(dims, seg), abs=1e-12)
    assert "operator" in plant.GetModelInstanceName(instance)


def test_a_scaled_operator_has_every_length_scaled_and_its_posture_kept():
    base = OperatorParams()
    small = base.scaled(0.8)
    for seg in ("LUA", "LLA", "RUA", "RLA", "SW"):
        assert getattr(small.dims, seg) == pytest.approx(0.8 * getattr(base.dims, seg), abs=1e-15)
    assert (small.torso_height, small.hand_length, small.head_radius) == pytest.approx((0.4, 0.148, 0.084))
    assert small.wrist_extension_deg == base.wrist_extension_deg and small.skin_rgba == base.skin_rgba
    np.testing.assert_allclose(small.index_H("left"), 0.8 * base.index_H("left"), atol=1e-15)
    lengths = segment_lengths(landmarks_from_q(np.zeros(NUM_ARM_DOF), np.zeros(NUM_ARM_DOF), small)[0])
    assert lengths["LUA"] == pytest.approx(0.8 * 0.288, abs=1e-12) and lengths["SW"] == pytest.approx(0.8 * 0.332)
    for bad in (0.0, -1.0, float("nan"), True):
        with pytest.raises(ValueError, match="positive number"):
            base.scaled(bad)
    with pytest.raises(ValueError, match="torso_height must be a length"):
        base.scaled(4.0)  # (a torso 2 m long)


def test_landmark_order_matches_skeleton():
    lm = landmarks_from_q(np.zeros(NUM_ARM_DOF), np.zeros(NUM_ARM_DOF))[0]
    assert lm.shape == (len(LANDMARKS), 3)
    # Left landmarks at +y, right ones at -y, in the skeleton's order.
    for k, name in enumerate(LANDMARKS):
        assert np.sign(lm[k, 1]) == (1 if name.startswith("left") else -1)


def test_wrist_posture_tilts_the_hand_toward_its_back_on_both_sides():
    straight = OperatorParams(wrist_extension_deg=0.0)
    bent = OperatorParams(wrist_extension_deg=30.0)
    for side in ("left", "right"):
        s = 1.0 if side == "left" else -1.0
        # Straight wrist: the knuckles lie along the forearm axis (+-y), palm normal +x.
        np.testing.assert_allclose(straight.index_H(side), [0.0, s * 0.09, 0.03], atol=1e-15)
        # Extension turns the hand about the thumb axis (z) toward the back of the hand (-x), by 30 deg.
        p0, p1 = straight.index_H(side), bent.index_H(side)
        assert p1[0] == pytest.approx(-0.09 * math.sin(math.radians(30.0)), abs=1e-12)
        assert p1[2] == p0[2] and np.linalg.norm(p1) == pytest.approx(np.linalg.norm(p0), abs=1e-12)
        R = bent.R_H_hand(side)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    # Mirror symmetry: the right hand is the left one reflected through the sagittal plane.
    m = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(bent.index_H("right"), bent.index_H("left") * m, atol=1e-15)
    np.testing.assert_allclose(bent.pinky_H("right"), bent.pinky_H("left") * m, atol=1e-15)
    # The wrist and the arm above it do not move; only the knuckles do.
    q = np.array([0.3, 0.2, -0.4, 0.9, 1.2])
    a, b = arm_forward_kinematics("left", q, straight), arm_forward_kinematics("left", q, bent)
    np.testing.assert_allclose(a[:3], b[:3], atol=1e-15)
    assert np.linalg.norm(a[3] - b[3]) > 0.04
    with pytest.raises(ValueError, match="wrist_extension_deg.*95"):
        OperatorParams(wrist_extension_deg=95.0)


def test_sdf_hand_geometry_follows_the_wrist_posture():
    sdf = operator_sdf(OperatorParams(wrist_extension_deg=25.0))
    yaw = f"{math.radians(25.0):.6g}"
    # Palm, fingers and thumb of both hands turned by the posture (about z, mirrored on the right).
    assert sdf.count(f" 0 0 {yaw}</pose>") == 2 and sdf.count(f" 0 0 -{yaw}</pose>") == 2
    assert sdf.count(f" 0 {yaw}</pose>") == 3 and sdf.count(f" 0 -{yaw}</pose>") == 3  # + thumbs (own roll)
    assert f" 0 {yaw}</pose>" not in operator_sdf(OperatorParams(wrist_extension_deg=0.0))
