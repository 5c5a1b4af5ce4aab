"""AKC+'s length projection with a kept shoulder: the elbow and the wrist share the correction.

:func:`~akc_drake.core.arm_geometry.project_lengths` with the shoulder's variances zero (the shoulder fixed),
no calibration variance and no gate, written out for that case: the terms the zero variances cancel are not
computed, and the operations that remain are the same, in the same order (the arm is bit-identical to
``project_lengths(f, (0, 0, 0, *v_ew), lu, lf)``). AKC+ runs it on the frames where a lost elbow cannot close
the arm at its image x, y from a kept shoulder (:mod:`akc_drake.core.akc_plus`), about half the frames of
some clips.
"""

from __future__ import annotations

import math

from akc_drake.core.arm_geometry import circle_point

_hypot = math.hypot
#: A segment shorter than this (m) has no direction (as in ``project_lengths``).
_MIN_SEGMENT_M = 1e-12


def project_forearm(s, f, v, lu, lf):
    """The elbow and wrist nearest ``f`` in the metric of variances ``v`` with ``|s - e| = lu``, ``|e - w| = lf``.

    Two steps of sequential quadratic programming (fewer once the lengths are met to 0.01 mm), then the elbow
    on the exact circle between the shoulder and the wrist, as ``project_lengths``.

    Args:
        s: the kept shoulder (x, y, z).
        f: the elbow's and the wrist's six coordinates.
        v: their six variances.
        lu, lf: the upper and lower arm lengths.

    Returns:
        The arm (nine floats: shoulder, elbow, wrist), or None when no arm with these lengths exists near ``f``
        (the shoulder-wrist distance out of reach, a zero-length segment, a singular step).
    """
    sx, sy, sz = s
    fex, fey, fez, fwx, fwy, fwz = f
    vex, vey, vez, vwx, vwy, vwz = v
    ex, ey, ez, wx, wy, wz = f
    for it in (0, 1):
        ax, ay, az = sx - ex, sy - ey, sz - ez
        bx, by, bz = ex - wx, ey - wy, ez - wz
        n1, n2 = _hypot(ax, ay, az), _hypot(bx, by, bz)
        if not (n1 >= _MIN_SEGMENT_M and n2 >= _MIN_SEGMENT_M):
            return None
        if it and abs(n1 - lu) + abs(n2 - lf) < 1e-5:
            break  # converged: the linearisation error is below 0.01 mm (the circle below makes it exact)
        ax, ay, az = ax / n1, ay / n1, az / n1
        bx, by, bz = bx / n2, by / n2, bz / n2
        a11 = ax * ax * vex + ay * ay * vey + az * az * vez
        a22 = bx * bx * (vex + vwx) + by * by * (vey + vwy) + bz * bz * (vez + vwz)
        a12 = -(ax * bx * vex + ay * by * vey + az * bz * vez)
        if it == 0:
            b1, b2 = n1 - lu, n2 - lf  # (at x = f the linearised constraints are the residuals)
        else:
            dex, dey, dez = fex - ex, fey - ey, fez - ez
            b1 = n1 - lu - ax * dex - ay * dey - az * dez
            b2 = n2 - lf + bx * (dex - (fwx - wx)) + by * (dey - (fwy - wy)) + bz * (dez - (fwz - wz))
        det = a11 * a22 - a12 * a12
        if not det > 1e-30:
            return None
        l1 = (a22 * b1 - a12 * b2) / det
        l2 = (a11 * b2 - a12 * b1) / det
        ex, ey, ez = fex - vex * (bx * l2 - ax * l1), fey - vey * (by * l2 - ay * l1), fez - vez * (bz * l2 - az * l1)
        wx, wy, wz = fwx + vwx * bx * l2, fwy + vwy * by * l2, fwz + vwz * bz * l2
    e = circle_point(wx, wy, wz, sx, sy, sz, lf, lu, ex, ey, ez)
    if e is None:
        return None
    return (sx, sy, sz, *e, wx, wy, wz)
