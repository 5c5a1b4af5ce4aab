import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator

from akc_drake.core import frames as F
from akc_drake.core.skeleton import INDEX
from akc_drake.systems.frame_mapper import FrameMapper

PERIOD = 0.1
OFFSET = 4e-3  # timing.stage_offset("mapper") with the default 1 ms per stage
R_C_TORSO = np.column_stack([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def camera_pose(wrist_shift=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The operator's rest posture placed 2 m in front of the camera, facing it."""
    pose_T = F.rest_operator_pose()
    pose_T[INDEX["left_wrist"]] += wrist_shift
    return pose_T @ R_C_TORSO.T + np.array([0.0, -0.2, 2.0])


def _X(port, ctx) -> np.ndarray:
    return port.Eval(ctx).GetAsMatrix4()


def _sim(system):
    sim = Simulator(system)
    return sim, sim.get_mutable_context()


def test_ports():
    fm = FrameMapper()
    assert fm.num_input_ports() == 1 and fm.get_input_port(0).get_name() == "landmarks_C"
    assert fm.get_input_port(0).size() == 36
    names = [fm.get_output_port(i).get_name() for i in range(fm.num_output_ports())]
    assert names == ["X_TE_desired_left", "X_TE_desired_right", "tracking_lost", "workspace_clipped"]
    ctx = fm.CreateDefaultContext()
    assert isinstance(fm.GetOutputPort("X_TE_desired_left").Eval(ctx), RigidTransform)


def test_home_pose_before_the_first_valid_frame():
    home_l = RigidTransform(RollPitchYaw(0.1, 0.2, 0.3), [0.4, 0.25, -0.1])
    fm = FrameMapper(X_TE_home_left=home_l)
    sim, ctx = _sim(fm)
    fm.get_input_port(0).FixValue(ctx, np.full(36, np.nan))
    sim.AdvanceTo(0.25)
    np.testing.assert_allclose(
        _X(fm.GetOutputPort("X_TE_desired_left"), ctx), home_l.GetAsMatrix4(), atol=1e-15
    )
    np.testing.assert_allclose(
        _X(fm.GetOutputPort("X_TE_desired_right"), ctx), F.default_home_pose("right", fm.mapping), atol=1e-15
    )
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [1.0, 1.0])


def test_valid_frames_are_mapped_and_degenerate_frames_hold_and_raise_tracking_lost():
    fm = FrameMapper(period_s=PERIOD)
    sim, ctx = _sim(fm)
    pose0 = camera_pose()
    fm.get_input_port(0).FixValue(ctx, pose0.reshape(36))
    sim.AdvanceTo(OFFSET + 1e-4)
    XE_l, XE_r = F.robot_targets(pose0, fm.mapping)
    np.testing.assert_allclose(_X(fm.GetOutputPort("X_TE_desired_left"), ctx), XE_l, atol=1e-12)
    np.testing.assert_allclose(_X(fm.GetOutputPort("X_TE_desired_right"), ctx), XE_r, atol=1e-12)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [0.0, 0.0])
    # Known numbers: the rest posture's left target (see test_frames).
    s = 0.69 / 0.57
    np.testing.assert_allclose(XE_l[:3, 3], [s * 0.28, 0.20, -s * 0.288], atol=1e-3)

    # Next frame: left wrist missing, right arm moved. Left holds; right follows.
    pose1 = camera_pose()
    pose1[INDEX["left_wrist"]] = np.nan
    pose1[INDEX["right_wrist"]] += [0.0, -0.05, 0.0]  # camera -y = up
    fm.get_input_port(0).FixValue(ctx, pose1.reshape(36))
    sim.AdvanceTo(PERIOD + OFFSET + 1e-4)
    np.testing.assert_allclose(_X(fm.GetOutputPort("X_TE_desired_left"), ctx), XE_l, atol=1e-12)
    XE_r1 = _X(fm.GetOutputPort("X_TE_desired_right"), ctx)
    assert XE_r1[2, 3] - XE_r[2, 3] == pytest.approx(s * 0.05, abs=1e-9)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [1.0, 0.0])
    assert np.all(np.isfinite(XE_r1))

    # Degenerate torso (coincident shoulders): the last torso frame is held and the wrists still map.
    pose2 = camera_pose()
    pose2[INDEX["right_shoulder"]] = pose2[INDEX["left_shoulder"]]
    fm.get_input_port(0).FixValue(ctx, pose2.reshape(36))
    sim.AdvanceTo(2 * PERIOD + OFFSET + 1e-4)
    expected = F.robot_targets(pose2, fm.mapping, torso=F.torso_of(pose0))[1]
    np.testing.assert_allclose(_X(fm.GetOutputPort("X_TE_desired_right"), ctx), expected, atol=1e-12)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [0.0, 0.0])

    # Tracking recovers.
    fm.get_input_port(0).FixValue(ctx, camera_pose(wrist_shift=(0.1, 0.0, 0.0)).reshape(36))
    sim.AdvanceTo(3 * PERIOD + OFFSET + 1e-4)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [0.0, 0.0])
    assert _X(fm.GetOutputPort("X_TE_desired_left"), ctx)[0, 3] == pytest.approx(
        XE_l[0, 3] + s * 0.1, abs=1e-9
    )


def test_update_time_is_the_mapper_offset():
    fm = FrameMapper(period_s=PERIOD)
    sim, ctx = _sim(fm)
    fm.get_input_port(0).FixValue(ctx, camera_pose().reshape(36))
    sim.AdvanceTo(OFFSET - 5e-4)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [1.0, 1.0])
    sim.AdvanceTo(OFFSET + 5e-4)
    np.testing.assert_array_equal(fm.GetOutputPort("tracking_lost").Eval(ctx), [0.0, 0.0])


def test_bad_parameters():
    with pytest.raises(ValueError, match="X_TE_home_right"):
        FrameMapper(X_TE_home_right=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="X_TE_home_left.*rotation"):
        FrameMapper(X_TE_home_left=np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="period_s"):
        FrameMapper(period_s=-1.0)


def test_torso_smoothing_spreads_a_sudden_torso_yaw_over_time():
    """A shoulder whose depth jumps (a corrector switching mirror candidates) yaws eq. (17)'s torso frame in one
    frame: without smoothing the targets swing at once, with the One Euro torso filter only by part of it, and
    with the calibrated hip-borne torso not at all."""
    from akc_drake.core import smoothing as sm

    still = camera_pose()
    jumped = still.copy()
    jumped[INDEX["left_shoulder"], 2] += 0.15  # the left shoulder's depth jumps 15 cm away from the camera
    moved = {}
    torso = F.TorsoModel.calibrate(np.stack([still] * 5))
    for name, kwargs in (
        ("raw", {}),
        ("smoothed", {"torso_smoothing": sm.TORSO_SMOOTHING}),
        ("hips", {"torso_model": torso}),
    ):
        fm = FrameMapper(**kwargs)
        sim, ctx = _sim(fm)
        port = fm.get_input_port(0)
        port.FixValue(ctx, still.ravel())
        sim.AdvanceTo(OFFSET + 1e-4)
        X0 = _X(fm.GetOutputPort("X_TE_desired_right"), ctx)
        port.FixValue(ctx, jumped.ravel())
        sim.AdvanceTo(PERIOD + OFFSET + 1e-4)
        X1 = _X(fm.GetOutputPort("X_TE_desired_right"), ctx)
        moved[name] = float(np.linalg.norm(X1[:3, 3] - X0[:3, 3]))
    assert moved["raw"] > 0.05  # the right-hand target swings with the torso at once
    assert moved["smoothed"] < 0.5 * moved["raw"]
    assert moved["hips"] < 1e-9


def test_workspace_clip_is_reported():
    far = camera_pose(wrist_shift=(0.6, 0.0, 0.0))  # the left wrist 60 cm further forward
    ws = {s: F.Workspace.for_side(s) for s in ("left", "right")}
    fm = FrameMapper(workspace=ws)
    sim, ctx = _sim(fm)
    fm.get_input_port(0).FixValue(ctx, far.ravel())
    sim.AdvanceTo(OFFSET + 1e-4)
    X = _X(fm.GetOutputPort("X_TE_desired_left"), ctx)
    assert ws["left"].contains(X[:3, 3], tol=1e-6)
    assert np.linalg.norm(X[:3, 3] - ws["left"].shoulder) == pytest.approx(ws["left"].r_max)
    np.testing.assert_array_equal(fm.GetOutputPort("workspace_clipped").Eval(ctx), [1.0, 0.0])


def test_hand_knuckles_port_is_used_when_connected():
    """The optional hand_knuckles port (MediaPipe Hands): unconnected, the pose's hand points make the frame; fed
    a knuckle vector turned about the forearm, the wrist frame turns with it."""
    pose = camera_pose()
    plain = FrameMapper(period_s=PERIOD, robust_wrist=True)
    fm = FrameMapper(period_s=PERIOD, robust_wrist=True, hand_knuckles_input=True)
    assert fm.GetInputPort("hand_knuckles").size() == 6
    out = {}
    for name, system, knuckles in (("plain", plain, None), ("unconnected", fm, None), ("fed", fm, "turned")):
        sim, ctx = _sim(system)
        system.get_input_port(0).FixValue(ctx, pose.reshape(36))
        if knuckles is not None:
            kn = np.zeros((2, 3))
            for k, side in enumerate(("left", "right")):
                h = pose[INDEX[f"{side}_index"]] - pose[INDEX[f"{side}_pinky"]]
                kn[k] = np.array([h[1], -h[0], h[2]]) / pose[INDEX[f"{side}_wrist"], 2]  # 90 deg in the image
            system.GetInputPort("hand_knuckles").FixValue(ctx, kn.reshape(6))
        sim.AdvanceTo(0.05)
        out[name] = _X(system.GetOutputPort("X_TE_desired_left"), ctx)
    np.testing.assert_allclose(out["unconnected"], out["plain"], atol=1e-12)
    assert F.rotation_angle(out["plain"][:3, :3].T @ out["fed"][:3, :3]) > np.radians(20.0)
