"""systems/camera_scene.py: camera placement and the helpers that build the simulated camera's scene."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams
from akc_drake.operator.motions import tpose
from akc_drake.systems import camera_scene as scene

SMALL = CameraIntrinsics(width=160, height=120, fx=153.75, fy=153.75, cx=79.5, cy=59.5)


def test_camera_placement():
    X = scene.CameraPlacement().X_OC()
    R = X.rotation().matrix()
    np.testing.assert_allclose(R[:, 2], [-1, 0, 0], atol=1e-12)  # optical axis along -x of O
    np.testing.assert_allclose(R[:, 0], [0, 1, 0], atol=1e-12)  # image right = the operator's left
    np.testing.assert_allclose(R[:, 1], [0, 0, -1], atol=1e-12)  # image down = down
    np.testing.assert_array_equal(X.translation(), [2.0, 0.0, 0.45])
    tilted = scene.CameraPlacement(distance_m=1.5, height_m=1.0, look_at_O=(0.0, 0.0, 0.3)).X_OC()
    np.testing.assert_allclose(tilted.rotation().matrix()[:, 2], np.array([-1.5, 0.0, -0.7]) / np.hypot(1.5, 0.7))
    with pytest.raises(ValueError, match="distance_m"):
        scene.CameraPlacement(distance_m=0.1)
    with pytest.raises(ValueError, match="height_m must be a finite number"):
        scene.CameraPlacement(height_m=float("nan"))
    with pytest.raises(ValueError, match="look_at_O"):
        scene.CameraPlacement(look_at_O=(2.0, 0.0, 0.45)).X_OC()
    with pytest.raises(ValueError, match="vertical"):
        scene.CameraPlacement(look_at_O=(2.0, 0.0, -1.0)).X_OC()


def test_a_camera_facing_the_operator():
    # The default placement, however given, is the default camera exactly (its renders and cache keys unchanged).
    assert scene.CameraPlacement.facing_operator() == scene.CameraPlacement()
    assert scene.CameraPlacement.facing_operator(2.0, 0.45, 0.0, 0.45) == scene.CameraPlacement()
    # To the operator's left (+y of O), level: the optical axis passes through the pelvis' vertical axis.
    side = scene.CameraPlacement.facing_operator(2.2, 0.45, 1.0).X_OC()
    axis = side.rotation().matrix()[:, 2]
    np.testing.assert_allclose(axis, np.array([-2.2, -1.0, 0.0]) / np.hypot(2.2, 1.0), atol=1e-12)
    np.testing.assert_allclose(side.rotation().matrix()[:, 1] @ [0, 0, 1], -1.0, atol=1e-12)  # image down = down
    # From above, aimed at the chest.
    high = scene.CameraPlacement.facing_operator(2.5, 1.1, 0.0, 0.45)
    assert high.look_at_O == (0.0, 0.0, 0.45)
    down = np.array([-2.5, 0.0, -0.65]) / np.hypot(2.5, 0.65)
    np.testing.assert_allclose(high.X_OC().rotation().matrix()[:, 2], down, atol=1e-12)


def test_camera_pose_forms():
    X = scene.CameraPlacement(lateral_m=0.2).X_OC()
    assert scene.as_X_OC(None).IsExactlyEqualTo(scene.CameraPlacement().X_OC())
    assert scene.as_X_OC(scene.CameraPlacement(lateral_m=0.2)).IsExactlyEqualTo(X)
    assert scene.as_X_OC(X) is X
    assert scene.as_X_OC(X.GetAsMatrix4()).IsExactlyEqualTo(X)
    for bad in ("front", np.eye(3), np.full((4, 4), np.nan)):
        with pytest.raises(ValueError, match="camera_pose must be"):
            scene.as_X_OC(bad)


def test_body_names_and_config_intrinsics():
    assert scene.BODIES == ("primitive", "skinned") and scene.check_body("skinned") == "skinned"
    with pytest.raises(ValueError, match="body must be one of primitive, skinned, got 'robot'"):
        scene.check_body("robot")
    from akc_drake.config import CameraConfig

    K = scene.intrinsics_from_config(CameraConfig(width=160, height=120, fov_x_deg=90.0, rate_hz=5.0))
    assert K.fx == pytest.approx(80.0) and K.fy == K.fx and (K.cx, K.cy, K.rate_hz) == (79.5, 59.5, 5.0)
    with pytest.raises(ValueError, match="fov_x_deg must be in \\(1, 179\\)"):
        scene.intrinsics_from_config(CameraConfig(fov_x_deg=180.0))


def _scene(camera_pose, wall=1.5):
    builder = DiagramBuilder()
    sg, plant, instance, skinned = scene.make_operator_scene(builder, OperatorParams(), "primitive", tpose(1.0), wall)
    q = builder.AddSystem(ConstantVectorSource(np.zeros(2 * NUM_ARM_DOF)))
    assert scene.connect_operator_pose(builder, sg, plant, instance, skinned, q.get_output_port()) is None
    sensor = scene.add_rgbd_sensor(builder, sg, SMALL, camera_pose)
    truth = builder.AddSystem(ConstantVectorSource(np.arange(36.0)))
    scene.export_held_outputs(builder, SMALL, 0.1, 0.0, sensor, sensor.depth_image_32F_output_port(),
                        truth.get_output_port(), render_color=False, render_label=True)
    diagram = builder.Build()
    before = diagram.CreateDefaultContext()
    np.testing.assert_array_equal(diagram.GetOutputPort("landmarks_true_C").Eval(before), np.zeros(36))
    sim = Simulator(diagram)
    sim.AdvanceTo(0.01)  # the holds sample at t = 0
    return diagram, sim.get_context(), plant, instance


def test_scene_renders_the_wall_and_the_operator_at_their_distances():
    # Looking along -x from 3 m to the operator's left: the operator is out of view, the wall's front face
    # (x = -1.5 + 0.025) is 2 + 1.475 m away at the image centre.
    side = scene.CameraPlacement(distance_m=2.0, lateral_m=3.0).X_OC()
    diagram, ctx, plant, instance = _scene(side)
    names = [diagram.get_output_port(i).get_name() for i in range(diagram.num_output_ports())]
    assert names == ["color_image", "depth_image", "label_image", "camera_info", "landmarks_true_C"]
    assert diagram.GetOutputPort("camera_info").Eval(ctx) == SMALL
    np.testing.assert_array_equal(diagram.GetOutputPort("landmarks_true_C").Eval(ctx), np.arange(36.0))
    depth = diagram.GetOutputPort("depth_image").Eval(ctx).data[:, :, 0]
    assert depth[60, 80] == pytest.approx(3.475, abs=1e-5)
    assert not diagram.GetOutputPort("color_image").Eval(ctx).data.any()  # not rendered: black
    assert "torso" in {plant.get_body(i).name() for i in plant.GetBodyIndices(instance)}
    # Straight on, the operator's torso is nearer than the wall; without the wall the background is empty.
    diagram, ctx, _, _ = _scene(scene.CameraPlacement().X_OC(), wall=None)
    depth = diagram.GetOutputPort("depth_image").Eval(ctx).data[:, :, 0]
    assert 1.7 < depth[60, 80] < 2.0 and np.isinf(depth[5, 2])
