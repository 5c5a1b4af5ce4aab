"""SkeletonVisualizer: bones and joints drawn in Meshcat, missing ones hidden, transforms recorded for StaticHtml."""

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from akc_drake.core.skeleton import INDEX
from akc_drake.systems.skeleton_visualizer import BONES, _bone_pose, default_X_WC


@pytest.fixture(scope="module")
def meshcat():
    return Meshcat()


def test_bone_pose_puts_a_unit_cylinder_between_the_joints():
    a, b = np.array([0.1, 0.2, 2.0]), np.array([0.1, 0.5, 2.4])
    X, L = _bone_pose(a, b)
    assert L == pytest.approx(0.5)
    np.testing.assert_allclose(X.translation(), 0.5 * (a + b))
    # The cylinder's axis (z) points from a to b.
    np.testing.assert_allclose(X.rotation().matrix()[:, 2], (b - a) / 0.5, atol=1e-12)
    assert _bone_pose(a, a) is None and _bone_pose(a, np.full(3, np.nan)) is None


def test_default_camera_pose_shows_the_operator_upright():
    X = default_X_WC()
    R = X.rotation().matrix()
    np.testing.assert_allclose(R @ [0.0, -1.0, 0.0], [0.0, 0.0, 1.0])  # camera "up" (-y_C) is world up
    np.testing.assert_allclose(R @ [0.0, 0.0, -1.0], [1.0, 0.0, 0.0])  # the operator faces world +x


def test_publishes_skeletons_and_records_them(meshcat):
    from akc_drake.systems.skeleton_visualizer import SkeletonVisualizer

    pose = np.tile([0.0, 0.0, 2.0], (12, 1)) + 0.1 * np.arange(36).reshape(12, 3)
    pose[INDEX["right_elbow"]] = np.nan
    builder = DiagramBuilder()
    vis = builder.AddSystem(SkeletonVisualizer(meshcat, X_WC=RigidTransform(), prefix="/test_skeleton"))
    for k in range(2):
        src = builder.AddSystem(ConstantVectorSource(pose.ravel()))
        builder.Connect(src.get_output_port(), vis.get_input_port(k))
    meshcat.StartRecording(set_visualizations_while_recording=True)
    Simulator(builder.Build()).AdvanceTo(0.25)
    meshcat.StopRecording()
    for name in ("raw", "corrected"):
        for b in range(len(BONES)):
            assert meshcat.HasPath(f"/test_skeleton/{name}/bone{b}")
    # Frames were recorded at 0.005 s, 0.105 s and 0.205 s (the publish offset and period).
    assert meshcat.get_mutable_recording().frame(0.205) > meshcat.get_mutable_recording().frame(0.005)
    # A bone with both ends present got a transform; the "visible" property was set on every bone.
    assert len(meshcat._GetPackedTransform("/test_skeleton/corrected/bone0")) > 0
    right_upper_arm = BONES.index(("right_shoulder", "right_elbow"))
    assert len(meshcat._GetPackedProperty(f"/test_skeleton/raw/bone{right_upper_arm}", "visible")) > 0
