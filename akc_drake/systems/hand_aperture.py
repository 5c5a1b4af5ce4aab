"""The hand channel on a camera: MediaPipe Hands on each RGB-D frame -> each hand's thumb-index distance."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.control_frames import hands_knuckle_vector
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS


class HandApertureDetector(LeafSystem):
    """Each camera frame's hands, measured: the same ``thumb_index_m`` output as
    :class:`~akc_drake.systems.gripper_command.HandApertureSource`, from a real detector.

    .. pydrake_system::

        name: HandApertureDetector
        input_ports:
        - color_image
        - depth_image
        - pixels (optional)
        output_ports:
        - thumb_index_m
        - hands_found
        - hand_knuckles

    Once per camera frame (at ``offset_s``, after the source has taken the frame) the detector
    (:class:`~akc_drake.io.hand_detector.HandDetector`, MediaPipe Hands) measures the thumb-tip to index-fingertip
    distance of each hand (metres; NaN when the hand is not found, which
    :class:`~akc_drake.systems.gripper_command.GripperCommand` reads as "keep the state"). ``pixels`` (the pose
    detector's 12 landmarks' pixels, row-major ``(12, 2)``), when connected, tells the hands apart by the pose's
    wrists; otherwise the hand landmarker's own handedness does. ``hands_found`` is ``[left, right]``, 1.0 when
    found. ``hand_knuckles`` is each hand's index-to-pinky knuckle vector ``[left (3), right (3)]`` in normalised
    image units (:func:`~akc_drake.core.control_frames.hands_knuckle_vector`; NaN where no hand), for the
    :class:`~akc_drake.systems.frame_mapper.FrameMapper`'s wrist frames (its ``hand_knuckles`` input), as the
    recorded runs replay them. All outputs are held between frames.

    Args:
        detector: a :class:`~akc_drake.io.hand_detector.HandDetector` (or anything with its ``detect``).
        intrinsics: the camera (the images' size and the deprojection).
        period_s: camera period; offset_s: update offset after the camera's sample time.
    """

    def __init__(self, detector, intrinsics: CameraIntrinsics, period_s: float, offset_s: float = 0.0):
        super().__init__()
        self.detector = detector
        self._K = intrinsics
        W, H = intrinsics.width, intrinsics.height
        self._color = self.DeclareAbstractInputPort("color_image", AbstractValue.Make(ImageRgba8U(W, H)))
        self._depth = self.DeclareAbstractInputPort("depth_image", AbstractValue.Make(ImageDepth32F(W, H)))
        self._pixels = self.DeclareVectorInputPort("pixels", 2 * NUM_LANDMARKS)
        self._aperture = self.DeclareDiscreteState(np.full(2, np.nan))
        self._found = self.DeclareDiscreteState(np.zeros(2))
        self._knuckles = self.DeclareDiscreteState(np.full(6, np.nan))
        self.DeclareStateOutputPort("thumb_index_m", self._aperture)
        self.DeclareStateOutputPort("hands_found", self._found)
        self.DeclareStateOutputPort("hand_knuckles", self._knuckles)
        self.DeclarePeriodicDiscreteUpdateEvent(period_s, offset_s, self._update)
        self._wrists = [LANDMARKS.index("left_wrist"), LANDMARKS.index("right_wrist")]

    def _update(self, context, discrete_state) -> None:
        color = np.ascontiguousarray(self._color.Eval(context).data[:, :, :3])
        depth = self._depth.Eval(context).data[:, :, 0].copy()
        wrists = None
        if self._pixels.HasValue(context):
            wrists = self._pixels.Eval(context).reshape(NUM_LANDMARKS, 2)[self._wrists]
        frame = CameraFrame(color=color, depth_m=depth, t=float(context.get_time()), intrinsics=self._K)
        m = self.detector.detect(frame, wrists)
        discrete_state.get_mutable_vector(self._aperture).SetFromVector(m.aperture_m)
        discrete_state.get_mutable_vector(self._found).SetFromVector(m.found.astype(float))
        knuckles = np.concatenate([hands_knuckle_vector(h, self._K) for h in m.landmarks_px])
        discrete_state.get_mutable_vector(self._knuckles).SetFromVector(knuckles)
