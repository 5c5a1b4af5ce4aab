"""Camera faults mid-run (issue 9, part 4): the source raises or stops delivering. The run ends cleanly, the
partial results and the recording so far are saved and reported."""

from __future__ import annotations

import json

import numpy as np
import pytest

from akc_drake import cli
from akc_drake.core.camera import CameraIntrinsics
from akc_drake.faults import FaultyFrameSource
from akc_drake.io import sources
from akc_drake.io.recording import RecordingReader, RecordingWriter

K = CameraIntrinsics(width=160, height=120, fx=154.0, fy=154.0, cx=79.5, cy=59.5, rate_hz=10.0)
FRAMES = 12


def _write_recording(path, n=FRAMES):
    rng = np.random.default_rng(0)
    with RecordingWriter(path, K) as w:
        for i in range(n):
            w.write(i * 0.1, rng.integers(0, 256, (K.height, K.width, 3), dtype=np.uint8),
                    np.full((K.height, K.width), 2.0), None)
    return path


@pytest.fixture
def recording(tmp_path):
    return _write_recording(tmp_path / "rec")


class _Live:
    """A recording played like a live camera: in order, no length, no going back."""

    def __init__(self, path):
        self._rec = sources.RecordingSource(path)
        self.intrinsics, self.rate_hz = self._rec.intrinsics, self._rec.rate_hz
        self.closed = False

    def __iter__(self):
        return iter(self._rec)

    def close(self):
        self.closed = True


def _faulty_open_source(monkeypatch, recording, fail_after, mode):
    """``open_source`` of any spec returns a live camera that fails after ``fail_after`` frames."""

    def fake(spec, **opts):
        return FaultyFrameSource(_Live(recording), fail_after, mode)

    monkeypatch.setattr(sources, "open_source", fake)


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def test_faulty_source_raises_or_stops_after_n_frames(recording):
    inner = sources.RecordingSource(recording)
    src = FaultyFrameSource(inner, 4, "raise")
    assert len(src) == FRAMES and src.intrinsics == inner.intrinsics and src.rate_hz == 10.0
    np.testing.assert_array_equal(src[3].color, inner[3].color)
    with pytest.raises(RuntimeError, match="frame 4"):
        src[4]
    got = []
    with pytest.raises(RuntimeError, match="frame 4"):
        for frame in src:
            got.append(frame.t)
    assert got == pytest.approx([0.0, 0.1, 0.2, 0.3])
    stop = FaultyFrameSource(inner, 4, "stop")
    assert len(stop) == 4 and [f.t for f in stop] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    with pytest.raises(IndexError):
        stop[4]

    class InOrder:  # a live camera: iteration only
        intrinsics, rate_hz = K, 10.0

        def __iter__(self):
            return iter(inner)

    live = FaultyFrameSource(InOrder(), 2, "raise")
    assert not hasattr(live, "__len__")
    with pytest.raises(RuntimeError):
        list(live)
    with pytest.raises(ValueError, match="mode"):
        FaultyFrameSource(inner, 1, "explode")
    with pytest.raises(ValueError, match="fail_after"):
        FaultyFrameSource(inner, -1)


def test_run_on_a_recording_that_breaks_mid_run_keeps_the_frames_before(tmp_path, recording, capsys):
    """A corrupt frame file is a real mid-run fault: the reader raises when it gets there."""
    (recording / "color" / "000007.png").write_bytes(b"\x89PNG\r\n\x1a\n broken")
    out = tmp_path / "out"
    rc = cli.main(["run", "--source", f"recording:{recording}", "--out", str(out),
                   "--json", str(out / "r.json")])
    err = capsys.readouterr().err
    assert rc == 0
    assert "Traceback" not in err
    warning = [line for line in _lines(err) if line.startswith("warning:")]
    assert len(warning) == 1 and "after 7 frames" in warning[0] and "000007.png" in warning[0]
    summary = json.loads((out / "r.json").read_text())
    assert summary["frames"] == 7 and summary["stop_reason"].startswith("source error")
    with np.load(out / "poses.npz", allow_pickle=False) as npz:
        assert npz["t"].shape == (7,) and npz["raw"].shape == (7, 12, 3)
        np.testing.assert_allclose(npz["t"], 0.1 * np.arange(7))


@pytest.mark.parametrize("mode", ["raise", "stop"])
def test_teleop_run_with_a_camera_that_fails_ends_cleanly(tmp_path, recording, monkeypatch, capsys, mode):
    _faulty_open_source(monkeypatch, recording, 6, mode)
    out = tmp_path / "out"
    rc = cli.main(["run", "--source", "realsense", "--seconds", "5", "--teleop", "--out", str(out),
                   "--json", str(out / "r.json")])
    err = capsys.readouterr().err
    assert rc == 0 and "Traceback" not in err
    summary = json.loads((out / "r.json").read_text())
    assert summary["frames"] == 6
    if mode == "raise":
        assert summary["stop_reason"].startswith("source error") and "frame 6" in summary["stop_reason"]
        assert any(line.startswith("warning:") and "after 6 frames" in line for line in _lines(err))
    else:
        assert summary["stop_reason"] == "source ended"
    assert summary["teleop"]["nan_commands"] == 0
    assert summary["teleop"]["max_joint_speed_ratio"] <= 1.0 + 1e-9
    with np.load(out / "poses.npz", allow_pickle=False) as npz:
        assert npz["t"].shape == (6,)


def test_a_camera_that_fails_before_the_first_frame_is_one_line_and_exit_2(recording, monkeypatch, capsys):
    _faulty_open_source(monkeypatch, recording, 0, "raise")
    rc = cli.main(["run", "--source", "realsense", "--seconds", "1"])
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    errors = [line for line in _lines(err) if "error:" in line]
    assert len(errors) == 1 and "frame 0" in errors[0]


def test_record_from_a_camera_that_fails_keeps_a_valid_recording(tmp_path, recording, monkeypatch, capsys):
    _faulty_open_source(monkeypatch, recording, 7, "raise")
    out = tmp_path / "copy"
    rc = cli.main(["record", "--source", "bag:camera.bag", "--out", str(out)])
    captured = capsys.readouterr()
    assert rc == 0 and "Traceback" not in captured.err
    assert "wrote 7 frames" in captured.out
    assert any(line.startswith("warning:") and "after 7 frames" in line for line in _lines(captured.err))
    copy = RecordingReader(out)
    original = RecordingReader(recording)
    assert len(copy) == 7
    np.testing.assert_array_equal(copy[6].color, original[6].color)
    np.testing.assert_allclose(copy.timestamps, original.timestamps[:7])
    # No temporary file is left behind.
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]


def test_record_from_a_camera_that_fails_at_once_is_exit_2(tmp_path, recording, monkeypatch, capsys):
    _faulty_open_source(monkeypatch, recording, 0, "raise")
    rc = cli.main(["record", "--source", "bag:camera.bag", "--out", str(tmp_path / "none")])
    err = capsys.readouterr().err
    assert rc == 2 and "Traceback" not in err
    assert len(_lines(err)) == 1 and "no frame recorded" in err
