"""The recording writer appends ``timestamps.csv`` (one row per frame, no rewrite), and a writer killed
mid-recording leaves a recording the reader loads, up to the last appended frame."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.io.recording import TIMESTAMPS_FILE, RecordingReader, RecordingWriter

K = CameraIntrinsics(width=16, height=12, fx=15.0, fy=15.0, cx=7.5, cy=5.5, depth_scale=0.001, rate_hz=10.0)


def _frame(i, rng, truth=True):
    color = rng.integers(0, 256, size=(K.height, K.width, 3), dtype=np.uint8)
    depth = rng.integers(0, 8000, size=(K.height, K.width)).astype(np.float64) * K.depth_scale
    return 0.1 * i, color, depth, rng.normal(size=(NUM_LANDMARKS, 3)) if truth else None


def test_each_frame_appends_one_row_to_the_same_file(tmp_path):
    rng = np.random.default_rng(0)
    ts = tmp_path / "rec" / TIMESTAMPS_FILE
    with RecordingWriter(tmp_path / "rec", K, sync_every=3) as w:
        assert not ts.exists()  # nothing before the first frame
        w.write(*_frame(0, rng))
        before, inode = ts.read_bytes(), os.stat(ts).st_ino
        assert before == b"index,t\n0,0.0\n"
        for i in range(1, 8):
            w.write(*_frame(i, rng))
            now = ts.read_bytes()
            assert now.startswith(before) and now[len(before):] == f"{i},{0.1 * i!r}\n".encode()
            assert os.stat(ts).st_ino == inode  # appended in place, never replaced
            before = now
    r = RecordingReader(tmp_path / "rec")
    np.testing.assert_array_equal(r.timestamps, 0.1 * np.arange(8))


def test_no_frames_is_a_header_only_file(tmp_path):
    RecordingWriter(tmp_path / "rec", K).close()
    assert (tmp_path / "rec" / TIMESTAMPS_FILE).read_text() == "index,t\n"


_KILLED_WRITER = textwrap.dedent(
    """
    import os, signal, sys
    import numpy as np
    sys.path.insert(0, {tests!r})
    from test_recording_append import K, _frame
    from akc_drake.io.recording import RecordingWriter

    rng = np.random.default_rng(1)
    w = RecordingWriter({out!r}, K, checkpoint_every=4, sync_every=5)
    for i in range(11):
        w.write(*_frame(i, rng))
    open({out!r} + "/color/000011.png", "wb").write(b"half a frame")  # the next frame, cut short
    os.kill(os.getpid(), signal.SIGKILL)  # no close(), no exit handlers
    """
)


def test_a_killed_writer_leaves_a_valid_recording(tmp_path):
    out = tmp_path / "rec"
    code = _KILLED_WRITER.format(tests=os.path.dirname(__file__), out=str(out))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == -signal.SIGKILL, p.stderr
    r = RecordingReader(out)
    assert len(r) == 11  # every appended row survives the kill (flushed), the cut frame is not listed
    rng = np.random.default_rng(1)
    expected = [_frame(i, rng) for i in range(11)]
    np.testing.assert_array_equal(r.timestamps, [e[0] for e in expected])
    for i in (0, 10):
        np.testing.assert_array_equal(r[i].color, expected[i][1])
        np.testing.assert_allclose(r[i].depth_m, expected[i][2], atol=K.depth_scale / 2)
    t, _, landmarks = r.ground_truth()
    assert len(t) == 8  # checkpointed at 4 and 8 frames
    np.testing.assert_array_equal(landmarks[7], expected[7][3])
    assert r[10].truth_C is None


@pytest.mark.parametrize(
    "tail, frames",
    [
        ("2,0.", 2),  # a torn last row (no newline, does not parse as a later time) is ignored
        ("2,0.2", 3),  # a last row without newline that parses is kept
        ("2", 2),
    ],
)
def test_the_reader_ignores_a_torn_last_row(tmp_path, tail, frames):
    rng = np.random.default_rng(2)
    with RecordingWriter(tmp_path / "rec", K) as w:
        for i in range(3):
            w.write(*_frame(i, rng, truth=False))
    ts = tmp_path / "rec" / TIMESTAMPS_FILE
    ts.write_text("index,t\n0,0.0\n1,0.1\n" + tail)
    assert len(RecordingReader(tmp_path / "rec")) == frames


def test_a_bad_row_before_the_last_is_still_an_error_naming_its_line(tmp_path):
    rng = np.random.default_rng(3)
    with RecordingWriter(tmp_path / "rec", K) as w:
        for i in range(3):
            w.write(*_frame(i, rng))
    (tmp_path / "rec" / TIMESTAMPS_FILE).write_text("index,t\n0,0.0\n1,x\n2,0.2")
    with pytest.raises(UserError, match=r"timestamps.csv: line 3: t must be a number"):
        RecordingReader(tmp_path / "rec")
