import math
import random

import pytest

from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
from akc_drake.core.akc_plus_search import BACKWARDS
from akc_drake.core.arm_geometry import bends_backwards, torso_axes
from akc_drake.core.skeleton import INDEX, BodyDimensions
from tests.test_akc_plus_lengths import random_arm

DIMS = BodyDimensions(LUA=0.29, LLA=0.26, RUA=0.29, RLA=0.26, SW=0.36)


def corrector():
    """A corrector mid-frame: no filter prior left out, the filter's elbow/shoulder depth variance 1e-2."""
    akc = ArmKinematicCorrectorPlus(DIMS)
    v = [0.0] * 36
    v[3 * INDEX["left_hip"] + 2] = v[3 * INDEX["right_hip"] + 2] = math.nan  # no torso depth term
    akc._v0 = v
    akc._axes = None
    akc._no_prior = set()
    akc._cur_var = [1e-2] * 9
    return akc


def test_penalty_of_a_folded_and_of_a_bent_elbow():
    akc = corrector()
    s, e = (0.18, 0.0, 2.0), (0.18, 0.29, 2.0)
    a = math.radians(30.0)  # folded to 30 deg, below elbow_min_deg (40)
    assert akc._penalty(s, e, (0.18 + 0.26 * math.sin(a), 0.29 - 0.26 * math.cos(a), 2.0), 0.29, 0.26) == BACKWARDS
    assert akc._penalty(s, e, (0.18, 0.55, 2.0), 0.29, 0.26) == 0.0  # straight down
    assert akc._penalty(s, e, (0.18, 0.29, 1.74), 0.29, 0.26) == 0.0  # forearm towards the camera


def test_lazy_elbow_choice_is_the_full_cost_choice():
    # _choose_elbow computes the anatomical penalty only for a candidate that can still win; over random
    # candidates it picks exactly what _choose picks with every extra term computed.
    rng = random.Random(3)
    akc = corrector()
    s, w = (0.18, 0.0, 2.0), (0.3, 0.45, 1.9)
    for _ in range(300):
        cands = [tuple(rng.uniform(-0.3, 0.3) + c for c in (0.2, 0.25, 2.0)) for _ in range(rng.choice((2, 3)))]
        f = tuple(rng.uniform(-0.3, 0.3) + c for c in (0.2, 0.25, 2.0))
        prev = None if rng.random() < 0.3 else tuple(rng.uniform(-0.3, 0.3) + c for c in (0.2, 0.25, 2.0))
        inv_w2 = None if rng.random() < 0.5 else 400.0
        extra = []
        for c in cands:
            x = 0.0 if inv_w2 is None else (math.dist(c, w) - 0.26) ** 2 * inv_w2
            extra.append(x + akc._penalty(s, c, w, 0.29, 0.26))
        want, _ = akc._choose(cands, *f, prev, 0, extra)
        assert akc._choose_elbow(cands, *f, prev, 0, s, w, 0.29, 0.26, inv_w2) is want


def test_a_left_out_prior_lets_continuity_choose():
    akc = corrector()
    akc._cur_var[5] = 1e-3  # the elbow's depth: sd 3.2 cm
    near_prev, near_filter = (0.2, 0.3, 2.2), (0.2, 0.3, 1.9)
    prev = (0.2, 0.3, 2.21)
    assert akc._choose([near_prev, near_filter], 0.2, 0.3, 1.9, prev, 0)[0] == near_filter  # 90 + 0.01 against 0 + 9.6
    akc._no_prior = {0}
    assert akc._choose([near_prev, near_filter], 0.2, 0.3, 1.9, prev, 0)[0] == near_prev


def test_rebuild_from_the_wrist_has_the_calibrated_lengths_and_follows_the_filter():
    akc = corrector()
    w = (0.3, 0.45, 1.9)
    f = (0.18, 0.0, 2.05, 0.25, 0.22, 2.08)  # filter's shoulder and elbow, both segments a few cm off
    s, e = akc._rebuild_from_wrist(f, w, None, None, 0, 1, 0.29, 0.26, True, True, None)
    assert math.dist(e, w) == pytest.approx(0.26, abs=1e-12)
    assert math.dist(s, e) == pytest.approx(0.29, abs=1e-12)
    assert e[:2] == f[3:5] and s[:2] == f[:2]  # eq. 7-8 keep the detected x, y
    # The candidates nearest the filter's depths: the elbow 11 cm behind the wrist (the mirror 11 cm in front).
    dz = math.sqrt(0.26**2 - 0.05**2 - 0.23**2)
    assert e[2] == pytest.approx(1.9 + dz, abs=1e-12)
    dz = math.sqrt(0.29**2 - 0.07**2 - 0.22**2)
    assert s[2] == pytest.approx(e[2] + dz, abs=1e-12)
    s2, e2 = akc._rebuild_shoulder(f, w, None, 1, 0.29, 0.26, True, None)
    assert math.dist(e2, w) == pytest.approx(0.26, abs=1e-12) and math.dist(s2, e2) == pytest.approx(0.29, abs=1e-12)
    assert s2[:2] == f[:2] and e2[:2] != f[3:5]  # the elbow moved radially, the shoulder's x, y kept
    mirror = 2.0 * e2[2] - s2[2]  # eq. 8's other candidate
    assert abs(s2[2] - f[2]) == pytest.approx(0.1213, abs=1e-4) and abs(mirror - f[2]) > 0.13


def test_a_rebuilt_shoulder_is_not_put_in_front_of_the_depth_its_pixel_reads():
    # An arm pointing at the camera (shoulder 2.0 m, elbow 1.75, wrist 1.5, nearly on one pixel), the elbow's depth
    # lost and its previous output in front of the wrist (the mirror configuration), the filter's priors left out:
    # continuity alone rebuilds the arm folded in front. The depth measured at the shoulder's pixel (2.03 m: its
    # surface, or its upper arm's) is a floor: the shoulder and so the elbow go behind.
    akc = corrector()
    akc._no_prior = {0, 1}
    w = (0.0, 0.02, 1.5)
    f = (0.0, 0.0, 2.0, 0.0, 0.01, 1.75)
    pe, ps = (0.0, 0.01, 1.25), (0.0, 0.0, 1.0)
    s, e = akc._rebuild_from_wrist(f, w, pe, ps, 0, 1, 0.29, 0.26, True, True, None)
    assert e[2] < w[2] and s[2] < 1.5  # (continuity: the mirror)
    akc._s_floor = 2.03
    s, e = akc._rebuild_from_wrist(f, w, pe, ps, 0, 1, 0.29, 0.26, True, True, None)
    assert e[2] > w[2] and s[2] > 1.95
    assert math.dist(e, w) == pytest.approx(0.26, abs=1e-12) and math.dist(s, e) == pytest.approx(0.29, abs=1e-12)
    # A candidate behind the floor costs nothing more.
    c = (0.0, 0.0, 2.2)
    base = akc._shoulder_cost(c, e, w, *f[:3], None, 0.0, 0.29, 0.26, None)
    akc._s_floor = float("nan")
    assert akc._shoulder_cost(c, e, w, *f[:3], None, 0.0, 0.29, 0.26, None) == base


def test_penalty_is_the_angle_test_and_bends_backwards():
    # _penalty inlines bends_backwards: the same verdict as the reference functions over random arms.
    rng = random.Random(8)
    akc = corrector()
    v = [rng.uniform(-0.3, 0.3) for _ in range(36)]
    for i in range(2, 36, 3):
        v[i] += 2.0
    akc._v0 = v
    axes = torso_axes(v)
    cos_min = math.cos(math.radians(akc.config.elbow_min_deg))
    verdicts = set()
    for _ in range(3000):
        s, e, w = random_arm(rng)
        u = [(a - b) / 0.29 for a, b in zip(s, e, strict=True)]
        f = [a - b for a, b in zip(w, e, strict=True)]
        folded = ((s[0] - e[0]) * f[0] + (s[1] - e[1]) * f[1] + (s[2] - e[2]) * f[2]) / (0.29 * 0.26) > cos_min
        want = BACKWARDS if folded or bends_backwards(*u, *f, 0.26, axes) else 0.0
        got = akc._penalty(s, e, w, 0.29, 0.26)
        assert got == want
        verdicts.add((folded, got))
    assert verdicts == {(True, BACKWARDS), (False, BACKWARDS), (False, 0.0)}


def test_other_shoulder_is_the_last_seen_output_else_the_filtered_one():
    akc = corrector()
    v = [0.1 * i for i in range(36)]
    akc._v = v
    o_left = akc._offsets[0][0]
    akc._prev = [None, None]
    assert akc._other_shoulder(1) == tuple(v[o_left : o_left + 3])  # no output yet: the filtered one
    v[o_left + 2] = math.nan
    assert akc._other_shoulder(1) is None  # not known at all
    right = tuple(0.5 + 0.01 * i for i in range(9))
    akc._prev = [None, right]
    akc._lost = [0.0, 0.0, 0.0, 0.0]
    assert akc._other_shoulder(0) == right[:3]  # the right shoulder's last output, seen when last corrected
    akc._lost[3] = 2.0
    assert akc._other_shoulder(0) is None  # rebuilt when last corrected: no evidence for the width
