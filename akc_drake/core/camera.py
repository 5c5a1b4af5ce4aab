"""Pinhole camera model, depth lookup and the 2D-detector interface (stage S2's pure part).

Camera frame C: x right, y down, z forward (depth), metres. Pixels ``(u, v)``: u to the right,
v down, origin at the top-left pixel's centre.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from akc_drake.core.skeleton import NUM_LANDMARKS


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of an RGB-D camera whose depth is aligned to colour.

    Attributes:
        width, height: image size in pixels.
        fx, fy: focal lengths in pixels.
        cx, cy: principal point in pixels.
        depth_scale: metres per unit of the uint16 depth image (RealSense default 0.001).
        rate_hz: frame rate.
    """

    width: int = 640
    height: int = 480
    fx: float = 615.0
    fy: float = 615.0
    cx: float = 319.5
    cy: float = 239.5
    depth_scale: float = 0.001
    rate_hz: float = 10.0

    def __post_init__(self):
        for name in ("width", "height"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or v <= 0:
                raise ValueError(f"intrinsics.{name} must be a positive integer, got {v!r}")
        for name in ("fx", "fy", "depth_scale", "rate_hz"):
            v = getattr(self, name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"intrinsics.{name} must be a positive number, got {v!r}")
        for name in ("cx", "cy"):
            v = getattr(self, name)
            if not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise ValueError(f"intrinsics.{name} must be a finite number, got {v!r}")

    @property
    def fov_y(self) -> float:
        """Vertical field of view, radians."""
        return 2.0 * math.atan(self.height / (2.0 * self.fy))

    def K(self) -> np.ndarray:
        """The 3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict, *, where: str = "intrinsics") -> CameraIntrinsics:
        """Build from a mapping (e.g. ``intrinsics.json``); a ``ValueError`` names ``where`` and the key."""
        if not isinstance(d, dict):
            raise ValueError(f"{where}: expected a JSON object")
        known = {f for f in cls.__dataclass_fields__}
        unknown = [k for k in d if k not in known]
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}")
        missing = [k for k in ("width", "height", "fx", "fy", "cx", "cy") if k not in d]
        if missing:
            raise ValueError(f"{where}: missing {', '.join(missing)}")
        try:
            return cls(**d)
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None

    @classmethod
    def load(cls, path) -> CameraIntrinsics:
        with open(path, encoding="utf-8") as f:
            try:
                d = json.load(f)
            except json.JSONDecodeError as e:
                raise ValueError(f"{path}: not valid JSON ({e})") from None
        return cls.from_dict(d, where=str(path))


def project(p_C: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """Project points ``(..., 3)`` in C to pixels ``(..., 2)``; NaN for points at or behind z = 0."""
    p = np.asarray(p_C, dtype=float)
    z = p[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K.fx * p[..., 0] / z + K.cx
        v = K.fy * p[..., 1] / z + K.cy
    uv = np.stack([u, v], axis=-1)
    uv[~(z > 0)] = np.nan
    return uv


def deproject(uv: np.ndarray, z: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """Pinhole inverse projection of pixels ``(..., 2)`` at depths ``(...)`` to points ``(..., 3)`` in C.

    NaN in ``uv`` or ``z`` gives NaN in the corresponding coordinates (x, y stay NaN when z is NaN,
    because metric x and y need the depth).
    """
    uv = np.asarray(uv, dtype=float)
    z = np.asarray(z, dtype=float)
    x = (uv[..., 0] - K.cx) * z / K.fx
    y = (uv[..., 1] - K.cy) * z / K.fy
    return np.stack([x, y, z], axis=-1)


#: The depth-lookup rules (:func:`depth_lookup`).
DEPTH_RULES: tuple[str, ...] = ("median", "nearest")
#: ``nearest``: a gap between sorted depths wider than this separates two surfaces (a body is about 20 cm
#: thick: a surface farther than that behind the nearer one is the background, or another body part behind).
NEAREST_GAP_M = 0.20
#: ``nearest``: the nearer surface must cover at least this share of the window's valid pixels (and 3 pixels),
#: so that a few pixels of an edge or of the depth noise do not decide.
NEAREST_MIN_SHARE = 0.25


def nearest_surface_depth(depths: np.ndarray, gap_m: float = NEAREST_GAP_M,
                          min_share: float = NEAREST_MIN_SHARE) -> float:
    """The depth of the nearest surface in a set of valid depths: the median of the nearest cluster.

    The sorted depths are split wherever two neighbours differ by more than ``gap_m``; the answer is the median
    of the nearest cluster that holds at least ``min_share`` of the depths (and at least 3), or of them all when
    no cluster does.

    Args:
        depths: ``(n,)`` valid depths (metres), n >= 1, any order.
        gap_m: the gap that separates two surfaces.
        min_share: the share of the depths the chosen cluster must hold.

    Returns:
        The depth in metres.
    """
    d = np.sort(np.asarray(depths, dtype=float).ravel())
    n = d.size
    need = max(3.0, min_share * n)
    start = 0
    for end in (*np.flatnonzero(np.diff(d) > gap_m), n - 1):
        if end + 1 - start >= need:
            return float(np.median(d[start:end + 1]))
        start = end + 1
    return float(np.median(d))


def depth_lookup(
    depth_m: np.ndarray,
    uv: np.ndarray,
    *,
    window: int = 5,
    min_depth: float = 0.2,
    max_depth: float = 10.0,
    rule: str = "median",
) -> np.ndarray:
    """Depth at each pixel, from the valid depths in a ``window`` x ``window`` patch around it.

    Rules:

    * ``median``: their median. A landmark whose patch straddles the body's edge (a wrist, a knuckle, a shoulder
      or hip on the silhouette) reads the background behind when most of the patch is background.
    * ``nearest``: the nearest surface that covers a quarter of the patch (:func:`nearest_surface_depth`): the
      body in front of the background wins as soon as it covers that much. MediaPipe on the skinned body (a
      15-pixel window): the wrists' and knuckles' readings 40 cm or more behind the joint fall two- to fourfold, and
      the filters' and AKC+'s mean 3D arm errors by 1-30 % (docs/results.md, "The depth lookup's nearest surface").
      Its price: an occluder in front (a fist over a shoulder) that covers a quarter of the patch is read where the
      median read the joint; the occlusion filter and AKC+ deal with most of those.

    Args:
        depth_m: ``(H, W)`` depth image in metres (0 or NaN where invalid).
        uv: ``(N, 2)`` pixel coordinates (NaN rows allowed).
        window: odd patch size in pixels.
        min_depth, max_depth: depths outside this range count as invalid.
        rule: ``median`` or ``nearest``.

    Returns:
        ``(N,)`` depths in metres; NaN where the pixel is missing, outside the image or has no valid depth.
    """
    if rule not in DEPTH_RULES:
        raise ValueError(f"rule must be one of {', '.join(DEPTH_RULES)}, got {rule!r}")
    d = np.asarray(depth_m)
    H, W = d.shape[:2]
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    out = np.full(len(uv), np.nan)
    r = max(int(window) // 2, 0)
    nearest = rule == "nearest"
    for n, (u, v) in enumerate(uv):
        if not (math.isfinite(u) and math.isfinite(v)):
            continue
        iu, iv = int(round(u)), int(round(v))
        if iu < 0 or iv < 0 or iu >= W or iv >= H:
            continue
        patch = d[max(iv - r, 0) : iv + r + 1, max(iu - r, 0) : iu + r + 1].astype(float).ravel()
        patch = patch[(patch >= min_depth) & (patch <= max_depth)]
        if patch.size:
            out[n] = nearest_surface_depth(patch) if nearest else float(np.median(patch))
    return out


@dataclass
class CameraFrame:
    """One RGB-D frame as a detector sees it.

    Attributes:
        color: ``(H, W, 3)`` uint8 RGB.
        depth_m: ``(H, W)`` float depth in metres (0 where invalid), aligned to ``color``.
        t: timestamp in seconds.
        intrinsics: the camera's intrinsics.
        truth_C: ``(J, 3)`` true landmark positions in C when the source is simulated, else None.
        label: ``(H, W)`` integer label image when the source is simulated (which body part each
            pixel shows), else None.
        extras: anything else a source wants a detector to see.
    """

    color: np.ndarray
    depth_m: np.ndarray
    t: float
    intrinsics: CameraIntrinsics
    truth_C: np.ndarray | None = None
    label: np.ndarray | None = None
    extras: dict = field(default_factory=dict)


@dataclass
class Detection2D:
    """A detector's answer for one frame.

    Attributes:
        uv: ``(J, 2)`` pixel coordinates in :data:`~akc_drake.core.skeleton.LANDMARKS` order, NaN where none.
        visibility: ``(J,)`` in [0, 1] (0 where none).
        person_found: False when the detector found nobody.
    """

    uv: np.ndarray
    visibility: np.ndarray
    person_found: bool = True

    @classmethod
    def empty(cls) -> Detection2D:
        return cls(np.full((NUM_LANDMARKS, 2), np.nan), np.zeros(NUM_LANDMARKS), False)


@runtime_checkable
class Detector(Protocol):
    """A 2D pose-landmark detector that :class:`~akc_drake.systems.landmark_extractor.LandmarkExtractor` calls.

    Implementations: the simulated detector (on renders, uses ``frame.truth_C`` and ``frame.label``)
    and MediaPipe's PoseLandmarker (on real images, uses ``frame.color`` and ``frame.t``).
    """

    name: str

    def detect(self, frame: CameraFrame) -> Detection2D: ...
