"""Intel RealSense recordings through pyrealsense2: play ``.bag``/``.db3`` files and write ``.db3`` files.

pyrealsense2 (the ``realsense`` extra) runs without a camera: it plays ROS1 ``.bag`` and ROS2
``.db3`` recordings and, through a ``software_device`` wrapped in a ``recorder``, writes ``.db3``.

Playback (:class:`BagReader`) loads the file as a playback device in non-real-time mode (the file is
read only as fast as frames are consumed, nothing is dropped) and starts the depth and colour sensors
itself, with a callback that blocks until the consumer takes the frame. Colour and depth frames are
paired by timestamp (within half a frame period). When the depth stream is not already registered
to the colour stream (different intrinsics or a non-identity extrinsic), the pair is combined into a
frameset and aligned to colour with ``rs.align(rs.stream.color)``.

Why not ``rs.pipeline`` with ``config.enable_device_from_file``: measured with pyrealsense2 2.59 on
files this module writes, the pipeline starts playing in real time before it can be switched to
non-real-time, and lost the first 1-2 frames at random; its syncer also paired depth ``k`` with
colour ``k - 1`` on every other frameset.
"""

from __future__ import annotations

import gc
import importlib
import math
import queue
import threading
from collections import deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.errors import SourceError, UserError
from akc_drake.io.recording import depth_to_units

NO_REALSENSE_HELP = "pyrealsense2 is not installed; install the extra with: pip install -e .[realsense]"
#: Seconds a playback waits for the next frame before it declares the file stalled.
STALL_TIMEOUT_S = 10.0


def import_pyrealsense2():
    """Import pyrealsense2, or raise a :class:`~akc_drake.errors.UserError` that says how to get it."""
    try:
        return importlib.import_module("pyrealsense2")
    except ImportError as e:
        msg = str(e)
        if "libusb" in msg:
            raise UserError(
                f"pyrealsense2 cannot load: {msg}. Install the system library: apt-get install libusb-1.0-0"
            ) from None
        raise UserError(f"{NO_REALSENSE_HELP} ({msg})") from None


def _round_sig(x: float, digits: int = 7) -> float:
    """Undo float32 storage noise: 0.0010000000474974513 -> 0.001."""
    if x == 0 or not math.isfinite(x):
        return x
    return float(f"{x:.{digits}g}")


def intrinsics_from_rs(rs_intr, *, depth_scale: float, rate_hz: float) -> CameraIntrinsics:
    """Our :class:`~akc_drake.core.camera.CameraIntrinsics` from a ``pyrealsense2.intrinsics``.

    RealSense's ``ppx, ppy`` use the same pixel convention as ours (integer coordinates at pixel centres).
    Lens distortion coefficients are ignored (RealSense colour streams are close to pinhole).
    """
    return CameraIntrinsics(
        width=int(rs_intr.width),
        height=int(rs_intr.height),
        fx=_round_sig(float(rs_intr.fx)),
        fy=_round_sig(float(rs_intr.fy)),
        cx=_round_sig(float(rs_intr.ppx)),
        cy=_round_sig(float(rs_intr.ppy)),
        depth_scale=_round_sig(float(depth_scale)),
        rate_hz=float(rate_hz),
    )


def _rs_intrinsics(rs, K: CameraIntrinsics):
    i = rs.intrinsics()
    i.width, i.height = int(K.width), int(K.height)
    i.fx, i.fy, i.ppx, i.ppy = float(K.fx), float(K.fy), float(K.cx), float(K.cy)
    i.model = rs.distortion.none
    i.coeffs = [0.0] * 5
    return i


def _video_stream(rs, stream, fmt, bpp: int, uid: int, K: CameraIntrinsics):
    vs = rs.video_stream()
    vs.type, vs.fmt, vs.bpp = stream, fmt, bpp
    vs.index, vs.uid = 0, uid
    vs.width, vs.height = int(K.width), int(K.height)
    vs.fps = max(int(round(K.rate_hz)), 1)
    vs.intrinsics = _rs_intrinsics(rs, K)
    return vs


def write_db3(
    path,
    frames: Iterable[CameraFrame],
    intrinsics: CameraIntrinsics,
    *,
    depth_intrinsics: CameraIntrinsics | None = None,
    timeout_s: float = 10.0,
    accel=None,
) -> int:
    """Write frames as a RealSense ``.db3`` recording (colour RGB8 + depth Z16).

    A pyrealsense2 ``software_device`` with a "Stereo Module" (depth) and an "RGB Camera" (colour)
    sensor is wrapped in a ``recorder``; each frame is injected into both sensors with timestamp
    ``frame.t * 1000`` ms (hardware clock domain) and frame number = its position.

    Args:
        path: the output file; must end in ``.db3`` (pyrealsense2 writes only ROS2 ``.db3``).
        frames: frames with ``color`` ``(H, W, 3)`` uint8 RGB and ``depth_m`` ``(H, W)`` metres, both
            ``intrinsics.width`` x ``intrinsics.height``; times strictly increasing.
        intrinsics: colour intrinsics; ``depth_scale`` quantises the depth and ``rate_hz`` is the fps.
        depth_intrinsics: the depth stream's intrinsics when the depth is *not* registered to colour
            (the extrinsic is always identity); default: the colour intrinsics (depth aligned to colour).
        timeout_s: how long to wait for the recorder to take each frame.
        accel: optional ``(N, 3)`` accelerometer samples (m/s^2, the D435i's IMU frame), written first on an
            ``accel`` stream of a "Motion Module" sensor at 100 Hz (a recording of a camera with an IMU). The
            software device's recorder does not store a motion stream's extrinsics: the IMU reads as aligned
            with the colour camera (as a D435i's is, up to its offset).

    Returns:
        The number of frames written.

    Raises:
        UserError: pyrealsense2 missing, a bad path or the recorder failing.
        ValueError: a frame with the wrong size/type or a non-increasing time.
    """
    rs = import_pyrealsense2()
    path = Path(path)
    if path.suffix != ".db3":
        raise UserError(f"{path}: pyrealsense2 writes only .db3 recordings; use a name ending in .db3")
    if not path.parent.is_dir():
        raise UserError(f"{path.parent}: folder not found")
    K = intrinsics
    Kd = depth_intrinsics or K
    if (Kd.width, Kd.height) != (K.width, K.height):
        raise ValueError("depth_intrinsics must have the colour stream's width and height")

    dev = rs.software_device()
    dev.register_info(rs.camera_info.name, "akc-drake software camera")
    dev.register_info(rs.camera_info.serial_number, "0")
    depth_sensor = dev.add_sensor("Stereo Module")
    color_sensor = dev.add_sensor("RGB Camera")
    depth_profile = depth_sensor.add_video_stream(_video_stream(rs, rs.stream.depth, rs.format.z16, 2, 0, Kd))
    color_profile = color_sensor.add_video_stream(_video_stream(rs, rs.stream.color, rs.format.rgb8, 3, 1, K))
    depth_sensor.add_read_only_option(rs.option.depth_units, float(K.depth_scale))
    extr = rs.extrinsics()
    extr.rotation = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    extr.translation = [0.0, 0.0, 0.0]
    depth_profile.register_extrinsics_to(color_profile, extr)
    motion_sensor = accel_profile = None
    A = None
    if accel is not None:
        A = np.asarray(accel, dtype=float).reshape(-1, 3)
        motion_sensor = dev.add_sensor("Motion Module")
        ms = rs.motion_stream()
        ms.type, ms.fmt, ms.index, ms.uid, ms.fps = rs.stream.accel, rs.format.motion_xyz32f, 0, 2, 100
        mi = rs.motion_device_intrinsic()
        mi.data = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
        mi.noise_variances, mi.bias_variances = [0.0] * 3, [0.0] * 3
        ms.intrinsics = mi
        accel_profile = motion_sensor.add_motion_stream(ms)

    try:
        rec = rs.recorder(str(path), dev)
    except RuntimeError as e:
        raise UserError(f"{path}: cannot record ({e})") from None
    delivered = [0]
    cond = threading.Condition()

    def on_frame(_f):
        with cond:
            delivered[0] += 1
            cond.notify_all()

    rec_sensors = rec.query_sensors()
    by_name = {s.get_info(rs.camera_info.name): s for s in rec_sensors}
    by_name["Stereo Module"].open(depth_profile)
    by_name["RGB Camera"].open(color_profile)
    if motion_sensor is not None:
        by_name["Motion Module"].open(accel_profile)
    for s in rec_sensors:
        s.start(on_frame)
    base = 0
    if A is not None:
        for k, a in enumerate(A):
            mf = rs.software_motion_frame()
            v = rs.vector()
            v.x, v.y, v.z = (float(c) for c in a)
            mf.data = v  # assign a whole vector: mf.data.x = ... would change a copy
            mf.timestamp = k * 10.0
            mf.domain = rs.timestamp_domain.hardware_clock
            mf.frame_number = k
            mf.profile = accel_profile.as_motion_stream_profile()
            motion_sensor.on_motion_frame(mf)
        base = len(A)
        with cond:
            if not cond.wait_for(lambda: delivered[0] >= base, timeout=timeout_s):
                raise UserError(f"{path}: the RealSense recorder did not take the accelerometer samples")

    n = 0
    last_t = -math.inf
    try:
        for frame in frames:
            color = np.ascontiguousarray(frame.color)
            if color.dtype != np.uint8 or color.shape != (K.height, K.width, 3):
                raise ValueError(
                    f"frame {n}: color must be uint8 ({K.height}, {K.width}, 3), "
                    f"got {color.dtype} {color.shape}"
                )
            depth_m = np.asarray(frame.depth_m)
            if depth_m.shape != (K.height, K.width):
                raise ValueError(
                    f"frame {n}: depth must have shape ({K.height}, {K.width}), got {depth_m.shape}"
                )
            t = float(frame.t)
            if not (math.isfinite(t) and t > last_t):
                raise ValueError(f"frame {n}: t = {t!r} s must be finite and after the previous {last_t!r} s")
            last_t = t
            units = np.ascontiguousarray(depth_to_units(depth_m, K.depth_scale))
            for sensor, profile, img, bpp in (
                (depth_sensor, depth_profile, units, 2),
                (color_sensor, color_profile, color, 3),
            ):
                f = rs.software_video_frame()
                f.pixels = img
                f.stride = K.width * bpp
                f.bpp = bpp
                f.timestamp = t * 1000.0
                f.domain = rs.timestamp_domain.hardware_clock
                f.frame_number = n
                f.profile = profile.as_video_stream_profile()
                if bpp == 2:
                    f.depth_units = float(K.depth_scale)
                sensor.on_video_frame(f)
            n += 1
            with cond:
                want = base + 2 * n
                if not cond.wait_for(lambda want=want: delivered[0] >= want, timeout=timeout_s):
                    raise UserError(f"{path}: the RealSense recorder stopped taking frames at frame {n - 1}")
    finally:
        for s in rec_sensors:
            try:
                s.stop()
                s.close()
            except RuntimeError:
                pass
        # The recorder finishes the file when it is destroyed.
        del rec_sensors, by_name, rec
        gc.collect()
    return n


def read_bag_accel(path, *, max_samples: int = 400, timeout_s: float = 5.0):
    """The accelerometer samples of a RealSense recording (a D435i's IMU), for the gravity direction.

    Plays only the ``accel`` stream (non-real-time) and collects up to ``max_samples`` samples.

    Args:
        path: the ``.bag``/``.db3`` recording.
        max_samples: stop after this many samples (4 s of a D435i at 100 Hz: the operator's calibration).
        timeout_s: give up when the playback makes no progress for this long.

    Returns:
        ``(samples (N, 3) m/s^2 in the IMU frame, R_color_accel (3, 3))``, or None when the recording has no
        accelerometer stream (a D435 without IMU, or a recording without it).
    """
    import time

    rs = import_pyrealsense2()
    ctx = rs.context()
    try:
        pb = ctx.load_device(str(path))
    except RuntimeError as e:
        raise UserError(f"{path}: not a readable RealSense recording ({e})") from None
    pb.set_real_time(False)
    sensor = profile = color = None
    for s in pb.query_sensors():
        for p in s.get_stream_profiles():
            if p.stream_type() == rs.stream.accel and profile is None:
                sensor, profile = s, p
            elif p.stream_type() == rs.stream.color and color is None:
                color = p
    if profile is None:
        return None
    R = np.eye(3)
    if color is not None:
        try:  # librealsense stores the rotation column-major
            R = np.asarray(profile.get_extrinsics_to(color).rotation, dtype=float).reshape(3, 3, order="F")
        except RuntimeError:
            pass  # no extrinsics recorded: the IMU is taken as aligned with the colour camera (a D435i's is)
    samples: list[tuple[float, float, float]] = []
    lock = threading.Lock()

    def on_sample(f) -> None:
        d = f.as_motion_frame().get_motion_data()
        with lock:
            if len(samples) < max_samples:
                samples.append((d.x, d.y, d.z))

    sensor.open(profile)
    sensor.start(on_sample)
    try:
        last, since, playing = 0, time.monotonic(), False
        while True:
            status = pb.current_status()
            playing = playing or status == rs.playback_status.playing
            with lock:
                n = len(samples)
            # "stopped" is also the status before playback starts: it means the end once we saw it play or got data
            if n >= max_samples or ((playing or n > 0) and status == rs.playback_status.stopped):
                break
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > timeout_s:
                break
            time.sleep(0.01)
    finally:
        sensor.stop()
        sensor.close()
        del sensor, pb, ctx
        gc.collect()
    with lock:
        return np.asarray(samples, dtype=float).reshape(-1, 3), R


@dataclass
class _Item:
    stream: str  # "depth" | "color"
    frame: object  # a kept pyrealsense2.frame
    t_ms: float


class BagReader:
    """Plays a RealSense ``.bag``/``.db3`` file frame by frame, without dropping frames.

    Iterating gives :class:`~akc_drake.core.camera.CameraFrame` with depth aligned to colour;
    ``frame.t`` counts from the first frame (s), ``frame.extras`` holds ``timestamp_ms`` (the
    recording's own colour timestamp), ``frame_number`` and ``source: "bag"``.

    Args:
        path: the recording.
        rate_hz: overrides the colour stream's fps as the frame rate.

    Raises:
        UserError: pyrealsense2 missing, the file missing or not a RealSense recording, or without a
            depth or colour stream, or a colour format we cannot convert.
    """

    def __init__(self, path, *, rate_hz: float | None = None):
        rs = self._rs = import_pyrealsense2()
        self.path = Path(path)
        if not self.path.is_file():
            raise UserError(f"{self.path}: RealSense recording not found")
        if self.path.suffix not in (".bag", ".db3"):
            raise UserError(f"{self.path}: expected a RealSense .bag or .db3 file")
        self._ctx = rs.context()
        try:
            self._pb = self._ctx.load_device(str(self.path))
        except RuntimeError as e:
            raise UserError(f"{self.path}: not a readable RealSense recording ({e})") from None
        self._pb.set_real_time(False)
        self._sensors = []
        depth_profile = color_profile = None
        depth_scale = 0.001
        for s in self._pb.query_sensors():
            for p in s.get_stream_profiles():
                st = p.stream_type()
                if st == rs.stream.depth and depth_profile is None and p.format() == rs.format.z16:
                    depth_profile = p.as_video_stream_profile()
                    self._sensors.append((s, p))
                    if s.is_depth_sensor():
                        depth_scale = s.as_depth_sensor().get_depth_scale()
                    break
                if st == rs.stream.color and color_profile is None:
                    color_profile = p.as_video_stream_profile()
                    self._sensors.append((s, p))
                    break
        if depth_profile is None or color_profile is None:
            missing = "depth (Z16)" if depth_profile is None else "colour"
            raise UserError(f"{self.path}: the recording has no {missing} stream")
        self._color_format = color_profile.format()
        if self._color_format not in (
            rs.format.rgb8,
            rs.format.bgr8,
            rs.format.rgba8,
            rs.format.bgra8,
            rs.format.yuyv,
        ):
            raise UserError(f"{self.path}: colour format {self._color_format} is not supported")
        fps = float(rate_hz or color_profile.fps() or 30)
        ci = color_profile.get_intrinsics()
        di = depth_profile.get_intrinsics()
        self.intrinsics = intrinsics_from_rs(ci, depth_scale=depth_scale, rate_hz=fps)
        self.rate_hz = fps
        try:
            ex = depth_profile.get_extrinsics_to(color_profile)
            identity = np.allclose(ex.rotation, np.eye(3).ravel(), atol=1e-9) and np.allclose(
                ex.translation, 0.0
            )
        except RuntimeError:
            identity = True  # no extrinsic recorded: treat the streams as co-located
        same = (di.width, di.height) == (ci.width, ci.height) and np.allclose(
            [di.fx, di.fy, di.ppx, di.ppy], [ci.fx, ci.fy, ci.ppx, ci.ppy], rtol=0, atol=1e-6
        )
        #: True when depth goes through ``rs.align(rs.stream.color)`` (not already registered to colour).
        self.needs_align = not (identity and same)
        self._align = rs.align(rs.stream.color) if self.needs_align else None
        self._queue: queue.Queue = queue.Queue(maxsize=4)
        self._stop = threading.Event()
        self._go = threading.Event()
        self._started = False
        self._closed = False
        self._t0_ms: float | None = None
        self._n = 0
        #: Frames that found no partner and were skipped.
        self.unpaired = 0

    # -- playback thread side ------------------------------------------------------------------------

    def _callback(self, f) -> None:
        # Runs on the playback thread. In non-real-time mode the playback waits for this to return,
        # so blocking here until the consumer has room throttles the file reading.
        self._go.wait()
        f.keep()
        stream = "depth" if f.get_profile().stream_type() == self._rs.stream.depth else "color"
        item = _Item(stream, f, float(f.get_timestamp()))
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.05)
                return
            except queue.Full:
                continue

    def _start(self) -> None:
        if self._started:
            return
        self._started = True
        try:
            for s, p in self._sensors:
                s.open(p)
                s.start(self._callback)
        except RuntimeError as e:
            raise UserError(f"{self.path}: cannot start playback ({e})") from None
        # The callback holds the first frame until every sensor has started, so none is lost.
        self._go.set()

    # -- consumer side -------------------------------------------------------------------------------

    def _next_item(self) -> _Item | None:
        rs = self._rs
        waited = 0.0
        while True:
            try:
                return self._queue.get(timeout=0.05)
            except queue.Empty:
                if self._pb.current_status() == rs.playback_status.stopped:
                    try:  # the last frame may have been queued just before the status changed
                        return self._queue.get_nowait()
                    except queue.Empty:
                        return None
                waited += 0.05
                if waited > STALL_TIMEOUT_S:
                    raise SourceError(
                        f"{self.path}: playback stalled (no frame for {STALL_TIMEOUT_S:g} s)"
                    ) from None

    def _to_rgb(self, c) -> np.ndarray:
        rs = self._rs
        a = np.asanyarray(c.get_data())
        fmt = self._color_format
        if fmt == rs.format.rgb8:
            return a.copy()
        if fmt == rs.format.bgr8:
            return cv2.cvtColor(a, cv2.COLOR_BGR2RGB)
        if fmt == rs.format.rgba8:
            return np.ascontiguousarray(a[..., :3])
        if fmt == rs.format.bgra8:
            return cv2.cvtColor(a, cv2.COLOR_BGRA2RGB)
        return cv2.cvtColor(a.reshape(a.shape[0], -1, 2), cv2.COLOR_YUV2RGB_YUYV)

    def _compose_and_align(self, depth, color):
        rs = self._rs
        pair = {}

        def combine(_f, source):
            source.frame_ready(source.allocate_composite_frame([pair["d"], pair["c"]]))

        pair["d"], pair["c"] = depth, color
        block = rs.processing_block(combine)
        out = rs.frame_queue(1)
        block.start(out)
        block.invoke(depth)
        fs = out.wait_for_frame().as_frameset()
        aligned = self._align.process(fs)
        return aligned.get_depth_frame(), aligned.get_color_frame()

    def _make_frame(self, depth: _Item, color: _Item) -> CameraFrame:
        K = self.intrinsics
        d, c = depth.frame, color.frame
        if self._align is not None:
            d, c = self._compose_and_align(d, c)
        rgb = self._to_rgb(c)
        units = np.asanyarray(d.get_data())
        if rgb.shape != (K.height, K.width, 3) or units.shape != (K.height, K.width):
            raise SourceError(
                f"{self.path}: frame {self._n} has colour {rgb.shape} / depth {units.shape}, "
                f"expected {K.height}x{K.width}"
            )
        if self._t0_ms is None:
            self._t0_ms = color.t_ms
        frame = CameraFrame(
            color=rgb,
            depth_m=units.astype(np.float64) * K.depth_scale,
            t=(color.t_ms - self._t0_ms) / 1000.0,
            intrinsics=K,
            extras={
                "timestamp_ms": color.t_ms,
                "frame_number": int(c.get_frame_number()),
                "index": self._n,
                "source": "bag",
            },
        )
        self._n += 1
        return frame

    def __iter__(self) -> Iterator[CameraFrame]:
        if self._closed:
            raise ValueError(f"{self.path}: the reader is closed")
        self._start()
        tol_ms = 500.0 / self.rate_hz
        depths: deque[_Item] = deque()
        colors: deque[_Item] = deque()
        try:
            while True:
                item = self._next_item()
                if item is None:
                    self.unpaired += len(depths) + len(colors)
                    return
                (depths if item.stream == "depth" else colors).append(item)
                # pair the oldest colour frame with the depth frame nearest to it in time
                while colors and depths:
                    c = colors[0]
                    best = min(depths, key=lambda d, c=c: abs(d.t_ms - c.t_ms))
                    if abs(best.t_ms - c.t_ms) <= tol_ms:
                        while depths[0] is not best:
                            depths.popleft()
                            self.unpaired += 1
                        depths.popleft()
                        colors.popleft()
                        yield self._make_frame(best, c)
                    elif depths[-1].t_ms > c.t_ms + tol_ms:
                        colors.popleft()  # its depth frame will not come any more
                        self.unpaired += 1
                    else:
                        break
                while len(depths) > 8:
                    depths.popleft()
                    self.unpaired += 1
        finally:
            depths.clear()
            colors.clear()

    def close(self) -> None:
        """Stop the playback and release the file; later calls do nothing."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._go.set()
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        if self._started:
            for s, _ in self._sensors:
                try:
                    s.stop()
                except RuntimeError:
                    pass
                try:
                    s.close()
                except RuntimeError:
                    pass
        self._sensors = []
        self._pb = None
        self._ctx = None

    def __enter__(self) -> BagReader:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass
