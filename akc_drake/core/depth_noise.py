"""A stereo (Intel RealSense D435-like) depth error model applied to ideal rendered depth.

An active stereo camera measures disparity ``d = f * b / z`` (focal length ``f`` in pixels, baseline ``b``);
sub-pixel disparity noise of standard deviation ``sigma_d`` gives a depth standard deviation that grows with
the square of the depth::

    sigma_z = z^2 * sigma_d / (f * b)

The matcher also fails where the disparity jumps (depth edges: silhouettes and occluding limbs), and
outside its working range; those pixels read 0 (invalid), as a RealSense reports them.

Neighbouring disparities of a block matcher share most of their matching window, so their errors are not
independent. Independent per-pixel noise (``correlation_px`` 0, the default) averages out in the depth lookup's
window: a 15-pixel median reads a joint's depth with about a tenth of a pixel's noise (0.1 cm at 2 m). Noise
correlated over ``correlation_px`` (the standard deviation of a Gaussian kernel, in pixels) keeps the same per-pixel
RMS and does not: at 4 pixels the 15-pixel median keeps about two thirds of it. That is the case to test a corrector
against whose readings must carry a real camera's depth error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


def frame_rng(seed: int, frame_index: int) -> np.random.Generator:
    """The random generator of one camera frame: reproducible from ``(seed, frame_index)`` alone."""
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, int(frame_index) & 0xFFFFFFFFFFFF])


@dataclass(frozen=True)
class StereoDepthNoise:
    """Parameters of the stereo depth error model.

    Attributes:
        baseline_m: stereo baseline ``b`` (D435: 50 mm).
        sigma_disparity_px: sub-pixel disparity noise ``sigma_d`` (pixels, RMS).
        min_depth_m, max_depth_m: working range; depths outside it read 0.
        edge_disparity_px: a disparity step between neighbouring pixels larger than this is a depth edge.
        edge_width_px: pixels within this distance of a depth edge read 0 (0: no invalid band).
        correlation_px: the disparity noise's correlation length, pixels: the standard deviation of the Gaussian
            kernel that smooths it (its per-pixel RMS stays ``sigma_disparity_px``); 0: independent per pixel.
    """

    baseline_m: float = 0.050
    sigma_disparity_px: float = 0.08
    min_depth_m: float = 0.2
    max_depth_m: float = 10.0
    edge_disparity_px: float = 1.0
    edge_width_px: int = 1
    correlation_px: float = 0.0

    def __post_init__(self):
        for name in ("baseline_m", "min_depth_m", "max_depth_m", "edge_disparity_px"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"StereoDepthNoise.{name} must be a positive number, got {v!r}")
        for name in ("sigma_disparity_px", "correlation_px"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"StereoDepthNoise.{name} must be a number >= 0, got {v!r}")
        if self.min_depth_m >= self.max_depth_m:
            raise ValueError(
                f"StereoDepthNoise: min_depth_m ({self.min_depth_m}) must be below "
                f"max_depth_m ({self.max_depth_m})"
            )
        if not isinstance(self.edge_width_px, (int, np.integer)) or self.edge_width_px < 0:
            raise ValueError(
                f"StereoDepthNoise.edge_width_px must be an integer >= 0, got {self.edge_width_px!r}"
            )

    @classmethod
    def ideal(cls) -> StereoDepthNoise:
        """No noise and no edge invalidation (only the working range applies)."""
        return cls(sigma_disparity_px=0.0, edge_width_px=0)

    def sigma_z(self, z, focal_px: float) -> np.ndarray:
        """Depth standard deviation at depth ``z`` (metres) for a focal length ``focal_px`` (pixels)."""
        z = np.asarray(z, dtype=float)
        return z * z * self.sigma_disparity_px / (focal_px * self.baseline_m)

    def edge_mask(self, depth_m: np.ndarray, focal_px: float) -> np.ndarray:
        """Pixels near a depth edge (a disparity step above :attr:`edge_disparity_px`), ``(H, W)`` bool.

        Pixels without a surface (0, inf or NaN) count as infinitely far (disparity 0).
        """
        z = np.asarray(depth_m, dtype=np.float32)
        if self.edge_width_px == 0:
            return np.zeros(z.shape, dtype=bool)
        with np.errstate(divide="ignore", invalid="ignore"):
            disp = np.float32(focal_px * self.baseline_m) / z
        disp[~np.isfinite(disp) | (z <= 0)] = 0.0
        jump = np.zeros(z.shape, dtype=np.uint8)
        thr = np.float32(self.edge_disparity_px)
        h = np.abs(disp[:, 1:] - disp[:, :-1]) > thr
        v = np.abs(disp[1:, :] - disp[:-1, :]) > thr
        jump[:, 1:] |= h
        jump[:, :-1] |= h
        jump[1:, :] |= v
        jump[:-1, :] |= v
        if self.edge_width_px > 1:
            k = 2 * (self.edge_width_px - 1) + 1
            jump = cv2.dilate(jump, np.ones((k, k), np.uint8))
        return jump.astype(bool)

    def _unit_noise(self, rng: np.random.Generator, shape) -> np.ndarray:
        """Standard normal noise per pixel, smoothed over :attr:`correlation_px` and rescaled to unit variance."""
        n = rng.standard_normal(shape, dtype=np.float32)
        if self.correlation_px <= 0:
            return n
        s = float(self.correlation_px)
        k = cv2.getGaussianKernel(2 * int(math.ceil(3.0 * s)) + 1, s)  # (what GaussianBlur uses for this size)
        n = cv2.GaussianBlur(n, (k.size, k.size), s, borderType=cv2.BORDER_REFLECT)
        # A separable kernel's output variance is the input's times (sum of k^2)^2; away from the borders exact.
        return n * np.float32(1.0 / float(np.sum(k * k)))

    def apply(self, depth_m: np.ndarray, focal_px: float, rng: np.random.Generator | None) -> np.ndarray:
        """A measured depth image from an ideal one.

        Args:
            depth_m: ``(H, W)`` ideal depth in metres (inf, NaN or 0 where nothing was hit).
            focal_px: the depth camera's focal length in pixels.
            rng: the frame's random generator (see :func:`frame_rng`); None: no noise.

        Returns:
            ``(H, W)`` float32 depth in metres; 0 where invalid (edges, outside the working range).
        """
        z = np.array(depth_m, dtype=np.float32, copy=True)
        if z.ndim == 3 and z.shape[2] == 1:
            z = z[:, :, 0]
        if z.ndim != 2:
            raise ValueError(f"depth_m must be an (H, W) image, got shape {np.shape(depth_m)}")
        invalid = self.edge_mask(z, focal_px)
        if rng is not None and self.sigma_disparity_px > 0:
            scale = np.float32(self.sigma_disparity_px / (focal_px * self.baseline_m))
            with np.errstate(invalid="ignore", over="ignore"):
                z += z * z * scale * self._unit_noise(rng, z.shape)
        with np.errstate(invalid="ignore"):
            invalid |= ~((z >= self.min_depth_m) & (z <= self.max_depth_m))
        z[invalid] = 0.0
        return z
