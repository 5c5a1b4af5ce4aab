"""Stage S2's numpy part: depth lookup, surface-to-centre correction and pinhole deprojection of detections.

The detector is pluggable (any :class:`akc_drake.core.camera.Detector`: the simulated detector on renders,
MediaPipe on real images). For each landmark the depth is read from the valid depth pixels in a window around
its detected pixel (:func:`akc_drake.core.camera.depth_lookup`; NaN when there are none): by default the
nearest surface covering a quarter of a 15-pixel window at 640x480, scaled with the focal length (``nearest``;
a landmark on the body's edge then reads the body, not the background behind it), or their median in a 5-pixel
window (``median``, the ``paper`` protocol's); the 3D point is the pinhole deprojection of the pixel at that depth
(:func:`akc_drake.core.camera.deproject`).
Nothing here knows about occlusion: a landmark hidden behind a limb gets the limb's depth. Stage S3 decides.
The LeafSystem around it is :class:`akc_drake.systems.landmark_extractor.LandmarkExtractor`.

Surface-to-centre correction. A depth camera reads the body's *surface*; the landmarks are joint *centres*
(and knuckles) inside the body. So every raw depth is short by about the body's half-thickness at that
joint, for a real RealSense + MediaPipe exactly as for the rendered operator. Before deprojection each
landmark's point is pushed ``surface_offset_m[j]`` further along its pixel ray: the measured range
``rho = z |d|`` (``d = ((u - cx) / fx, (v - cy) / fy, 1)``) becomes ``rho + offset``, i.e.
``z_centre = z_surface + offset / |d|``. This is exact for a sphere (or a cylinder seen across its axis)
centred on the joint and viewed through its centre, where the ray meets the surface along its normal; for
a limb seen obliquely the ray is not normal to the surface and the true surface-to-centre distance along
the ray is larger (up to ``radius / cos(angle)``), so the correction is approximate there. Near the image
centre ``|d|`` is about 1 and the correction is simply ``z_centre ~ z_surface + offset``. It is applied to
whatever the depth reads, also when that is an occluder (stage S3 rejects those). ``surface_offset_m = 0``
turns it off.
"""

from __future__ import annotations

import functools

import numpy as np

from akc_drake.core.camera import DEPTH_RULES, CameraFrame, CameraIntrinsics, Detector, deproject, depth_lookup
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS

#: The extractor's depth lookup by default: the nearest surface (:func:`~akc_drake.core.camera.depth_lookup`)
#: in a window of :data:`DEFAULT_DEPTH_WINDOW` pixels at a :data:`REFERENCE_FOCAL_PX` focal length (4.9 cm at
#: 2 m: about a wrist's width), scaled with the camera's focal length (:func:`default_depth_window`).
DEFAULT_DEPTH_RULE = "nearest"
DEFAULT_DEPTH_WINDOW = 15
REFERENCE_FOCAL_PX = 615.0


def default_depth_window(intrinsics: CameraIntrinsics | None = None) -> int:
    """The default depth-lookup window for a camera: :data:`DEFAULT_DEPTH_WINDOW` pixels at a
    :data:`REFERENCE_FOCAL_PX` focal length (the RealSense D435's colour camera at 640x480), scaled with the
    focal length to the nearest odd number, so that it covers the same patch of a body at the same distance
    (15 at 640x480; 23 at 1280x720 with a 920-pixel focal length; 3 at 160x120)."""
    fx = (intrinsics or CameraIntrinsics()).fx
    return 2 * max(int(round((DEFAULT_DEPTH_WINDOW * fx / REFERENCE_FOCAL_PX - 1.0) / 2.0)), 0) + 1

#: Default surface-to-centre offset per joint type (metres): half the body's thickness at the joint, seen
#: from the front, for a typical adult. These are our estimates from common anthropometric sizes, not
#: measured values: shoulder ~0.05 (the glenohumeral centre lies about 5 cm behind the front of the
#: deltoid, upper-arm depth at the deltoid ~10-11 cm); elbow ~0.04 (elbow depth with soft tissue ~8 cm);
#: wrist ~0.025 (wrist about 4 cm thick and 5.5-6 cm wide: a mean half-thickness of ~2.5 cm); knuckles
#: (index and pinky MCP) ~0.015 (hand about 3 cm thick at the knuckles, seen face-on); hip ~0.09 (the hip
#: joint centre sits about mid-depth of a ~18 cm thick upper thigh/groin). The simulated operator
#: (:class:`akc_drake.operator.model.OperatorParams`) has deltoid 0.055, elbow 0.045, wrist 0.032-0.035,
#: knuckles 0.015 and hip 0.095 (half the pelvis depth): close to, but deliberately not tuned to, these.
DEFAULT_SURFACE_OFFSET_M: dict[str, float] = {
    "shoulder": 0.05,
    "elbow": 0.04,
    "wrist": 0.025,
    "pinky": 0.015,
    "index": 0.015,
    "hip": 0.09,
}


def surface_offsets(spec=None) -> np.ndarray:
    """The ``(12,)`` per-landmark surface-to-centre offsets (metres) described by ``spec``.

    Args:
        spec: None (the defaults, :data:`DEFAULT_SURFACE_OFFSET_M`), a number (the same offset for all
            landmarks; 0 turns the correction off), ``(12,)`` offsets in
            :data:`~akc_drake.core.skeleton.LANDMARKS` order, or a mapping from joint type (``"shoulder"``,
            ``"elbow"``, ``"wrist"``, ``"index"``, ``"pinky"``, ``"hip"``) or landmark name
            (``"left_wrist"``) to an offset; joints a mapping leaves out keep their default.

    Returns:
        ``(12,)`` float64 offsets, each finite and in [0, 0.5] m.

    Raises:
        ValueError: naming the bad key or value.
    """
    default = np.array([DEFAULT_SURFACE_OFFSET_M[name.split("_", 1)[1]] for name in LANDMARKS])
    if spec is None:
        out = default
    elif isinstance(spec, dict):
        out = default.copy()
        for key, value in spec.items():
            names = [n for n in LANDMARKS if n == key or n.split("_", 1)[1] == key]
            if not names:
                raise ValueError(
                    f"surface_offset_m: unknown joint {key!r}; use one of "
                    f"{', '.join(DEFAULT_SURFACE_OFFSET_M)} or a landmark name"
                )
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"surface_offset_m[{key!r}] must be a number, got {value!r}") from None
            for n in names:
                out[LANDMARKS.index(n)] = v
    else:
        try:
            a = np.asarray(spec, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"surface_offset_m must be a number or {NUM_LANDMARKS} numbers, got {spec!r}"
            ) from None
        if a.ndim == 0:
            out = np.full(NUM_LANDMARKS, float(a))
        elif a.shape == (NUM_LANDMARKS,):
            out = a.copy()
        else:
            raise ValueError(
                f"surface_offset_m must be a number or {NUM_LANDMARKS} numbers, got shape {a.shape}"
            )
    bad = ~np.isfinite(out) | (out < 0) | (out > 0.5)
    if np.any(bad):
        j = int(np.flatnonzero(bad)[0])
        raise ValueError(f"surface_offset_m[{LANDMARKS[j]!r}] must be in [0, 0.5] m, got {out[j]!r}")
    return out


def surface_to_centre_depth(
    uv: np.ndarray, z: np.ndarray, offset_m: np.ndarray, K: CameraIntrinsics
) -> np.ndarray:
    """Depths of points ``offset_m`` further along their pixel rays than the surface depths ``z``.

    ``z_centre = z + offset / |d|`` with ``d = ((u - cx) / fx, (v - cy) / fy, 1)`` (the range along the ray
    grows by ``offset``); see the module docstring for when this is exact. NaN stays NaN.

    Args:
        uv: ``(N, 2)`` pixels. z: ``(N,)`` surface depths (metres). offset_m: ``(N,)`` offsets (metres).
        K: the camera.

    Returns:
        ``(N,)`` corrected depths.
    """
    uv = np.asarray(uv, dtype=float)
    dx = (uv[..., 0] - K.cx) / K.fx
    dy = (uv[..., 1] - K.cy) / K.fy
    return np.asarray(z, dtype=float) + np.asarray(offset_m, dtype=float) / np.sqrt(1.0 + dx * dx + dy * dy)


def extract_landmarks(
    frame: CameraFrame,
    detector: Detector,
    *,
    window: int | None = None,
    min_depth: float = 0.2,
    max_depth: float = 10.0,
    surface_offset_m=None,
    depth_rule: str = DEFAULT_DEPTH_RULE,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detect, look up depth, correct it from the body surface to the joint centre and deproject.

    Args:
        frame: the RGB-D frame.
        detector: any Detector.
        window: depth-lookup window (odd, pixels); None: :func:`default_depth_window` of the frame's camera.
        min_depth, max_depth: valid depth range (metres).
        depth_rule: the depth lookup's rule, ``nearest`` or ``median`` (:func:`~akc_drake.core.camera.depth_lookup`).
        surface_offset_m: surface-to-centre offsets, as :func:`surface_offsets` takes them (None: the
            defaults; 0: no correction).

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
    offsets = surface_offsets(surface_offset_m)
    if frame.extras.get("depth_is_surface", True) is False:
        offsets = np.zeros_like(offsets)  # e.g. a constant --depth for a video: already a joint depth
    if window is None:
        window = default_depth_window(frame.intrinsics)
    z = depth_lookup(frame.depth_m, uv, window=window, min_depth=min_depth, max_depth=max_depth, rule=depth_rule)
    if np.any(offsets):
        z = surface_to_centre_depth(uv, z, offsets, frame.intrinsics)
    return deproject(uv, z, frame.intrinsics), vis, uv


def check_extractor_options(detector, intrinsics, window, period_s, depth_rule: str = DEFAULT_DEPTH_RULE) -> float:
    """Validate a landmark extractor's options; returns the sampling period (default ``1 / rate_hz``).

    Args:
        detector: must implement the :class:`~akc_drake.core.camera.Detector` protocol.
        intrinsics: a :class:`~akc_drake.core.camera.CameraIntrinsics` (the default camera when None).
        window: depth-lookup window: a positive odd integer.
        period_s: the sampling period, or None for the camera period.
        depth_rule: one of :data:`~akc_drake.core.camera.DEPTH_RULES`.

    Raises:
        ValueError: naming the bad option.
    """
    if not isinstance(detector, Detector):
        raise ValueError(f"detector must implement the Detector protocol (name, detect), got {detector!r}")
    if intrinsics is not None and not isinstance(intrinsics, CameraIntrinsics):
        raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}")
    if not isinstance(window, (int, np.integer)) or window < 1 or window % 2 == 0:
        raise ValueError(f"window must be a positive odd integer, got {window!r}")
    if depth_rule not in DEPTH_RULES:
        raise ValueError(f"depth_rule must be one of {', '.join(DEPTH_RULES)}, got {depth_rule!r}")
    K = intrinsics or CameraIntrinsics()
    period = 1.0 / K.rate_hz if period_s is None else float(period_s)
    if not period > 0:
        raise ValueError(f"period_s must be positive, got {period_s!r}")
    return period


@functools.lru_cache(maxsize=8)
def black_image(width: int, height: int) -> np.ndarray:
    """A shared read-only ``(height, width, 3)`` uint8 black image (for detectors that ignore colour)."""
    img = np.zeros((height, width, 3), dtype=np.uint8)
    img.flags.writeable = False
    return img


def camera_frame(color, depth, t: float, K, truth=None, label=None) -> CameraFrame:
    """The :class:`CameraFrame` of one sample of the extractor's inputs, after checking the image sizes.

    Args:
        color: ``(H, W, 3)`` uint8 image, or None for a shared black one (:func:`black_image`).
        depth: ``(H, W)`` metres. t: the frame time.
        K: the camera (must be a :class:`CameraIntrinsics` of size ``W x H``).
        truth: ``(12, 3)`` true landmarks or None. label: ``(H, W)`` label image or None.

    Raises:
        ValueError: ``K`` is not a CameraIntrinsics, or an image size differs from it.
    """
    if not isinstance(K, CameraIntrinsics):
        raise ValueError(f"camera_info must hold a CameraIntrinsics, got {type(K).__name__}")
    if color is None:
        color = black_image(K.width, K.height)
    if depth.shape != (K.height, K.width) or color.shape[:2] != (K.height, K.width):
        raise ValueError(
            f"image size {depth.shape[1]}x{depth.shape[0]} (depth), "
            f"{color.shape[1]}x{color.shape[0]} (colour) "
            f"does not match camera_info {K.width}x{K.height}"
        )
    return CameraFrame(color=color, depth_m=depth, t=t, intrinsics=K, truth_C=truth, label=label)
