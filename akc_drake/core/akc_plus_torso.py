"""AKC+'s torso references: what carries a shoulder held on the torso, and when the torso outvotes a shoulder.

A shoulder whose depth the occlusion filter dropped, or that the detector lost altogether, is held at our outputs'
running-mean offset from a torso reference (:func:`~akc_drake.core.akc_plus_evidence.fuse_held`):

* the hips' centre, in a frame where both hips' measured depths pass the innovation test (a filter extrapolating a
  hip that a hand hides carried the velocity it had, 38 cm in ten frames, into the held offsets: bvhtools_test
  60-120 s, simulated; one that follows a hip read on the wall behind the body's edge, where a bending torso puts
  the landmark, ran 50-120 cm off for five frames and taught the held shoulder 20 cm: bvhtools_a1 driven bone by
  bone) and the filter's hips are no farther apart than the shoulder width reaches (:meth:`TorsoReference.
  _torso_anchors`: a filter that follows hips read on the wall by turns passes that test);
* where the hips have been no reference for ``hips_lost_frames`` (1 s at 10 Hz: out of the image, an operator at
  a desk or a camera close to the chest), the other shoulder, which the clavicles carry with the chest: the
  filter's, seen this frame and agreeing with our last output of it, the offset from it learnt while the hips are
  no reference (a filter that followed an occluder's depth
  passes the innovation test: the right shoulder read on its own arm 25 cm in front, bvhtools_a1 driven bone by
  bone). A shorter loss of the hips (an edge's depth, a hand over a hip) leaves the hold off: two references
  taking turns moved the held shoulder. Without the hips, a shoulder lost for 20 frames ran 14 cm off in y with
  the filter (mocapbank driven bone by bone).

A measured shoulder depth is an occluder's, and the torso's depth replaces it on the pixel's ray, when the held
shoulder and a second vote contradict it (:meth:`TorsoReference._torso_outvotes`: the seen elbow, or a measured wrist
nearer than the arm can fold), or when it jumps towards the camera alone, against the other shoulder, or behind
it farther than the shoulder width reaches (:meth:`TorsoReference._shoulder_jumped`: the hips, misread with it, are
then no vote).

:class:`TorsoReference` is a mixin of :class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus`: it reads and
sets the corrector's per-frame state (``_hips``, ``_anchor``, ``_hips_lost``, ``_pair_z``) and its settings.
"""

from __future__ import annotations

import math

from akc_drake.core.akc_plus_evidence import fuse_held
from akc_drake.core.skeleton import INDEX

_hypot = math.hypot
_isfinite = math.isfinite
_NAN = float("nan")
_LHIP, _RHIP = 3 * INDEX["left_hip"], 3 * INDEX["right_hip"]
_Z, _XYZ = (2,), (0, 1, 2)  # (the held shoulder's axes: its depth dropped; lost altogether)
NO_HIPS = (_NAN, _NAN, _NAN)  # (the hips' centre unknown: the held shoulder off this frame)


def _seen(z: float, f: float, p: float, rz: float, g2: float):
    """A measured depth ``z`` passes the innovation test against the filter's ``f`` (posterior variance ``p``; the
    test of ``_arm``'s seen depth: the residual's variance is ``R - P``). False for a NaN."""
    q = rz - p
    return (z - f) ** 2 <= g2 * (q if q > 0.0 else 0.0) + 1e-12


def learn_offset(held, side, out, anchor, a):
    """``held[side]``: the running mean (weight ``a``) of the shoulder ``out[0:3]`` minus ``anchor``, its blind
    frames reset (the first frame starts it)."""
    h = held[side]
    if h is None:
        held[side] = [out[0] - anchor[0], out[1] - anchor[1], out[2] - anchor[2], 0.0]
    else:
        h[0] += a * (out[0] - anchor[0] - h[0])
        h[1] += a * (out[1] - anchor[1] - h[1])
        h[2] += a * (out[2] - anchor[2] - h[2])
        h[3] = 0.0


def _held_depth(a, v_s):
    """The depth of the shoulder held on the torso reference ``a`` (``_anchor[side]``: the anchor point and the
    held offset with its blind frames) and the variance its random walk has reached (``v_s`` per frame)."""
    h = a[1]
    return a[0][2] + h[2], v_s * (h[3] + 1.0)


class TorsoReference:
    """The torso references of AKC+'s held shoulders (a mixin: the corrector holds the state it reads)."""

    __slots__ = ()

    def _torso_anchors(self, v, m):
        """This frame's torso references: sets ``_hips`` (the hips' centre, NaN when they are none) and
        ``_anchor`` (per side the anchor point and the held offset from it, or None), counts ``_hips_lost``.

        The hips are a reference when both their measured depths pass the innovation test
        (:meth:`_hips_consistent`) and the filter's hips are no farther apart than the shoulder width reaches
        (beyond the gate of two measurements' and the width's variances): no body has hips wider than its
        shoulders (MediaPipe's hip landmarks are the hip joints', nearer each other still), so one of them reads
        something else. A filter that follows hips read on the wall behind a body leaning towards the camera (each
        hip's pixel on the body one frame and on the wall 1.5 m behind the next) passes the innovation test; the
        right shoulder held on such hips, 1.6 m apart in depth, went 80 cm behind, where the filter's was 1 cm off
        (MediaPipe on cmu_01_06 driven bone by bone, frame 216).

        Returns:
            ``(hold, hips, others)``: whether the hips are a reference, their centre, and per side the shoulder
            that may carry the other side's (:meth:`_other_anchor`; None where none).
        """
        d: float  # (a C double when compiled: setup.py)
        pair = self._v_s and m is not None and self._var is not None
        hold = (pair and _isfinite(m[_LHIP + 2] + m[_RHIP + 2]) and _isfinite(v[_LHIP + 2] + v[_RHIP + 2])
                and self._hips_consistent(v, m))
        if hold:  # (hips farther apart than the shoulders: see above)
            d = _hypot(v[_LHIP] - v[_RHIP], v[_LHIP + 1] - v[_RHIP + 1], v[_LHIP + 2] - v[_RHIP + 2]) - self._ls
            hold = not (d > 0.0 and d * d > self._width_gate)
        hips = self._hips = ((0.5 * (v[_LHIP] + v[_RHIP]), 0.5 * (v[_LHIP + 1] + v[_RHIP + 1]),
                              0.5 * (v[_LHIP + 2] + v[_RHIP + 2])) if hold else NO_HIPS)
        self._hips_lost = 0.0 if hold else self._hips_lost + 1.0
        # (the shoulders' offsets from each other are learnt, and used, only while the hips are no reference)
        others = (self._other_anchor(v, m, 0), self._other_anchor(v, m, 1)) if pair and not hold else (None, None)
        use_pair = self._hips_lost >= self._pf.hips_lost_frames
        held_sh, held_ss, anchor = self._held_sh, self._held_ss, self._anchor
        for side in (0, 1):
            if hold and held_sh[side] is not None:
                anchor[side] = (hips, held_sh[side])
            elif use_pair and others[1 - side] is not None and held_ss[side] is not None:
                anchor[side] = (others[1 - side], held_ss[side])
            else:
                anchor[side] = None
        return hold, hips, others

    def _hips_consistent(self, v, m):
        """Whether both hips' measured depths pass the innovation test against the filter (``_arm``'s test of a
        seen depth): a hip landmark on the body's edge reads the background behind it (the wall, 1.5 m deep),
        and a filter without a gate follows it for several frames."""
        var, rz, g2 = self._var, self._r_z, self._gate2
        o, p = _LHIP + 2, _RHIP + 2
        return _seen(m[o], v[o], var[o], rz, g2) and _seen(m[p], v[p], var[p], rz, g2)

    def _other_anchor(self, v, m, k):
        """Shoulder ``k`` as the torso's reference of the other side's held shoulder: the filter's, when its depth
        is seen this frame (measured, passing the innovation test), was seen when last corrected, and agrees with
        that output within ``consistency_m``; else None."""
        p = self._prev[k]
        if p is None or self._lost[2 * k + 1] > 0:
            return None
        o = self._offsets[k][0]
        x, y, z = v[o], v[o + 1], v[o + 2]
        mz = m[o + 2]
        if not (_isfinite(m[o] + m[o + 1] + mz + x + y + z) and _seen(mz, z, self._var[o + 2], self._r_z,
                                                                      self._gate2)):
            return None
        if _hypot(x - p[0], y - p[1], z - p[2]) > self._cons:
            return None
        return (x, y, z)

    def _torso_outvotes(self, f, vs, m, side):
        """A measured shoulder depth that the torso and a second vote both contradict (two against one): replaced
        on its pixel's ray by the shoulder held on the torso (``f``, ``vs`` changed in place); True if so. Called
        for a shoulder whose depth was measured; the cheapest test first, as it fails on most frames. Without a
        torso reference (no ``_anchor``) only the shoulder width's bound votes (:meth:`_beyond_width`).

        The measurement is off the held shoulder's depth beyond the gate of their variances (the hold's random walk
        and the measurement's). The second vote is one of

        * the seen elbow (measured, its depth passing the innovation test): the upper arm from the measurement to
          it misses the calibrated length by more than ``consistency_m`` where the held shoulder at the same pixel
          fits it better by that much; or
        * the measured wrist: the measurement is in front of the held depth and nearer the wrist (in 3D) than the
          arm can fold (the shoulder-wrist distance at ``elbow_min_deg``, less ``consistency_m``): the hand's depth
          read at the shoulder's pixel, the arm pointing at the camera (MediaPipe on bvhtools_a3 driven bone by
          bone: the shoulder read 50 cm in front, 3 cm from the wrist's depth, for three frames; the held offset
          learnt it and then outvoted the true depths: the shoulder's z RMSE 26.4 cm, the KF's 15.3); or farther
          from the measurement than the arm reaches (``l_u + l_f + consistency_m``) while the held shoulder is
          within that reach (MediaPipe's shoulders read on the wall 1.75 m behind, a held-out CMU clip driven bone
          by bone; the filter followed them and the arm was rebuilt from them, 1.8 m off); or
        * our last output: the measurement is farther from its depth than the arm reaches, where the held depth is
          within that reach (no shoulder moves that far in a frame; the same wall, the elbow and the wrist lost).

        Such a depth is an occluder's, the arm's own surface read at the shoulder's pixel, and a filter that had no
        prior for it (a shoulder lost for many frames, then read 26 cm in front: mocapbank driven bone by bone,
        simulated detector) passes the innovation test by following it. (The wrist's vote needs no pixel
        proximity: a shoulder at the depth of a wrist that far from it in the image, as in a T-pose, is no vote.)
        """
        g2: float; rz: float; cons: float; hz: float; vh: float; mx: float; my: float; mz: float; lu: float; lf: float
        fold: float; ex: float; ey: float; ez: float; miss: float; dw: float; reach: float  # (C doubles: setup.py)
        if self._anchor[side] is None:  # (no torso reference: only the shoulder width's bound, ``_beyond_width``)
            return self._beyond_width(f, vs, m, side)
        o_s, o_e, o_w = self._offsets[side]
        g2, rz, cons = self._gate2, self._r_z, self._cons
        hz, vh = _held_depth(self._anchor[side], self._v_s)
        mx, my, mz = m[o_s], m[o_s + 1], m[o_s + 2]
        if not (mz - hz) ** 2 > g2 * (vh + rz) or hz <= 0.0:  # (NaN: False)
            return False
        if not (_isfinite(mx + my) and mz > 0.0):
            return False
        k = hz / mz  # (the held depth on the measured pixel's ray)
        hx, hy = mx * k, my * k
        lu, lf = self._lu[side], self._lf[side]
        fold = math.sqrt(lu * lu + lf * lf - 2.0 * lu * lf * self._cos_min) - cons  # (NaN wrist: no vote)
        dw, reach = _hypot(mx - m[o_w], my - m[o_w + 1], mz - m[o_w + 2]), lu + lf + cons
        pv = self._prev[side]
        if not (mz < hz and dw < fold
                or dw > reach and _hypot(hx - m[o_w], hy - m[o_w + 1], hz - m[o_w + 2]) <= reach
                or pv is not None and abs(mz - pv[2]) > reach and abs(hz - pv[2]) <= reach):
            if not (_isfinite(m[o_e] + m[o_e + 1] + m[o_e + 2]) and _seen(m[o_e + 2], f[5], self._var[o_e + 2], rz,
                                                                           g2)):
                return False  # (the elbow not seen)
            ex, ey, ez = f[3], f[4], f[5]
            miss = abs(_hypot(mx - ex, my - ey, mz - ez) - lu)
            if miss <= cons or abs(_hypot(hx - ex, hy - ey, hz - ez) - lu) > miss - cons:
                return False
        f[0], f[1], f[2] = hx, hy, hz
        vs[2] = vh
        return True

    def _hold_on_torso(self, f, vs, m, side, a):
        """A shoulder whose depth was dropped, or lost altogether: the filter's estimate and the shoulder held on
        the torso (anchor ``a``), fused (``fuse_held``; ``f``, ``vs`` changed in place); True if held. Not where the
        fused shoulder lies beyond the arm's reach (``l_u + l_f + consistency_m``) of a seen wrist (measured, its
        depth passing the innovation test) while the filter's lies within it: the torso turned or leant while the
        shoulder was hidden, and its held offset no longer holds (the simulated detector on boxing driven bone by
        bone: the trunk leant back 40 cm in four frames, the lost shoulder held 38 cm in front, 80 cm from the
        seen wrist; the EKF's, within reach, was 2 cm off). The blind frame is counted either way.

        After a constrained filter (an EKF), a shoulder blind for more than ``recent_frames`` counts the filter's
        variance as no less than the hold's (``fuse_held``'s ``honest_frames``), as an elbow and a wrist lost
        altogether do: the bone constraints shrink the posterior of a joint nothing measures. MediaPipe's
        bvhtools_a3, its left shoulder's depth dropped for most of the clip: the EKF's shoulder drifted 19 cm in
        depth (RMSE), the fusion followed it as the hold's walk grew, and AKC+(EKF)'s shoulder was 19.2 cm off in
        3D; 6.8 with the filter's variance so counted."""
        x: float; y: float; z: float; wx: float; wy: float; wz: float; reach: float  # (C doubles: setup.py)
        o_s, o_w = self._offsets[side][0], self._offsets[side][2]
        x, y, z = f[0], f[1], f[2]
        v0 = (vs[0], vs[1], vs[2])
        # (After a constrained filter, its variance of a shoulder blind for more than ``recent_frames`` counts no
        # less than the hold's, as for an elbow and a wrist lost altogether: ``_blind_honest``.)
        fuse_held(f, vs, a[1], a[0], self._v_s, 0, _Z if _isfinite(m[o_s] + m[o_s + 1]) else _XYZ,
                  self._blind_honest)
        wx, wy, wz = m[o_w], m[o_w + 1], m[o_w + 2]
        if not _isfinite(wx + wy + wz):
            return True
        reach = self._lu[side] + self._lf[side] + self._cons
        if (_hypot(f[0] - wx, f[1] - wy, f[2] - wz) > reach and _hypot(x - wx, y - wy, z - wz) <= reach
                and _seen(wz, self._v[o_w + 2], self._var[o_w + 2], self._r_z, self._gate2)):
            f[0], f[1], f[2] = x, y, z
            vs[0], vs[1], vs[2] = v0
            return False
        return True

    def _torso_confirms(self, f, m, side):
        """Whether the measured shoulder depth, which replaced the filter's in ``f`` (the ray test), lies within the
        gate of the shoulder held on the torso: two against one, the filter's shoulder is the wrong one, whatever
        an elbow and a wrist read on the wall behind it say (:func:`~akc_drake.core.akc_plus_evidence.
        unreachable_replacements` then keeps it, as a held shoulder). An EKF pulled behind by an elbow and a wrist
        read on the wall 1.5 m behind took the seen shoulder 29 cm with it (its bone constraints); the ray test
        took the shoulder's and the wrist's readings, the reach test undid the shoulder's, on the torso, as out of
        the wall wrist's reach, and the arm rebuilt from that wrist put the shoulder on the wall (MediaPipe,
        bvhtools_b2's window at 30 Hz, frame 636)."""
        a = self._anchor[side]
        mz = m[self._offsets[side][0] + 2]
        if a is None or f[2] != mz:
            return False
        hz, vh = _held_depth(a, self._v_s)
        return (mz - hz) ** 2 <= self._gate2 * (vh + self._r_z)

    def _beyond_width(self, f, vs, m, side):
        """A measured shoulder farther from the camera than the shoulder width allows: put on its pixel's ray at
        our last output's depth when that is within the bound (``f``, ``vs`` changed in place); True if so.

        A point at range ``r`` on one ray is at least ``r sin t`` from every point of another ray at angle ``t``:
        a shoulder whose pixel's ray makes angle ``t`` with the other shoulder's is at most ``(SW +
        consistency_m) / sin t`` from the camera, whatever the torso's turn and the other shoulder's depth. A
        depth beyond that is the background read past the body's edge. MediaPipe on a held-out CMU clip driven
        bone by bone, 30 Hz: both shoulders read on the wall at 3.5 m for 44 frames (the bound 2.9 m, the truth
        1.8 m), the hips no reference (their filter lagging), the left elbow's and wrist's depths dropped; the
        arm was rebuilt on the wall: the elbow's z RMSE over the clip 32 cm, the KF's 11 (8 with this). It does not lock
        in: a reading within the bound is never held, and our last output must be within it too.
        """
        mx: float; my: float; mz: float; ox: float; oy: float; oz: float; ax: float; ay: float; bx: float; by: float
        c: float; sin_t: float; k: float; reach: float  # (C doubles: setup.py)
        o_s, o_o = self._offsets[side][0], self._offsets[1 - side][0]
        mx, my, mz, ox, oy, oz = m[o_s], m[o_s + 1], m[o_s + 2], m[o_o], m[o_o + 1], m[o_o + 2]
        pv = self._prev[side]
        if pv is None or not (_isfinite(mx + my + mz + ox + oy + oz) and mz > 0.0 and oz > 0.0):
            return False
        ax, ay, bx, by = mx / mz, my / mz, ox / oz, oy / oz
        c = (ax * bx + ay * by + 1.0) / math.sqrt((ax * ax + ay * ay + 1.0) * (bx * bx + by * by + 1.0))
        sin_t = math.sqrt(max(1.0 - c * c, 0.0))
        reach = self._ls + self._cons
        if _hypot(mx, my, mz) * sin_t <= reach:
            return False
        k = pv[2] / mz  # (our last output's depth on the measured pixel's ray)
        if _hypot(mx * k, my * k, pv[2]) * sin_t > reach:
            return False
        f[0], f[1], f[2] = mx * k, my * k, pv[2]
        vs[2] = self._r_z
        return True

    def _off_body(self, m, o_s, o_o):
        """Whether the measured shoulder at ``o_s`` is farther from the measured one at ``o_o`` than the shoulder
        width reaches (beyond the gate of both measurements' and the width's variances): no torso turn puts it
        there, and a depth behind is the background behind a landmark off the body's edge."""
        d: float
        d = _hypot(m[o_s] - m[o_o], m[o_s + 1] - m[o_o + 1], m[o_s + 2] - m[o_o + 2]) - self._ls
        return d > 0.0 and d * d > self._width_gate

    def _shoulder_jumped(self, f, vs, m, side, held):
        """A measured shoulder depth that jumped towards the camera, alone, or behind beyond the shoulder width:
        replaced on its pixel's ray by the depth the other shoulder carries (``f``, ``vs`` changed in place); True
        if so, or if ``held`` (another rule holds the shoulder on the torso: then only the measured depth is
        recorded). Off with ``sigma_shoulder_m = 0``.

        ``_pair_z[side]``: the running mean (weight ``shoulder_alpha``) of the measured depth minus the other
        shoulder's, measured in the same frames; the frames it has held the shoulder; the depth last measured and
        the frames since. Only while the other shoulder is seen (its depth passing the innovation test) and not
        itself held so.

        The clavicles carry a shoulder with the chest: the two shoulders' depths differ by what the torso's turn
        makes of the shoulder width, which changes little from one frame to the next. A measured depth in front of
        the other shoulder's plus that difference beyond the gate (the measurement's variance and the hold's random
        walk, ``sigma_shoulder_m`` per frame), that also jumped towards the camera by as much since it was last
        measured (the gate widened by the walk over the frames since), reads an occluder (the head or an arm of a
        bending torso). It is held at that difference until a measurement falls within the gate again; the walk's
        growing variance ends the hold after a few seconds (a torso that turned meanwhile). Both tests are needed:
        the difference alone held a shoulder whose mean had learnt the other one's long occlusion (the simulated
        detector, bvhtools_a1's right shoulder read 25 cm in front under its hand: the left one, well seen, held
        5-10 cm off when the hand left); our last output in place of the last measured depth held a shoulder that
        a rebuild had put 24 cm off (vicon_playground driven bone by bone, MediaPipe).

        A depth that jumped behind (by as much, both tests) is held so only when it puts the two measured shoulders
        farther apart than the shoulder width reaches (:meth:`_off_body`): a turning torso moves a shoulder behind
        the other within that reach, but the background behind a landmark off the body's edge is beyond it
        (MediaPipe on bvhtools_b driven bone by bone, 30 Hz: the right shoulder read on the wall 1.6 m behind for
        three frames; taken, it taught the torso holds the wall and kept the seen shoulder 20-35 cm behind for the
        next 60 frames).

        MediaPipe on mocapbank driven bone by bone: bent forward, the right shoulder's pixel reads 30 cm in front
        for 65 frames from one frame to the next, with the hips (read on the belly) as far in front, so the
        shoulder held on them agreed; the right elbow, rebuilt from it, 12.6 cm RMSE in z against the KF's 2.7
        (7.6 with this rule: the hold ends after 44 frames, 25 cm off).
        """
        mz: float; moz: float; last: float; since: float; g2: float; rz: float; n: float; v_s: float; mx: float
        my: float  # (C doubles when compiled: setup.py)
        o_s, o_o = self._offsets[side][0], self._offsets[1 - side][0]
        mz, moz = m[o_s + 2], m[o_o + 2]
        pz, po = self._pair_z[side], self._pair_z[1 - side]
        if mz == mz:
            last, since, pz[2], pz[3] = pz[2], pz[3], mz, 0.0
        else:
            last = since = _NAN  # (not read: no depth this frame)
            pz[3] += 1.0
        if held or mz != mz or vs[2] != vs[2] or not self._v_s:
            return held
        g2, rz = self._gate2, self._r_z
        if po[1] > 0.0 or not (_seen(moz, self._v[o_o + 2], self._var[o_o + 2], rz, g2) or (
                pz[1] > 0.0 and self._prev[1 - side] is not None
                and abs(moz - self._prev[1 - side][2]) <= self._cons)):
            # (NaN: not seen.) While it holds, the other shoulder's reading also counts where it agrees with our
            # last output of it: a filter that went after the held one's occluder fails it (boxing driven bone by
            # bone, MediaPipe, frames 243-245: the left arm read on the right glove 45-70 cm in front, the coupled
            # EKF's right shoulder 17 cm off its correct reading, and the left shoulder taken on the glove).
            return False
        d = mz - moz
        if pz[0] != pz[0]:
            pz[0] = d
            return False
        n, v_s = pz[1], self._v_s
        vh = v_s * (n + 1.0)
        hz = moz + pz[0]
        mx, my = m[o_s], m[o_s + 1]
        # (held: until within the gate; not yet: the jump since the last measured depth too, the same way; NaN:
        # False. Behind: only a depth that puts the shoulders farther apart than the width reaches, ``_off_body``.)
        if not ((mz - hz) ** 2 > g2 * (rz + vh) and _isfinite(mx + my) and mz > 0.0
                and (mz < hz or self._off_body(m, o_s, o_o))
                and (n > 0.0 or ((mz < last) == (mz < hz) and (mz - last) ** 2 > g2 * (rz + v_s * (since + 1.0))))):
            pz[0] += self._a_s * (d - pz[0])
            pz[1] = 0.0
            return False
        k = hz / mz  # (the held depth on the measured pixel's ray)
        f[0], f[1], f[2] = mx * k, my * k, hz
        vs[2] = vh + rz
        pz[1] = n + 1.0
        # (this frame's torso reference of the shoulder, for a rebuild's torso term: the hips', if any, agreed with
        # the reading)
        self._anchor[side] = ((0.0, 0.0, moz), (0.0, 0.0, pz[0], n))
        return True
