"""The occlusion filter of stage S3 (paper §II-C, "Stage 3: Temporal Landmark Filtering").

Four checks discard unreliable measurements before the Kalman filter (the third and the fourth are ours, not the
paper's):

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

   The 2D detection is reliable, but S2 deprojected it at the occluder's depth: ``x`` and ``y`` lie
   on the landmark's pixel ray at that depth, short of the joint by the depth ratio (an elbow read on
   the forearm 40 cm in front, at 2 m, is 20 % short: 6 cm at 0.3 m off the optical axis). With
   ``held`` (our rule, not the paper's: ``hold_rays``) the filter keeps each landmark's last accepted
   position and moves a dropped depth's ``x``, ``y`` along the ray to its depth (docs/results.md,
   session 39).

3. **Background** (our rule, not the paper's: ``background_m``). A landmark's pixel on the silhouette's edge, or
   just past it, reads the background: MediaPipe's elbow or wrist on the wall 1.5 m behind the body, a hip on the
   wall behind a body that leans towards the camera. The detector's visibility stays high there, the proximity
   check has nothing to say, and a filter that follows the reading runs a metre off. A depth read farther behind
   every accepted neighbour on the body (the joints a segment joins it to: :data:`DEPTH_NEIGHBOURS`) than
   ``background_m``, longer than any such segment, is dropped as the proximity check drops one (``x``, ``y``
   kept, and with ``held`` put back on the ray).

4. **A hand over a hip** (our rule, not the paper's: ``hand_reach_m``). A hand held in front of the pelvis (reaching
   for a table, carrying something) covers a hip's pixel with its fingers, and the hip reads the hand. MediaPipe's
   hip stays where it is in the image with high visibility, and nothing else above drops it: no pair of the
   proximity check has a hip, and the reading is in front, not behind. Measured on the teleop demo's pick-and-place
   (MediaPipe on the skinned body, seed 1, AKC(KF)): the right hip read 154.6 cm against its 197.2 the frame
   before, the knuckles 8.5-9.3 cm from its ray; the teleop filter's gate let it through (4.3 m/s, under its 6 m/s
   floor), the torso frame carried by the hips turned, and when the fingers curled to grasp the hip read 197 cm
   again: the robot's wrist target swung 15 cm across the box while the operator's hand held still. A hip's depth
   is dropped when it reads farther in front of the other hip than a turned pelvis puts it
   (:data:`HIP_FRONT_M`), at the depth of an accepted hand landmark (wrist or knuckle, either hand, within
   :data:`HAND_DEPTH_M`) whose hand reaches its pixel (within ``hand_reach_m`` of it, measured across the line
   of sight at the hand's depth).

The first two checks are numpy, vectorised over the fixed pair list; the background check, the hand check and the
hold run on plain floats (12 rows).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from akc_drake.core.kalman import LEFT_RIGHT_SWAP, SWAP_MIN_PAIRS, SWAP_RATIO
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


#: The background check's margin (metres): longer than any segment between :data:`DEPTH_NEIGHBOURS` (an adult's
#: upper arm is at most about 0.40 m, the shoulder breadth 0.46, MediaPipe's hip landmarks nearer each other than
#: the shoulders), so no pose puts a landmark that far behind all of them.
BACKGROUND_M = 0.6

#: Each landmark and a neighbour on the body whose depth bounds its own (a segment joins them): the background
#: check. The knuckles are left out (the hand's landmarks are read on one small surface, and go with the wrist).
DEPTH_NEIGHBOURS: tuple[tuple[str, str], ...] = tuple(
    pair
    for side, other in (("left", "right"), ("right", "left"))
    for pair in (
        (f"{side}_shoulder", f"{side}_elbow"),
        (f"{side}_shoulder", f"{other}_shoulder"),
        (f"{side}_elbow", f"{side}_shoulder"),
        (f"{side}_elbow", f"{side}_wrist"),
        (f"{side}_wrist", f"{side}_elbow"),
        (f"{side}_hip", f"{other}_hip"),
    )
)
_NB = tuple((INDEX[p], INDEX[q]) for p, q in DEPTH_NEIGHBOURS)


def _drop_background(z: list, out: list, margin: float, depth_dropped: np.ndarray) -> None:
    """The background check, in place on ``depth_dropped``: a depth ``z[i]`` more than ``margin`` behind every
    neighbour whose depth is accepted (not ``out``: rejected or dropped) and finite, and at least one (plain floats:
    twelve pairs cost less than the numpy calls would)."""
    n_ok = [0] * NUM_LANDMARKS
    n_behind = [0] * NUM_LANDMARKS
    isfinite = math.isfinite
    for p, q in _NB:
        zp, zq = z[p], z[q]
        if out[p] or out[q] or not isfinite(zp + zq):
            continue
        n_ok[p] += 1
        if zp - zq > margin:
            n_behind[p] += 1
    for i in range(NUM_LANDMARKS):
        if n_ok[i] and n_behind[i] == n_ok[i]:
            depth_dropped[i] = True


#: How far across the line of sight a hand covers from its landmarks (metres): MediaPipe's knuckles are the
#: fingers' bases (the index and pinky MCP joints), and an adult's fingers reach 8-10 cm past them; with the depth
#: window's half width (2.5 cm at 2 m), 12 cm.
HAND_REACH_M = 0.12
#: A hip read farther than this (metres) in front of the other hip is no turned pelvis: MediaPipe's hip landmarks
#: are about 20 cm apart on an adult (nearer each other than the shoulders), so a body turned side-on puts one at
#: most that far in front of the other.
HIP_FRONT_M = 0.20
#: A hip reading within this (metres) of a hand landmark's depth is at the hand: the hand's own depth extent
#: (fingers towards the camera or away) and the readings' noise.
HAND_DEPTH_M = 0.15
_HIPS = ((INDEX["left_hip"], INDEX["right_hip"]), (INDEX["right_hip"], INDEX["left_hip"]))
_HAND = tuple(INDEX[f"{side}_{part}"] for side in ("left", "right") for part in ("wrist", "index", "pinky"))


def _drop_hand_over_hip(points: list, out: list, reach: float, depth_dropped: np.ndarray) -> None:
    """The hand check, in place on ``depth_dropped``: a hip read more than :data:`HIP_FRONT_M` in front of the
    other hip, within :data:`HAND_DEPTH_M` of an accepted hand landmark's depth whose lateral distance from the
    hip's ray at that depth is under ``reach`` (``points`` as lists of floats, ``out`` rejected or dropped)."""
    isfinite = math.isfinite
    for h, o in _HIPS:
        if out[h] or out[o]:
            continue
        xh, yh, zh = points[h]
        zo = points[o][2]
        if not (isfinite(xh + yh + zh + zo) and zh > 0.0) or zo - zh <= HIP_FRONT_M:
            continue
        uh, vh = xh / zh, yh / zh
        for d in _HAND:
            xd, yd, zd = points[d]
            if out[d] or not (isfinite(xd + yd + zd) and zd > 0.0) or abs(zh - zd) >= HAND_DEPTH_M:
                continue
            du, dv = (uh - xd / zd) * zd, (vh - yd / zd) * zd
            if du * du + dv * dv < reach * reach:
                depth_dropped[h] = True
                break


#: The paper's occlusion filter: its pairs, any detected distal joint may occlude, a dropped depth's x, y stay
#: where S2 deprojected them, and no background or hand check.
PAPER_RULES = {"pairs": PAPER_PROXIMAL_DISTAL_PAIRS, "distal_must_be_accepted": False, "hold_rays": False,
               "background_m": None, "hand_reach_m": None}


class OcclusionInfo(NamedTuple):
    """What the occlusion filter removed, for diagnostics.

    Attributes:
        rejected: ``(12,)`` bool, landmark rejected entirely (visibility below threshold or NaN).
        depth_dropped: ``(12,)`` bool, landmark kept but its depth ``z`` dropped by the proximity
            check or the background check (never set for a rejected landmark).
    """

    rejected: np.ndarray
    depth_dropped: np.ndarray


def _as_shape(a, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    return arr


def check_parameters(image_width: float, visibility_threshold: float, proximity: float,
                     background_m: float | None = None, hand_reach_m: float | None = None) -> None:
    """Raise a ``ValueError`` naming the parameter and value if any is out of range (``background_m``,
    ``hand_reach_m``: None, or a positive number of metres)."""
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
    if background_m is not None and not (
        isinstance(background_m, (int, float, np.integer, np.floating)) and background_m > 0.0
    ):
        raise ValueError(f"background_m must be a positive number of metres or None, got {background_m!r}")
    if hand_reach_m is not None and not (
        isinstance(hand_reach_m, (int, float, np.integer, np.floating)) and math.isfinite(hand_reach_m)
        and hand_reach_m > 0.0
    ):
        raise ValueError(f"hand_reach_m must be a positive number of metres or None, got {hand_reach_m!r}")


_SWAP = LEFT_RIGHT_SWAP.tolist()


def _hold_rays(accepted: np.ndarray, points: np.ndarray, dropped: np.ndarray, held: np.ndarray) -> None:
    """``occlusion_filter``'s hold, in place (plain floats: 12 rows cost less than the numpy calls would).

    A detector's left/right swap (a whole body labelled mirror-wise for a frame) is told as the KF tells it
    (:func:`akc_drake.core.kalman.left_right_swapped`, here against the held positions): on such a frame each
    row reads and records the held row of the label it swapped with, so that the hold stays the person's and
    the output is the unswapped frame's with its rows exchanged.
    """
    a, h, sw = accepted.tolist(), held.tolist(), _SWAP
    fin = [math.isfinite(r[0] + r[1] + r[2]) for r in a]
    fh = [math.isfinite(r[0] + r[1] + r[2]) for r in h]
    e_given = e_swap = 0.0
    pairs = 0
    for i in range(NUM_LANDMARKS):
        j = sw[i]
        if fin[i] and fh[i] and fin[j] and fh[j]:
            ai, aj, hi = a[i], a[j], h[i]
            e_given += (ai[0] - hi[0]) ** 2 + (ai[1] - hi[1]) ** 2 + (ai[2] - hi[2]) ** 2
            e_swap += (aj[0] - hi[0]) ** 2 + (aj[1] - hi[1]) ** 2 + (aj[2] - hi[2]) ** 2
            pairs += 1
    swap = pairs >= 2 * SWAP_MIN_PAIRS and e_swap < SWAP_RATIO * e_given  # (both rows of each pair count)
    for i in np.flatnonzero(dropped).tolist():
        zr, z = h[sw[i] if swap else i][2], points[i, 2]
        if 0.0 < zr < math.inf and 0.0 < z < math.inf:  # (a garbage depth of 0 or inf is no ray's depth)
            accepted[i, 0] *= zr / z
            accepted[i, 1] *= zr / z
    for i in range(NUM_LANDMARKS):
        if fin[i]:
            h[sw[i] if swap else i] = a[i]
    if any(fin):
        held[:] = h


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
    hold_rays: bool = True,
    held: np.ndarray | None = None,
    background_m: float | None = BACKGROUND_M,
    hand_reach_m: float | None = HAND_REACH_M,
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
        hold_rays: with ``held``, put a dropped depth's ``x``, ``y`` on the landmark's pixel ray at its last
            accepted depth (False: the paper's filter, which keeps them; ``held`` is then left as it is).
        held: the state of a filter run over a sequence: a ``(12, 3)`` float64 array of each landmark's last
            accepted position (all three axes accepted; NaN rows: none yet, start with all NaN), updated in
            place with this frame's. None (default): stateless, ``x``, ``y`` kept as deprojected.
        background_m: drop the depth of a landmark read more than this (metres) behind every neighbour in
            :data:`DEPTH_NEIGHBOURS` whose depth is accepted (at least one); None: no background check (the
            paper's filter).
        hand_reach_m: drop the depth of a hip read at a hand's depth, far in front of the other hip, with a hand
            landmark within this (metres, across the line of sight) of its pixel ray (the module docstring's
            check 4); None: no hand check (the paper's filter).

    Returns:
        ``(accepted_C, info)``: ``accepted_C`` is a new ``(12, 3)`` array (rejected rows all NaN,
        dropped depths NaN in column 2) and ``info`` an :class:`OcclusionInfo`.

    Raises:
        ValueError: an array has the wrong shape or a parameter is out of range (the message names it).
    """
    check_parameters(image_width, visibility_threshold, proximity, background_m, hand_reach_m)
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
    if background_m is not None:
        _drop_background(points[:, 2].tolist(), (rejected | depth_dropped).tolist(), float(background_m),
                         depth_dropped)
    if hand_reach_m is not None:  # (after the background: a hip read on the wall is no reference for the other)
        _drop_hand_over_hip(points.tolist(), (rejected | depth_dropped).tolist(), float(hand_reach_m),
                            depth_dropped)

    accepted = points.copy()
    accepted[rejected] = np.nan
    accepted[depth_dropped, 2] = np.nan
    if held is not None and hold_rays:
        if not (isinstance(held, np.ndarray) and held.shape == (NUM_LANDMARKS, 3) and held.dtype == np.float64):
            raise ValueError(f"held must be a float64 array of shape ({NUM_LANDMARKS}, 3)")
        _hold_rays(accepted, points, depth_dropped, held)
    return accepted, OcclusionInfo(rejected, depth_dropped)
