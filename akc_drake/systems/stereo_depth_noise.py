"""The stereo depth-noise model (:mod:`akc_drake.core.depth_noise`) as a Drake system on depth images."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.depth_noise import StereoDepthNoise, frame_rng


class StereoDepthNoiseSystem(LeafSystem):
    """Applies the stereo depth-noise model to an ideal depth image (direct feedthrough).

    The noise of the frame at time ``t`` is drawn from ``frame_rng(seed, round(t * rate_hz))``, so a frame's
    noise depends only on the seed and the frame index.

    .. pydrake_system::

        name: StereoDepthNoiseSystem
        input_ports:
        - depth_image_ideal
        output_ports:
        - depth_image

    Args:
        intrinsics: the camera (focal length and rate).
        noise: the depth error model.
        seed: noise seed.
    """

    def __init__(self, intrinsics: CameraIntrinsics, noise: StereoDepthNoise, seed: int = 0):
        super().__init__()
        self._K = intrinsics
        self._noise = noise
        self._seed = int(seed)
        model = AbstractValue.Make(ImageDepth32F(intrinsics.width, intrinsics.height))
        self._in = self.DeclareAbstractInputPort("depth_image_ideal", model)
        self.DeclareAbstractOutputPort(
            "depth_image",
            lambda: AbstractValue.Make(ImageDepth32F(intrinsics.width, intrinsics.height)),
            self._calc,
            prerequisites_of_calc={self.time_ticket(), self._in.ticket()},
        )

    def noisy_depth(self, ideal_m: np.ndarray, t: float) -> np.ndarray:
        """The measured depth ``(H, W)`` float32 (0 invalid) for an ideal depth image taken at ``t``."""
        k = int(round(t * self._K.rate_hz))
        return self._noise.apply(ideal_m, self._K.fx, frame_rng(self._seed, k))

    def _calc(self, context, output):
        ideal = self._in.Eval(context).data[:, :, 0]
        img = output.get_mutable_value()
        img.mutable_data[:, :, 0] = self.noisy_depth(ideal, context.get_time())
