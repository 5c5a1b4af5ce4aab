"""Tests for akc_drake.operator.retarget: joint lookup, operator-frame directions, resampling, loading."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.errors import UserError
from akc_drake.operator.asf_amc import read_amc, read_asf
from akc_drake.operator.bvh import BVHMotion, read_bvh, write_bvh
from akc_drake.operator.model import NEUTRAL_FOREARM_ROLL, arm_forward_kinematics
from akc_drake.operator.motions import OperatorMotion
from akc_drake.operator.retarget import (
    arm_directions_from_positions,
    auto_up_axis,
    find_arm_joints,
    load_motion_file,
    motion_from_spec,
    parse_joint_names,
    resample_directions,
    retarget_motion,
    retarget_positions,
)

DATA = Path(__file__).parent / "data" / "mocap"
BVH = DATA / "upper_body.bvh"
ASF = DATA / "tiny.asf"
AMC = DATA / "tiny.amc"

# Expected directions in O (x forward, y left, z up) for the frames of both test files:
# T-pose, arms forward, arms forward with the forearms up, T-pose turned, (BVH only) T-pose moved.
UPPER_L = [[0, 1, 0], [1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0]]
FORE_L = [[0, 1, 0], [1, 0, 0], [0, 0, 1], [0, 1, 0], [0, 1, 0]]
UPPER_R = [[0, -1, 0], [1, 0, 0], [1, 0, 0], [0, -1, 0], [0, -1, 0]]
FORE_R = [[0, -1, 0], [1, 0, 0], [0, 0, 1], [0, -1, 0], [0, -1, 0]]


def _check_expected(d, n_frames: int):
    np.testing.assert_allclose(d.upper["left"], UPPER_L[:n_frames], atol=1e-12)
    np.testing.assert_allclose(d.fore["left"], FORE_L[:n_frames], atol=1e-12)
    np.testing.assert_allclose(d.upper["right"], UPPER_R[:n_frames], atol=1e-12)
    np.testing.assert_allclose(d.fore["right"], FORE_R[:n_frames], atol=1e-12)


def test_bvh_directions_in_operator_frame():
    m = read_bvh(BVH)
    d = arm_directions_from_positions(m.global_positions(), m.joint_names)
    assert d.joints["left_shoulder"] == "LeftArm" and d.joints["left_elbow"] == "LeftForeArm"
    assert d.joints["left_wrist"] == "LeftHand" and d.joints["right_shoulder"] == "RightArm"
    assert d.joints["hips"] == "Hips" and d.joints["left_hip"] == "LeftUpLeg"
    _check_expected(d, 5)
    # O's forward axis is the file's +z while the person faces it, +x after the 90 deg turn to the left.
    np.testing.assert_allclose(d.R_FO[0, :, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(d.R_FO[3, :, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(
        d.R_FO @ np.swapaxes(d.R_FO, 1, 2), np.broadcast_to(np.eye(3), (5, 3, 3)), atol=1e-12
    )
    assert all(p is None for p in d.palm.values())


def test_cmu_amc_directions_in_operator_frame():
    m = read_amc(AMC, read_asf(ASF))
    d = arm_directions_from_positions(m.bone_start_positions(), m.joint_names)
    assert [d.joints[f"left_{p}"] for p in ("shoulder", "elbow", "wrist")] == [
        "lhumerus",
        "lradius",
        "lwrist",
    ]
    assert [d.joints[f"right_{p}"] for p in ("shoulder", "elbow", "wrist")] == [
        "rhumerus",
        "rradius",
        "rwrist",
    ]
    _check_expected(d, 4)


def _check_q_reproduces_directions(motion: OperatorMotion, upper: dict, fore: dict):
    for side in ("left", "right"):
        q = motion.q_left if side == "left" else motion.q_right
        fk = arm_forward_kinematics(side, q)
        u = fk[:, 1] - fk[:, 0]
        f = fk[:, 2] - fk[:, 1]
        np.testing.assert_allclose(u / np.linalg.norm(u, axis=1)[:, None], upper[side], atol=1e-9)
        np.testing.assert_allclose(f / np.linalg.norm(f, axis=1)[:, None], fore[side], atol=1e-9)


def test_load_bvh_at_its_own_rate_gives_joint_angles():
    om = load_motion_file(BVH, rate_hz=40.0)
    assert isinstance(om, OperatorMotion) and om.name == "upper_body"
    np.testing.assert_allclose(om.times, np.arange(5) * 0.025, atol=1e-12)
    # T-pose: no adduction, elevation or flexion, forearm roll neutral.
    np.testing.assert_allclose(om.q_left[0, [0, 1, 3, 4]], [0, 0, 0, NEUTRAL_FOREARM_ROLL], atol=1e-12)
    # The humeral rotation of a straight arm is undetermined; the model takes it from frame 2, where the
    # forearm rises in front: -90 deg.
    np.testing.assert_allclose(om.q_left[:, 2], -math.pi / 2, atol=1e-12)
    np.testing.assert_allclose(om.q_right[:, 2], -math.pi / 2, atol=1e-12)
    # Arms forward: +90 deg shoulder horizontal adduction on both sides.
    assert om.q_left[1, 0] == pytest.approx(math.pi / 2) and om.q_right[1, 0] == pytest.approx(math.pi / 2)
    # Forearms up: 90 deg of elbow flexion.
    assert om.q_left[2, 3] == pytest.approx(math.pi / 2) and om.q_right[2, 3] == pytest.approx(math.pi / 2)
    # The operator model's forward kinematics points the arms where the file does.
    m = read_bvh(BVH)
    d = arm_directions_from_positions(m.global_positions(), m.joint_names)
    _check_q_reproduces_directions(om, d.upper, d.fore)


def test_load_amc_needs_skeleton_and_matches_bvh():
    with pytest.raises(UserError, match="needs its ASF skeleton"):
        load_motion_file(AMC)
    om = load_motion_file(AMC, ASF, rate_hz=120.0)
    assert om.name == "tiny" and om.times.shape == (4,)
    bvh = load_motion_file(BVH, rate_hz=40.0)
    # Same poses frame by frame (the humeral rotation of the straight arm is undetermined, so compare
    # the directions through the operator's kinematics rather than the raw angles).
    for side in ("left", "right"):
        a = arm_forward_kinematics(side, getattr(om, f"q_{side}"))
        b = arm_forward_kinematics(side, getattr(bvh, f"q_{side}")[:4])
        np.testing.assert_allclose(a[:, :3], b[:, :3], atol=1e-9)
    skel = read_asf(ASF)
    assert load_motion_file(AMC, skel, rate_hz=120.0).q_left.shape == (4, 5)


def _sweep_motion(n_frames: int, frame_time: float, degrees_total: float = 90.0) -> BVHMotion:
    """The upper-body skeleton sweeping its left arm from the side to the front at a constant rate."""
    base = read_bvh(BVH)
    ch = np.zeros((n_frames, base.channels.shape[1]))
    ch[:, base.column("Hips", "Yposition")] = 90.0
    ch[:, base.column("LeftArm", "Yrotation")] = -degrees_total * np.arange(n_frames) / (n_frames - 1)
    return BVHMotion(joints=base.joints, frame_time=frame_time, channels=ch, name="sweep")


def test_resampling_to_the_camera_rate():
    m = _sweep_motion(121, 1 / 120)  # 1 s at 120 Hz, 0 -> 90 deg
    om = retarget_motion(m)
    assert om.times.shape == (11,)
    np.testing.assert_allclose(om.times, np.arange(11) / 10.0, atol=1e-12)
    # Every 12th input frame: adduction 9 deg per output frame.
    np.testing.assert_allclose(om.q_left[:, 0], np.deg2rad(9.0 * np.arange(11)), atol=1e-9)
    assert retarget_motion(m, rate_hz=30.0).times.shape == (31,)
    assert retarget_motion(m, rate_hz=120.0).times.shape == (121,)
    assert retarget_motion(m, rate_hz=7.0).times.shape == (8,)


def test_resampling_interpolates_between_frames():
    m = _sweep_motion(5, 0.25)  # 4 Hz, 22.5 deg per frame
    om = retarget_motion(m, rate_hz=10.0)
    assert om.times.shape == (11,)
    # t = 0.1 s lies 0.4 of the way from frame 0 (0 deg) to frame 1 (22.5 deg): the normalised linear
    # interpolation of the two unit vectors.
    a = np.deg2rad(22.5)
    expected = math.atan2(0.4 * math.sin(a), 0.6 + 0.4 * math.cos(a))
    assert om.q_left[1, 0] == pytest.approx(expected, abs=1e-12)
    assert om.q_left[10, 0] == pytest.approx(math.pi / 2, abs=1e-12)


@settings(max_examples=30, deadline=None)
@given(
    angles=st.lists(st.floats(-3.0, 3.0), min_size=2, max_size=8),
    t_new=st.floats(0.0, 1.0),
)
def test_resampled_directions_are_unit_vectors(angles, t_new):
    # Arcs of less than 180 deg between neighbours never interpolate through zero.
    th = np.cumsum(np.clip(np.asarray(angles), -3.0, 3.0))
    dirs = np.stack([np.cos(th), np.sin(th), np.zeros_like(th)], axis=1)
    t = np.linspace(0.0, 1.0, len(th))
    out = resample_directions(t, dirs, np.array([t_new]))
    assert np.linalg.norm(out[0]) == pytest.approx(1.0)
    k = min(int(np.searchsorted(t, t_new, side="right")) - 1, len(th) - 2)
    # The result lies between its two neighbours (on the shorter arc).
    c = np.cross(dirs[k], dirs[k + 1])[2]
    assert np.cross(dirs[k], out[0])[2] * c >= -1e-12
    assert np.cross(out[0], dirs[k + 1])[2] * c >= -1e-12


def test_joint_aliases():
    bvh_mixamo = [
        "mixamorig:Hips",
        "mixamorig:LeftShoulder",
        "mixamorig:LeftArm",
        "mixamorig:LeftForeArm",
        "mixamorig:LeftHand",
        "mixamorig:RightShoulder",
        "mixamorig:RightArm",
        "mixamorig:RightForeArm",
        "mixamorig:RightHand",
        "mixamorig:LeftHandIndex1",
        "mixamorig:LeftHandPinky1",
    ]
    j = find_arm_joints(bvh_mixamo)
    assert j["left_shoulder"] == "mixamorig:LeftArm" and j["right_wrist"] == "mixamorig:RightHand"
    assert j["left_index"] == "mixamorig:LeftHandIndex1" and j["right_index"] is None
    assert j["hips"] == "mixamorig:Hips"
    daz = [
        "hip",
        "abdomen",
        "chest",
        "lCollar",
        "lShldr",
        "lForeArm",
        "lHand",
        "rCollar",
        "rShldr",
        "rForeArm",
        "rHand",
        "lThigh",
        "rThigh",
    ]
    j = find_arm_joints(daz)
    assert (j["left_shoulder"], j["left_elbow"], j["left_wrist"]) == ("lShldr", "lForeArm", "lHand")
    assert j["right_hip"] == "rThigh" and j["hips"] == "hip"
    plain = ["pelvis", "l_shoulder", "l_elbow", "l_wrist", "r_shoulder", "r_elbow", "r_wrist"]
    j = find_arm_joints(plain)
    assert (j["right_shoulder"], j["right_elbow"], j["right_wrist"]) == ("r_shoulder", "r_elbow", "r_wrist")
    # A BVH "LeftShoulder" is the clavicle when "LeftArm" exists, the shoulder joint when it does not.
    only = ["Hips", "LeftShoulder", "LeftElbow", "LeftWrist", "RightShoulder", "RightElbow", "RightWrist"]
    assert find_arm_joints(only)["left_shoulder"] == "LeftShoulder"
    biped = [
        "Bip01 Pelvis",
        "Bip01 L UpperArm",
        "Bip01 L Forearm",
        "Bip01 L Hand",
        "Bip01 R UpperArm",
        "Bip01 R Forearm",
        "Bip01 R Hand",
    ]
    j = find_arm_joints(biped)
    assert (j["left_shoulder"], j["right_elbow"]) == ("Bip01 L UpperArm", "Bip01 R Forearm")
    cmu = read_asf(ASF).joint_names
    assert find_arm_joints(cmu)["left_wrist"] == "lwrist"


@pytest.mark.parametrize(
    "convention",
    [
        # Blender / Rigify: the clavicle is "shoulder.L", the side after a dot.
        {"LeftShoulder": "shoulder.L", "LeftArm": "upper_arm.L", "LeftForeArm": "forearm.L", "LeftHand": "hand.L",
         "RightShoulder": "shoulder.R", "RightArm": "upper_arm.R", "RightForeArm": "forearm.R",
         "RightHand": "hand.R", "LeftUpLeg": "thigh.L", "RightUpLeg": "thigh.R"},
        # Unreal's mannequin.
        {"LeftShoulder": "clavicle_l", "LeftArm": "upperarm_l", "LeftForeArm": "lowerarm_l", "LeftHand": "hand_l",
         "RightShoulder": "clavicle_r", "RightArm": "upperarm_r", "RightForeArm": "lowerarm_r",
         "RightHand": "hand_r", "LeftUpLeg": "thigh_l", "RightUpLeg": "thigh_r", "Hips": "pelvis"},
        # Bandai Namco's motion dataset: "Shoulder_L" is the clavicle there too.
        {"LeftShoulder": "Shoulder_L", "LeftArm": "UpperArm_L", "LeftForeArm": "LowerArm_L", "LeftHand": "Hand_L",
         "RightShoulder": "Shoulder_R", "RightArm": "UpperArm_R", "RightForeArm": "LowerArm_R",
         "RightHand": "Hand_R"},
        # Kinect: joints named by the joint, the side spelled out last (no clavicle).
        {"LeftShoulder": "SpineShoulderL", "LeftArm": "ShoulderLeft", "LeftForeArm": "ElbowLeft",
         "LeftHand": "WristLeft", "RightShoulder": "SpineShoulderR", "RightArm": "ShoulderRight",
         "RightForeArm": "ElbowRight", "RightHand": "WristRight", "LeftUpLeg": "HipLeft", "RightUpLeg": "HipRight"},
        # OptiTrack Motive's segments, namespaced by the skeleton.
        {"LeftShoulder": "Sk1:LShoulder", "LeftArm": "Sk1:LUArm", "LeftForeArm": "Sk1:LFArm", "LeftHand": "Sk1:LHand",
         "RightShoulder": "Sk1:RShoulder", "RightArm": "Sk1:RUArm", "RightForeArm": "Sk1:RFArm",
         "RightHand": "Sk1:RHand"},
    ],
    ids=["blender", "unreal", "bandai", "kinect", "motive"],
)
def test_joint_names_with_the_side_last_or_abbreviated(convention):
    """Rigs that name the side after the part, or abbreviate the segments, need no name map."""
    m = read_bvh(BVH)
    renamed = [convention.get(n, n) for n in m.joint_names]
    d = arm_directions_from_positions(m.global_positions(), renamed)
    for role, joint in (("left_shoulder", "LeftArm"), ("left_elbow", "LeftForeArm"), ("left_wrist", "LeftHand"),
                        ("right_shoulder", "RightArm"), ("right_elbow", "RightForeArm"),
                        ("right_wrist", "RightHand")):
        assert d.joints[role] == convention[joint]
    if "LeftUpLeg" in convention:
        assert d.joints["left_hip"] == convention["LeftUpLeg"]
    _check_expected(d, 5)
    # Kinect's skeleton has a hand joint beyond the wrist: the wrist is still the wrist.
    kinect = ["SpineBase", "ShoulderLeft", "ElbowLeft", "WristLeft", "HandLeft", "ShoulderRight", "ElbowRight",
              "WristRight", "HandRight"]
    assert find_arm_joints(kinect)["left_wrist"] == "WristLeft"
    # Twist bones and numbered copies are not the joints.
    ue = ["pelvis", "upperarm_twist_01_l", "upperarm_l", "lowerarm_twist_01_l", "lowerarm_l", "hand_l",
          "upperarm_r", "lowerarm_r", "hand_r", "index_01_l", "pinky_01_r"]
    j = find_arm_joints(ue)
    assert (j["left_shoulder"], j["left_elbow"]) == ("upperarm_l", "lowerarm_l")
    assert (j["left_index"], j["right_pinky"]) == ("index_01_l", "pinky_01_r")


def test_parse_joint_names(tmp_path):
    both = {"left_shoulder": "upper_arm.L", "right_shoulder": "upper_arm.R"}
    assert parse_joint_names(" left_shoulder=upper_arm.L, right_shoulder = upper_arm.R ,") == both
    f = tmp_path / "names.json"
    f.write_text(json.dumps(both))
    assert parse_joint_names(str(f)) == both
    for bad, message in (("left_shoulder", "is not role=joint"), ("=x", "is not role=joint"), (" , ", "empty"),
                         ("left_knee=x", "unknown role")):
        with pytest.raises(UserError, match=message):
            parse_joint_names(bad)
    for content, message in (("[1, 2]", "JSON object"), ("{", "not valid JSON"), ('{"left_shoulder": 3}', "object")):
        f.write_text(content)
        with pytest.raises(UserError, match=message):
            parse_joint_names(str(f))
    with pytest.raises(UserError, match="cannot read"):
        parse_joint_names(str(tmp_path / "missing.json"))
    # motion_from_spec takes the map for a file (the record and run commands' --joint-names).
    text = BVH.read_text()
    for old, new in (("LeftArm", "ShL"), ("RightArm", "ShR"), ("LeftShoulder", "ClL"), ("RightShoulder", "ClR")):
        text = re.sub(rf"JOINT {old}\b", f"JOINT {new}", text)
    renamed = tmp_path / "renamed.bvh"
    renamed.write_text(text)
    with pytest.raises(UserError, match="no joint for left_shoulder"):
        motion_from_spec(str(renamed))
    m = motion_from_spec(str(renamed), names={"left_shoulder": "ShL", "right_shoulder": "ShR"})
    ref = motion_from_spec(str(BVH))
    np.testing.assert_array_equal(m.q_left, ref.q_left)
    np.testing.assert_array_equal(m.q_right, ref.q_right)


def test_name_map_and_missing_joints(tmp_path):
    m = read_bvh(BVH)
    rename = {
        "LeftArm": "ShoulderL",
        "RightArm": "ShoulderR",
        "LeftShoulder": "ClavL",
        "RightShoulder": "ClavR",
    }
    renamed = [rename.get(n, n) for n in m.joint_names]
    with pytest.raises(UserError, match="no joint for left_shoulder") as e:
        arm_directions_from_positions(m.global_positions(), renamed, source="x.bvh")
    assert str(e.value).startswith("x.bvh:") and "ShoulderL" in str(e.value)
    names = {"left_shoulder": "ShoulderL", "right_shoulder": "ShoulderR"}
    d = arm_directions_from_positions(m.global_positions(), renamed, names=names)
    _check_expected(d, 5)
    with pytest.raises(UserError, match="left_knee"):
        find_arm_joints(m.joint_names, {"left_knee": "LeftUpLeg"})
    with pytest.raises(UserError, match="'Nope'"):
        find_arm_joints(m.joint_names, {"left_wrist": "Nope"})
    with pytest.raises(UserError, match="must be different joints"):
        find_arm_joints(m.joint_names, {"left_wrist": "LeftForeArm"})


def test_up_axis_is_configurable():
    m = read_bvh(BVH)
    P = m.global_positions()
    # The same data in a Z-up file: rotate +90 deg about x (y -> z).
    R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    Pz = P @ R.T
    dz = arm_directions_from_positions(Pz, m.joint_names, up="z")
    _check_expected(dz, 5)
    # Using the torso's own up direction (hips to shoulders) gives the same here: the torso is upright.
    _check_expected(arm_directions_from_positions(Pz, m.joint_names, up=None), 5)
    _check_expected(arm_directions_from_positions(Pz, m.joint_names, up=(0, 0, 2)), 5)
    # Upside down: with up = -y the person's left and forward flip; the arms still point "sideways".
    d_neg = arm_directions_from_positions(P, m.joint_names, up="-y")
    np.testing.assert_allclose(d_neg.upper["left"][0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(d_neg.fore["left"][2], [0, 0, -1], atol=1e-12)
    with pytest.raises(UserError, match="up axis"):
        arm_directions_from_positions(P, m.joint_names, up="w")


def test_up_axis_auto_finds_a_z_up_or_upside_down_export():
    """The default up axis is the file's axis nearest the torso: a Z-up export needs no option."""
    m = read_bvh(BVH)
    P = m.global_positions()
    R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # y -> z
    _check_expected(arm_directions_from_positions(Pz := P @ R.T, m.joint_names), 5)
    spine = m.joint_names.index("Spine")
    assert auto_up_axis(Pz[:, spine] - Pz[:, m.joint_names.index("Hips")] + 1e-3) == "z"
    # y -> -z (a file whose "down" is +z): still the person's up.
    _check_expected(arm_directions_from_positions(P @ (R @ R @ R).T, m.joint_names), 5)
    # With the file's Y named explicitly, the Z-up data is read as a person lying down (here a degenerate frame).
    with pytest.raises(UserError, match="shoulder line"):
        arm_directions_from_positions(Pz, m.joint_names, up="y")
    assert auto_up_axis(np.array([[0.1, 0.9, 0.2], [0.0, 0.8, -0.3]])) == "y"
    # No torso to go by (the hips' joints at the shoulders): the BVH convention, Y, and no error.
    names = m.joint_names
    flat = P.copy()
    for hip, shoulder in (("LeftUpLeg", "LeftArm"), ("RightUpLeg", "RightArm")):
        flat[:, names.index(hip)] = P[:, names.index(shoulder)]
    auto, y = arm_directions_from_positions(flat, names), arm_directions_from_positions(flat, names, up="y")
    np.testing.assert_array_equal(auto.upper["left"], y.upper["left"])
    assert auto_up_axis(np.array([[0.2, -0.1, -0.97]])) == "-z"


def test_torso_up_follows_a_leaning_person():
    m = read_bvh(BVH)
    ch = m.channels.copy()
    ch[:, m.column("Hips", "Xrotation")] = 30.0  # the whole body tilted 30 deg about the file's x (left) axis
    tilted = BVHMotion(joints=m.joints, frame_time=m.frame_time, channels=ch)
    P = tilted.global_positions()
    # Relative to the torso the arms are unchanged.
    _check_expected(arm_directions_from_positions(P, m.joint_names, up=None), 5)
    # Relative to the world's up axis, the arms pointing forward now also point down by 30 deg.
    d = arm_directions_from_positions(P, m.joint_names, up="y")
    np.testing.assert_allclose(d.upper["left"][1], [math.cos(math.pi / 6), 0, -0.5], atol=1e-12)


def _knuckle_positions(palm_down: bool) -> tuple[np.ndarray, list[str]]:
    """A T-pose in a Y-up file (left = +x, forward = +z) with index and pinky knuckles."""
    names = [
        "Hips",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "LeftHandIndex1",
        "LeftHandPinky1",
        "RightArm",
        "RightForeArm",
        "RightHand",
        "RightHandIndex1",
        "RightHandPinky1",
    ]
    P = {"Hips": [0, 1.0, 0]}
    for s, sign in (("Left", 1.0), ("Right", -1.0)):
        P[f"{s}Arm"] = [sign * 0.17, 1.4, 0]
        P[f"{s}ForeArm"] = [sign * 0.46, 1.4, 0]
        P[f"{s}Hand"] = [sign * 0.74, 1.4, 0]
        # Palm down: the thumb side (index) is in front. Palm forward: the index is on top.
        across = np.array([0, 0, 0.03]) if palm_down else np.array([0, 0.03, 0])
        P[f"{s}HandIndex1"] = np.array([sign * 0.83, 1.4, 0]) + across
        P[f"{s}HandPinky1"] = np.array([sign * 0.82, 1.4, 0]) - across
    return np.array([[P[n] for n in names]], dtype=float), names


def test_palm_normal_sets_the_forearm_roll():
    P, names = _knuckle_positions(palm_down=True)
    d = arm_directions_from_positions(P, names)
    np.testing.assert_allclose(d.palm["left"][0], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(d.palm["right"][0], [0, 0, -1], atol=1e-12)
    om = retarget_positions(np.repeat(P, 2, axis=0), names, 0.1)
    np.testing.assert_allclose(om.q_left[:, 4], NEUTRAL_FOREARM_ROLL, atol=1e-12)
    np.testing.assert_allclose(om.q_right[:, 4], NEUTRAL_FOREARM_ROLL, atol=1e-12)
    P2, _ = _knuckle_positions(palm_down=False)
    om2 = retarget_positions(np.repeat(P2, 2, axis=0), names, 0.1)
    # Palm forward (thumb up) is the zero forearm roll.
    np.testing.assert_allclose(om2.q_left[:, 4], 0.0, atol=1e-12)
    np.testing.assert_allclose(om2.q_right[:, 4], 0.0, atol=1e-12)


def test_file_errors(tmp_path):
    with pytest.raises(UserError, match="unknown motion file type '.trc'"):
        load_motion_file(tmp_path / "walk.trc")
    with pytest.raises(UserError, match="walk.c3d: not a readable C3D file"):
        load_motion_file(tmp_path / "walk.c3d")
    with pytest.raises(UserError, match="is a skeleton"):
        load_motion_file(ASF)
    with pytest.raises(UserError, match="must end in .asf"):
        load_motion_file(AMC, BVH)
    bad = tmp_path / "bad.bvh"
    bad.write_text(BVH.read_text().replace("Frames: 5", "Frames: 6"))
    with pytest.raises(UserError, match=r"bad\.bvh:\d+: truncated"):
        load_motion_file(bad)
    # A motion shorter than one camera period.
    short = tmp_path / "short.bvh"
    write_bvh(short, _sweep_motion(3, 0.01))
    with pytest.raises(UserError, match="shorter than one sample period"):
        load_motion_file(short)
    assert load_motion_file(short, rate_hz=100.0).times.shape == (3,)


def test_degenerate_frames_are_reported():
    m = read_bvh(BVH)
    P = m.global_positions().copy()
    P[2, m.joint_index("LeftForeArm")] = P[2, m.joint_index("LeftArm")]
    with pytest.raises(UserError, match="frame 2: the left upper arm"):
        arm_directions_from_positions(P, m.joint_names, source="f.bvh")
    P = m.global_positions().copy()
    P[1, m.joint_index("RightArm")] = P[1, m.joint_index("LeftArm")] + [0, 0.3, 0]  # shoulders on the up axis
    with pytest.raises(UserError, match="frame 1: the shoulder line"):
        arm_directions_from_positions(P, m.joint_names)
    # Arms that flip by 180 deg between two frames cannot be interpolated.
    P = np.repeat(m.global_positions()[:1], 2, axis=0)
    s, e = m.joint_index("LeftArm"), m.joint_index("LeftForeArm")
    P[1, e] = 2 * P[1, s] - P[1, e]
    with pytest.raises(UserError, match="reverses"):
        retarget_positions(P, m.joint_names, 0.2, rate_hz=10.0)
