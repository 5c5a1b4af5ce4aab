"""Reading a frame source one camera frame at a time: the bookkeeping behind the real-frame camera system.

A frame source (:mod:`akc_drake.io.sources`: a recording, a RealSense file or camera, a video) is an iterable
of :class:`~akc_drake.core.camera.CameraFrame` with ``intrinsics`` and ``rate_hz``. :class:`FrameReader`
fetches frame ``k`` from it (by index when the source has ``__len__`` and ``__getitem__``, else in order),
and :func:`advance` turns the current :class:`FrameSourceState` into the next one: the next frame, checked
and copied, or the same frame marked ``finished`` when the source ran out or failed.
The LeafSystem around it is :class:`akc_drake.systems.frame_source.FrameSourceSystem`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.errors import SourceError

POSE_SIZE = 3 * NUM_LANDMARKS


@dataclass(frozen=True)
class FrameSourceState:
    """The frame a frame-source system currently shows.

    Attributes:
        index: the frame's position in the source; -1 before the first frame.
        finished: True after the source ran out of frames or failed.
        t: the frame's own timestamp (s); NaN before the first frame.
        color: ``(H, W, 3)`` uint8 RGB.
        depth: ``(H, W)`` float32 metres (0 = no depth).
        truth: ``(36,)`` true landmarks in C (NaN when unknown).
    """

    index: int
    finished: bool
    t: float
    color: np.ndarray
    depth: np.ndarray
    truth: np.ndarray

    @classmethod
    def initial(cls, K: CameraIntrinsics) -> FrameSourceState:
        """The state before the first frame: black image, depth 0, truth NaN, index -1."""
        return cls(index=-1, finished=False, t=float("nan"), color=np.zeros((K.height, K.width, 3), np.uint8),
                   depth=np.zeros((K.height, K.width), np.float32), truth=np.full(POSE_SIZE, np.nan))


def source_period(source, period_s: float | None = None) -> tuple[CameraIntrinsics, float]:
    """Check that ``source`` is a frame source; returns its intrinsics and the sampling period.

    Args:
        source: the frame source (``intrinsics``, iterable, optional ``rate_hz``).
        period_s: the sampling period; None: ``1 / source.rate_hz`` (or ``1 / intrinsics.rate_hz``).

    Raises:
        ValueError: naming what is wrong with the source or the period.
    """
    K = getattr(source, "intrinsics", None)
    if not isinstance(K, CameraIntrinsics):
        raise ValueError(f"source.intrinsics must be a CameraIntrinsics, got {type(K).__name__}")
    if not hasattr(source, "__iter__"):
        raise ValueError(f"source must be iterable (a frame source), got {type(source).__name__}")
    if period_s is None:
        rate = float(getattr(source, "rate_hz", K.rate_hz))
        if not (math.isfinite(rate) and rate > 0):
            raise ValueError(f"source.rate_hz must be a positive number, got {rate!r}")
        period_s = 1.0 / rate
    if not (math.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period_s must be a positive number, got {period_s!r}")
    return K, float(period_s)


class FrameReader:
    """Fetches frame ``k`` of a frame source: by index when it has ``__len__`` and ``__getitem__`` (a
    recording: any frame, any number of times), else in order (a file played once, a live camera: the
    next frame, or the last one again; an earlier one raises :class:`~akc_drake.errors.SourceError`)."""

    def __init__(self, source, intrinsics: CameraIntrinsics):
        self.source = source
        self.intrinsics = intrinsics
        self.random_access = hasattr(source, "__len__") and hasattr(source, "__getitem__")
        self._iterator = None
        self._next_index = 0
        self._last: CameraFrame | None = None

    def fetch(self, k: int) -> CameraFrame | None:
        """Frame ``k`` of the source, or None past its end."""
        if self.random_access:
            return self.source[k] if k < len(self.source) else None
        if k == self._next_index - 1 and self._last is not None:
            return self._last
        if k != self._next_index:
            raise SourceError(
                f"frame source {type(self.source).__name__} is read in order and cannot go back to "
                f"frame {k} (next is {self._next_index}); build a new FrameSourceSystem for a new simulation"
            )
        if self._iterator is None:
            self._iterator = iter(self.source)
        try:
            frame = next(self._iterator)
        except StopIteration:
            return None
        self._next_index += 1
        self._last = frame
        return frame


def state_from_frame(k: int, frame: CameraFrame, K: CameraIntrinsics) -> FrameSourceState:
    """The state showing ``frame`` (index ``k``): images checked against ``K`` and copied, NaN depth -> 0.

    Raises:
        SourceError: the colour image is not uint8 ``(H, W, 3)`` or the depth not ``(H, W)``.
    """
    color = np.asarray(frame.color)
    depth = np.asarray(frame.depth_m)
    if color.dtype != np.uint8 or color.shape != (K.height, K.width, 3):
        raise SourceError(
            f"frame {k}: color must be uint8 ({K.height}, {K.width}, 3), got {color.dtype} {color.shape}"
        )
    if depth.shape != (K.height, K.width):
        raise SourceError(f"frame {k}: depth must have shape ({K.height}, {K.width}), got {depth.shape}")
    truth = np.full(POSE_SIZE, np.nan)
    if frame.truth_C is not None:
        tr = np.asarray(frame.truth_C, dtype=float)
        if tr.shape == (NUM_LANDMARKS, 3):
            truth = tr.reshape(-1).copy()
    return FrameSourceState(
        index=k,
        finished=False,
        t=float(frame.t),
        color=np.array(color, dtype=np.uint8, copy=True),
        depth=np.nan_to_num(depth.astype(np.float32), nan=0.0),
        truth=truth,
    )


def advance(reader: FrameReader, s: FrameSourceState) -> tuple[FrameSourceState, BaseException | None]:
    """The state after ``s``: the next frame, or ``s`` marked finished (held) at the end or on an error.

    Returns:
        ``(state, error)``: ``error`` is the exception the source raised (the state is then ``s``
        finished), else None. A finished ``s`` is returned unchanged.
    """
    if s.finished:
        return s, None
    k = s.index + 1
    try:
        frame = reader.fetch(k)
        new = replace(s, finished=True) if frame is None else state_from_frame(k, frame, reader.intrinsics)
    except Exception as e:  # a failing source must not abort the simulation
        return replace(s, finished=True), e
    return new, None
