"""The gripper command from the operator's hand: thumb-index distance with hysteresis.

The 12 pose landmarks (BlazePose's) have no fingertips: ``*_index`` and ``*_pinky`` are knuckles, which barely
move when a hand closes. The gripper is therefore commanded from a separate hand channel, the distance between
the thumb tip and the index fingertip of each hand (MediaPipe Hands' landmarks 4 and 8 on a real camera; on the
simulated operator, :class:`~akc_drake.systems.gripper_command.HandApertureSource` makes it from the motion's
hand closure with detector noise). :func:`pinch_distance_m` measures it from a hand landmarker's 21 landmarks and
the depth image (:class:`~akc_drake.io.hand_detector.HandDetector`); :func:`hand_sides` tells the operator's left
hand from the right.

A pinch closes the gripper when the distance falls below ``close_below_m`` and opens it when the distance rises
above ``open_above_m``; in between the gripper keeps its state (hysteresis, so noise around one threshold does not
chatter the fingers). A missing measurement (NaN) keeps the state too: losing sight of the hand must not drop
the object.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from akc_drake.core.camera import CameraIntrinsics, depth_lookup

#: Thumb-index tip distance of an open hand and of a pinch (metres), for the simulated hand channel.
OPEN_HAND_APERTURE_M = 0.09
PINCH_APERTURE_M = 0.015
#: MediaPipe Hands' 21 landmarks: the wrist, the thumb tip, the index fingertip, and the palm (the wrist and the
#: four finger knuckles, MCP), where the depth camera measures the hand's distance.
NUM_HAND_LANDMARKS = 21
HAND_WRIST, THUMB_TIP, INDEX_TIP, MIDDLE_MCP = 0, 4, 8, 9
PALM_LANDMARKS = (0, 5, 9, 13, 17)
#: A detected hand is the pose's wrist's when its wrist is within this many hand lengths (wrist to middle
#: knuckle, in pixels) of it.
WRIST_GATE_HAND_LENGTHS = 1.5


def pinch_distance_m(hand_px, depth_m, intrinsics: CameraIntrinsics, window: int = 5) -> float:
    """The thumb-tip to index-fingertip distance (metres) of one detected hand, from its landmarks and the depth.

    The hand's shape comes from the landmarker: pixels ``u, v`` and its relative depth ``z`` (MediaPipe's ``z``,
    same scale as ``x``, converted to pixels); the metric scale from the depth camera, the median depth of the
    palm's landmarks (:data:`PALM_LANDMARKS`). The fingertips' own depth pixels are not used: a fingertip covers a
    few pixels, often straddles the hand's silhouette, and a stereo camera's noise there (centimetres at 2 m) is
    the size of the pinch itself; the palm's landmarks sit on a broad patch of skin. A pixel offset ``d`` at depth
    ``Z`` is ``d * Z / f`` metres, and the relative depth keeps a pinch seen end-on from looking closed.

    Args:
        hand_px: ``(21, 3)`` ``u, v`` (pixels, our convention: origin at the top-left pixel's centre) and ``z``
            (pixels) of MediaPipe Hands' landmarks.
        depth_m: ``(H, W)`` depth image in metres (0 or NaN where invalid), aligned to the colour image.
        intrinsics: the camera.
        window: depth-lookup patch (pixels) per palm landmark.

    Returns:
        The distance in metres; NaN when the palm has no valid depth or a tip is missing.
    """
    h = np.asarray(hand_px, dtype=float)
    if h.shape != (NUM_HAND_LANDMARKS, 3):
        raise ValueError(f"hand_px must be ({NUM_HAND_LANDMARKS}, 3), got {h.shape}")
    z = depth_lookup(depth_m, h[list(PALM_LANDMARKS), :2], window=window)
    if not np.any(np.isfinite(z)):
        return math.nan
    Z = float(np.nanmedian(z))
    d = h[THUMB_TIP] - h[INDEX_TIP]
    K = intrinsics
    return float(Z * math.sqrt((d[0] / K.fx) ** 2 + (d[1] / K.fy) ** 2 + (d[2] / K.fx) ** 2))


def hand_size_px(hand_px) -> np.ndarray:
    """Per detected hand (``(n, 21, 3)`` or ``(21, 3)``), its size in the image (pixels): the larger of the wrist to
    middle-knuckle length and half its landmarks' bounding-box diagonal. A hand pointing at the camera
    foreshortens the first to a few pixels while its fingers still fan out across the image, so the second keeps the
    gate of :func:`hand_sides` from shrinking to nothing."""
    H = np.asarray(hand_px, dtype=float).reshape(-1, NUM_HAND_LANDMARKS, 3)[:, :, :2]
    length = np.linalg.norm(H[:, MIDDLE_MCP] - H[:, HAND_WRIST], axis=1)
    with np.errstate(invalid="ignore"):
        span = 0.5 * np.linalg.norm(np.nanmax(H, axis=1) - np.nanmin(H, axis=1), axis=1)
    return np.fmax(length, span)


def hand_sides(labels, hand_px, pose_wrists_px=None, *, mirrored: bool = False) -> dict[str, int]:
    """Which detected hand is the operator's left and which the right: ``{"left": index, "right": index}``.

    With the pose detector's wrists (``pose_wrists_px``, ``(2, 2)`` left, right; NaN where unknown), each pose
    wrist takes the detected hand whose wrist is nearest (the pairing with the smallest total distance), if within
    :data:`WRIST_GATE_HAND_LENGTHS` hand sizes (:func:`hand_size_px`): the body's detector sees the arms, which says
    more about which hand is which than a hand's own look. A hand no known pose wrist takes is left unassigned (NaN
    downstream: the gripper keeps its state): MediaPipe's handedness labels are unreliable exactly where the gate
    fails (on our renders it called both hands "Left" while the right hand reached toward the camera, and a
    fallback to the labels closed the left gripper with the right hand's pinch).

    Without any pose wrist, the landmarker's handedness labels: MediaPipe's Tasks API (0.10.15 and later) labels the
    person's own hands in an unmirrored image (a camera looking at the person); ``mirrored`` swaps them (a selfie
    view). Two hands with the same label (or none) are told apart by their order in the image instead: facing the
    camera, the person's right hand is the one further left in an unmirrored image.

    Args:
        labels: per detected hand, ``"Left"`` or ``"Right"`` (best first among equals).
        hand_px: per detected hand, ``(21, 3)`` landmarks in pixels (see :func:`pinch_distance_m`).
        pose_wrists_px: optional ``(2, 2)`` pose wrists' pixels.
        mirrored: the image is mirrored (swap the labels).

    Returns:
        The sides found, each with the index of its hand in ``labels``.
    """
    n = len(labels)
    if n == 0:
        return {}
    H = np.asarray(hand_px, dtype=float).reshape(n, NUM_HAND_LANDMARKS, 3)
    P = None if pose_wrists_px is None else np.asarray(pose_wrists_px, dtype=float).reshape(2, 2)
    if P is not None and np.any(np.all(np.isfinite(P), axis=1)):
        wrists = H[:, HAND_WRIST, :2]
        gate = WRIST_GATE_HAND_LENGTHS * hand_size_px(H)
        dist = np.linalg.norm(P[:, None, :] - wrists[None, :, :], axis=2)  # (side, hand)
        ok = np.isfinite(dist) & (dist <= gate[None, :])
        pairs = [((0, i), (1, j)) for i in range(n) for j in range(n) if i != j]
        pairs += [((0, i),) for i in range(n)] + [((1, j),) for j in range(n)]
        best, best_cost = (), math.inf
        for cand in pairs:
            if not all(ok[s, h] for s, h in cand):
                continue
            # more hands matched first, then the smaller total distance
            cost = -1e9 * len(cand) + sum(dist[s, h] for s, h in cand)
            if cost < best_cost:
                best, best_cost = cand, cost
        return {("left", "right")[s]: h for s, h in best}
    labs = []
    for label in labels:
        lab = str(label).lower()
        if mirrored and lab in ("left", "right"):
            lab = "right" if lab == "left" else "left"
        labs.append(lab)
    if n >= 2 and not {"left", "right"} <= set(labs[:2]):
        # one label for both (or none): the image order, the right hand further left unless mirrored
        u = H[:2, HAND_WRIST, 0]
        if np.all(np.isfinite(u)) and u[0] != u[1]:
            first_is_right = (u[0] < u[1]) != bool(mirrored)
            return {"right": 0, "left": 1} if first_is_right else {"left": 0, "right": 1}
    sides: dict[str, int] = {}
    for k, lab in enumerate(labs):
        if lab in ("left", "right"):
            sides.setdefault(lab, k)
    return sides


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


def gripper_states(apertures, hysteresis: GripperHysteresis | None = None, closed: bool = False) -> np.ndarray:
    """``(T, 2)`` bool gripper states (True: closed) the hysteresis gives for ``(T, 2)`` thumb-index distances
    (NaN: unknown, the state is kept), starting from ``closed``."""
    h = hysteresis or GripperHysteresis()
    A = np.asarray(apertures, dtype=float).reshape(-1, 2)
    out = np.zeros(A.shape, dtype=bool)
    state = [bool(closed), bool(closed)]
    for k, row in enumerate(A):
        state = [h.step(c, float(a)) for c, a in zip(state, row, strict=True)]
        out[k] = state
    return out


def hand_channel_report(apertures, truth_m, intended_closed, times, hysteresis: GripperHysteresis | None = None):
    """How well a measured hand channel commands the grippers, per hand (plain JSON types).

    Args:
        apertures: ``(T, 2)`` measured thumb-index distances (NaN: hand not found).
        truth_m: ``(T, 2)`` the true distances.
        intended_closed: ``(T, 2)`` bool, the gripper state the operator means (e.g. hand closure > 0.5).
        times: ``(T,)`` frame times, seconds.

    Returns:
        ``{"left": {...}, "right": {...}}`` with ``found`` (share of frames with a measurement),
        ``aperture_error_cm`` (median and p95 of the absolute error over found frames), ``state_agreement``
        (share of frames whose gripper state is the intended one) and ``switch_delay_s`` (per intended switch,
        the delay until the gripper reaches that state; None if it does not before the next switch).
    """
    A = np.asarray(apertures, dtype=float).reshape(-1, 2)
    T = np.asarray(truth_m, dtype=float).reshape(-1, 2)
    want = np.asarray(intended_closed, dtype=bool).reshape(-1, 2)
    t = np.asarray(times, dtype=float)
    got = gripper_states(A, hysteresis, closed=False)
    out = {}
    for s, side in enumerate(("left", "right")):
        found = np.isfinite(A[:, s])
        err = 100.0 * np.abs(A[found, s] - T[found, s])
        switches = np.flatnonzero(np.diff(want[:, s].astype(int))) + 1
        delays = []
        for i, k in enumerate(switches):
            end = switches[i + 1] if i + 1 < len(switches) else len(t)
            hit = np.flatnonzero(got[k:end, s] == want[k, s])
            delays.append(float(t[k + hit[0]] - t[k]) if hit.size else None)
        out[side] = {
            "found": float(np.mean(found)) if len(found) else math.nan,
            "aperture_error_cm": {
                "median": float(np.median(err)) if err.size else math.nan,
                "p95": float(np.percentile(err, 95)) if err.size else math.nan,
            },
            "state_agreement": float(np.mean(got[:, s] == want[:, s])) if len(t) else math.nan,
            "switch_delay_s": delays,
        }
    return out
