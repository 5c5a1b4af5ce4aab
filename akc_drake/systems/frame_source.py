"""Stage S1 from real frames: any frame source (recording, RealSense file or camera, video) as a camera.

The frame bookkeeping (reading by index or in order, checking and copying each frame, holding the last one)
is :mod:`akc_drake.core.frame_reader`; :class:`FrameSourceState` and ``POSE_SIZE`` stay importable from here.
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.frame_reader import POSE_SIZE, FrameReader, FrameSourceState, advance, source_period
from akc_drake.systems.timing import DEFAULT_STAGE_OFFSET_S, stage_offset


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
    next frame into the abstract state (:class:`~akc_drake.core.frame_reader.FrameSourceState`); every
    output is computed from that state. ``color_image`` is ImageRgba8U (alpha 255), ``depth_image``
    ImageDepth32F in metres (0 where the source has no depth), ``label_image`` ImageLabel16I of zeros (real
    images have no labels), ``camera_info`` an AbstractValue holding the source's
    :class:`~akc_drake.core.camera.CameraIntrinsics`, ``landmarks_true_C`` the 36 true landmark
    coordinates when the source has them (a simulated recording) else NaN, ``finished`` 1.0 once there
    are no more frames, ``frame_index`` the frame's position (-1 before the first frame).

    Before the first update the images are black, depth 0, truth NaN. After the last frame the system
    holds it and sets ``finished``. A source that raises mid-run (a camera unplugged, a corrupt file)
    does not stop the simulation: the exception is stored in :attr:`error`, the system holds its last
    frame and sets ``finished``. Sources with ``__len__`` and ``__getitem__`` (recordings) are read by
    index, so the outputs are a function of the state alone; other sources (files played once, live
    cameras) are read in order, and such a system can run one simulation only.

    Args:
        source: a frame source (see :mod:`akc_drake.io.sources`).
        period_s: the sampling period; default ``1 / source.rate_hz``.
        stage_offset_s: the per-stage offset (see :mod:`akc_drake.systems.timing`).
    """

    def __init__(self, source, *, period_s: float | None = None,
                 stage_offset_s: float = DEFAULT_STAGE_OFFSET_S):
        super().__init__()
        K, self.period_s = source_period(source, period_s)
        self._source = source
        self._K = K
        self._reader = FrameReader(source, K)
        #: The exception the source raised, or None.
        self.error: BaseException | None = None
        W, H = K.width, K.height
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(FrameSourceState.initial(K)))
        self.DeclarePeriodicUnrestrictedUpdateEvent(
            self.period_s, stage_offset("source", stage_offset_s), self._update
        )
        deps = {self.abstract_state_ticket(self._state_index)}
        self._label = ImageLabel16I(W, H)
        self._label.mutable_data[:] = 0
        self.DeclareAbstractOutputPort("color_image", lambda: AbstractValue.Make(ImageRgba8U(W, H)),
                                       self._calc_color, prerequisites_of_calc=deps)
        self.DeclareAbstractOutputPort("depth_image", lambda: AbstractValue.Make(ImageDepth32F(W, H)),
                                       self._calc_depth, prerequisites_of_calc=deps)
        self.DeclareAbstractOutputPort("label_image", lambda: AbstractValue.Make(ImageLabel16I(W, H)),
                                       self._calc_label, prerequisites_of_calc={self.nothing_ticket()})
        self.DeclareAbstractOutputPort("camera_info", lambda: AbstractValue.Make(K), self._calc_info,
                                       prerequisites_of_calc={self.nothing_ticket()})
        self.DeclareVectorOutputPort("landmarks_true_C", POSE_SIZE, self._calc_truth, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("finished", 1, self._calc_finished, prerequisites_of_calc=deps)
        self.DeclareVectorOutputPort("frame_index", 1, self._calc_index, prerequisites_of_calc=deps)

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self._K

    @property
    def source(self):
        return self._source

    def _update(self, context, state) -> None:
        new, error = advance(self._reader, self._s(context))
        if error is not None:
            self.error = error
        state.get_mutable_abstract_state(self._state_index).set_value(new)

    def _s(self, context) -> FrameSourceState:
        return context.get_abstract_state(self._state_index).get_value()

    def _calc_color(self, context, output) -> None:
        data = output.get_mutable_value().mutable_data
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
    """Add a :class:`FrameSourceSystem` for ``source`` to ``builder``, named "FrameSource" (keywords: as
    its constructor), and return it."""
    system = builder.AddSystem(FrameSourceSystem(source, **kwargs))
    system.set_name("FrameSource")
    return system


__all__ = ["POSE_SIZE", "AddFrameSource", "FrameSourceState", "FrameSourceSystem"]
