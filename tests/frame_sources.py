"""A frame source for tests that need a camera's frames without a camera: a video-like in-order source."""

import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics


class NoiseFrames:
    """``n`` frames of uniform noise at a constant 2 m depth, 160x120 at 10 Hz."""

    intrinsics = CameraIntrinsics(width=160, height=120, fx=150.0, fy=150.0, cx=79.5, cy=59.5)
    rate_hz = 10.0
    depth_is_surface = False  # a constant depth, like `video:FILE --depth 2.0`

    def __init__(self, n: int = 3):
        self.n = n

    def __len__(self):
        return self.n

    def __iter__(self):
        rng = np.random.default_rng(0)
        K = self.intrinsics
        for i in range(self.n):
            color = rng.integers(0, 256, (K.height, K.width, 3), dtype=np.uint8)
            yield CameraFrame(color, np.full((K.height, K.width), 2.0), i / self.rate_hz, K)
