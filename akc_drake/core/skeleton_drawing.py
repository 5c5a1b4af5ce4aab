"""The geometry of a drawn skeleton (numpy): which bones, each bone's frame, where the skeleton stands.

:class:`akc_drake.systems.skeleton_visualizer.SkeletonVisualizer` draws with it in Meshcat. A bone is a
unit-length cylinder along its frame's z axis, centred between its two joints and scaled to its length.
The skeletons stand beside the robot, facing the way it faces, mirrored as the teleop mapping is: the
camera frame C is turned by :data:`R_WC_FACING_X` (the operator's forward, -z_C, is world +x, left, +x_C,
world +y and up, -y_C, world +z) and placed so that the hip midpoint of the first frame that shows both
hips stands at :data:`SKELETON_HIPS_W`.
"""

from __future__ import annotations

import numpy as np

from akc_drake.core.skeleton import INDEX

#: Bones drawn, as pairs of landmark names.
BONES: tuple[tuple[str, str], ...] = (
    ("left_shoulder", "right_shoulder"),
    ("left_shoulder", "left_elbow"),
    ("left_elbow", "left_wrist"),
    ("right_shoulder", "right_elbow"),
    ("right_elbow", "right_wrist"),
    ("left_wrist", "left_index"),
    ("left_wrist", "left_pinky"),
    ("right_wrist", "right_index"),
    ("right_wrist", "right_pinky"),
    ("left_shoulder", "left_hip"),
    ("right_shoulder", "right_hip"),
    ("left_hip", "right_hip"),
)
#: ``(len(BONES), 2)`` landmark indices of each bone's ends.
BONE_INDEX = np.array([[INDEX[a], INDEX[b]] for a, b in BONES])

#: Where the skeletons' hip midpoint is placed (world, metres): 1.4 m to the robot's left, 0.95 m up.
SKELETON_HIPS_W = (-0.1, 1.4, 0.95)
#: Rotation of the camera frame C in the world for the skeletons (operator facing world +x, upright).
R_WC_FACING_X = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def bone_frame(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The frame of a bone from joint ``a`` to joint ``b``.

    Returns:
        ``(R, centre, length)``: a rotation whose z column points from ``a`` to ``b`` (x and y complete it;
        the cylinder is symmetric about z), the midpoint and the distance; None when an end is not finite
        or the ends coincide (within 1e-9 m).
    """
    d = b - a
    L = float(np.linalg.norm(d))
    if not np.isfinite(L) or L < 1e-9:
        return None
    z = d / L
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z]), 0.5 * (a + b), L


def anchor_position(P: np.ndarray) -> np.ndarray | None:
    """Where C must stand in the world (turned by :data:`R_WC_FACING_X`) so that the hip midpoint of the
    ``(12, 3)`` pose ``P`` (camera frame) is at :data:`SKELETON_HIPS_W`; None unless both hips are finite."""
    hips = P[[INDEX["left_hip"], INDEX["right_hip"]]]
    if not np.all(np.isfinite(hips)):
        return None
    return np.asarray(SKELETON_HIPS_W) - R_WC_FACING_X @ hips.mean(axis=0)
