"""Stage S2 as a Drake system: 2D landmark detection on an RGB-D frame, depth lookup and deprojection.

The numpy work (depth lookup, surface-to-centre correction, deprojection, option and image-size checks)
is :mod:`akc_drake.core.landmark_extraction`; its names stay importable from here.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detector
from akc_drake.core.landmark_extraction import (
    DEFAULT_DEPTH_RULE,
    DEFAULT_SURFACE_OFFSET_M,
    camera_frame,
    check_extractor_options,
    default_depth_window,
    extract_landmarks,
    surface_offsets,
    surface_to_centre_depth,
)
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.systems import timing


class LandmarkExtractor(LeafSystem):
    """Stage S2 as a sampled system: detector + depth lookup + surface-to-centre correction + deprojection.

    At ``t_k + timing.stage_offset("extractor")`` it builds a :class:`~akc_drake.core.camera.CameraFrame`
    from its inputs (frame time ``t_k``), runs :func:`~akc_drake.core.landmark_extraction.extract_landmarks`
    and stores the result in its discrete state; the outputs read the state. Before the first frame the
    outputs are NaN (landmarks, pixels) and 0 (visibility).

    .. pydrake_system::

        name: LandmarkExtractor
        input_ports:
        - color_image
        - depth_image
        - camera_info (optional)
        - label_image (optional)
        - landmarks_true_C (optional)
        output_ports:
        - landmarks_C
        - visibility
        - pixels

    ``color_image`` is ImageRgba8U, ``depth_image`` ImageDepth32F (metres, 0 invalid), ``camera_info`` an
    AbstractValue of :class:`~akc_drake.core.camera.CameraIntrinsics` (when unconnected: the intrinsics given
    to the constructor); the optional ports are left unconnected for real cameras (the frame then carries
    no label image or truth). Outputs: ``landmarks_C`` 36 = (12, 3) row-major in the camera frame C,
    ``visibility`` 12, ``pixels`` 24 = (12, 2) row-major.

    Args:
        intrinsics: the camera; sets the image size of the input models and the default period
            (``1 / rate_hz``); default 640x480 at 10 Hz. Deprojection uses the intrinsics on ``camera_info``.
        detector: any Detector; None: a :class:`~akc_drake.core.sim_detector.SimulatedDetector` seeded with
            ``seed`` (needs the ``landmarks_true_C`` input).
        period_s: sampling period (default: the camera period).
        stage_offset_s: the per-stage offset (updates at ``t_k + timing.stage_offset("extractor", ...)``).
        seed: seed of the default simulated detector.
        window: depth-lookup window (odd, pixels); None: scaled with the focal length, 15 at 640x480
            (:func:`~akc_drake.core.landmark_extraction.default_depth_window`). min_depth, max_depth: valid
            depth range (metres).
        surface_offset_m: per-landmark surface-to-centre depth offsets, as
            :func:`~akc_drake.core.landmark_extraction.surface_offsets` takes them (None: the defaults).
        depth_rule: the depth lookup's rule: ``nearest`` (the nearest surface in the window, the default) or
            ``median`` (:func:`~akc_drake.core.camera.depth_lookup`).
    """

    def __init__(self, intrinsics: CameraIntrinsics | None = None, detector: Detector | None = None, *,
                 period_s: float | None = None, stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
                 seed: int = 0, window: int | None = None, min_depth: float = 0.2, max_depth: float = 10.0,
                 surface_offset_m=None, depth_rule: str = DEFAULT_DEPTH_RULE):
        super().__init__()
        if detector is None:
            from akc_drake.core.sim_detector import SimulatedDetector

            detector = SimulatedDetector(seed=seed)
        if window is None and (intrinsics is None or isinstance(intrinsics, CameraIntrinsics)):
            window = default_depth_window(intrinsics)
        self._period = check_extractor_options(detector, intrinsics, window, period_s, depth_rule)
        K = intrinsics or CameraIntrinsics()
        self._detector = detector
        self._window = int(window)
        self._depth_rule = depth_rule
        self._offsets = surface_offsets(surface_offset_m)
        self._range = (float(min_depth), float(max_depth))
        self._offset = timing.stage_offset("extractor", stage_offset_s)
        W, H = K.width, K.height
        self._color = self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U(W, H)))
        self._depth = self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F(W, H)))
        self._info = self.DeclareAbstractInputPort("camera_info", AbstractValue.Make(K))
        self._label = self.DeclareAbstractInputPort("label_image", AbstractValue.Make(ImageLabel16I(W, H)))
        self._truth = self.DeclareVectorInputPort("landmarks_true_C", 3 * NUM_LANDMARKS)
        self._K_default = K
        self._s_points = self.DeclareDiscreteState(BasicVector(np.full(3 * NUM_LANDMARKS, np.nan)))
        self._s_vis = self.DeclareDiscreteState(BasicVector(np.zeros(NUM_LANDMARKS)))
        self._s_pix = self.DeclareDiscreteState(BasicVector(np.full(2 * NUM_LANDMARKS, np.nan)))
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, self._offset, self._update)
        self.DeclareStateOutputPort("landmarks_C", self._s_points)
        self.DeclareStateOutputPort("visibility", self._s_vis)
        self.DeclareStateOutputPort("pixels", self._s_pix)

    @property
    def detector(self) -> Detector:
        return self._detector

    @property
    def window(self) -> int:
        """The depth lookup's window (odd, pixels)."""
        return self._window

    @property
    def depth_rule(self) -> str:
        """The depth lookup's rule (``nearest`` or ``median``)."""
        return self._depth_rule

    @property
    def surface_offset_m(self) -> np.ndarray:
        """The ``(12,)`` surface-to-centre offsets this extractor applies (a copy)."""
        return self._offsets.copy()

    def frame_from_inputs(self, context) -> CameraFrame:
        """The :class:`CameraFrame` the inputs describe (frame time = context time - the stage offset)."""
        K = self._info.Eval(context) if self._info.HasValue(context) else self._K_default
        # Copies: the frame owns its arrays (a detector may keep frames; the inputs change next frame).
        # A detector that does not look at colour (the simulated one) gets a shared black image: no copy.
        color = None
        if self._color.HasValue(context) and getattr(self._detector, "needs_color", True):
            color = np.ascontiguousarray(self._color.Eval(context).data[:, :, :3])
        depth = self._depth.Eval(context).data[:, :, 0].copy()
        label = self._label.Eval(context).data[:, :, 0].copy() if self._label.HasValue(context) else None
        truth = self._truth.Eval(context).reshape(NUM_LANDMARKS, 3) if self._truth.HasValue(context) else None
        return camera_frame(color, depth, context.get_time() - self._offset, K, truth, label)

    def _update(self, context, discrete_state):
        lo, hi = self._range
        points, vis, uv = extract_landmarks(self.frame_from_inputs(context), self._detector, window=self._window,
                                            min_depth=lo, max_depth=hi, surface_offset_m=self._offsets,
                                            depth_rule=self._depth_rule)
        discrete_state.get_mutable_vector(self._s_points).SetFromVector(points.ravel())
        discrete_state.get_mutable_vector(self._s_vis).SetFromVector(vis)
        discrete_state.get_mutable_vector(self._s_pix).SetFromVector(uv.ravel())


def AddLandmarkExtractor(builder, source, detector: Detector | None = None, **kwargs) -> LandmarkExtractor:
    """Add a :class:`LandmarkExtractor` fed by ``source`` (a DepthCameraSource or any system with the same
    output port names) and return it. ``label_image`` and ``landmarks_true_C`` are connected when the
    source has them.
    """
    intrinsics = kwargs.pop("intrinsics", getattr(source, "intrinsics", None))
    extractor = builder.AddSystem(LandmarkExtractor(intrinsics, detector, **kwargs))
    for name in ("color_image", "depth_image", "camera_info", "label_image", "landmarks_true_C"):
        if source.HasOutputPort(name):
            builder.Connect(source.GetOutputPort(name), extractor.GetInputPort(name))
    return extractor


__all__ = ["DEFAULT_SURFACE_OFFSET_M", "AddLandmarkExtractor", "LandmarkExtractor", "extract_landmarks",
           "surface_offsets", "surface_to_centre_depth"]
