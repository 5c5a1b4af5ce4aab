"""Real input on the command line: a real video of a person, bag -> recording conversion, and every source's
error path (missing file, wrong format, no device, missing model) as one clear line and exit code 2.

The "real video of a person" is built from scikit-image's astronaut photograph (a real photo of a person) with
small per-frame shifts and zoom, written with ``cv2.VideoWriter``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import cv2
import numpy as np
import pytest

pytest.importorskip("mediapipe")
skimage_data = pytest.importorskip("skimage.data")

from akc_drake import cli  # noqa: E402
from akc_drake.core.camera import CameraFrame  # noqa: E402
from akc_drake.io.mediapipe_detector import find_pose_model  # noqa: E402
from akc_drake.io.recording import RecordingReader  # noqa: E402
from akc_drake.io.sources import guess_intrinsics  # noqa: E402

try:
    find_pose_model()
except Exception as e:  # noqa: BLE001
    pytest.skip(f"no MediaPipe pose model here: {e}", allow_module_level=True)


def astronaut_frames(n, width=640, height=480):
    """``n`` RGB frames of the astronaut photo, shifted and zoomed a little from frame to frame."""
    img = skimage_data.astronaut()  # 512 x 512 RGB
    k = width / 640.0
    out = []
    for i in range(n):
        s = (0.85 + 0.05 * np.sin(2 * np.pi * i / 25)) * k
        dx = (64 + 12 * np.sin(2 * np.pi * i / 17)) * k
        dy = (-20 + 6 * np.cos(2 * np.pi * i / 13)) * k
        M = np.array([[s, 0.0, dx], [0.0, s, dy]])
        out.append(cv2.warpAffine(img, M, (width, height), borderMode=cv2.BORDER_REPLICATE))
    return out


def write_video(path, frames, fps=10.0):
    H, W = frames[0].shape[:2]
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (W, H))
    if not w.isOpened():
        pytest.skip("OpenCV cannot write mp4v here")
    for f in frames:
        w.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    w.release()
    return path


def akc(*argv, cwd):
    env = {k: v for k, v in os.environ.items() if k != "AKC_DRAKE_NATIVE_LOGS"}
    # A native crash (one SIGSEGV of ``record --source bag:`` seen once on a loaded machine, not reproduced in 21
    # runs) then prints the Python stack of every thread into the stderr that the failing assertion shows.
    env["PYTHONFAULTHANDLER"] = "1"
    return subprocess.run(
        [sys.executable, "-m", "akc_drake.cli", *argv], cwd=cwd, env=env, capture_output=True, text=True,
        timeout=300,
    )


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("real")
    write_video(d / "person.mp4", astronaut_frames(20))
    (d / "notvideo.mp4").write_text("this is not a video\n")
    (d / "junk.bag").write_bytes(b"\x00junk" * 100)
    (d / "junk.task").write_bytes(b"not a model")
    (d / "notes.txt").write_text("hello\n")
    (d / "empty_recording").mkdir()
    return d


def test_run_on_a_real_video_of_a_person(files, tmp_path):
    """Done-when: ``akc-drake run --source video:FILE --depth 2.0 --json out.json`` finds the person."""
    out = tmp_path / "out.json"
    video = files / "person.mp4"
    p = akc("run", "--source", f"video:{video}", "--depth", "2.0", "--json", str(out), cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert "Traceback" not in p.stderr and "W0000" not in p.stderr  # MediaPipe's native log lines are hidden
    s = json.loads(out.read_text())
    assert s["frames"] == 20 and s["stop_reason"] == "source ended" and s["detector"] == "mediapipe"
    assert s["frames_with_person"] >= 16  # a person in most frames
    assert s["config"]["width"] == 640 and s["config"]["rate_hz"] == 10.0
    # the astronaut's face and shoulders are in view
    for name in ("left_shoulder", "right_shoulder"):
        assert s["visibility_mean"][name] > 0.9 and s["visible_share"][name] >= 0.8
    lat = s["latency_ms"]
    stages = ("source", "detector", "depth_deprojection", "occlusion_filter", "filter", "corrector")
    stages += ("end_to_end",)
    for k in stages:
        assert lat[k]["frames"] == 20 and 0 <= lat[k]["median"] <= lat[k]["max"], k
    with np.load(s["poses_npz"]) as z:
        raw = z["raw"]
    found = np.isfinite(raw[:, 0]).all(axis=1) & np.isfinite(raw[:, 1]).all(axis=1)
    assert found.sum() >= 16
    # constant depth 2 m; the person faces the camera, so their left shoulder is on the image's right (+x)
    np.testing.assert_allclose(raw[found, :2, 2], 2.0)
    assert np.all(raw[found, 0, 0] > raw[found, 1, 0])
    assert "dims" in s and s["dims_origin"].startswith("paper manual")


def _bag(path, n=8):
    from akc_drake.io.realsense import write_db3

    K = guess_intrinsics(320, 240, 10.0)
    ramp = np.linspace(1.9, 2.1, 320)[None, :] * np.ones((240, 1))
    frames = [CameraFrame(c, ramp, 0.1 * i, K) for i, c in enumerate(astronaut_frames(n, 320, 240))]
    write_db3(path, frames, K)
    return path, frames


def test_bag_to_recording_and_run_on_both(tmp_path):
    pytest.importorskip("pyrealsense2")
    bag, frames = _bag(tmp_path / "session.db3")
    rec = tmp_path / "rec"
    p = akc("record", "--source", f"bag:{bag}", "--out", str(rec), cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    r = RecordingReader(rec)
    assert len(r) == len(frames)
    for i in (0, len(frames) - 1):
        np.testing.assert_array_equal(r[i].color, frames[i].color)
        np.testing.assert_allclose(r[i].depth_m, frames[i].depth_m, atol=r.intrinsics.depth_scale)
    np.testing.assert_allclose(r.timestamps, 0.1 * np.arange(len(frames)), atol=1e-6)

    summaries = {}
    for name, spec in (("bag", f"bag:{bag}"), ("recording", f"recording:{rec}")):
        out = tmp_path / name / "s.json"
        assert cli.main(["run", "--source", spec, "--json", str(out)]) == 0
        summaries[name] = json.loads(out.read_text())
    for s in summaries.values():
        assert s["frames"] == len(frames) and s["frames_with_person"] >= len(frames) - 2
    raws = [np.load(s["poses_npz"])["raw"] for s in summaries.values()]
    # the converted recording gives the pipeline the same frames as the bag
    np.testing.assert_allclose(raws[0], raws[1], atol=1e-9, equal_nan=True)
    z = raws[0][:, 0, 2]  # left shoulder depth, from the 1.9-2.1 m ramp
    z = z[np.isfinite(z)]
    assert z.size >= len(frames) - 2 and np.all((z > 1.85) & (z < 2.15))


def _no_realsense_attached() -> bool:
    try:
        import pyrealsense2 as rs

        return len(rs.context().query_devices()) == 0
    except Exception:  # noqa: BLE001
        return True


VIDEO = "video:{d}/person.mp4"
ERRORS = [
    (["run", "--source", "video:{d}/missing.mp4"], "missing.mp4: video file not found"),
    (["run", "--source", "video:{d}/notvideo.mp4"], "notvideo.mp4: not a video OpenCV can read"),
    (["run", "--source", "bag:{d}/missing.bag"], "missing.bag: RealSense recording not found"),
    (["run", "--source", "bag:{d}/junk.bag"], "junk.bag: not a readable RealSense recording"),
    (["run", "--source", "bag:{d}/notes.txt"], "notes.txt: expected a RealSense .bag or .db3 file"),
    (["run", "--source", "recording:{d}/missing"], "missing: recording folder not found"),
    (["run", "--source", "recording:{d}/empty_recording"], "intrinsics.json: missing"),
    (["run", "--source", VIDEO, "--pose-model", "{d}/missing.task"], "pose model file not found"),
    (["run", "--source", VIDEO, "--pose-model", "{d}/junk.task"], "cannot load the MediaPipe"),
    (["run", "--source", VIDEO, "--dims", "{d}/missing.json"], "missing.json: no such file"),
    (["run", "--source", "webcam"], "unknown source"),
    (["calibrate", "--source", "bag:{d}/junk.bag", "--out", "{d}/dims.json"], "not a readable RealSense"),
    (["record", "--source", "bag:{d}/missing.bag", "--out", "{d}/rec"], "RealSense recording not found"),
    (["run", "--source", "realsense", "--seconds", "1"], "no RealSense camera found"),
    (["record", "--source", "realsense", "--seconds", "1", "--out", "{d}/rec"], "no RealSense camera found"),
]


@pytest.mark.parametrize("argv, message", ERRORS, ids=[" ".join(a).replace("{d}/", "") for a, _ in ERRORS])
def test_source_errors_are_one_line_and_exit_2(files, argv, message):
    if "realsense" in argv and not _no_realsense_attached():
        pytest.skip("a RealSense camera is attached")
    argv = [a.format(d=files) for a in argv]
    p = akc(*argv, cwd=files)
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert lines[0].startswith(f"akc-drake {argv[0]}: error: ") and message in lines[0]
    assert not (files / "rec").exists() and not (files / "dims.json").exists()
