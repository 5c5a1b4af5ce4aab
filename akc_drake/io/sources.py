"""Frame sources: recordings, RealSense files, a live RealSense and RGB video, behind one interface.

A frame source is an iterable of :class:`~akc_drake.core.camera.CameraFrame` with attributes
``intrinsics`` (:class:`~akc_drake.core.camera.CameraIntrinsics`) and ``rate_hz``, and a ``close()``
method (every source is also a context manager). :class:`~akc_drake.systems.frame_source.FrameSourceSystem`
turns any of them into the simulated camera's output ports.

``open_source(spec)`` parses the ``--source`` option: ``recording:DIR``, ``bag:FILE``, ``realsense``
(or ``realsense:SERIAL``), ``video:FILE``; ``sim`` gives None (the caller renders the operator).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol, runtime_checkable

import cv2
import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.errors import SourceError, UserError
from akc_drake.io._stderr import quiet_native_stderr
from akc_drake.io.realsense import BagReader, import_pyrealsense2, intrinsics_from_rs
from akc_drake.io.recording import RecordingReader

#: Horizontal field of view assumed for a video whose intrinsics are not given, degrees
#: (a typical webcam; the RealSense D435 colour camera has 69 degrees).
DEFAULT_VIDEO_HFOV_DEG = 65.0

SOURCE_FORMS = "sim, recording:DIR, bag:FILE, realsense[:SERIAL], video:FILE"


@runtime_checkable
class FrameSource(Protocol):
    """What every frame source offers."""

    intrinsics: CameraIntrinsics
    rate_hz: float

    def __iter__(self) -> Iterator[CameraFrame]: ...

    def close(self) -> None: ...


class _SourceBase:
    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release the source (files, devices); later calls do nothing."""


class RecordingSource(_SourceBase):
    """A recording folder (see :mod:`akc_drake.io.recording`) as a frame source.

    Iterating more than once replays the recording from its first frame; indexing gives any frame.

    Args:
        path: the recording folder.

    Raises:
        UserError: the folder is not a valid recording (the message names the file and field).
    """

    kind = "recording"

    def __init__(self, path):
        self.reader = RecordingReader(path)
        self.path = self.reader.path
        self.intrinsics = self.reader.intrinsics
        self.rate_hz = self.reader.rate_hz

    def __len__(self) -> int:
        return len(self.reader)

    def __getitem__(self, i: int) -> CameraFrame:
        return self.reader[i]

    def __iter__(self) -> Iterator[CameraFrame]:
        return iter(self.reader)

    def ground_truth(self):
        """``(t, names, landmarks)`` of a simulated recording, else None."""
        return self.reader.ground_truth()


class BagSource(_SourceBase):
    """A RealSense ``.bag``/``.db3`` recording, played frame by frame (non-real-time, nothing dropped).

    Depth is aligned to colour (``rs.align(rs.stream.color)``) when the file's depth stream is not
    already registered to colour; intrinsics come from the colour stream profile and the depth
    sensor's depth scale. ``frame.t`` counts from the first frame. The file plays once: iterate once.

    Args:
        path: the recording.
        rate_hz: overrides the colour stream's fps as the source's rate.

    Raises:
        UserError: pyrealsense2 missing, the file missing or not a RealSense recording with depth and colour.
    """

    kind = "bag"

    def __init__(self, path, *, rate_hz: float | None = None):
        self.path = Path(path)
        self._reader = BagReader(self.path, rate_hz=rate_hz)
        self.intrinsics = self._reader.intrinsics
        self.rate_hz = self._reader.rate_hz

    @property
    def needs_align(self) -> bool:
        """True when depth is aligned to colour by ``rs.align``."""
        return self._reader.needs_align

    def __iter__(self) -> Iterator[CameraFrame]:
        return iter(self._reader)

    def close(self) -> None:
        self._reader.close()


class RealSenseSource(_SourceBase):
    """A live Intel RealSense (D435 or similar): colour RGB8 and depth Z16 aligned to colour.

    The camera streams at ``fps``; the pipeline keeps only the newest frameset, so a consumer that
    pulls at a lower ``rate_hz`` gets the latest frame each time. ``frame.t`` counts from the first
    frame. Iteration ends after ``seconds`` (if given) or when :meth:`close` is called.

    Args:
        width, height: stream size (both streams).
        fps: the camera's frame rate (6, 15, 30, 60 on a D435).
        rate_hz: the source's nominal rate (default ``fps``).
        serial: a device serial number when several cameras are attached.
        seconds: stop after this long.
        timeout_s: how long to wait for a frame before raising :class:`~akc_drake.errors.SourceError`.

    Raises:
        UserError / SourceError: pyrealsense2 missing, no device attached, or the stream cannot start.
    """

    kind = "realsense"

    def __init__(
        self,
        width: int = 640,
        height: int = 480,
        fps: int = 30,
        *,
        rate_hz: float | None = None,
        serial: str | None = None,
        seconds: float | None = None,
        timeout_s: float = 5.0,
    ):
        rs = self._rs = import_pyrealsense2()
        devices = rs.context().query_devices()
        if len(devices) == 0:
            raise SourceError(
                "realsense: no RealSense camera found (connect a D435 to a USB 3 port), "
                "or use --source recording:DIR or bag:FILE"
            )
        serials = [d.get_info(rs.camera_info.serial_number) for d in devices]
        if serial is not None and str(serial) not in serials:
            raise SourceError(f"realsense: no camera with serial {serial}; attached: {', '.join(serials)}")
        self._pipe = rs.pipeline()
        cfg = rs.config()
        if serial is not None:
            cfg.enable_device(str(serial))
        cfg.enable_stream(rs.stream.depth, int(width), int(height), rs.format.z16, int(fps))
        cfg.enable_stream(rs.stream.color, int(width), int(height), rs.format.rgb8, int(fps))
        try:
            profile = self._pipe.start(cfg)
        except RuntimeError as e:
            raise SourceError(f"realsense: cannot start {width}x{height} @ {fps} fps ({e})") from None
        self._running = True
        depth_scale = profile.get_device().first_depth_sensor().get_depth_scale()
        color = profile.get_stream(rs.stream.color).as_video_stream_profile()
        self.rate_hz = float(rate_hz or fps)
        self.intrinsics = intrinsics_from_rs(
            color.get_intrinsics(), depth_scale=depth_scale, rate_hz=self.rate_hz
        )
        self._align = rs.align(rs.stream.color)
        self.seconds = seconds
        self.timeout_s = float(timeout_s)

    def __iter__(self) -> Iterator[CameraFrame]:
        K = self.intrinsics
        t0 = None
        n = 0
        while self._running:
            try:
                fs = self._pipe.wait_for_frames(int(self.timeout_s * 1000))
            except RuntimeError as e:
                raise SourceError(f"realsense: no frame for {self.timeout_s:g} s ({e})") from None
            fs = self._align.process(fs)
            d, c = fs.get_depth_frame(), fs.get_color_frame()
            if not d or not c:
                continue
            t_ms = float(c.get_timestamp())
            t0 = t_ms if t0 is None else t0
            t = (t_ms - t0) / 1000.0
            if self.seconds is not None and t > self.seconds:
                return
            yield CameraFrame(
                color=np.asanyarray(c.get_data()).copy(),
                depth_m=np.asanyarray(d.get_data()).astype(np.float64) * K.depth_scale,
                t=t,
                intrinsics=K,
                extras={
                    "timestamp_ms": t_ms,
                    "frame_number": int(c.get_frame_number()),
                    "index": n,
                    "source": "realsense",
                },
            )
            n += 1

    def close(self) -> None:
        if getattr(self, "_running", False):
            self._running = False
            self._pipe.stop()


def guess_intrinsics(
    width: int,
    height: int,
    rate_hz: float,
    hfov_deg: float = DEFAULT_VIDEO_HFOV_DEG,
    depth_scale: float = 0.001,
) -> CameraIntrinsics:
    """Pinhole intrinsics of an uncalibrated camera from its horizontal field of view.

    Square pixels, principal point at the image centre: ``fx = fy = (W / 2) / tan(hfov / 2)``.
    """
    if not 1.0 <= hfov_deg <= 179.0:
        raise ValueError(f"hfov_deg must be in [1, 179] degrees, got {hfov_deg!r}")
    f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    return CameraIntrinsics(
        width=int(width),
        height=int(height),
        fx=f,
        fy=f,
        cx=(width - 1) / 2.0,
        cy=(height - 1) / 2.0,
        depth_scale=depth_scale,
        rate_hz=float(rate_hz),
    )


class VideoSource(_SourceBase):
    """An RGB video file (anything OpenCV reads), with depth from a constant or a matching depth video.

    Depth: ``depth_m`` (metres, the same at every pixel), or ``depth_video`` (a video of the same size
    whose frames hold depth: a 16-bit grey frame in units of ``intrinsics.depth_scale``, or an 8-bit one
    in units of ``depth_video_scale`` metres per grey level), or neither (depth 0 = none everywhere: the
    pipeline then gets no 3D landmarks). Intrinsics: given, or guessed from ``hfov_deg``.
    ``frame.t = index / rate_hz``. Iterating again restarts the video.

    Args:
        path: the RGB video.
        depth_m: a constant depth in metres.
        depth_video: a depth video with the same size and frame count.
        intrinsics: the camera's intrinsics (must match the video size).
        hfov_deg: horizontal field of view for guessed intrinsics.
        rate_hz: overrides the video's frame rate.
        depth_video_scale: metres per grey level of an 8-bit depth video.

    Raises:
        UserError: a missing or unreadable file, mismatched sizes, or a bad depth value.
    """

    kind = "video"

    def __init__(
        self,
        path,
        depth_m: float | None = None,
        depth_video=None,
        *,
        intrinsics: CameraIntrinsics | None = None,
        hfov_deg: float = DEFAULT_VIDEO_HFOV_DEG,
        rate_hz: float | None = None,
        depth_video_scale: float = 0.02,
    ):
        self.path = Path(path)
        if depth_m is not None and depth_video is not None:
            raise UserError("video: give a constant depth (--depth) or a depth video, not both")
        if depth_m is not None and not (
            isinstance(depth_m, (int, float)) and math.isfinite(depth_m) and 0.0 < depth_m <= 20.0
        ):
            raise UserError(f"video: --depth must be a distance in metres in (0, 20], got {depth_m!r}")
        self.depth_m = None if depth_m is None else float(depth_m)
        self.depth_video = None if depth_video is None else Path(depth_video)
        self.depth_video_scale = float(depth_video_scale)
        #: A constant ``depth_m`` is the person's (joint) depth, not a measured surface: the extractor then
        #: adds no surface-to-centre offset.
        self.depth_is_surface = self.depth_video is not None
        cap = self._open(self.path)
        W = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        H = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        cap.release()
        if W <= 0 or H <= 0:
            raise UserError(f"{self.path}: cannot read the video's frame size")
        if rate_hz is None:
            if not (math.isfinite(fps) and fps > 0):
                raise UserError(f"{self.path}: the video has no frame rate; give one (rate_hz)")
            rate_hz = fps
        if intrinsics is None:
            intrinsics = guess_intrinsics(W, H, rate_hz, hfov_deg)
        elif (intrinsics.width, intrinsics.height) != (W, H):
            raise UserError(
                f"{self.path}: video is {W}x{H} but the intrinsics are {intrinsics.width}x{intrinsics.height}"
            )
        elif intrinsics.rate_hz != rate_hz:
            intrinsics = CameraIntrinsics(**{**intrinsics.as_dict(), "rate_hz": float(rate_hz)})
        self.intrinsics = intrinsics
        self.rate_hz = float(rate_hz)
        if self.depth_video is not None:
            dcap = self._open(self.depth_video)
            dW, dH = int(dcap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(dcap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            dcap.release()
            if (dW, dH) != (W, H):
                raise UserError(f"{self.depth_video}: depth video is {dW}x{dH}, the colour video {W}x{H}")

    @staticmethod
    def _open(path: Path) -> cv2.VideoCapture:
        if not path.is_file():
            raise UserError(f"{path}: video file not found")
        with quiet_native_stderr():  # FFmpeg logs "moov atom not found" etc. for a file it cannot read
            cap = cv2.VideoCapture(str(path))
        if not cap.isOpened():
            raise UserError(f"{path}: not a video OpenCV can read")
        return cap

    def _depth_from(self, img: np.ndarray) -> np.ndarray:
        a = img[..., 0] if img.ndim == 3 else img
        if a.dtype == np.uint16:
            return a.astype(np.float64) * self.intrinsics.depth_scale
        return a.astype(np.float64) * self.depth_video_scale

    def __iter__(self) -> Iterator[CameraFrame]:
        K = self.intrinsics
        cap = self._open(self.path)
        dcap = None
        if self.depth_video is not None:
            dcap = self._open(self.depth_video)
            dcap.set(cv2.CAP_PROP_CONVERT_RGB, 0)
        try:
            n = 0
            while True:
                ok, bgr = cap.read()
                if not ok:
                    return
                if bgr.shape[:2] != (K.height, K.width):
                    raise SourceError(
                        f"{self.path}: frame {n} is {bgr.shape[1]}x{bgr.shape[0]}, "
                        f"expected {K.width}x{K.height}"
                    )
                if dcap is not None:
                    okd, dimg = dcap.read()
                    if not okd:
                        raise SourceError(f"{self.depth_video}: ends at frame {n}, before the colour video")
                    depth = self._depth_from(dimg)
                    if depth.shape != (K.height, K.width):
                        raise SourceError(f"{self.depth_video}: frame {n} has the wrong size {depth.shape}")
                elif self.depth_m is not None:
                    depth = np.full((K.height, K.width), self.depth_m)
                else:
                    depth = np.zeros((K.height, K.width))
                rgb = (
                    cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
                    if bgr.ndim == 3
                    else cv2.cvtColor(bgr, cv2.COLOR_GRAY2RGB)
                )
                yield CameraFrame(
                    color=rgb,
                    depth_m=depth,
                    t=n / self.rate_hz,
                    intrinsics=K,
                    # A constant --depth is the person's (joint) depth, not a measured surface.
                    extras={"index": n, "source": "video", "depth_is_surface": self.depth_is_surface},
                )
                n += 1
        finally:
            cap.release()
            if dcap is not None:
                dcap.release()


_KINDS = {
    "recording": RecordingSource,
    "bag": BagSource,
    "realsense": RealSenseSource,
    "video": VideoSource,
}

#: ``open_source`` option -> (source kind, constructor parameter).
_OPTIONS = {
    "rate_hz": ("bag", "realsense", "video"),
    "depth_m": ("video",),
    "depth_video": ("video",),
    "intrinsics": ("video",),
    "hfov_deg": ("video",),
    "depth_video_scale": ("video",),
    "width": ("realsense",),
    "height": ("realsense",),
    "fps": ("realsense",),
    "seconds": ("realsense",),
    "timeout_s": ("realsense",),
}


#: The command-line flag of an option, for messages.
_FLAGS = {"depth_m": "--depth", "seconds": "--seconds"}


def open_source(spec: str, **opts):
    """Open the frame source that ``spec`` names.

    Args:
        spec: ``sim``, ``recording:DIR``, ``bag:FILE``, ``realsense``, ``realsense:SERIAL`` or ``video:FILE``.
        **opts: options for the chosen kind (``rate_hz``, ``depth_m``, ``depth_video``, ``intrinsics``,
            ``hfov_deg``, ``depth_video_scale``, ``width``, ``height``, ``fps``, ``seconds``,
            ``timeout_s``); options set to None are ignored, so a caller can pass its flags unconditionally.

    Returns:
        The source, or None for ``sim`` (the caller renders the simulated operator).

    Raises:
        UserError: an unknown spec, a missing argument, an option that does not apply to the kind, or
            whatever the source raises when it opens (missing file, wrong format, no device).
    """
    unknown = [k for k in opts if k not in _OPTIONS]
    if unknown:
        raise ValueError(f"open_source: unknown option(s) {', '.join(unknown)}")
    if not isinstance(spec, str) or not spec.strip():
        raise UserError(f"--source: empty; expected one of {SOURCE_FORMS}")
    spec = spec.strip()
    kind, sep, arg = spec.partition(":")
    kind = kind.strip().lower()
    if kind == "sim" and not sep:
        return None
    if kind not in _KINDS:
        raise UserError(f"--source {spec!r}: unknown source; expected one of {SOURCE_FORMS}")
    given = {k: v for k, v in opts.items() if v is not None}
    wrong = [k for k in given if kind not in _OPTIONS[k]]
    if wrong:
        shown = ", ".join(f"{k} ({_FLAGS[k]})" if k in _FLAGS else k for k in wrong)
        raise UserError(f"--source {spec!r}: option(s) {shown} do not apply to a {kind} source")
    if kind == "realsense":
        if arg:
            given["serial"] = arg
        return RealSenseSource(**given)
    if not arg.strip():
        raise UserError(f"--source {spec!r}: missing the path after '{kind}:'")
    return _KINDS[kind](arg, **given)
