"""Stage S5 end to end on numpy: a landmark pose in, the two robot targets out, with the state that links frames.

:class:`ControlFrameTracker` is what :class:`~akc_drake.systems.frame_mapper.FrameMapper` runs once per camera
frame:

1. **Torso**: from the hips through a calibrated :class:`~akc_drake.core.frames.TorsoModel` when one is given
   (the shoulders are the most occluded landmarks in teleoperation; :func:`calibrate_torso` takes its vertical
   from the T-pose's trunk, not from the shoulder line), else eq. (17) from the shoulders and
   hips; held still while it stays within 10 cm / 10 deg of its settled pose (``torso_hold``,
   :data:`~akc_drake.core.smoothing.TORSO_HOLD`, the mean of its first second: the detector's hips move with the
   arms, a standing operator's do not; a step or a turn is followed); then smoothed on SE(3)
   (:data:`~akc_drake.core.smoothing.TORSO_SMOOTHING`, One Euro + flip guard). Missing: the last torso is held.
2. **Wrists** (eq. 17) in the camera frame: a wrist hidden by its own hand (the forearm pointing at the camera,
   the depth reading the back of the hand, or past its edge) is first put a hand's length behind the knuckles
   (:func:`wrist_behind_hand`); the
   hand vector ``p_i - p_p`` (MediaPipe Hands' knuckle line when given, :func:`hands_knuckle_vector`, its
   index/pinky swaps held off, :func:`hands_swapped`) is rebuilt from its image-plane part and the hand's learnt width
   (:func:`~akc_drake.core.frames.reconstruct_hand_vector`: the knuckles'
   depths are the noisiest inputs of eq. 17), the sign of its depth part, when the forearm does not decide it,
   from a two-state filter over frames (:func:`depth_sign_step`: continuity of the roll about the forearm, Hands'
   measured depth, an anatomical prior on the forearm's rotation, :func:`neutral_hand_direction`); a frame whose
   hand vector is unreliable is kept on the side of
   the previous one (:func:`~akc_drake.core.frames.resolve_wrist_flip`), then expressed in the torso frame and
   mapped to the robot (:func:`~akc_drake.core.frames.map_to_robot`).
3. **Speed gate**: a side whose wrist/hand/hip landmarks would have moved faster than ``max_landmark_speed``
   since its last accepted frame is treated as lost (:func:`~akc_drake.core.frames.plausible_step`).
4. **Smoothing** of each target on SE(3) (:data:`~akc_drake.core.smoothing.WRIST_SMOOTHING`).
5. **Workspace**: the smoothed target's position is projected into the arm's reachable shell
   (:class:`~akc_drake.core.frames.Workspace`); a clipped target is reported as such (not an IK failure).

The whole state is one flat vector (:attr:`ControlFrameTracker.state_size`), so a Drake system keeps it in
discrete state.
"""

from __future__ import annotations

import math

import numpy as np

from akc_drake.core import smoothing
from akc_drake.core.arm_geometry import behind_hand, turn_with
from akc_drake.core.frames import (
    DEFAULT_HAND_WIDTH_M,
    DEFAULT_MAX_LANDMARK_SPEED,
    HAND_OUTLIER_WIDTHS,
    SPEED_GATED_LANDMARKS,
    RobotMapping,
    TorsoModel,
    forearm_depth_sign,
    map_to_robot,
    plausible_step,
    reconstruct_hand_vector,
    resolve_wrist_flip,
    torso_of,
    transform,
    wrist_frame,
)
from akc_drake.core.skeleton import INDEX, SIDES

#: Initial estimate of the wrist-to-knuckle-midpoint distance (metres) before it is learnt from the operator
#: (MediaPipe's wrist to the midpoint of its index and pinky knuckles: 8-8.5 cm measured on the rendered adult).
DEFAULT_HAND_LENGTH_M = 0.085


def wrist_behind_hand(p_e, p_w, p_i, p_p, hand_length_m: float) -> np.ndarray:
    """The wrist put on its pixel ray a hand's length behind the knuckles when its own hand hides it from the camera
    (:func:`~akc_drake.core.arm_geometry.behind_hand`, which AKC+ applies to the measured wrist as well).

    Args:
        p_e, p_w, p_i, p_p: ``(3,)`` elbow, wrist, index and pinky knuckles in the camera frame C (z forward).
        hand_length_m: the wrist-to-knuckle-midpoint distance.

    Returns:
        The wrist, ``(3,)`` (a copy of ``p_w`` when unchanged).
    """
    p_w = np.array(p_w, dtype=float)
    e = [float(x) for x in p_e]
    c = [0.5 * (float(a) + float(b)) for a, b in zip(p_i, p_p, strict=True)]
    return p_w * behind_hand(*e, *p_w.tolist(), *c, hand_length_m)


def calibrate_torso(poses) -> TorsoModel:
    """The hip-carried :class:`~akc_drake.core.frames.TorsoModel` from a held T-pose, its vertical from the trunk.

    :meth:`TorsoModel.calibrate <akc_drake.core.frames.TorsoModel.calibrate>` takes eq. (17)'s frame of the mean
    pose, whose vertical is perpendicular to the shoulder line: a detector's pixel error on one shoulder rolls the
    whole frame, and a roll is a constant error of every target, across the torso's width at both wrists (up on
    one side, down on the other). The two shoulders are 30-40 cm apart and each is detected a centimetre off
    (MediaPipe on the rendered T-pose: one shoulder 0.9 cm lower than the other, a 1.5 deg roll, 1-1.5 cm at the
    wrist targets); the trunk (hip midpoint to shoulder midpoint) is 45-55 cm long and its ends are means of two
    landmarks, so its direction is a few times less noisy. An operator standing in a T-pose holds the shoulders
    level across the upright trunk, so the trunk is the vertical: the shoulder line is kept for the frame's
    heading only (orthogonalised against the trunk), the origin stays the shoulder midpoint.

    Args:
        poses: ``(T, 12, 3)`` camera-frame poses of the held T-pose (frames missing a torso landmark are skipped).

    Raises:
        ValueError: no frame with all four torso landmarks, or a degenerate mean torso.
    """
    P = np.asarray(poses, dtype=float).reshape(-1, len(INDEX), 3)
    ls, rs, lh, rh = (INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_hip", "right_hip"))
    ok = np.all(np.isfinite(P[:, [ls, rs, lh, rh]]), axis=(1, 2))
    if not ok.any():
        raise ValueError("calibrate_torso: no frame shows both shoulders and both hips")
    mean = np.mean(P[ok], axis=0)
    s_m, h_m = 0.5 * (mean[ls] + mean[rs]), 0.5 * (mean[lh] + mean[rh])
    up, across = s_m - h_m, mean[ls] - mean[rs]
    n_up = float(np.linalg.norm(up))
    if n_up > 1e-6:
        up /= n_up
        across = across - float(across @ up) * up  # the shoulder line levelled across the trunk
        half = 0.5 * float(np.linalg.norm(mean[ls] - mean[rs]))
        n_across = float(np.linalg.norm(across))
        if n_across > 1e-6:
            mean[ls], mean[rs] = s_m + half * across / n_across, s_m - half * across / n_across
    return TorsoModel.calibrate(mean[None])


#: The elbow bend (deg, between the upper arm and the forearm) from which its plane starts to set the prior's neutral
#: roll, and from which it alone does (:func:`neutral_hand_direction`): a few centimetres of landmark error bend a
#: straight arm by 5-10 deg in any direction (on the demo's T-poses the pose's bend pointed anywhere).
NEUTRAL_BEND_DEG = (20.0, 40.0)
#: The straight arm's prior counts half the bent elbow's: the upper arm's own rotation (~+-60-90 deg, unseen when the
#: elbow is straight) adds to the forearm's (a T-pose is held palms down, forward or up).
NEUTRAL_STRAIGHT_WEIGHT = 0.5


def neutral_hand_direction(p_s, p_e, p_w, R_torso) -> np.ndarray:
    """The anatomical prior on the hand's roll: where the knuckle line ``p_i - p_p`` points, across the forearm,
    with the forearm neither pronated nor supinated (camera frame), scaled by how well the pose defines it.

    With the forearm in its neutral rotation the thumb side of the hand (the index knuckle's, relative to the
    pinky's) faces the way elbow flexion moves the wrist: forward for an arm hanging with the palm toward the thigh,
    up for a forearm held forward. Pronation and supination turn it at most ~80-90 deg either way, so of two
    candidates mirrored about the image plane the one nearer this direction is the likelier one when nothing
    measured decides (:func:`depth_sign_step`). A bent elbow (:data:`NEUTRAL_BEND_DEG`) gives it directly: minus
    the upper arm's part across the forearm. A straight arm
    does not show the upper arm's own rotation: the hanging arm's direction (the torso's forward axis, for the palm
    toward the thigh) is carried to the forearm's by the shortest swing from hanging (a T-pose: palms down;
    reaching forward: thumbs up), faded out from the horizontal to the arm held overhead, where the swing is
    undefined. It is a prior: wrong for a palms-up T-pose or a hand turned over with the shoulder's help.

    Args:
        p_s, p_e, p_w: ``(3,)`` shoulder, elbow, wrist in C (a missing shoulder: the straight-arm reference only).
        R_torso: ``(3, 3)`` the torso frame {0} in C (x forward, z up).

    Returns:
        ``(3,)`` across the forearm, length in [0, 1] (0: no prior).
    """
    f = np.asarray(p_w, dtype=float) - np.asarray(p_e, dtype=float)
    nf = float(np.linalg.norm(f))
    if not (math.isfinite(nf) and nf > 1e-6):
        return np.zeros(3)
    f /= nf
    down, forward = -np.asarray(R_torso, dtype=float)[:, 2], np.asarray(R_torso, dtype=float)[:, 0]
    c = float(down @ f)
    swing = np.zeros(3)
    if c > -1.0 + 1e-6:  # forward carried by the smallest rotation taking down onto f
        swing = np.array(turn_with(*forward.tolist(), *down.tolist(), *f.tolist()))
        swing = NEUTRAL_STRAIGHT_WEIGHT * min(1.0 + c, 1.0) * (swing - float(swing @ f) * f)  # faded overhead
    u = np.asarray(p_e, dtype=float) - np.asarray(p_s, dtype=float)
    bent = -(u - float(u @ f) * f) / float(np.linalg.norm(u)) if np.all(np.isfinite(u)) and np.linalg.norm(u) > 1e-6 \
        else np.zeros(3)
    lo, hi = (math.sin(math.radians(a)) for a in NEUTRAL_BEND_DEG)
    w = min(max((float(np.linalg.norm(bent)) - lo) / (hi - lo), 0.0), 1.0)
    return w * bent / max(float(np.linalg.norm(bent)), 1e-12) + (1.0 - w) * swing


def _across(v, f) -> np.ndarray:
    """The unit direction of ``v`` across the unit forearm ``f`` (zero when ``v`` is along it)."""
    v = v - float(v @ f) * f
    n = float(np.linalg.norm(v))
    return v / n if n > 1e-9 else np.zeros(3)


def roll_candidates(h_C, dz: float, forearm_C) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit forearm ``f`` and the two candidates ``h+/- = (h_x, h_y, +/-dz)`` taken across it (their roll about
    it), for :func:`roll_cosines`."""
    f = np.asarray(forearm_C, dtype=float) / max(float(np.linalg.norm(forearm_C)), 1e-12)
    return f, _across(np.array([h_C[0], h_C[1], dz]), f), _across(np.array([h_C[0], h_C[1], -dz]), f)


def roll_cosines(candidates, reference_C) -> tuple[float, float] | None:
    """``(cos(h+, r), cos(h-, r))`` of the two :func:`roll_candidates` to a reference direction ``r`` taken across
    the same forearm; None without ``r``."""
    if reference_C is None or not np.all(np.isfinite(reference_C)):
        return None
    f, u_plus, u_minus = candidates
    r = _across(np.asarray(reference_C, dtype=float), f)
    return float(u_plus @ r), float(u_minus @ r)


#: The hand's depth sign as a two-hypothesis filter (:func:`depth_sign_step`): the hand's roll rate about the forearm
#: between frames (rad/s, one sigma); the time constant (s) of the filter's reset to the anatomical prior (how long a
#: branch is kept on continuity alone); the measured depth's chance of the right sign, from none at the first share
#: of the hand's width in MEASURED_SIGN_SHARE to MEASURED_SIGN_P at the second (Hands' z on the demo's recordings,
#: 9 runs: right 0.57 under 2 mm, 0.61 2-5 mm, 0.73 5-10 mm, 0.87 10-20 mm, 0.94 20-30 mm; below ~5 mm its errors
#: persist over frames, so they would add up frame after frame); the prior's concentration on the roll (von Mises,
#: per unit of :func:`neutral_hand_direction`'s length); the belief after a frame whose forearm decided the sign.
ROLL_RATE_SIGMA, BRANCH_RESET_S, MEASURED_SIGN_P, MEASURED_SIGN_SHARE, NEUTRAL_KAPPA = 3.0, 2.0, 0.9, (0.07, 0.25), 1.0
FOREARM_SIGN_BELIEF = 0.98


def depth_sign_step(belief: float, h_C, dz: float, forearm_C, roll_previous_C, neutral_C, width_m: float,
                    dt: float):
    """One frame of the filter on the sign of the hand vector's depth part (the knuckle line's two mirror candidates
    ``(h_x, h_y, +/-dz)``), for frames whose forearm does not decide it
    (:func:`~akc_drake.core.frames.forearm_depth_sign`).

    A hidden Markov model with two states. Transition: the candidate whose roll about the forearm continues the
    previous frame's (:func:`roll_cosines` to ``roll_previous_C``, the previous wrist frame's hand direction: not the
    camera-z sign, which is arbitrary once the hand has crossed the image plane or the forearm has turned out of the
    ray) keeps the previous belief, the other gets it with the odds of the roll it would need in ``dt`` (Gaussian
    roll rate, :data:`ROLL_RATE_SIGMA`; half and half when the previous frame is as near to both); mixed with the
    anatomical prior (:func:`neutral_hand_direction`, von Mises ``exp(NEUTRAL_KAPPA |n| cos)``) at the rate
    ``dt / BRANCH_RESET_S``, which is all there is on a first frame. Observation: the measured depth's sign (up to
    :data:`MEASURED_SIGN_P`). So the prior decides only what neither the forearm, nor continuity, nor the measurement
    does (a first frame with Hands' z ~0), and a branch that the measurement and the prior keep contradicting is left
    within a second or two (before: continuity alone, so a hand put on the mirror once stayed there for a whole
    phase); a real turn is followed by continuity. The belief returned is that the roll is right: the chosen sign's
    probability, plus the other's when the two candidates are within the roll noise of each other (a forearm along
    the ray, where the sign barely moves the frame).

    Args:
        belief: the probability that the previous frame's branch was right (NaN: no previous frame).
        h_C: ``(3,)`` measured hand vector in C; dz: the depth part's size; forearm_C: ``p_e - p_w``;
        roll_previous_C: the previous frame's hand direction across its forearm, or None; neutral_C: the prior's
            direction (:func:`neutral_hand_direction`); width_m: the hand's width; dt: time since that frame, s.

    Returns:
        ``(sign, belief)``: +1 / -1 and the probability that it is right.
    """
    sigma = max(ROLL_RATE_SIGMA * dt, 1e-3)
    candidates = roll_candidates(h_C, dz, forearm_C)  # (taken across the forearm once, for the three references)
    c = roll_cosines(candidates, neutral_C)
    prior = 1.0 / (1.0 + math.exp(-NEUTRAL_KAPPA * float(np.linalg.norm(neutral_C)) * (c[0] - c[1]))) if c else 0.5
    c = roll_cosines(candidates, roll_previous_C) if math.isfinite(belief) else None
    p_plus = prior
    if c is not None:  # the previous belief carried to the candidate nearer in roll; a reset to the prior
        a_p, a_m = (math.acos(min(max(x, -1.0), 1.0)) for x in c)
        stay = 1.0 / (1.0 + math.exp(-min(abs(a_p**2 - a_m**2) / (2.0 * sigma**2), 50.0)))
        p_cont = belief * stay + (1.0 - belief) * (1.0 - stay)
        eps = 1.0 - math.exp(-dt / BRANCH_RESET_S)
        p_plus = (1.0 - eps) * (p_cont if a_p <= a_m else 1.0 - p_cont) + eps * prior
    log_odds = math.log(max(p_plus, 1e-12) / max(1.0 - p_plus, 1e-12))
    hz = float(h_C[2])
    lo, hi = MEASURED_SIGN_SHARE
    q = 0.5 + (MEASURED_SIGN_P - 0.5) * min(max((abs(hz) / width_m - lo) / (hi - lo), 0.0), 1.0)
    log_odds += math.copysign(math.log(q / (1.0 - q)), hz)
    post = 1.0 / (1.0 + math.exp(-min(max(log_odds, -50.0), 50.0)))
    post = max(post, 1.0 - post)
    c = roll_cosines(candidates, np.array([h_C[0], h_C[1], dz]))  # the two candidates' roll apart
    apart = math.acos(min(max(c[1], -1.0), 1.0)) if c is not None else math.pi
    belief = post + (1.0 - post) * math.exp(-(apart**2) / (2.0 * sigma**2))  # right in roll even if not in sign
    return (1.0 if log_odds >= 0.0 else -1.0), belief


#: MediaPipe Hands' index and pinky knuckles (MCP joints): landmarks 5 and 17.
HANDS_INDEX_MCP, HANDS_PINKY_MCP = 5, 17
#: When Hands misses a hand it had, its last hand vector is kept this long (s) before the pose's two points are
#: used again (on the demo's skinned body those are 30-100 deg off: one frame of them is a flip).
HANDS_HOLD_S = 0.5
#: Hands' knuckle line pointing the other way in the image (by more than this, deg) from the last one seen at
#: least :data:`HANDS_SWAP_MIN_SHARE` of the hand's width long in the image is taken as Hands swapping the index
#: and the pinky, not as a turn: a hand seen end-on (fingers toward the camera) reads about the same palm up and
#: palm down, and on the demo's reaches Hands' line reversed for 0.1-0.4 s, often through a frame or two where it
#: collapsed to a few millimetres, or when the hand came back after Hands had missed it (measured on the skinned
#: body: the wrist frame 130-180 deg off in those frames). A person's forearm rotation (<= ~10 rad/s) takes more
#: than a frame to turn it over, through the hand seen edge-on. The previous vector is kept, as for a missed hand;
#: a reversal that persists :data:`HANDS_HOLD_S` (no long line the old way meanwhile) is accepted, so a real turn
#: is followed at most that late.
HANDS_SWAP_DEG, HANDS_SWAP_MIN_SHARE = 90.0, 0.5


def hands_swapped(h_C, reference_xy, width_m: float) -> bool:
    """Whether Hands' knuckle vector ``h_C`` (camera frame) points the other way in the image from
    ``reference_xy`` (the last image part at least :data:`HANDS_SWAP_MIN_SHARE` of ``width_m`` long), by more than
    :data:`HANDS_SWAP_DEG`; False when ``h_C``'s own image part is shorter than that (no reliable direction)."""
    a, b = np.asarray(h_C, dtype=float)[:2], np.asarray(reference_xy, dtype=float)[:2]
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if not (math.isfinite(na) and math.isfinite(nb)) or na < HANDS_SWAP_MIN_SHARE * width_m or nb <= 0.0:
        return False
    return float(a @ b) < math.cos(math.radians(HANDS_SWAP_DEG)) * na * nb


def hands_knuckle_vector(hand_px, intrinsics) -> np.ndarray:
    """The index-to-pinky knuckle vector of one hand seen by MediaPipe Hands, in normalised image units.

    Hands' landmarks are pixels ``u, v`` and a relative depth ``z`` on ``u``'s scale (pixels), learnt from the
    hand's appearance: ``((u5 - u17) / fx, (v5 - v17) / fy, (z5 - z17) / fx)``. Times the hand's depth it is the
    vector in the camera frame C (:meth:`ControlFrameTracker.step` multiplies it by the knuckles' depth). Measured
    on the demo (MediaPipe on the skinned body), its image direction is 6-17 deg from the rig's knuckle line, where
    the pose model's two hand points are 28-107 deg off; the wrist frame built from it is 8-13 deg (median) from
    the operator's, against 33-66 deg from the pose's points.

    Args:
        hand_px: ``(21, 3)`` the hand's landmarks (``u, v, z`` pixels; NaN: no hand).
        intrinsics: the camera (``fx``, ``fy``).

    Returns:
        ``(3,)``; NaN when the hand or a knuckle is missing.
    """
    h = np.asarray(hand_px, dtype=float).reshape(-1, 3)
    d = h[HANDS_INDEX_MCP] - h[HANDS_PINKY_MCP]
    return np.array([d[0] / intrinsics.fx, d[1] / intrinsics.fy, d[2] / intrinsics.fx])


_S = smoothing.STATE_SIZE
_GATED = {side: [INDEX[n] for n in SPEED_GATED_LANDMARKS[side]] for side in SIDES}
_NG = 3 * len(_GATED["left"]) + 1  # gated positions + time


class ControlFrameTracker:
    """Landmarks to smoothed, workspace-clipped robot targets (see the module docstring).

    Args:
        mapping: the operator-to-robot mapping.
        torso_model: a calibrated :class:`TorsoModel` (None: eq. 17's torso from the shoulders).
        wrist_smoothing, torso_smoothing: :class:`~akc_drake.core.smoothing.SE3SmoothingParams`, None: off.
        workspace: per side a :class:`Workspace` (None: no clipping).
        max_landmark_speed: the speed gate, m/s (None: off).
        robust_wrist: rebuild the hand vector and keep the wrist frame off its mirror (step 2); False: eq. (17)
            on the landmarks as they are.
        torso_hold: :class:`~akc_drake.core.smoothing.HoldParams` of the torso anchor (None: off).
    """

    def __init__(
        self,
        mapping: RobotMapping,
        *,
        torso_model: TorsoModel | None = None,
        wrist_smoothing: smoothing.SE3SmoothingParams | None = smoothing.WRIST_SMOOTHING,
        torso_smoothing: smoothing.SE3SmoothingParams | None = smoothing.TORSO_SMOOTHING,
        workspace: dict | None = None,
        max_landmark_speed: float | None = DEFAULT_MAX_LANDMARK_SPEED,
        robust_wrist: bool = True,
        torso_hold: smoothing.HoldParams | None = None,
    ):
        self.mapping = mapping
        self.torso_smoothing, self.torso_hold = torso_smoothing, torso_hold
        self._hold = smoothing.SE3Hold(torso_hold) if torso_hold is not None else None
        self.robust_wrist = bool(robust_wrist)
        self.torso_model = torso_model
        self._torso_f = smoothing.SE3OneEuro(torso_smoothing) if torso_smoothing is not None else None
        self._wrist_f = smoothing.SE3OneEuro(wrist_smoothing) if wrist_smoothing is not None else None
        self.workspace = workspace
        self.max_speed = max_landmark_speed
        # Layout: torso filter | torso R (9) + origin (3) | per side: wrist filter, previous R_C (9), gate,
        # hand width estimate (1), previous hand vector (3), hand length estimate (1), time of the last hand
        # knuckles (1), the last long image part of Hands' knuckle vector (2), the time since which Hands has read it
        # reversed (1), the belief in the hand's depth sign (1).
        self._side = _S + 9 + _NG + 10
        self._hold_at = _S + 12 + 2 * self._side  # the torso anchor's state, last
        self.state_size = self._hold_at + smoothing.HOLD_STATE_SIZE

    def initial_state(self) -> np.ndarray:
        return np.full(self.state_size, np.nan)

    def _torso(self, state: np.ndarray, t: float, pose: np.ndarray):
        measured = self.torso_model.torso(pose) if self.torso_model is not None else torso_of(pose)
        if measured is not None:
            R, o = measured
            if self._hold is not None:  # held first: the One Euro filter then smooths the hold's moves
                h = slice(self._hold_at, self._hold_at + smoothing.HOLD_STATE_SIZE)
                state[h], R, o = self._hold.step(state[h], t, R, o)
            if self._torso_f is not None:
                state[:_S], R, o, _ = self._torso_f.step(state[:_S], t, R, o)
            state[_S : _S + 9] = R.ravel()
            state[_S + 9 : _S + 12] = o
        v = state[_S : _S + 12]
        if not np.all(np.isfinite(v)):
            return None
        return v[:9].reshape(3, 3), v[9:12]

    def _hand_vector(self, state: np.ndarray, sl: slice, i_belief: int, h: np.ndarray, forearm: np.ndarray,
                     roll_previous, neutral, dt: float) -> np.ndarray:
        """The hand vector rebuilt from its image-plane part (:func:`reconstruct_hand_vector`), its depth's sign
        from the forearm else :func:`depth_sign_step`; the hand's width is learnt from frames whose hand vector lies
        mostly in the image plane (exponential average)."""
        v = state[sl]
        width = v[0] if np.isfinite(v[0]) else DEFAULT_HAND_WIDTH_M
        n = float(np.linalg.norm(h))
        if n > 1e-6 and float(np.linalg.norm(h[:2])) >= 0.8 * n and 0.03 < n < 0.15:
            width += (0.3 if n > width else 0.02) * (n - width)  # the in-plane length is the most the projection shows
        previous = v[1:4] if np.all(np.isfinite(v[1:4])) else None
        sign = None
        if previous is None or float(h[0] ** 2 + h[1] ** 2) <= (HAND_OUTLIER_WIDTHS * width) ** 2:  # not an outlier
            dz = max(math.sqrt(max(width**2 - float(h[0] ** 2 + h[1] ** 2), 0.0)), 1e-9)
            sign = forearm_depth_sign(h, dz, forearm)
            if sign:
                state[i_belief] = FOREARM_SIGN_BELIEF
            else:
                sign, state[i_belief] = depth_sign_step(state[i_belief], h, dz, forearm, roll_previous, neutral, width,
                                                        dt)
        out = reconstruct_hand_vector(h, width, previous, forearm, sign)
        state[sl] = np.concatenate([[width], out])
        return out

    def _wrist(self, state: np.ndarray, j: int, p_e, p_w, p_i, p_p) -> np.ndarray:
        """The wrist, put behind its hand when the hand hides it (:func:`wrist_behind_hand`); the hand's length
        is learnt from frames whose wrist-to-knuckles vector lies mostly in the image plane (exponential average)."""
        length = state[j] if np.isfinite(state[j]) else DEFAULT_HAND_LENGTH_M
        d = p_w - 0.5 * (p_i + p_p)
        n = float(np.linalg.norm(d))
        if 0.04 < n < 0.15 and float(np.linalg.norm(d[:2])) >= 0.9 * n:
            length += 0.1 * (n - length)
        state[j] = length
        return wrist_behind_hand(p_e, p_w, p_i, p_p, length)

    def _hands_accepted(self, state: np.ndarray, ref_sl: slice, hand_sl: slice, t: float, h_meas) -> bool:
        """False when Hands' measured knuckle vector ``h_meas`` is an index/pinky swap: :func:`hands_swapped`
        against the last long image part, read so for less than :data:`HANDS_HOLD_S`. An accepted vector with a
        long image part becomes the reference."""
        width = state[hand_sl][0] if np.isfinite(state[hand_sl][0]) else DEFAULT_HAND_WIDTH_M
        ref = state[ref_sl]
        if self.robust_wrist and np.all(np.isfinite(ref[:2])) and hands_swapped(h_meas, ref[:2], width):
            since = ref[2] if np.isfinite(ref[2]) else t
            if t - since < HANDS_HOLD_S:
                state[ref_sl] = [ref[0], ref[1], since]
                return False
        if float(np.linalg.norm(h_meas[:2])) >= HANDS_SWAP_MIN_SHARE * width:
            state[ref_sl] = [h_meas[0], h_meas[1], np.nan]
        return True

    def step(self, state, t: float, pose, hand_knuckles=None) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
        """One camera frame.

        Args:
            state: the tracker state (:meth:`initial_state` first); t: the frame's time, s; pose: ``(12, 3)``
                landmarks in the camera frame C (NaN where missing).
            hand_knuckles: optional ``(2, 3)`` per side (left, right) MediaPipe Hands' knuckle vector in
                normalised image units (:func:`hands_knuckle_vector`; NaN where no hand): when given it replaces
                the pose's ``p_i - p_p`` as the measured hand vector (scaled by the pose knuckles' depth), whose
                image part is much closer to the hand's (see :func:`hands_knuckle_vector`).

        Returns:
            ``(new_state, targets, lost, clipped)``: per side (left, right) a 4x4 ``X_TE`` or None (lost: hold
            the previous target), ``lost`` and ``clipped`` as float arrays ``[left, right]``.
        """
        state = np.array(state, dtype=float)
        pose = np.asarray(pose, dtype=float).reshape(-1, 3)
        knuckles = None if hand_knuckles is None else np.asarray(hand_knuckles, dtype=float).reshape(2, 3)
        torso = self._torso(state, t, pose)
        targets: list = [None, None]
        lost = np.ones(2)
        clipped = np.zeros(2)
        if torso is None:
            return state, targets, lost, clipped
        R0, o0 = torso
        for k, side in enumerate(SIDES):
            b = _S + 12 + k * self._side
            f_sl, prev_sl = slice(b, b + _S), slice(b + _S, b + _S + 9)
            gate_sl, hand_sl = slice(b + _S + 9, b + _S + 9 + _NG), slice(b + _S + 9 + _NG, b + _S + 13 + _NG)
            i_length, i_hands_t = b + _S + 13 + _NG, b + _S + 14 + _NG
            ref_sl = slice(b + _S + 15 + _NG, b + _S + 18 + _NG)  # Hands' last long image part (2), reversed since
            p_e, p_w, p_i, p_p = (pose[INDEX[f"{side}_{n}"]] for n in ("elbow", "wrist", "index", "pinky"))
            R_w = None
            if np.all(np.isfinite([p_e, p_w, p_i, p_p])):
                if self.robust_wrist:
                    p_w = self._wrist(state, i_length, p_e, p_w, p_i, p_p)
                h_meas, previous = p_i - p_p, state[hand_sl][1:]
                fresh = knuckles is not None and bool(np.all(np.isfinite(knuckles[k])))
                if fresh:
                    h_meas = knuckles[k] * (0.5 * (p_i[2] + p_p[2]))  # Hands' knuckles at the pose knuckles' depth
                    fresh = self._hands_accepted(state, ref_sl, hand_sl, t, h_meas)
                    if fresh:
                        state[i_hands_t] = t
                if (knuckles is not None and not fresh and self.robust_wrist
                        and np.all(np.isfinite(previous)) and t - state[i_hands_t] <= HANDS_HOLD_S):
                    h = previous.copy()  # Hands missed the hand for a moment: a hand does not turn over in 0.5 s
                elif self.robust_wrist:  # continuity by the previous frame's roll (-x: the hand across the forearm)
                    prev = state[prev_sl]
                    neutral = neutral_hand_direction(pose[INDEX[f"{side}_shoulder"]], p_e, p_w, R0)
                    t_prev = state[gate_sl][-1]  # the time of the previous frame R_C
                    h = self._hand_vector(state, hand_sl, b + _S + 18 + _NG, h_meas, p_e - p_w,
                                          -prev[0::3] if np.all(np.isfinite(prev)) else None, neutral,
                                          t - t_prev if math.isfinite(t_prev) else 0.0)
                else:
                    h = h_meas
                R_w = wrist_frame(p_e, p_w, p_p + h, p_p)
            if R_w is None:
                continue
            gate = state[gate_sl]
            points = pose[_GATED[side]]
            if self.max_speed is not None and math.isfinite(gate[-1]):
                if not plausible_step(gate[:-1].reshape(-1, 3), points, t - gate[-1], self.max_speed):
                    continue  # a jump no person makes: a fault, hold the target
            prev = state[prev_sl]
            if self.robust_wrist:
                R_w = resolve_wrist_flip(R_w, h, prev.reshape(3, 3) if np.all(np.isfinite(prev)) else None)
            state[prev_sl] = R_w.ravel()
            state[gate_sl] = np.concatenate([points.ravel(), [t]])
            X = map_to_robot(transform(R0.T @ R_w, R0.T @ (p_w - o0)), side, self.mapping)
            if self._wrist_f is not None:
                state[f_sl], R, p, _ = self._wrist_f.step(state[f_sl], t, X[:3, :3], X[:3, 3])
                X = transform(R, p)
            if self.workspace is not None:
                p, was_clipped = self.workspace[side].clip(X[:3, 3])
                X[:3, 3] = p
                clipped[k] = float(was_clipped)
            targets[k] = X
            lost[k] = 0.0
        return state, targets, lost, clipped
