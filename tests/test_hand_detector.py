"""MediaPipe Hands on the rendered skinned operator (akc_drake.io.hand_detector): the gripper follows the hand."""

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, project
from akc_drake.core.gripper import GripperHysteresis
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.io import hand_detector as hd

pytest.importorskip("mediapipe", reason="the 'mediapipe' extra is not installed")


def test_a_missing_model_file_is_one_line_naming_it(tmp_path):
    bad = tmp_path / "nope.task"
    with pytest.raises(UserError) as e:
        hd.HandDetector(model_path=bad)
    msg = str(e.value)
    assert str(bad) in msg and "--hand-model" in msg and "\n" not in msg
    junk = tmp_path / "junk.task"
    junk.write_bytes(b"not a model")
    with pytest.raises(UserError, match="cannot load the MediaPipe hand model"):
        hd.HandDetector(model_path=junk)


def test_the_demo_rejects_a_bad_hand_model_with_exit_2(tmp_path, capsys):
    from akc_drake.cli import main

    code = main(["demo", "--task", "pick-place", "--hand-model", str(tmp_path / "missing.task")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "missing.task" in err


@pytest.fixture(scope="module")
def renders():
    """The pick-and-place operator (skinned, hands following the motion) at 5.5 s (right hand open, reaching)
    and 8 s (right hand pinching, lifting): colour, depth, the true landmarks in C and the true apertures."""
    try:
        model = hd.find_hand_model()
    except UserError as e:
        pytest.skip(f"no hand model here: {e}")
    from akc_drake.config import PipelineConfig
    from akc_drake.diagrams import sim_camera
    from akc_drake.operator.motions import pick_place
    from akc_drake.systems.depth_camera_source import DepthCameraSource
    from akc_drake.systems.skinned_body import hands_follow

    K, placement, noise = sim_camera(PipelineConfig())
    motion = pick_place(0)
    with hands_follow(motion):
        src = DepthCameraSource(motion, intrinsics=K, camera_pose=placement, noise=noise, seed=0, body="skinned",
                                render_label=False)
    ctx = src.CreateDefaultContext()
    sc, nc = src.sensor.GetMyContextFromRoot(ctx), src.noise_system.GetMyContextFromRoot(ctx)
    tc = src.truth_system.GetMyContextFromRoot(ctx)
    out = {}
    for name, t in (("open", 5.5), ("closed", 8.0)):
        ctx.SetTime(t)
        rgb = np.ascontiguousarray(src.sensor.color_image_output_port().Eval(sc).data[:, :, :3])
        depth = src.noise_system.get_output_port().Eval(nc).data[:, :, 0].copy()
        truth = src.truth_system.get_output_port().Eval(tc).reshape(NUM_LANDMARKS, 3)
        ap = src.skinned.pinch_aperture(motion.closure([motion.start + t])[0])
        out[name] = (CameraFrame(color=rgb, depth_m=depth, t=t, intrinsics=K), truth, ap)
    with hd.HandDetector(model) as det:
        yield det, out


def test_the_gripper_closes_on_the_closed_rendered_hand_and_opens_on_the_open_one(renders):
    det, frames = renders
    h = GripperHysteresis()
    state, measured = False, {}
    for name in ("open", "closed", "open"):
        frame, _, truth_ap = frames[name]
        m = det.detect(frame)
        assert m.found[1], name
        measured[name] = m.aperture_m[1]
        # within 2 cm of the true thumb-index distance (12.7 cm open, 1.5 cm pinched)
        assert abs(m.aperture_m[1] - truth_ap[1]) < 0.02, (name, m.aperture_m[1], truth_ap[1])
        state = h.step(state, m.aperture_m[1])
        assert state == (name == "closed"), name
    assert measured["open"] > h.open_above_m and measured["closed"] < h.close_below_m


def test_the_hands_are_the_operators_own_sides(renders):
    """MediaPipe's handedness on an unmirrored render is the person's own: the hand called right is at the true
    right wrist; the pose's wrists, given swapped, swap them."""
    det, frames = renders
    frame, truth, _ = frames["closed"]
    K = frame.intrinsics
    wrists = np.array([project(truth[INDEX[f"{s}_wrist"]], K) for s in ("left", "right")])
    m = det.detect(frame)
    assert m.found.all()
    for s in range(2):
        assert np.linalg.norm(m.landmarks_px[s, 0, :2] - wrists[s]) < 30.0, s
        assert np.linalg.norm(m.landmarks_px[s, 0, :2] - wrists[1 - s]) > 60.0, s
    swapped = det.detect(frame, wrists[::-1])
    np.testing.assert_array_equal(swapped.landmarks_px[0], m.landmarks_px[1])
    assert swapped.aperture_m[0] == m.aperture_m[1]
