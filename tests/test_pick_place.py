"""The pick-and-place task: the operator's motion reaches the box through the mapping, the scoring, and a run
with ground-truth landmarks (no detector noise, no corrector) that picks the box up and places it."""

import numpy as np
import pytest

from akc_drake.core.frames import calibrated_mapping, robot_targets
from akc_drake.operator.model import OperatorParams
from akc_drake.operator.motions import PICK_BOX_T, PLACE_TARGET_T, make_motion, pick_place
from akc_drake.teleop.task import score_box


@pytest.fixture(scope="module")
def motion():
    return pick_place(0, mapping=calibrated_mapping(OperatorParams().dims))


def test_motion_puts_the_robot_tool_on_the_box_and_the_target(motion):
    mapping = calibrated_mapping(OperatorParams().dims)
    P = motion.landmarks_O()
    closed = motion.hand_closed[:, 1]
    first_closed = int(np.argmax(closed > 0.5))
    last_closed = len(closed) - 1 - int(np.argmax(closed[::-1] > 0.5))
    tool_at_grasp = robot_targets(P[first_closed], mapping)[1][:3, 3]
    tool_at_release = robot_targets(P[last_closed], mapping)[1][:3, 3]
    # The operator's mapped wrist on the box's centre (within 1.5 cm: the wrist posture is the hand's own).
    assert np.linalg.norm(tool_at_grasp - PICK_BOX_T) < 0.015
    assert np.linalg.norm(tool_at_release[:2] - np.asarray(PLACE_TARGET_T)[:2]) < 0.015
    assert np.all(motion.hand_closed[:, 0] == 0.0)  # the left hand stays open
    assert make_motion("pick-place", 1, 0).name == "pick-place"


def test_score_box():
    X = np.eye(4)
    X[:3, 3] = [0.55, -0.39, 0.745]
    ok = score_box(X, [0.55, -0.40, 0.745], [0.55, -0.15, 0.745], ("table",))
    assert ok.success and ok.released and ok.upright and ok.box_error_cm == pytest.approx(1.0)
    held = score_box(X, [0.55, -0.40, 0.745], [0.55, -0.15, 0.745], ("gripper_right_left_finger_link", "table"))
    assert not held.success and not held.released
    far = X.copy()
    far[:3, 3] = [0.55, -0.35, 0.745]
    assert not score_box(far, [0.55, -0.40, 0.745], [0.55, -0.15, 0.745], ("table",)).success
    tilted = X.copy()
    tilted[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.5), -np.sin(0.5)], [0.0, np.sin(0.5), np.cos(0.5)]])
    assert not score_box(tilted, [0.55, -0.40, 0.745], [0.55, -0.15, 0.745], ("table",)).upright


def test_grasp_report_is_the_tool_against_the_box_when_the_hand_begins_to_close():
    from akc_drake.teleop.task import grasp_report

    t = np.arange(0.0, 2.0, 0.02)
    box = np.tile([0.55, -0.15, -0.355], (len(t), 1))
    box[t >= 1.0, 0] += 0.07  # pushed 7 cm forward at 1 s
    tool = box + np.array([-0.05, 0.01, 0.02])
    r = grasp_report(t, tool, box, 1.5)
    np.testing.assert_allclose(r["grasp_tool_minus_box_cm"], [-5.0, 1.0, 2.0], atol=1e-9)
    assert r["box_moved_before_grasp_cm"] == pytest.approx(7.0)
    assert grasp_report(t, tool, box, 0.5)["box_moved_before_grasp_cm"] == pytest.approx(0.0)
    assert grasp_report(t, tool, box, float("inf")) == {}  # no grasp
    assert grasp_report(t, tool, np.full_like(box, np.nan), 1.5) == {}  # no box seen


def test_pick_and_place_with_ground_truth_landmarks_succeeds(motion):
    from akc_drake.config import PipelineConfig
    from akc_drake.core.frames import TorsoModel
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import Measurements
    from akc_drake.teleop import scenario as sc
    from akc_drake.teleop.task import SETTLE_S, _world_from_T

    cfg = PipelineConfig().validate()
    session = sc.render_motion(motion, cfg)
    truth = Measurements(session.truth, np.ones(session.truth.shape[:2]), session.pixels, session.truth)
    run, _ = sc.run_teleop(
        cfg,
        BodyDimensions.paper_participant(),
        corrector="Raw",
        replay=truth,
        motion=motion,
        torso_model=TorsoModel.calibrate(session.truth[:5]),
        settle_s=SETTLE_S,
    )
    out = score_box(run.box_pose, _world_from_T(PLACE_TARGET_T), _world_from_T(PICK_BOX_T), run.box_contacts)
    assert out.moved and out.released and out.upright
    assert out.success, out
    assert out.box_error_cm < 2.0


def test_hand_recorder_keeps_the_apertures_and_the_knuckle_vectors():
    from types import SimpleNamespace

    from akc_drake.core.camera import CameraIntrinsics
    from akc_drake.io.hand_detector import HandMeasurement
    from akc_drake.teleop.task import HandRecorder

    K = CameraIntrinsics()
    hands = np.full((2, 21, 3), np.nan)
    hands[1, 5], hands[1, 17] = [330.0, 200.0, -4.0], [300.0, 210.0, 2.0]  # the right hand's two knuckles
    found = HandMeasurement(aperture_m=np.array([np.nan, 0.02]), found=np.array([False, True]), landmarks_px=hands,
                            score=np.array([0.0, 0.9]))
    detector = SimpleNamespace(detect=lambda frame, wrists: found)
    rec = HandRecorder(detector)
    rec(SimpleNamespace(intrinsics=K))
    rec(SimpleNamespace(intrinsics=K))
    np.testing.assert_allclose(rec.apertures, [[np.nan, 0.02]] * 2)
    kn = rec.knuckles
    assert kn.shape == (2, 2, 3)
    assert np.all(np.isnan(kn[:, 0]))  # no left hand
    np.testing.assert_allclose(kn[0, 1], [30.0 / K.fx, -10.0 / K.fy, -6.0 / K.fx])


def test_the_closed_loop_run_is_recorded_on_its_own_meshcat_page(monkeypatch):
    """The closed loop renders its operator on the simulation's clock, so its recorded run gets a Meshcat of its
    own, recorded from time 0 (the run itself is stubbed here: only the recording's plumbing is tested)."""
    from pydrake.geometry import Box, Meshcat

    from akc_drake.teleop import task

    seen = {}

    def fake_run(*args):
        meshcat = args[-1]
        seen["meshcat"] = meshcat
        meshcat.SetObject("/drake/box_seen", Box(0.05, 0.05, 0.05))
        return "run", "diagram"

    monkeypatch.setattr(task, "_closed_loop_run", fake_run)
    run, td, html = task._recorded_closed_loop_run("cfg", "calib")
    assert (run, td) == ("run", "diagram") and isinstance(seen["meshcat"], Meshcat)
    assert html is not None and "<html" in html.lower() and len(html) > 1000
