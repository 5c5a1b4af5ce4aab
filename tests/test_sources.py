"""Frame sources: recording folders, RGB video, and the --source parser."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.errors import SourceError, UserError
from akc_drake.io.recording import RecordingWriter
from akc_drake.io.sources import (
    FrameSource,
    RecordingSource,
    VideoSource,
    guess_intrinsics,
    open_source,
)

K = CameraIntrinsics(width=32, height=24, fx=30.0, fy=30.0, cx=15.5, cy=11.5, depth_scale=0.001, rate_hz=10.0)


@pytest.fixture
def rec(tmp_path):
    rng = np.random.default_rng(0)
    with RecordingWriter(tmp_path / "rec", K) as w:
        for i in range(4):
            w.write(
                0.1 * i,
                rng.integers(0, 256, (24, 32, 3), dtype=np.uint8),
                np.full((24, 32), 1.0 + 0.1 * i),
                np.full((NUM_LANDMARKS, 3), float(i)),
            )
    return tmp_path / "rec"


def test_recording_source(rec):
    src = RecordingSource(rec)
    assert isinstance(src, FrameSource)
    assert src.intrinsics == K and src.rate_hz == 10.0 and len(src) == 4
    frames = list(src)
    assert [f.t for f in frames] == [0.0, 0.1, 0.2, 0.30000000000000004]
    assert all(isinstance(f, CameraFrame) for f in frames)
    np.testing.assert_array_equal(frames[2].truth_C, np.full((NUM_LANDMARKS, 3), 2.0))
    np.testing.assert_allclose(frames[3].depth_m, 1.3, rtol=0, atol=1e-12)
    # iterating again replays from the start
    again = list(src)
    assert np.array_equal(again[0].color, frames[0].color)
    assert src.ground_truth()[2].shape == (4, NUM_LANDMARKS, 3)
    src.close()


def _write_video(path, fourcc, frames, fps=10.0, is_color=True):
    H, W = frames[0].shape[:2]
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (W, H), is_color)
    if not w.isOpened():
        pytest.skip(f"OpenCV cannot write {fourcc} here")
    for f in frames:
        w.write(f)
    w.release()


def _colour_frames(n, H=48, W=64):
    # flat colour blocks survive lossy codecs almost unchanged
    out = []
    for i in range(n):
        rgb = np.zeros((H, W, 3), np.uint8)
        rgb[:, : W // 2] = (200, 40 + 20 * i, 10)
        rgb[:, W // 2 :] = (20, 90, 220 - 20 * i)
        out.append(rgb)
    return out


@pytest.mark.parametrize("fourcc, ext", [("mp4v", ".mp4"), ("MJPG", ".avi")])
def test_video_source_reads_a_video(tmp_path, fourcc, ext):
    rgb = _colour_frames(5)
    path = tmp_path / f"v{ext}"
    _write_video(path, fourcc, [cv2.cvtColor(f, cv2.COLOR_RGB2BGR) for f in rgb], fps=12.0)
    with VideoSource(path, depth_m=1.8) as src:
        assert isinstance(src, FrameSource)
        assert src.rate_hz == pytest.approx(12.0)
        K = src.intrinsics
        assert (K.width, K.height) == (64, 48)
        # guessed intrinsics: 65 degrees horizontal field of view, centred principal point
        assert 2 * math.degrees(math.atan(32 / K.fx)) == pytest.approx(65.0)
        assert K.fx == K.fy and (K.cx, K.cy) == (31.5, 23.5)
        frames = list(src)
        again = list(src)
    assert len(frames) == 5 and len(again) == 5
    for i, (f, want) in enumerate(zip(frames, rgb, strict=True)):
        assert f.color.dtype == np.uint8 and f.color.shape == (48, 64, 3)
        # RGB order (not BGR): left half is red-dominant
        assert np.abs(f.color[10:40, 5:25].astype(int) - want[10:40, 5:25]).mean() < 6
        assert f.t == pytest.approx(i / 12.0)
        assert np.all(f.depth_m == 1.8)
    assert np.array_equal(frames[3].color, again[3].color)


def test_video_source_without_depth_has_no_depth(tmp_path):
    _write_video(tmp_path / "v.avi", "MJPG", _colour_frames(2))
    src = VideoSource(tmp_path / "v.avi")
    f = next(iter(src))
    assert f.depth_m.shape == (48, 64) and np.all(f.depth_m == 0)


def test_video_source_with_a_depth_video(tmp_path):
    _write_video(tmp_path / "c.avi", "MJPG", _colour_frames(3))
    levels = [50, 100, 150]  # grey levels: 1.0, 2.0, 3.0 m at 0.02 m per level
    grey = [np.full((48, 64), v, np.uint8) for v in levels]
    _write_video(tmp_path / "d.avi", "MJPG", grey, is_color=False)
    src = VideoSource(tmp_path / "c.avi", depth_video=tmp_path / "d.avi")
    frames = list(src)
    assert len(frames) == 3
    for f, v in zip(frames, levels, strict=True):
        np.testing.assert_allclose(f.depth_m[8:40, 8:56], v * 0.02, atol=0.05)
    # a shorter depth video is an error naming it
    _write_video(tmp_path / "short.avi", "MJPG", grey[:1], is_color=False)
    with pytest.raises(SourceError, match=r"short\.avi: ends at frame 1"):
        list(VideoSource(tmp_path / "c.avi", depth_video=tmp_path / "short.avi"))


def test_video_source_with_given_intrinsics(tmp_path):
    _write_video(tmp_path / "v.avi", "MJPG", _colour_frames(2))
    Kv = CameraIntrinsics(width=64, height=48, fx=50.0, fy=51.0, cx=30.0, cy=20.0, rate_hz=5.0)
    src = VideoSource(tmp_path / "v.avi", depth_m=2.0, intrinsics=Kv)
    assert src.intrinsics.fx == 50.0 and src.intrinsics.rate_hz == 10.0  # the video's own rate wins
    src = VideoSource(tmp_path / "v.avi", depth_m=2.0, intrinsics=Kv, rate_hz=5.0)
    assert src.intrinsics == Kv and [f.t for f in src] == [0.0, 0.2]
    with pytest.raises(UserError, match=r"v\.avi: video is 64x48 but the intrinsics are 32x24"):
        VideoSource(tmp_path / "v.avi", intrinsics=K)


def test_video_source_errors_name_the_file(tmp_path):
    with pytest.raises(UserError, match=r"nope\.mp4: video file not found"):
        VideoSource(tmp_path / "nope.mp4")
    (tmp_path / "text.mp4").write_text("not a video")
    with pytest.raises(UserError, match=r"text\.mp4: not a video OpenCV can read"):
        VideoSource(tmp_path / "text.mp4")
    _write_video(tmp_path / "v.avi", "MJPG", _colour_frames(1))
    with pytest.raises(UserError, match=r"--depth must be a distance in metres in \(0, 20\], got -1"):
        VideoSource(tmp_path / "v.avi", depth_m=-1.0)
    with pytest.raises(UserError, match="not both"):
        VideoSource(tmp_path / "v.avi", depth_m=1.0, depth_video=tmp_path / "v.avi")
    with pytest.raises(UserError, match=r"missing\.avi: video file not found"):
        VideoSource(tmp_path / "v.avi", depth_video=tmp_path / "missing.avi")


def test_guess_intrinsics():
    Kg = guess_intrinsics(640, 480, 10.0, hfov_deg=90.0)
    assert Kg.fx == pytest.approx(320.0) and Kg.fy == pytest.approx(320.0)
    assert (Kg.cx, Kg.cy) == (319.5, 239.5)
    with pytest.raises(ValueError, match="hfov_deg"):
        guess_intrinsics(640, 480, 10.0, hfov_deg=0.0)


def test_open_source(rec, tmp_path):
    assert open_source("sim") is None
    assert open_source(" sim ") is None
    src = open_source(f"recording:{rec}")
    assert isinstance(src, RecordingSource) and len(src) == 4
    _write_video(tmp_path / "v.avi", "MJPG", _colour_frames(2))
    v = open_source(f"video:{tmp_path / 'v.avi'}", depth_m=1.2, rate_hz=None)
    assert isinstance(v, VideoSource) and v.depth_m == 1.2


@pytest.mark.parametrize(
    "spec, pattern",
    [
        ("webcam", r"--source 'webcam': unknown source; expected one of sim, recording:DIR"),
        ("", r"--source: empty"),
        ("recording:", r"--source 'recording:': missing the path after 'recording:'"),
        ("recording:/no/such/dir", r"/no/such/dir: recording folder not found"),
        ("bag:/no/such.bag", r"/no/such\.bag: RealSense recording not found"),
        ("video:/no/such.mp4", r"/no/such\.mp4: video file not found"),
        ("sim:x", r"unknown source"),
    ],
)
def test_open_source_errors(spec, pattern):
    with pytest.raises(UserError, match=pattern):
        open_source(spec)


def test_open_source_option_checks(rec):
    with pytest.raises(UserError, match=r"depth_m \(--depth\) do not apply to a recording source"):
        open_source(f"recording:{rec}", depth_m=1.0)
    with pytest.raises(ValueError, match=r"unknown option\(s\) pose_model"):
        open_source(f"recording:{rec}", pose_model="x")


def test_realsense_without_a_camera_says_so():
    rs = pytest.importorskip("pyrealsense2", reason="pyrealsense2 not installed", exc_type=ImportError)
    if len(rs.context().query_devices()):
        pytest.skip("a RealSense camera is attached")
    with pytest.raises(SourceError, match=r"realsense: no RealSense camera found"):
        open_source("realsense")
    with pytest.raises(SourceError, match=r"no RealSense camera found"):
        open_source("realsense:12345", fps=15)
