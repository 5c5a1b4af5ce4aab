"""C3D motion files as the operator's input (akc_drake/operator/c3d_motion.py): markers to joints, gaps, loading."""

from pathlib import Path

import numpy as np
import pytest

from akc_drake.core.skeleton import INDEX, LANDMARKS
from akc_drake.errors import UserError
from akc_drake.evaluation.motion_set import find_clips
from akc_drake.io.export.c3d import write_c3d
from akc_drake.operator.bvh import read_bvh
from akc_drake.operator.c3d_motion import c3d_joint_positions, fill_gaps, read_c3d
from akc_drake.operator.retarget import load_motion_file

BVH = Path(__file__).parent / "data" / "mocap" / "upper_body.bvh"
Z_UP = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # the file's Y (up) to Z


def _bvh_points():
    m = read_bvh(BVH)
    return m, m.global_positions() * 10.0 @ Z_UP.T  # cm -> mm, Z up as a lab's C3D


def _plug_in_gait(m, P, offset_mm=0.0):
    """Plug-in Gait labels on the BVH's joints (the wrist's two markers either side of it), a subject prefix."""
    j = {n: P[:, m.joint_names.index(n)] for n in m.joint_names}
    d = np.array([0.0, offset_mm, 0.0])
    pts = {}
    for s, side in (("L", "Left"), ("R", "Right")):
        pts[f"{s}SHO"] = j[f"{side}Arm"]
        pts[f"{s}ELB"] = j[f"{side}ForeArm"]
        pts[f"{s}WRA"] = j[f"{side}Hand"] + d
        pts[f"{s}WRB"] = j[f"{side}Hand"] - d
        pts[f"{s}FIN"] = j[f"{side}Hand"] + 50.0
    for lab in ("LASI", "RASI", "LPSI", "RPSI"):
        pts[lab] = j["Hips"] + (20.0 if lab[1] == "A" else -20.0) * np.array([1.0, 0, 0])
    pts["C7"] = j["Neck"]
    names = list(pts)
    return np.stack([pts[n] for n in names], axis=1), [f"Subject01:{n}" for n in names]


def test_fill_gaps_interpolates_in_time_and_holds_the_ends():
    t = np.arange(8.0)
    x = np.stack([t, 2 * t, -t], axis=1)
    g = x.copy()
    g[[0, 3, 4, 7], :] = np.nan
    g[5, 1] = np.inf  # one bad coordinate invalidates the frame
    out = fill_gaps(g)
    np.testing.assert_allclose(out[1:7], x[1:7], atol=1e-12)  # the inner gaps: linear motion back exactly
    np.testing.assert_array_equal(out[0], x[1])  # held before the first valid frame
    np.testing.assert_array_equal(out[7], x[6])  # and after the last
    assert fill_gaps(x) is x and fill_gaps(np.full((3, 3), np.nan)) is None


def test_markers_to_joints():
    m, P = _bvh_points()
    pts, labels = _plug_in_gait(m, P, offset_mm=25.0)
    pos, names = c3d_joint_positions([lab.lower() for lab in labels], pts)
    assert names == ["left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
                     "hips"]
    # The wrist between its two markers; the pelvis between the four.
    np.testing.assert_allclose(pos[:, 2], P[:, m.joint_names.index("LeftHand")], atol=1e-9)
    np.testing.assert_allclose(pos[:, 6], P[:, m.joint_names.index("Hips")], atol=1e-9)
    # A joint centre of the lab's model comes before the skin marker.
    centre = P[:, m.joint_names.index("LeftForeArm")] + 7.0
    pos2, names2 = c3d_joint_positions([*labels, "Subject01:LEJC"], np.concatenate([pts, centre[:, None]], axis=1))
    np.testing.assert_allclose(pos2[:, names2.index("left_elbow")], centre)
    # A name map picks a marker itself; an unknown one, or a missing elbow, is one line naming the labels.
    pos3, names3 = c3d_joint_positions(labels, pts, {"left_wrist": "LFIN"})
    np.testing.assert_allclose(pos3[:, names3.index("left_wrist")], pts[:, labels.index("Subject01:LFIN")])
    with pytest.raises(UserError, match="'NOPE'"):
        c3d_joint_positions(labels, pts, {"left_wrist": "NOPE"})
    with pytest.raises(UserError, match="unknown role.*'left_knee'"):
        c3d_joint_positions(labels, pts, {"left_knee": "LFIN"})
    keep = [i for i, lab in enumerate(labels) if not lab.endswith("LELB")]
    with pytest.raises(UserError, match="no marker for left_elbow .*LEJC or LELB.*Subject01:LSHO"):
        c3d_joint_positions([labels[i] for i in keep], pts[:, keep], source="x.c3d")


def _marker_pairs(m, P, half_mm=40.0):
    """DART's C3D marker set (Georgia Tech's) on the BVH's joints: a marker either side of each arm joint, 2 *
    ``half_mm`` apart (front/back shoulder, lateral/inner elbow, outer/inner wrist), the four waist markers."""
    j = {n: P[:, m.joint_names.index(n)] for n in m.joint_names}
    dx, dy = np.array([half_mm, 0.0, 0.0]), np.array([0.0, half_mm, 0.0])
    pts = {}
    for s, side in (("L", "Left"), ("R", "Right")):
        pts[f"{s}FSH"], pts[f"{s}BSH"] = j[f"{side}Arm"] + dx, j[f"{side}Arm"] - dx
        pts[f"{s}ELB"], pts[f"{s}IEL"] = j[f"{side}ForeArm"] + dy, j[f"{side}ForeArm"] - dy
        pts[f"{s}OWR"], pts[f"{s}IWR"] = j[f"{side}Hand"] - dy, j[f"{side}Hand"] + dy
        pts[f"{s}UPA"] = 0.5 * (j[f"{side}Arm"] + j[f"{side}ForeArm"]) + dx
    for lab in ("LFWT", "RFWT", "LBWT", "RBWT"):
        pts[lab] = j["Hips"] + (30.0 if lab[1] == "F" else -30.0) * np.array([1.0, 0, 0])
    names = list(pts)
    return np.stack([pts[n] for n in names], axis=1), [f"Nick01:{n}" for n in names]


def test_marker_pairs_either_side_of_a_joint_give_its_centre():
    m, P = _bvh_points()
    pts, labels = _marker_pairs(m, P)
    pos, names = c3d_joint_positions(labels, pts)
    assert names == ["left_shoulder", "left_elbow", "left_wrist", "right_shoulder", "right_elbow", "right_wrist",
                     "hips"]
    for k, joint in enumerate(["LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand",
                               "Hips"]):
        np.testing.assert_allclose(pos[:, k], P[:, m.joint_names.index(joint)], atol=1e-9)  # 40 mm either side
    # The pair comes before the lateral epicondyle alone (which Plug-in Gait files have without the inner one).
    keep = [i for i, lab in enumerate(labels) if not lab.endswith("LIEL")]
    pos1, _ = c3d_joint_positions([labels[i] for i in keep], pts[:, keep])
    np.testing.assert_allclose(pos1[:, 1], pts[:, labels.index("Nick01:LELB")])
    # A name map's "A+B" averages a group of markers; a group with an absent marker is one line.
    pos2, names2 = c3d_joint_positions(labels, pts, {"left_elbow": "LUPA+LELB"})
    want = 0.5 * (pts[:, labels.index("Nick01:LUPA")] + pts[:, labels.index("Nick01:LELB")])
    np.testing.assert_allclose(pos2[:, names2.index("left_elbow")], want)
    np.testing.assert_allclose(pos2[:, names2.index("right_elbow")], pos[:, 4])
    with pytest.raises(UserError, match="'LUPA\\+NOPE', but 'NOPE' is no marker.*a group is A\\+B"):
        c3d_joint_positions(labels, pts, {"left_elbow": "LUPA+NOPE"})
    pos3, names3 = c3d_joint_positions(labels, pts, {"hips": "LFWT+RFWT"})  # the pelvis by a group too
    want = 0.5 * (pts[:, labels.index("Nick01:LFWT")] + pts[:, labels.index("Nick01:RFWT")])
    np.testing.assert_allclose(pos3[:, names3.index("hips")], want)
    with pytest.raises(UserError, match="hips = 'LFWT\\+NOPE', but 'NOPE' is no marker"):
        c3d_joint_positions(labels, pts, {"hips": "LFWT+NOPE"})


@pytest.mark.parametrize("labels_from", ["plug-in gait", "akc-drake export"])
def test_a_c3d_file_drives_the_operator_as_its_bvh_does(tmp_path, labels_from):
    m, P = _bvh_points()
    if labels_from == "plug-in gait":
        pts, labels = _plug_in_gait(m, P)
    else:  # our own C3D export: the landmarks' names
        joint = {"left_shoulder": "LeftArm", "left_elbow": "LeftForeArm", "left_wrist": "LeftHand",
                 "right_shoulder": "RightArm", "right_elbow": "RightForeArm", "right_wrist": "RightHand",
                 "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg"}
        pts = np.full((P.shape[0], len(LANDMARKS), 3), np.nan)
        for lm, jn in joint.items():
            pts[:, INDEX[lm]] = P[:, m.joint_names.index(jn)]
        labels = list(LANDMARKS)
    path = tmp_path / "clip.c3d"
    write_c3d(path, pts, labels, rate_hz=1.0 / m.frame_time)
    data = read_c3d(path)
    assert data["rate_hz"] == pytest.approx(40.0) and data["points"].shape == pts.shape
    # At the file's 40 Hz: every frame (T-pose, arms forward, forearms up, the body turned).
    want = load_motion_file(BVH, rate_hz=40.0)  # Y up, joints by name
    got = load_motion_file(path, rate_hz=40.0)  # Z up (found from the torso), joints from the markers
    assert np.ptp(want.q_left, axis=0).max() > 1.5  # (the arms move)
    np.testing.assert_allclose(got.times, want.times)
    np.testing.assert_allclose(got.q_left, want.q_left, atol=1e-5)
    np.testing.assert_allclose(got.q_right, want.q_right, atol=1e-5)
    assert find_clips(tmp_path)[0]["path"] == str(path)  # a folder of C3D files is a motion set


def test_a_gap_is_filled_and_bad_files_are_one_line(tmp_path):
    m, P = _bvh_points()
    pts, labels = _plug_in_gait(m, P)
    pts[2, labels.index("Subject01:LELB")] = np.nan  # an invalid frame of one marker
    path = tmp_path / "gap.c3d"
    write_c3d(path, pts, labels, rate_hz=40.0)
    assert np.isnan(read_c3d(path)["points"][2, labels.index("Subject01:LELB")]).all()
    got = load_motion_file(path)
    assert np.all(np.isfinite(got.q_left))
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(b"not a c3d file")
    with pytest.raises(UserError, match="not a readable C3D file"):
        load_motion_file(bad)
    with pytest.raises(UserError, match="needs no skeleton"):
        load_motion_file(path, BVH)
