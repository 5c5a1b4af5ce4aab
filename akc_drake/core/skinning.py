"""Linear blend skinning and the tetrahedral "shell" a deformable render geometry needs (pure numpy).

Linear blend skinning (LBS): each bone ``b`` has an affine map ``M_b = [A_b | t_b]`` (3 x 4) from the rest
pose to the current pose; a point ``v`` with bone weights ``w_b`` (summing to 1) goes to
``sum_b w_b (A_b v + t_b)``. :class:`LinearBlendSkinning` evaluates that for every point at once with one
matrix product ``W @ M`` (``W`` the ``(N, B)`` weights, sparse, ``M`` the ``(B, 12)`` bone maps), and only for the
points some moving bone touches: the rest of the body keeps its rest position.

SceneGraph renders a deformable geometry from a tetrahedral mesh (the boundary of its tetrahedra).
:func:`prism_shell` turns a surface into a thin tetrahedral layer under it (each triangle's prism down to an
inner copy of the surface), so that the renderer draws the surface itself, shaded with normals from the
surface's own triangles; the inner copy is hidden inside the body. Each inner vertex is skinned with the
weights of its surface vertex.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

#: Default thickness of the prism layer under the surface (metres).
SHELL_DEPTH_M = 0.002


def rigid_map(R: np.ndarray, pivot_rest: np.ndarray, pivot_posed: np.ndarray) -> np.ndarray:
    """The ``(3, 4)`` map ``v -> R (v - pivot_rest) + pivot_posed``."""
    R = np.asarray(R, dtype=float)
    return np.hstack([R, (np.asarray(pivot_posed, float) - R @ np.asarray(pivot_rest, float))[:, None]])


def stretch_map(head: np.ndarray, tail: np.ndarray, new_head: np.ndarray, new_tail: np.ndarray, scale: float):
    """The ``(3, 4)`` affine map that takes a bone ``head -> tail`` onto ``new_head -> new_tail``.

    Directions across the bone are scaled by ``scale``; the bone vector itself goes onto the new one, so
    a bone is stretched along its length (and turned, when the new vector points elsewhere).

    Raises:
        ValueError: a zero-length bone or a non-positive scale.
    """
    head, tail = np.asarray(head, float), np.asarray(tail, float)
    a = tail - head
    n = float(np.linalg.norm(a))
    if not n > 1e-12 or not scale > 0:
        raise ValueError(f"stretch_map needs a bone of non-zero length and scale > 0, got |a| = {n}, {scale}")
    d = a / n
    b = np.asarray(new_tail, float) - np.asarray(new_head, float)
    S = scale * (np.eye(3) - np.outer(d, d)) + np.outer(b, d) / n
    return np.hstack([S, (np.asarray(new_head, float) - S @ head)[:, None]])


def apply_map(M: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(N, 3)`` points mapped by the ``(3, 4)`` affine map ``M``."""
    return np.asarray(points, float) @ M[:, :3].T + M[:, 3]


class LinearBlendSkinning:
    """Vectorised linear blend skinning of a fixed set of points.

    Args:
        rest: ``(N, 3)`` rest positions.
        weights: ``(N, B)`` bone weights (each row sums to 1).
        moving_bones: indices of the bones whose map may differ from the identity; every other bone must
            keep the identity map (checked), so points they alone carry are never recomputed. None: all.

    Raises:
        ValueError: shapes that disagree, negative weights or rows that do not sum to 1 (within 1e-6).
    """

    def __init__(self, rest: np.ndarray, weights: np.ndarray, moving_bones=None):
        rest = np.asarray(rest, dtype=float)
        W = np.asarray(weights, dtype=float)
        if rest.ndim != 2 or rest.shape[1] != 3:
            raise ValueError(f"rest must have shape (N, 3), got {rest.shape}")
        if W.ndim != 2 or W.shape[0] != rest.shape[0]:
            raise ValueError(f"weights must have shape ({rest.shape[0]}, B), got {W.shape}")
        if np.any(W < 0) or not np.allclose(W.sum(axis=1), 1.0, atol=1e-6):
            raise ValueError("weights must be non-negative and sum to 1 for every point")
        self.rest = rest
        self.weights = W
        self.num_bones = W.shape[1]
        moving = np.arange(self.num_bones) if moving_bones is None else np.unique(np.asarray(moving_bones, int))
        self.moving_bones = moving
        self._static = np.setdiff1d(np.arange(self.num_bones), moving)
        self.rows = np.flatnonzero(W[:, moving].sum(axis=1) > 0.0)
        # Sparse (a point hangs on a few bones): the product stays single-threaded, as fast as BLAS on an idle
        # machine and without its thread wake-ups on a busy one.
        self._W = sparse.csr_matrix(W[np.ix_(self.rows, moving)])
        self._x = np.ascontiguousarray(rest[self.rows])
        self._identity = np.hstack([np.eye(3), np.zeros((3, 1))])

    def skin(self, maps: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Skinned positions ``(N, 3)`` for the bone maps ``maps`` ``(B, 3, 4)``.

        Args:
            maps: one affine map per bone (rest -> posed).
            out: an ``(N, 3)`` array to write into (its rows outside the moving set are set to rest).

        Raises:
            ValueError: a wrong shape, or a bone outside ``moving_bones`` whose map is not the identity.
        """
        maps = np.asarray(maps, dtype=float)
        if maps.shape != (self.num_bones, 3, 4):
            raise ValueError(f"maps must have shape ({self.num_bones}, 3, 4), got {maps.shape}")
        if self._static.size and not np.allclose(maps[self._static], self._identity, atol=1e-12):
            raise ValueError("a bone outside moving_bones has a non-identity map")
        if out is None:
            out = self.rest.copy()
        else:
            out[:] = self.rest
        delta = (maps[self.moving_bones] - self._identity).reshape(len(self.moving_bones), 12)
        A = (self._W @ delta).reshape(-1, 3, 4)
        x = self._x
        out[self.rows] += A[:, :, 0] * x[:, 0:1] + A[:, :, 1] * x[:, 1:2] + A[:, :, 2] * x[:, 2:3] + A[:, :, 3]
        return out


def blend_affine(points: np.ndarray, weights: np.ndarray, maps: np.ndarray) -> np.ndarray:
    """All points through all bone maps at once (no moving-bone shortcut): ``(N, 3)``."""
    A = (np.asarray(weights, float) @ np.asarray(maps, float).reshape(len(maps), 12)).reshape(-1, 3, 4)
    return np.einsum("nij,nj->ni", A[:, :, :3], points) + A[:, :, 3]


def vtk_tetra_text(points: np.ndarray, tets: np.ndarray, title: str = "shell") -> str:
    """A legacy ASCII VTK unstructured grid of tetrahedra (what ``RegisterDeformableGeometry`` reads)."""
    lines = [
        "# vtk DataFile Version 3.0",
        title,
        "ASCII",
        "DATASET UNSTRUCTURED_GRID",
        f"POINTS {len(points)} double",
    ]
    lines += [f"{x:.9f} {y:.9f} {z:.9f}" for x, y, z in np.asarray(points, float)]
    lines.append(f"CELLS {len(tets)} {5 * len(tets)}")
    lines += [f"4 {a} {b} {c} {d}" for a, b, c, d in np.asarray(tets, int)]
    lines.append(f"CELL_TYPES {len(tets)}")
    lines += ["10"] * len(tets)
    return "\n".join(lines) + "\n"


def vertex_normals(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals ``(V, 3)`` (zero for a vertex no triangle uses)."""
    points = np.asarray(points, float)
    triangles = np.asarray(triangles, dtype=np.int64)
    P = points[triangles]
    face_n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    n = np.zeros_like(points)
    for k in range(3):
        np.add.at(n, triangles[:, k], face_n)
    return n / (np.linalg.norm(n, axis=1, keepdims=True) + 1e-15)


def prism_shell(points: np.ndarray, triangles: np.ndarray, depth: float = SHELL_DEPTH_M):
    """A tetrahedral layer under a surface: each triangle's prism down to an inner copy of the surface.

    The inner copy of vertex ``i`` is vertex ``V + i``, ``depth`` inside along the vertex normal. Each prism
    is cut into three tetrahedra, every quadrilateral side cut along the diagonal from its lowest-numbered
    vertex, so neighbouring prisms share whole faces: the boundary of the layer is the surface, its inner
    copy and, only where the surface itself has a border, the narrow side walls. Rendered, the surface
    vertices' normals therefore come from the surface's own triangles (no speckle), unlike
    :func:`tet_shell`, whose inner faces touch every surface vertex.

    Returns:
        ``(shell_points, tets)``: ``(2 V, 3)`` surface then inner vertices, ``(3 T, 4)`` positive tetrahedra.
    """
    points = np.asarray(points, float)
    tri = np.sort(np.asarray(triangles, dtype=np.int64), axis=1)  # a < b < c
    V = len(points)
    pts = np.vstack([points, points - depth * vertex_normals(points, triangles)])
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    tets = np.concatenate(
        [
            np.column_stack([a, b, c, c + V]),
            np.column_stack([a, b, b + V, c + V]),
            np.column_stack([a, a + V, b + V, c + V]),
        ]
    )
    p0, p1, p2, p3 = (pts[tets[:, i]] for i in range(4))
    flip = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), p3 - p0) < 0
    tets[flip] = tets[flip][:, [0, 2, 1, 3]]
    return pts, tets


def plane_section(points: np.ndarray, triangles: np.ndarray, origin, normal, radius: float | None = None) -> np.ndarray:
    """Where a triangle surface crosses a plane: ``(S, 2, 3)`` line segments.

    Args:
        points, triangles: the surface.
        origin, normal: a point of the plane and its normal.
        radius: keep only the segments whose midpoint lies within ``radius`` of ``origin`` (e.g. one limb's
            cross-section, not the torso's the same plane cuts); None: all.
    """
    P = np.asarray(points, float)
    tri = np.asarray(triangles, dtype=np.int64)
    o = np.asarray(origin, float)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    s = (P - o) @ n
    st = s[tri]
    pos = st > 0.0
    cut = pos.any(axis=1) & ~pos.all(axis=1)
    tri, st, pos = tri[cut], st[cut], pos[cut]
    # The lone vertex (on its own side of the plane) and the two edges from it that the plane crosses.
    lone = np.where(pos.sum(axis=1) == 1, np.argmax(pos, axis=1), np.argmin(pos, axis=1))
    rows = np.arange(len(tri))
    ends = []
    for k in (1, 2):
        other = (lone + k) % 3
        a, b = tri[rows, lone], tri[rows, other]
        sa, sb = st[rows, lone], st[rows, other]
        f = (sa / (sa - sb))[:, None]
        ends.append(P[a] + f * (P[b] - P[a]))
    seg = np.stack(ends, axis=1)
    if radius is not None:
        seg = seg[np.linalg.norm(seg.mean(axis=1) - o, axis=1) < radius]
    return seg


def section_centre(segments: np.ndarray) -> np.ndarray:
    """The centre of a cross-section's outline (``(S, 2, 3)`` segments): their length-weighted mean midpoint."""
    seg = np.asarray(segments, float)
    w = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1)
    if seg.size == 0 or not w.sum() > 0:
        raise ValueError("the plane does not cut the surface there")
    return (seg.mean(axis=1) * w[:, None]).sum(axis=0) / w.sum()


def limb_axis(points, triangles, start, end, fractions=(0.3, 0.4, 0.5, 0.6, 0.7), radius: float = 0.08):
    """The centre line of a limb of a surface, between two points on its length (e.g. two joint centres).

    The surface is cut by planes across the segment ``start -> end`` at ``fractions`` of its length; the line
    fitted (least squares) through the cross-sections' centres is the limb's axis.

    Returns:
        ``(point, direction)``: a point of the axis (the centres' mean) and its unit direction (pointing
        from ``start`` toward ``end``).
    """
    a, b = np.asarray(start, float), np.asarray(end, float)
    d = (b - a) / np.linalg.norm(b - a)
    centres = np.array(
        [section_centre(plane_section(points, triangles, a + f * (b - a), d, radius)) for f in fractions]
    )
    m = centres.mean(axis=0)
    axis = np.linalg.svd(centres - m)[2][0]
    return m, axis if axis @ d >= 0 else -axis


def distance_to_line(p, point, direction) -> float:
    """Distance from ``p`` to the line through ``point`` along the unit ``direction``."""
    r = np.asarray(p, float) - np.asarray(point, float)
    return float(np.linalg.norm(r - (r @ direction) * np.asarray(direction, float)))
