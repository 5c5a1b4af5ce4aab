"""Tests of akc_drake.core.occlusion (paper §II-C): cases worked out by hand, then invariants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from akc_drake.core.occlusion import (
    BACKGROUND_M,
    DEPTH_NEIGHBOURS,
    HAND_REACH_M,
    HIP_FRONT_M,
    PAPER_RULES,
    occlusion_filter,
)
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, PROXIMAL_DISTAL_PAIRS

W = 640  # 5 % of the width = 32 px


def scene():
    """A T-pose-like frame: every landmark visible and well apart in the image."""
    points = np.array([[0.1 * j - 0.6, 0.05 * j, 2.0 + 0.01 * j] for j in range(NUM_LANDMARKS)])
    pixels = np.array([[40.0 + 50.0 * j, 100.0 + 20.0 * (j % 3)] for j in range(NUM_LANDMARKS)])
    visibility = np.full(NUM_LANDMARKS, 0.95)
    return points, pixels, visibility


def test_everything_visible_and_apart_passes_unchanged():
    points, pixels, vis = scene()
    accepted, info = occlusion_filter(points, pixels, vis, W)
    np.testing.assert_array_equal(accepted, points)
    assert not info.rejected.any() and not info.depth_dropped.any()
    assert accepted is not points


def test_visibility_below_threshold_rejects_the_whole_landmark():
    points, pixels, vis = scene()
    le, rw, lh = INDEX["left_elbow"], INDEX["right_wrist"], INDEX["left_hip"]
    vis[le] = 0.69
    vis[rw] = np.nan
    vis[lh] = 0.7  # exactly at the threshold: kept
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert np.isnan(accepted[le]).all() and np.isnan(accepted[rw]).all()
    np.testing.assert_array_equal(accepted[lh], points[lh])
    np.testing.assert_array_equal(np.flatnonzero(info.rejected), sorted([le, rw]))
    # a custom threshold
    accepted, info = occlusion_filter(points, pixels, vis, W, visibility_threshold=0.5)
    assert np.flatnonzero(info.rejected).tolist() == [rw]


def test_proximal_depth_dropped_within_5_percent_of_width_of_a_distal_joint():
    points, pixels, vis = scene()
    le, lw = INDEX["left_elbow"], INDEX["left_wrist"]
    pixels[le] = pixels[lw] + [20.0, 24.0]  # 31.2 px < 32 px: occluded by the wrist
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert np.isnan(accepted[le, 2])
    np.testing.assert_array_equal(accepted[le, :2], points[le, :2])  # x, y kept
    np.testing.assert_array_equal(accepted[lw], points[lw])  # the distal joint keeps its depth
    assert np.flatnonzero(info.depth_dropped).tolist() == [le]
    assert not info.rejected.any()


def test_proximal_depth_kept_outside_the_radius():
    points, pixels, vis = scene()
    le, lw = INDEX["left_elbow"], INDEX["left_wrist"]
    pixels[le] = pixels[lw] + [-20.0, 26.0]  # 32.8 px > 32 px (and 55 px from the right elbow, 70 from its wrist)
    accepted, info = occlusion_filter(points, pixels, vis, W)
    np.testing.assert_array_equal(accepted, points)
    assert not info.depth_dropped.any()
    # the radius scales with the width and the proximity fraction
    accepted, info = occlusion_filter(points, pixels, vis, W, proximity=0.06)
    assert np.flatnonzero(info.depth_dropped).tolist() == [le]
    accepted, info = occlusion_filter(points, pixels, vis, 700)
    assert np.flatnonzero(info.depth_dropped).tolist() == [le]


def test_shoulder_depth_dropped_behind_the_hand_and_both_sides_independent():
    points, pixels, vis = scene()
    rs, ri = INDEX["right_shoulder"], INDEX["right_index"]
    ls, lp = INDEX["left_shoulder"], INDEX["left_pinky"]
    pixels[rs] = pixels[ri] + [5.0, 0.0]
    pixels[ls] = pixels[lp] + [0.0, -10.0]
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert sorted(np.flatnonzero(info.depth_dropped).tolist()) == sorted([rs, ls])
    assert np.isnan(accepted[[rs, ls], 2]).all()


def test_hand_of_the_other_arm_hides_a_shoulder_or_an_elbow_in_ours_not_in_the_papers():
    points, pixels, vis = scene()
    le, rw = INDEX["left_elbow"], INDEX["right_wrist"]
    pixels[le] = pixels[rw] + [1.0, 1.0]
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert np.flatnonzero(info.depth_dropped).tolist() == [le]
    assert np.isnan(accepted[le, 2]) and np.array_equal(accepted[le, :2], points[le, :2])
    # the other arm's distal joint is the occluder: the right wrist keeps its depth
    np.testing.assert_array_equal(np.delete(accepted, le, axis=0), np.delete(points, le, axis=0))
    # a hand across the chest: the right index near the left shoulder
    points, pixels, vis = scene()
    ls, ri = INDEX["left_shoulder"], INDEX["right_index"]
    pixels[ls] = pixels[ri] + [-12.0, 9.0]  # 15 px
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert np.flatnonzero(info.depth_dropped).tolist() == [ls]
    # the paper's pairs are on one arm only
    accepted, info = occlusion_filter(points, pixels, vis, W, **PAPER_RULES)
    np.testing.assert_array_equal(accepted, points)
    assert not info.depth_dropped.any()
    # no pair makes an arm's distal joint the proximal of the other's
    assert (("left_wrist", "right_shoulder") not in PROXIMAL_DISTAL_PAIRS
            and ("right_elbow", "left_elbow") not in PROXIMAL_DISTAL_PAIRS)


def test_distal_joint_is_never_dropped_and_rejected_distal_cannot_occlude():
    points, pixels, vis = scene()
    le, lw = INDEX["left_elbow"], INDEX["left_wrist"]
    pixels[lw] = pixels[le]
    vis[lw] = 0.2  # the wrist is the hidden one: the elbow's depth is right
    accepted, info = occlusion_filter(points, pixels, vis, W)
    np.testing.assert_array_equal(accepted[le], points[le])
    assert np.isnan(accepted[lw]).all()
    assert info.rejected.tolist() == [j == lw for j in range(NUM_LANDMARKS)]
    assert not info.depth_dropped.any()


def test_rejected_proximal_is_not_also_marked_depth_dropped_and_nan_pixels_are_ignored():
    points, pixels, vis = scene()
    le, lw, re = INDEX["left_elbow"], INDEX["left_wrist"], INDEX["right_elbow"]
    pixels[le] = pixels[lw]
    vis[le] = 0.1
    pixels[re] = np.nan
    accepted, info = occlusion_filter(points, pixels, vis, W)
    assert info.rejected[le] and not info.depth_dropped[le]
    np.testing.assert_array_equal(accepted[re], points[re])


def test_inputs_are_not_modified():
    points, pixels, vis = scene()
    pixels[INDEX["left_elbow"]] = pixels[INDEX["left_wrist"]]
    vis[0] = 0.0
    copies = points.copy(), pixels.copy(), vis.copy()
    occlusion_filter(points, pixels, vis, W)
    for a, b in zip((points, pixels, vis), copies, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(points_C=np.zeros((11, 3))), "points_C"),
        (dict(pixels=np.zeros((12, 3))), "pixels"),
        (dict(visibility=np.zeros(13)), "visibility"),
        (dict(image_width=0), "image_width"),
        (dict(image_width=float("nan")), "image_width"),
        (dict(visibility_threshold=1.5), "visibility_threshold"),
        (dict(proximity=-0.1), "proximity"),
    ],
)
def test_bad_input_raises_value_error_naming_it(kwargs, match):
    points, pixels, vis = scene()
    args = dict(points_C=points, pixels=pixels, visibility=vis, image_width=W)
    args.update(kwargs)
    extra = {k: args.pop(k) for k in ("visibility_threshold", "proximity") if k in args}
    with pytest.raises(ValueError, match=match):
        occlusion_filter(args["points_C"], args["pixels"], args["visibility"], args["image_width"], **extra)


def test_pairs_cover_elbow_and_shoulder_against_all_distal_joints():
    proximal = {p for p, _ in PROXIMAL_DISTAL_PAIRS}
    assert proximal == {"left_shoulder", "left_elbow", "right_shoulder", "right_elbow"}


@settings(max_examples=60, deadline=None)
@given(
    points=arrays(np.float64, (NUM_LANDMARKS, 3), elements=st.floats(-5, 5)),
    pixels=arrays(np.float64, (NUM_LANDMARKS, 2), elements=st.floats(0, 640) | st.just(np.nan)),
    vis=arrays(np.float64, (NUM_LANDMARKS,), elements=st.floats(0, 1) | st.just(np.nan)),
    proximity=st.floats(0.0, 0.5),
)
def test_output_is_input_with_entries_removed(points, pixels, vis, proximity):
    accepted, info = occlusion_filter(points, pixels, vis, W, proximity=proximity, background_m=None)
    kept = ~np.isnan(accepted)
    np.testing.assert_array_equal(accepted[kept], points[kept])
    # rejected rows are all NaN; a dropped depth only removes z
    assert np.isnan(accepted[info.rejected]).all()
    assert np.isnan(accepted[info.depth_dropped, 2]).all()
    np.testing.assert_array_equal(accepted[info.depth_dropped, :2], points[info.depth_dropped, :2])
    assert not (info.rejected & info.depth_dropped).any()
    np.testing.assert_array_equal(info.rejected, ~(vis >= 0.7))
    # only proximal joints can lose their depth
    proximal = [INDEX[p] for p, _ in PROXIMAL_DISTAL_PAIRS]
    assert not np.delete(info.depth_dropped, proximal).any()
    # with zero proximity nothing is dropped
    if proximity == 0.0:
        assert not info.depth_dropped.any()


def test_paper_rules_use_only_the_wrist_pairs_and_any_detected_distal_joint():
    from akc_drake.core.occlusion import PAPER_RULES

    points, pixels, vis = scene()
    s, e, w = INDEX["left_shoulder"], INDEX["left_elbow"], INDEX["left_wrist"]
    # The elbow sits on the shoulder's pixel: our shoulder-elbow pair drops the shoulder depth, the paper's not.
    pixels[e] = pixels[s] + [5.0, 0.0]
    ours, info = occlusion_filter(points, pixels, vis, W)
    paper, pinfo = occlusion_filter(points, pixels, vis, W, **PAPER_RULES)
    assert info.depth_dropped[s] and np.isnan(ours[s, 2])
    assert not pinfo.depth_dropped[s] and paper[s, 2] == points[s, 2]
    # A wrist rejected for low visibility still occludes the elbow under the paper's rules (not under ours).
    pixels[w] = pixels[e] + [3.0, 0.0]
    vis[w] = 0.2
    _, info = occlusion_filter(points, pixels, vis, W)
    _, pinfo = occlusion_filter(points, pixels, vis, W, **PAPER_RULES)
    assert pinfo.depth_dropped[e] and pinfo.depth_dropped[s]
    assert not info.depth_dropped[e]


@settings(max_examples=60, deadline=None)
@given(
    points=arrays(np.float64, (NUM_LANDMARKS, 3), elements=st.floats(-5, 5) | st.just(np.nan)),
    vis=arrays(np.float64, (NUM_LANDMARKS,), elements=st.floats(0, 1)),
)
def test_the_background_check_drops_exactly_the_depths_behind_every_accepted_neighbour(points, vis):
    pixels = scene()[1]  # (apart: the proximity check drops nothing)
    accepted, info = occlusion_filter(points, pixels, vis, W)
    z = points[:, 2]
    kept = ~info.rejected & np.isfinite(z)
    for i in range(NUM_LANDMARKS):
        nb = [INDEX[q] for p, q in DEPTH_NEIGHBOURS if INDEX[p] == i and kept[INDEX[q]]]
        behind = kept[i] and len(nb) > 0 and all(z[i] - z[q] > BACKGROUND_M for q in nb)
        assert info.depth_dropped[i] == behind
        if behind:
            assert np.isnan(accepted[i, 2]) and (accepted[i, :2] == points[i, :2]).all()


def test_an_elbow_read_on_the_wall_behind_its_shoulder_and_wrist_goes_back_on_its_ray():
    # MediaPipe's elbow on the silhouette's edge reads the wall 1.5 m behind (bvhtools_b, the skinned body): S2
    # deprojected its pixel there, x, y 1.7 times the joint's. Its depth is dropped, and x, y go back on the ray at
    # the depth last accepted; the shoulder and the wrist, which the elbow's reading does not move, are kept.
    points, pixels, vis = scene()
    ls, le, lw = INDEX["left_shoulder"], INDEX["left_elbow"], INDEX["left_wrist"]
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    occlusion_filter(points, pixels, vis, W, held=held)
    wall = points.copy()
    wall[le] = points[le] * 3.5 / points[le, 2]
    accepted, info = occlusion_filter(wall, pixels, vis, W, held=held)
    assert info.depth_dropped.tolist() == [i == le for i in range(NUM_LANDMARKS)]
    np.testing.assert_allclose(accepted[le, :2], points[le, :2], rtol=1e-12)
    np.testing.assert_array_equal(accepted[[ls, lw]], points[[ls, lw]])
    # A wrist on the wall behind its elbow, its one neighbour, likewise; a hip behind the other hip.
    for j in (lw, INDEX["right_hip"]):
        wall = points.copy()
        wall[j, 2] += 1.5
        assert occlusion_filter(wall, pixels, vis, W)[1].depth_dropped.tolist() == [i == j for i in range(12)]
    # Within the margin (an upper arm pointing away from the camera: 0.4 m behind), or behind the shoulder but
    # not the wrist (the forearm pointing back at the camera), or with no neighbour accepted: kept.
    for dz, wrist_dz, vis_nb in ((0.4, 0.0, 0.95), (1.5, 1.5, 0.95), (1.5, 0.0, 0.1)):
        p, v = points.copy(), vis.copy()
        p[le, 2] += dz
        p[lw, 2] += wrist_dz
        v[[ls, lw]] = vis_nb
        assert not occlusion_filter(p, pixels, v, W)[1].depth_dropped[le]
    # The paper's filter has no such check; a margin that is no positive number of metres is refused.
    assert PAPER_RULES["background_m"] is None
    wall[le] = points[le] * 3.5 / points[le, 2]
    assert not occlusion_filter(wall, pixels, vis, W, **PAPER_RULES)[1].depth_dropped.any()
    for bad in (0.0, -1.0, "0.6"):
        with pytest.raises(ValueError, match="background_m"):
            occlusion_filter(wall, pixels, vis, W, background_m=bad)


#: Two frames of the teleop demo's pick-and-place (MediaPipe on the skinned body, seed 1, AKC(KF), t = 5.2 and
#: 5.3 s), as S2 deprojected them: the right hand goes down to the box in front of the pelvis, its fingers cover
#: the right hip's pixel and the hip reads them (1.972 -> 1.546 m) while its pixel stays where it was.
HAND_OVER_HIP_BEFORE = np.array([
    [0.158, -0.059, 1.989], [-0.133, -0.049, 1.801], [0.206, 0.179, 1.742], [-0.121, 0.122, 1.607],
    [0.193, 0.156, 1.675], [-0.112, 0.212, 1.528], [0.158, 0.127, 1.562], [-0.124, 0.26, 1.491],
    [0.164, 0.095, 1.557], [-0.102, 0.256, 1.496], [0.098, 0.449, 1.98], [-0.08, 0.451, 1.972]])
HAND_OVER_HIP = np.array([
    [0.157, -0.059, 1.989], [-0.135, -0.049, 1.822], [0.205, 0.177, 1.736], [-0.121, 0.12, 1.613],
    [0.192, 0.156, 1.677], [-0.112, 0.216, 1.531], [0.158, 0.126, 1.558], [-0.125, 0.264, 1.493],
    [0.164, 0.095, 1.557], [-0.102, 0.26, 1.498], [0.098, 0.449, 1.98], [-0.063, 0.353, 1.546]])


def test_a_hip_read_on_the_hand_in_front_of_it_goes_back_on_its_ray():
    rh, lh = INDEX["right_hip"], INDEX["left_hip"]
    pixels, vis = np.full((NUM_LANDMARKS, 2), np.nan), np.full(NUM_LANDMARKS, 0.99)
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    _, info = occlusion_filter(HAND_OVER_HIP_BEFORE, pixels, vis, W, held=held)
    assert not info.depth_dropped.any()
    accepted, info = occlusion_filter(HAND_OVER_HIP, pixels, vis, W, held=held)
    assert info.depth_dropped.tolist() == [i == rh for i in range(NUM_LANDMARKS)]
    # back on its ray at the depth last accepted: where it was the frame before, within the detector's jitter
    np.testing.assert_allclose(accepted[rh, :2], HAND_OVER_HIP[rh, :2] * 1.972 / 1.546, rtol=1e-12)
    assert np.linalg.norm(accepted[rh, :2] - HAND_OVER_HIP_BEFORE[rh, :2]) < 0.005
    # The paper's filter has no such check (and here, without pixels, drops nothing).
    assert PAPER_RULES["hand_reach_m"] is None
    assert not occlusion_filter(HAND_OVER_HIP, pixels, vis, W, **PAPER_RULES)[1].depth_dropped.any()
    # Each condition alone is not enough.
    rw, ri, rp = INDEX["right_wrist"], INDEX["right_index"], INDEX["right_pinky"]
    level = HAND_OVER_HIP.copy()  # the hips level (the hand at the hip's depth beside it, arms hanging): kept
    level[lh, 2] = level[rh, 2] + HIP_FRONT_M - 0.01
    far = HAND_OVER_HIP.copy()  # the hand 25 cm in front of the hip's reading (a body side-on): kept
    far[[rw, ri, rp], :] *= (1.546 - 0.25) / far[[rw, ri, rp], 2:3]
    away = HAND_OVER_HIP.copy()  # the hand's landmarks farther than the fingers reach across the ray: kept
    for j in (rw, ri, rp):
        away[j, 0] -= 0.08
    hidden = vis.copy()  # the hand rejected (low visibility): kept
    hidden[[rw, ri, rp]] = 0.2
    for p, v in ((level, vis), (far, vis), (away, vis), (HAND_OVER_HIP, hidden)):
        assert not occlusion_filter(p, pixels, v, W)[1].depth_dropped[rh]
    # The reach is the argument: a shorter one keeps the hip (its fingers' knuckles are 8.5-9.3 cm from its ray).
    assert occlusion_filter(HAND_OVER_HIP, pixels, vis, W, hand_reach_m=0.095)[1].depth_dropped[rh]
    assert not occlusion_filter(HAND_OVER_HIP, pixels, vis, W, hand_reach_m=0.08)[1].depth_dropped[rh]
    assert HAND_REACH_M > 0.095
    for bad in (0.0, -1.0, float("nan"), "0.12"):
        with pytest.raises(ValueError, match="hand_reach_m"):
            occlusion_filter(HAND_OVER_HIP, pixels, vis, W, hand_reach_m=bad)


def test_a_dropped_depths_x_y_go_on_its_pixel_ray_at_its_last_accepted_depth():
    points, pixels, vis = scene()
    le, lw = INDEX["left_elbow"], INDEX["left_wrist"]
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    # Frame 1: all accepted; the state records every position.
    accepted, _ = occlusion_filter(points, pixels, vis, W, held=held)
    np.testing.assert_array_equal(accepted, points)
    np.testing.assert_array_equal(held, points)
    # Frame 2: the forearm crosses in front of the elbow at 2.06 m. The joint is at (0.3, -0.1, 2.5) and S2
    # deprojected its pixel at the forearm's depth: x, y 2.06 / 2.5 of the joint's.
    joint = np.array([0.3, -0.1, 2.5])
    held[le] = joint
    read = joint * 2.06 / 2.5
    p2 = points.copy()
    p2[le] = read
    pixels[le] = pixels[lw] + [10.0, 0.0]
    before = held.copy()
    accepted, info = occlusion_filter(p2, pixels, vis, W, held=held)
    assert info.depth_dropped[le] and np.isnan(accepted[le, 2])
    np.testing.assert_allclose(accepted[le, :2], joint[:2], rtol=1e-12)  # 6 cm in x moved back onto the joint
    np.testing.assert_array_equal(held[le], joint)  # a dropped depth leaves the state
    keep = np.arange(NUM_LANDMARKS) != le
    np.testing.assert_array_equal(accepted[keep], p2[keep])
    np.testing.assert_array_equal(held[keep], p2[keep])
    # Stateless (no held), the paper's rules (the state untouched), or no depth accepted yet: x, y as deprojected.
    for kw in ({}, {"held": before, "hold_rays": False}, {"held": np.full((NUM_LANDMARKS, 3), np.nan)}):
        accepted, _ = occlusion_filter(p2, pixels, vis, W, **kw)
        np.testing.assert_array_equal(accepted[le, :2], read[:2])
    assert PAPER_RULES["hold_rays"] is False
    np.testing.assert_array_equal(before[le], joint)
    # A rejected landmark leaves its held position too.
    vis[lw] = 0.1
    held[lw] = [0.5, 0.0, 1.0]
    occlusion_filter(points, pixels, vis, W, held=held)
    np.testing.assert_array_equal(held[lw], [0.5, 0.0, 1.0])


def test_a_left_right_swapped_frame_reads_and_records_the_held_rows_of_the_other_side():
    from akc_drake.core.kalman import LEFT_RIGHT_SWAP

    points, pixels, vis = scene()
    le, lw = INDEX["left_elbow"], INDEX["left_wrist"]
    pixels[le] = pixels[lw] + [10.0, 0.0]
    points[le] = np.array([0.3, -0.1, 2.5]) * 0.8
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    occlusion_filter(scene()[0], scene()[1], vis, W, held=held)  # a first frame, as labelled
    held[le] = [0.3, -0.1, 2.5]
    held_s = held.copy()
    straight, _ = occlusion_filter(points, pixels, vis, W, held=held)
    # The same frame with the whole body labelled mirror-wise: the rows exchanged, nothing else.
    swapped, _ = occlusion_filter(points[LEFT_RIGHT_SWAP], pixels[LEFT_RIGHT_SWAP], vis[LEFT_RIGHT_SWAP], W,
                                  held=held_s)
    np.testing.assert_array_equal(swapped, straight[LEFT_RIGHT_SWAP])
    np.testing.assert_array_equal(held_s, held)
    np.testing.assert_allclose(straight[le, :2], [0.3, -0.1], rtol=1e-12)


@pytest.mark.parametrize("bad", [np.zeros((11, 3)), np.zeros((NUM_LANDMARKS, 3), dtype=np.float32),
                                 [[2.0] * 3] * NUM_LANDMARKS, np.zeros(NUM_LANDMARKS)])
def test_held_must_be_a_float64_state_array(bad):
    points, pixels, vis = scene()
    with pytest.raises(ValueError, match="held"):
        occlusion_filter(points, pixels, vis, W, held=bad)
