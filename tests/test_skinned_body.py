"""SkinnedBody and the skinned operator in the camera source: vertices on SceneGraph, truth, renders."""

import numpy as np
import pytest
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform

from akc_drake.core.camera import CameraIntrinsics, project
from akc_drake.core.depth_noise import StereoDepthNoise
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.operator.motions import make_motion, tpose
from akc_drake.operator.skinned import skinned_operator
from akc_drake.systems.depth_camera_source import DepthCameraSource
from akc_drake.systems.skinned_body import SkinnedBody, register_skinned_body

SMALL = CameraIntrinsics(width=160, height=120, fx=153.75, fy=153.75, cx=79.5, cy=59.5)


@pytest.fixture(scope="module")
def body():
    return skinned_operator()


def test_outputs_the_shell_vertices_and_the_truth(body):
    sg = SceneGraph()
    _, ids = register_skinned_body(sg, body)
    X_WO = RigidTransform([0.0, 0.0, 1.0])
    sys_ = SkinnedBody(body, ids, X_WO)
    ctx = sys_.CreateDefaultContext()
    q = make_motion("I", 1, 0).q()[25]
    sys_.get_input_port().FixValue(ctx, q)
    config = sys_.get_output_port(0).Eval(ctx)
    for name, gid in ids.items():
        v = np.asarray(config.value(gid)).reshape(-1, 3)
        assert v.shape == (len(body.regions[name][0]), 3)
    skin = np.asarray(config.value(ids["skin"])).reshape(-1, 3)
    assert np.allclose(skin, body.posed_points(q)[body.regions["skin"][0]] + [0, 0, 1.0], atol=1e-12)
    truth = sys_.get_output_port(1).Eval(ctx).reshape(NUM_LANDMARKS, 3)
    assert np.allclose(truth, body.landmarks_O(q[None])[0] + [0, 0, 1.0], atol=1e-12)


def _render(motion, K, t=0.0):
    src = DepthCameraSource(motion, intrinsics=K, body="skinned", render_label=False, noise=StereoDepthNoise.ideal())
    ctx = src.CreateDefaultContext()
    ctx.SetTime(t)
    sc = src.sensor.GetMyContextFromRoot(ctx)
    rgb = np.asarray(src.sensor.color_image_output_port().Eval(sc).data)[:, :, :3].copy()
    depth = np.asarray(src.sensor.depth_image_32F_output_port().Eval(sc).data)[:, :, 0].copy()
    truth = src.truth_system.get_output_port().Eval(src.truth_system.GetMyContextFromRoot(ctx))
    return rgb, depth, truth.reshape(NUM_LANDMARKS, 3)


def test_a_render_shows_the_body_where_the_truth_projects():
    rgb, depth, truth = _render(tpose(1.0), SMALL)
    for name in ("left_shoulder", "right_shoulder", "left_elbow", "right_wrist", "left_hip"):
        u, v = np.round(project(truth[INDEX[name]], SMALL)).astype(int)
        # The body's surface, a few cm in front of the joint centre, not the wall 1.5 m behind.
        assert 0.0 < truth[INDEX[name], 2] - depth[v, u] < 0.12, name
    assert depth[5, 5] > 3.0  # the wall
    # Shirt blue on the chest, skin on the forearm.
    c = np.round(project(0.5 * (truth[INDEX["left_shoulder"]] + truth[INDEX["right_hip"]]), SMALL)).astype(int)
    r, g, b = rgb[c[1], c[0]].astype(int)
    assert b > r + 30
    f = np.round(project(0.5 * (truth[INDEX["left_elbow"]] + truth[INDEX["left_wrist"]]), SMALL)).astype(int)
    r, g, b = rgb[f[1], f[0]].astype(int)
    assert r > b + 30


def test_mediapipe_finds_the_rendered_tpose_within_10_px():
    pytest.importorskip("mediapipe")
    from akc_drake.core.camera import CameraFrame
    from akc_drake.io.mediapipe_detector import MediaPipeDetector

    K = CameraIntrinsics()
    rgb, depth, truth = _render(tpose(1.0), K)
    with MediaPipeDetector() as det:
        d = det.detect(CameraFrame(color=rgb, depth_m=depth, t=0.0, intrinsics=K))
    assert d.person_found
    arm = [INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("shoulder", "elbow", "wrist")]
    err = np.linalg.norm(d.uv[arm] - np.array([project(truth[j], K) for j in arm]), axis=1)
    assert np.all(err < 10.0), err


def test_shells_have_the_illustration_role_only_when_asked(body):
    for illustration in (False, True):
        sg = SceneGraph()
        _, ids = register_skinned_body(sg, body, illustration=illustration)
        inspector = sg.model_inspector()
        for gid in ids.values():
            assert inspector.GetPerceptionProperties(gid) is not None
            assert (inspector.GetIllustrationProperties(gid) is not None) == illustration


def test_a_mediapipe_session_does_not_render_labels():
    from akc_drake.io.mediapipe_detector import MediaPipeDetector
    from akc_drake.systems.depth_camera_source import images_needed

    # images_needed reads the class attributes: no MediaPipe model needs to load.
    assert images_needed(MediaPipeDetector) == (True, False)
