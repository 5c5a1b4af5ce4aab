"""The teleop diagram run as the demo runs it: 1 s of replayed (and rendered) frames, zero NaN commands."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akc_drake import faults, teleop
from akc_drake.config import CameraConfig, PipelineConfig
from akc_drake.core.frames import robot_targets
from akc_drake.core.skeleton import BodyDimensions
from akc_drake.diagrams import Measurements
from akc_drake.operator.motions import make_motion

# A small image keeps rendering cheap; everything else is the demo's default configuration.
CFG = PipelineConfig(camera=CameraConfig(width=160, height=120))
DIMS = BodyDimensions.paper_participant()
FRAMES = 10  # 1 s at 10 Hz


@pytest.fixture(scope="module")
def motion():
    return teleop.truncate_motion(make_motion("II", 1, 0), FRAMES + 1, CFG.camera.rate_hz)


@pytest.fixture(scope="module")
def session(motion):
    return teleop.render_motion(motion, CFG, seed=0)


@pytest.fixture(scope="module")
def akc_run(session, motion):
    """1 s of AKC(KF) teleoperation on the replayed rendering, recorded in Meshcat."""
    meshcat, err = teleop.make_meshcat()
    if meshcat is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    run, td = teleop.run_teleop(
        CFG,
        DIMS,
        corrector="AKC(KF)",
        replay=Measurements.from_session(session),
        motion=motion,
        num_frames=FRAMES,
        meshcat=meshcat,
    )
    if meshcat is not None:
        meshcat.StopRecording()
    return run, td, meshcat


def test_one_second_of_teleop_commands_no_nan(akc_run):
    run, td, _ = akc_run
    assert run.frames == FRAMES
    assert run.nan_commands == 0
    assert td.monitor.nan_commands == 0
    # The monitor sampled every IK period from t = 0 to the end (1.0005 s): 101 samples.
    assert td.monitor.samples == 101
    # The IK status was read once per IK update (t = 0, 0.01, ..., 1.0) for each arm.
    assert run.ik_steps == {"left": 101, "right": 101}
    assert 0 <= run.ik_failures["left"] <= 101 and 0 <= run.ik_failures["right"] <= 101
    assert sum(run.ik_failure_kinds.values()) == run.ik_failures["left"] + run.ik_failures["right"]
    # A step is a failure, driven by the position-only IK, by the joint-space move, or a full-pose solution.
    for side in teleop.SIDES:
        assert run.ik_failures[side] + run.ik_relaxed[side] + run.ik_joint_space[side] <= 101
    assert all(arm.approach is not None for arm in td.ik.values())
    # The commanded joints stayed within the joint guard's limits: speed ratio <= 1 (plus the QP's tolerance).
    assert 0.0 < run.max_speed_ratio <= 1.0 + 1e-6
    for side in teleop.SIDES:
        assert np.all(np.isfinite(run.ee[side]))
        assert np.all(np.isfinite(run.target[side]))
        # One monitor error sample per frame, at t_k + 0.09 s.
        np.testing.assert_allclose(run.error_t[side], 0.09 + 0.1 * np.arange(FRAMES), atol=1e-9)
        assert np.all(np.isfinite(run.errors[side])) and np.all(run.errors[side] < 1.5)


def test_per_frame_samples_agree_with_the_monitor(akc_run):
    run, _, _ = akc_run
    for side in teleop.SIDES:
        # The monitor's own distance and the one from the per-frame samples are the same numbers.
        d = np.linalg.norm(run.target[side][:, :3, 3] - run.ee[side], axis=1)
        np.testing.assert_allclose(d, run.errors[side], rtol=0, atol=1e-12)
        # Targets are proper rigid transforms.
        R = run.target[side][:, :3, :3]
        np.testing.assert_allclose(
            np.einsum("kji,kjl->kil", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-9
        )


def test_operator_targets_are_the_truth_through_the_mapping(akc_run, session):
    """The operator's true wrist through the same mapping and the same workspace clip as the targets."""
    run, td, _ = akc_run
    k = 7
    ws = td.mapper.tracker.workspace
    for side, X in zip(("left", "right"), robot_targets(session.truth[k], td.mapper.mapping), strict=True):
        X[:3, 3] = ws[side].clip(X[:3, 3])[0]
        np.testing.assert_allclose(run.operator[side][k], X, atol=1e-12)


def test_recording_covers_the_run(akc_run):
    _, _, meshcat = akc_run
    if meshcat is None:
        pytest.skip("Meshcat could not open a localhost port here")
    before = meshcat.StaticHtml()
    meshcat.PublishRecording()
    after = meshcat.StaticHtml()
    assert "<html" in after.lower()
    # The page now carries the animation: the robot's links and the skeletons at 64 frames per second.
    assert len(after) - len(before) > 20_000


def test_lost_tracking_holds_the_robot_without_nan(session, motion):
    """Blank frames 3-9 (no person): the mapper holds the last target; commands stay finite."""
    meas = Measurements.from_session(session)
    plan = faults.dropout_plan(meas.num_frames, [(3, meas.num_frames, "person")])
    mask = plan.frames
    run, td = teleop.run_teleop(
        CFG,
        DIMS,
        corrector="AKC(KF)",
        replay=faults.apply_dropouts(meas, plan),
        motion=motion,
        num_frames=FRAMES,
        dropout=mask,
    )
    assert run.nan_commands == 0
    assert run.tracking_lost_share > 0.3
    assert run.dropout.sum() == FRAMES - 3
    for side in teleop.SIDES:
        # Held target: the KF predicts for a while, then the target stops changing.
        X = run.target[side]
        np.testing.assert_allclose(X[-1], X[-2], atol=1e-12)


@pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # inf - inf in the frames
def test_garbage_measurements_never_reach_the_robot_as_nan(session, motion):
    """Inf, huge and NaN landmark values, and visibilities outside [0, 1]: the robot gets finite commands."""
    meas = Measurements.from_session(session)
    L = meas.landmarks_C.copy()
    L[2] = 1e6
    L[4, :6] = np.inf
    L[5, ::2] = np.nan
    V = meas.visibility.copy()
    V[6] = 7.0
    bad = Measurements(L, V, meas.pixels.copy(), meas.truth_C)
    for corrector in ("Raw", "KF"):
        run, _ = teleop.run_teleop(
            CFG, DIMS, corrector=corrector, replay=bad, motion=motion, num_frames=FRAMES
        )
        assert run.nan_commands == 0, corrector
        for side in teleop.SIDES:
            assert np.all(np.isfinite(run.ee[side]))


def test_rendered_run_matches_the_replay(akc_run, motion):
    """The camera rendered inside the diagram gives what the replay of render_session gave."""
    replayed, _, _ = akc_run
    n = 5
    run, td = teleop.run_teleop(CFG, DIMS, corrector="AKC(KF)", motion=motion, num_frames=n)
    assert run.rendered and run.frames == n
    assert run.nan_commands == 0
    assert math.isfinite(run.realtime_factor) and run.realtime_factor > 0
    for side in teleop.SIDES:
        np.testing.assert_allclose(run.target[side], replayed.target[side][:n], atol=1e-9)
        np.testing.assert_allclose(run.ee[side], replayed.ee[side][:n], atol=1e-9)


def test_ik_status_counter_counts_each_update_once_from_a_later_start(session, motion):
    meas = Measurements.from_session(session)
    run, td = teleop.run_teleop(
        CFG, DIMS, corrector="KF", replay=meas, motion=motion, num_frames=5, start_time=3.0
    )
    # IK updates at 3.00, 3.01, ..., 3.50.
    assert run.ik_steps == {"left": 51, "right": 51}
    np.testing.assert_allclose(run.error_t["left"], 0.09 + 0.1 * np.arange(5), atol=1e-9)
    assert run.nan_commands == 0


def test_run_teleop_rejects_bad_arguments(session):
    meas = Measurements.from_session(session)
    with pytest.raises(ValueError, match="AKC2"):
        teleop.run_teleop(CFG, DIMS, corrector="AKC2", replay=meas)
    with pytest.raises(ValueError, match="replay"):
        teleop.run_teleop(CFG, DIMS, corrector="KF")


def test_arm_limits_from_the_config_and_from_the_argument():
    """The config's ``arm_limits`` reach both limiters and the monitor; ``motion_limits`` given wins over them."""
    from akc_drake.config import ArmLimitsConfig
    from akc_drake.diagrams import build_teleop_diagram
    from akc_drake.robot.model import arm_motion_limits

    cfg = PipelineConfig(camera=CFG.camera, arm_limits=ArmLimitsConfig(acceleration=[5.0], jerk=[900.0]))
    td = build_teleop_diagram(cfg)
    for side in ("left", "right"):
        _, acc, jerk = td.ik[side].limiter.limits
        np.testing.assert_array_equal(acc, np.full(7, 5.0))
        np.testing.assert_array_equal(jerk, np.full(7, 900.0))
        np.testing.assert_array_equal(td.monitor.acceleration_limits[side], np.full(7, 5.0))
    td = build_teleop_diagram(cfg, motion_limits=True)
    np.testing.assert_array_equal(td.ik["left"].limiter.limits[1], arm_motion_limits("left")[0])
    td = build_teleop_diagram(PipelineConfig(camera=CFG.camera, arm_limits=ArmLimitsConfig(enabled=False)))
    assert td.ik["left"].limiter is None and td.ik["right"].limiter is None
    np.testing.assert_array_equal(td.monitor.acceleration_limits["right"], arm_motion_limits("right")[0])


def test_the_hand_detector_the_builder_made_is_closed_with_the_diagram():
    """Teleop on a camera's frames measures the hands with MediaPipe Hands; one the builder made is the diagram's
    to close (a pose detector passed in stays the caller's)."""
    from frame_sources import NoiseFrames

    from akc_drake import diagrams
    from akc_drake.errors import UserError
    from akc_drake.io import hand_detector as hd
    from akc_drake.io import mediapipe_detector as mpd

    try:
        mpd.find_pose_model()
        hd.find_hand_model()
    except UserError as e:
        pytest.skip(f"no MediaPipe model here: {e}")

    cfg = PipelineConfig(source="video:x", camera=CameraConfig(width=160, height=120, rate_hz=10.0))
    with mpd.MediaPipeDetector() as pose:
        with diagrams.build_teleop_diagram(cfg, frame_source=NoiseFrames(2), detector=pose, log_stages=False) as built:
            (hands,) = built.owned
            assert isinstance(hands, hd.HandDetector) and hands._landmarker is not None
        assert hands._landmarker is None and pose._landmarker is not None
