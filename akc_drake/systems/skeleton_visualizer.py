"""Draws the operator's skeleton in Meshcat: raw measurements in red, the corrected pose in blue (paper Fig. 1).

The skeletons stand beside the robot, facing the way it faces, mirrored as the teleop mapping is (the operator's
left arm, which drives the robot's left arm, is on the robot's left): the camera frame C is turned so that the
operator's forward (-z_C) is world +x, left (+x_C) world +y and up (-y_C) world +z, and placed so that the hip
midpoint of the first frame that shows both hips stands at :data:`SKELETON_HIPS_W` (to the robot's left, at a
person's hip height). Later frames move with the operator. The geometry (bones, bone frames, the anchor) is
:mod:`akc_drake.core.skeleton_drawing`.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Cylinder, Meshcat, Rgba, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import LeafSystem

from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.core.skeleton_drawing import (
    BONE_INDEX,
    BONES,
    R_WC_FACING_X,
    SKELETON_HIPS_W,
    anchor_position,
    bone_frame,
)

RED = Rgba(0.85, 0.15, 0.15, 1.0)
BLUE = Rgba(0.15, 0.35, 0.9, 1.0)


def default_X_WC(distance_m: float = 1.8, height_m: float = 1.3, y_m: float = 1.2) -> RigidTransform:
    """A camera pose that shows the operator upright, facing world +x, standing at (0, y_m, 0) in Meshcat.

    The camera frame C is x right, y down, z forward; the operator faces the camera (-z_C).
    """
    return RigidTransform(RotationMatrix(R_WC_FACING_X), [distance_m, y_m, height_m])


def _bone_pose(a: np.ndarray, b: np.ndarray) -> tuple[RigidTransform, float] | None:
    """The pose of a bone's unit cylinder and its length (:func:`~akc_drake.core.skeleton_drawing.bone_frame`)."""
    frame = bone_frame(a, b)
    if frame is None:
        return None
    R, centre, L = frame
    return RigidTransform(RotationMatrix(R), centre), L


class SkeletonVisualizer(LeafSystem):
    """Publishes skeletons (one per input port) to Meshcat at the camera rate, recordable for StaticHtml.

    .. pydrake_system::

        name: SkeletonVisualizer
        input_ports:
        - landmarks_C_raw
        - landmarks_C_corrected
        output_ports: []

    Each bone is a unit-length cylinder scaled along its axis; a bone whose ends are missing (NaN) is hidden.
    When the Meshcat is recording, the transforms are also saved in the animation, so the exported HTML
    replays the skeletons with the robot.

    Args:
        meshcat: the Meshcat instance.
        X_WC: pose of the camera frame C in the Meshcat world; None (the default): turned as
            :data:`R_WC_FACING_X` and placed on the first frame with both hips (see the module docstring).
        period_s: publish period (the camera period).
        offset_s: publish offset after the camera's sample time.
        prefix: Meshcat path under which the skeletons are drawn.
    """

    def __init__(
        self,
        meshcat: Meshcat,
        X_WC: RigidTransform | None = None,
        period_s: float = 0.1,
        offset_s: float = 0.005,
        prefix: str = "/operator",
        radius: float = 0.012,
    ):
        super().__init__()
        self._meshcat = meshcat
        self._X_WC = X_WC  # None until the first frame with both hips, when it is not given
        self._prefix = prefix
        self._names = ("raw", "corrected")
        colors = (RED, BLUE)
        for name in self._names:
            self.DeclareVectorInputPort(f"landmarks_C_{name}", 3 * NUM_LANDMARKS)
        for name, rgba in zip(self._names, colors, strict=True):
            for k in range(len(BONES)):
                meshcat.SetObject(f"{prefix}/{name}/bone{k}", Cylinder(radius, 1.0), rgba)
            for j in range(NUM_LANDMARKS):
                meshcat.SetObject(f"{prefix}/{name}/joint{j}", Sphere(1.6 * radius), rgba)
        if self._X_WC is not None:
            meshcat.SetTransform(prefix, self._X_WC)
        else:
            meshcat.SetProperty(prefix, "visible", False)
        self.DeclarePeriodicPublishEvent(period_s, offset_s, self._publish)

    def _anchor(self, P: np.ndarray, t: float) -> bool:
        """Place the skeletons on the first pose with both hips; False while there is none yet."""
        if self._X_WC is not None:
            return True
        p_WC = anchor_position(P)
        if p_WC is None:
            return False
        self._X_WC = RigidTransform(RotationMatrix(R_WC_FACING_X), p_WC)
        self._meshcat.SetTransform(self._prefix, self._X_WC, t)
        self._meshcat.SetProperty(self._prefix, "visible", True, t)
        return True

    def _publish(self, context):
        t = context.get_time()
        # Every call passes time_in_recording = t: Meshcat ignores it unless a recording was started.
        for k, name in enumerate(self._names):
            port = self.get_input_port(k)
            if not port.HasValue(context):
                continue
            P = np.asarray(port.Eval(context)).reshape(NUM_LANDMARKS, 3)
            if not self._anchor(P, t):
                continue
            base = f"{self._prefix}/{name}"
            for b, (i, j) in enumerate(BONE_INDEX):
                path = f"{base}/bone{b}"
                pose = _bone_pose(P[i], P[j])
                if pose is None:
                    self._meshcat.SetProperty(path, "visible", False, t)
                    continue
                X, L = pose
                self._meshcat.SetProperty(path, "visible", True, t)
                self._meshcat.SetTransform(path, X, t)
                self._meshcat.SetProperty(path, "scale", [1.0, 1.0, L], t)
            for j in range(NUM_LANDMARKS):
                path = f"{base}/joint{j}"
                ok = bool(np.isfinite(P[j]).all())
                self._meshcat.SetProperty(path, "visible", ok, t)
                if ok:
                    self._meshcat.SetTransform(path, RigidTransform(P[j]), t)


__all__ = ["BLUE", "BONES", "R_WC_FACING_X", "RED", "SKELETON_HIPS_W", "SkeletonVisualizer", "default_X_WC"]
