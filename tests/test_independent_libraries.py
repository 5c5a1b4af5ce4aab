"""Our hand-written numerics checked against independent, well-kept libraries on random data.

* BVH rotations and forward kinematics against scipy's ``Rotation`` (intrinsic Euler sequences) and against
  ``pybvh`` reading the same file;
* ASF/AMC forward kinematics (Acclaim's ``G = G_parent C M C^-1``) against scipy's ``Rotation`` (extrinsic
  sequences, the first listed axis applied first);
* the per-axis constant-velocity KF against ``filterpy.kalman.KalmanFilter`` with the textbook matrices, with
  missing measurements, to 1e-12;
* the rotation step of the SE(3) smoothing (torso and wrist frames) against scipy's ``Slerp``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from akc_drake.operator.asf_amc import parse_amc, parse_asf
from akc_drake.operator.bvh import parse_bvh

ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")


# ------------------------------------------------------------------------------------------------ BVH
def _random_bvh(rng, n_joints=6, frames=5, six_channel_joints=False):
    """A random BVH chain (each joint's parent random among the earlier ones) and its numbers.

    Returns:
        ``(text, parents, offsets, orders, values)``: per joint its parent index, OFFSET, rotation order and
        per frame its channel values (root: 3 positions then 3 rotations; others: 3 rotations, or 3 positions
        then 3 rotations with ``six_channel_joints``).
    """
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, n_joints)]
    offsets = rng.uniform(-20, 20, (n_joints, 3))
    orders = [ORDERS[int(rng.integers(len(ORDERS)))] for _ in range(n_joints)]
    n_pos = [3] + [3 if six_channel_joints else 0] * (n_joints - 1)
    values = [
        np.concatenate([rng.uniform(-30, 30, (frames, n_pos[j])), rng.uniform(-180, 180, (frames, 3))], axis=1)
        for j in range(n_joints)
    ]
    children = {j: [k for k in range(n_joints) if parents[k] == j] for j in range(n_joints)}
    lines = ["HIERARCHY"]

    def emit(j, depth):
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if j == 0 else 'JOINT'} j{j}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(repr(float(v)) for v in offsets[j])}")
        chans = (["Xposition", "Yposition", "Zposition"] if n_pos[j] else []) + [f"{a}rotation" for a in orders[j]]
        lines.append(f"{pad}  CHANNELS {len(chans)} {' '.join(chans)}")
        for k in children[j]:
            emit(k, depth + 1)
        if not children[j]:
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 0.0 5.0 0.0", pad + "  }"])
        lines.append(pad + "}")

    emit(0, 0)
    # Channel columns follow the depth-first order of the hierarchy.
    dfs = []

    def walk(j):
        dfs.append(j)
        for k in children[j]:
            walk(k)

    walk(0)
    rows = np.concatenate([values[j] for j in dfs], axis=1)
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.04"]
    lines += [" ".join(repr(float(v)) for v in row) for row in rows]
    return "\n".join(lines) + "\n", parents, offsets, orders, values, n_pos


def _scipy_bvh_fk(parents, offsets, orders, values, n_pos):
    """Global rotations and positions per joint ``{j: (R (F,3,3), p (F,3))}`` from scipy's Rotation."""
    out = {}
    for j in range(len(parents)):  # parents come first (parents[j] < j)
        rot = Rotation.from_euler(orders[j].upper(), values[j][:, n_pos[j] :], degrees=True)  # intrinsic
        t = np.broadcast_to(offsets[j], (len(values[j]), 3)).copy()
        if n_pos[j]:
            t = values[j][:, :3]
        if parents[j] < 0:
            out[j] = (rot.as_matrix(), t)
        else:
            Rp, pp = out[parents[j]]
            out[j] = (Rp @ rot.as_matrix(), pp + np.einsum("fij,fj->fi", Rp, t))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("six", [False, True])
def test_bvh_forward_kinematics_matches_scipy_rotation(seed, six):
    text, parents, offsets, orders, values, n_pos = _random_bvh(np.random.default_rng(seed), six_channel_joints=six)
    motion = parse_bvh(text, units="m", source="random.bvh")
    R, p = motion.global_transforms()
    ref = _scipy_bvh_fk(parents, offsets, orders, values, n_pos)
    for j, (R_ref, p_ref) in ref.items():
        i = motion.joint_index(f"j{j}")
        np.testing.assert_allclose(R[:, i], R_ref, atol=1e-12)
        np.testing.assert_allclose(p[:, i], p_ref, atol=1e-10)


@pytest.mark.parametrize("seed", [3, 4])
def test_bvh_forward_kinematics_matches_pybvh(seed, tmp_path):
    pybvh = pytest.importorskip("pybvh")
    text, *_ = _random_bvh(np.random.default_rng(seed), n_joints=7, frames=6)
    path = tmp_path / "random.bvh"
    path.write_text(text)
    theirs = pybvh.read_bvh_file(path, world_up="+y", warn_on_world_up_disagreement=False)
    ours = parse_bvh(text, units="m", source=str(path))
    p_theirs = theirs.joint_positions()
    p_ours = ours.global_positions()
    assert p_theirs.shape[0] == ours.num_frames == 6
    for name in (f"j{j}" for j in range(7)):
        np.testing.assert_allclose(
            p_ours[:, ours.joint_index(name)], p_theirs[:, theirs.joint_index[name]], atol=1e-9, err_msg=name
        )


def test_the_packaged_bvh_file_matches_pybvh():
    pybvh = pytest.importorskip("pybvh")
    from pathlib import Path

    path = Path(__file__).parent / "data" / "mocap" / "upper_body.bvh"
    ours = parse_bvh(path.read_text(), units="m", source=str(path))
    theirs = pybvh.read_bvh_file(path, world_up="+y", warn_on_world_up_disagreement=False)
    p_theirs = theirs.joint_positions()
    names = [n for n in ours.joint_names if n in theirs.joint_index]
    assert len(names) >= 10
    for name in names:
        np.testing.assert_allclose(
            ours.global_positions()[:, ours.joint_index(name)], p_theirs[:, theirs.joint_index[name]], atol=1e-9
        )


# ------------------------------------------------------------------------------------------------ ASF/AMC
def _random_asf_amc(rng, n_bones=6, frames=4):
    bones = []
    for b in range(1, n_bones + 1):
        parent = "root" if b == 1 else f"b{int(rng.integers(1, b))}"
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        axis = rng.uniform(-90, 90, 3)
        axis_order = ORDERS[int(rng.integers(len(ORDERS)))]
        dof = [f"r{a}" for a in rng.permutation(list("xyz"))[: int(rng.integers(1, 4))]]
        bones.append(dict(name=f"b{b}", parent=parent, direction=d, length=float(rng.uniform(0.5, 3)),
                          axis=axis, axis_order=axis_order, dof=dof))
    root_rot = [f"R{a}" for a in rng.permutation(list("XYZ"))]
    root_order = ["TX", "TY", "TZ"] + root_rot
    root_axis = ORDERS[int(rng.integers(len(ORDERS)))]
    root_orientation = rng.uniform(-90, 90, 3)
    asf = [":version 1.10", ":name random", ":units", "  mass 1.0", "  length 1.0", "  angle deg", ":root",
           "  order " + " ".join(root_order), f"  axis {root_axis}", "  position 0 0 0",
           "  orientation " + " ".join(repr(float(v)) for v in root_orientation), ":bonedata"]
    for i, b in enumerate(bones, start=1):
        asf += ["  begin", f"    id {i}", f"    name {b['name']}",
                "    direction " + " ".join(repr(float(v)) for v in b["direction"]),
                f"    length {b['length']!r}",
                "    axis " + " ".join(repr(float(v)) for v in b["axis"]) + f" {b['axis_order']}",
                "    dof " + " ".join(b["dof"]), "  end"]
    asf += [":hierarchy", "  begin"]
    for parent in ["root"] + [b["name"] for b in bones]:
        kids = [b["name"] for b in bones if b["parent"] == parent]
        if kids:
            asf.append(f"    {parent} " + " ".join(kids))
    asf.append("  end")
    values = {"root": np.concatenate([rng.uniform(-1, 1, (frames, 3)), rng.uniform(-180, 180, (frames, 3))], 1)}
    for b in bones:
        values[b["name"]] = rng.uniform(-170, 170, (frames, len(b["dof"])))
    amc = [":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(frames):
        amc.append(str(f + 1))
        for name, v in values.items():
            amc.append(name + "".join(" " + repr(float(x)) for x in v[f]))
    root = dict(order=root_order, axis=root_axis, orientation=root_orientation)
    return "\n".join(asf) + "\n", "\n".join(amc) + "\n", bones, root, values


def _extrinsic(order: str, angles_by_axis: dict[str, np.ndarray]) -> Rotation:
    """Rotation applying the per-axis angles in ``order``, the first listed first (scipy's lowercase)."""
    seq = order.lower()
    return Rotation.from_euler(seq, np.stack([angles_by_axis[a] for a in seq], axis=-1), degrees=True)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_asf_amc_forward_kinematics_matches_scipy_rotation(seed):
    asf, amc, bones, root, values = _random_asf_amc(np.random.default_rng(seed))
    skel = parse_asf(asf, length_unit="m", source="random.asf")
    motion = parse_amc(amc, skel, source="random.amc")
    R_ours, _, end_ours = motion.global_transforms()
    F = motion.num_frames
    # root
    C = _extrinsic(root["axis"], dict(zip("xyz", root["orientation"], strict=True)))
    rv = values["root"]
    M = _extrinsic("".join(d[1] for d in root["order"][3:]),
                   {d[1].lower(): rv[:, 3 + k] for k, d in enumerate(root["order"][3:])})
    G = {"root": C * M * C.inv()}
    end = {"root": rv[:, :3]}
    for b in bones:  # parents come first
        C = _extrinsic(b["axis_order"], dict(zip("xyz", b["axis"], strict=True)))
        M = _extrinsic("".join(d[1] for d in b["dof"]),
                       {d[1]: values[b["name"]][:, k] for k, d in enumerate(b["dof"])})
        G[b["name"]] = G[b["parent"]] * C * M * C.inv()
        end[b["name"]] = end[b["parent"]] + G[b["name"]].apply(np.tile(b["length"] * b["direction"], (F, 1)))
    names = ["root"] + [b["name"] for b in bones]
    for i, name in enumerate(names):
        np.testing.assert_allclose(R_ours[:, i], G[name].as_matrix(), atol=1e-12, err_msg=name)
        np.testing.assert_allclose(end_ours[:, i], end[name], atol=1e-12, err_msg=name)


# ------------------------------------------------------------------------------------------------ KF
def test_constant_velocity_kf_matches_filterpy_to_1e_12():
    kalman = pytest.importorskip("filterpy.kalman")
    from akc_drake.core.kalman import ConstantVelocityKF, KFConfig

    rng = np.random.default_rng(7)
    J, T, dt = 4, 60, 0.1
    cfg = KFConfig(sigma_x=0.01, sigma_y=0.02, sigma_z=0.05, accel_psd=(0.3, 0.5, 0.8), init_vel_var=0.25)
    ours = ConstantVelocityKF(J, cfg)
    truth = np.cumsum(rng.normal(0, 0.02, (T, J, 3)), axis=0) + [0.0, 0.0, 2.0]
    z = truth + rng.normal(0, 1, (T, J, 3)) * np.sqrt(cfg.r)
    # missing data: short gaps (< max_predict_s), whole landmarks and single axes (the paper's partial update)
    for _ in range(25):
        t, j = int(rng.integers(1, T)), int(rng.integers(J))
        z[t : t + int(rng.integers(1, 4)), j, int(rng.integers(3)) if rng.random() < 0.5 else slice(None)] = np.nan
    q, r = np.array(cfg.accel_psd), cfg.r
    F = np.array([[1.0, dt], [0.0, 1.0]])
    theirs = {}
    for t in range(T):
        est = ours.step(z[t], dt)
        for j in range(J):
            for a in range(3):
                kf = theirs.get((j, a))
                if kf is None:
                    if np.isfinite(z[t, j, a]):  # the first measurement initialises the axis
                        kf = theirs[(j, a)] = kalman.KalmanFilter(dim_x=2, dim_z=1)
                        kf.x = np.array([[z[t, j, a]], [0.0]])
                        kf.P = np.diag([r[a], cfg.init_vel_var])
                        kf.F, kf.H, kf.R = F, np.array([[1.0, 0.0]]), np.array([[r[a]]])
                        kf.Q = q[a] * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
                    continue
                kf.predict()
                kf.update(None if not np.isfinite(z[t, j, a]) else np.array([[z[t, j, a]]]))
        for (j, a), kf in theirs.items():
            assert abs(est[j, a] - kf.x[0, 0]) <= 1e-12, (t, j, a)
            assert abs(ours.velocity[j, a] - kf.x[1, 0]) <= 1e-11, (t, j, a)
            assert abs(ours.position_variance[j, a] - kf.P[0, 0]) <= 1e-14, (t, j, a)
    assert len(theirs) == 3 * J


# ------------------------------------------------------------------------------------------------ slerp
def test_se3_smoothing_rotation_step_is_scipys_slerp():
    """With a constant cutoff (beta = 0), one step moves the rotation along the geodesic by the low-pass
    factor: exactly ``Slerp([0, 1], [R_estimate, R_sample])(alpha)``."""
    smoothing = pytest.importorskip("akc_drake.core.smoothing")
    rng = np.random.default_rng(11)
    euro = smoothing.OneEuroParams(min_cutoff_hz=0.7, beta=0.0, d_cutoff_hz=1.0)
    params = smoothing.SE3SmoothingParams(position=euro, rotation=euro, max_angular_speed=None)
    for _ in range(20):
        R0, R1 = Rotation.random(2, random_state=rng)
        if (R0.inv() * R1).magnitude() > np.pi - 1e-3:
            continue  # a half turn has no unique geodesic
        dt = float(rng.uniform(0.01, 0.2))
        f = smoothing.SE3OneEuro(params)
        state, _, _, _ = f.step(smoothing.initial_state(), 0.0, R0.as_matrix(), np.zeros(3))
        _, R, _, accepted = f.step(state, dt, R1.as_matrix(), np.zeros(3))
        a = smoothing.alpha(euro.min_cutoff_hz, dt)
        expected = Slerp([0.0, 1.0], Rotation.concatenate([R0, R1]))([a]).as_matrix()[0]
        assert accepted
        np.testing.assert_allclose(R, expected, atol=1e-12)
