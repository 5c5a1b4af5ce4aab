"""Linear blend skinning and the tetrahedral render shell (akc_drake.core.skinning)."""

import numpy as np
import pytest

from akc_drake.core import skinning


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.fixture
def two_bones():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(200, 3))
    w = rng.uniform(size=(200, 3))
    w[:100, 2] = 0.0  # bone 2 touches only the second half
    w /= w.sum(axis=1, keepdims=True)
    return pts, w


def test_identity_maps_reproduce_the_rest_points(two_bones):
    pts, w = two_bones
    lbs = skinning.LinearBlendSkinning(pts, w, moving_bones=[2])
    maps = np.tile(np.hstack([np.eye(3), np.zeros((3, 1))]), (3, 1, 1))
    assert np.max(np.abs(lbs.skin(maps) - pts)) < 1e-12
    assert set(lbs.rows) == set(range(100, 200))


def test_one_rigid_map_for_every_bone_moves_the_points_rigidly(two_bones):
    pts, w = two_bones
    R = _rot([1, 2, 3], 0.7)
    M = skinning.rigid_map(R, [0.1, 0.2, 0.3], [1.0, -1.0, 0.5])
    out = skinning.LinearBlendSkinning(pts, w).skin(np.tile(M, (3, 1, 1)))
    expected = (pts - [0.1, 0.2, 0.3]) @ R.T + [1.0, -1.0, 0.5]
    assert np.max(np.abs(out - expected)) < 1e-12


def test_blend_matches_the_per_point_formula(two_bones):
    pts, w = two_bones
    maps = np.stack([skinning.rigid_map(_rot([0, 0, 1], a), [0, 0, 0], [a, 0, 0]) for a in (0.0, 0.4, -0.9)])
    out = skinning.LinearBlendSkinning(pts, w).skin(maps)
    k = 150
    ref = sum(w[k, b] * (maps[b, :, :3] @ pts[k] + maps[b, :, 3]) for b in range(3))
    assert np.allclose(out[k], ref, atol=1e-12)
    assert np.allclose(skinning.blend_affine(pts, w, maps), out, atol=1e-12)


def test_a_static_bone_that_moves_is_refused(two_bones):
    pts, w = two_bones
    lbs = skinning.LinearBlendSkinning(pts, w, moving_bones=[2])
    maps = np.tile(np.hstack([np.eye(3), np.zeros((3, 1))]), (3, 1, 1))
    maps[0, 0, 3] = 0.01
    with pytest.raises(ValueError, match="moving_bones"):
        lbs.skin(maps)


def test_weights_must_sum_to_one():
    with pytest.raises(ValueError, match="sum to 1"):
        skinning.LinearBlendSkinning(np.zeros((2, 3)), np.array([[0.5, 0.4], [1.0, 0.0]]))


def test_stretch_map_takes_the_bone_onto_the_new_one_and_scales_across():
    h, t = np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.3, 0.0])
    M = skinning.stretch_map(h, t, [1.0, 0.0, 0.0], [1.0, 0.0, 0.4], 1.1)
    out = skinning.apply_map(M, np.array([h, t, [0.1, 0.0, 0.0]]))
    assert np.allclose(out[0], [1.0, 0.0, 0.0]) and np.allclose(out[1], [1.0, 0.0, 0.4])
    assert np.isclose(np.linalg.norm(out[2] - out[0]), 0.11)


def test_prism_shell_is_a_positive_layer_just_under_the_surface():
    # A closed octahedron, counter-clockwise from outside.
    V = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    T = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    pts, tets = skinning.prism_shell(V, T, depth=0.01)
    assert pts.shape == (12, 3) and tets.shape == (24, 4)
    a, b, c, d = (pts[tets[:, i]] for i in range(4))
    vol = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6
    assert np.all(vol > 0)
    # Inner vertices 0.01 inside along the vertex normal (here: toward the centre).
    assert np.allclose(np.linalg.norm(pts[6:], axis=1), 0.99)
    # The prisms fill the layer between the octahedron and its inner copy exactly (no overlap, no gap).
    outer = 4 / 3
    assert vol.sum() == pytest.approx(outer * (1 - 0.99**3), rel=1e-9)
    # Boundary faces (used by one tetrahedron): the 8 outer and 8 inner triangles only, no side walls.
    faces = np.sort(
        np.concatenate([tets[:, [0, 1, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 3]], tets[:, [1, 2, 3]]]), axis=1
    )
    _, counts = np.unique(faces, axis=0, return_counts=True)
    assert np.sum(counts == 1) == 16


def test_vtk_text_has_the_counts_drake_reads():
    pts, tets = skinning.prism_shell(np.eye(3), np.array([[0, 1, 2]]))
    vtk = skinning.vtk_tetra_text(pts, tets)
    assert "POINTS 6 double" in vtk and "CELLS 3 15" in vtk and vtk.strip().endswith("10")
    assert np.allclose(skinning.vertex_normals(np.eye(3), np.array([[0, 1, 2]])), 1 / np.sqrt(3))


def _tube(radius=0.04, length=0.3, centre=(0.1, -0.2, 0.5), n=48, rings=31):
    """A closed-side cylinder along z (triangles), its axis through ``centre``."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    z = np.linspace(0, length, rings)
    pts = np.array([[radius * np.cos(t), radius * np.sin(t), h] for h in z for t in a]) + centre
    tris = []
    for r in range(rings - 1):
        for k in range(n):
            i, j = r * n + k, r * n + (k + 1) % n
            tris += [[i, j, j + n], [i, j + n, i + n]]
    return pts, np.array(tris)


def test_plane_section_cuts_a_tube_in_a_circle_around_its_axis():
    pts, tris = _tube()
    seg = skinning.plane_section(pts, tris, [0.1, -0.2, 0.625], [0, 0, 1])
    assert len(seg) == 2 * 48  # each quad of the tube is two triangles, both cut
    # Every end lies on the plane and on the tube (within the polygon's chord sag).
    assert np.allclose(seg[..., 2], 0.625, atol=1e-12)
    r = np.linalg.norm(seg[..., :2] - [0.1, -0.2], axis=-1)
    assert np.all((r <= 0.04 + 1e-12) & (r > 0.04 * np.cos(np.pi / 48) - 1e-12))
    assert np.allclose(skinning.section_centre(seg), [0.1, -0.2, 0.625], atol=1e-12)
    # A radius filter keeps only what lies near the origin; a plane that misses the surface cuts nothing.
    assert len(skinning.plane_section(pts, tris, [0.3, -0.2, 0.625], [0, 0, 1], radius=0.1)) == 0
    assert len(skinning.plane_section(pts, tris, [0, 0, 2.0], [0, 0, 1])) == 0
    with pytest.raises(ValueError, match="does not cut"):
        skinning.section_centre(np.zeros((0, 2, 3)))


def test_limb_axis_of_a_turned_tube_is_its_axis():
    pts, tris = _tube(centre=(0.0, 0.0, 0.0))
    R = _rot([1, 2, 0.5], 0.7)
    p = pts @ R.T + [0.2, 0.1, -0.3]
    start, end = R @ [0.0, 0.0, 0.02] + [0.2, 0.1, -0.3], R @ [0.0, 0.0, 0.28] + [0.2, 0.1, -0.3]
    point, d = skinning.limb_axis(p, tris, start, end)
    assert np.allclose(d, R[:, 2], atol=1e-9)
    assert skinning.distance_to_line(start, point, d) < 1e-9
    # A point 1 cm off the axis is 1 cm from it.
    off = start + 0.01 * R[:, 0]
    assert skinning.distance_to_line(off, point, d) == pytest.approx(0.01, abs=1e-9)
