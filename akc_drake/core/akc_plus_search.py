"""AKC+'s candidate search: the Gaussian cost of a rebuilt joint's candidates and the choice among them.

A rebuilt joint's candidates (eq. 7-8, the circle between a kept shoulder and the wrist, or the nearest point
at the calibrated length) are scored as Gaussian log-likelihoods (:mod:`akc_drake.core.akc_plus`)::

    J = |p - p̂|^2 / sigma_f^2 + min(|p - p_prev|^2 / sigma_t^2, cap^2) [+ width, torso and anatomy terms]

The anatomy term (a folded or hyperextended elbow) is a penalty >= 0 computed last and only for a candidate
that can still win: floating-point addition is monotone, so a partial cost already at or above the best one
stays there whatever is added (the choice is the same as computing every term of every candidate).

:class:`CandidateSearch` is a mixin of :class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus`: it reads
the corrector's per-frame state (the filter priors left out, the covariance-matched variances, the previous
output, the torso's depth) and its settings.
"""

from __future__ import annotations

import math

from akc_drake.core.arm_geometry import bends_backwards, segment_distance2, torso_axes
from akc_drake.core.arm_geometry import candidates as _candidates
from akc_drake.core.arm_geometry import d2 as _d2
from akc_drake.core.arm_geometry import radial as _radial
from akc_drake.core.skeleton import INDEX

_hypot = math.hypot
_inf = math.inf
_NAN = float("nan")
_isfinite = math.isfinite
_LHIP_Z = 3 * INDEX["left_hip"] + 2
_RHIP_Z = 3 * INDEX["right_hip"] + 2
#: The anatomical tests' penalty (a squared standard deviation) for a folded (below elbow_min_deg) or a
#: hyperextended (m5) elbow: both are tests on noisy positions near their limits (a tight but real fold
#: whose filtered elbow depth is a few cm off reads below the limit; a nearly straight arm's direction of
#: bend is noise), so they are strong evidence, no veto: a filter estimate that fits the lengths and a
#: continuous configuration can outweigh them, a mirror candidate tens of cm away cannot.
BACKWARDS = 25.0


class CandidateSearch:
    """The candidate costs and choices of AKC+ (a mixin: the corrector holds the state it reads)."""

    __slots__ = ()

    def _other_shoulder(self, side):
        """The other shoulder for the shoulder width term: its last corrected position (the filtered one may be
        drifting on a lost depth), else the filtered one; None if neither is known.

        Only a shoulder seen when last corrected counts (a rebuilt one may be a wrong configuration, which the
        width term would copy to this side). Needed only when a shoulder is rebuilt (a few frames in a hundred),
        so computed then: neither the other arm's output, its counters nor the pose change during this arm's
        correction, so it is what it would have been before it.
        """
        po = self._prev[1 - side]
        if po is not None:
            return None if self._lost[3 - 2 * side] > 0 else (po[0], po[1], po[2])
        v, o = self._v, self._offsets[1 - side][0]
        x, y, z = v[o], v[o + 1], v[o + 2]
        return (x, y, z) if _isfinite(x + y + z) else None

    def _inv_f2(self, k):
        """1 / sigma_f^2 of joint ``k``'s filter prior (0 when the filter's estimate was replaced by ours)."""
        if k in self._no_prior:
            return 0.0
        vs = self._cur_var
        if vs is not None:
            # The filter's own (covariance-matched) depth variance of the joint.
            v = vs[5 if k % 2 == 0 else 2]
            # A variance the filter does not know (NaN: not yet initialised) is no prior at all.
            return 1.0 / max(v, 1e-12) if v == v else 0.0
        cfg = self.config
        # Drift: the frames without a depth (unless the estimate still fits the calibrated length) and twice
        # the distance the filter's depth has travelled since it was lost.
        sf = cfg.sigma_filter_m + 2.0 * self._travel[k]
        if k not in self._fits:
            sf += self._pf.drift_m_per_frame * self._lost[k]
        return 1.0 / (sf * sf)

    def _choose(self, cands, fx, fy, fz, prev_p, k_lost, extra=None):
        """The candidate with the smallest Gaussian cost (filter prior, temporal prior, extra terms)."""
        inv_f2 = self._inv_f2(k_lost)
        best = None
        best_j = _inf
        for i, p in enumerate(cands):
            j = _d2(p, fx, fy, fz) * inv_f2
            if prev_p is not None:
                j += min(_d2(p, prev_p[0], prev_p[1], prev_p[2]) * self._inv_t2, self._t_cap)
            if extra is not None:
                j += extra[i]
            if j < best_j:
                best_j, best = j, p
        return best, best_j

    def _choose_elbow(self, cands, fx: float, fy: float, fz: float, prev_p, k_lost, s, w, lu: float, lf: float,
                      inv_w2=None):
        """:meth:`_choose` of elbow candidates with the anatomical penalty (shoulder ``s``, wrist ``w``) and,
        with ``inv_w2``, the wrist's forearm-length term ``(|c - w| - lf)^2 inv_w2`` as extra terms.

        The same choice as computing every term of every candidate (the first candidate with the smallest
        cost), with the penalty (0 or ``BACKWARDS``) computed only where it can change the choice: not at all
        when the candidate with the smallest other terms wins even with the penalty and the others without it
        (mirror candidates tens of cm apart usually differ by more than the penalty), else only for a
        candidate whose other terms leave it a chance to win. (``_inv_f2`` inline: this runs on most frames.)
        """
        inv_f2: float; v: float; inv_t2: float; t_cap: float; qx: float; qy: float; qz: float; px: float; py: float
        pz: float; x: float; high: float; pen_b: float; best_j: float  # (C doubles when compiled: setup.py)
        if k_lost in self._no_prior:
            inv_f2 = 0.0
        else:
            vs = self._cur_var
            if vs is None:
                inv_f2 = self._inv_f2(k_lost)
            else:
                v = vs[5 if k_lost % 2 == 0 else 2]
                inv_f2 = 1.0 / (1e-12 if 1e-12 > v else v) if v == v else 0.0  # (max(v, 1e-12) exactly)
        inv_t2, t_cap = self._inv_t2, self._t_cap
        qx, qy, qz = prev_p if prev_p is not None else (0.0, 0.0, 0.0)  # (not read without prev_p)
        # Each candidate's terms without the penalty: j (filter, temporal) and x (the wrist's), low = j + x.
        js, xs, lows = [], [], []
        for px, py, pz in cands:
            dx, dy, dz = px - fx, py - fy, pz - fz
            j = (dx * dx + dy * dy + dz * dz) * inv_f2
            if prev_p is not None:
                dx, dy, dz = px - qx, py - qy, pz - qz
                t = (dx * dx + dy * dy + dz * dz) * inv_t2
                j += t_cap if t_cap < t else t  # (min(t, t_cap), NaN included)
            if inv_w2 is None:
                x = 0.0
            else:
                x = _hypot(px - w[0], py - w[1], pz - w[2]) - lf
                x = x * x * inv_w2
            js.append(j)
            xs.append(x)
            lows.append(j + x)
        # Bounds on each cost j + (x + penalty) (rounding is monotone): j + x <= cost <= j + (x + BACKWARDS).
        n = len(lows)
        b = 0
        for i in range(1, n):
            if lows[i] < lows[b]:
                b = i
        high = js[b] + (xs[b] + BACKWARDS)
        for i in range(n):
            if i != b and not high < lows[i]:  # (NaN: no shortcut)
                break
        else:
            return cands[b] if high < _inf else None
        # The candidate with the smallest other terms first: without the penalty its cost is its low, and it wins
        # outright (a later candidate's cost is at least its own low, which is no smaller: a tie goes to the
        # first; an earlier one's low is larger, as b is the first smallest).
        pen_b = self._penalty(s, cands[b], w, lu, lf)
        if pen_b == 0.0 and lows[b] < _inf:
            return cands[b]
        best = None
        best_j = _inf
        for i in range(n):
            if lows[i] >= best_j:
                continue  # (the penalty is >= 0)
            j = js[i] + (xs[i] + (pen_b if i == b else self._penalty(s, cands[i], w, lu, lf)))
            if j < best_j:
                best_j, best = j, cands[i]
        return best

    def _penalty(self, s, e, w, lu: float, lf: float, axes=None):
        """BACKWARDS when the arm's elbow is folded below elbow_min_deg or hyperextended (m5, our sign:
        :func:`~akc_drake.core.arm_geometry.bends_backwards`)."""
        ex: float; ey: float; ez: float
        ex, ey, ez = e
        ux, uy, uz = s[0] - ex, s[1] - ey, s[2] - ez
        fx, fy, fz = w[0] - ex, w[1] - ey, w[2] - ez
        cos_t = (ux * fx + uy * fy + uz * fz) / (lu * lf)
        if cos_t > self._cos_min:
            return BACKWARDS
        if axes is None:  # the torso's axes, computed once per frame and only when needed
            axes = self._axes
            if axes is None:
                axes = self._axes = torso_axes(self._v0)
        return BACKWARDS if bends_backwards(ux / lu, uy / lu, uz / lu, fx, fy, fz, lf, axes) else 0.0

    def _held_z(self, side):
        """The depth of ``side``'s shoulder held on the torso: this frame's anchor's depth (the hips', else the other
        shoulder's) plus our outputs' running-mean offset from it (NaN when none is held or no anchor is seen)."""
        a = self._anchor[side]
        return _NAN if a is None else a[0][2] + a[1][2]

    def _set_torso(self, side):
        """The torso term of ``side``'s shoulder candidates (``_tz``, ``_inv_tz2``), set before a rebuild.

        The held shoulder's depth (the hips' depth ``_hips[2]`` carrying our outputs' running-mean offset, with the
        hold's variance as ``fuse_held``'s) when known, else the hips' depth of the pose as given with
        ``sigma_torso_m``. A shoulder read on its own upper arm 24 cm in front is equidistant from eq. 8's two
        candidates, and the hips' 20 cm let the one 50 cm in front win (MediaPipe, bvhtools_a1).
        """
        tz = self._held_z(side)
        if tz == tz:
            self._tz, self._inv_tz2 = tz, 1.0 / (self._v_s * (self._anchor[side][1][3] + 1.0))
        else:
            v0 = self._v0
            self._tz, self._inv_tz2 = 0.5 * (v0[_LHIP_Z] + v0[_RHIP_Z]), self._inv_torso2

    def _shoulder_cost(self, c, e, w, sx: float, sy: float, sz: float, ps, inv_fs2: float, lu: float, lf: float, other,
                       bound: float = _inf):
        """The cost of shoulder candidate ``c`` (``inv_fs2``: its filter prior's 1 / sigma^2, ``_inv_f2``).

        A candidate whose cost already reaches ``bound`` (the best so far) before the anatomical penalty cannot
        win (the penalty is >= 0): that partial cost is returned without computing the penalty.
        """
        cx: float; cy: float; cz: float; t: float; j: float; dw: float; tz: float; fl: float
        cx, cy, cz = c
        dx, dy, dz = cx - sx, cy - sy, cz - sz
        j = (dx * dx + dy * dy + dz * dz) * inv_fs2
        if ps is not None:
            dx, dy, dz = cx - ps[0], cy - ps[1], cz - ps[2]
            t = (dx * dx + dy * dy + dz * dz) * self._inv_t2
            j += t if t < self._t_cap else self._t_cap
        if other is not None and self._inv_w2:
            dw = _hypot(c[0] - other[0], c[1] - other[1], c[2] - other[2]) - self._ls
            j += dw * dw * self._inv_w2
        tz = self._tz  # (set by ``_arm`` before a rebuild: the held shoulder's depth, else the hips')
        if tz == tz:
            # The shoulders sit on the torso (both arms' mirror candidates together would otherwise keep the
            # shoulder width; one read on its own upper arm, 24 cm in front, is equidistant from both).
            dz = c[2] - tz
            j += dz * dz * self._inv_tz2
        fl = self._s_floor  # (set by ``_arm`` before a rebuild: the depth measured at the shoulder's pixel)
        if fl == fl and cz < fl:
            # No joint is in front of the surface its pixel reads (the arm's own, over a shoulder whose upper arm
            # points at the camera; the elbow's mirror candidate in front of the wrist put it there: 50 cm, MediaPipe
            # on bvhtools_a3 driven bone by bone).
            j += (fl - cz) * (fl - cz) / self._r_z
        if j >= bound:
            return j
        return j + self._penalty(c, e, w, lu, lf)

    def _choose_shoulder(self, pair, e, w, sx, sy, sz, ps, ks, lu, lf, other):
        """The shoulder candidate of ``pair`` with the smallest :meth:`_shoulder_cost`."""
        best, best_j = pair[0], _inf
        inv_fs2 = self._inv_f2(ks)
        for c in pair:
            j = self._shoulder_cost(c, e, w, sx, sy, sz, ps, inv_fs2, lu, lf, other, best_j)
            if j < best_j:
                best, best_j = c, j
        return best

    def _rebuild_from_wrist(self, f, w, pe, ps, ke, ks, lu, lf, exy, sxy, other):
        """Elbow and shoulder rebuilt from the wrist ``w`` (neither kept): the pair of the elbow's candidates
        (eq. 7) and each one's shoulder candidates (eq. 8) with the smallest total cost; ``f``: the filter's
        shoulder and elbow (6 floats). Returns ``(shoulder, elbow)``."""
        sx, sy, sz, ex, ey, ez = f
        wx, wy, wz = w
        tol = self._tol
        e_cands = _candidates(wx, wy, wz, ex, ey, ez, lf, exy, tol)
        best = None
        best_j = _inf
        inv_fe2, inv_fs2 = self._inv_f2(ke), self._inv_f2(ks)
        for ec in e_cands:
            je = _d2(ec, ex, ey, ez) * inv_fe2
            if pe is not None:
                je += min(_d2(ec, pe[0], pe[1], pe[2]) * self._inv_t2, self._t_cap)
            if je >= best_j:
                continue  # cannot win: the shoulder's cost is >= 0
            s_pair = _candidates(ec[0], ec[1], ec[2], sx, sy, sz, lu, sxy, tol)
            if len(s_pair) == 1:
                sc = s_pair[0]
                js = self._shoulder_cost(sc, ec, w, sx, sy, sz, ps, inv_fs2, lu, lf, other)
            else:
                sc, js = None, _inf
                for c in s_pair:
                    jc = self._shoulder_cost(c, ec, w, sx, sy, sz, ps, inv_fs2, lu, lf, other, js)
                    if jc < js:
                        sc, js = c, jc
            if je + js < best_j:
                best_j, best = je + js, (sc, ec)
        return best

    def _prepare_rebuild(self, side, mz, wz, lu, lf):
        """Before a rebuild of ``side``'s shoulder: its torso term (:meth:`_set_torso`) and its floor, the depth
        ``mz`` measured at its pixel if within the arm's reach of the wrist's depth ``wz`` (not the wall behind):
        whatever surface it read (the shoulder's, its upper arm's), the joint is not in front of it."""
        self._set_torso(side)
        self._s_floor = mz if abs(mz - wz) <= lu + lf else _NAN

    def _outvoted(self, side, f, w, prev, ks, lu, lf, sxy, df, mz):
        """The rebuilt ``(shoulder, elbow)`` (eq. 8, :meth:`_rebuild_shoulder`) when a seen shoulder (measured depth
        ``mz``) is outvoted, two against one, by the seen elbow that fits the wrist ``w`` (its forearm ``df`` off
        its length); None when the shoulder is kept.

        The elbow fits the wrist better than the shoulder fits the elbow, by more than ``consistency_m`` (e.g. an
        occluding upper arm's depth read at the shoulder's pixel), unless
        * the shoulder's depth agrees with the shoulder held on the torso (two against two: MediaPipe's 2D elbow
          5 cm short of the joint leaves both segments short, and eq. 8 moved such a shoulder 12-18 cm);
        * or eq. 8's shoulder would lie in front of the depth its own pixel reads, beyond the gate of a seen
          reading's error (``seen_depth_sigma_m``; without it the filter's ``R``): an occluder reads in front of the
          joint, so a rebuild in front contradicts the one reason to outvote the reading (MediaPipe, cmu_01_01
          driven bone by bone at 30 Hz: the upper arm 5.7 cm short in the image, the shoulder read within 0.1 cm
          and rebuilt 17.5 cm in front for six frames; bvhtools_a2's window, its 2D elbow 6 cm off and the hip under
          the hand read 21 cm in front: rebuilt 12-15 cm in front, inside the gate of ``R``, on four frames, which
          made up AKC+(KF)'s worst increase on the MediaPipe windows' seen frames, +0.71 -> +0.48 cm, session 55);
        * or eq. 8's shoulder lies behind the reading but nothing of its own arm can cover its pixel: the upper
          arm farther than ``arm_cover_deg`` from the line of sight (its image length at least ``l_u`` times the
          sine) and the forearm (elbow to wrist, in the image) farther than ``occlusion_radius_m`` from it
          (MediaPipe, cmu_01_03 driven bone by bone: the 2D elbow 6 cm short of the joint, the wrist read 8 cm
          in front, and the shoulder, read within 0.5 cm, rebuilt 17 cm behind).
        ``f``: the filter's shoulder and elbow (6 floats); ``prev``: the arm's last output or None.
        """
        sx, sy, sz, ex, ey, ez = f
        if not (self._cons < abs(_hypot(sx - ex, sy - ey, sz - ez) - lu) > df
                and not abs(sz - self._held_z(side)) <= self._cons):
            return None
        self._prepare_rebuild(side, mz, w[2], lu, lf)
        ps = (prev[0], prev[1], prev[2]) if prev is not None else None
        rebuilt = self._rebuild_shoulder(f, w, ps, ks, lu, lf, sxy, self._other_shoulder(side))
        s = rebuilt[0]
        if s[2] > mz:
            return rebuilt if ((sx - ex) ** 2 + (sy - ey) ** 2 < self._cover2 * lu * lu
                               or segment_distance2(sx, sy, ex, ey, w[0], w[1]) < self._occ_r2) else None
        c = self.config  # (a seen reading's error; 0 under ``paper``: the filter's R alone)
        if c.seen_depth_sigma_m > 0.0:
            return None if mz - s[2] > c.arm_radius_m + c.gate_sigma * c.seen_depth_sigma_m else rebuilt
        return None if (mz - s[2]) ** 2 > self._gate2 * self._r_z else rebuilt

    def _rebuild_shoulder(self, f, w, ps, ks, lu, lf, sxy, other):
        """The elbow kept (moved radially to ``lf`` from the wrist ``w``) and the shoulder rebuilt from it (eq. 8);
        ``f``: the filter's shoulder and elbow (6 floats). Returns ``(shoulder, elbow)``."""
        sx, sy, sz, ex, ey, ez = f
        e = _radial(w[0], w[1], w[2], ex, ey, ez, lf)
        s_c = _candidates(e[0], e[1], e[2], sx, sy, sz, lu, sxy, self._tol)
        if len(s_c) == 1:
            return s_c[0], e
        return self._choose_shoulder(s_c, e, w, sx, sy, sz, ps, ks, lu, lf, other), e
