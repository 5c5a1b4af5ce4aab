"""AKC+'s projections of an arm onto the exact lengths (plain floats, unrolled: they run on most frames).

* :func:`project_arm`: both depths known, the whole arm nearest the filter's in its covariance metric (the
  maximum a posteriori arm under the filter's Gaussian and exact lengths) after a chi2 test against the
  calibrated lengths.
* :func:`project_forearm`: a kept shoulder (its variances zero, no calibration variance, no gate): the terms
  the zero variances cancel are not computed (the arm of ``project_arm(f, (0, 0, 0, *v_ew), lu, lf, 0.0,
  inf)``, bit-identical). AKC+ runs it on the frames where a lost elbow cannot close the arm at its image x, y
  from a kept shoulder (:mod:`akc_drake.core.akc_plus`), about half the frames of some clips.
* :func:`circle_pair`: ``circle_point`` for the two Pythagorean elbow candidates, the circle computed once.
* :func:`measured_arm`: the arm as measured this frame, whose lengths ``project_arm`` tests after an EKF.
* :func:`learn_elbow_offset`: the elbow's landmark offset, learnt from the two segments' misfits as measured; the
  projections add its excess over the others' to the elbow's variances (``elbow_var``).
* :func:`behind_surface` and :class:`SurfaceMemory`: an elbow the projection puts in front of the surface its pixel
  read goes behind it, and the verdict is remembered while the pixel reads that surface.

Both projections take two steps of sequential quadratic programming (fewer once the lengths are met to 0.01 mm)
written out (the final circle from :func:`~akc_drake.core.arm_geometry.circle_of`): a loop over the steps, its
branches on the step number and the calls cost about a third of the projection's time as source, and compiled still
0.8-1.0 us of AKC+'s ~18.7 us per frame (2026-11-25). ``offset_var`` (AKC+'s landmark offsets) is added to each
variance here, as the caller's ``[x + offset_var for x in var]`` would.
"""

from __future__ import annotations

import math

from akc_drake.core.arm_geometry import body_covers, circle_nearest, circle_of

_hypot = math.hypot
_sqrt = math.sqrt
_inf = math.inf
_NAN = float("nan")
_isfinite = math.isfinite
#: A segment shorter than this (m) has no direction.
_MIN_SEGMENT_M = 1e-12


def _circle(wx: float, wy: float, wz: float, sx: float, sy: float, sz: float, lf: float, lu: float, px: float,
            py: float, pz: float):
    """:func:`~akc_drake.core.arm_geometry.circle_point`'s elbow in the arm (None if no circle)."""
    c = circle_of(wx, wy, wz, sx, sy, sz, lf, lu)
    if c is None:
        return None
    return (sx, sy, sz, *circle_nearest(c, px, py, pz), wx, wy, wz)


def project_arm(f, var, lu: float, lf: float, length_var: float, gate: float, offset_var: float = 0.0, tested=None,
                elbow_var: float = 0.0):
    """The arm nearest ``f`` in the filter's metric whose segments have exactly the lengths ``lu`` and ``lf``.

    Minimises ``sum (p - f)^2 / var`` over the nine coordinates (shoulder, elbow, wrist) subject to
    ``|s - e| = lu`` and ``|e - w| = lf``: the maximum a posteriori arm under the filter's Gaussian (a diagonal
    covariance per axis) and exact lengths. The nearly noise-free axes (x, y) then barely move and the
    correction goes to the uncertain depths, in proportion to their variances. Two steps of sequential
    quadratic programming (the constraints linearised at the current point; the second skipped once the
    lengths are met to 0.01 mm), then the elbow is put on the exact circle between the shoulder and the wrist.
    Two steps approximate the minimum: on a sample of 3,684 of AKC+'s calls (10 clips, simulated and MediaPipe
    detectors, KF and EKF) the arm is within 0.01 mm of the constrained minimum in the median, more than 1 cm from
    it on 0.9 %; iterating to convergence moved the 10-clip summaries (worst increase over the filter, lost-joint
    and pooled arm z) by at most 0.02 cm (2026-11-25).

    Before any step, ``chi2 = g^T (J V J^T + length_var I)^-1 g`` of the length residuals ``g`` tests whether
    the filter's arm is consistent with the calibrated lengths (2 degrees of freedom; ``length_var`` is the
    calibration's variance): above ``gate`` nothing is projected. With ``tested``, ``g`` is that arm's residuals
    (``J`` still at ``f``): after a filter whose posterior already holds the lengths (an EKF's bone constraint,
    which moves a seen joint off its measurement to fit them), its arm passes the test by construction, and the
    arm as measured is the evidence (:func:`measured_arm`; MediaPipe's 2D wrist 4-6 cm off the joint read a
    forearm 6 cm short, the EKF moved the seen wrist 6 cm in depth to fit it and the projection finished the job).

    Args:
        f: nine floats, the filter's shoulder, elbow and wrist.
        var: their nine variances (> 0).
        lu, lf: the upper and lower arm lengths.
        length_var: the variance of each calibrated length (m^2).
        gate: the largest chi2 accepted.
        offset_var: added to each variance (AKC+'s landmark offsets), as ``[x + offset_var for x in var]``.
        tested: nine floats, the arm whose lengths the chi2 test judges (None: ``f``).
        elbow_var: added to the elbow's three variances besides ``offset_var`` (:func:`learn_elbow_offset`).

    Returns:
        The arm (nine floats), or None when chi2 > gate (or is NaN) or no arm with these lengths exists near
        ``f`` (the shoulder-wrist distance out of reach, a zero-length segment, a singular step).
    """
    fsx: float; fsy: float; fsz: float; fex: float; fey: float; fez: float; fwx: float; fwy: float; fwz: float
    vsx: float; vsy: float; vsz: float; vex: float; vey: float; vez: float; vwx: float; vwy: float; vwz: float
    n1: float; n2: float; g1: float; g2: float; o: float; chi2: float
    fsx, fsy, fsz, fex, fey, fez, fwx, fwy, fwz = f
    vsx, vsy, vsz, vex, vey, vez, vwx, vwy, vwz = var
    if offset_var:
        o = offset_var
        vsx, vsy, vsz, vex, vey, vez = vsx + o, vsy + o, vsz + o, vex + o, vey + o, vez + o
        vwx, vwy, vwz = vwx + o, vwy + o, vwz + o
    if elbow_var:
        vex, vey, vez = vex + elbow_var, vey + elbow_var, vez + elbow_var
    # Step 1, at x = f (the linearised constraints are the residuals themselves).
    ax, ay, az = fsx - fex, fsy - fey, fsz - fez
    bx, by, bz = fex - fwx, fey - fwy, fez - fwz
    n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
    if not (n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M):
        return None
    ax, ay, az = ax / n1, ay / n1, az / n1
    bx, by, bz = bx / n2, by / n2, bz / n2
    a11 = ax * ax * (vsx + vex) + ay * ay * (vsy + vey) + az * az * (vsz + vez)
    a22 = bx * bx * (vex + vwx) + by * by * (vey + vwy) + bz * bz * (vez + vwz)
    a12 = -(ax * bx * vex + ay * by * vey + az * bz * vez)
    b1, b2 = n1 - lu, n2 - lf
    c11, c22 = a11 + length_var, a22 + length_var
    det = c11 * c22 - a12 * a12
    g1, g2 = b1, b2
    if tested is not None:
        g1 = _hypot(tested[0] - tested[3], tested[1] - tested[4], tested[2] - tested[5]) - lu
        g2 = _hypot(tested[3] - tested[6], tested[4] - tested[7], tested[5] - tested[8]) - lf
    chi2 = (c22 * g1 * g1 - 2.0 * a12 * g1 * g2 + c11 * g2 * g2) / det if det > 0.0 else _inf
    if not chi2 <= gate:
        return None
    det = a11 * a22 - a12 * a12
    if not det > 1e-30:
        return None
    l1 = (a22 * b1 - a12 * b2) / det
    l2 = (a11 * b2 - a12 * b1) / det
    sx, sy, sz = fsx - vsx * ax * l1, fsy - vsy * ay * l1, fsz - vsz * az * l1
    ex, ey, ez = fex - vex * (bx * l2 - ax * l1), fey - vey * (by * l2 - ay * l1), fez - vez * (bz * l2 - az * l1)
    wx, wy, wz = fwx + vwx * bx * l2, fwy + vwy * by * l2, fwz + vwz * bz * l2
    # Step 2, unless the lengths are met to 0.01 mm: the constraints linearised at x, for the target f.
    ax, ay, az = sx - ex, sy - ey, sz - ez
    bx, by, bz = ex - wx, ey - wy, ez - wz
    n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
    if not (n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M):
        return None
    if not abs(n1 - lu) + abs(n2 - lf) < 1e-5:
        ax, ay, az = ax / n1, ay / n1, az / n1
        bx, by, bz = bx / n2, by / n2, bz / n2
        a11 = ax * ax * (vsx + vex) + ay * ay * (vsy + vey) + az * az * (vsz + vez)
        a22 = bx * bx * (vex + vwx) + by * by * (vey + vwy) + bz * bz * (vez + vwz)
        a12 = -(ax * bx * vex + ay * by * vey + az * bz * vez)
        dsx, dsy, dsz = fsx - sx, fsy - sy, fsz - sz
        dex, dey, dez = fex - ex, fey - ey, fez - ez
        b1 = n1 - lu + ax * (dsx - dex) + ay * (dsy - dey) + az * (dsz - dez)
        b2 = n2 - lf + bx * (dex - (fwx - wx)) + by * (dey - (fwy - wy)) + bz * (dez - (fwz - wz))
        det = a11 * a22 - a12 * a12
        if not det > 1e-30:
            return None
        l1 = (a22 * b1 - a12 * b2) / det
        l2 = (a11 * b2 - a12 * b1) / det
        sx, sy, sz = fsx - vsx * ax * l1, fsy - vsy * ay * l1, fsz - vsz * az * l1
        ex, ey = fex - vex * (bx * l2 - ax * l1), fey - vey * (by * l2 - ay * l1)
        ez = fez - vez * (bz * l2 - az * l1)
        wx, wy, wz = fwx + vwx * bx * l2, fwy + vwy * by * l2, fwz + vwz * bz * l2
    return _circle(wx, wy, wz, sx, sy, sz, lf, lu, ex, ey, ez)


def measured_arm(m, offsets):
    """The arm as measured this frame: the nine coordinates of ``m`` (flat) at the shoulder's, the elbow's and the
    wrist's ``offsets``, or None when ``m`` is None or any of them was not measured (NaN)."""
    if m is None:
        return None
    t = [m[o + k] for o in offsets for k in range(3)]
    return t if _isfinite(sum(t)) else None


def learn_elbow_offset(acc, m, o_s: int, o_e: int, o_w: int, lu: float, lf: float, alpha: float, cap: float,
                       offset_var: float) -> float:
    """Learn the elbow's landmark offset from this frame's measured arm; return its variance's excess over the others'.

    A landmark's offset from its joint centre (the detector's 2D point off the joint, a depth read off the centre)
    changes the measured segments' lengths. The elbow ends both: displaced by ``d`` it shortens the upper arm by
    ``a . d`` and lengthens the forearm by ``b . d`` (``a``, ``b`` the unit vectors elbow to shoulder and wrist to
    elbow), so with an isotropic offset of variance ``v`` per axis the misfits' product has the mean
    ``E[m_u m_f] = -v (a . b)``; the shoulder's and the wrist's offsets, each in one segment, and a calibration's
    length error, a constant, add nothing to it on average. ``v`` is the regression of ``-m_u m_f`` on ``a . b``
    through the origin: ``acc`` holds the running means (weight ``alpha``) of ``-m_u m_f (a . b)`` and
    ``(a . b)^2``, from a prior worth 0.5 of a straight arm's ``(a . b)^2`` at ``offset_var`` (AKC+'s reset); an
    arm bent at a right angle tells nothing and weighs nothing. Each misfit is clipped to ``cap`` (a depth misread
    by a hand's length). Measured against the truth on the 10 clips: MediaPipe's elbow offset 1-5 cm^2 in x, y
    where this reads 0.3-11 (bvhtools_a1's left elbow, biased along the arm, the most); the simulated detector's
    0.1-0.5 cm^2, this 0.1-0.9.

    Args:
        acc: ``[mean of -m_u m_f c, mean of c^2]`` (``c = a . b``), updated in place.
        m: this frame's measurements (flat); the arm counts only when its nine coordinates are all measured.
        o_s, o_e, o_w: the shoulder's, the elbow's and the wrist's flat offsets in ``m``.
        lu, lf: the calibrated upper and lower arm lengths.
        alpha: the newest frame's weight (0: nothing learnt, 0 returned).
        cap: the largest misfit counted (m).
        offset_var: every landmark's offset variance per axis in the projections (AKC+'s ``length_sigma_m^2 / 2``).

    Returns:
        ``max(0, v - offset_var)``: what the projections add to the elbow's variances; 0 while the running mean of
        ``c^2`` is below 0.1 (too few arms that were not bent at a right angle).
    """
    sx: float; sy: float; sz: float; ex: float; ey: float; ez: float; wx: float; wy: float; wz: float
    ax: float; ay: float; az: float; bx: float; by: float; bz: float; n1: float; n2: float; c: float; mu: float
    mf: float
    if not alpha > 0.0:
        return 0.0
    if m is not None:
        sx, sy, sz, ex, ey, ez = m[o_s], m[o_s + 1], m[o_s + 2], m[o_e], m[o_e + 1], m[o_e + 2]
        wx, wy, wz = m[o_w], m[o_w + 1], m[o_w + 2]
        if _isfinite(sx + sy + sz + ex + ey + ez + wx + wy + wz):
            ax, ay, az, bx, by, bz = sx - ex, sy - ey, sz - ez, ex - wx, ey - wy, ez - wz
            n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
            if n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M:
                c = (ax * bx + ay * by + az * bz) / (n1 * n2)
                mu, mf = max(-cap, min(cap, n1 - lu)), max(-cap, min(cap, n2 - lf))
                acc[0] += alpha * (-mu * mf * c - acc[0])
                acc[1] += alpha * (c * c - acc[1])
    if not acc[1] >= 0.1:
        return 0.0
    c = acc[0] / acc[1] - offset_var
    return c if c > 0.0 else 0.0


def anchored_wrist(arm, s, e, w, m, o_w: int, v, lu: float, lf: float, offset_var: float, gate2: float):
    """``AKCPlusConfig.seen_wrist_anchor``: when ``arm`` (the forearm's fit, :func:`project_forearm`) moves the wrist
    measured in ``m`` (flat, at offset ``o_w``; all three coordinates) beyond the gate in x or y (``gate2`` times
    its variance in ``v``, the arm's nine, plus ``offset_var``), the arm with the wrist ``w`` kept and the elbow on
    the circle between the shoulder ``s`` and it, nearest ``e``; else None (None too without a circle)."""
    if arm is None or m is None or not _isfinite(m[o_w] + m[o_w + 1] + m[o_w + 2]):
        return None
    if (arm[6] - m[o_w]) ** 2 <= gate2 * (v[6] + offset_var) and (arm[7] - m[o_w + 1]) ** 2 <= gate2 * (
            v[7] + offset_var):
        return None
    return _circle(w[0], w[1], w[2], s[0], s[1], s[2], lf, lu, e[0], e[1], e[2])


def project_forearm(s, f, v, lu: float, lf: float, offset_var: float = 0.0):
    """The elbow and wrist nearest ``f`` in the metric of variances ``v`` with ``|s - e| = lu``, ``|e - w| = lf``.

    Two steps of sequential quadratic programming (fewer once the lengths are met to 0.01 mm), then the elbow
    on the exact circle between the shoulder and the wrist, as :func:`project_arm`.

    Args:
        s: the kept shoulder (x, y, z).
        f: the elbow's and the wrist's six coordinates.
        v: their six variances.
        lu, lf: the upper and lower arm lengths.
        offset_var: added to each variance (AKC+'s landmark offsets), as ``[x + offset_var for x in v]``.

    Returns:
        The arm (nine floats: shoulder, elbow, wrist), or None when no arm with these lengths exists near ``f``
        (the shoulder-wrist distance out of reach, a zero-length segment, a singular step).
    """
    sx: float; sy: float; sz: float; fex: float; fey: float; fez: float; fwx: float; fwy: float; fwz: float
    vex: float; vey: float; vez: float; vwx: float; vwy: float; vwz: float; n1: float; n2: float; o: float
    sx, sy, sz = s
    fex, fey, fez, fwx, fwy, fwz = f
    vex, vey, vez, vwx, vwy, vwz = v
    if offset_var:
        o = offset_var
        vex, vey, vez, vwx, vwy, vwz = vex + o, vey + o, vez + o, vwx + o, vwy + o, vwz + o
    # Step 1, at x = f.
    ax, ay, az = sx - fex, sy - fey, sz - fez
    bx, by, bz = fex - fwx, fey - fwy, fez - fwz
    n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
    if not (n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M):
        return None
    ax, ay, az = ax / n1, ay / n1, az / n1
    bx, by, bz = bx / n2, by / n2, bz / n2
    a11 = ax * ax * vex + ay * ay * vey + az * az * vez
    a22 = bx * bx * (vex + vwx) + by * by * (vey + vwy) + bz * bz * (vez + vwz)
    a12 = -(ax * bx * vex + ay * by * vey + az * bz * vez)
    b1, b2 = n1 - lu, n2 - lf
    det = a11 * a22 - a12 * a12
    if not det > 1e-30:
        return None
    l1 = (a22 * b1 - a12 * b2) / det
    l2 = (a11 * b2 - a12 * b1) / det
    ex, ey, ez = fex - vex * (bx * l2 - ax * l1), fey - vey * (by * l2 - ay * l1), fez - vez * (bz * l2 - az * l1)
    wx, wy, wz = fwx + vwx * bx * l2, fwy + vwy * by * l2, fwz + vwz * bz * l2
    # Step 2, unless the lengths are met to 0.01 mm.
    ax, ay, az = sx - ex, sy - ey, sz - ez
    bx, by, bz = ex - wx, ey - wy, ez - wz
    n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
    if not (n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M):
        return None
    if not abs(n1 - lu) + abs(n2 - lf) < 1e-5:
        ax, ay, az = ax / n1, ay / n1, az / n1
        bx, by, bz = bx / n2, by / n2, bz / n2
        a11 = ax * ax * vex + ay * ay * vey + az * az * vez
        a22 = bx * bx * (vex + vwx) + by * by * (vey + vwy) + bz * bz * (vez + vwz)
        a12 = -(ax * bx * vex + ay * by * vey + az * bz * vez)
        dex, dey, dez = fex - ex, fey - ey, fez - ez
        b1 = n1 - lu - ax * dex - ay * dey - az * dez
        b2 = n2 - lf + bx * (dex - (fwx - wx)) + by * (dey - (fwy - wy)) + bz * (dez - (fwz - wz))
        det = a11 * a22 - a12 * a12
        if not det > 1e-30:
            return None
        l1 = (a22 * b1 - a12 * b2) / det
        l2 = (a11 * b2 - a12 * b1) / det
        ex, ey = fex - vex * (bx * l2 - ax * l1), fey - vey * (by * l2 - ay * l1)
        ez = fez - vez * (bz * l2 - az * l1)
        wx, wy, wz = fwx + vwx * bx * l2, fwy + vwy * by * l2, fwz + vwz * bz * l2
    return _circle(wx, wy, wz, sx, sy, sz, lf, lu, ex, ey, ez)


def behind_surface(arm, f, v, lu, lf, z_read, tol, z_prev, offset_var=0.0, shoulder_kept=False):
    """``arm`` (a projection of ``f``), or the other configuration when ``arm`` puts the elbow in front of the
    surface its pixel read.

    A depth camera reads the first surface on a joint's pixel ray: the joint is at that depth (the depth offset
    removes the limb's radius) or behind it (an occluder in front), never in front. When the filter followed an
    elbow read on a surface in front of it (MediaPipe on the skinned body, bvhtools_a2: 12-19 cm in front), the
    arm's lengths contradict its depths, and the projection from the filter's elbow can tip to the mirror
    configuration: the elbow in front of the wrist, farther in front of its reading. The projection is then run
    again from the elbow's Pythagorean candidate behind the shoulder (eq. 8 at the elbow's image x, y), and its
    arm is taken when it leaves the elbow behind the surface, its depth nearer our previous output's elbow's: no
    switch of configuration without that evidence too (an elbow in front of its reading because its 2D position is
    off the joint, the upper arm toward the camera, must not jump behind the shoulder).

    Args:
        arm: the projected arm (nine floats); its elbow's depth is ``arm[5]``.
        f: the nine coordinates (shoulder, elbow, wrist) the projection started from; the elbow's x, y are its
            image position.
        v: their nine variances.
        lu, lf: the upper and lower arm lengths.
        z_read: the depth read at the elbow's pixel (NaN: none; ``arm`` is returned).
        tol: how far in front of it an elbow may be (the reading's noise).
        z_prev: our previous output's elbow depth (NaN: none; ``arm`` is returned).
        offset_var: the projections' landmark-offset variance (:func:`project_arm`).
        shoulder_kept: the shoulder is kept (:func:`project_forearm`), else projected too (:func:`project_arm`,
            without the lengths' test).
    """
    if not arm[5] < z_read - tol or z_prev != z_prev:
        return arm
    sx, sy, sz = f[0], f[1], f[2]
    gz = _behind_shoulder(sx, sy, sz, f[3], f[4], lu)
    if gz != gz:
        return arm
    g = (sx, sy, sz, f[3], f[4], gz, f[6], f[7], f[8])
    if shoulder_kept:
        alt = project_forearm(g[0:3], g[3:9], v[3:9], lu, lf, offset_var)
    else:
        alt = project_arm(g, v, lu, lf, 0.0, _inf, offset_var)
    return alt if alt is not None and _takes_behind(alt[5], arm[5], z_read, tol, z_prev) else arm


def _behind_shoulder(sx: float, sy: float, sz: float, ex: float, ey: float, lu: float) -> float:
    """The depth of the elbow's Pythagorean candidate behind the shoulder at its image ``ex, ey`` (eq. 8); NaN when
    the upper arm cannot reach it."""
    r2 = lu * lu - (ex - sx) * (ex - sx) - (ey - sy) * (ey - sy)
    return sz + _sqrt(r2) if r2 >= 0.0 else _NAN


def _takes_behind(z_alt: float, z: float, z_read: float, tol: float, z_prev: float) -> bool:
    """Whether an elbow at depth ``z_alt`` replaces one at ``z``: not in front of the reading ``z_read`` beyond
    ``tol``, and nearer our previous output's depth ``z_prev`` (no switch of configuration without both)."""
    return not z_alt < z_read - tol and abs(z_alt - z_prev) < abs(z - z_prev)


class SurfaceMemory:
    """An elbow judged behind the surface its pixel read, remembered while the pixel reads that surface: a mixin of
    :class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus` (its attributes ``_read_e``: per side the depth
    read when our output was put behind it, NaN: none; ``_verdict``: this frame's ``_arm`` put it there;
    ``_cons``, ``_fs_r``, ``_v``).

    :func:`behind_surface` acts while the arm's lengths contradict the reading. Once the filter has followed the
    reading onto the occluder, nothing in this frame contradicts it: MediaPipe's left elbow behind the chest
    (bvhtools_a2's window, 10 Hz), read 19 cm in front, was put behind it while the wrist was seen; the wrist then
    lost, the EKF at the chest and the elbow rebuilt radially from the shoulder towards it, the elbow and the lost
    wrist went 20-30 cm in front for 30 frames. So the verdict holds while the pixel reads the same surface (within
    ``consistency_m`` of the last frame's reading) and another part of the body can lie on its ray
    (:func:`~akc_drake.core.arm_geometry.body_covers`: without it, a wrong verdict on an elbow raised to the side,
    nothing in front, held it 15-25 cm behind its correct reading for 14 frames; MediaPipe, cmu_13_26).

    When the detector then loses the elbow altogether, the memory stays until it is detected again, and the filter's
    estimate, which followed the occluder, is no evidence: the elbow is the upper arm held at the shoulder
    (:func:`~akc_drake.core.akc_plus_evidence.fuse_held` with ``no_evidence``). From the side (MediaPipe, held-out
    cmu_01_06, the far arm behind the body, read 30-41 cm in front), the KF ran on to 60-88 cm in front after the
    loss, and the elbow fused with it 40-50 cm."""

    __slots__ = ()

    def _surface_tol(self, side, z: float, ze: float, o: int) -> float:
        """:func:`behind_surface`'s ``tol`` for an elbow (flat offset ``o``) at depth ``ze`` read at ``z``:
        ``consistency_m`` when it is in front of the reading beyond that; ``-consistency_m`` (it must go behind
        the reading) where the last frame's verdict holds; NaN: neither."""
        c = self._cons
        if ze < z - c:
            return c
        zr = self._read_e[side]
        if zr == zr and abs(z - zr) <= c and ze < z + c and body_covers(self._v, o, side, self._fs_r):
            return -c
        return _NAN

    def _judged(self, arm, alt):
        """``alt`` (:func:`behind_surface`'s result), the verdict noted when it is not ``arm``."""
        if alt is not arm:
            self._verdict = True
        return alt

    def _behind_radial(self, side, o: int, s, e, ex: float, ey: float, z: float, z_prev: float, lu: float):
        """The elbow ``e`` put on the upper arm's sphere radially (a lost wrist: no projection), or, under
        :meth:`_surface_tol`, the Pythagorean candidate behind the shoulder at its image ``ex, ey`` when that is
        behind the reading ``z`` and nearer our previous output's depth ``z_prev`` (as :func:`behind_surface`)."""
        t = self._surface_tol(side, z, e[2], o)
        if t != t or z_prev != z_prev:
            return e
        gz = _behind_shoulder(s[0], s[1], s[2], ex, ey, lu)
        if not (gz == gz and _takes_behind(gz, e[2], z, t, z_prev)):
            return e
        self._verdict = True
        return ex, ey, gz

    def _remember_surface(self, side, out, m, o: int) -> None:
        """After this frame's output ``out`` of arm ``side``: its elbow's reading (flat offset ``o`` of ``m``)
        remembered when a rule put the elbow behind it beyond ``consistency_m``; kept while the detector loses the
        elbow altogether (no x, y)."""
        if m is not None and not _isfinite(m[o] + m[o + 1]):
            return  # (lost altogether: the memory stays, and the filter that followed the surface is no evidence)
        z = _NAN if m is None else m[o + 2]
        self._read_e[side] = z if self._verdict and out[5] > z + self._cons else _NAN  # (NaN z: NaN)


def circle_pair(wx: float, wy: float, wz: float, sx: float, sy: float, sz: float, lf: float, lu: float, p, p2):
    """:func:`~akc_drake.core.arm_geometry.circle_point` for two points ``p`` and ``p2`` (the two Pythagorean
    elbow candidates), the circle computed once: ``(q, q2)``, each bit-identical to ``circle_point``'s, or None
    when the circle does not exist (it depends on the shoulder and the wrist alone)."""
    c = circle_of(wx, wy, wz, sx, sy, sz, lf, lu)
    if c is None:
        return None
    return circle_nearest(c, p[0], p[1], p[2]), circle_nearest(c, p2[0], p2[1], p2[2])


def same_configuration(arm, sz, ez, wz):
    """Whether ``arm`` (nine floats) bends as the arm with depths ``sz``, ``ez``, ``wz`` (x, y alike): each segment
    points to the same side of the image plane (the sign of its depth difference; a segment in the plane, a
    zero difference, agrees with either side). The mirror candidates of eq. 7-8 differ in exactly this.
    """
    return (arm[2] - arm[5]) * (sz - ez) >= 0.0 and (arm[5] - arm[8]) * (ez - wz) >= 0.0


def sphere_point(cx, cy, cz, px, py, pz, vx, vy, vz, r):
    """The point at distance ``r`` from ``c`` nearest ``p`` in the metric of variances ``(vx, vy, vz)``.

    The minimiser of ``sum (q_i - p_i)^2 / v_i`` with ``|q - c| = r`` is ``q_i - c_i = (p_i - c_i) / (1 + lam v_i)``
    for the multiplier ``lam`` that solves ``|q - c| = r`` (a secular equation, decreasing in ``lam`` above
    ``-1 / max v``): Newton steps on ``1 / |q - c| - 1 / r`` (nearly linear in ``lam``), kept above the pole, then
    the exact length by scaling. Equal variances give the radial point.

    Args:
        cx, cy, cz: the sphere's centre (e.g. the elbow); px, py, pz: the point (e.g. the filter's wrist).
        vx, vy, vz: the point's variances (> 0).
        r: the radius (e.g. the forearm's length).

    Returns:
        The point (x, y, z); the radial one when ``p`` is at ``c`` or a variance is not positive.
    """
    dx, dy, dz = px - cx, py - cy, pz - cz
    n = _hypot(dx, dy, dz)
    if not (n >= _MIN_SEGMENT_M and vx > 0.0 and vy > 0.0 and vz > 0.0):
        if not n >= _MIN_SEGMENT_M:
            return (cx, cy, cz + r)
        return (cx + dx * r / n, cy + dy * r / n, cz + dz * r / n)
    pole = -1.0 / max(vx, vy, vz)
    lam = 0.0
    qx, qy, qz = dx, dy, dz
    for _ in range(20):
        ax, ay, az = 1.0 + lam * vx, 1.0 + lam * vy, 1.0 + lam * vz
        qx, qy, qz = dx / ax, dy / ay, dz / az
        n = _hypot(qx, qy, qz)
        phi = 1.0 / n - 1.0 / r
        if abs(phi) * r < 1e-12:
            break
        # d|q|/dlam = -(sum q_i^2 v_i / a_i) / |q|; dphi/dlam = -(d|q|/dlam) / |q|^2
        dphi = (qx * qx * vx / ax + qy * qy * vy / ay + qz * qz * vz / az) / (n * n * n)
        step = lam - phi / dphi
        lam = step if step > pole else 0.5 * (lam + pole)
    n = _hypot(qx, qy, qz)
    return (cx + qx * r / n, cy + qy * r / n, cz + qz * r / n)
