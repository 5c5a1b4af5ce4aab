"""The detector's figures against ground truth (akc_drake.evaluation.detector_metrics)."""

import numpy as np
import pytest

from akc_drake.core.camera import CameraIntrinsics, project
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.evaluation.detector_metrics import (
    detector_report,
    format_report,
    occlusion_flags,
    side_by_side,
    true_occlusion,
    upper_arm_ray_angle,
)
from akc_drake.evaluation.report import Table
from akc_drake.evaluation.session import Session

K = CameraIntrinsics()


def _pose(left_forward: bool) -> np.ndarray:
    """Landmarks in the camera frame (x right, y down, z away), a person 2 m away; the left arm either out to the
    side (on the image's right) or pointing straight at the camera's centre."""
    P = np.zeros((NUM_LANDMARKS, 3))
    for side, s in (("left", 1.0), ("right", -1.0)):
        sh = np.array([s * 0.166, -0.45, 2.0])
        P[INDEX[f"{side}_shoulder"]] = sh
        P[INDEX[f"{side}_hip"]] = [s * 0.09, 0.05, 2.0]
        d = -sh / np.linalg.norm(sh) if (side == "left" and left_forward) else np.array([s, 0.0, 0.0])
        P[INDEX[f"{side}_elbow"]] = sh + 0.29 * d
        P[INDEX[f"{side}_wrist"]] = sh + 0.57 * d
        P[INDEX[f"{side}_index"]] = sh + 0.66 * d + [0, 0.0, 0.0] + np.cross(d, [0, 1, 0]) * 0.03
        P[INDEX[f"{side}_pinky"]] = sh + 0.65 * d - np.cross(d, [0, 1, 0]) * 0.03
    return P


def _session(truth, pixels, vis, raw):
    T = len(truth)
    return Session(t=np.arange(T) / 10.0, raw=raw, visibility=vis, pixels=pixels, truth=truth, intrinsics=K)


def test_an_arm_pointing_at_the_camera_hides_its_shoulder_and_elbow_only():
    truth = np.stack([_pose(False), _pose(True)])
    occ = true_occlusion(truth, K)
    assert not occ[0].any()
    hidden = {n for n in INDEX if occ[1, INDEX[n]]}
    assert {"left_shoulder", "left_elbow"} <= hidden
    assert not any(n.startswith("right") for n in hidden)


def test_flags_are_the_occlusion_filters_visibility_and_proximity_checks():
    P = _pose(True)
    uv = np.array([project(p, K) for p in P])[None]
    vis = np.full((1, NUM_LANDMARKS), 0.99)
    vis[0, INDEX["right_wrist"]] = 0.3
    f_vis, f_prox = occlusion_flags(_session(P[None], uv, vis, P[None]))
    assert f_vis[0, INDEX["right_wrist"]] and f_vis[0].sum() == 1
    assert f_prox[0, INDEX["left_shoulder"]] and f_prox[0, INDEX["left_elbow"]]
    assert not f_prox[0, INDEX["right_shoulder"]] and not f_prox[0, INDEX["left_wrist"]]


def test_report_counts_detection_pixel_error_flags_and_depth_error():
    truth = np.stack([_pose(False), _pose(True), _pose(True)])
    uv = np.stack([[project(p, K) for p in P] for P in truth]) + [3.0, 4.0]  # 5 px off everywhere
    uv[2] = np.nan  # nobody found in the last frame
    vis = np.full((3, NUM_LANDMARKS), 0.99)
    raw = truth.copy()
    raw[1, INDEX["left_shoulder"], 2] -= 0.5  # the depth read on the hand, 50 cm short
    rep = detector_report(_session(truth, uv, vis, raw))
    assert rep["frames"] == 3 and rep["detection_rate"] == pytest.approx(2 / 3, abs=1e-4)
    ls = rep["joints"]["left_shoulder"]
    assert ls["visible"]["frames"] == 1 and ls["occluded"]["frames"] == 1
    assert ls["visible"]["px_median"] == pytest.approx(5.0) and ls["occluded"]["px_median"] == pytest.approx(5.0)
    assert ls["occluded"]["depth_err_cm_median"] == pytest.approx(50.0)
    assert ls["occluded"]["flag_visibility"] == 0.0 and ls["occluded"]["flag_proximity"] == 1.0
    assert ls["visible"]["flag_any"] == 0.0
    text = format_report("test", rep)
    assert "66.7 % of 3 frames" in text and "| left_shoulder | 1/1 | 5.0 / 5.0 |" in text


def test_side_by_side_puts_both_values_and_the_paper_in_each_cell():
    a = Table("t1", "Table", ["z"], ["Raw", "AKC"], np.array([[30.0, 6.0]]), np.array([[34.9, 3.3]]), decimals=1)
    b = Table("t1", "Table", ["z"], ["Raw", "AKC"], np.array([[33.8, 6.9]]), np.array([[34.9, 3.3]]), decimals=1)
    md = side_by_side([a], [b], "sim", "mediapipe")
    assert "sim / mediapipe (paper)" in md and "| z | 30.0 / 33.8 (34.9) | 6.0 / 6.9 (3.3) |" in md


def test_upper_arm_angle_to_the_camera_ray_and_the_figures_by_view():
    """An arm pointing at the camera is end-on (0 deg), one out to the side is seen side-on; the visible
    joints' pixel errors are split by that angle, and the figure without the end-on frames is given beside
    the one over every visible frame."""
    truth = np.stack([_pose(False), _pose(True)])
    ang = upper_arm_ray_angle(truth)
    assert ang.shape == (2, 2)
    assert ang[1, 0] == pytest.approx(0.0, abs=1e-6)  # left arm at the camera
    E = truth[0, INDEX["left_elbow"]]  # out to the side along +x: the angle between +x and the ray -E
    assert ang[0, 0] == pytest.approx(np.degrees(np.arccos(-E[0] / np.linalg.norm(E))), abs=1e-9)
    assert ang[0, 0] == pytest.approx(ang[1, 1], abs=1e-9) and 100.0 < ang[0, 0] < 105.0
    # Motion II's peak on the left: the upper arm at the camera, the forearm up (image -y); its elbow is visible.
    up = truth[1].copy()
    E = up[INDEX["left_elbow"]]
    for n, h in (("wrist", 0.27), ("index", 0.36), ("pinky", 0.35)):
        up[INDEX[f"left_{n}"]] = E + [0.0, -h, 0.0]
    truth = np.stack([truth[0], up])
    uv = np.stack([[project(p, K) for p in P] for P in truth])
    uv[:, INDEX["right_elbow"]] += [6.0, 8.0]  # 10 px off in both frames (the right arm side-on)
    uv[1, INDEX["left_elbow"]] += [0.0, -20.0]  # 20 px up the forearm with the left upper arm end-on
    rep = detector_report(_session(truth, uv, np.full((2, NUM_LANDMARKS), 0.99), truth))
    le, re = rep["joints"]["left_elbow"], rep["joints"]["right_elbow"]
    assert le["visible"]["frames"] == 2 and le["visible"]["px_median"] == pytest.approx(10.0)
    assert le["visible_not_end_on"]["frames"] == 1 and le["visible_not_end_on"]["px_median"] == pytest.approx(0.0)
    assert le["visible_by_upper_arm_angle"]["0-10"] == {"frames": 1, "px_median": pytest.approx(20.0)}
    assert le["visible_by_upper_arm_angle"]["10-30"] == {"frames": 0, "px_median": None}
    assert re["visible_not_end_on"]["px_median"] == pytest.approx(10.0) and re["visible_not_end_on"]["frames"] == 2
    assert "visible_not_end_on" not in rep["joints"]["left_hip"]
    text = format_report("test", rep)
    assert "| left_elbow | 20.0 (1) | - (0) | 0.0 (1) | 10.0 (2) | 0.0 (1) |" in text


def test_pixel_errors_by_the_detectors_visibility_band():
    """Each found frame of an arm joint counts in the band of its visibility (1.0 in the top band, NaN in none);
    a frame where nobody was found counts nowhere."""
    P = _pose(False)
    truth = np.stack([P] * 5)
    uv = np.stack([[project(p, K) for p in P]] * 5)
    j = INDEX["right_wrist"]
    uv[:, j] += np.array([[3.0, 4.0], [6.0, 8.0], [0.0, 2.0], [0.0, 7.0], [0.0, 0.0]])  # 5, 10, 2, 7, 0 px
    vis = np.full((5, NUM_LANDMARKS), 0.99)
    vis[:, j] = [1.0, 0.75, 0.995, np.nan, 0.5]
    uv[4] = np.nan  # nobody found in the last frame
    rep = detector_report(_session(truth, uv, vis, truth))
    bands = rep["joints"]["right_wrist"]["by_visibility"]
    assert list(bands) == ["0-0.7", "0.7-0.8", "0.8-0.9", "0.9-0.95", "0.95-0.99", "0.99-1"]
    assert bands["0.99-1"]["frames"] == 2 and bands["0.99-1"]["px_median"] == pytest.approx(3.5)
    assert bands["0.7-0.8"] == {"frames": 1, "px_median": pytest.approx(10.0), "px_p90": pytest.approx(10.0)}
    assert bands["0-0.7"]["frames"] == 0 and bands["0-0.7"]["px_median"] is None
    assert sum(b["frames"] for b in bands.values()) == 3  # the NaN visibility and the empty frame count nowhere
    assert "by_visibility" not in rep["joints"]["right_hip"]
    text = format_report("test", rep)
    assert "| right_wrist | - (0) | 10.0 (1) | - (0) | - (0) | - (0) | 3.5 (2) |" in text
