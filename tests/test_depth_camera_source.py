"""Stage S1 in simulation: the rendered operator with real self-occlusion, sampled at the camera rate."""

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from akc_drake.core.camera import CameraIntrinsics, project
from akc_drake.core.depth_noise import StereoDepthNoise
from akc_drake.core.sim_detector import SimulatedDetector
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams, arm_angles_from_directions
from akc_drake.operator.motions import OperatorMotion, make_motion, tpose
from akc_drake.systems.depth_camera_source import (
    CameraPlacement,
    DepthCameraSource,
    render_session,
)
from akc_drake.systems.landmark_extractor import AddLandmarkExtractor

SMALL = CameraIntrinsics(width=160, height=120, fx=153.75, fy=153.75, cx=79.5, cy=59.5)
MEDIUM = CameraIntrinsics(width=320, height=240, fx=307.5, fy=307.5, cx=159.5, cy=119.5)


def _static(q_left, q_right, seconds=0.5):
    t = np.array([0.0, seconds])
    return OperatorMotion(t, np.tile(q_left, (2, 1)), np.tile(q_right, (2, 1)), "static")


def _first_frame(motion, intrinsics=SMALL, **kwargs):
    """Outputs of a DepthCameraSource after its first sample (run in a Simulator)."""
    source = DepthCameraSource(motion, intrinsics=intrinsics, noise=StereoDepthNoise.ideal(), **kwargs)
    sim = Simulator(source)
    sim.AdvanceTo(0.01)
    ctx = sim.get_context()
    depth = source.GetOutputPort("depth_image").Eval(ctx).data[:, :, 0].copy()
    truth = source.GetOutputPort("landmarks_true_C").Eval(ctx).reshape(NUM_LANDMARKS, 3)
    return source, ctx, depth, truth


def _at(image, uv):
    return image[int(round(uv[1])), int(round(uv[0]))]


def test_t_pose_elbow_pixel_reads_the_elbows_own_surface():
    params = OperatorParams()
    source, ctx, depth, truth = _first_frame(tpose(1.0, sway_deg=0.0))
    for side in ("left", "right"):
        e = INDEX[f"{side}_elbow"]
        uv = project(truth[e], SMALL)
        assert _at(depth, uv) == pytest.approx(truth[e, 2] - params.upper_arm_radius, abs=0.003)
    label = source.GetOutputPort("label_image").Eval(ctx).data[:, :, 0]
    names = source.body_names_by_label()
    assert names[int(_at(label, project(truth[INDEX["left_elbow"]], SMALL)))] in (
        "left_upper_arm",
        "left_forearm",
    )
    assert names[int(_at(label, project(truth[INDEX["right_shoulder"]], SMALL)))] == "right_upper_arm"


def _forearm_at_camera(params):
    placement = CameraPlacement()
    elbow_O = params.shoulder_O("left") + [0.0, params.dims.LUA, 0.0]
    to_camera = placement.position_O() - elbow_O
    q_left = arm_angles_from_directions("left", [[0.0, 1.0, 0.0]], [to_camera])[0]
    return _first_frame(_static(q_left, np.zeros(NUM_ARM_DOF)), camera_pose=placement, params=params)


def test_forearm_pointing_at_the_camera_hides_the_elbow_behind_the_hand():
    """Real occlusion from the render, not injected: the elbow's pixel reads the near end of its own hand
    (with a straight wrist, the hand a rigid extension of the forearm)."""
    params = OperatorParams(wrist_extension_deg=0.0)
    source, ctx, depth, truth = _forearm_at_camera(params)
    e, w = INDEX["left_elbow"], INDEX["left_wrist"]
    uv_e, uv_w = project(truth[e], SMALL), project(truth[w], SMALL)
    assert np.linalg.norm(uv_e - uv_w) < 0.5  # the wrist is right in front of the elbow
    d_elbow, d_wrist = _at(depth, uv_e), _at(depth, uv_w)
    assert d_elbow == pytest.approx(d_wrist, abs=0.003)  # the elbow reads what the wrist reads ...
    # ... the near end of the hand, lf + hand length in front of the elbow along the ray:
    dist = np.linalg.norm(truth[e])
    expected = truth[e, 2] * (dist - params.dims.LLA - params.hand_length) / dist
    assert d_elbow == pytest.approx(expected, abs=0.004)
    assert truth[e, 2] - d_elbow > 0.4  # raw elbow depth off by more than 40 cm
    assert truth[w, 2] - d_wrist > 0.15  # and the wrist reads the fingertips


def test_natural_wrist_posture_lets_the_wrist_pixel_see_the_wrist():
    """With the default wrist extension the hand tilts out of the forearm's line: the wrist's pixel sees the
    wrist and the base of the palm (a few cm in front of the joint centre), while the elbow stays hidden."""
    params = OperatorParams()
    assert params.wrist_extension_deg > 0
    source, ctx, depth, truth = _forearm_at_camera(params)
    e, w = INDEX["left_elbow"], INDEX["left_wrist"]
    d_elbow, d_wrist = _at(depth, project(truth[e], SMALL)), _at(depth, project(truth[w], SMALL))
    assert 0.02 < truth[w, 2] - d_wrist < 0.06
    assert truth[e, 2] - d_elbow > params.dims.LLA  # the elbow still reads its own wrist region


def test_motion_II_shoulder_depth_is_wrong_while_x_y_stay_close():
    session = render_session(make_motion("II", 1, 0), MEDIUM, seed=0)
    assert session.raw.shape == (61, NUM_LANDMARKS, 3) and session.truth.shape == (61, NUM_LANDMARKS, 3)
    for side in ("left", "right"):
        s = INDEX[f"{side}_shoulder"]
        err = session.raw[:, s] - session.truth[:, s]
        assert np.mean(np.abs(err[:, 2]) > 0.10) > 0.6
        # Once the arms are up (the first cycle starts from a T-pose), the shoulder is hidden throughout.
        assert np.mean(np.abs(err[session.t >= 2.5, 2]) > 0.10) > 0.9
        assert np.all(np.abs(err[:3, 2]) < 0.10)  # in the T-pose the shoulder is seen
        median_z = np.nanmedian(np.abs(err[:, 2]))
        for axis in (0, 1):
            assert np.nanmedian(np.abs(err[:, axis])) < min(0.05, median_z / 4)
    # The hips, never occluded, are measured well.
    h = INDEX["left_hip"]
    assert np.nanmedian(np.abs(session.raw[:, h] - session.truth[:, h])) < 0.1


def test_diagram_and_render_session_give_the_same_measurements():
    motion = make_motion("I", 1, 3)
    builder = DiagramBuilder()
    source = builder.AddSystem(DepthCameraSource(motion, intrinsics=SMALL, seed=2))
    extractor = AddLandmarkExtractor(builder, source, SimulatedDetector(seed=2))
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    session = render_session(motion, SMALL, seed=2)
    ext_ctx = extractor.GetMyContextFromRoot(ctx)
    for k in range(4):
        sim.AdvanceTo(0.1 * k + 0.05)
        np.testing.assert_array_equal(
            extractor.GetOutputPort("landmarks_C").Eval(ext_ctx), session.raw[k].ravel()
        )
        np.testing.assert_array_equal(
            extractor.GetOutputPort("visibility").Eval(ext_ctx), session.visibility[k]
        )
        np.testing.assert_allclose(
            source.GetOutputPort("landmarks_true_C").Eval(source.GetMyContextFromRoot(ctx)),
            session.truth[k].ravel(),
            atol=1e-12,
        )


def test_outputs_are_held_between_frames_and_truth_matches_the_motion():
    motion = make_motion("I", 1, 0)
    source = DepthCameraSource(motion, intrinsics=SMALL, render_label=False)
    sim = Simulator(source)
    ctx = sim.get_context()
    port = source.GetOutputPort("depth_image")
    sim.AdvanceTo(1.02)
    a = port.Eval(ctx).data.copy()
    truth_a = source.GetOutputPort("landmarks_true_C").Eval(ctx).copy()
    sim.AdvanceTo(1.09)
    np.testing.assert_array_equal(port.Eval(ctx).data, a)
    sim.AdvanceTo(1.11)
    assert np.any(port.Eval(ctx).data != a)
    # The truth of the frame taken at t = 1.0 s, in the camera frame.
    lm_O = motion.landmarks_O([1.0])[0]
    X_CO = source.X_OC.inverse()
    np.testing.assert_allclose(truth_a.reshape(12, 3), np.array([X_CO @ p for p in lm_O]), atol=1e-12)
    assert source.GetOutputPort("camera_info").Eval(ctx) == SMALL
    assert np.all(source.GetOutputPort("label_image").Eval(ctx).data == 0)  # labels not rendered
    names = [source.get_output_port(i).get_name() for i in range(source.num_output_ports())]
    assert sorted(names) == sorted(
        ["color_image", "depth_image", "label_image", "camera_info", "landmarks_true_C"]
    )


def test_noise_is_applied_and_reproducible():
    motion = tpose(1.0, sway_deg=0.0)
    ideal = _first_frame(motion)[2]

    def noisy(seed):
        source = DepthCameraSource(motion, intrinsics=SMALL, seed=seed, render_label=False)
        sim = Simulator(source)
        sim.AdvanceTo(0.01)
        return source.GetOutputPort("depth_image").Eval(sim.get_context()).data[:, :, 0].copy()

    a, b, c = noisy(1), noisy(1), noisy(2)
    np.testing.assert_array_equal(a, b)
    both = (a > 0) & (c > 0)
    assert np.any(a[both] != c[both])
    on_body = (a > 0) & (ideal > 0) & (ideal < 2.5)
    diff = a[on_body] - ideal[on_body]
    sigma = StereoDepthNoise().sigma_z(2.0, SMALL.fx)
    assert np.std(diff) == pytest.approx(sigma, rel=0.3)
    assert np.count_nonzero((a == 0) & (ideal > 0)) > 0  # edge pixels invalid


def test_camera_pose_and_motion_are_checked_and_a_rigid_transform_is_taken_as_is():
    X = CameraPlacement(lateral_m=0.1).X_OC()
    with pytest.raises(ValueError, match="camera_pose"):
        DepthCameraSource(tpose(1.0), camera_pose="front")
    with pytest.raises(ValueError, match="OperatorMotion"):
        DepthCameraSource("II")
    with pytest.raises(ValueError, match="body must be one of"):
        DepthCameraSource(tpose(1.0), body="robot")
    source = DepthCameraSource(tpose(1.0), intrinsics=SMALL, camera_pose=RigidTransform(X.GetAsMatrix4()))
    np.testing.assert_allclose(source.X_OC.GetAsMatrix4(), X.GetAsMatrix4())


def test_render_session_callbacks_and_colour():
    motion = _static(np.zeros(NUM_ARM_DOF), np.zeros(NUM_ARM_DOF), seconds=0.3)
    calls, frames = [], []
    session = render_session(
        motion,
        SMALL,
        seed=0,
        progress=lambda k, n: calls.append((k, n)),
        frame_callback=lambda f: frames.append(f.color.copy()),
    )
    assert calls == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert len(frames) == 4 and frames[0].shape == (120, 160, 3) and frames[0].any()
    assert session.render_s.shape == (4,) and np.all(session.source_time_s > 0)
    np.testing.assert_allclose(session.t, [0.0, 0.1, 0.2, 0.3])
    # Without a frame callback the simulated detector needs no colour: a black image is passed instead.
    seen = []

    class Spy(SimulatedDetector):
        def detect(self, frame):
            seen.append(frame.color.any())
            return super().detect(frame)

    render_session(motion, SMALL, detector=Spy())
    assert seen == [False] * 4


def test_frames_given_to_the_callback_can_be_kept():
    kept = []
    session = render_session(make_motion("I", 1, 0), SMALL, seed=1, frame_callback=kept.append)
    assert len(kept) == len(session.t) == 61
    # Each kept frame still shows its own moment (the arms move between 0 s and 3 s).
    assert np.any(kept[0].color != kept[30].color)
    assert np.any(kept[0].depth_m != kept[30].depth_m)
    np.testing.assert_array_equal(kept[30].truth_C, session.truth[30])
    assert kept[30].t == pytest.approx(3.0)


def test_pipeline_config_builds_the_described_camera():
    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.systems.depth_camera_source import add_sim_camera_source, intrinsics_from_config

    cam = CameraConfig(width=160, height=120, fov_x_deg=69.0, rate_hz=5.0, distance_m=1.8, height_m=0.35)
    K = intrinsics_from_config(cam)
    assert K.fx == pytest.approx(80.0 / np.tan(np.radians(34.5))) and K.fy == K.fx
    assert (K.width, K.height, K.cx, K.cy, K.rate_hz) == (160, 120, 79.5, 59.5, 5.0)
    builder = DiagramBuilder()
    source, K2, n = add_sim_camera_source(builder, PipelineConfig(motion="tpose", cycles=1, camera=cam))
    assert K2 == K and n == 51  # 10 s at 5 Hz
    sim = Simulator(builder.Build())
    sim.AdvanceTo(0.01)
    truth = source.GetOutputPort("landmarks_true_C").Eval(source.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_allclose(truth.reshape(12, 3)[INDEX["left_hip"]], [0.09, 0.35, 1.8], atol=1e-12)
    with pytest.raises(ValueError, match="fov_x_deg"):
        intrinsics_from_config(CameraConfig(fov_x_deg=0.0))
    # Placed to the operator's left and above, aimed at the chest (the config's camera, as `evaluate --camera`).
    placed = CameraConfig(width=160, height=120, distance_m=2.5, height_m=1.1, lateral_m=0.5, aim_height_m=0.45)
    source, _, _ = add_sim_camera_source(DiagramBuilder(), PipelineConfig(motion="tpose", cycles=1, camera=placed))
    from akc_drake.systems.camera_scene import CameraPlacement

    assert source.X_OC.IsExactlyEqualTo(CameraPlacement.facing_operator(2.5, 1.1, 0.5, 0.45).X_OC())


def test_surface_to_centre_correction_removes_the_t_pose_depth_bias():
    """In a T-pose nothing is occluded: the raw depth of each joint is its surface, short by the body's
    half-thickness; the extractor's default correction brings it back to the joint centre."""
    motion = tpose(0.4, sway_deg=0.0)
    idx = [INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_elbow", "left_wrist", "left_hip")]
    off = render_session(motion, MEDIUM, noise=StereoDepthNoise.ideal(), surface_offset_m=0)
    on = render_session(motion, MEDIUM, noise=StereoDepthNoise.ideal())
    bias_off = (off.raw - off.truth)[:, idx, 2]
    bias_on = (on.raw - on.truth)[:, idx, 2]
    assert np.all(bias_off < -0.025)  # surfaces 2.5-10 cm in front of the joint centres
    assert np.all(np.abs(bias_on) < 0.015)  # corrected to within 1.5 cm
    np.testing.assert_array_equal(on.pixels, off.pixels)
