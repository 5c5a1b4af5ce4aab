import math

import numpy as np
import pytest

from akc_drake.core.arm_geometry import (
    DEFAULT_AXES,
    behind_hand,
    behind_reading,
    bends_backwards,
    body_covers,
    circle_nearest,
    circle_of,
    circle_point,
    circle_xy_pair,
    covered_excess,
    drop_unreadable,
    elbow_angle_deg,
    follow,
    nearest_depth,
    ray_check,
    segment_distance2,
    signed_elbow_angle_deg,
    straight_arm,
    torso_axes,
    turn_with,
)
from akc_drake.core.skeleton import INDEX


def _pose_facing_camera():
    v = np.zeros((12, 3))
    v[INDEX["left_shoulder"]] = [0.18, 0.0, 2.0]
    v[INDEX["right_shoulder"]] = [-0.18, 0.0, 2.0]
    v[INDEX["left_hip"]] = [0.12, 0.5, 2.0]
    v[INDEX["right_hip"]] = [-0.12, 0.5, 2.0]
    return v


def test_torso_axes_of_an_operator_facing_the_camera():
    front, down, lat = torso_axes(_pose_facing_camera().ravel().tolist())
    np.testing.assert_allclose(front, [0, 0, -1], atol=1e-12)  # towards the camera
    np.testing.assert_allclose(down, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(lat, [1, 0, 0], atol=1e-12)
    v = _pose_facing_camera()
    v[INDEX["left_hip"]] = np.nan
    assert torso_axes(v.ravel().tolist()) == DEFAULT_AXES


def test_signed_elbow_angle():
    # Arm hanging down, forearm forward (towards the camera): flexion, 90 deg.
    s, e = np.array([0.2, 0.0, 2.0]), np.array([0.2, 0.3, 2.0])
    assert signed_elbow_angle_deg(s, e, e + [0, 0, -0.25]) == pytest.approx(90.0)
    # Forearm bent backwards by 45 deg: hyperextension, theta = 360 - 135 = 225 deg (outside [40, 180]).
    w = e + 0.25 * np.array([0, np.cos(np.radians(45)), np.sin(np.radians(45))])
    assert elbow_angle_deg(s, e, w) == pytest.approx(135.0)
    assert signed_elbow_angle_deg(s, e, w) == pytest.approx(225.0)
    # Upper arm raised forwards (horizontal, towards the camera): the anterior side is up, so a forearm bent
    # upwards is flexion, whatever the torso's front.
    e2 = s + [0, 0, -0.3]
    assert signed_elbow_angle_deg(s, e2, e2 + [0, -0.25, 0]) == pytest.approx(90.0)
    assert not bends_backwards(0, 0, 1.0, 0, -0.25, 0, 0.25, DEFAULT_AXES)
    assert np.isnan(elbow_angle_deg(s, s, e))


def _arm():
    s, e, w = np.array([0.18, 0.0, 2.0]), np.array([0.25, 0.25, 1.9]), np.array([0.3, 0.1, 1.7])
    return s, e, w, float(np.linalg.norm(s - e)), float(np.linalg.norm(e - w))


def test_circle_point_is_at_both_lengths_and_nearest():
    s, e, w, lu, lf = _arm()
    p = circle_point(*w, *s, lf, lu, *(e + 0.01))
    assert np.linalg.norm(np.array(p) - w) == pytest.approx(lf, abs=1e-12)
    assert np.linalg.norm(np.array(p) - s) == pytest.approx(lu, abs=1e-12)
    assert np.linalg.norm(np.array(p) - e) < 0.02
    assert circle_point(*w, *(w + [2.0, 0, 0]), lf, lu, *e) is None


def test_circle_of_is_where_the_two_spheres_meet_and_circle_nearest_projects_onto_it():
    s, e, w, lu, lf = _arm()
    cx, cy, cz, nx, ny, nz, h = circle_of(*w, *s, lf, lu)
    c, n = np.array([cx, cy, cz]), np.array([nx, ny, nz])
    assert np.linalg.norm(n) == pytest.approx(1.0, abs=1e-15) and np.allclose(np.cross(n, s - w), 0.0, atol=1e-15)
    assert np.linalg.norm(np.cross(c - w, n)) < 1e-15  # (the centre on the wrist-shoulder line)
    for t in np.linspace(0.0, 2.0 * np.pi, 7):  # every point of the circle is at both lengths
        u = np.cross(n, [1.0, 0.0, 0.0])
        p = c + h * (math.cos(t) * u / np.linalg.norm(u) + math.sin(t) * np.cross(n, u / np.linalg.norm(u)))
        assert np.linalg.norm(p - w) == pytest.approx(lf, abs=1e-12)
        assert np.linalg.norm(p - s) == pytest.approx(lu, abs=1e-12)
    q = np.array(circle_nearest((cx, cy, cz, nx, ny, nz, h), *e))  # (e is on the circle: itself)
    assert np.linalg.norm(q - e) < 1e-12
    assert circle_of(*w, *(w + [2.0, 0, 0]), lf, lu) is None


def test_circle_xy_pair_is_at_both_lengths_and_keeps_a_reachable_image_position():
    s, e, w, lu, lf = _arm()
    q, q2 = circle_xy_pair(*w, *s, lf, lu, e[0], e[1])
    # The true elbow's x, y is on the circle's image: the nearest point has them exactly (the elbow itself or the
    # circle's other point with the same x, y, its mirror).
    for p in (q, q2):
        assert np.linalg.norm(np.array(p) - w) == pytest.approx(lf, abs=1e-12)
        assert np.linalg.norm(np.array(p) - s) == pytest.approx(lu, abs=1e-12)
    assert math.hypot(q[0] - e[0], q[1] - e[1]) < 1e-7
    assert min(np.linalg.norm(np.array(p) - e) for p in (q, q2)) < 1e-6
    assert circle_xy_pair(*w, *(w + [2.0, 0, 0]), lf, lu, *e[:2]) is None  # (no circle: out of reach)


def test_circle_xy_pair_finds_the_nearest_points_where_eq_7_8_has_none():
    # An image position farther from the wrist's than the forearm is long (eq. 7-8 has no depth for it): the
    # nearest points of the circle in x, y, against a dense sampling of the circle.
    rng = np.random.default_rng(3)
    lu, lf, found = 0.29, 0.27, 0
    for _ in range(300):
        s, w = rng.normal(size=3) * 0.2 + [0, 0, 2.0], rng.normal(size=3) * 0.2 + [0, 0, 2.0]
        p = w[:2] + rng.normal(size=2) * 0.3
        d = float(np.linalg.norm(s - w))
        got = circle_xy_pair(*w, *s, lf, lu, *p)
        if not abs(lf - lu) < d < lf + lu:
            assert got is None
            continue
        n = (s - w) / d
        a = (d * d + lf * lf - lu * lu) / (2 * d)
        u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        t = np.linspace(0, 2 * np.pi, 20000)[:, None]
        circle = w + a * n + math.sqrt(lf * lf - a * a) * (np.cos(t) * u + np.sin(t) * np.cross(n, u))
        xy2 = ((circle[:, :2] - p) ** 2).sum(1)
        q, q2 = (np.array(x) for x in got)
        assert ((q[:2] - p) ** 2).sum() <= xy2.min() + 1e-12
        assert ((q[:2] - p) ** 2).sum() <= ((q2[:2] - p) ** 2).sum()
        for x in (q, q2):
            assert np.linalg.norm(x - s) == pytest.approx(lu, abs=1e-12)
            assert np.linalg.norm(x - w) == pytest.approx(lf, abs=1e-12)
        found += math.hypot(*(p - w[:2])) > lf
    assert found > 100  # (most positions beyond the forearm's reach: 155 of 234 circles)


def test_covered_excess_is_a_limbs_radius_over_the_sine_of_its_angle_to_the_line_of_sight():
    r, length = 0.05, 0.28
    e = np.array([0.2, 0.1, 2.0])
    for deg in (20.0, 35.0, 60.0):  # the forearm turned towards the camera, deg from the line of sight
        t = math.radians(deg)
        w = e + length * np.array([math.sin(t), 0.0, -math.cos(t)])
        want = min(r * (1.0 / math.sin(t) - 1.0), length)
        assert covered_excess(*e, *w, length, r) == pytest.approx(want, rel=1e-12)
    assert covered_excess(*e, *(e + [0.0, 0.0, -length]), length, r) == pytest.approx(length)  # (end-on: capped)
    assert covered_excess(*e, *(e + [0.2, 0.0, 0.19]), length, r) == 0.0  # (the wrist behind: nothing covers e)
    assert covered_excess(*e, *(e + [0.3, 0.0, -0.01]), length, r) == 0.0  # (longer than l in x, y)
    assert covered_excess(*e, 0.3, 0.1, float("nan"), length, r) == 0.0  # (no depth)


def test_drop_unreadable_sets_rows_nearer_than_any_camera_reads_nan():
    m = [0.1, 0.2, 2.0, 0.3, 0.4, 0.005, 0.5, 0.6, float("nan"), 0.7, 0.8, -1.0]
    drop_unreadable(m)
    assert m[:3] == [0.1, 0.2, 2.0]
    assert all(math.isnan(x) for x in m[3:6] + m[8:9] + m[9:12]) and m[6:8] == [0.5, 0.6]


def test_rebuild_variance_first_order_far_from_the_image_plane_and_bounded_on_it():
    from akc_drake.core.arm_geometry import rebuild_variance

    vxy, vl, vaz, length = 1e-4, 1e-4, 2e-3, 0.29
    # A segment 60 deg out of the image plane: dz = l sin 60; the first-order propagation.
    dxy = length * 0.5
    dz2 = length**2 - dxy**2
    first = vaz + (dxy**2 * 2 * vxy + length**2 * vl) / dz2
    got = rebuild_variance(0.0, 0.0, vxy, vxy, vaz, dxy, 0.0, vxy, vxy, length, vl)
    assert got == pytest.approx(first, rel=0.1)
    assert got > vaz
    # In the plane (and out of reach) the first order diverges; the rebuilt depth is still within about
    # sqrt(sd(dz^2)) of the anchor's: a Monte Carlo of z = sqrt(max(l^2 - dx^2, 0)) agrees within a factor 2.
    rng = np.random.default_rng(0)
    n = 20000
    for dx in (length, length + 0.01):
        x = dx + rng.normal(0.0, np.sqrt(2 * vxy), n)
        lk = length + rng.normal(0.0, np.sqrt(vl), n)
        mc = float(np.mean(np.maximum(lk**2 - x**2, 0.0)))  # E[dz^2] about the anchor (true dz ~ 0)
        v = rebuild_variance(0.0, 0.0, vxy, vxy, 0.0, dx, 0.0, vxy, vxy, length, vl)
        assert np.isfinite(v) and 0.5 * mc < v < 2.0 * mc


def test_rebuild_variance_adds_the_mirror_candidates_risk():
    from math import erfc, sqrt

    from akc_drake.core.arm_geometry import rebuild_variance

    vxy, vl, length, dxy = 1e-4, 1e-4, 0.29, 0.25
    base = rebuild_variance(0.0, 0.0, vxy, vxy, 1e-3, dxy, 0.0, vxy, vxy, length, vl)
    dz2 = length**2 - dxy**2
    for prior in (1e-4, 2.5e-3, 0.04):
        got = rebuild_variance(0.0, 0.0, vxy, vxy, 1e-3, dxy, 0.0, vxy, vxy, length, vl, prior)
        # P(wrong candidate) = Phi(-dz / sd), at (2 dz)^2.
        assert got - base == pytest.approx(0.5 * erfc(sqrt(dz2 / prior) / sqrt(2)) * 4 * dz2, rel=1e-9)
    # A sure prior never picks the mirror; a vague one does half the time.
    assert rebuild_variance(0.0, 0.0, vxy, vxy, 1e-3, dxy, 0.0, vxy, vxy, length, vl, 1e-8) == pytest.approx(base)
    vague = rebuild_variance(0.0, 0.0, vxy, vxy, 1e-3, dxy, 0.0, vxy, vxy, length, vl, 1e6)
    assert vague - base == pytest.approx(2 * dz2, rel=1e-3)


def _ray_case():
    """An arm's offsets and measurement (shoulder, elbow, wrist first in the flat 36, the rest NaN), its
    variances, and ``ray_check``'s further arguments: the filter's flat variances (P), the image's and the depth's
    R, the innovation gate squared and the chi2 gate."""
    nan = float("nan")
    m = [0.18, 0.0, 2.0, 0.3, 0.2, 1.9, 0.35, 0.4, 1.7] + [nan] * 27
    var = [1e-4, 1e-4, 1e-3] * 3
    return (0, 3, 6), m, var, (var + [1e-4] * 27, 1e-4, 2.5e-3, 9.0, 11.8)


def test_ray_check_takes_the_measurement_only_off_the_measured_ray():
    offs, m, var, args = _ray_case()
    nan = float("nan")
    # The filter's shoulder on the measured ray but 30 cm deeper (an occluder's depth measured): kept.
    f = [0.18 * 2.3 / 2.0, 0.0, 2.3] + m[3:9]
    vs = list(var)
    ray_check(m, offs, f, vs, *args)
    assert f[:3] == [0.18 * 2.3 / 2.0, 0.0, 2.3] and vs == var
    # The filter's shoulder 10 cm off the ray in y: the measured point and its variances replace it.
    f = [0.18, 0.10, 2.3] + m[3:9]
    ray_check(m, offs, f, vs, *args)
    assert f[:3] == m[:3] and vs[:3] == [1e-4, 1e-4, 2.5e-3] and vs[3:] == var[3:]
    # Off the ray but the depth passes the innovation test (2 cm): the test has nothing to decide.
    f = [0.18, 0.10, 2.02] + m[3:9]
    ray_check(m, offs, f, list(var), *args)
    assert f[:3] == [0.18, 0.10, 2.02]
    # A diverged filter's shoulder behind the camera (no ray to compare): the measured point replaces it.
    f = [-0.09, 0.44, -0.035] + m[3:9]
    vs = list(var)
    ray_check(m, offs, f, vs, *args)
    assert f[:3] == m[:3] and vs[:3] == [1e-4, 1e-4, 2.5e-3]
    # A joint without a measured depth is left alone.
    m2 = list(m)
    m2[2] = nan
    f = [0.18, 0.10, 2.3] + m[3:9]
    ray_check(m2, offs, f, list(var), *args)
    assert f[:3] == [0.18, 0.10, 2.3]


def test_ray_check_takes_the_measurement_that_agrees_with_our_last_output_against_a_filter_that_jumped():
    # An EKF whose constraints swing a seen shoulder 30 cm deeper in one frame, on the measured ray: the measured
    # depth agrees with our last output (within ``agree``), the filter is beyond the gate of R from it, so the
    # measurement replaces it. Without our last output, or with a measurement off it, the on-ray rule keeps it.
    offs, m, var, args = _ray_case()
    prev = (0.18, 0.0, 2.02, 0.3, 0.2, 1.9, 0.35, 0.4, 1.7)
    f = [0.18 * 2.3 / 2.0, 0.0, 2.3] + m[3:9]
    vs = list(var)
    ray_check(m, offs, f, vs, *args, prev, 0.05)
    assert f[:3] == m[:3] and vs[:3] == [1e-4, 1e-4, 2.5e-3]
    for p, agree in ((None, 0.05), ((0.18, 0.0, 2.1, *prev[3:]), 0.05)):
        f = [0.18 * 2.3 / 2.0, 0.0, 2.3] + m[3:9]
        ray_check(m, offs, f, list(var), *args, p, agree)
        assert f[2] == 2.3
    # a filter within the gate of our last output (3 sigma of R = 15 cm) has not jumped: kept too
    f = [0.18 * 2.12 / 2.0, 0.0, 2.12] + m[3:9]
    ray_check(m, offs, f, list(var), *args, prev, 0.05)
    assert f[2] == 2.12


def test_ray_check_takes_a_depth_behind_a_filter_that_moved_in_front_of_our_last_output():
    # An EKF whose bone constraint pulls a seen shoulder 14 cm in front (1.86 m), on the ray; the depth read
    # (2.0 m) is behind it, where no occluder reads, and 8 cm from our last output (2.08 m), nearer it than the
    # filter: the measurement replaces the filter. A reading behind that our last output does not support (it was
    # at the filter's depth: a pixel on the torso behind), or no last output (a KF), stays rejected.
    offs, m, var, args = _ray_case()
    filt = [0.18 * 1.86 / 2.0, 0.0, 1.86] + m[3:9]
    f, vs = list(filt), list(var)
    ray_check(m, offs, f, vs, *args, (0.18, 0.0, 2.08, *m[3:9]), 0.05)
    assert f[:3] == m[:3] and vs[:3] == [1e-4, 1e-4, 2.5e-3] and vs[3:] == var[3:]
    for prev in ((0.18 * 1.86 / 2.0, 0.0, 1.86, *m[3:9]), None):
        f = list(filt)
        ray_check(m, offs, f, list(var), *args, prev, 0.05)
        assert f == filt


def test_behind_hand_puts_a_wrist_its_hand_hides_a_hands_length_behind_the_knuckles():
    # The forearm points straight at the camera; the wrist's pixel reads the hand at 2.00 m, the knuckles' midpoint
    # 3 cm aside in the image at 1.98 m: the wrist is sqrt(8.5^2 - 3^2) = 7.953 cm behind the knuckles.
    k = behind_hand(0.0, 0.0, 2.3, 0.0, 0.0, 2.0, 0.03, 0.0, 1.98, 0.085)
    assert k * 2.0 == pytest.approx(1.98 + np.sqrt(0.085**2 - 0.03**2), abs=1e-12)
    # Halfway between the shares 0.5 and 0.8 of the forearm along the ray: half the move.
    fz = -0.65 / np.sqrt(1 - 0.65**2)  # (forearm (1, 0, fz): share 0.65)
    k_half = behind_hand(-0.1, 0.0, 2.0 - 0.1 * fz, 0.0, 0.0, 2.0, 0.03, 0.0, 1.98, 0.085)
    assert (k_half - 1.0) == pytest.approx(0.5 * (k - 1.0), rel=1e-9)
    # At most a hand's length either way: knuckles read 30 cm in front (a depth off the hand).
    assert behind_hand(0.0, 0.0, 2.3, 0.0, 0.0, 2.0, 0.0, 0.0, 1.70, 0.085) * 2.0 == pytest.approx(1.915, abs=1e-12)
    # Left as it is: a forearm across the image, knuckles more than a hand's length behind the wrist (their depth
    # failed), anything NaN.
    assert behind_hand(-0.28, 0.0, 2.0, 0.0, 0.0, 2.0, 0.03, 0.0, 1.98, 0.085) == 1.0
    assert behind_hand(0.0, 0.0, 2.3, 0.0, 0.0, 2.0, 0.03, 0.0, 2.09, 0.085) == 1.0
    nan = float("nan")
    for args in ((nan, 0.0, 2.3), (0.0, 0.0, nan)):
        assert behind_hand(*args, 0.0, 0.0, 2.0, 0.03, 0.0, 1.98, 0.085) == 1.0
    assert behind_hand(0.0, 0.0, 2.3, 0.0, 0.0, 2.0, 0.03, 0.0, nan, 0.085) == 1.0
    assert behind_hand(0.0, 0.0, 2.3, 0.0, 0.0, nan, 0.03, 0.0, 1.98, 0.085) == 1.0


def test_turn_with_is_the_smallest_rotation_between_two_directions():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    for _ in range(20):
        a, b, v = rng.normal(size=(3, 3))
        a *= rng.uniform(0.1, 3.0)  # (any lengths: only the directions count)
        axis = np.cross(a, b)
        angle = np.arctan2(np.linalg.norm(axis), a @ b)
        want = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).apply(v)
        np.testing.assert_allclose(turn_with(*v, *a, *b), want, atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(turn_with(*v, *a, *b)), np.linalg.norm(v), rtol=1e-12)
    # A vector along the axis stays; one along a goes along b with its length; no turn leaves v as it is.
    np.testing.assert_allclose(turn_with(0.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 2.0), atol=1e-15)
    np.testing.assert_allclose(turn_with(0.26, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 3.0, 0.0), (0.0, 0.26, 0.0), atol=1e-15)
    assert turn_with(0.1, 0.2, 0.3, 1.0, 2.0, 3.0, 2.0, 4.0, 6.0) == pytest.approx((0.1, 0.2, 0.3), abs=1e-15)
    # Undefined turns leave v as it is: a zero direction, a NaN, a half turn.
    assert turn_with(0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0) == (0.1, 0.2, 0.3)
    assert turn_with(0.1, 0.2, 0.3, np.nan, 0.0, 0.0, 1.0, 0.0, 0.0) == (0.1, 0.2, 0.3)
    assert turn_with(0.1, 0.2, 0.3, 1.0, 0.0, 0.0, -2.0, 0.0, 0.0) == (0.1, 0.2, 0.3)


def test_behind_reading_takes_the_point_nearer_the_reading_one_in_front_counting_twice():
    # The points at 0.25 from the elbow (0, 0, 1.75) with the wrist's x, y (0.07, 0): depths 1.75 +- 0.24.
    dz = math.sqrt(0.25**2 - 0.07**2)
    behind, front = (0.07, 0.0, 1.75 + dz), (0.07, 0.0, 1.75 - dz)
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.76, 0.25) == pytest.approx(behind)  # (the forearm's surface)
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.52, 0.25) == pytest.approx(front)  # (at the joint)
    # the reading behind the front point (0.1) or in front of both (0.2): the nearer, the front one
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.75 - dz + 0.1, 0.25) == pytest.approx(front)
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.75 - dz - 0.2, 0.25) == pytest.approx(front)
    # between them: the behind point 0.27 away against the front one 0.21 in front of the reading, counting 0.42
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.72, 0.25) == pytest.approx(behind)
    # nearer the front point by more than half: 0.45 against 0.03 in front (0.06)
    assert behind_reading(0.0, 0.0, 1.75, 0.07, 0.0, 1.75 - dz + 0.03, 0.25) == pytest.approx(front)
    assert behind_reading(0.0, 0.0, 1.75, 0.3, 0.0, 1.75, 0.25) is None  # (beyond the length in x, y)


def test_nearest_depth_keeps_x_y_and_takes_the_depth_nearer_the_joints_own():
    # A shoulder the filter has 90 cm behind its seen elbow (0.21, -0.05, 1.59), upper arm 0.293: the two points
    # with its x, y at that length are 1.59 +- 0.281; the one behind is nearer its own depth.
    e, s = (0.207, -0.052, 1.588), (0.126, -0.064, 2.714)
    dz = math.sqrt(0.293**2 - (s[0] - e[0]) ** 2 - (s[1] - e[1]) ** 2)
    got = nearest_depth(*e, *s, 0.293)
    assert got == pytest.approx((s[0], s[1], e[2] + dz))
    assert math.dist(got, e) == pytest.approx(0.293, abs=1e-12)
    # the same shoulder 40 cm in front of the elbow: the point in front
    assert nearest_depth(*e, s[0], s[1], 1.2, 0.293) == pytest.approx((s[0], s[1], e[2] - dz))
    # x, y out of reach of the length: as ``follow`` (moved towards the elbow)
    far = (0.6, -0.064, 2.0)
    assert nearest_depth(*e, *far, 0.293) == pytest.approx(follow(*e, *far, 0.293))
    assert math.dist(nearest_depth(*e, *far, 0.293), e) == pytest.approx(0.293, abs=1e-12)


def test_segment_distance2_is_to_the_nearest_point_of_the_segment_in_the_image():
    # elbow (0, 0), wrist (0.3, 0): a shoulder above the forearm's middle, beyond each end, and on it
    assert segment_distance2(0.1, 0.05, 0.0, 0.0, 0.3, 0.0) == pytest.approx(0.05**2)
    assert segment_distance2(-0.03, 0.04, 0.0, 0.0, 0.3, 0.0) == pytest.approx(0.05**2)  # (nearest the elbow)
    assert segment_distance2(0.34, -0.03, 0.0, 0.0, 0.3, 0.0) == pytest.approx(0.05**2)  # (nearest the wrist)
    assert segment_distance2(0.2, 0.0, 0.0, 0.0, 0.3, 0.0) == pytest.approx(0.0, abs=1e-15)
    # a forearm pointing at the camera (both ends on one pixel): the distance to that point
    assert segment_distance2(0.03, 0.04, 0.1, 0.1, 0.1, 0.1) == pytest.approx(0.07**2 + 0.06**2)


def _covers(pose, joint, side, r=0.05):
    return body_covers(pose.reshape(-1).tolist(), 3 * INDEX[joint], side, r)


def test_body_covers_an_elbow_inside_the_torsos_outline_or_near_another_limb_or_a_hand():
    # The torso 36 cm wide at the shoulders, 24 at the hips, 50 cm tall, 2 m from the camera; the hands far away.
    v = np.full((12, 3), np.nan)
    v[:10] = [1.0, 1.0, 2.0]
    v[:4] = _pose_facing_camera()[:4]
    v[[INDEX["left_hip"], INDEX["right_hip"]]] = _pose_facing_camera()[[INDEX["left_hip"], INDEX["right_hip"]]]
    v[INDEX["right_elbow"]], v[INDEX["right_wrist"]] = [-0.45, 0.0, 2.0], [-0.70, 0.0, 2.0]  # (the right arm out)
    le = INDEX["left_elbow"]
    v[le] = [0.05, 0.25, 2.2]  # behind the belly, its pixel inside the outline
    assert _covers(v, "left_elbow", 0)
    v[le] = [0.20, 0.25, 2.0]  # 5 cm outside the edge (x 0.15 at this height), 4.96 cm from it: within r = 5 cm
    assert _covers(v, "left_elbow", 0)
    assert not _covers(v, "left_elbow", 0, r=0.04)
    v[le] = [0.40, 0.25, 2.0]  # out to the side: nothing in front
    assert not _covers(v, "left_elbow", 0)
    v[le] = [0.05, 0.25, 1.0]  # the same pixel as (0.1, 0.5) at 2 m: the image decides, not the metric position
    assert _covers(v, "left_elbow", 0)
    v[le] = [0.40, 0.25, 2.0]
    v[INDEX["right_wrist"]] = [0.40, 0.30, 1.7]  # the other forearm passes 7 cm from it in the image ...
    assert _covers(v, "left_elbow", 0)  # ... within two radii (10 cm at its depth)
    v[INDEX["right_wrist"]] = [0.40, 0.36, 1.7]  # ... 13 cm: not
    assert not _covers(v, "left_elbow", 0)
    v[INDEX["right_wrist"]] = [-0.70, 0.0, 2.0]
    v[INDEX["left_index"]] = [0.37, 0.23, 1.85]  # its own hand's knuckles in front of it
    assert _covers(v, "left_elbow", 0)
    v[INDEX["left_index"]] = [1.0, 1.0, 2.0]
    assert not _covers(v, "left_elbow", 0)
    v[INDEX["left_hip"]] = np.nan  # a torso not known cannot be ruled out
    assert _covers(v, "left_elbow", 0)


def test_straight_arm_reaches_towards_a_wrist_beyond_the_arm():
    s, lu, lf = (-0.16, -0.05, 2.49), 0.29, 0.27
    # Within reach: a circle of elbows exists, no straight arm.
    assert straight_arm(*s, -0.2, 0.45, 2.5, lu, lf) is None
    assert circle_of(-0.2, 0.45, 2.5, *s, lf, lu) is not None
    # 2 cm beyond, pointing away from the camera: the wrist keeps its x, y at the depth nearest its own that reaches
    # (2.3 cm nearer; as ``follow``, which moves it radially when that would move it much farther).
    w = (-0.16, 0.30, 2.95)
    arm = straight_arm(*s, *w, lu, lf)
    assert arm[6:8] == pytest.approx(w[:2], abs=1e-12)
    assert w[2] - arm[8] == pytest.approx(2.95 - 2.49 - math.sqrt(0.56**2 - 0.35**2), abs=1e-12)
    # Beyond in the image plane itself (no depth reaches): radially, towards the shoulder.
    far = (-0.16, 0.60, 2.49)
    arm_far = straight_arm(*s, *far, lu, lf)
    assert arm_far[6:] == pytest.approx((-0.16, -0.05 + lu + lf, 2.49), abs=1e-12)
    for a in (arm, arm_far):
        sh, el, wr = np.array(a[0:3]), np.array(a[3:6]), np.array(a[6:9])
        assert tuple(sh) == s
        assert np.linalg.norm(el - sh) == pytest.approx(lu, abs=1e-12)
        assert np.linalg.norm(wr - el) == pytest.approx(lf, abs=1e-12)
        assert np.cross(el - sh, wr - sh) == pytest.approx(np.zeros(3), abs=1e-12)  # (straight)
