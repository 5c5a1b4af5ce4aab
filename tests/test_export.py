"""``akc-drake export``: each format read back by an independent reader gives the same positions to 0.1 mm."""

import json

import ezc3d
import numpy as np
import pytest

from akc_drake.cli import main as cli
from akc_drake.core.skeleton import INDEX, LANDMARKS, NUM_LANDMARKS, BodyDimensions, segment_lengths
from akc_drake.core.world_frame import BVH_FROM_W, Y_UP_FROM_W, WorldFrame
from akc_drake.fileio import atomic_save_npz
from akc_drake.io.export.poses import load_poses
from akc_drake.io.export.table import read_trc
from akc_drake.operator.bvh import read_bvh
from akc_drake.operator.bvh_export import BVH_NAMES
from akc_drake.pipeline.export import export_poses

DIMS = BodyDimensions.paper_participant()
TOL_M = 1e-4  # 0.1 mm


def _unit(v):
    return v / np.linalg.norm(v)


def synthetic_session(T=40, seed=0):
    """A session in the camera frame: an upright operator 2.2 m away, arms moving with the calibrated lengths
    (the ``corrected`` stage), noisy ``raw``/``accepted``, ``truth``, a camera pitched down by 10 degrees."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * 0.1
    P = np.empty((T, NUM_LANDMARKS, 3))
    for k, tk in enumerate(t):
        for side, s in (("left", -1.0), ("right", 1.0)):  # in W: the operator faces -x, their left is -y
            sh = np.array([2.2, s * DIMS.SW / 2, 1.40])
            P[k, INDEX[f"{side}_shoulder"]] = sh
            P[k, INDEX[f"{side}_hip"]] = [2.2, s * 0.1, 0.91]
            a = 0.8 * np.sin(2 * np.pi * tk / 4 + (0 if s < 0 else 1))
            up_dir = _unit(np.array([-np.sin(a), s * np.cos(a), -0.3]))
            el = sh + DIMS.upper(side) * up_dir
            fore = _unit(np.array([-np.cos(a), s * 0.3, 0.5 * np.sin(a)]))
            wr = el + DIMS.lower(side) * fore
            P[k, INDEX[f"{side}_elbow"]], P[k, INDEX[f"{side}_wrist"]] = el, wr
            P[k, INDEX[f"{side}_index"]] = wr + 0.09 * fore + [0, 0, 0.02]
            P[k, INDEX[f"{side}_pinky"]] = wr + 0.08 * fore - [0, 0, 0.02]
    # camera at (0, 0, 1.2), looking along +x, pitched 10 degrees down: W -> C
    c, s_ = np.cos(np.radians(10)), np.sin(np.radians(10))
    R_W_Cnom = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    R_WC = np.array([[c, 0, s_], [0, 1, 0], [-s_, 0, c]]) @ R_W_Cnom
    corrected = (P - [0, 0, 1.2]) @ R_WC
    raw = corrected + rng.normal(scale=0.02, size=corrected.shape)
    raw[5:8, INDEX["left_elbow"]] = np.nan
    accepted = raw.copy()
    accepted[rng.random((T, NUM_LANDMARKS)) < 0.2, 2] = np.nan
    return dict(t=t, raw=raw, accepted=accepted, filtered=raw, corrected=corrected, truth=corrected,
                visibility=np.ones((T, NUM_LANDMARKS)), names=np.array(LANDMARKS), dims=DIMS.as_array())


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    return atomic_save_npz(tmp_path_factory.mktemp("poses") / "poses.npz", **synthetic_session())


def _world(summary) -> WorldFrame:
    w = summary["world_frame"]
    return WorldFrame(np.array(w["R_CW"]), np.array(w["p_CW"]), source=w["source"])


def test_world_frame_is_gravity_aligned(npz, tmp_path):
    s = export_poses(load_poses(npz), "csv", tmp_path / "a.csv")
    W = _world(s)
    P_W = W.to_world(load_poses(npz).stage("corrected"))
    # The synthetic operator is upright: shoulders level in W, trunk vertical, camera 1.2 m up (anthropometric
    # floor estimate: a few cm).
    assert abs(s["world_frame"]["camera_height_m"] - 1.2) < 0.1
    mid = lambda a, b: 0.5 * (P_W[:, INDEX[a]] + P_W[:, INDEX[b]])  # noqa: E731
    trunk = mid("left_shoulder", "right_shoulder") - mid("left_hip", "right_hip")
    # W is estimated from the noisy filtered stage (2 cm noise): up to within a few mm over the trunk.
    np.testing.assert_allclose(trunk[:, :2], 0.0, atol=0.01)


def test_csv_round_trip(npz, tmp_path):
    out = tmp_path / "s.csv"
    assert cli(["export", "--poses", str(npz), "--format", "csv", "--out", str(out), "--stage", "raw",
                "--json", str(tmp_path / "s.json")]) == 0
    s = json.loads((tmp_path / "s.json").read_text())
    data = np.genfromtxt(out, delimiter=",", names=True)  # numpy's CSV reader, "NaN" as missing
    assert data.dtype.names[:4] == ("time", "left_shoulder_x", "left_shoulder_y", "left_shoulder_z")
    back = np.stack([np.stack([data[f"{n}_{a}"] for a in "xyz"], axis=-1) for n in LANDMARKS], axis=1)
    want = _world(s).to_world(load_poses(npz).stage("raw"))
    np.testing.assert_array_equal(np.isnan(back), np.isnan(want))
    np.testing.assert_allclose(back, want, atol=TOL_M)
    np.testing.assert_allclose(data["time"], load_poses(npz).t)


def test_trc_round_trip_in_mm_y_up(npz, tmp_path):
    out = tmp_path / "s.trc"
    s = export_poses(load_poses(npz), "trc", out, stage="raw")
    trc = read_trc(out)
    h = trc["header"]
    assert (h["Units"], h["DataRate"], h["NumFrames"], h["NumMarkers"]) == ("mm", "10", "40", "12")
    assert trc["markers"] == list(LANDMARKS)
    np.testing.assert_array_equal(trc["frame"], np.arange(1, 41))
    want = _world(s).to_world(load_poses(npz).stage("raw")) @ Y_UP_FROM_W.T * 1000
    np.testing.assert_array_equal(np.isnan(trc["points"]), np.isnan(want))
    np.testing.assert_allclose(trc["points"], want, atol=TOL_M * 1000)
    # Y up: the shoulders are above the hips, about 1.4 m above the floor.
    assert np.nanmedian(trc["points"][:, INDEX["left_shoulder"], 1]) == pytest.approx(1400, abs=100)


def test_c3d_round_trip_with_ezc3d(npz, tmp_path):
    out = tmp_path / "s.c3d"
    s = export_poses(load_poses(npz), "c3d", out, stage="raw")
    c = ezc3d.c3d(str(out))
    assert c["parameters"]["POINT"]["LABELS"]["value"] == list(LANDMARKS)
    assert c["parameters"]["POINT"]["UNITS"]["value"] == ["mm"]
    assert c["parameters"]["POINT"]["RATE"]["value"][0] == pytest.approx(10.0)
    back = np.asarray(c["data"]["points"])[:3].transpose(2, 1, 0)
    want = _world(s).to_world(load_poses(npz).stage("raw")) * 1000
    np.testing.assert_array_equal(np.isnan(back), np.isnan(want))
    np.testing.assert_allclose(back, want, atol=TOL_M * 1000)


def test_bvh_round_trip_with_calibrated_bones(npz, tmp_path):
    out = tmp_path / "s.bvh"
    s = export_poses(load_poses(npz), "bvh", out, stage="corrected")
    motion = read_bvh(out, units="cm")  # our BVH reader: forward kinematics of the file
    assert motion.num_frames == 40 and motion.frame_time == pytest.approx(0.1)
    G = motion.global_positions()
    want = _world(s).to_world(load_poses(npz).stage("corrected")) @ BVH_FROM_W.T
    for lm, joint in BVH_NAMES.items():
        np.testing.assert_allclose(G[:, motion.joint_names.index(joint)], want[:, INDEX[lm]], atol=TOL_M)
    # The hierarchy's bone lengths are the calibrated ones.
    j = {jt.name: jt for jt in motion.joints}
    assert np.linalg.norm(j["LeftElbow"].offset) == pytest.approx(100 * DIMS.LUA)
    assert np.linalg.norm(j["RightWrist"].offset) == pytest.approx(100 * DIMS.RLA)
    # A raw skeleton is re-placed at the calibrated lengths along its measured directions.
    export_poses(load_poses(npz), "bvh", tmp_path / "raw.bvh", stage="raw")
    G = read_bvh(tmp_path / "raw.bvh", units="cm").global_positions()
    names = read_bvh(tmp_path / "raw.bvh", units="cm").joint_names
    up = np.linalg.norm(G[:, names.index("LeftElbow")] - G[:, names.index("LeftShoulder")], axis=1)
    np.testing.assert_allclose(up, DIMS.LUA, atol=1e-6)
    raw_lua = segment_lengths(load_poses(npz).stage("raw"))["LUA"]
    assert np.nanmax(raw_lua) - np.nanmin(raw_lua) > 0.01  # while the raw arm itself stretches


def test_camera_frame_and_rts(npz, tmp_path):
    out = tmp_path / "c.csv"
    s = export_poses(load_poses(npz), "csv", out, stage="corrected", frame="camera")
    assert s["world_frame"]["source"] == "identity"
    back = np.genfromtxt(out, delimiter=",", skip_header=1)[:, 1:].reshape(40, 12, 3)
    np.testing.assert_allclose(back, load_poses(npz).stage("corrected"), atol=1e-12)
    assert cli(["export", "--poses", str(npz), "--format", "csv", "--out", str(tmp_path / "r.csv"),
                "--smooth", "rts", "--json", str(tmp_path / "r.json")]) == 0
    gain = json.loads((tmp_path / "r.json").read_text())["rts_gain"]
    assert gain["filtered"]["rts_rmse_cm"] < gain["filtered"]["forward_rmse_cm"]


@pytest.mark.parametrize(
    "args,message",
    [
        (["--format", "obj"], "unknown format 'obj'"),
        (["--format", "csv", "--stage", "nope"], "unknown stage"),
        (["--format", "csv", "--out", "/proc/no/such.csv"], "/proc"),
    ],
)
def test_user_mistakes_one_line_exit_2_no_file(npz, tmp_path, capsys, args, message):
    out = tmp_path / "x.out"
    argv = ["export", "--poses", str(npz), "--out", str(out)] + args
    assert cli(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert list(tmp_path.iterdir()) == []


def test_wrong_shape_and_unwritable(tmp_path, capsys):
    bad = atomic_save_npz(tmp_path / "bad.npz", t=np.arange(3.0), corrected=np.zeros((3, 5, 3)))
    assert cli(["export", "--poses", str(bad), "--format", "csv", "--out", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert "field 'corrected' must have shape (3, 12, 3)" in err and len(err.strip().splitlines()) == 1
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    good = atomic_save_npz(tmp_path / "good.npz", **synthetic_session(T=5))
    try:
        import os

        if os.access(ro, os.W_OK):  # root ignores permissions: write into a path below a regular file instead
            target = tmp_path / "good.npz" / "x.csv"
        else:
            target = ro / "x.csv"
        assert cli(["export", "--poses", str(good), "--format", "csv", "--out", str(target)]) == 2
        assert "cannot write" in capsys.readouterr().err
    finally:
        ro.chmod(0o700)
    assert not (ro / "x.csv").exists()


def test_world_frame_from_a_tpose_calibration(npz, tmp_path):
    # A calibration session seen by a camera rolled by 90 degrees: the world frame follows the calibration file.
    s = synthetic_session(T=10)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # C_rolled = R^T C
    calib = {k: (v @ R if k in ("raw", "accepted", "filtered", "corrected", "truth") else v) for k, v in s.items()}
    cal = atomic_save_npz(tmp_path / "tpose.npz", **calib)
    out = tmp_path / "c.csv"
    assert cli(["export", "--poses", str(npz), "--format", "csv", "--out", str(out), "--calibration", str(cal),
                "--json", str(tmp_path / "c.json")]) == 0
    w = json.loads((tmp_path / "c.json").read_text())["world_frame"]
    own = export_poses(load_poses(npz), "csv", tmp_path / "own.csv")["world_frame"]
    # (both estimated from noisy landmarks: 2 cm noise, 10 vs 40 frames)
    np.testing.assert_allclose(np.array(w["R_CW"])[:, 2], R.T @ np.array(own["R_CW"])[:, 2], atol=0.05)


def test_bvh_reads_the_same_in_bvhio(npz, tmp_path):
    """A third-party BVH reader with its own forward kinematics (bvhio, on PyGLM) agrees with the export."""
    bvhio = pytest.importorskip("bvhio")
    out = tmp_path / "s.bvh"
    s = export_poses(load_poses(npz), "bvh", out, stage="corrected")
    want = _world(s).to_world(load_poses(npz).stage("corrected")) @ BVH_FROM_W.T * 100  # cm
    root = bvhio.readAsHierarchy(str(out))
    by_name = {BVH_NAMES[k]: INDEX[k] for k in BVH_NAMES}
    checked = 0
    for f in (0, 13, 39):
        root.loadPose(f)
        for joint, _, _ in root.layout():
            if joint.Name in by_name:
                np.testing.assert_allclose(np.array(joint.PositionWorld), want[f, by_name[joint.Name]],
                                           atol=0.01)  # cm: 0.1 mm (PyGLM is float32)
                checked += 1
    assert checked == 3 * len(BVH_NAMES)
