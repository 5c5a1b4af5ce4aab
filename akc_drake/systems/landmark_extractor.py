"""Stage S2: 2D landmark detection on an RGB-D frame, depth lookup and pinhole deprojection.

The detector is pluggable (any :class:`akc_drake.core.camera.Detector`: the simulated detector on renders,
MediaPipe on real images). For each landmark the depth is the median of the valid depth pixels in a small
window around its detected pixel (:func:`akc_drake.core.camera.depth_lookup`; NaN when there are none), and
the 3D point is the pinhole deprojection of the pixel at that depth (:func:`akc_drake.core.camera.deproject`).
Nothing here knows about occlusion: a landmark hidden behind a limb gets the limb's depth. Stage S3 decides.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageLabel16I, ImageRgba8U

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detector, deproject, depth_lookup
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.systems import timing


def extract_landmarks(
    frame: CameraFrame,
    detector: Detector,
    *,
    window: int = 5,
    min_depth: float = 0.2,
    max_depth: float = 10.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detect, look up depth and deproject the landmarks of one frame.

    Args:
        frame: the RGB-D frame.
        detector: any Detector.
        window: depth-lookup window (odd, pixels).
        min_depth, max_depth: valid depth range (metres).

    Returns:
        ``(landmarks_C (12, 3), visibility (12,), pixels (12, 2))``; NaN landmarks and pixels and zero
        visibility when the detector finds nobody.
    """
    det = detector.detect(frame)
    if not det.person_found:
        return (
            np.full((NUM_LANDMARKS, 3), np.nan),
            np.zeros(NUM_LANDMARKS),
            np.full((NUM_LANDMARKS, 2), np.nan),
        )
    uv = np.asarray(det.uv, dtype=float).reshape(NUM_LANDMARKS, 2)
    vis = np.asarray(det.visibility, dtype=float).reshape(NUM_LANDMARKS)
    z = depth_lookup(frame.depth_m, uv, window=window, min_depth=min_depth, max_depth=max_depth)
    return deproject(uv, z, frame.intrinsics), vis, uv


class LandmarkExtractor(LeafSystem):
    """Stage S2 as a sampled system: detector + depth lookup + deprojection at the camera rate.

    At ``t_k + timing.stage_offset("extractor")`` it builds a
    :class:`~akc_drake.core.camera.CameraFrame` from its inputs (frame time ``t_k``), runs
    :func:`extract_landmarks` and stores the result in its discrete state; the outputs read the state. Before
    the first frame the outputs are NaN (landmarks, pixels) and 0 (visibility).

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
    no label image or truth). Outputs: ``landmarks_C``
    36 = (12, 3) row-major in the camera frame C, ``visibility`` 12, ``pixels`` 24 = (12, 2) row-major.
    """

    def __init__(
        self,
        intrinsics: CameraIntrinsics | None = None,
        detector: Detector | None = None,
        *,
        period_s: float | None = None,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
        seed: int = 0,
        window: int = 5,
        min_depth: float = 0.2,
        max_depth: float = 10.0,
    ):
        """Args:
        intrinsics: the camera; sets the image size of the input models and the default period
            (``1 / rate_hz``); default 640x480 at 10 Hz. Deprojection uses the intrinsics that arrive on
            ``camera_info``.
        detector: any Detector (``detect(CameraFrame) -> Detection2D``); None: a
            :class:`~akc_drake.core.sim_detector.SimulatedDetector` seeded with ``seed`` (needs the
            ``landmarks_true_C`` input).
        period_s: sampling period (default: the camera period).
        stage_offset_s: the per-stage offset; the extractor updates at
            ``t_k + timing.stage_offset("extractor", stage_offset_s)``.
        seed: seed of the default simulated detector.
        window: depth-lookup window (odd, pixels).
        min_depth, max_depth: valid depth range (metres).
        """
        super().__init__()
        if detector is None:
            from akc_drake.core.sim_detector import SimulatedDetector

            detector = SimulatedDetector(seed=seed)
        if not isinstance(detector, Detector):
            raise ValueError(
                f"detector must implement the Detector protocol (name, detect), got {detector!r}"
            )
        if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}")
        if not isinstance(window, (int, np.integer)) or window < 1 or window % 2 == 0:
            raise ValueError(f"window must be a positive odd integer, got {window!r}")
        K = intrinsics or CameraIntrinsics()
        period = 1.0 / K.rate_hz if period_s is None else float(period_s)
        if not period > 0:
            raise ValueError(f"period_s must be positive, got {period_s!r}")
        self._detector = detector
        self._window = int(window)
        self._range = (float(min_depth), float(max_depth))
        self._period = period
        self._offset = timing.stage_offset("extractor", stage_offset_s)
        W, H = K.width, K.height
        self._color = self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U(W, H)))
        self._depth = self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F(W, H)))
        self._info = self.DeclareAbstractInputPort("camera_info", AbstractValue.Make(K))
        self._label = self.DeclareAbstractInputPort("label_image", AbstractValue.Make(ImageLabel16I(W, H)))
        self._truth = self.DeclareVectorInputPort("landmarks_true_C", 3 * NUM_LANDMARKS)
        self._K_default = K
        n3, n2 = 3 * NUM_LANDMARKS, 2 * NUM_LANDMARKS
        self._s_points = self.DeclareDiscreteState(BasicVector(np.full(n3, np.nan)))
        self._s_vis = self.DeclareDiscreteState(BasicVector(np.zeros(NUM_LANDMARKS)))
        self._s_pix = self.DeclareDiscreteState(BasicVector(np.full(n2, np.nan)))
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, self._offset, self._update)
        self.DeclareStateOutputPort("landmarks_C", self._s_points)
        self.DeclareStateOutputPort("visibility", self._s_vis)
        self.DeclareStateOutputPort("pixels", self._s_pix)

    @property
    def detector(self) -> Detector:
        return self._detector

    def frame_from_inputs(self, context) -> CameraFrame:
        """The :class:`CameraFrame` the inputs describe (frame time = context time - the stage offset)."""
        K = self._info.Eval(context) if self._info.HasValue(context) else self._K_default
        if not isinstance(K, CameraIntrinsics):
            raise ValueError(f"camera_info must hold a CameraIntrinsics, got {type(K).__name__}")
        # Copies: the frame owns its arrays (a detector may keep frames; the inputs change next frame).
        color = np.ascontiguousarray(self._color.Eval(context).data[:, :, :3])
        depth = self._depth.Eval(context).data[:, :, 0].copy()
        if depth.shape != (K.height, K.width) or color.shape[:2] != (K.height, K.width):
            raise ValueError(
                f"image size {depth.shape[1]}x{depth.shape[0]} (depth), "
                f"{color.shape[1]}x{color.shape[0]} (colour) "
                f"does not match camera_info {K.width}x{K.height}"
            )
        label = self._label.Eval(context).data[:, :, 0].copy() if self._label.HasValue(context) else None
        truth = self._truth.Eval(context).reshape(NUM_LANDMARKS, 3) if self._truth.HasValue(context) else None
        t = context.get_time() - self._offset
        return CameraFrame(color=color, depth_m=depth, t=t, intrinsics=K, truth_C=truth, label=label)

    def _update(self, context, discrete_state):
        frame = self.frame_from_inputs(context)
        lo, hi = self._range
        points, vis, uv = extract_landmarks(
            frame, self._detector, window=self._window, min_depth=lo, max_depth=hi
        )
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
