"""The gripper command from the operator's hand: thumb-index distance with hysteresis.

The 12 pose landmarks (BlazePose's) have no fingertips: ``*_index`` and ``*_pinky`` are knuckles, which barely
move when a hand closes. The gripper is therefore commanded from a separate hand channel, the distance between
the thumb tip and the index fingertip of each hand (MediaPipe Hands' landmarks 4 and 8 on a real camera; on the
simulated operator, :class:`~akc_drake.systems.hand_aperture.HandApertureSource` makes it from the motion's
hand closure with detector noise).

A pinch closes the gripper when the distance falls below ``close_below_m`` and opens it when the distance rises
above ``open_above_m``; in between the gripper keeps its state (hysteresis, so noise around one threshold does not
chatter the fingers). A missing measurement (NaN) keeps the state too: losing sight of the hand must not drop
the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Thumb-index tip distance of an open hand and of a pinch (metres), for the simulated hand channel.
OPEN_HAND_APERTURE_M = 0.09
PINCH_APERTURE_M = 0.015


@dataclass(frozen=True)
class GripperHysteresis:
    """Thresholds of the pinch detector and the finger positions it commands.

    Attributes:
        close_below_m: thumb-index distance below which the gripper closes.
        open_above_m: distance above which it opens (> ``close_below_m``).
        open_m, closed_m: finger opening commanded when open / closed (metres per finger; the robot's fingers
            travel 0-0.04 m; a closed command below the object's half width squeezes it).
    """

    close_below_m: float = 0.035
    open_above_m: float = 0.055
    open_m: float = 0.04
    closed_m: float = 0.0

    def __post_init__(self):
        for name in ("close_below_m", "open_above_m", "open_m", "closed_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ValueError(f"GripperHysteresis.{name} must be a length >= 0 in metres, got {v!r}")
        if not self.close_below_m < self.open_above_m:
            raise ValueError(
                f"GripperHysteresis: close_below_m ({self.close_below_m}) must be below open_above_m "
                f"({self.open_above_m})"
            )

    def step(self, closed: bool, aperture_m: float) -> bool:
        """The new state (True: closed) from the previous one and a thumb-index distance (NaN: unknown)."""
        if not math.isfinite(aperture_m):
            return bool(closed)
        if closed:
            return not aperture_m > self.open_above_m
        return aperture_m < self.close_below_m

    def opening(self, closed: bool) -> float:
        """The finger opening to command for a state."""
        return self.closed_m if closed else self.open_m


def aperture_from_closure(closure, rng: np.random.Generator | None = None, noise_m: float = 0.004) -> np.ndarray:
    """Thumb-index distance of a hand closed by ``closure`` (0 open .. 1 pinch), with Gaussian noise.

    Args:
        closure: array of closures in [0, 1].
        rng: the noise generator (None: no noise); noise_m: its standard deviation, metres.
    """
    c = np.clip(np.asarray(closure, dtype=float), 0.0, 1.0)
    d = OPEN_HAND_APERTURE_M + c * (PINCH_APERTURE_M - OPEN_HAND_APERTURE_M)
    if rng is not None and noise_m > 0:
        d = d + rng.normal(0.0, noise_m, d.shape)
    return np.maximum(d, 0.0)
