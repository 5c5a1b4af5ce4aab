"""run --export / --ros2-bag / --lcm on the rendered operator (short runs), and the world frame against the
simulated camera (level: gravity is -y of the camera)."""

import json

import numpy as np
import pytest

from akc_drake.cli import main as cli
from akc_drake.io.export.poses import load_poses, world_frame_for
from akc_drake.io.export.ros2bag import read_ros2_bag
from akc_drake.io.export.table import read_trc


@pytest.fixture(scope="module")
def teleop_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    argv = ["run", "--source", "sim", "--motion", "I", "--seconds", "1.5", "--teleop", "--lcm", "memq://",
            "--export", "trc,csv", "--ros2-bag", str(out / "teleop.mcap"), "--out", str(out), "--json",
            str(out / "run.json")]
    assert cli(argv) == 0
    return out


def test_run_writes_exports_and_bag(teleop_run):
    summary = json.loads((teleop_run / "run.json").read_text())
    names = sorted(p.split("/")[-1] for p in summary["exports"])
    assert names == ["corrected.csv", "corrected.trc", "filtered.csv", "filtered.trc", "raw.csv", "raw.trc"]
    poses = load_poses(teleop_run / "poses.npz")
    assert poses.dims is not None and poses.num_frames == 15
    trc = read_trc(teleop_run / "corrected.trc")
    W = world_frame_for(poses)
    from akc_drake.core.world_frame import Y_UP_FROM_W

    want = W.to_world(poses.stage("corrected")) @ Y_UP_FROM_W.T * 1000
    np.testing.assert_allclose(trc["points"], want, atol=0.1)
    bag = read_ros2_bag(teleop_run / "teleop.mcap")
    counts = {k: len(v) for k, v in bag.items()}
    assert counts == summary["ros2_bag"]["messages"]
    assert counts["/akc/skeleton/corrected"] == 15 and counts["/robot/joint_commands"] >= 140  # 100 Hz IK
    children = {x.child_frame_id for _, m in bag["/tf"] for x in m.transforms}
    assert {"left_wrist_target", "right_ee", "operator_torso", "operator_left_wrist"} <= children
    _, js = bag["/robot/joint_commands"][-1]
    assert len(js.name) == 14 and np.all(np.isfinite(js.position))
    # The robot's measured joint state: one message per command, same stamps, same joint names, finite values that
    # follow the commands (the station's position control lags a command by a few IK steps at most).
    states, cmds = bag["/robot/joint_states"], bag["/robot/joint_commands"]
    assert len(states) == len(cmds)
    assert [ns for ns, _ in states] == [ns for ns, _ in cmds]
    assert all(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == ns for ns, m in states)
    q_meas = np.array([m.position for _, m in states])
    v_meas = np.array([m.velocity for _, m in states])
    q_cmd = np.array([m.position for _, m in cmds])
    assert list(states[0][1].name) == list(cmds[0][1].name) and q_meas.shape == v_meas.shape == (len(states), 14)
    assert np.all(np.isfinite(q_meas)) and np.all(np.isfinite(v_meas))
    assert np.median(np.abs(q_meas[5:] - q_cmd[:-5])) < 0.05
    assert np.max(np.abs(np.diff(q_meas, axis=0))) > 1e-4  # the arm moves: not a constant copy


def test_world_frame_on_the_rendered_operator_is_level(teleop_run):
    # The simulated camera is level (its y axis points down): the estimated up must be -y_C.
    W = world_frame_for(load_poses(teleop_run / "poses.npz"))
    tilt = np.degrees(np.arccos(np.clip(-W.R_CW[1, 2], -1, 1)))
    assert tilt < 3.0
    assert 0.8 < W.camera_height_m < 2.0


def test_lcm_needs_teleop_and_bad_export_format(tmp_path, capsys):
    assert cli(["run", "--source", "sim", "--seconds", "0.5", "--lcm", "memq://", "--out", str(tmp_path)]) == 2
    assert "--teleop" in capsys.readouterr().err
    assert cli(["run", "--source", "sim", "--seconds", "0.5", "--export", "fbx", "--out", str(tmp_path)]) == 2
    assert "unknown format 'fbx'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
