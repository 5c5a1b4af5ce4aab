"""Arm Kinematic Correction (AKC) exactly as the paper describes it: stage S4 (§II-D, eq. 7-15).

For each arm, the filtered wrist is trusted and the elbow and shoulder depths are rebuilt from the
calibrated segment lengths with the Pythagorean theorem (eq. 7-8): two elbow depths, and two shoulder
depths for each, give four candidate configurations. A negative radicand falls back to the validity
projection (eq. 9). The candidate with the smallest cost (eq. 10, metrics eq. 11-15) wins; the shoulder-width
metric m4 couples the two arms, so when both arms are tracked their 4 x 4 candidate pairs are scored jointly.
Our improved corrector, AKC+, is :mod:`akc_drake.core.akc_plus`.

**What the paper says, and how it is implemented here.**

* x, y of the elbow and shoulder: "Given reliable 2D coordinates (x, y) from pose detection, the depth (z)
  of occluded joints can be reconstructed using geometric constraints" (eq. 7-8 change z only), and
  "AKC improves depth estimation while preserving the accuracy of image-plane coordinates" (§IV); the
  x/y changes it reports are "less than 0.65 cm at worst" (§III-C). So a candidate keeps the filtered
  x, y of the elbow and shoulder; only eq. (9), "applied only as a fallback mechanism", moves them.
* The shrink factor: "the preset arm length is reduced during candidate search using a shrink factor
  (s), such that the adjusted length is l_j' = s l_j" (§II-D), to stop the depth jumping "between the ±
  solutions" when "the arm is fully extended near the zero-depth plane". And of the output: "AKC maintains
  constant arm length throughout the motion" (Table VI, 0.0 cm range, with s = 0.8 in the main tables).
  The paper does not say at which length the chosen configuration is output. Our reading, the one that
  satisfies all three statements: s is used *during the search*, i.e. to test the radicands (a radicand
  ``(s l)^2 - d_xy^2 < 0`` selects eq. 9, so the ± pair collapses into one candidate exactly in the
  near-extended case the paper describes), and every candidate is placed with the calibrated length l:
  ``p_e,z = p_w,z ± sqrt(l_f^2 - d_xy^2)`` (x, y kept) or eq. (9) with l. The output therefore has exactly
  the calibrated lengths, and x, y are kept except under eq. (9). (An earlier version of this module scaled
  the shrunk candidate about the wrist by 1/s, which moved x, y by 25 % of their in-plane distance.)
* The metrics are computed on these placed candidates, so m3 compares the candidate with the previous
  output at the same (full) lengths, and m4 scores the shoulders that are output.
* m5: "k if theta not in [40°, 180°]", which "penalizes joint configurations outside physiological
  limits (e.g., theta < 40° and theta > 180°)". An unsigned angle between two segments never exceeds 180°,
  so theta must be signed; the paper does not say how. Our convention
  (:func:`~akc_drake.core.arm_geometry.signed_elbow_angle_deg`): theta is the interior angle when the
  forearm bends the anatomical way and 360° - interior when it bends backwards (hyperextension), the
  anterior side of the upper arm following the torso frame of eq. (17).
* The paper is silent on: missing inputs (we hold the arm / reuse the last output, see the class), m3 on
  the first frame (0), m4 when one arm is missing (against the other side's filtered shoulder), ties
  (the lowest candidate index wins).

The hot path (:meth:`ArmKinematicCorrector.correct`) works on plain Python floats: a numpy call costs
microseconds, and AKC runs 16 joint candidates per frame. The input is converted to floats once and the
output back to numpy once.

Candidate indices: ``i = 2 * a + b`` with ``a`` the elbow sign of eq. (7) and ``b`` the shoulder sign of
eq. (8); sign index 0 is ``+`` (farther from the camera, larger z_C) and 1 is ``-`` (nearer).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

from akc_drake.core.arm_geometry import (
    arm_inputs,
    bends_backwards,
    elbow_angle_deg,
    signed_elbow_angle_deg,
    torso_axes,
)
from akc_drake.core.skeleton import NUM_LANDMARKS, SIDES, BodyDimensions, side_indices

_sqrt = math.sqrt
_hypot = math.hypot
_isfinite = math.isfinite
_NAN = float("nan")

#: A segment shorter than this (m) has no direction; the previous or the default direction is used.
_MIN_SEGMENT_M = 1e-12
#: Tolerance on the cosine of the elbow angle at the bounds of [elbow_min_deg, elbow_max_deg].
_COS_TOL = 1e-12

#: Length of the corrector's state vector: per side (shoulder, elbow, wrist) xyz = 18, then 2 validity flags.
STATE_SIZE = 20


@dataclass(frozen=True)
class AKCWeights:
    """Weights of the candidate cost (eq. 10) and the search shrink factor.

    Attributes:
        w1: elbow spatial consistency m1 (eq. 11).
        w2: shoulder spatial consistency m2 (eq. 12).
        w3: temporal consistency m3 (eq. 13).
        w4: shoulder-width regularisation m4 (eq. 14).
        w5: anatomical plausibility m5 (eq. 15).
        s: shrink factor; candidates are searched with lengths ``s * l`` (paper §II-D).
        elbow_min_deg, elbow_max_deg: the plausible elbow angle range of m5, degrees.
        k: the value of m5 outside that range.

    The default is the paper's preset ``Wb`` (w1=0, w2=14, w3=12, s=0.8, w4=w5=100).
    """

    w1: float = 0.0
    w2: float = 14.0
    w3: float = 12.0
    w4: float = 100.0
    w5: float = 100.0
    s: float = 0.8
    elbow_min_deg: float = 40.0
    elbow_max_deg: float = 180.0
    k: float = 1.0

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool):
                raise ValueError(f"AKCWeights.{f.name} must be a number, got {value!r}")
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"AKCWeights.{f.name} must be a number, got {value!r}") from None
            if not math.isfinite(v):
                raise ValueError(f"AKCWeights.{f.name} must be finite, got {value!r}")
            object.__setattr__(self, f.name, v)
        for name in ("w1", "w2", "w3", "w4", "w5", "k"):
            if getattr(self, name) < 0.0:
                raise ValueError(f"AKCWeights.{name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 < self.s <= 2.0:
            raise ValueError(f"AKCWeights.s (shrink factor) must be in (0, 2], got {self.s!r}")
        if not 0.0 <= self.elbow_min_deg <= 180.0:
            raise ValueError(f"AKCWeights.elbow_min_deg must be in [0, 180], got {self.elbow_min_deg!r}")
        if not 0.0 <= self.elbow_max_deg <= 180.0:
            raise ValueError(f"AKCWeights.elbow_max_deg must be in [0, 180], got {self.elbow_max_deg!r}")
        if self.elbow_min_deg >= self.elbow_max_deg:
            raise ValueError(
                f"AKCWeights.elbow_min_deg ({self.elbow_min_deg!r}) must be below "
                f"elbow_max_deg ({self.elbow_max_deg!r})"
            )

    @classmethod
    def preset(cls, name: str) -> AKCWeights:
        """One of the paper's presets ``"Wa"``, ``"Wb"``, ``"Wc"`` (§III-E).

        Raises:
            ValueError: naming the unknown preset.
        """
        try:
            return WEIGHT_PRESETS[name]
        except KeyError:
            known = ", ".join(WEIGHT_PRESETS)
            raise ValueError(f"unknown AKC weight preset {name!r}; known: {known}") from None

    def replace(self, **changes) -> AKCWeights:
        """A copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        return dataclasses.asdict(self)


#: The paper's weight presets: Wa tuned on Motion I, Wb on Motion II, Wc on both (w4 = w5 = 100 for all).
WEIGHT_PRESETS: MappingProxyType = MappingProxyType(
    {
        "Wa": AKCWeights(w1=0.0, w2=8.0, w3=18.0, s=1.0),
        "Wb": AKCWeights(w1=0.0, w2=14.0, w3=12.0, s=0.8),
        "Wc": AKCWeights(w1=1.0, w2=19.0, w3=20.0, s=0.9),
    }
)


class AKCResult:
    """The outcome of one :meth:`ArmKinematicCorrector.correct` call.

    Attributes:
        pose: ``(12, 3)`` the input pose with the six arm joints replaced by the corrected ones.
        chosen: ``(2,)`` int, the chosen candidate index per arm (left, right); -1 when the arm was held.
        fallback: ``(2,)`` bool, the validity projection (eq. 9) was used for the arm.
        held: ``(2,)`` bool, the arm could not be corrected and holds its last output (NaN if none).
        cost: ``(2,)`` the chosen candidate's cost (eq. 10) per arm; NaN when held.

    The four diagnostics are kept as given (e.g. Python lists) and converted to numpy arrays on first
    access: building four small arrays costs about as much as a sixth of an AKC frame, and a caller that
    only wants the pose should not pay for them.
    """

    __slots__ = ("pose", "_chosen", "_fallback", "_held", "_cost")

    def __init__(self, pose: np.ndarray, chosen, fallback, held, cost):
        self.pose = pose
        self._chosen = chosen
        self._fallback = fallback
        self._held = held
        self._cost = cost

    @property
    def chosen(self) -> np.ndarray:
        a = self._chosen
        if type(a) is not np.ndarray:
            a = self._chosen = np.asarray(a, dtype=np.int64)
        return a

    @property
    def fallback(self) -> np.ndarray:
        a = self._fallback
        if type(a) is not np.ndarray:
            a = self._fallback = np.asarray(a, dtype=bool)
        return a

    @property
    def held(self) -> np.ndarray:
        a = self._held
        if type(a) is not np.ndarray:
            a = self._held = np.asarray(a, dtype=bool)
        return a

    @property
    def cost(self) -> np.ndarray:
        a = self._cost
        if type(a) is not np.ndarray:
            a = self._cost = np.asarray(a, dtype=np.float64)
        return a

    def __repr__(self) -> str:
        return (
            f"AKCResult(chosen={self.chosen.tolist()}, fallback={self.fallback.tolist()}, "
            f"held={self.held.tolist()}, cost={self.cost.tolist()}, pose=<{self.pose.shape}>)"
        )


class ArmCandidates(NamedTuple):
    """The four candidate configurations of one arm (index ``2 * a + b``, see the module docstring).

    Attributes:
        elbow: ``(4, 3)`` elbow position of each candidate (rows 0-1 and 2-3 share an elbow).
        shoulder: ``(4, 3)`` shoulder position of each candidate.
        elbow_fallback: the elbow radicand of eq. (7) was negative and eq. (9) placed the elbow.
        shoulder_fallback: ``(2,)`` bool, per elbow candidate, eq. (9) placed the shoulder.
    """

    elbow: np.ndarray
    shoulder: np.ndarray
    elbow_fallback: bool
    shoulder_fallback: np.ndarray


def _shoulder_pair(ex, ey, ez, sx, sy, sz, lu_s, lu):
    """Two shoulder candidates from one elbow (eq. 8), or twice the eq. (9) projection. Plain floats.

    The radicand is tested with the search length ``lu_s = s l_u`` (the shrink factor); a candidate is
    then placed with the calibrated length ``lu``, keeping the shoulder's x, y (see the module docstring).
    """
    dx = sx - ex
    dy = sy - ey
    d2 = dx * dx + dy * dy
    if d2 <= lu_s * lu_s and d2 <= lu * lu:
        q = _sqrt(lu * lu - d2)
        # eq. (8): p_s,z = p_e,z ± sqrt(l_u^2 - (p_s,x - p_e,x)^2 - (p_s,y - p_e,y)^2)
        return (sx, sy, ez + q), (sx, sy, ez - q), False
    # eq. (9): p_s = p_e + l_u (p_s - p_e) / ||p_s - p_e||
    dz = sz - ez
    n = _hypot(dx, dy, dz)
    f = lu / n if n > _MIN_SEGMENT_M else 0.0
    p = (ex + dx * f, ey + dy * f, ez + dz * f)
    return p, p, True


def _candidates(wx, wy, wz, ex, ey, ez, sx, sy, sz, lf_s, lu_s, lf, lu):
    """The four candidates of one arm in plain floats (searched with ``lf_s, lu_s``, placed with ``lf, lu``).

    Returns:
        ``(E, S, elbow_fallback, shoulder_fallback)``: ``E`` two elbow tuples, ``S`` four shoulder tuples
        (``S[2a + b]`` belongs to ``E[a]``), the elbow flag and a tuple of two shoulder flags.
    """
    dx = ex - wx
    dy = ey - wy
    d2 = dx * dx + dy * dy
    if d2 <= lf_s * lf_s and d2 <= lf * lf:
        q = _sqrt(lf * lf - d2)
        # eq. (7): p_e,z = p_w,z ± sqrt(l_f^2 - (p_e,x - p_w,x)^2 - (p_e,y - p_w,y)^2)
        e0 = (ex, ey, wz + q)
        e1 = (ex, ey, wz - q)
        efb = False
    else:
        # eq. (9): p_e = p_w + l_f (p_e - p_w) / ||p_e - p_w||  (||.|| >= in-plane distance > 0)
        dz = ez - wz
        f = lf / _hypot(dx, dy, dz)
        e0 = e1 = (wx + dx * f, wy + dy * f, wz + dz * f)
        efb = True
    s0, s1, fb0 = _shoulder_pair(e0[0], e0[1], e0[2], sx, sy, sz, lu_s, lu)
    if efb:
        s2, s3, fb1 = s0, s1, fb0
    else:
        s2, s3, fb1 = _shoulder_pair(e1[0], e1[1], e1[2], sx, sy, sz, lu_s, lu)
    return (e0, e1), (s0, s1, s2, s3), efb, (fb0, fb1)


def _vec3(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.shape != (3,):
        raise ValueError(f"{name} must have shape (3,), got {a.shape}")
    return a


def akc_arm_candidates(p_w, p_e_hat, p_s_hat, l_f: float, l_u: float, shrink: float = 1.0) -> ArmCandidates:
    """The four candidate configurations of one arm (eq. 7-9), as the corrector computes them.

    Args:
        p_w: ``(3,)`` the filtered wrist (finite).
        p_e_hat: ``(3,)`` the filtered elbow; x, y must be finite; a NaN z is taken as the wrist's
            (it only matters for the eq. 9 projection).
        p_s_hat: ``(3,)`` the filtered shoulder; x, y must be finite; a NaN z is taken as ``p_e_hat``'s
            (or the wrist's).
        l_f: calibrated forearm length, metres.
        l_u: calibrated upper-arm length, metres.
        shrink: the shrink factor s: a radicand is tested with ``s * l`` (negative -> eq. 9), candidates are
            placed with ``l``.

    Returns:
        The :class:`ArmCandidates`.

    Raises:
        ValueError: naming the argument that has the wrong shape or a non-finite value.
    """
    w = _vec3(p_w, "p_w")
    e = _vec3(p_e_hat, "p_e_hat")
    s = _vec3(p_s_hat, "p_s_hat")
    if not np.all(np.isfinite(w)):
        raise ValueError(f"p_w must be finite, got {w.tolist()}")
    if not np.all(np.isfinite(e[:2])):
        raise ValueError(f"p_e_hat x, y must be finite, got {e.tolist()}")
    if not np.all(np.isfinite(s[:2])):
        raise ValueError(f"p_s_hat x, y must be finite, got {s.tolist()}")
    for name, v in (("l_f", l_f), ("l_u", l_u)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a positive finite length, got {v!r}")
    wx, wy, wz = (float(t) for t in w)
    ex, ey, ez = (float(t) for t in e)
    sx, sy, sz = (float(t) for t in s)
    if not math.isfinite(ez):
        ez = wz
    if not math.isfinite(sz):
        sz = ez
    lf, lu = float(l_f), float(l_u)
    E, S, efb, sfb = _candidates(wx, wy, wz, ex, ey, ez, sx, sy, sz, shrink * lf, shrink * lu, lf, lu)
    elbows = np.array([E[0], E[0], E[1], E[1]], dtype=float)
    return ArmCandidates(elbows, np.array(S, dtype=float), bool(efb), np.array(sfb, dtype=bool))





class ArmKinematicCorrector:
    """AKC for both arms, with the previous corrected output as state (for m3 and for holding).

    Args:
        dims: the calibrated body dimensions (arm lengths and shoulder width).
        weights: cost weights and shrink factor; the paper's ``Wb`` by default.
        anatomical_check: hold an arm whose chosen configuration is anatomically impossible (see below).

    Per arm and frame (see the module docstring for the candidates):

    * missing wrist (any coordinate NaN/inf) -> the arm holds its last output (``held``), NaN if none yet;
    * missing elbow/shoulder x or y -> x, y (and a missing z) from the previous output; held if none yet;
    * missing elbow z -> the wrist's z, missing shoulder z -> the elbow's (only eq. 9 and m1/m2 use them);
    * with ``anatomical_check`` (off by default, the paper's AKC; the teleop diagram turns it on): when the
      chosen candidate has its elbow angle outside ``[elbow_min_deg, elbow_max_deg]`` (with m5 on, that
      means every candidate is anatomically impossible, e.g. a garbage wrist next to the shoulder), the arm
      holds its last output for that frame (``held``) rather than output an impossible arm.

    The output always has exactly the calibrated arm lengths for a corrected arm (to rounding).
    """

    def __init__(
        self, dims: BodyDimensions, weights: AKCWeights | None = None, *, anatomical_check: bool = False
    ):
        if not isinstance(dims, BodyDimensions):
            raise ValueError(f"dims must be a BodyDimensions, got {type(dims).__name__}")
        self._anatomical_check = bool(anatomical_check)
        if weights is None:
            weights = AKCWeights()
        if not isinstance(weights, AKCWeights):
            raise ValueError(f"weights must be an AKCWeights, got {type(weights).__name__}")
        self._dims = dims
        self._weights = weights
        s = weights.s
        self._lf = (dims.LLA, dims.RLA)
        self._lu = (dims.LUA, dims.RUA)
        self._lf_s = (s * dims.LLA, s * dims.RLA)
        self._lu_s = (s * dims.LUA, s * dims.RUA)
        self._ls = dims.SW
        self._wv = (weights.w1, weights.w2, weights.w3, weights.w5 * weights.k)
        # theta >= elbow_min <=> cos(theta) <= cos(elbow_min); theta <= elbow_max <=> cos >= cos(elbow_max).
        self._cos_min = math.cos(math.radians(weights.elbow_min_deg)) + _COS_TOL
        self._cos_max = math.cos(math.radians(weights.elbow_max_deg)) - _COS_TOL
        # Flat offsets into the row-major (12, 3) pose of (shoulder, elbow, wrist) per side.
        self._offsets = tuple(tuple(3 * i for i in side_indices(side)) for side in SIDES)
        self._prev: list[tuple | None] = [None, None]

    @property
    def dims(self) -> BodyDimensions:
        return self._dims

    @property
    def weights(self) -> AKCWeights:
        return self._weights

    def reset(self) -> None:
        """Forget the previous output (the next frame is a first frame)."""
        self._prev = [None, None]

    def get_state_vector(self) -> np.ndarray:
        """The state as a ``(20,)`` vector: per side (left, right) shoulder, elbow, wrist xyz, then 2 flags.

        Joints of an arm without a previous output are NaN and its flag is 0.
        """
        v = np.full(STATE_SIZE, np.nan)
        for side in (0, 1):
            p = self._prev[side]
            if p is not None:
                v[9 * side : 9 * side + 9] = p
                v[18 + side] = 1.0
            else:
                v[18 + side] = 0.0
        return v

    def set_state_vector(self, v) -> None:
        """Restore a state from :meth:`get_state_vector`.

        Raises:
            ValueError: naming the wrong shape, a bad flag, or non-finite joints of a valid arm.
        """
        a = np.asarray(v, dtype=float)
        if a.shape != (STATE_SIZE,):
            raise ValueError(f"AKC state vector must have shape ({STATE_SIZE},), got {a.shape}")
        prev: list[tuple | None] = [None, None]
        for side in (0, 1):
            flag = a[18 + side]
            if flag not in (0.0, 1.0):
                raise ValueError(
                    f"AKC state vector: validity flag [{18 + side}] must be 0 or 1, got {flag!r}"
                )
            if flag == 1.0:
                joints = a[9 * side : 9 * side + 9]
                if not np.all(np.isfinite(joints)):
                    raise ValueError(
                        f"AKC state vector: {SIDES[side]} arm is flagged valid but has non-finite joints "
                        f"{joints.tolist()}"
                    )
                prev[side] = tuple(joints.tolist())
        self._prev = prev

    # ------------------------------------------------------------------ hot path (plain floats)

    def _prepare(self, v, side, axes):
        """Candidates and their per-arm costs (all metrics but m4) for one side, or None to hold."""
        prev = self._prev[side]
        joints = arm_inputs(v, self._offsets[side], prev)
        if joints is None:
            return None
        sx, sy, sz, ex, ey, ez, wx, wy, wz = joints

        lf = self._lf[side]
        lu = self._lu[side]
        E, S, efb, sfb = _candidates(
            wx, wy, wz, ex, ey, ez, sx, sy, sz, self._lf_s[side], self._lu_s[side], lf, lu
        )
        w1, w2, w3, kw5 = self._wv
        if prev is None:
            w3 = 0.0  # eq. (13) is 0 on the first frame
        (e0x, e0y, e0z), (e1x, e1y, e1z) = E
        c0 = c1 = 0.0
        if w1:
            # eq. (11): m1 = ||p_e - p̂_e||
            c0 = w1 * _hypot(e0x - ex, e0y - ey, e0z - ez)
            c1 = w1 * _hypot(e1x - ex, e1y - ey, e1z - ez)
        if w3:
            # eq. (13), elbow part: ||p_e - p_e^prev|| (both placed at the calibrated lengths)
            c0 += w3 * _hypot(e0x - prev[3], e0y - prev[4], e0z - prev[5])
            c1 += w3 * _hypot(e1x - prev[3], e1y - prev[4], e1z - prev[5])
        costs = [c0, c0, c1, c1]
        if w2 or w3 or kw5:
            if w3:
                p0, p1, p2 = prev[0], prev[1], prev[2]
            px, py, pz = e0x, e0y, e0z
            for i in range(4):
                if i == 2:
                    px, py, pz = e1x, e1y, e1z
                qx, qy, qz = S[i]
                c = costs[i]
                if w2:
                    # eq. (12): m2 = ||p_s - p̂_s||
                    c += w2 * _hypot(qx - sx, qy - sy, qz - sz)
                if w3:
                    # eq. (13), shoulder part: ||p_s - p_s^prev||
                    c += w3 * _hypot(qx - p0, qy - p1, qz - p2)
                if kw5 and not self._angle_ok(qx, qy, qz, px, py, pz, wx, wy, wz, lu, lf, axes):
                    # eq. (15): m5 = k when the signed elbow angle theta is outside [theta_min, theta_max]
                    c += kw5
                costs[i] = c
        return (wx, wy, wz), E, S, costs, efb or sfb[0] or sfb[1]

    def _angle_ok(self, sx, sy, sz, ex, ey, ez, wx, wy, wz, lu, lf, axes) -> bool:
        """m5's test: the signed elbow angle theta lies in ``[elbow_min_deg, elbow_max_deg]``.

        theta is the interior angle (shoulder-elbow-wrist) when the forearm bends the anatomical way, and
        ``360 deg - interior`` when it bends backwards (hyperextension),
        see :func:`~akc_drake.core.arm_geometry.signed_elbow_angle_deg`.
        ``lu`` and ``lf`` are the segments' lengths (the placed candidates have exactly these).
        """
        ux, uy, uz = sx - ex, sy - ey, sz - ez
        fx, fy, fz = wx - ex, wy - ey, wz - ez
        cos_t = (ux * fx + uy * fy + uz * fz) / (lu * lf)
        if cos_t > self._cos_min:  # interior angle below elbow_min_deg (or its mirror above 360 - min)
            return False
        if bends_backwards(ux / lu, uy / lu, uz / lu, fx, fy, fz, lf, axes):
            return False  # theta = 360 deg - interior > 180 deg >= elbow_max_deg
        return cos_t >= self._cos_max

    def correct(self, pose) -> AKCResult:
        """Correct one filtered pose.

        Args:
            pose: ``(12, 3)`` filtered landmarks in the camera frame, NaN where missing.

        Returns:
            The :class:`AKCResult`; the non-arm landmarks are passed through unchanged.

        Raises:
            ValueError: if ``pose`` does not have shape (12, 3).
        """
        a = np.asarray(pose, dtype=np.float64)
        if a.shape != (NUM_LANDMARKS, 3):
            raise ValueError(f"pose must have shape ({NUM_LANDMARKS}, 3), got {a.shape}")
        v = a.ravel().tolist()
        axes = torso_axes(v) if self._wv[3] or self._anatomical_check else None
        left = self._prepare(v, 0, axes)
        right = self._prepare(v, 1, axes)
        chosen = [-1, -1]
        cost = [_NAN, _NAN]
        w4 = self._weights.w4
        ls = self._ls

        if left is not None and right is not None:
            Sl, Sr = left[2], right[2]
            cl, cr = left[3], right[3]
            if w4:
                # Both arms tracked: score the 4 x 4 pairs jointly; each arm's eq. (10) cost includes w4 m4,
                # and the pair with the smallest sum of the two arms' costs wins.
                best = math.inf
                bi = bj = 0
                bm = 0.0
                w4x2 = 2.0 * w4
                # The inner loop over the right arm's 4 candidates is unrolled (a third faster in CPython).
                (r0x, r0y, r0z), (r1x, r1y, r1z), (r2x, r2y, r2z), (r3x, r3y, r3z) = Sr
                cr0, cr1, cr2, cr3 = cr
                for i in range(4):
                    qx, qy, qz = Sl[i]
                    base = cl[i]
                    # eq. (14): m4 = | l_s - ||p_s,l - p_s,r|| |, for the right candidates j = 0..3
                    m4 = abs(ls - _hypot(qx - r0x, qy - r0y, qz - r0z))
                    t = base + cr0 + w4x2 * m4
                    if t < best:
                        best, bi, bj, bm = t, i, 0, m4
                    m4 = abs(ls - _hypot(qx - r1x, qy - r1y, qz - r1z))
                    t = base + cr1 + w4x2 * m4
                    if t < best:
                        best, bi, bj, bm = t, i, 1, m4
                    m4 = abs(ls - _hypot(qx - r2x, qy - r2y, qz - r2z))
                    t = base + cr2 + w4x2 * m4
                    if t < best:
                        best, bi, bj, bm = t, i, 2, m4
                    m4 = abs(ls - _hypot(qx - r3x, qy - r3y, qz - r3z))
                    t = base + cr3 + w4x2 * m4
                    if t < best:
                        best, bi, bj, bm = t, i, 3, m4
                chosen = [bi, bj]
                cost = [cl[bi] + w4 * bm, cr[bj] + w4 * bm]
            else:
                bi = min(range(4), key=cl.__getitem__)
                bj = min(range(4), key=cr.__getitem__)
                chosen = [bi, bj]
                cost = [cl[bi], cr[bj]]
        else:
            for side, prep in ((0, left), (1, right)):
                if prep is None:
                    continue
                c = prep[3]
                S = prep[2]
                other = self._other_shoulder(v, 1 - side) if w4 else None
                if other is not None:
                    ox, oy, oz = other
                    # eq. (14) against the other side's filtered (or last output) shoulder.
                    c = [
                        ci + w4 * abs(ls - _hypot(q[0] - ox, q[1] - oy, q[2] - oz))
                        for ci, q in zip(c, S, strict=True)
                    ]
                i = min(range(4), key=c.__getitem__)
                chosen[side] = i
                cost[side] = c[i]

        held = [True, True]
        fallback = [False, False]
        for side, prep in ((0, left), (1, right)):
            o_s, o_e, o_w = self._offsets[side]
            if prep is not None:
                i = chosen[side]
                # The candidates are already placed at the calibrated lengths (eq. 7-9 with l, not s l).
                out = (*prep[2][i], *prep[1][i >> 1], *prep[0])
                if _isfinite(sum(out)) and (not self._anatomical_check or self._plausible(side, out, axes)):
                    self._prev[side] = out
                    held[side] = False
                    fallback[side] = prep[4]
                else:  # overflow from absurd input, or an impossible elbow: hold instead of emitting it
                    chosen[side] = -1
                    cost[side] = _NAN
            if held[side]:
                out = self._prev[side]
                if out is None:
                    out = (_NAN,) * 9
            v[o_s : o_s + 3] = out[0:3]
            v[o_e : o_e + 3] = out[3:6]
            v[o_w : o_w + 3] = out[6:9]
        # The diagnostics stay Python lists until read (see AKCResult).
        return AKCResult(np.array(v).reshape(NUM_LANDMARKS, 3), chosen, fallback, held, cost)

    def _plausible(self, side, out, axes) -> bool:
        """The placed arm ``out`` (9 floats) has its signed elbow angle within [elbow_min_deg, elbow_max_deg]."""
        return self._angle_ok(*out, self._lu[side], self._lf[side], axes)

    def _other_shoulder(self, v, side):
        """The other side's shoulder for m4: filtered if finite, else its last output, else None."""
        o = self._offsets[side][0]
        x, y, z = v[o], v[o + 1], v[o + 2]
        if _isfinite(x + y + z):
            return x, y, z
        p = self._prev[side]
        if p is not None:
            return p[0], p[1], p[2]
        return None


__all__ = [
    "AKCResult",
    "AKCWeights",
    "ArmCandidates",
    "ArmKinematicCorrector",
    "WEIGHT_PRESETS",
    "akc_arm_candidates",
    "elbow_angle_deg",
    "signed_elbow_angle_deg",
    "torso_axes",
]
