"""core/frame_reader.py: reading a frame source frame by frame, checking and copying frames, holding the last."""

from __future__ import annotations

import math

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame
from akc_drake.core.frame_reader import (
    POSE_SIZE,
    FrameReader,
    FrameSourceState,
    advance,
    source_period,
    state_from_frame,
)
from akc_drake.errors import SourceError
from tests.test_frame_source import K, _camera_frames, _ListSource


class _IndexedSource(_ListSource):
    """A random-access source (like a recording): ``__len__`` and ``__getitem__``."""

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, k):
        self.pulled += 1
        return self.frames[k]


def test_initial_state_is_black_zero_depth_no_truth():
    s = FrameSourceState.initial(K)
    assert (s.index, s.finished) == (-1, False) and math.isnan(s.t)
    assert s.color.shape == (12, 16, 3) and s.color.dtype == np.uint8 and not s.color.any()
    assert s.depth.shape == (12, 16) and s.depth.dtype == np.float32 and not s.depth.any()
    assert s.truth.shape == (POSE_SIZE,) == (36,) and np.isnan(s.truth).all()


def test_source_period_from_the_source_or_the_argument():
    src = _ListSource([], rate_hz=30.0)
    intr, period = source_period(src)
    assert intr is K and period == 1.0 / 30.0
    assert source_period(src, 0.2) == (K, 0.2)
    with pytest.raises(ValueError, match="source.rate_hz must be a positive number, got 0.0"):
        source_period(_ListSource([], rate_hz=0.0))
    with pytest.raises(ValueError, match="period_s must be a positive number, got inf"):
        source_period(src, float("inf"))
    with pytest.raises(ValueError, match="source.intrinsics must be a CameraIntrinsics, got NoneType"):
        source_period(object())


def test_state_from_frame_copies_and_cleans_the_frame():
    frames, colors = _camera_frames(1)
    frame = frames[0]
    frame.depth_m[2, 3] = np.nan
    frame.truth_C = np.arange(36.0).reshape(12, 3)
    s = state_from_frame(7, frame, K)
    assert (s.index, s.finished, s.t) == (7, False, 0.0)
    np.testing.assert_array_equal(s.color, colors[0])
    assert s.color is not frame.color and s.depth.dtype == np.float32 and s.depth[2, 3] == 0.0
    np.testing.assert_array_equal(s.depth[0], frame.depth_m[0].astype(np.float32))
    np.testing.assert_array_equal(s.truth, np.arange(36.0))
    frame.truth_C = np.ones((3, 3))  # not a (12, 3) skeleton: no truth
    assert np.isnan(state_from_frame(0, frame, K).truth).all()
    bad = CameraFrame(frame.color, np.zeros((5, 5)), 0.0, K)
    with pytest.raises(SourceError, match=r"frame 4: depth must have shape \(12, 16\), got \(5, 5\)"):
        state_from_frame(4, bad, K)
    grey = CameraFrame(frame.color.astype(np.float32), frame.depth_m, 0.0, K)
    with pytest.raises(SourceError, match=r"frame 2: color must be uint8 \(12, 16, 3\), got float32"):
        state_from_frame(2, grey, K)


def test_in_order_reader_gives_the_last_frame_again_but_never_an_earlier_one():
    frames, _ = _camera_frames(3)
    src = _ListSource(frames)
    reader = FrameReader(src, K)
    assert not reader.random_access
    assert reader.fetch(0) is frames[0] and reader.fetch(0) is frames[0] and src.pulled == 1
    assert reader.fetch(1) is frames[1] and reader.fetch(2) is frames[2]
    assert reader.fetch(3) is None
    with pytest.raises(SourceError, match="cannot go back to frame 0 \\(next is 3\\)"):
        reader.fetch(0)


def test_random_access_reader_reads_any_frame():
    frames, _ = _camera_frames(3)
    reader = FrameReader(_IndexedSource(frames), K)
    assert reader.random_access
    assert reader.fetch(2) is frames[2] and reader.fetch(0) is frames[0] and reader.fetch(3) is None


def test_advance_steps_to_the_end_then_holds():
    frames, colors = _camera_frames(2)
    reader = FrameReader(_ListSource(frames), K)
    s0 = FrameSourceState.initial(K)
    s1, err = advance(reader, s0)
    assert err is None and s1.index == 0 and np.array_equal(s1.color, colors[0])
    s2, _ = advance(reader, s1)
    assert s2.index == 1 and s2.t == pytest.approx(0.1)
    s3, err = advance(reader, s2)
    assert err is None and s3.finished and s3.index == 1 and s3.color is s2.color  # the last frame, held
    assert advance(reader, s3) == (s3, None)


def test_advance_records_a_failing_source_and_holds_its_last_frame():
    frames, colors = _camera_frames(4)
    reader = FrameReader(_ListSource(frames, fail_at=1), K)
    s1, _ = advance(reader, FrameSourceState.initial(K))
    s2, err = advance(reader, s1)
    assert isinstance(err, SourceError) and str(err) == "camera unplugged"
    assert s2.finished and s2.index == 0 and np.array_equal(s2.color, colors[0])
