"""``akc-drake calibrate``: T-/L-pose calibration through extractor -> occlusion filter -> KF, then --dims."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from akc_drake import cli
from akc_drake.commands.calibrate import MIN_VALID_FRAMES, min_valid_frames
from akc_drake.core.calibration import load_dims
from akc_drake.core.skeleton import BodyDimensions

TRUE = BodyDimensions.paper_participant().as_dict()  # the simulated operator


def _one_error_line(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"akc-drake {command}: error:")
    return err[0]


def test_min_valid_frames():
    assert min_valid_frames(100) == 50
    assert min_valid_frames(11) == 6
    assert min_valid_frames(10) == MIN_VALID_FRAMES


@pytest.mark.parametrize("pose", ["tpose", "lpose"])
def test_sim_calibration_recovers_the_operator(tmp_path, capsys, pose):
    out = tmp_path / "sub" / "dims.json"  # the folder is created
    rc = cli.main(["calibrate", "--source", "sim", "--pose", pose, "--frames", "20", "--out", str(out)])
    assert rc == 0
    dims = load_dims(out).as_dict()
    for name, value in dims.items():
        # the depth camera sees the body's surface, not the joint centres: about a centimetre short
        assert value == pytest.approx(TRUE[name], abs=0.02), name
    doc = json.loads(out.read_text())
    cal = doc["calibration"]
    assert cal["method"] == pose and cal["frames"] == 20 and cal["warnings"] == []
    assert all(v >= min_valid_frames(20) for v in cal["valid_frames"].values())
    lo, hi = (140, 180) if pose == "tpose" else (50, 130)
    assert all(lo <= a <= hi for a in cal["elbow_angle_deg"].values())
    printed = capsys.readouterr().out
    assert f"calibrated from 20 frames ({pose}, sim)" in printed and "true" in printed


def test_dims_from_calibrate_drive_run(tmp_path):
    dims = tmp_path / "dims.json"
    assert cli.main(["calibrate", "--source", "sim", "--frames", "10", "--out", str(dims)]) == 0
    out = tmp_path / "run.json"
    argv = ["run", "--source", "sim", "--dims", str(dims), "--seconds", "0.3", "--json", str(out)]
    assert cli.main(argv) == 0
    s = json.loads(out.read_text())
    assert s["dims"] == pytest.approx(load_dims(dims).as_dict())
    # AKC places the arms at the calibrated lengths
    with np.load(s["poses_npz"]) as z:
        c = z["corrected"][-1]
    assert np.linalg.norm(c[0] - c[2]) == pytest.approx(s["dims"]["LUA"], abs=1e-9)


def _blank_video(path, n=12):
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (96, 72))
    if not w.isOpened():
        pytest.skip("OpenCV cannot write MJPG here")
    for i in range(n):
        w.write(np.full((72, 96, 3), 80 + 5 * i, np.uint8))
    w.release()
    return path


def test_nobody_in_view_is_one_line_and_keeps_the_old_file(tmp_path, capsys):
    pytest.importorskip("mediapipe")
    video = _blank_video(tmp_path / "blank.avi")
    out = tmp_path / "dims.json"
    out.write_text("previous calibration\n")
    argv = ["calibrate", "--source", f"video:{video}", "--depth", "2", "--frames", "12", "--out", str(out)]
    rc = cli.main(argv)
    assert rc == 2
    line = _one_error_line(capsys, "calibrate")
    assert "too few valid frames" in line and "0 of 12 frames" in line
    assert out.read_text() == "previous calibration\n"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--frames", "3"], "--frames must be an integer of at least 10, got 3"),
        (["--source", "video:/no/such.mp4"], "/no/such.mp4: video file not found"),
        (["--source", "recording:/no/such/dir"], "/no/such/dir"),
        (["--config", "/no/such.yaml"], "/no/such.yaml: config file not found"),
    ],
)
def test_option_errors(tmp_path, capsys, argv, message):
    assert cli.main(["calibrate", "--out", str(tmp_path / "d.json"), *argv]) == 2
    assert message in _one_error_line(capsys, "calibrate")
    assert not (tmp_path / "d.json").exists()


def test_out_must_be_a_file(tmp_path, capsys):
    assert cli.main(["calibrate", "--source", "sim", "--out", str(tmp_path)]) == 2
    assert "is a folder" in _one_error_line(capsys, "calibrate")
