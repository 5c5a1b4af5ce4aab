"""AKC+'s evidence tests: which of the filter's coordinates and depths are trustworthy (plain Python floats).

The statistical side of :mod:`akc_drake.core.akc_plus` with the filter's covariance: covariance matching of
the filter's variances by the running normalised innovation squared (:func:`arm_variances`), the hold of a
joint the detector lost altogether (:func:`hold_blind`; the soft hold of a joint on its neighbour or the torso,
:func:`fuse_held`) and the known-depth test of a depth not measured this frame (:func:`known_depths`). Pure
functions on plain floats and lists (a numpy call costs more than the arithmetic of one arm); the state they
update (the running NIS, the arm's coordinates) is passed in.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from akc_drake.core.arm_geometry import behind_hand, rebuild_variance

if TYPE_CHECKING:  # (read by Cython when compiling: typed indices, see setup.py; never imported at run time)
    import cython

_NAN = float("nan")
_INF = float("inf")


def arm_variances(sub_index, var, m, v, f, nis, alpha: float, floor: float, g2: float, refit=False,
                  seen_var: float = 0.0, noise=None):
    """The nine error variances of an arm (shoulder, elbow, wrist): the filter's times the running NIS.

    The running NIS measures the filter's error against its model while it is measured; an axis not measured
    this frame is extrapolated, and its variance may be inflated by it but never shrunk.

    A measured coordinate that passes the innovation test, of a filter whose covariance-matched error variance
    exceeds the measurement's (a lagging filter on a fast joint), is the better estimate of the two: it
    replaces the filter's in ``f`` with the measurement's variance. The test's residual variance is the
    model's (R - P) plus the filter's excess error the running NIS shows (its covariance-matched variance
    above P).

    With ``refit`` (a filter whose posterior also holds bone-length constraints: the EKFs), a measured coordinate
    that passes the test and whose running NIS ``k`` exceeds 1 is instead fused again with its measurement as a
    Kalman update whose prior variance is the one the NIS shows: for a scalar update (prior variance ``P0``,
    posterior ``P = P0 R / (P0 + R)``) the posterior residual's variance is ``R - P``, and a prior whose true
    variance is ``c P0`` makes it ``k (R - P)`` with ``k = (c P0 + R) / (P0 + R)``; that update's estimate and
    variance are then ``z - (z - f) / k`` and ``R - (R - P) / k`` (``k`` = 1: the filter's; ``k`` -> inf: the
    measurement's), whatever ``P0`` was. With a plain KF the same excess came as much from the measurement as
    from lag: moving its estimate so towards the measurement made the wrists' depth 0.15-0.71 cm worse on 8 of
    the 14 real-motion clips and windows (the binary rule above is its limit, and stays).

    With ``refit`` and ``seen_var`` > 0, a measured depth that passes the test is taken as read instead, with the
    variance ``seen_var`` (``AKCPlusConfig.seen_depth_sigma_m`` squared): the EKF's bone constraints and its lag
    keep a seen joint's depth off its reading by more than the reading errs; x and y are refitted as above.

    With ``noise`` as well (``AKCPlusConfig.seen_depth_fusion``), that depth is the reading and the filter's
    fused by the variances their residuals show (:func:`depth_reading_noise`): the reading's frame-to-frame noise
    ``s2`` (the arm's smallest), and the filter's error ``e2``, the running mean square of the residual (the NIS
    mean times ``R - P``) less ``s2``. In that mean this frame's NIS is winsorised at 9 times the mean before it,
    as in the noise's, so that one misread frame raises it at most 2.6-fold and cannot vouch for itself (at the
    gate's winsorisation a reading 19 cm off, inside the gate, was taken whole). The depth moves from the
    filter's by ``w = e2 / (e2 + s2)`` of the residual, with the variance ``w s2``, never below ``seen_var``: the
    landmark's offset from the joint centre changes with the pose and the surface read, an error that
    frame-to-frame differences do not show. A filter that lags a moving joint (``e2`` large) gives the reading; a
    still joint under a noisy camera keeps the filter's average. With the stereo noise of a real camera
    (``--depth-noise sigma_disparity_px=0.16,correlation_px=4``, about 1.3 cm per joint reading at 2 m), taken as
    read AKC+(EKF) was up to 0.61 cm worse than the EKF on a still shoulder's depth (the third held-out set) and
    0.75 on a still wrist (MediaPipe's clips); fused, at most 0.36 and 0.46. With the default's nearly
    noise-free readings (``s2`` small, ``w`` near 1) it is the reading, nearly as before.

    Without ``refit`` (a KF), with ``seen_var`` and ``noise``, a depth that the first rule would let replace the
    filter's moves ``w`` of the way instead, at the variance of that combination in the KF's own model,
    ``(1 - w)^2 p k + w^2 R`` (near ``R``, the replacement's, when the reading is clean): the KF's error above ``R``
    is a fast joint's lag or misread readings it took, and a reading taken whole carried each single misread frame
    into the output (MediaPipe's wrist read 16-19 cm behind on three frames of the second held-out set with a real
    camera's noise: AKC+(KF) +0.55 cm over the KF -> +0.48). Given ``w s2`` as after an EKF, such a depth became an
    anchor: a wrist read on the wall that the KF followed rebuilt the shoulder and the elbow there, 1.4-1.7 m off.
    A depth the KF's error does not so exceed stays the filter's: fused too, the shoulders of the MediaPipe windows
    followed their readings' slow errors (+0.46 -> +0.73 cm).

    Args:
        sub_index: per coordinate ``(position in the arm, flat index, R, NIS index)``.
        var: the filter's flat (36) posterior variances P.
        m: the flat (36) measurement, NaN where not measured.
        v: the flat (36) filtered pose.
        f: the arm's nine filtered coordinates (changed in place).
        nis: the running NIS means (18; this arm's entries updated in place).
        alpha: the newest frame's weight in the running mean; floor: the smallest factor it may apply.
        g2: the innovation gate squared (each frame's NIS is winsorised at it).
        refit: the filter's posterior holds constraints (see above).
        seen_var: a seen depth's error variance (0: refitted like x and y after a constrained filter, replaced
            or kept after a KF).
        noise: with ``seen_var``, the arms' depth reading noise (``depth_reading_noise``'s list of 12, changed in
            place) to fuse a seen depth with; None: taken as read (after a KF, the filter's replaced).

    Returns:
        The nine variances (a list).
    """
    p: float; k: float; kc: float; z: float; d: float; q: float; vi: float; r: float; s2: float; w: float
    i: cython.Py_ssize_t; j: cython.Py_ssize_t; n: cython.Py_ssize_t  # (C types when compiled: setup.py)
    b = 1.0 - alpha
    out = [0.0] * 9
    fuse = seen_var > 0.0 and noise is not None
    s2 = depth_reading_noise(sub_index, m, v, noise, alpha, seen_var) if fuse else 0.0
    for i, j, r, n in sub_index:
        p = var[j]
        k = kc = nis[n]
        z = m[j]
        if z != z:  # not measured
            out[i] = p * (k if k > 1.0 else 1.0)
            continue
        d = r - p
        if d > 0.0:
            # This frame's NIS joins the running mean, winsorised at the gate (a robust mean: one outlier cannot
            # make the filter look inconsistent and so vouch for itself).
            q = z - v[j]
            q = q * q / d
            k = nis[n] = b * k + alpha * (q if q < g2 else g2)
            if fuse:  # (the fusion's mean: this frame's NIS winsorised at 9 times the mean before it)
                kc = b * kc + alpha * (q if q < 9.0 * kc else 9.0 * kc)
        vi = p * (k if k > floor else floor)
        refit_k = refit and k > 1.0 and r > p
        # (A depth after a constrained filter, ``seen_var``; after a KF, fused, one that would replace the filter's.)
        seen_z = seen_var > 0.0 and i % 3 == 2 and (refit or (fuse and vi > r))
        if seen_z or refit_k or vi > r:
            d = z - f[i]
            if d * d <= g2 * ((r - p if r > p else 0.0) + (vi - p if vi > p else 0.0)) + 1e-12:
                if seen_z and fuse:  # the reading and the filter, fused by their residuals' variances
                    q = kc * (r - p) - s2 if r > p else vi - s2  # (the filter's error variance)
                    if q < p * floor:
                        q = p * floor
                    w = q / (q + s2)
                    f[i] += w * d
                    if refit:
                        vi = w * s2 if w * s2 > seen_var else seen_var
                    else:  # (the combination's variance in the KF's own model: a reading's error R, the filter's vi)
                        vi = (1.0 - w) * (1.0 - w) * vi + w * w * r
                elif seen_z:  # the reading, at the error a seen depth has
                    f[i] = z
                    vi = seen_var
                elif refit_k:  # the update at the prior variance the NIS shows
                    f[i] = z - d / k
                    vi = r - (r - p) / k
                else:  # the measurement replaces the filter
                    f[i] = z
                    vi = r
        out[i] = vi
    return out


def depth_reading_noise(sub_index, m, v, noise, alpha: float, prior: float) -> float:
    """The arm's depth reading noise: each joint's running estimate updated with this frame, and the arm's
    smallest (a variance, m^2).

    A joint's residual is its measured depth less the filter's (``m - v``). Between two consecutive frames that
    read it, half the squared change of the residual joins a running mean (weight ``alpha``; winsorised at 9 times
    the mean, so that one misread frame moves it at most 2.6 times): white reading noise of variance ``s2`` gives
    ``s2``, and the filter's error adds what it changes by in a frame (its lag on a moving joint). The arm's
    smallest, its stillest joint's, is the estimate: the three joints are read by the same camera at nearly the
    same range.

    Args:
        sub_index: per coordinate ``(position in the arm, flat index, R, NIS index)`` (the depths: positions 2, 5, 8).
        m: the flat (36) measurement, NaN where not measured; v: the flat (36) filtered pose.
        noise: per arm (left, right) and joint (shoulder, elbow, wrist) the last residual (NaN: not read last
            frame) and the running mean (12 floats; this arm's entries changed in place).
        alpha: the running mean's weight of the newest frame; prior: its value before any frame (a millionth of it
            is its floor: the winsorisation needs a positive mean).

    Returns:
        The smallest of the arm's three running means.
    """
    q: float; d: float; s: float; best: float  # (C doubles when compiled: setup.py)
    j: cython.Py_ssize_t; n: cython.Py_ssize_t; o: cython.Py_ssize_t
    b = 1.0 - alpha
    best = _INF
    for _, j, _, n in sub_index[2::3]:  # (the arm's three depths)
        o = 2 * (n // 3)
        q = m[j]
        if q != q:  # (not read: the next reading starts afresh)
            noise[o] = _NAN
        else:
            q -= v[j]
            d = noise[o]
            s = noise[o + 1]
            if d == d:
                d = 0.5 * (q - d) * (q - d)
                s = b * s + alpha * (d if d < 9.0 * s else 9.0 * s)
                noise[o + 1] = s if s > prior * 1e-6 else prior * 1e-6
            noise[o] = q
        s = noise[o + 1]
        if s < best:
            best = s
    return best


def beyond_reach(f, vs, m, offsets, prev, lu, lf, r_axes, length_var, g2):
    """A shoulder or a wrist lost altogether (no x, y) whose filtered position lies beyond the reach of the elbow
    measured this frame is no evidence: it starts from our last output of it with a variance of 1 m^2 per axis
    (``f``, ``vs`` changed in place), so that the holds and the lengths place it.

    Beyond reach: farther from the measured elbow than the segment's length, by more than the gate of the
    variances (the joint's, the measurement's and the length's). A filter can diverge while it sees nothing of a
    joint (the paper's per-joint EKF, whose bone constraint pulls a lost shoulder towards a lost wrist: metres
    off in x and y on mocapbank driven bone by bone), and the seen elbow was then moved 1.5 m to it.

    Args:
        f, vs: the arm's nine coordinates and their variances (lists; changed in place).
        m: the flat (36) measurement; offsets: flat indices of the arm's shoulder, elbow and wrist x.
        prev: our last output of the arm (nine floats) or None; lu, lf: the upper and lower arm lengths.
        r_axes: the measurement's variances per axis; length_var: the calibrated length's; g2: the gate squared.
    """
    o_s, o_e, o_w = offsets
    mx, my, mz = m[o_e], m[o_e + 1], m[o_e + 2]
    if prev is None or not math.isfinite(mx + my + mz):
        return
    r = r_axes[0] + r_axes[1] + r_axes[2] + length_var
    for base, o, length in ((0, o_s, lu), (6, o_w, lf)):
        if m[o] == m[o] or m[o + 1] == m[o + 1]:  # (x, y detected: not lost altogether)
            continue
        d = math.hypot(f[base] - mx, f[base + 1] - my, f[base + 2] - mz) - length
        if d > 0.0 and d * d > g2 * (vs[base] + vs[base + 1] + vs[base + 2] + r):
            f[base], f[base + 1], f[base + 2] = prev[base], prev[base + 1], prev[base + 2]
            vs[base] = vs[base + 1] = vs[base + 2] = 1.0


def hold_blind(p, vs, base, f0, prev, r_z):
    """A joint the detector lost altogether (no x, y): a depth the filter extrapolates is held at our last output.

    Extrapolated: a filter variance above the measurement's ``r_z`` and a depth more than one measurement
    sigma from the filter's estimate when the joint was last seen (``f0``; our last output's if none). x and y
    are kept as the filter gives them.

    Args:
        p: the joint's filtered (x, y, z); vs: the arm's nine variances; base: the joint's offset in the arm.
        f0: the filter's estimate when last seen, or None; prev: the arm's last output (nine floats).
        r_z: the measurement's depth variance.

    Returns:
        ``(point, held)``: ``held`` means the filter's prior is to be left out of the candidate choice.
    """
    f0z = prev[base + 2] if f0 is None else f0[2]
    if vs[base + 2] > r_z and (p[2] - f0z) ** 2 > r_z:
        return (p[0], p[1], prev[base + 2]), True
    return p, False


def fuse_held(f, vs, held, anchor, v_step: float, base, axes=(0, 1, 2), honest_frames: float = math.inf,
              no_evidence: bool = False):
    """A joint not measured this frame: the filter's estimate fused with the joint held at an offset from an anchor.

    Two Gaussian priors of the joint ``f[base:base + 3]``: the filter's (its covariance-matched variances
    ``vs[base:base + 3]``), and our outputs' offset ``held[:3]`` from ``anchor`` while the joint was measured,
    carried by this frame's ``anchor``, a random walk whose variance grows by ``v_step`` per blind frame
    (``held[3]``, counted here). Their product, on each axis of ``axes``, replaces the filter's coordinate and its
    variance; an axis whose variance the filter does not know (NaN) is left as it is. Fused once from the last
    measurement, not frame by frame: the filter's successive extrapolations are one piece of evidence, not
    independent ones. Three holds of AKC+ (:mod:`akc_drake.core.akc_plus`):

    * a wrist the detector lost altogether (``base`` 6): the forearm as our output last had it with the wrist
      detected, at this frame's elbow (``v_step`` = ``sigma_temporal_m^2``: how far a joint may move between two
      frames). A constant-velocity extrapolation of the wrist alone runs on while the hand stops or turns; the
      wrist moves with the elbow the camera still sees;
    * an elbow the detector lost altogether (``base`` 3): the upper arm likewise, at this frame's shoulder (seen,
      or itself held first), and the wrist then at the fused elbow;
    * a shoulder whose depth the occlusion filter dropped (``base`` 0, ``axes`` ``(2,)``), or that the detector
      lost altogether (all three axes): the shoulder's running-mean offset from the hips' centre, at this frame's
      hips' centre (the shoulder sits on the torso; ``v_step`` = ``sigma_shoulder_m^2``; after a constrained
      filter with ``honest_frames`` too). A constant-velocity
      filter that holds the landmark reports a variance that grows without bound, so eq. 8 from the elbow would
      replace a shoulder it holds well with one that carries the elbow's depth error, several cm; one that
      extrapolates a lost landmark carries the velocity of its last, often disturbed, measurements: 30 cm in x
      after ten frames.

    Args:
        f: the arm's nine coordinates (changed in place); vs: their nine variances (changed in place).
        held: ``[dx, dy, dz, n]``, the offset from the anchor and the blind frames (``n`` counts this frame).
        anchor: this frame's anchor ``(x, y, z)`` (the joint before it, or the hips' centre).
        v_step: the held joint's variance per axis and blind frame.
        base: the joint's offset in the arm (0 the shoulder, 3 the elbow, 6 the wrist).
        axes: the axes fused.
        honest_frames: after this many blind frames the filter's variance is no error measure (a constrained
            filter's, whose bone constraints shrink the posterior of a joint nothing measures): each axis counts
            it at least the hold's variance (inf: always the filter's).
        no_evidence: the filter's estimate is no evidence (it followed a depth judged an occluder's:
            :class:`~akc_drake.core.akc_plus_lengths.SurfaceMemory`; or, for a wrist, readings misread before the
            loss: :func:`held_segments`): the hold alone, with its variance.
    """
    n: float; v: float
    n = held[3] = held[3] + 1.0
    vh = v_step * n
    for k in axes:
        i = base + k
        v = vs[i]
        if no_evidence:
            f[i], vs[i] = anchor[k] + held[k], vh
        elif v == v:  # (a variance the filter does not know: NaN, left as it is)
            if n > honest_frames and v < vh:
                v = vh  # (no surer than the hold: ``honest_frames``)
            s = v + vh
            f[i] = (vh * f[i] + v * (anchor[k] + held[k])) / s
            vs[i] = v * vh / s


def followed_rejected(z: float, fz: float, prev, i: cython.Py_ssize_t, bound2: float) -> bool:
    """Whether the filter followed a measured depth ``z`` that the innovation test rejected: its depth ``fz`` moved
    from our last output's (``prev[i]``) towards the reading by more than ``sqrt(bound2)`` (``g2 R``: more than a
    measurement's noise). A filter without a gate (the KF) moves towards an occluder's reading; its estimate and
    its small posterior variance are then no evidence of the joint (``_arm`` leaves its prior out, as for a depth
    that another rule rejects but the filter followed). The simulated detector on held-out cmu_05_11 driven bone by
    bone, 30 Hz: an elbow read 1.08 m in front (an occluder, its 2D 18 cm off), the KF 38 cm in front after it,
    its variance 4 cm; the elbow chosen towards it went 53 cm in front for three frames, where our last output, the
    wrist and the truth lay behind."""
    p: float
    if prev is None:
        return False
    p = prev[i]
    return (fz - p) * (z - p) > 0.0 and (fz - p) * (fz - p) > bound2  # (NaN z: False)


def known_depths(m, vs, me, ms, o_e, o_s, ke, ks, lu: float, lf: float, xy, r_z: float, length_var: float, no_prior,
                 lost, recent):
    """Whether the elbow's and the shoulder's depths are known (see :mod:`akc_drake.core.akc_plus`).

    Known: measured and seen, or not measured this frame (nor held at our last output, ``no_prior``) with a
    filter variance within the measurement's or, when last seen at most ``recent`` frames ago, within the
    variance eq. 7-8 would give the depth from its neighbours (:func:`~akc_drake.core.arm_geometry.
    rebuild_variance`: the elbow from the wrist, fused with the one from a seen shoulder; the shoulder from the
    elbow, whose own variance is then the smaller of the filter's and its rebuilt one).

    Args:
        m: the flat (36) measurement or None; vs: the arm's nine variances.
        me, ms: the elbow's, the shoulder's depth seen this frame.
        o_e, o_s: their flat offsets; ke, ks: their joint keys (``no_prior``, ``lost``).
        lu, lf: the arm's calibrated lengths; xy: ``(sx, sy, ex, ey, wx, wy)``.
        r_z: the measurement's depth variance; length_var: the calibrated lengths' variance.
        no_prior: the joint keys whose filter estimate is no evidence; lost: frames since each was seen.
        recent: the largest number of frames since a measurement for the rebuild comparison.

    Returns:
        ``(elbow known, shoulder known)``.
    """
    sx: float; sy: float; ex: float; ey: float; wx: float; wy: float; ve: float; vsz: float; mze: float; mzs: float
    rb: float; rs: float
    sx, sy, ex, ey, wx, wy = xy
    ve, vsz = vs[5], vs[2]
    # Each test without its rebuilt variance; that variance is computed only where the test turns on it (a
    # filter variance above the measurement's, ``not v <= r_z`` so that NaN counts as above).
    mze, mzs = (_NAN, _NAN) if m is None else (m[o_e + 2], m[o_s + 2])  # (NaN: not measured this frame)
    kn_e = me or (ke not in no_prior and mze != mze and (ve <= r_z or lost[ke] <= recent))
    kn_s = ms or (ks not in no_prior and mzs != mzs and (vsz <= r_z or lost[ks] <= recent))
    need_e = not me and kn_e and not ve <= r_z
    need_s = not ms and kn_s and not vsz <= r_z
    if need_e or (need_s and not me):
        rb = rebuild_variance(wx, wy, vs[6], vs[7], vs[8], ex, ey, vs[3], vs[4], lf, length_var, ve)
        if ms:
            rs = rebuild_variance(sx, sy, vs[0], vs[1], vs[2], ex, ey, vs[3], vs[4], lu, length_var, ve)
            rb = rb * rs / (rb + rs)
        if need_e:
            kn_e = ve <= rb
        if rb < ve:
            ve = rb
    if need_s:
        kn_s = vsz <= rebuild_variance(ex, ey, vs[3], vs[4], ve, sx, sy, vs[0], vs[1], lu, length_var, vsz)
    return kn_e, kn_s


def _stretched(m, oa, ob, length, r_axes, length_var, g2):
    """Whether the measured joints at flat offsets ``oa``, ``ob`` are farther apart than ``length`` reaches."""
    dx, dy, dz = m[ob] - m[oa], m[ob + 1] - m[oa + 1], m[ob + 2] - m[oa + 2]
    d2 = dx * dx + dy * dy + dz * dz
    if not d2 > 0.0:  # (NaN: a joint not measured)
        return False
    r = d2**0.5 - length
    if r <= 0.0:
        return False
    rx, ry, rz = r_axes
    s = 2.0 * (dx * dx * rx + dy * dy * ry + dz * dz * rz) / d2 + length_var
    return r * r > g2 * s


def _restore(k, f, vs, f0, sub_index, var, nis, floor):
    """Joint ``k`` of the arm back to the filter's point and covariance-matched variances."""
    i = 3 * k
    for c in (i, i + 1, i + 2):
        _, j, _, n = sub_index[c]
        q = nis[n]
        f[c] = f0[c]
        vs[c] = var[j] * (q if q > floor else floor)


def unreachable_replacements(f, vs, f0, m, offsets, sub_index, var, nis, floor, lu, lf, r_axes, length_var, g2,
                             s_held=False) -> int:
    """Undo a measured point that replaced the filter's (covariance matching, the ray test) off the arm's reach.

    Both replacement rules weigh the measurement against the filter alone. A depth read off the joint (the
    background or another limb behind a landmark that sits off the body's edge: MediaPipe puts landmarks several
    cm off the joint, and a depth pixel past the silhouette reads the wall 1-1.5 m behind) is on the joint's
    ray, so the ray test takes it for the filter's error; but no arm with the calibrated lengths joins it to the
    other joints the camera measured this frame. So a replaced joint is tested against each other measured
    joint of the arm, measurement against measurement (the filter's neighbour may be the one that is wrong, e.g.
    a per-joint EKF's lost joint): a pair farther apart than the arm reaches (its segment's calibrated length,
    or both lengths for the shoulder and the wrist) by more than the gate (``(d - l)^2 > g2 (u^T (R_a + R_b) u +
    length_var)``, ``u`` the direction, ``R`` the measurement's variances) undoes a replacement: it gets back the
    filter's point and its covariance-matched variances (:func:`arm_variances`' before the replacement). Which
    one: a joint stretched from both others, which fit each other, and read behind both (the background past the
    silhouette) is the odd one, and only its replacement is undone, if any; otherwise, pair by pair, the outer
    joint's if it was replaced, else the inner one's, and a measurement so undone is tested no further (a wrist
    on the wall blamed the seen shoulder's and elbow's replacements too). Only a stretch is tested: a
    pair nearer than its length is a foreshortened depth error either way, and a real measurement's (the
    design half: testing both ways undid the ray test's fixes of the `ours` EKF's seen joints, worst increase
    +0.25 -> +0.55 cm with the simulated detector). A shoulder held on the torso (``s_held``: its depth dropped,
    :func:`fuse_held`) counts as measured at its held point: an elbow and a wrist both read on the wall
    behind them agree with each other, and only the torso tells that neither is reachable from the shoulder
    (MediaPipe, bvhtools_test2 60-131 s: the arm rebuilt from them put the shoulder 1.5 m behind).

    Args:
        f, vs: the arm's nine coordinates and variances after the replacements (changed in place).
        f0: the filter's nine coordinates.
        m: the flat (36) measurement; offsets: the arm's flat shoulder, elbow and wrist x indices.
        sub_index, var, nis, floor: as :func:`arm_variances` (``nis`` already updated this frame).
        lu, lf: the calibrated upper and lower arm lengths; r_axes: the measurement's x, y, z variances;
        length_var: the lengths' variance.
        g2: the gate squared.
        s_held: the shoulder (``f[0:3]``) is held on the torso, or its reading replaced the filter's and agrees
            with the torso's (``TorsoReference._torso_confirms``); it is never restored.

    Returns:
        How many joints were restored.
    """
    o_s, o_e, o_w = offsets
    z = m[o_e + 2]
    r1 = f[5] == z and f0[5] != z
    z = m[o_w + 2]
    r2 = f[8] == z and f0[8] != z
    if s_held:
        if not (r1 or r2):
            return 0  # (nothing replaced: nothing to undo; a held shoulder is never restored)
        m = m[:]  # (a copy: the caller's measurement stays as measured)
        m[o_s], m[o_s + 1], m[o_s + 2] = f[0], f[1], f[2]
        r0 = False
    else:
        z = m[o_s + 2]
        r0 = f[2] == z and f0[2] != z
    if not (r0 or r1 or r2):
        return 0
    # The odd joint, two against one, whatever its filter says (a wrist read on the wall, which the paper's EKF had
    # followed, undid the seen shoulder's and elbow's replacements: bvhtools_c's shoulder 66 cm behind); one read
    # in front of two that fit each other may be the one right (an elbow and a wrist both on the wall).
    s01 = _stretched(m, o_s, o_e, lu, r_axes, length_var, g2)
    s12 = _stretched(m, o_e, o_w, lf, r_axes, length_var, g2)
    s02 = _stretched(m, o_s, o_w, lu + lf, r_axes, length_var, g2)
    odd = 2 if s12 and s02 and not s01 else 0 if s01 and s02 and not s12 else 1 if s01 and s12 and not s02 else -1
    z3 = (m[o_s + 2], m[o_e + 2], m[o_w + 2])
    replaced = [r0, r1, r2]
    if odd >= 0 and z3[odd] > z3[odd - 1] and z3[odd] > z3[odd - 2]:
        if replaced[odd]:
            _restore(odd, f, vs, f0, sub_index, var, nis, floor)
            return 1
        return 0
    out = 0
    # Otherwise the pairs in order (shoulder-elbow, elbow-wrist, shoulder-wrist); the outer joint's replacement
    # undone first. A measurement so undone is no reading of its joint: no later pair is tested against it.
    bad = [False, False, False]
    for a, b, stretched in ((0, 1, s01), (1, 2, s12), (0, 2, s02)):
        if stretched and (replaced[a] or replaced[b]) and not (bad[a] or bad[b]):
            k = b if replaced[b] else a
            _restore(k, f, vs, f0, sub_index, var, nis, floor)
            bad[k], replaced[k] = True, False
            out += 1
    return out


def forearm_misread(m, o_s: cython.Py_ssize_t, o_e: cython.Py_ssize_t, o_w: cython.Py_ssize_t, lu: float, lf: float,
                    tol: float) -> bool:
    """Whether the measured wrist is the odd one out of an arm measured whole: its forearm to the measured elbow
    misses ``lf`` by more than ``tol`` while the measured upper arm fits ``lu`` within it (two against one). False
    when any of the nine coordinates of ``m`` (offsets ``o_s``, ``o_e``, ``o_w``) is NaN.

    Such a reading is no forearm to hold for the frames the wrist is then lost altogether (``fuse_held``): the
    detector loses a wrist as it goes behind the body or out of view, and the frames before read it off, its 2D
    short and its depth on whatever covers it. The arm output from it has the forearm's length made up in depth.
    MediaPipe on bvhtools_c: the last frame before a 15-frame loss read the wrist 11 cm in front with its 2D 7 cm
    short (the forearm 21.9 cm against 27.4); the projection put the wrist 16.5 cm in front and the hold carried
    it (18-22 cm in front, the KF 7-15).
    """
    d: float; u: float  # (C doubles: setup.py)
    d = math.hypot(m[o_e] - m[o_w], m[o_e + 1] - m[o_w + 1], m[o_e + 2] - m[o_w + 2]) - lf
    if not abs(d) > tol:  # (the common case: one hypot)
        return False
    u = math.hypot(m[o_e] - m[o_s], m[o_e + 1] - m[o_s + 1], m[o_e + 2] - m[o_s + 2]) - lu
    return abs(u) <= tol


def held_segments(blind, blind_e, out, m, o_s: cython.Py_ssize_t, o_e: cython.Py_ssize_t, o_w: cython.Py_ssize_t,
                  lu: float, lf: float, tol: float):
    """One arm's segments held for the frames a joint is lost altogether (``fuse_held``), after the arm ``out``
    (nine floats) was output for the measurement ``m`` (None: no measurement, all detected): ``(blind,
    blind_e)``, each side's entries of AKC+'s ``_blind`` and ``_blind_e`` (lists, or None before any).

    * ``blind``, the forearm (wrist - elbow) of our output, the blind frames, the upper arm (elbow - shoulder) the
      held forearm turns with, and the misread frames: taken when the wrist is detected, unless its reading is
      misread (:func:`forearm_misread`). Then the forearm held from before is kept and ages a frame, a random
      walk's step, and the misread frames count one more: a filter that took those readings extrapolates their
      error once the wrist is lost, and is then no evidence of it (``fuse_held``'s ``no_evidence``).
    * ``blind_e``, the upper arm and the blind frames: taken when the elbow is detected.
    """
    if m is None or math.isfinite(m[o_w] + m[o_w + 1]):
        if blind is not None and m is not None and forearm_misread(m, o_s, o_e, o_w, lu, lf, tol):
            blind[3] += 1.0
            blind[7] += 1.0
        else:
            blind = [out[6] - out[3], out[7] - out[4], out[8] - out[5], 0.0, out[3] - out[0], out[4] - out[1],
                     out[5] - out[2], 0.0]
    if m is None or math.isfinite(m[o_e] + m[o_e + 1]):
        blind_e = [out[3] - out[0], out[4] - out[1], out[5] - out[2], 0.0]
    return blind, blind_e


def wrist_misfit(f, vs, lu, lf, cons, shoulder_kept):
    """Whether a seen wrist's depth, not the seen elbow's, carries a too-long forearm (``|e - w| > lf``).

    * The wrist the forearm's nearer end (``wz < ez``), the shoulder kept (``shoulder_kept``: seen, or held on the
      torso) and the upper arm within ``cons`` of ``lu`` (the elbow fits its shoulder): two against one. A depth
      camera reads a joint in front of where it is (an occluder: the hand, the fingers) far more often than behind
      it (the silhouette's edge, which the gates catch): the wrist's depth is the likelier error; it takes the
      correction and the elbow stays (shared by their variances, the seen elbow took 3-6 cm of the wrist's error:
      MediaPipe on the skinned body, bvhtools_a1, the wrist read 6-12 cm in front).
    * The wrist the farther end, beyond the forearm's reach (``lf + cons``), and known worse than the elbow (its
      variance ``vs[8]`` above the elbow's ``vs[5]``): the silhouette's edge read past the wrist that the gates
      did not catch, as the filter followed it over a few frames. MediaPipe on a held-out CMU clip driven bone by
      bone: the wrist's pixel read the wall 1.7 m behind two frames running; the second passed the innovation
      test, the shoulder (the upper arm towards the camera) was no anchor, and the arm was rebuilt from that
      wrist, the seen shoulder and elbow with it, 1.4-1.7 m off (the elbow's z RMSE over the clip 12.3 cm against
      the KF's 4.1; 6.4 with this rule). Without the shoulder: the elbow and the variances are the evidence.

    Args:
        f: the arm's nine coordinates (shoulder, elbow, wrist); vs: their variances; lu, lf: the calibrated
            lengths; cons: the tolerance (``consistency_m``); shoulder_kept: the shoulder seen or held.
    """
    sx, sy, sz, ex, ey, ez, wx, wy, wz = f
    d = math.hypot(ex - wx, ey - wy, ez - wz)
    if wz < ez:
        return shoulder_kept and d > lf and abs(math.hypot(sx - ex, sy - ey, sz - ez) - lu) <= cons
    return wz > ez and d > lf + cons and vs[8] > vs[5]


def hidden_wrist(v, m, o_e: cython.Py_ssize_t, o_w: cython.Py_ssize_t, o_i: cython.Py_ssize_t, o_p: cython.Py_ssize_t,
                 length: float) -> None:
    """A measured wrist that its own hand hides, put behind the hand (:func:`~akc_drake.core.arm_geometry.behind_hand`).

    The forearm's direction is the filter's elbow to the measured wrist (the elbow's depth is often dropped then:
    its pixel is near the wrist's). The filter's wrist, which filtered the same readings, is moved by the same
    step (its bias removed, its lag kept: replaced by the measurement, a lagging EKF's arm 20-40 cm behind its new
    wrist was rebuilt off its image x, y).

    Args:
        v: the flat (36) filtered pose; m: the flat (36) measurement (both changed in place).
        o_e, o_w, o_i, o_p: the elbow's, wrist's, index and pinky knuckles' flat offsets.
        length: the wrist to the knuckles' midpoint.
    """
    wx: float; wy: float; wz: float; k: float
    wx, wy, wz = m[o_w], m[o_w + 1], m[o_w + 2]
    if not wz < v[o_e + 2]:  # (the forearm not toward the camera, or a depth NaN: the common case, at once)
        return
    k = behind_hand(v[o_e], v[o_e + 1], v[o_e + 2], wx, wy, wz, 0.5 * (m[o_i] + m[o_p]),
                    0.5 * (m[o_i + 1] + m[o_p + 1]), 0.5 * (m[o_i + 2] + m[o_p + 2]), length)
    if k != 1.0:
        k -= 1.0
        m[o_w], m[o_w + 1], m[o_w + 2] = wx + k * wx, wy + k * wy, wz + k * wz
        v[o_w], v[o_w + 1], v[o_w + 2] = v[o_w] + k * wx, v[o_w + 1] + k * wy, v[o_w + 2] + k * wz
