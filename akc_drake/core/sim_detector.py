"""A simulated 2D pose-landmark detector for rendered frames (stands in for MediaPipe BlazePose).

It knows the true landmarks (``frame.truth_C``, from the simulation) and looks at the rendered depth image
to tell how hidden each landmark is, as a detector would from the image:

* Pixels: the true landmark projected with the pinhole model, plus Gaussian pixel noise (larger for
  hidden landmarks, whose position the network has to infer).
* Visibility: around each landmark's pixel (a disc of radius :attr:`SimulatedDetector.window_m` at the
  landmark's depth) the share of valid depth pixels whose surface lies clearly in front of the landmark's
  own surface (by more than the body radius there plus :attr:`occlusion_margin_m`) is hidden. Hiding by the
  landmark's own arm (a surface near that arm's bones) counts only :attr:`self_occlusion_weight` as much:
  like BlazePose, the detector sees the arm lead to a joint behind it and stays fairly confident. The
  score falls linearly from :attr:`visible_score` (nothing hidden) to :attr:`occluded_score` (all hidden
  by something else), plus a little noise.

  So, as in the paper, visibility alone misses most self-occlusions: a shoulder behind its own forearm and
  hand (Motion II) mostly keeps a score above 0.7 while its depth reading is the occluder's, which is
  what the paper's proximity check catches; the fully hidden frames, and anything hidden by another body
  part, fall below 0.7. With the defaults a landmark scores below 0.7 when about 40 % of its
  neighbourhood is hidden by something else, or about 67 % by its own arm.

Everything is reproducible from ``seed`` and the frame time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from akc_drake.core.camera import CameraFrame, Detection2D, project
from akc_drake.core.depth_noise import frame_rng
from akc_drake.core.skeleton import INDEX, LANDMARKS, NUM_LANDMARKS

#: Radius of the body around each landmark (metres): the depth of the landmark's own visible surface is
#: about this much less than the landmark's (joint centre) depth. Defaults match the operator model.
DEFAULT_SURFACE_RADIUS_M: dict[str, float] = {
    "shoulder": 0.055,
    "elbow": 0.045,
    "wrist": 0.032,
    "pinky": 0.015,
    "index": 0.015,
    "hip": 0.095,
}


def _default_radii() -> np.ndarray:
    return np.array([DEFAULT_SURFACE_RADIUS_M[name.split("_", 1)[1]] for name in LANDMARKS])


_LANDMARK_SIDE = tuple(name.split("_", 1)[0] for name in LANDMARKS)
_LANDMARK_ON_ARM = tuple(not name.endswith("_hip") for name in LANDMARKS)
#: Fingertips lie about twice as far from the wrist as the knuckles.
_FINGERTIP_FACTOR = 2.0


def _arm_bones(truth: np.ndarray, side: str) -> np.ndarray | None:
    """``(3, 2, 3)`` bones of one arm (shoulder-elbow, elbow-wrist, wrist-fingertips); None if any is NaN."""
    s, e, w, i, p = (truth[INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist", "index", "pinky"))
    tip = w + _FINGERTIP_FACTOR * ((i + p) / 2.0 - w)
    bones = np.array([[s, e], [e, w], [w, tip]])
    return bones if np.all(np.isfinite(bones)) else None


def _distance_to_bones(points: np.ndarray, bones: np.ndarray) -> np.ndarray:
    """Distance of each point ``(n, 3)`` to the nearest of the segments ``(m, 2, 3)``."""
    best = np.full(len(points), np.inf)
    for a, b in bones:
        ab = b - a
        L2 = float(ab @ ab)
        t = np.zeros(len(points)) if L2 == 0.0 else np.clip((points - a) @ ab / L2, 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[:, None] * ab), axis=1)
        best = np.minimum(best, d)
    return best


@dataclass
class SimulatedDetector:
    """Detector protocol implementation for simulated frames (needs ``frame.truth_C``).

    Attributes:
        pixel_noise_px: standard deviation of the 2D landmark noise for a visible landmark (pixels).
        hidden_noise_gain: the pixel noise grows to ``pixel_noise_px * (1 + gain)`` for a fully hidden one.
        visible_score: visibility of an unoccluded landmark.
        occluded_score: visibility of a fully occluded landmark.
        score_noise: standard deviation of the noise added to the visibility score.
        window_m: radius (metres, at the landmark's depth) of the neighbourhood the visibility judges.
        occlusion_margin_m: a surface counts as occluding when it is this much in front of the
            landmark's own surface.
        surface_radius_m: ``(12,)`` body radius around each landmark (see :data:`DEFAULT_SURFACE_RADIUS_M`).
        self_occlusion_weight: how much hiding by the landmark's own arm counts (1: as any other occluder).
        limb_radius_m: a hiding surface within this distance of the landmark's own arm bones belongs to
            that arm.
        miss_rate: probability that a landmark is not detected at all in a frame (NaN pixel, visibility 0).
        seed: seeds the noise (combined with the frame time).
        name: the detector's name.
    """

    pixel_noise_px: float = 1.5
    hidden_noise_gain: float = 1.0
    visible_score: float = 0.97
    occluded_score: float = 0.30
    score_noise: float = 0.03
    window_m: float = 0.08
    occlusion_margin_m: float = 0.04
    surface_radius_m: np.ndarray = field(default_factory=_default_radii)
    self_occlusion_weight: float = 0.6
    limb_radius_m: float = 0.07
    miss_rate: float = 0.0
    seed: int = 0
    name: str = "simulated"

    #: The detector reads only ``truth_C`` and ``depth_m``: a renderer may skip the colour image.
    needs_color = False
    #: ... and the label image.
    needs_label = False

    def __post_init__(self):
        for attr in ("pixel_noise_px", "hidden_noise_gain", "score_noise", "window_m", "occlusion_margin_m"):
            v = getattr(self, attr)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"SimulatedDetector.{attr} must be a number >= 0, got {v!r}")
        for attr in ("limb_radius_m",):
            v = getattr(self, attr)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"SimulatedDetector.{attr} must be a number >= 0, got {v!r}")
        for attr in ("visible_score", "occluded_score", "miss_rate", "self_occlusion_weight"):
            v = getattr(self, attr)
            if not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
                raise ValueError(f"SimulatedDetector.{attr} must be in [0, 1], got {v!r}")
        r = np.asarray(self.surface_radius_m, dtype=float)
        if r.shape != (NUM_LANDMARKS,) or not np.all(np.isfinite(r)) or np.any(r < 0):
            raise ValueError(
                f"SimulatedDetector.surface_radius_m must be {NUM_LANDMARKS} lengths >= 0, got {r!r}"
            )
        self.surface_radius_m = r

    def occluded_share(self, frame: CameraFrame, uv: np.ndarray | None = None) -> np.ndarray:
        """``(12,)`` share of each landmark's neighbourhood hidden by a nearer surface (NaN: unknown).

        Args:
            frame: the frame (uses ``truth_C``, ``depth_m``, ``intrinsics``).
            uv: the true pixels (default: projected from ``truth_C``).
        """
        return self.occlusion_shares(frame, uv)[0]

    def occlusion_shares(
        self, frame: CameraFrame, uv: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Hidden share of each landmark's neighbourhood, in all and by the landmark's own arm.

        A hiding pixel belongs to the landmark's own arm when its 3D point (the pixel deprojected at its
        depth) lies within :attr:`limb_radius_m` of that arm's bones (shoulder-elbow, elbow-wrist,
        wrist-fingertips, from ``truth_C``). Hips have no own arm.

        Returns:
            ``(total (12,), own_arm (12,))`` shares in [0, 1]; NaN where unknown (no valid depth around).
        """
        K = frame.intrinsics
        truth = np.asarray(frame.truth_C, dtype=float)
        if uv is None:
            uv = project(truth, K)
        depth = np.asarray(frame.depth_m)
        H, W = depth.shape[:2]
        total = np.full(NUM_LANDMARKS, np.nan)
        own = np.full(NUM_LANDMARKS, np.nan)
        bones = {side: _arm_bones(truth, side) for side in ("left", "right")}
        for j in range(NUM_LANDMARKS):
            u, v = uv[j]
            z = truth[j, 2]
            if not (math.isfinite(u) and math.isfinite(v) and z > 0):
                continue
            r = max(1, int(round(self.window_m * K.fx / z)))
            iu, iv = int(round(u)), int(round(v))
            u0, u1, v0, v1 = max(iu - r, 0), min(iu + r + 1, W), max(iv - r, 0), min(iv + r + 1, H)
            if u0 >= u1 or v0 >= v1:
                continue
            patch = depth[v0:v1, u0:u1]
            dv, du = np.ogrid[v0 - iv : v1 - iv, u0 - iu : u1 - iu]
            inside = (du * du + dv * dv) <= r * r
            valid = inside & (patch > 0) & np.isfinite(patch)
            n = int(np.count_nonzero(valid))
            if n == 0:
                continue
            hiding = valid & (patch < z - self.surface_radius_m[j] - self.occlusion_margin_m)
            total[j] = np.count_nonzero(hiding) / n
            arm = bones.get(_LANDMARK_SIDE[j]) if _LANDMARK_ON_ARM[j] else None
            if arm is None or total[j] == 0.0:
                own[j] = 0.0
                continue
            rows, cols = np.nonzero(hiding)
            zz = patch[rows, cols].astype(float)
            pts = np.stack([(cols + u0 - K.cx) * zz / K.fx, (rows + v0 - K.cy) * zz / K.fy, zz], axis=1)
            own[j] = np.count_nonzero(_distance_to_bones(pts, arm) < self.limb_radius_m) / n
        return total, own

    def detect(self, frame: CameraFrame) -> Detection2D:
        """Landmark pixels and visibility for a simulated frame.

        Raises:
            ValueError: the frame has no ``truth_C`` (this detector works on simulated frames only).
        """
        if frame.truth_C is None:
            raise ValueError("SimulatedDetector needs frame.truth_C (the simulated ground truth); got None")
        truth = np.asarray(frame.truth_C, dtype=float)
        if truth.shape != (NUM_LANDMARKS, 3):
            raise ValueError(f"frame.truth_C must have shape ({NUM_LANDMARKS}, 3), got {truth.shape}")
        K = frame.intrinsics
        uv_true = project(truth, K)
        total, own = self.occlusion_shares(frame, uv_true)
        rng = frame_rng(self.seed, int(round(frame.t * 1000.0)))
        total = np.where(np.isfinite(total), total, 0.0)
        own = np.where(np.isfinite(own), own, 0.0)
        sigma = self.pixel_noise_px * (1.0 + self.hidden_noise_gain * total)
        uv = uv_true + rng.standard_normal((NUM_LANDMARKS, 2)) * sigma[:, None]
        # Hiding by the landmark's own arm counts only partly: the network sees the arm lead there.
        hidden = (total - own) + self.self_occlusion_weight * own
        vis = self.visible_score - (self.visible_score - self.occluded_score) * hidden
        vis = np.clip(vis + self.score_noise * rng.standard_normal(NUM_LANDMARKS), 0.0, 1.0)
        inside = (
            (uv[:, 0] >= -0.5)
            & (uv[:, 0] <= K.width - 0.5)
            & (uv[:, 1] >= -0.5)
            & (uv[:, 1] <= K.height - 0.5)
        )
        inside &= np.all(np.isfinite(uv), axis=1)
        if self.miss_rate > 0:
            inside &= rng.random(NUM_LANDMARKS) >= self.miss_rate
        uv[~inside] = np.nan
        vis[~inside] = 0.0
        return Detection2D(uv=uv, visibility=vis, person_found=bool(np.any(inside)))
