"""``akc-drake record``: a rendered session written as a recording folder that reloads bit-exact."""

from pathlib import Path

import numpy as np
import pytest

from akc_drake.cli import main
from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import LANDMARKS
from akc_drake.io.recording import RecordingReader, depth_to_units, units_to_depth
from akc_drake.operator.motions import make_motion
from akc_drake.systems.depth_camera_source import render_session

DATA = Path(__file__).parent / "data" / "mocap"


def test_record_motion_II_reloads_bit_exact(tmp_path, capsys):
    out = tmp_path / "rec"
    assert main(["record", "--motion", "II", "--cycles", "1", "--seed", "3", "--out", str(out)]) == 0
    assert "wrote 61 frames of motion II" in capsys.readouterr().out
    reader = RecordingReader(out)
    assert len(reader) == 61
    assert reader.intrinsics == CameraIntrinsics()
    np.testing.assert_allclose(reader.timestamps, np.arange(61) / 10.0)

    # Render the same session again and compare every frame with what was written.
    rendered = []
    session = render_session(
        make_motion("II", 1, 3),
        CameraIntrinsics(),
        seed=3,
        frame_callback=lambda f: rendered.append((f.color.copy(), f.depth_m.copy(), f.truth_C.copy())),
    )
    t, names, landmarks = reader.ground_truth()
    assert names == LANDMARKS
    np.testing.assert_array_equal(t, session.t)
    np.testing.assert_array_equal(landmarks, session.truth)
    scale = reader.intrinsics.depth_scale
    for k in (0, 17, 30, 60):
        frame = reader[k]
        color, depth, truth = rendered[k]
        np.testing.assert_array_equal(frame.color, color)
        np.testing.assert_array_equal(frame.depth_m, units_to_depth(depth_to_units(depth, scale), scale))
        np.testing.assert_array_equal(frame.truth_C, truth)
        # Quantisation to millimetres is the only change, and invalid pixels stay invalid.
        valid = depth > 0
        assert np.abs(frame.depth_m[valid] - depth[valid]).max() <= scale / 2 + 1e-6
        assert np.all(frame.depth_m[~valid] == 0)


def test_record_refuses_to_overwrite_and_keeps_what_is_there(tmp_path, capsys):
    out = tmp_path / "rec"
    assert main(["record", "--motion", str(DATA / "upper_body.bvh"), "--out", str(out)]) == 0
    assert len(RecordingReader(out)) == 2
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main(["record", "--motion", "I", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "already holds a recording" in err and "Traceback" not in err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--motion", "III"], "unknown motion 'III'"),
        (["--motion", "I", "--cycles", "0"], "--cycles must be a positive integer"),
        (["--motion", "I", "--seconds", "3"], "--seconds applies to live or bag sources"),
        (["--motion", "missing/file.bvh"], "motion file not found"),
        (["--motion", "I", "--source", "webcam"], "unknown source"),
        (["--motion", "I", "--joint-names", "left_knee=LeftUpLeg"], "unknown role"),
    ],
)
def test_bad_options_exit_2_with_a_clear_message(tmp_path, capsys, argv, message):
    assert main(["record", *argv, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert message in err
    assert err.startswith("akc-drake record: error:") and "Traceback" not in err
    assert not (tmp_path / "x" / "timestamps.csv").exists()
