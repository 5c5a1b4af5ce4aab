import numpy as np
import pytest

from akc_drake.core import skeleton as sk


def test_landmark_order_matches_blazepose_order():
    # Our order is BlazePose's order restricted to the 12 landmarks we use.
    assert list(sk.BLAZEPOSE_ORDER) == sorted(sk.BLAZEPOSE_ORDER)
    assert sk.BLAZEPOSE_INDEX["left_shoulder"] == 11
    assert sk.BLAZEPOSE_INDEX["right_hip"] == 24
    assert sk.BLAZEPOSE_INDEX["left_index"] == 19 and sk.BLAZEPOSE_INDEX["left_pinky"] == 17
    assert sk.NUM_LANDMARKS == 12 and len(set(sk.LANDMARKS)) == 12


def test_side_indices_and_idx():
    s, e, w = sk.side_indices("left")
    assert (sk.LANDMARKS[s], sk.LANDMARKS[e], sk.LANDMARKS[w]) == ("left_shoulder", "left_elbow", "left_wrist")
    with pytest.raises(ValueError, match="side"):
        sk.side_indices("middle")
    with pytest.raises(KeyError, match="left_knee"):
        sk.idx("left_knee")


def test_body_dimensions_validation_names_the_field():
    d = sk.BodyDimensions.paper_participant()
    assert d.upper("left") == 0.288 and d.lower("right") == 0.270 and d.SW == 0.332
    with pytest.raises(ValueError, match="LLA"):
        sk.BodyDimensions(LUA=0.3, LLA=-0.1, RUA=0.3, RLA=0.3, SW=0.3)
    with pytest.raises(ValueError, match="RUA.*metres"):
        sk.BodyDimensions(LUA=0.3, LLA=0.3, RUA=28.9, RLA=0.3, SW=0.3)
    with pytest.raises(ValueError, match="SW"):
        sk.BodyDimensions(LUA=0.3, LLA=0.3, RUA=0.3, RLA=0.3, SW=float("nan"))
    with pytest.raises(ValueError, match="RLA.*number"):
        sk.BodyDimensions(LUA=0.3, LLA=0.3, RUA=0.3, RLA="long", SW=0.3)


def test_body_dimensions_dict_round_trip_and_errors():
    d = sk.BodyDimensions.paper_manual()
    assert sk.BodyDimensions.from_dict(d.as_dict()) == d
    np.testing.assert_allclose(d.as_array(), [0.32, 0.26, 0.32, 0.26, 0.33])
    with pytest.raises(ValueError, match="dims.json: missing SW"):
        sk.BodyDimensions.from_dict({"LUA": 0.3, "LLA": 0.3, "RUA": 0.3, "RLA": 0.3}, where="dims.json")
    with pytest.raises(ValueError, match="unknown key"):
        sk.BodyDimensions.from_dict({**d.as_dict(), "HEAD": 0.2})


def test_segment_lengths_on_pose_and_trajectory():
    pose = np.full((12, 3), np.nan)
    pose[sk.idx("left_shoulder")] = [0.0, 0.0, 2.0]
    pose[sk.idx("left_elbow")] = [0.3, 0.0, 2.0]
    pose[sk.idx("left_wrist")] = [0.3, 0.4, 2.0]
    L = sk.segment_lengths(pose)
    assert L["LUA"] == pytest.approx(0.3) and L["LLA"] == pytest.approx(0.4)
    assert np.isnan(L["RUA"]) and np.isnan(L["SW"])
    traj = np.stack([pose, pose * 2])
    assert sk.segment_lengths(traj)["LLA"] == pytest.approx([0.4, 0.8])


def test_check_pose_shapes():
    assert sk.check_pose(np.zeros((12, 3))).dtype == np.float64
    with pytest.raises(ValueError, match=r"landmarks must have shape \(12, 3\), got \(6, 3\)"):
        sk.check_pose(np.zeros((6, 3)), name="landmarks")
    assert sk.check_pose(np.zeros((5, 12, 3)), allow_trajectory=True).shape == (5, 12, 3)
