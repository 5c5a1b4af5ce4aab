"""The occlusion filter of stage S3 (paper §II-C, "Stage 3: Temporal Landmark Filtering").

Two checks discard unreliable measurements before the Kalman filter:

1. **Visibility.** A landmark whose detector visibility is below ``visibility_threshold`` (0.7 in
   the paper), or is NaN, is rejected entirely: its whole row becomes NaN.
2. **Proximity.** Under self-occlusion the visibility score can miss a corrupted depth: when the
   forearm crosses in front of the elbow or shoulder, the depth looked up at the proximal joint's
   pixel is the depth of the occluding distal joint. So the depth (``z`` only; ``x`` and ``y`` are
   kept, the 2D detection stays reliable) of a proximal joint is dropped when its pixel lies within
   ``proximity * image_width`` pixels (5 % in the paper) of the pixel of a distal joint on the same
   arm, for the pairs of :data:`akc_drake.core.skeleton.PROXIMAL_DISTAL_PAIRS`.

   Only an *accepted* distal joint can occlude: a distal joint that is itself rejected for low
   visibility is most likely the hidden one (behind the proximal joint), in which case the
   proximal joint's depth is the right one and is kept.

Pure numpy, vectorised over the fixed pair list (no Python loop per landmark).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS, PAPER_PROXIMAL_DISTAL_PAIRS, PROXIMAL_DISTAL_PAIRS

#: Paper defaults (§II-C).
DEFAULT_VISIBILITY_THRESHOLD = 0.7
DEFAULT_PROXIMITY = 0.05

_PROX = np.array([INDEX[p] for p, _ in PROXIMAL_DISTAL_PAIRS], dtype=np.intp)
_DIST = np.array([INDEX[d] for _, d in PROXIMAL_DISTAL_PAIRS], dtype=np.intp)
_PAIR_INDEX = {PROXIMAL_DISTAL_PAIRS: (_PROX, _DIST)}


def _pair_indices(pairs) -> tuple[np.ndarray, np.ndarray]:
    """(proximal, distal) index arrays of a pair list (cached per list)."""
    got = _PAIR_INDEX.get(pairs)
    if got is None:
        try:
            got = (np.array([INDEX[p] for p, _ in pairs], dtype=np.intp),
                   np.array([INDEX[d] for _, d in pairs], dtype=np.intp))
        except KeyError as e:
            raise ValueError(f"pairs: unknown landmark {e.args[0]!r}") from None
        _PAIR_INDEX[tuple(pairs)] = got
    return got


#: The paper's occlusion filter: its pairs, and any detected distal joint may occlude.
PAPER_RULES = {"pairs": PAPER_PROXIMAL_DISTAL_PAIRS, "distal_must_be_accepted": False}


class OcclusionInfo(NamedTuple):
    """What the occlusion filter removed, for diagnostics.

    Attributes:
        rejected: ``(12,)`` bool, landmark rejected entirely (visibility below threshold or NaN).
        depth_dropped: ``(12,)`` bool, landmark kept but its depth ``z`` dropped by the proximity
            check (never set for a rejected landmark).
    """

    rejected: np.ndarray
    depth_dropped: np.ndarray


def _as_shape(a, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    return arr


def check_parameters(image_width: float, visibility_threshold: float, proximity: float) -> None:
    """Raise a ``ValueError`` naming the parameter and value if any is out of range."""
    if not isinstance(image_width, (int, float, np.integer, np.floating)) or not (
        math.isfinite(image_width) and image_width > 0
    ):
        raise ValueError(f"image_width must be a positive number of pixels, got {image_width!r}")
    if not isinstance(visibility_threshold, (int, float, np.integer, np.floating)) or not (
        0.0 <= visibility_threshold <= 1.0
    ):
        raise ValueError(f"visibility_threshold must be in [0, 1], got {visibility_threshold!r}")
    if not isinstance(proximity, (int, float, np.integer, np.floating)) or not (
        math.isfinite(proximity) and proximity >= 0.0
    ):
        raise ValueError(f"proximity must be a non-negative fraction of the image width, got {proximity!r}")


def occlusion_filter(
    points_C,
    pixels,
    visibility,
    image_width: float,
    *,
    visibility_threshold: float = DEFAULT_VISIBILITY_THRESHOLD,
    proximity: float = DEFAULT_PROXIMITY,
    pairs: tuple[tuple[str, str], ...] = PROXIMAL_DISTAL_PAIRS,
    distal_must_be_accepted: bool = True,
) -> tuple[np.ndarray, OcclusionInfo]:
    """Discard occluded landmarks and corrupted proximal depths (paper §II-C).

    Args:
        points_C: ``(12, 3)`` landmarks in the camera frame C, metres, NaN where missing.
        pixels: ``(12, 2)`` pixel coordinates ``(u, v)`` of the landmarks, NaN where missing.
        visibility: ``(12,)`` detector visibility in [0, 1]; NaN counts as not visible.
        image_width: image width in pixels (the proximity radius is a fraction of it).
        visibility_threshold: landmarks with visibility strictly below this are rejected.
        proximity: radius of the proximity check as a fraction of ``image_width``; a proximal
            joint whose pixel is strictly closer than ``proximity * image_width`` to an accepted
            distal joint's pixel on the same arm loses its depth.
        pairs: the (proximal, distal) pairs checked: ours by default, the paper's in
            :data:`~akc_drake.core.skeleton.PAPER_PROXIMAL_DISTAL_PAIRS` (``PAPER_RULES``).
        distal_must_be_accepted: our rule that a distal joint rejected for low visibility does not occlude
            (it is most likely the hidden one); the paper has no such rule (False).

    Returns:
        ``(accepted_C, info)``: ``accepted_C`` is a new ``(12, 3)`` array (rejected rows all NaN,
        dropped depths NaN in column 2) and ``info`` an :class:`OcclusionInfo`.

    Raises:
        ValueError: an array has the wrong shape or a parameter is out of range (the message names it).
    """
    check_parameters(image_width, visibility_threshold, proximity)
    points = _as_shape(points_C, (NUM_LANDMARKS, 3), "points_C")
    pix = _as_shape(pixels, (NUM_LANDMARKS, 2), "pixels")
    vis = _as_shape(visibility, (NUM_LANDMARKS,), "visibility")

    # ``not (vis >= thr)`` is also True for NaN visibility.
    rejected = ~(vis >= visibility_threshold)
    # Squared pixel distance of every (proximal, distal) pair; NaN pixels compare False.
    prox, dist = _pair_indices(pairs)
    d = pix[prox] - pix[dist]
    d2 = np.einsum("ij,ij->i", d, d)
    radius = proximity * image_width
    near = d2 < radius * radius
    if distal_must_be_accepted:
        near &= ~rejected[dist]
    depth_dropped = np.zeros(NUM_LANDMARKS, dtype=bool)
    depth_dropped[prox[near]] = True
    depth_dropped &= ~rejected

    accepted = points.copy()
    accepted[rejected] = np.nan
    accepted[depth_dropped, 2] = np.nan
    return accepted, OcclusionInfo(rejected, depth_dropped)
