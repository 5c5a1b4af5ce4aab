"""Small geometry of one arm in the camera frame, shared by AKC (:mod:`akc_drake.core.akc`) and AKC+.

Plain Python floats on the hot paths (a numpy call costs microseconds); numpy only in the public helpers
that take arrays.
"""

from __future__ import annotations

import math

import numpy as np

from akc_drake.core.skeleton import INDEX

_hypot = math.hypot
_isfinite = math.isfinite
_NAN = float("nan")
#: A segment shorter than this (m) has no direction.
_MIN_SEGMENT_M = 1e-12
#: A depth nearer than this (m) is no reading: no depth camera measures there (the D435 from about 0.2 m), and a pixel
#: ray scaled to it is degenerate (a reading of 1e-38 m put a shoulder 1e37 m off on its ray).
MIN_DEPTH_M = 0.01


def drop_unreadable(m) -> None:
    """Every row of the flat measurement ``m`` (a list, changed in place) whose depth is nearer than
    :data:`MIN_DEPTH_M` set NaN: no reading (its ray is degenerate)."""
    for o in range(2, len(m), 3):
        if m[o] < MIN_DEPTH_M:
            m[o - 2] = m[o - 1] = m[o] = _NAN


def elbow_angle_deg(p_s, p_e, p_w) -> float:
    """Angle at the elbow between (shoulder - elbow) and (wrist - elbow), degrees; NaN if undefined."""
    a = np.asarray(p_s, float) - np.asarray(p_e, float)
    b = np.asarray(p_w, float) - np.asarray(p_e, float)
    na, nb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
    if not (na > _MIN_SEGMENT_M and nb > _MIN_SEGMENT_M) or not (math.isfinite(na) and math.isfinite(nb)):
        return _NAN
    c = max(-1.0, min(1.0, float(a @ b) / (na * nb)))
    return math.degrees(math.acos(c))

#: Default torso axes in the camera frame C (x right, y down, z away from the camera) of an operator
#: facing the camera: front (towards the camera), down, and the lateral axis (right shoulder -> left).
DEFAULT_AXES = ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))
_LSH, _RSH = 3 * INDEX["left_shoulder"], 3 * INDEX["right_shoulder"]
_LHIP, _RHIP = 3 * INDEX["left_hip"], 3 * INDEX["right_hip"]
#: The forearm counts as bent backwards when its component across the upper arm points behind the upper
#: arm's anterior side by more than this fraction of the forearm length (sin 15 deg ~ 0.26: the normal
#: range of elbow hyperextension is 0-15 deg, and a near-straight arm's direction of bend is noise).
_BACKWARD_FRACTION = 0.25


def torso_axes(v) -> tuple:
    """(front, down, lateral) unit vectors of the torso from a flat ``(36,)`` pose (list of floats).

    As the paper's torso frame (eq. 17): lateral = left shoulder - right shoulder, down = from the shoulders'
    midpoint to the hips' midpoint made orthogonal to it, front = down x lateral (towards the camera for an
    operator facing it). Missing shoulders or hips give the default of an operator facing the camera.
    """
    lx: float; ly: float; lz: float; dx: float; dy: float; dz: float; nl: float; nd: float  # (setup.py)
    lx, ly, lz = v[_LSH] - v[_RSH], v[_LSH + 1] - v[_RSH + 1], v[_LSH + 2] - v[_RSH + 2]
    dx = 0.5 * (v[_LHIP] + v[_RHIP] - v[_LSH] - v[_RSH])
    dy = 0.5 * (v[_LHIP + 1] + v[_RHIP + 1] - v[_LSH + 1] - v[_RSH + 1])
    dz = 0.5 * (v[_LHIP + 2] + v[_RHIP + 2] - v[_LSH + 2] - v[_RSH + 2])
    nl = _hypot(lx, ly, lz)
    if not (_isfinite(nl + dx + dy + dz) and nl > 1e-6):
        return DEFAULT_AXES
    lx, ly, lz = lx / nl, ly / nl, lz / nl
    t = dx * lx + dy * ly + dz * lz
    dx, dy, dz = dx - t * lx, dy - t * ly, dz - t * lz
    nd = _hypot(dx, dy, dz)
    if not nd > 1e-6:
        return DEFAULT_AXES
    dx, dy, dz = dx / nd, dy / nd, dz / nd
    front = (dy * lz - dz * ly, dz * lx - dx * lz, dx * ly - dy * lx)
    return front, (dx, dy, dz), (lx, ly, lz)


def bends_backwards(ux: float, uy: float, uz: float, fx: float, fy: float, fz: float, lf: float, axes) -> bool:
    """Whether the forearm ``f`` bends backwards (hyperextension) about the elbow, for m5's signed angle.

    ``u`` is the unit vector elbow -> shoulder. The paper does not say how it signs theta; our convention:
    the upper arm's anterior side is the torso's front carried along by the arm's elevation (arm down or
    abducted: the torso's front; raised forwards to horizontal: up; overhead: backwards), and the elbow
    is hyperextended when the forearm's component across the upper arm points away from that side by more
    than :data:`_BACKWARD_FRACTION` of the forearm. Where the anterior side is ill-defined (arm raised
    sideways overhead) the angle is taken unsigned.
    """
    ax: float; ay: float; az: float; bx: float; by: float; bz: float; cx: float; cy: float; cz: float; n: float
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = axes
    hd = -(ux * bx + uy * by + uz * bz)  # humerus (shoulder -> elbow) . down
    hf = -(ux * ax + uy * ay + uz * az)  # . front
    hl = abs(ux * cx + uy * cy + uz * cz)  # |. lateral|
    k = hd + hl
    nx, ny, nz = ax * k - bx * hf, ay * k - by * hf, az * k - bz * hf
    n = _hypot(nx, ny, nz)
    if n < 0.3:
        return False
    t = fx * ux + fy * uy + fz * uz
    px, py, pz = fx - t * ux, fy - t * uy, fz - t * uz
    return (px * nx + py * ny + pz * nz) / n < -_BACKWARD_FRACTION * lf


def signed_elbow_angle_deg(p_s, p_e, p_w, axes=DEFAULT_AXES) -> float:
    """m5's signed elbow angle in [0, 360) degrees: the interior angle, or 360 - interior when bent backwards.

    Args:
        p_s, p_e, p_w: shoulder, elbow and wrist.
        axes: (front, down, lateral) torso axes (see :func:`torso_axes`); default: facing the camera.
    """
    interior = elbow_angle_deg(p_s, p_e, p_w)
    if not math.isfinite(interior):
        return _NAN
    u = np.asarray(p_s, float) - np.asarray(p_e, float)
    f = np.asarray(p_w, float) - np.asarray(p_e, float)
    u = u / np.linalg.norm(u)
    lf = float(np.linalg.norm(f))
    if bends_backwards(*u.tolist(), *f.tolist(), lf, axes):
        return 360.0 - interior
    return interior


def arm_inputs(v, offsets, prev):
    """One arm's shoulder, elbow and wrist from a flat pose ``v`` (plain floats), for the correctors' hot path.

    A missing wrist means the arm cannot be corrected (None). A missing elbow or shoulder x, y takes the previous
    output's (None without one); a missing depth takes the previous output's, else the next joint's (elbow <- wrist,
    shoulder <- elbow).

    Args:
        v: the flattened (12 * 3) pose, NaN where missing.
        offsets: the flat indices of the arm's shoulder, elbow and wrist x.
        prev: the arm's previous output (9 floats: shoulder, elbow, wrist) or None.

    Returns:
        ``(sx, sy, sz, ex, ey, ez, wx, wy, wz)`` or None to hold the arm.
    """
    o_s, o_e, o_w = offsets
    wx, wy, wz = v[o_w], v[o_w + 1], v[o_w + 2]
    if not _isfinite(wx + wy + wz):
        return None
    ex, ey, ez = v[o_e], v[o_e + 1], v[o_e + 2]
    if not _isfinite(ex + ey):
        if prev is None:
            return None
        ex, ey = prev[3], prev[4]
    if not _isfinite(ez):
        ez = prev[5] if prev is not None else wz
    sx, sy, sz = v[o_s], v[o_s + 1], v[o_s + 2]
    if not _isfinite(sx + sy):
        if prev is None:
            return None
        sx, sy = prev[0], prev[1]
    if not _isfinite(sz):
        sz = prev[2] if prev is not None else ez
    return sx, sy, sz, ex, ey, ez, wx, wy, wz


def ray_check(m, offsets, f, vs, var, r_xy: float, r_z: float, g2: float, gate: float, prev=None,
              agree: float = 0.0) -> None:
    """Measured depths the innovation test rejects: an occluder's, or the filter's error? The ray decides.

    The image measures a joint's ray (x / z, y / z); an occluder's depth read at the joint's pixel moves the
    measured (deprojected) point along that ray, not off it. So for each joint whose measured depth fails the
    innovation test (``(z - fz)^2 > g2 (R - P)``), the filter's point, scaled to the measured depth, is compared
    with the measured one in x, y (chi2 with 2 degrees of freedom against ``gate``; the residual's variance is
    the image's ``r_xy`` plus the filter's, scaled): a filter whose ray the detector contradicts is wrong about
    the joint (e.g. an EKF whose bone constraint moved a seen joint towards a lost neighbour) and is no evidence:
    the measured point replaces it in ``f``, with the measurement's variances in ``vs`` (both changed in place).
    A rejected depth on the filter's ray stays rejected (an occluder's), unless ``prev`` (our last output of the
    arm) sides with the measurement:
    * it agrees with it within ``agree`` while the filter's depth is beyond the gate of ``r_z`` from that output:
      two against one, the filter jumped (the paper's per-joint EKF swung mocapbank's seen shoulder 23 cm behind
      and 28 in front on alternate frames, on the ray) or lags (a KF that followed a wrist read on the wall, 84 cm
      behind the reading back on the body, which our last output took the frame before: MediaPipe, held-out
      cmu_05_11 driven bone by bone at 30 Hz; given for the EKF only, the elbow rebuilt from that KF's wrist went
      43 cm behind);
    * or the measured depth is behind the filter's and nearer our last output than the filter's is: no occluder
      reads behind the joint, and the filter moved away from it (the paper's per-joint EKF, its bone constraint
      pulling a seen elbow 20-28 cm in front of its reading towards a lost wrist: mocapbank, simulated detector,
      seed 2; AKC+(EKF) kept that elbow, and the lost wrist's z went +0.93 cm over the EKF's). A reading behind
      that our last output does not support (a wrist's pixel on the torso behind the hand) stays rejected.
    A filter's point at or behind the camera (no ray to compare; no joint is there: the paper's per-joint EKF
    diverged so on mocapbank driven bone by bone) is replaced likewise.

    Args:
        m: the flat (36) measurement, NaN where missing.
        offsets: flat indices of the arm's shoulder, elbow and wrist x.
        f, vs: the arm's nine filtered coordinates and their variances (lists).
        var: the filter's flat (36) posterior variances (the innovation test's ``P``).
        r_xy, r_z: the measurement's variances; g2: the innovation gate squared; gate: the largest chi2 accepted.
        prev: our last output of the arm (9 floats) or None; agree: the largest |measured - last output| depth.
    """
    mz: float; fz: float; q: float; mx: float; my: float; pz: float
    for i, o in ((0, offsets[0]), (3, offsets[1]), (6, offsets[2])):
        mz = m[o + 2]
        fz = f[i + 2]
        d, q = mz - fz, r_z - var[o + 2]
        if d * d > g2 * (q if q > 0.0 else 0.0) + 1e-12:
            mx, my = m[o], m[o + 1]
            if fz > 0.0:
                k = mz / fz
                dx, dy, k2 = mx - f[i] * k, my - f[i + 1] * k, k * k
                off = dx * dx / (r_xy + vs[i] * k2) + dy * dy / (r_xy + vs[i + 1] * k2) > gate
                if not off and prev is not None and mx == mx and my == my:
                    pz = prev[i + 2]
                    off = (abs(mz - pz) <= agree and (fz - pz) ** 2 > g2 * r_z) or (
                        mz > fz and abs(mz - pz) < abs(fz - pz))
            else:  # (the filter's point behind the camera, where no joint is: a diverged filter)
                off = mz > 0.0 and mx == mx and my == my
            if off:
                f[i], f[i + 1], f[i + 2] = mx, my, mz
                vs[i], vs[i + 1], vs[i + 2] = r_xy, r_xy, r_z


def circle_of(wx: float, wy: float, wz: float, sx: float, sy: float, sz: float, lf: float, lu: float):
    """Where the spheres of radius ``lf`` about the wrist and ``lu`` about the shoulder meet: ``(cx, cy, cz, nx, ny,
    nz, h)``, the circle's centre (on the wrist-shoulder line), its unit axis (wrist to shoulder) and its radius, or
    None if they do not meet. Plain floats."""
    d: float; h: float; a: float
    nx, ny, nz = sx - wx, sy - wy, sz - wz
    d = _hypot(nx, ny, nz)
    if not (abs(lf - lu) < d < lf + lu):
        return None
    nx, ny, nz = nx / d, ny / d, nz / d
    a = (d * d + lf * lf - lu * lu) / (2.0 * d)
    h = lf * lf - a * a
    h = math.sqrt(0.0 if 0.0 > h else h)  # (max(h, 0.0) exactly: -0.0 and NaN kept)
    return wx + a * nx, wy + a * ny, wz + a * nz, nx, ny, nz, h


def circle_nearest(c, px: float, py: float, pz: float):
    """The point of circle ``c`` (:func:`circle_of`) nearest to ``p``: ``p``'s projection on the circle's plane
    pushed out to the radius (``p`` on the axis: any point of the circle; one orthogonal to the axis and to y)."""
    q: float; t: float; f: float
    cx, cy, cz, nx, ny, nz, h = c
    qx, qy, qz = px - cx, py - cy, pz - cz
    t = qx * nx + qy * ny + qz * nz
    qx, qy, qz = qx - t * nx, qy - t * ny, qz - t * nz
    q = _hypot(qx, qy, qz)
    if q < 1e-12:
        qx, qy, qz = nz, 0.0, -nx
        q = _hypot(qx, qy, qz)
        if q < 1e-12:
            qx, qy, qz, q = 1.0, 0.0, 0.0, 1.0
    f = h / q
    return cx + qx * f, cy + qy * f, cz + qz * f


def circle_point(wx: float, wy: float, wz: float, sx: float, sy: float, sz: float, lf: float, lu: float, px: float,
                 py: float, pz: float):
    """The elbow at ``lf`` from the wrist and ``lu`` from the shoulder nearest to ``p``; None if none exists
    (:func:`circle_of`, :func:`circle_nearest`)."""
    c = circle_of(wx, wy, wz, sx, sy, sz, lf, lu)
    return None if c is None else circle_nearest(c, px, py, pz)


#: Samples of the circle in :func:`circle_xy_pair` before each minimum's refinement (15 degrees apart).
_CIRCLE_SAMPLES = 24
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def _xy2(t: float, a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """``(a0 + a1 cos t + a2 sin t)^2 + (b0 + b1 cos t + b2 sin t)^2``."""
    c: float = math.cos(t)
    s: float = math.sin(t)
    g: float = a0 + a1 * c + a2 * s
    k: float = b0 + b1 * c + b2 * s
    return g * g + k * k


def circle_xy_pair(wx: float, wy: float, wz: float, sx: float, sy: float, sz: float, lf: float, lu: float,
                   px: float, py: float):
    """The elbows at ``lf`` from the wrist and ``lu`` from the shoulder nearest in x, y to ``(px, py)`` (the elbow's
    image position): ``(q, q2)``, the nearest first (the same point twice when the distance has one minimum on the
    circle), or None when the circle does not exist or every point of it is equally near.

    Eq. 7-8's two depths keep the elbow's image x, y exactly; when it is farther from the wrist's in x, y than the
    forearm is long they do not exist (a detector's 2D elbow a few cm off the joint). The elbow lies on the circle
    between the shoulder and the wrist, and the points of that circle nearest its x, y keep them best. The squared
    distance in x, y of the circle's point at angle ``t`` is a trigonometric polynomial of degree 2 in ``t`` (at most
    two minima): sampled, then each sampled local minimum refined by golden-section search between its neighbours.
    Plain floats.
    """
    h: float; t: float; c: float; s: float; g: float; lo: float; hi: float; t1: float; t2: float; f1: float
    f2: float
    circle = circle_of(wx, wy, wz, sx, sy, sz, lf, lu)
    if circle is None:
        return None
    cx, cy, cz, nx, ny, nz, h = circle
    # An orthonormal basis (u, v) of the circle's plane.
    ux, uy, uz = (nz, 0.0, -nx) if abs(ny) < 0.9 else (0.0, -nz, ny)
    g = _hypot(ux, uy, uz)
    ux, uy, uz = ux / g, uy / g, uz / g
    vx, vy, vz = ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux
    # The point at angle t: x - px = a0 + a1 cos t + a2 sin t, y - py = b0 + b1 cos t + b2 sin t.
    a0, a1, a2 = cx - px, h * ux, h * vx
    b0, b1, b2 = cy - py, h * uy, h * vy
    n = _CIRCLE_SAMPLES
    vals = [_xy2(2.0 * math.pi * k / n, a0, a1, a2, b0, b1, b2) for k in range(n)]
    best = []
    for k in range(n):
        if vals[k] <= vals[k - 1] and vals[k] < vals[(k + 1) % n]:  # (a minimum within a sample either side)
            lo, hi = 2.0 * math.pi * (k - 1) / n, 2.0 * math.pi * (k + 1) / n
            t1, t2 = hi - _GOLDEN * (hi - lo), lo + _GOLDEN * (hi - lo)
            f1, f2 = _xy2(t1, a0, a1, a2, b0, b1, b2), _xy2(t2, a0, a1, a2, b0, b1, b2)
            while hi - lo > 1e-9:
                if f1 <= f2:
                    hi, t2, f2 = t2, t1, f1
                    t1 = hi - _GOLDEN * (hi - lo)
                    f1 = _xy2(t1, a0, a1, a2, b0, b1, b2)
                else:
                    lo, t1, f1 = t1, t2, f2
                    t2 = lo + _GOLDEN * (hi - lo)
                    f2 = _xy2(t2, a0, a1, a2, b0, b1, b2)
            t = 0.5 * (lo + hi)
            c, s = math.cos(t), math.sin(t)
            best.append((_xy2(t, a0, a1, a2, b0, b1, b2), cx + h * (c * ux + s * vx), cy + h * (c * uy + s * vy),
                         cz + h * (c * uz + s * vz)))
    if not best:  # (every point equally near: the circle's axis along the line of sight and p on it)
        return None
    best.sort()
    q = best[0][1:]
    return q, (best[1][1:] if len(best) > 1 else q)


# ------------------------------------------------------------------ AKC+'s candidates (plain floats)
def pythagoras(ax: float, ay: float, az: float, px: float, py: float, length: float):
    """The two points at ``length`` from anchor ``a`` with the x, y of ``p`` (eq. 7-8), or None if too far."""
    dx, dy = px - ax, py - ay
    r2 = length * length - dx * dx - dy * dy
    if r2 < 0.0:
        return None
    r: float = math.sqrt(r2)
    return (px, py, az + r), (px, py, az - r)


def behind_reading(ax: float, ay: float, az: float, px: float, py: float, z_read: float, length: float):
    """Of the two points at ``length`` from anchor ``a`` with the x, y of ``p`` (eq. 7-8), the nearer to the depth
    ``z_read`` read at ``p``'s pixel, one in front of it counting twice its distance; None when there is none.

    A camera reads the first surface on the ray, so a joint is likelier behind its reading than in front of it (a
    wrist behind its forearm, whose pixel shows the forearm's surface).
    """
    pair = pythagoras(ax, ay, az, px, py, length)
    if pair is None:
        return None
    b, f = pair  # (behind, in front)
    db, df = b[2] - z_read, f[2] - z_read  # (each candidate's depth behind the reading)
    return b if (db if db >= 0.0 else -2.0 * db) <= (df if df >= 0.0 else -2.0 * df) else f


def rebuild_variance(ax: float, ay: float, vax: float, vay: float, vaz: float, px: float, py: float, vpx: float,
                     vpy: float, length: float, length_var: float, prior_var: float = 0.0):
    """The variance of the depth eq. 7-8 gives joint ``p`` from anchor ``a`` (first order, regularised).

    ``z_p = z_a +- dz`` with ``dz^2 = l^2 - dx^2 - dy^2`` (``dx = x_p - x_a``, ``dy = y_p - y_a``), so
    ``var(dz^2) = 4 (dx^2 (vx_p + vx_a) + dy^2 (vy_p + vy_a) + l^2 var_l)`` and, to first order,
    ``var dz = var(dz^2) / (4 dz^2)``. That diverges near the image plane, where the rebuilt depth is in fact
    within about ``sqrt(sd(dz^2))`` of the anchor's: the denominator is ``4 |dz^2| + 2 sd(dz^2)``, which is
    the first-order value far from the plane, half of ``sd(dz^2)`` on it (``E max(u, 0)`` is 0.4 sd for a
    Gaussian ``u`` of mean 0) and less again out of reach (eq. 9's fallback puts the joint at the anchor's
    depth, which the data then favour). Plus the anchor's depth variance ``vaz``. With ``prior_var`` (the
    variance of the prior that chooses between the two candidates ``z_a +- dz``, e.g. the filter's depth), plus
    the mirror's risk: the wrong candidate, ``2 dz`` away, is chosen with probability ``Phi(-dz / sd)``.

    Args:
        ax, ay: the anchor's x, y; vax, vay, vaz: its variances.
        px, py: the joint's x, y; vpx, vpy: their variances.
        length: the segment's calibrated length; length_var: its variance.
        prior_var: the variance of the prior that chooses the candidate (0: the mirror's risk left out).
    """
    dx, dy = px - ax, py - ay
    dx2, dy2 = dx * dx, dy * dy
    l2 = length * length
    dz2 = l2 - dx2 - dy2
    v4 = 4.0 * (dx2 * (vpx + vax) + dy2 * (vpy + vay) + l2 * length_var)
    den: float = 4.0 * abs(dz2) + 2.0 * math.sqrt(v4)
    out: float = vaz + (v4 / den if den > 0.0 else 0.0)
    if prior_var > 0.0 and dz2 > 0.0:
        out += 2.0 * dz2 * math.erfc(math.sqrt(dz2 / (2.0 * prior_var)))  # Phi(-dz/sd) (2 dz)^2
    return out


def candidates(ax: float, ay: float, az: float, px: float, py: float, pz: float, length: float, xy_seen, tol: float):
    """The joint's candidates at ``length`` from anchor ``a``: the Pythagorean pair (eq. 7-8) when its x, y
    were detected this frame; when they were not (the filter holds them, less reliable 2D) and ``p`` is
    already within ``tol`` of the length, ``p`` moved radially (a small correction).
    """
    if not xy_seen and abs(_hypot(px - ax, py - ay, pz - az) - length) <= tol:
        return (radial(ax, ay, az, px, py, pz, length),)
    pair = pythagoras(ax, ay, az, px, py, length)
    if pair is not None:
        return pair
    # No solution: the nearest point at the length, x, y moved as little as possible when they were detected
    # (at the anchor's depth), else along the joint's direction (every axis as uncertain).
    return (in_plane(ax, ay, az, px, py, length) if xy_seen else radial(ax, ay, az, px, py, pz, length),)


def in_plane(ax: float, ay: float, az: float, px: float, py: float, length: float):
    """The point at ``length`` from ``a`` along the in-plane direction to ``p``, at ``a``'s depth."""
    dx, dy = px - ax, py - ay
    n: float = _hypot(dx, dy)
    if n < 1e-12:
        return ax, ay + length, az
    f = length / n
    return ax + dx * f, ay + dy * f, az


def radial(ax: float, ay: float, az: float, px: float, py: float, pz: float, length: float):
    """``p`` moved along its direction from ``a`` to ``length`` from it (eq. 9's form)."""
    dx, dy, dz = px - ax, py - ay, pz - az
    n: float = _hypot(dx, dy, dz)
    if n < 1e-12:
        return ax, ay + length, az
    f = length / n
    return ax + dx * f, ay + dy * f, az + dz * f


def segment_distance2(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """The squared distance in the image plane (x, y) from point ``p`` to the segment from ``a`` to ``b``."""
    dx, dy = bx - ax, by - ay
    n: float = dx * dx + dy * dy
    t: float = 0.0 if n < 1e-24 else ((px - ax) * dx + (py - ay) * dy) / n
    t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
    return (px - ax - t * dx) ** 2 + (py - ay - t * dy) ** 2


def _nearer(pair, pz: float):
    """Of a Pythagorean pair (:func:`pythagoras`), the point whose depth is nearer ``pz`` (the first on a tie)."""
    b, f = pair
    return b if abs(b[2] - pz) <= abs(f[2] - pz) else f


def nearest_depth(ax: float, ay: float, az: float, px: float, py: float, pz: float, length: float):
    """Joint ``p`` moved to ``length`` from ``a`` with its x, y kept (eq. 7-8): of the two depths, the one nearer its
    own; radially (as :func:`follow`) when its x, y are out of reach."""
    pair = pythagoras(ax, ay, az, px, py, length)
    return radial(ax, ay, az, px, py, pz, length) if pair is None else _nearer(pair, pz)


def follow(ax: float, ay: float, az: float, px: float, py: float, pz: float, length: float):
    """Joint ``p`` moved to ``length`` from ``a``: its x, y kept (the image is the reliable part) at the
    Pythagorean depth nearest its own when that moves it less than 1.5 times the radial move, else radially."""
    r = radial(ax, ay, az, px, py, pz, length)
    pair = pythagoras(ax, ay, az, px, py, length)
    if pair is None:
        return r
    q = _nearer(pair, pz)
    if abs(q[2] - pz) <= 1.5 * _hypot(r[0] - px, r[1] - py, r[2] - pz):
        return q
    return r


def straight_arm(sx: float, sy: float, sz: float, wx: float, wy: float, wz: float, lu: float, lf: float):
    """The arm from the shoulder ``s`` straight towards a wrist ``w`` beyond its reach (farther than ``lu + lf``):
    the wrist moved to ``lu + lf`` from the shoulder as :func:`follow` moves it (its x, y kept at the Pythagorean
    depth nearest its own, else radially) and the elbow on the segment at ``lu``; the nine floats, or None when the
    wrist is within reach (a circle of elbows exists: :func:`circle_of`)."""
    c: float; ex: float; ey: float; ez: float
    if not _hypot(wx - sx, wy - sy, wz - sz) > lu + lf:
        return None
    wx, wy, wz = follow(sx, sy, sz, wx, wy, wz, lu + lf)
    c = lu / (lu + lf)
    ex, ey, ez = sx + c * (wx - sx), sy + c * (wy - sy), sz + c * (wz - sz)
    return (sx, sy, sz, ex, ey, ez, wx, wy, wz)


def d2(p, qx: float, qy: float, qz: float):
    dx: float; dy: float; dz: float
    dx, dy, dz = p[0] - qx, p[1] - qy, p[2] - qz
    return dx * dx + dy * dy + dz * dz


def covered_excess(ex: float, ey: float, ez: float, wx: float, wy: float, wz: float, length: float,
                   r: float) -> float:
    """How much nearer than the depth offset assumes a joint's pixel may read the surface of its own segment, when that
    segment (from ``e`` to ``w``, of calibrated ``length``) points towards the camera: ``r (length / d_xy - 1)`` with
    ``d_xy`` the segment's length in x, y, at most ``length``; 0 when ``w`` is not nearer the camera than ``e`` (or a
    depth is NaN). A limb of radius ``r`` read on its side reads ``r`` in front of its axis, which the offset
    removes; turned at angle ``t`` to the line of sight it covers its end's pixel, whose ray meets its surface ``r /
    sin t`` in front (``sin t`` ~ ``d_xy / length``). The rule for a shoulder under its upper arm uses the same excess
    (``arm_radius_m``). The elbow under its forearm, measured on the evaluation's renders (its reading's error by the
    cosine of the forearm's angle to the line of sight, 0.8-0.9 / 0.9-1): the simulated detector 2.0 / 3.8 cm in front
    (clips), MediaPipe 1.1-1.6 / 2.1-2.8 cm. Plain floats."""
    d: float
    if not wz < ez:
        return 0.0
    d = _hypot(ex - wx, ey - wy)
    if not d < length:
        return 0.0
    return min(r * (length / (d if d > 1e-3 else 1e-3) - 1.0), length)


#: The forearm's share along the camera ray (``-f_z / |f|``, wrist nearer than the elbow) from which the hand is
#: taken to hide the wrist (0.5, 30 deg out of the image plane; none below) and to fully hide it (0.8, 53 deg).
TOWARD_CAMERA_SHARE = (0.5, 0.8)


def behind_hand(ex: float, ey: float, ez: float, wx: float, wy: float, wz: float, cx: float, cy: float, cz: float,
                length: float) -> float:
    """The factor that puts a wrist its own hand hides on its pixel ray behind the hand (1.0: left as it is).

    When the forearm points toward the camera, the hand is in front of the wrist and the depth at the wrist's pixel
    is not the wrist's: it reads the back of the hand or the fingers, up to a hand's length (10-15 cm measured)
    nearer, or, the end-on arm being a small patch in the image, past the hand's edge, farther (MediaPipe's wrist on
    the rendered reaches: 3-7 cm too far for a second while the arm is held out; the knuckles' midpoint there within
    1 cm of its true depth, the back of the hand being a broad surface facing the camera). The hand's length is a
    constant (``length``, wrist to the knuckles' midpoint ``c``), and its image part is measured, so the wrist lies
    ``dz = sqrt(L^2 - |(w - c)_xy|^2)`` behind ``c``. The wrist is moved along its pixel ray toward that depth, from
    nearer or from farther, by a weight that grows from 0 to 1 as the forearm (elbow ``e`` to wrist ``w``) turns
    toward the camera (:data:`TOWARD_CAMERA_SHARE`). Every step is continuous in the landmarks (no switch, so no jump
    from one frame to the next); a forearm across the image is left as it is, and so is a wrist whose knuckles read
    more than a hand's length behind it (their depth failed); the move is at most a hand's length either way.
    Plain floats (AKC+'s hot path); NaN anywhere leaves the wrist as it is.

    Returns:
        ``k``: the wrist is ``k * w`` (its pixel ray through the camera centre).
    """
    nf: float; lo: float; hi: float; dz: float
    fx, fy, fz = wx - ex, wy - ey, wz - ez
    nf = _hypot(fx, fy, fz)
    if not (nf > 1e-6 and wz > 1e-6) or cz - wz > length or not _isfinite(cx + cy + cz):
        return 1.0
    lo, hi = TOWARD_CAMERA_SHARE
    weight = (-fz / nf - lo) / (hi - lo)
    if not weight > 0.0:
        return 1.0
    dx, dy = wx - cx, wy - cy
    dz = math.sqrt(max(length * length - dx * dx - dy * dy, 0.0))
    deficit = min(max(cz + dz - wz, -length), length)  # at most a hand's length either way
    return (wz + (weight if weight < 1.0 else 1.0) * deficit) / wz


def turn_with(vx: float, vy: float, vz: float, ax: float, ay: float, az: float, bx: float, by: float,
              bz: float) -> tuple[float, float, float]:
    """The vector ``v`` turned by the smallest rotation that takes direction ``a`` to direction ``b`` (Rodrigues,
    with the axis ``a x b`` unnormalised: ``v c + k x v + (k . v) k / (1 + c)``, ``c`` the cosine). A forearm held
    while its wrist is not seen turns so with its upper arm (the arm swinging about the shoulder as one piece); the
    teleoperation's roll prior carries the torso's forward axis so (``control_frames``).
    ``v`` is returned as it is when either direction is degenerate or the turn is a half turn or more (then the
    smallest rotation is not defined). Plain floats (AKC+'s hot path)."""
    na: float; nb: float
    na, nb = _hypot(ax, ay, az), _hypot(bx, by, bz)
    if not (na > _MIN_SEGMENT_M and nb > _MIN_SEGMENT_M):
        return vx, vy, vz
    inv = 1.0 / (na * nb)
    c = (ax * bx + ay * by + az * bz) * inv
    if not c > -1.0 + 1e-9:
        return vx, vy, vz
    kx, ky, kz = (ay * bz - az * by) * inv, (az * bx - ax * bz) * inv, (ax * by - ay * bx) * inv
    q = (kx * vx + ky * vy + kz * vz) / (1.0 + c)
    return (vx * c + ky * vz - kz * vy + q * kx, vy * c + kz * vx - kx * vz + q * ky,
            vz * c + kx * vy - ky * vx + q * kz)


#: Flat offsets (3 x landmark index) of the torso's outline in the image, in order around it: the left shoulder,
#: the right shoulder, the right hip, the left hip.
_TORSO = tuple(3 * INDEX[n] for n in ("left_shoulder", "right_shoulder", "right_hip", "left_hip"))
#: Per side (left, right): the other arm's shoulder, elbow and wrist, then the hands' points that can cover an
#: elbow's pixel (its own wrist and knuckles and the other hand's knuckles), as flat offsets.
_COVERS = tuple(
    (tuple(3 * INDEX[f"{o}_{j}"] for j in ("shoulder", "elbow", "wrist")),
     tuple(3 * INDEX[n] for n in (f"{s}_wrist", f"{s}_pinky", f"{s}_index", f"{o}_pinky", f"{o}_index")))
    for s, o in (("left", "right"), ("right", "left")))


def body_covers(v, o: int, side: int, r: float) -> bool:
    """Whether another part of the body can lie on the pixel ray of the joint at flat offset ``o`` of arm ``side``
    (0 left, 1 right) in pose ``v`` (36 floats, camera frame): the torso (the shoulders' and hips' quadrilateral in
    the image, widened by ``r``), the other arm (its upper arm and forearm within ``2 r``: two limbs' radii), or a
    hand (its own wrist or either hand's knuckles within ``2 r``). Compared in the image (x / z, y / z), the widths
    taken at the joint's depth. A torso point not known (NaN, or nearer than :data:`MIN_DEPTH_M`) cannot rule the torso
    out: True.

    A camera reads the first surface on a joint's ray; a depth read in front of the joint needs an occluder there.
    An elbow read 19 cm in front was the chest (its pixel inside the torso's outline: MediaPipe, bvhtools_a2); one
    raised to the side, 16 cm outside it, had nothing in front and its reading was right (cmu_13_26).
    """
    ez = v[o + 2]
    if not ez >= MIN_DEPTH_M:
        return True
    u, w, q = v[o] / ez, v[o + 1] / ez, r / ez
    pts = []
    for k in _TORSO:
        z = v[k + 2]
        if not (z >= MIN_DEPTH_M and _isfinite(v[k] + v[k + 1])):
            return True
        pts.append((v[k] / z, v[k + 1] / z))
    inside = False
    for i in range(4):
        ax, ay = pts[i]
        bx, by = pts[i - 3]
        if (ay > w) != (by > w) and u < ax + (w - ay) * (bx - ax) / (by - ay):
            inside = not inside
        if segment_distance2(u, w, ax, ay, bx, by) <= q * q:
            return True
    if inside:
        return True
    q2 = 4.0 * q * q
    arm, hands = _COVERS[side]
    for a, b in ((arm[0], arm[1]), (arm[1], arm[2])):
        za, zb = v[a + 2], v[b + 2]
        if za >= MIN_DEPTH_M and zb >= MIN_DEPTH_M and segment_distance2(u, w, v[a] / za, v[a + 1] / za, v[b] / zb,
                                                       v[b + 1] / zb) <= q2:
            return True
    for k in hands:
        z = v[k + 2]
        if z >= MIN_DEPTH_M and _hypot(v[k] / z - u, v[k + 1] / z - w) ** 2 <= q2:
            return True
    return False
