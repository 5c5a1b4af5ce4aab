"""core/skeleton_drawing.py: the bones drawn, each bone's frame, and where the drawn skeleton stands."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from akc_drake.core import skeleton_drawing as drawing
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS


def test_bones_join_named_landmarks():
    assert len(drawing.BONES) == 12 and drawing.BONE_INDEX.shape == (12, 2)
    forearm = drawing.BONES.index(("left_elbow", "left_wrist"))
    assert drawing.BONE_INDEX[forearm].tolist() == [INDEX["left_elbow"], INDEX["left_wrist"]]
    assert set(drawing.BONE_INDEX.ravel()) == set(range(NUM_LANDMARKS))  # every landmark is on a bone


@pytest.mark.parametrize("d", [[0.0, 0.3, 0.4], [1.0, 0.0, 0.0], [-0.2, 0.1, -2.0], [0.95, 0.0, 0.31]])
def test_bone_frame_is_a_rotation_with_z_along_the_bone(d):
    a = np.array([0.1, -0.2, 2.0])
    b = a + np.array(d)
    R, centre, L = drawing.bone_frame(a, b)
    assert L == pytest.approx(np.linalg.norm(d), abs=1e-15)
    np.testing.assert_allclose(centre, a + 0.5 * np.array(d), atol=1e-15)
    np.testing.assert_allclose(R[:, 2], np.array(d) / L, atol=1e-15)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    # scipy reads it as a proper rotation that takes z to the bone direction
    np.testing.assert_allclose(Rotation.from_matrix(R).apply([0.0, 0.0, L]), d, atol=1e-12)


def test_degenerate_bones_are_not_drawn():
    a = np.array([0.1, 0.2, 2.0])
    assert drawing.bone_frame(a, a) is None
    assert drawing.bone_frame(a, a + 1e-10) is None
    assert drawing.bone_frame(a, np.array([np.nan, 0.0, 2.0])) is None


def test_anchor_puts_the_hip_midpoint_at_the_chosen_world_point():
    P = np.full((NUM_LANDMARKS, 3), np.nan)
    assert drawing.anchor_position(P) is None
    P[INDEX["left_hip"]] = [0.15, 0.4, 2.1]
    assert drawing.anchor_position(P) is None  # one hip is not enough
    P[INDEX["right_hip"]] = [-0.15, 0.42, 2.2]
    p_WC = drawing.anchor_position(P)
    hips_W = drawing.R_WC_FACING_X @ np.array([0.0, 0.41, 2.15]) + p_WC
    np.testing.assert_allclose(hips_W, drawing.SKELETON_HIPS_W, atol=1e-15)
    # The operator faces world +x and stands upright: C's -z is world +x, C's -y world +z.
    np.testing.assert_array_equal(drawing.R_WC_FACING_X @ [0, 0, -1], [1, 0, 0])
    np.testing.assert_array_equal(drawing.R_WC_FACING_X @ [0, -1, 0], [0, 0, 1])
    np.testing.assert_allclose(p_WC, [-0.1 + 2.15, 1.4, 0.95 + 0.41], atol=1e-15)
