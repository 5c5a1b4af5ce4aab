import math
import random

import numpy as np
import pytest
from scipy.optimize import minimize

from akc_drake.core.akc_plus_lengths import (
    SurfaceMemory,
    behind_surface,
    circle_pair,
    learn_elbow_offset,
    measured_arm,
    project_arm,
    project_forearm,
    same_configuration,
    sphere_point,
)
from akc_drake.core.arm_geometry import circle_point
from akc_drake.core.skeleton import INDEX


def random_arm(rng):
    """A random arm about 2 m from the camera near the lengths 0.29 and 0.26: shoulder, elbow and wrist."""
    s = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(1.7, 2.3))
    e = tuple(c + rng.gauss(0.0, 0.17) for c in s)
    w = tuple(c + rng.gauss(0.0, 0.15) for c in e)
    return s, e, w


def test_forearm_projection_is_the_arm_projection_with_a_fixed_shoulder():
    # Bit-identical to project_arm with zero shoulder variances (no calibration variance, no gate) over random
    # arms near the lengths.
    rng = random.Random(11)
    solved = 0
    for _ in range(2000):
        s, e, w = random_arm(rng)
        v = tuple(rng.uniform(1e-5, 1e-2) for _ in range(6))
        want = project_arm((*s, *e, *w), (0.0, 0.0, 0.0, *v), 0.29, 0.26, 0.0, math.inf)
        got = project_forearm(s, (*e, *w), v, 0.29, 0.26)
        assert got == want
        solved += got is not None
    assert solved > 1000


def test_forearm_projection_keeps_the_shoulder_and_moves_the_uncertain_depths():
    s = (0.18, 0.0, 2.0)
    e, w = (0.2, 0.27, 2.05), (0.25, 0.5, 1.95)  # upper arm 27.8 cm, forearm 25.3 cm: both short
    v = (1e-4, 1e-4, 4e-3, 1e-4, 1e-4, 2.5e-3)  # x, y as a measurement knows them, depths far less
    arm = project_forearm(s, (*e, *w), v, 0.29, 0.26)
    assert arm[:3] == s
    assert math.dist(arm[:3], arm[3:6]) == pytest.approx(0.29, abs=1e-12)
    assert math.dist(arm[3:6], arm[6:]) == pytest.approx(0.26, abs=1e-12)
    moved = [abs(a - b) for a, b in zip(arm[3:], (*e, *w), strict=True)]
    assert max(moved[0], moved[1], moved[3], moved[4]) < 0.006  # x, y: at most 6 mm
    assert moved[2] > 0.03 and moved[5] > 0.01  # the depths take the correction
    assert project_forearm(s, (*e, 0.9, 0.5, 1.95), v, 0.29, 0.26) is None  # the wrist out of reach


def _local_map_arm(f, var, lu, lf, start):
    """The constrained minimum of sum (p - f)^2 / var nearest ``start`` (SciPy's SLSQP in the whitened
    coordinates (p - f) / sd), or None where SLSQP does not converge to the exact lengths."""
    f, sd = np.asarray(f), np.sqrt(np.asarray(var))

    def lengths(q):
        p = f + q * sd
        return np.array([np.linalg.norm(p[0:3] - p[3:6]) - lu, np.linalg.norm(p[3:6] - p[6:9]) - lf])

    res = minimize(lambda q: float(q @ q), (np.asarray(start) - f) / sd, jac=lambda q: 2.0 * q, method="SLSQP",
                   constraints=[{"type": "eq", "fun": lengths}], options={"ftol": 1e-15, "maxiter": 1000})
    if not (res.success and np.abs(lengths(res.x)).max() < 1e-9):
        return None
    return f + res.x * sd


def test_arm_projection_approximates_the_map_arm_with_exact_lengths():
    # Arms a filter produces (segments within 5 mm of the lengths, x, y known to 3-10 mm, depths to 3-10 cm),
    # against a general constrained solver started from the projection: two steps and the circle are at its minimum
    # to 0.003 mm in the median; the worst of these 60 is 1.5 mm away (4.7 mm of 200) (the steps stop before
    # converging: iterating to convergence moves the 10-clip summaries by at most 0.02 cm, see project_arm).
    rng = random.Random(5)
    lu, lf = 0.29, 0.26
    away = []
    while len(away) < 60:
        s = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(1.7, 2.3)])
        d = np.array([rng.gauss(0.0, 1.0) for _ in range(3)])
        e = s + d / np.linalg.norm(d) * (lu + rng.uniform(-0.005, 0.005))
        d = np.array([rng.gauss(0.0, 1.0) for _ in range(3)])
        w = e + d / np.linalg.norm(d) * (lf + rng.uniform(-0.005, 0.005))
        if np.linalg.norm(s - w) > 0.5:  # (near full extension the circle may not exist)
            continue
        var = [v for _ in range(3) for v in (rng.uniform(1e-5, 1e-4),) * 2 + (rng.uniform(1e-3, 1e-2),)]
        f = (*s, *e, *w)
        arm = project_arm(f, var, lu, lf, 1e-4, 11.8, 5e-5)
        assert math.dist(arm[:3], arm[3:6]) == pytest.approx(lu, abs=1e-12)
        assert math.dist(arm[3:6], arm[6:]) == pytest.approx(lf, abs=1e-12)
        want = _local_map_arm(f, [v + 5e-5 for v in var], lu, lf, arm)
        if want is not None:
            away.append(np.abs(np.array(arm) - want).max())
    assert np.median(away) < 5e-5 and max(away) < 0.01


def test_arm_projection_keeps_an_exact_arm_and_gates_an_inconsistent_one():
    s, e, w = np.array([0.18, 0.0, 2.0]), np.array([0.25, 0.25, 1.9]), np.array([0.3, 0.1, 1.7])
    lu, lf = float(np.linalg.norm(s - e)), float(np.linalg.norm(e - w))
    f = (*s, *e, *w)
    var = [1e-4, 1e-4, 2.5e-3] * 3
    np.testing.assert_allclose(project_arm(f, var, lu, lf, 1e-4, 11.8), f, atol=1e-12)
    g = list(f)
    g[5] -= 0.20  # the elbow 20 cm off in depth: far outside the variances
    assert project_arm(g, var, lu, lf, 1e-4, 11.8) is None
    arm = project_arm(g, var, lu, lf, 1e-4, math.inf)  # no gate: projected, the lengths exact
    assert math.dist(arm[:3], arm[3:6]) == pytest.approx(lu, abs=1e-12)
    assert math.dist(arm[3:6], arm[6:]) == pytest.approx(lf, abs=1e-12)
    assert project_arm((*s, *s, *w), [1e-4] * 9, lu, lf, 0.0, math.inf) is None  # a zero-length upper arm
    assert project_arm([float("nan")] * 9, var, lu, lf, 0.0, 11.8) is None


def test_arm_projection_meets_the_lengths_and_moves_the_uncertain_depths():
    s, e, w = (0.18, 0.0, 2.0), (0.2, 0.27, 2.05), (0.25, 0.5, 1.95)
    var = (1e-4, 1e-4, 1e-3, 1e-4, 1e-4, 4e-3, 1e-4, 1e-4, 2.5e-3)
    arm = project_arm((*s, *e, *w), var, 0.29, 0.26, 0.0, math.inf)
    assert math.dist(arm[:3], arm[3:6]) == pytest.approx(0.29, abs=1e-12)
    assert math.dist(arm[3:6], arm[6:]) == pytest.approx(0.26, abs=1e-12)
    moved = [abs(a - b) for a, b in zip(arm, (*s, *e, *w), strict=True)]
    assert max(moved[i] for i in (0, 1, 3, 4, 6, 7)) < 0.006  # x, y: at most 6 mm
    assert moved[5] > moved[2] and moved[5] > 0.02  # the least certain depth (the elbow's) moves most
    # 1.5 and 0.4 cm short: chi2 0.47 with a 1 cm calibration sigma (passes 0.5, not 0.4)
    assert project_arm((*s, *e, *w), var, 0.29, 0.26, 1e-4, 0.5) is not None
    assert project_arm((*s, *e, *w), var, 0.29, 0.26, 1e-4, 0.4) is None


def test_a_tested_arm_decides_the_lengths_test_and_the_filter_arm_is_projected():
    # The filter's arm fits the lengths (as an EKF's bone constraint makes it); the arm as measured, its 2D
    # wrist 8 cm off the joint towards the elbow at the same depth, reads the forearm 7.3 cm short: tested, it
    # fails the gate that the filter's arm passes. A tested arm that fits passes and the projection is the filter
    # arm's, bit for bit.
    s, e = np.array([0.18, 0.0, 2.0]), np.array([0.25, 0.25, 1.9])
    w = e + np.array([0.15, -0.2, -0.09])
    lu, lf = float(np.linalg.norm(s - e)), float(np.linalg.norm(e - w))
    var = [1e-5, 1e-5, 2e-4] * 3
    m = w.copy()
    m[:2] += 0.08 * (e - w)[:2] / np.linalg.norm((e - w)[:2])
    assert lf - np.linalg.norm(e - m) > 0.07
    f = (*s, *e, *w)
    assert project_arm(f, var, lu, lf, 1e-4, 11.8, 5e-5) is not None
    assert project_arm(f, var, lu, lf, 1e-4, 11.8, 5e-5, (*s, *e, *m)) is None
    g = list(f)
    g[8] += 0.01  # (the filter's wrist 1 cm off in depth: the arm it projects)
    assert project_arm(g, var, lu, lf, 1e-4, 11.8, 5e-5, f) == project_arm(g, var, lu, lf, 1e-4, 11.8, 5e-5)


def test_measured_arm_is_the_whole_arm_or_none():
    m = [float(i) for i in range(36)]
    assert measured_arm(m, (0, 6, 12)) == [0.0, 1.0, 2.0, 6.0, 7.0, 8.0, 12.0, 13.0, 14.0]
    m[14] = float("nan")
    assert measured_arm(m, (0, 6, 12)) is None and measured_arm(m, (3, 9, 15)) is not None
    assert measured_arm(None, (0, 6, 12)) is None


def test_offset_variance_is_added_to_each_variance():
    # offset_var gives the arm of the variances with the offset added by the caller (bit-identical).
    rng = random.Random(9)
    for _ in range(500):
        s, e, w = random_arm(rng)
        var = [rng.uniform(1e-5, 1e-2) for _ in range(9)]
        ov = rng.choice((5e-5, 2e-4))
        want = project_arm((*s, *e, *w), [x + ov for x in var], 0.29, 0.26, 0.0, 13.8)
        assert project_arm((*s, *e, *w), var, 0.29, 0.26, 0.0, 13.8, ov) == want
        want = project_forearm(s, (*e, *w), [x + ov for x in var[3:]], 0.29, 0.26)
        assert project_forearm(s, (*e, *w), var[3:], 0.29, 0.26, ov) == want


def test_elbow_variance_is_added_to_the_elbows_variances():
    rng = random.Random(12)
    for _ in range(300):
        s, e, w = random_arm(rng)
        var = [rng.uniform(1e-5, 1e-2) for _ in range(9)]
        ev = rng.uniform(1e-5, 1e-3)
        ov = rng.choice((0.0, 2e-4))
        bumped = [x + ov + ev if 3 <= i < 6 else x + ov for i, x in enumerate(var)]
        want = project_arm((*s, *e, *w), bumped, 0.29, 0.26, 0.0, 13.8)
        assert project_arm((*s, *e, *w), var, 0.29, 0.26, 0.0, 13.8, ov, None, ev) == want


def _measured_arms(seed, n, sigma_s, sigma_e, sigma_w, lu=0.29, lf=0.26, du=0.0):
    """``n`` measured arms (flat: shoulder, elbow, wrist), exact arms of random poses (the upper arm ``du`` longer than
    ``lu``) with isotropic landmark offsets of these standard deviations; the forearm mostly along the upper arm."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        s = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(1.8, 2.2)])
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        v = rng.normal(size=3) + 1.5 * u
        v /= np.linalg.norm(v)
        e = s + (lu + du) * u
        w = e + lf * v
        yield np.concatenate([s + rng.normal(0.0, sigma_s, 3), e + rng.normal(0.0, sigma_e, 3),
                              w + rng.normal(0.0, sigma_w, 3)]).tolist()


def _learnt(arms, alpha=0.003, offset_var=0.5e-4):
    acc, extra = [0.5 * offset_var, 0.5], 0.0
    for m in arms:
        extra = learn_elbow_offset(acc, m, 0, 3, 6, 0.29, 0.26, alpha, 0.05, offset_var)
    return extra


def test_the_elbows_offset_is_learnt_from_the_two_segments_misfits():
    # An elbow 2 cm off its joint (4e-4 m^2 per axis), the shoulder and the wrist 0.5 cm: the excess over the
    # projections' 0.5e-4 is learnt, about 3.5e-4.
    assert _learnt(_measured_arms(1, 4000, 0.005, 0.02, 0.005)) == pytest.approx(3.5e-4, rel=0.25)
    # The shoulder and the wrist 2 cm off, the elbow 0.5 cm: each misfits one segment, and their product is no
    # elbow's offset.
    assert _learnt(_measured_arms(2, 4000, 0.02, 0.005, 0.02)) < 0.5e-4
    # Nor is a calibrated length 3 cm short (a constant misfit of the upper arm).
    assert _learnt(_measured_arms(3, 4000, 0.005, 0.005, 0.005, du=0.03)) < 0.3e-4


def test_learn_elbow_offset_needs_a_whole_measured_arm_and_a_weight():
    arm = next(_measured_arms(4, 1, 0.0, 0.05, 0.0))
    acc = [2.5e-5, 0.5]
    assert learn_elbow_offset(acc, arm, 0, 3, 6, 0.29, 0.26, 0.0, 0.05, 0.5e-4) == 0.0 and acc == [2.5e-5, 0.5]
    for m in (None, [math.nan] + arm[1:]):
        assert learn_elbow_offset(acc, m, 0, 3, 6, 0.29, 0.26, 0.1, 0.05, 0.5e-4) == 0.0 and acc == [2.5e-5, 0.5]
    learn_elbow_offset(acc, arm, 0, 3, 6, 0.29, 0.26, 0.1, 0.05, 0.5e-4)
    assert acc != [2.5e-5, 0.5]
    acc = [1.0, 0.05]  # (too few arms that were not bent at a right angle: nothing added yet)
    assert learn_elbow_offset(acc, None, 0, 3, 6, 0.29, 0.26, 0.1, 0.05, 0.5e-4) == 0.0


def test_circle_pair_is_circle_point_twice():
    rng = random.Random(4)
    met = 0
    for _ in range(2000):
        w = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(1.7, 2.3))
        s = tuple(c + rng.gauss(0.0, 0.25) for c in w)
        p, p2 = (tuple(c + rng.gauss(0.0, 0.2) for c in w) for _ in range(2))
        if rng.random() < 0.05:
            p = tuple(a + 0.3 * (b - a) for a, b in zip(w, s, strict=True))  # on the axis
        want = circle_point(*w, *s, 0.26, 0.29, *p)
        got = circle_pair(*w, *s, 0.26, 0.29, p, p2)
        if want is None:
            assert got is None
        else:
            assert got == (want, circle_point(*w, *s, 0.26, 0.29, *p2))
            met += 1
    assert 500 < met < 2000


def test_same_configuration_compares_the_side_each_segment_points_to():
    arm = (0.0, 0.0, 2.0, 0.0, 0.29, 1.9, 0.0, 0.5, 2.05)  # upper arm towards the camera, forearm away
    assert same_configuration(arm, 2.1, 2.0, 2.2)  # the same signs, other depths
    assert not same_configuration(arm, 1.9, 2.0, 2.2)  # the upper arm mirrored
    assert not same_configuration(arm, 2.1, 2.0, 1.9)  # the forearm mirrored
    assert same_configuration(arm, 2.0, 2.0, 2.2)  # an upper arm in the image plane agrees with either side


def test_sphere_point_is_the_nearest_point_at_the_radius_in_the_metric():
    rng = random.Random(3)
    for _ in range(200):
        c = [rng.uniform(-1.0, 1.0) for _ in range(3)]
        p = [ci + rng.uniform(-0.5, 0.5) for ci in c]  # inside and outside the sphere
        v = [10 ** rng.uniform(-4.0, -1.0) for _ in range(3)]
        q = sphere_point(*c, *p, *v, 0.28)
        assert math.dist(q, c) == pytest.approx(0.28, abs=1e-12)
        # Stationary (KKT): the metric gradient (p - q) / v is parallel to the radius q - c ...
        g = [(p[i] - q[i]) / v[i] for i in range(3)]
        u = [q[i] - c[i] for i in range(3)]
        cross = (g[1] * u[2] - g[2] * u[1], g[2] * u[0] - g[0] * u[2], g[0] * u[1] - g[1] * u[0])
        assert math.hypot(*cross) <= 1e-7 * math.hypot(*g) * 0.28 + 1e-12
        # ... and a minimum: no point of a 2-degree ring about it on the sphere is nearer.
        cost = sum((q[i] - p[i]) ** 2 / v[i] for i in range(3))
        for k in range(12):
            a = 2 * math.pi * k / 12
            d = [u[0] + 0.01 * math.cos(a), u[1] + 0.01 * math.sin(a), u[2]]
            n = math.hypot(*d)
            other = [c[i] + d[i] * 0.28 / n for i in range(3)]
            assert sum((other[i] - p[i]) ** 2 / v[i] for i in range(3)) >= cost - 1e-12


def test_sphere_point_with_equal_variances_is_radial():
    q = sphere_point(0.0, 0.0, 2.0, 0.3, 0.4, 2.0, 0.01, 0.01, 0.01, 0.25)
    assert q == pytest.approx((0.15, 0.2, 2.0), abs=1e-12)
    # an anisotropic metric moves the surer axes less: depth sigma 10x the image's
    q = sphere_point(0.0, 0.0, 2.0, 0.3, 0.0, 2.2, 1e-4, 1e-4, 1e-2, 0.25)
    assert abs(q[0] - 0.3) < abs(0.3 * 0.25 / math.hypot(0.3, 0.2) - 0.3)


def _arm_with_the_elbow_read_in_front():
    """An arm 2 m away, the elbow 9 cm behind the shoulder and the forearm toward the camera (20 cm in depth); the
    elbow read 15 cm in front and the wrist 4 cm behind: (truth, read, variances, lu, lf). The forearm as read is
    nearly parallel to the image plane and 8.5 cm short."""
    lu, lf = 0.29, 0.26
    s = np.array([0.18, 0.0, 2.0])
    e = s + lu * np.array([-0.15, 0.94, 0.31]) / np.linalg.norm([-0.15, 0.94, 0.31])
    w = e + lf * np.array([-0.15, 0.6, -0.78]) / np.linalg.norm([-0.15, 0.6, -0.78])
    truth = (*s, *e, *w)
    read = (*s, e[0], e[1], e[2] - 0.15, w[0], w[1], w[2] + 0.04)
    v = (1e-5, 1e-5, 1e-4) + (1e-5, 1e-5, 1.5e-3) * 2  # (the shoulder's depth better known than the others')
    return tuple(map(float, truth)), tuple(map(float, read)), v, lu, lf


def test_an_elbow_projected_in_front_of_its_reading_takes_the_configuration_behind_it():
    truth, read, v, lu, lf = _arm_with_the_elbow_read_in_front()
    arm = project_arm(read, v, lu, lf, 0.0, math.inf, 5e-5)
    assert arm[5] < truth[5] - 0.2 and arm[5] < arm[2]  # the mirror: the elbow 22 cm off, in front of the shoulder
    alt = behind_surface(arm, read, v, lu, lf, read[5], 0.05, truth[5], 5e-5)
    assert alt[5] >= read[5] - 0.05 and alt[5] > alt[2]  # behind its reading, behind the shoulder
    assert math.dist(alt[3:6], truth[3:6]) < 0.015 and math.dist(alt[6:9], truth[6:9]) < 0.02
    assert math.dist(alt[0:3], alt[3:6]) == pytest.approx(lu, abs=1e-12)
    assert math.dist(alt[3:6], alt[6:9]) == pytest.approx(lf, abs=1e-12)
    # The shoulder kept (AKC+ starts the forearm's projection from the elbow at the upper arm's length from it,
    # radially): the projection from the candidate behind, the shoulder where it was.
    s, e = np.array(read[0:3]), np.array(read[3:6])
    start = (*read[0:5], float((s + 0.29 * (e - s) / np.linalg.norm(e - s))[2]), *read[6:9])
    fore = project_forearm(start[0:3], start[3:9], v[3:9], lu, lf, 5e-5)
    assert fore[5] < truth[5] - 0.2
    kept = behind_surface(fore, start, v, lu, lf, read[5], 0.05, truth[5], 5e-5, shoulder_kept=True)
    assert kept[0:3] == read[0:3] and kept[5] >= read[5] - 0.05
    assert math.dist(kept[3:6], truth[3:6]) < 0.015
    assert math.dist(kept[3:6], kept[6:9]) == pytest.approx(lf, abs=1e-12)


def test_behind_surface_switches_only_with_evidence():
    truth, read, v, lu, lf = _arm_with_the_elbow_read_in_front()
    arm = project_arm(read, v, lu, lf, 0.0, math.inf, 5e-5)
    # Our last elbow in front (nearer this arm's than the other configuration's): no switch.
    assert behind_surface(arm, read, v, lu, lf, read[5], 0.05, arm[5] - 0.02, 5e-5) is arm
    nan = float("nan")
    assert behind_surface(arm, read, v, lu, lf, nan, 0.05, truth[5], 5e-5) is arm  # no reading
    assert behind_surface(arm, read, v, lu, lf, read[5], 0.05, nan, 5e-5) is arm  # no last output
    assert behind_surface(arm, read, v, lu, lf, arm[5] + 0.04, 0.05, truth[5], 5e-5) is arm  # within the noise
    # The elbow's image position beyond the upper arm's reach of the shoulder: no candidate behind it.
    far = (*read[0:3], read[3] + 0.3, *read[4:9])
    assert behind_surface(arm, far, v, lu, lf, read[5], 0.05, truth[5], 5e-5) is arm


class _Memory(SurfaceMemory):
    """SurfaceMemory's rules on the attributes AKC+ gives them (``consistency_m`` 5 cm, ``arm_radius_m`` 5 cm)."""

    __slots__ = ("_cons", "_fs_r", "_read_e", "_v", "_verdict")

    def __init__(self, pose, read_e):
        self._cons, self._fs_r, self._read_e, self._v, self._verdict = 0.05, 0.05, list(read_e), pose, False


def _left_elbow_behind_the_chest():
    """A pose 2 m from the camera, the left elbow's pixel inside the torso's outline (behind the belly), as a flat
    list; and the elbow's flat offset."""
    p = np.full((12, 3), 5.0)  # (hands and the right arm far off)
    for name, xyz in (("left_shoulder", (0.18, 0.0, 2.0)), ("right_shoulder", (-0.18, 0.0, 2.0)),
                      ("left_hip", (0.12, 0.5, 2.0)), ("right_hip", (-0.12, 0.5, 2.0)),
                      ("left_elbow", (0.08, 0.27, 2.1)), ("left_wrist", (0.0, 0.5, 1.9))):
        p[INDEX[name]] = xyz
    return p.reshape(-1).tolist(), 3 * INDEX["left_elbow"]


def test_surface_memory_holds_a_verdict_while_the_same_surface_is_read_and_the_body_covers_the_pixel():
    v, o = _left_elbow_behind_the_chest()
    nan = float("nan")
    # No verdict: only an elbow in front of its reading beyond consistency_m is put behind it (behind_surface).
    mem = _Memory(v, (nan, nan))
    assert mem._surface_tol(0, 1.92, 1.85, o) == 0.05
    assert math.isnan(mem._surface_tol(0, 1.92, 1.92, o))
    # Last frame's verdict: the chest read at 1.92 m. The same surface now (1.90): an elbow at the reading (the
    # filter followed it) must go behind it beyond consistency_m (tol -5 cm) ...
    mem = _Memory(v, (1.92, nan))
    assert mem._surface_tol(0, 1.90, 1.90, o) == -0.05
    assert math.isnan(mem._surface_tol(1, 1.90, 1.90, o))  # (the other arm's memory is its own)
    # ... not one already behind it, nor once the pixel reads another surface (moved beyond consistency_m) ...
    assert math.isnan(mem._surface_tol(0, 1.90, 1.96, o))
    assert math.isnan(mem._surface_tol(0, 1.86, 1.86, o))
    # ... nor where nothing of the body can lie on the ray (the elbow raised to the side).
    side = list(v)
    side[o:o + 3] = [0.45, -0.1, 2.0]
    assert math.isnan(_Memory(side, (1.92, nan))._surface_tol(0, 1.90, 1.90, o))
    # The radial elbow of a lost wrist goes to the Pythagorean candidate behind the shoulder at its image x, y,
    # when that is behind the reading and nearer our last output's depth; the verdict is noted.
    s, lu = (0.18, 0.0, 2.0), 0.29
    e = (0.08, 0.27, 1.93)
    out = mem._behind_radial(0, o, s, e, 0.08, 0.27, 1.90, 2.10, lu)
    assert out[:2] == (0.08, 0.27) and out[2] == pytest.approx(2.0 + math.sqrt(lu**2 - 0.1**2 - 0.27**2))
    assert math.dist(s, out) == pytest.approx(lu) and mem._verdict
    mem = _Memory(v, (1.92, nan))
    assert mem._behind_radial(0, o, s, e, 0.08, 0.27, 1.90, 1.93, lu) is e and not mem._verdict  # last output in front
    # After the output: the reading is remembered only with a verdict, the elbow behind it beyond consistency_m.
    m = [nan] * 36
    m[o:o + 3] = [0.08, 0.27, 1.90]
    out9 = (*s, 0.08, 0.27, 2.06, 0.0, 0.5, 1.9)
    mem._remember_surface(0, out9, m, o)
    assert math.isnan(mem._read_e[0])
    mem._verdict = True
    mem._remember_surface(0, out9, m, o)
    assert mem._read_e[0] == 1.90
    mem._remember_surface(0, (*out9[:5], 1.93, *out9[6:]), m, o)
    assert math.isnan(mem._read_e[0])
    # Lost altogether (no x, y): the memory stays until the elbow is detected again.
    mem._remember_surface(0, out9, m, o)
    m[o:o + 3] = [nan, nan, nan]
    mem._verdict = False
    mem._remember_surface(0, out9, m, o)
    assert mem._read_e[0] == 1.90
