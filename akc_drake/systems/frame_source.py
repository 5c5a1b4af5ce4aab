"""Stage S1 from real frames: any frame source (recording, RealSense file or camera, video) as a camera."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.errors import SourceError
from akc_drake.systems.timing import DEFAULT_STAGE_OFFSET_S, stage_offset

POSE_SIZE = 3 * NUM_LANDMARKS


@dataclass(frozen=True)
class FrameSourceState:
    """The abstract state of :class:`FrameSourceSystem`: the frame currently on its outputs.

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


class FrameSourceSystem(LeafSystem):
    """Pulls frames from a frame source at the camera rate; the same outputs as the simulated camera.

    .. pydrake_system::

        name: FrameSourceSystem
        output_ports:
        - color_image
        - depth_image
        - label_image
        - camera_info
        - landmarks_true_C
        - finished
        - frame_index

    A periodic unrestricted update (period ``1 / rate``, offset ``stage_offset("source")`` = 0) takes the
    next frame into the abstract state (:class:`FrameSourceState`); every output is computed from that
    state. ``color_image`` is ImageRgba8U (alpha 255), ``depth_image`` ImageDepth32F in metres (0 where
    the source has no depth), ``label_image`` ImageLabel16I of zeros (real images have no labels),
    ``camera_info`` an AbstractValue holding the source's
    :class:`~akc_drake.core.camera.CameraIntrinsics`, ``landmarks_true_C`` the 36 true landmark
    coordinates when the source has them (a simulated recording) else NaN, ``finished`` 1.0 once there
    are no more frames, ``frame_index`` the frame's position (-1 before the first frame).

    Before the first update the images are black, depth 0, truth NaN. After the last frame the system
    holds it and sets ``finished``. A source that raises mid-run (a camera unplugged, a corrupt file)
    does not stop the simulation: the exception is stored in :attr:`error`, the system holds its last
    frame and sets ``finished``.

    Sources with ``__len__`` and ``__getitem__`` (recordings) are read by index, so the outputs are a
    function of the state alone; other sources (files played once, live cameras) are read in order,
    and such a system can run one simulation only (asking for an earlier frame sets :attr:`error`).

    Args:
        source: a frame source (see :mod:`akc_drake.io.sources`): iterable of
            :class:`~akc_drake.core.camera.CameraFrame`, with ``intrinsics`` and ``rate_hz``.
        period_s: the sampling period; default ``1 / source.rate_hz``.
        stage_offset_s: the per-stage offset (see :mod:`akc_drake.systems.timing`).
    """

    def __init__(
        self, source, *, period_s: float | None = None, stage_offset_s: float = DEFAULT_STAGE_OFFSET_S
    ):
        super().__init__()
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
        self._source = source
        self._K = K
        self.period_s = float(period_s)
        self._random_access = hasattr(source, "__len__") and hasattr(source, "__getitem__")
        self._iterator = None
        self._next_index = 0
        self._last: CameraFrame | None = None
        #: The exception the source raised, or None.
        self.error: BaseException | None = None

        W, H = K.width, K.height
        initial = FrameSourceState(
            index=-1,
            finished=False,
            t=float("nan"),
            color=np.zeros((H, W, 3), np.uint8),
            depth=np.zeros((H, W), np.float32),
            truth=np.full(POSE_SIZE, np.nan),
        )
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(initial))
        self.DeclarePeriodicUnrestrictedUpdateEvent(
            self.period_s, stage_offset("source", stage_offset_s), self._update
        )
        deps = {self.abstract_state_ticket(self._state_index)}
        self._label = ImageLabel16I(W, H)
        self._label.mutable_data[:] = 0
        self.DeclareAbstractOutputPort(
            "color_image",
            lambda: AbstractValue.Make(ImageRgba8U(W, H)),
            self._calc_color,
            prerequisites_of_calc=deps,
        )
        self.DeclareAbstractOutputPort(
            "depth_image",
            lambda: AbstractValue.Make(ImageDepth32F(W, H)),
            self._calc_depth,
            prerequisites_of_calc=deps,
        )
        self.DeclareAbstractOutputPort(
            "label_image",
            lambda: AbstractValue.Make(ImageLabel16I(W, H)),
            self._calc_label,
            prerequisites_of_calc={self.nothing_ticket()},
        )
        self.DeclareAbstractOutputPort(
            "camera_info",
            lambda: AbstractValue.Make(K),
            self._calc_info,
            prerequisites_of_calc={self.nothing_ticket()},
        )
        self.DeclareVectorOutputPort(
            "landmarks_true_C", POSE_SIZE, self._calc_truth, prerequisites_of_calc=deps
        )
        self.DeclareVectorOutputPort("finished", 1, self._calc_finished, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("frame_index", 1, self._calc_index, prerequisites_of_calc=deps)

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self._K

    @property
    def source(self):
        return self._source

    # -- reading the source ------------------------------------------------------------------------

    def _fetch(self, k: int) -> CameraFrame | None:
        """Frame ``k`` of the source, or None past its end."""
        if self._random_access:
            return self._source[k] if k < len(self._source) else None
        if k == self._next_index - 1 and self._last is not None:
            return self._last
        if k != self._next_index:
            raise SourceError(
                f"frame source {type(self._source).__name__} is read in order and cannot go back to "
                f"frame {k} (next is {self._next_index}); build a new FrameSourceSystem for a new simulation"
            )
        if self._iterator is None:
            self._iterator = iter(self._source)
        try:
            frame = next(self._iterator)
        except StopIteration:
            return None
        self._next_index += 1
        self._last = frame
        return frame

    def _state_from(self, k: int, frame: CameraFrame) -> FrameSourceState:
        K = self._K
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

    def _update(self, context, state) -> None:
        s: FrameSourceState = context.get_abstract_state(self._state_index).get_value()
        if s.finished:
            return  # hold
        k = s.index + 1
        try:
            frame = self._fetch(k)
            new = replace(s, finished=True) if frame is None else self._state_from(k, frame)
        except Exception as e:  # a failing source must not abort the simulation; see the class doc
            self.error = e
            new = replace(s, finished=True)
        state.get_mutable_abstract_state(self._state_index).set_value(new)

    # -- outputs -------------------------------------------------------------------------------------

    def _s(self, context) -> FrameSourceState:
        return context.get_abstract_state(self._state_index).get_value()

    def _calc_color(self, context, output) -> None:
        img = output.get_mutable_value()
        data = img.mutable_data
        data[..., :3] = self._s(context).color
        data[..., 3] = 255

    def _calc_depth(self, context, output) -> None:
        output.get_mutable_value().mutable_data[..., 0] = self._s(context).depth

    def _calc_label(self, context, output) -> None:
        output.set_value(self._label)

    def _calc_info(self, context, output) -> None:
        output.set_value(self._K)

    def _calc_truth(self, context, output: BasicVector) -> None:
        output.SetFromVector(self._s(context).truth)

    def _calc_finished(self, context, output: BasicVector) -> None:
        output.SetFromVector([1.0 if self._s(context).finished else 0.0])

    def _calc_index(self, context, output: BasicVector) -> None:
        output.SetFromVector([float(self._s(context).index)])


def AddFrameSource(builder, source, **kwargs) -> FrameSourceSystem:
    """Add a :class:`FrameSourceSystem` for ``source`` to ``builder``, named "FrameSource".

    Args:
        builder: a DiagramBuilder.
        source: the frame source.
        **kwargs: passed to :class:`FrameSourceSystem`.

    Returns:
        The added system.
    """
    system = builder.AddSystem(FrameSourceSystem(source, **kwargs))
    system.set_name("FrameSource")
    return system
