"""ROS 2 MCAP bags written with rosbags: read back with the library, message counts, stamps and values match."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.frames import torso_of, wrist_in_torso
from akc_drake.core.world_frame import WorldFrame
from akc_drake.io.export.ros2bag import BONES, JointSeries, read_ros2_bag, write_ros2_bag
from tests.test_export import synthetic_session

START = 1_700_000_000_000_000_000


def test_bag_round_trip(tmp_path):
    s = synthetic_session(T=12)
    t, corrected, raw = s["t"], s["corrected"], s["raw"]
    W = WorldFrame(Rotation.from_euler("xyz", [0.1, -0.2, 0.3]).as_matrix(), np.array([0.1, 1.2, 0.3]))
    names = [f"arm_left_{i}_joint" for i in range(1, 8)]
    tq = np.arange(24) * 0.05
    qs = np.random.default_rng(0).normal(size=(24, 7))
    cmds = JointSeries(tq, names, qs)
    state = JointSeries(tq, names, qs + 0.01, velocity=qs * 0.5)
    K = CameraIntrinsics(width=64, height=48, fx=60.0, fy=61.0, cx=32.0, cy=24.0)
    imgs = [np.full((48, 64, 3), k, dtype=np.uint8) for k in range(12)]
    out = tmp_path / "run.mcap"
    counts = write_ros2_bag(out, t, {"raw": raw, "corrected": corrected}, world=W, joint_commands=cmds,
                            joint_states=state, intrinsics=K, images=imgs, start_ns=START)
    assert out.is_file() and [p.name for p in tmp_path.iterdir()] == ["run.mcap"]  # no temporary left
    bag = read_ros2_bag(out)
    want = {"/tf_static": 1, "/akc/skeleton/raw": 12, "/akc/skeleton/corrected": 12, "/tf": 12,
            "/robot/joint_commands": 24, "/robot/joint_states": 24, "/camera/color/camera_info": 12,
            "/camera/color/image_raw": 12}
    assert {k: len(v) for k, v in bag.items()} == want == counts

    # Stamps: start + t, on the record and in the header.
    for k, (ns, msg) in enumerate(bag["/akc/skeleton/corrected"]):
        assert ns == START + round(t[k] * 1e9)
        h = msg.markers[0].header
        assert h.stamp.sec * 10**9 + h.stamp.nanosec == ns and h.frame_id == "world"
    # Values: the joints of the corrected skeleton in W, the bones between them.
    P_W = W.to_world(corrected)
    ns, msg = bag["/akc/skeleton/corrected"][3]
    joints = np.array([[p.x, p.y, p.z] for p in msg.markers[0].points])
    np.testing.assert_allclose(joints, P_W[3], atol=1e-12)
    assert len(msg.markers[1].points) == 2 * len(BONES)
    # The raw skeleton misses the left elbow in frames 5-7: 11 joints, and no bone through it.
    _, msg = bag["/akc/skeleton/raw"][6]
    assert len(msg.markers[0].points) == 11 and len(msg.markers[1].points) == 2 * (len(BONES) - 2)

    # /tf_static: world -> camera is the inverse of the world frame's pose in the camera.
    tf = bag["/tf_static"][0][1].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("world", "camera")
    R = Rotation.from_quat([tf.transform.rotation.x, tf.transform.rotation.y, tf.transform.rotation.z,
                            tf.transform.rotation.w]).as_matrix()
    np.testing.assert_allclose(R, W.R_CW.T, atol=1e-12)
    tr = tf.transform.translation
    np.testing.assert_allclose([tr.x, tr.y, tr.z], W.to_world(np.zeros(3)), atol=1e-12)

    # /tf per frame: the torso in W and the wrist control frames in the torso (eq. 17).
    _, msg = bag["/tf"][4]
    by_child = {x.child_frame_id: x for x in msg.transforms}
    assert set(by_child) == {"operator_torso", "operator_left_wrist", "operator_right_wrist"}
    R0, o = torso_of(corrected[4])
    tw = by_child["operator_torso"].transform.translation
    np.testing.assert_allclose([tw.x, tw.y, tw.z], W.to_world(o), atol=1e-12)
    X_left, _ = wrist_in_torso(corrected[4])
    lw = by_child["operator_left_wrist"].transform
    np.testing.assert_allclose([lw.translation.x, lw.translation.y, lw.translation.z], X_left[:3, 3], atol=1e-12)
    q = lw.rotation
    np.testing.assert_allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), X_left[:3, :3], atol=1e-9)

    # JointState commands and state.
    ns, js = bag["/robot/joint_states"][10]
    assert ns == START + round(tq[10] * 1e9) and list(js.name) == names
    np.testing.assert_allclose(js.position, state.position[10])
    np.testing.assert_allclose(js.velocity, state.velocity[10])
    _, jc = bag["/robot/joint_commands"][23]
    np.testing.assert_allclose(jc.position, qs[23])
    assert len(jc.velocity) == 0

    # Camera info and images.
    _, ci = bag["/camera/color/camera_info"][0]
    assert (ci.width, ci.height, ci.header.frame_id) == (64, 48, "camera")
    np.testing.assert_allclose(ci.k, [60, 0, 32, 0, 61, 24, 0, 0, 1])
    _, im = bag["/camera/color/image_raw"][7]
    assert (im.encoding, im.width, im.height, im.step) == ("rgb8", 64, 48, 192) and np.all(im.data == 7)


def test_failed_write_leaves_nothing(tmp_path):
    out = tmp_path / "x.mcap"
    out.write_bytes(b"earlier result")
    with pytest.raises(ValueError):
        write_ros2_bag(out, np.arange(3) * 0.1, {"raw": np.zeros((3, 12, 3))}, frame="nowhere")
    with pytest.raises(Exception):  # noqa: B017 - a broken skeleton array mid-write
        write_ros2_bag(out, np.arange(3) * 0.1, {"raw": np.zeros((2, 12, 3))}, start_ns=START)
    assert out.read_bytes() == b"earlier result"
    assert [p.name for p in tmp_path.iterdir()] == ["x.mcap"]


def test_foxglove_layout_shows_what_the_bag_holds(tmp_path):
    import json
    from importlib import resources

    layout = json.loads(resources.files("akc_drake.data").joinpath("foxglove_layout.json").read_text())
    assert {"configById", "layout", "globalVariables", "userNodes", "playbackConfig"} <= set(layout)
    panels = layout["configById"]

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)  # every panel is placed, every placed panel exists
    topics = set(panels["3D!akcskeleton"]["topics"])
    topics |= {panels["Image!akccamera"]["cameraTopic"], panels["RawMessages!akcstate"]["topicPath"]}
    topics |= {p["value"].split(".", 1)[0] for k, v in panels.items() if k.startswith("Plot!") for p in v["paths"]}
    frames = {k.split(":", 1)[1] for k in panels["3D!akcskeleton"]["transforms"]}
    s = synthetic_session(T=4)
    stages = {k: s[k] for k in ("raw", "accepted", "filtered", "corrected", "truth")}
    names = [f"arm_left_{i}_joint" for i in range(1, 8)]
    series = JointSeries(np.arange(4) * 0.1, names, np.zeros((4, 7)))
    X = np.broadcast_to(np.eye(4), (4, 4, 4))
    write_ros2_bag(tmp_path / "all.mcap", s["t"], stages, joint_commands=series,
                   robot_frames={"left_wrist_target": (s["t"], X)},
                   intrinsics=CameraIntrinsics(width=8, height=6, fx=5.0, fy=5.0, cx=4.0, cy=3.0),
                   images=[np.zeros((6, 8, 3), np.uint8)] * 4, start_ns=START)
    bag = read_ros2_bag(tmp_path / "all.mcap")
    assert topics <= set(bag), topics - set(bag)
    tf_frames = {x.child_frame_id for _, m in bag["/tf"] + bag["/tf_static"] for x in m.transforms}
    assert frames - {"robot_torso"} <= tf_frames and "left_wrist_target" in tf_frames


def test_teleop_bag_carries_the_measured_joint_state(tmp_path):
    # Two teleop runs one after the other: commands and measured states (positions and velocities) per run.
    from akc_drake.pipeline.export import TeleopRecording, write_teleop_bag

    s = synthetic_session(T=10)
    names = [f"arm_{side}_{i}_joint" for side in ("left", "right") for i in range(1, 8)]
    rng = np.random.default_rng(1)
    recs = []
    for _ in range(2):
        tq = np.arange(30) * 0.01
        q = rng.normal(size=(30, 14))
        state = JointSeries(tq, names, q + 0.02, velocity=rng.normal(size=(30, 14)))
        X = np.tile(np.eye(4), (30, 1, 1))
        recs.append(TeleopRecording(s["t"], {"corrected": s["corrected"]}, JointSeries(tq, names, q),
                                    {"left_wrist_target": (tq, X)}, state))
    out = tmp_path / "teleop.mcap"
    counts = write_teleop_bag(out, recs, world=WorldFrame.camera(), gap_s=1.0, start_ns=START)
    bag = read_ros2_bag(out)
    assert counts["/robot/joint_states"] == len(bag["/robot/joint_states"]) == 60
    states = bag["/robot/joint_states"]
    # The second run starts gap_s after the first one's last frame (0.9 s): at 1.9 s.
    want_t = np.concatenate([recs[0].states.t, recs[1].states.t + 1.9])
    np.testing.assert_array_equal([ns for ns, _ in states], START + np.round(want_t * 1e9).astype(np.int64))
    np.testing.assert_array_equal([ns for ns, _ in states], [ns for ns, _ in bag["/robot/joint_commands"]])
    got_q = np.array([m.position for _, m in states])
    got_v = np.array([m.velocity for _, m in states])
    np.testing.assert_array_equal(got_q, np.concatenate([r.states.position for r in recs]))
    np.testing.assert_array_equal(got_v, np.concatenate([r.states.velocity for r in recs]))
    assert list(states[0][1].name) == names
    # A recording without the measured state (an older monitor): no half-logged topic.
    recs[1].states = None
    counts = write_teleop_bag(tmp_path / "partial.mcap", recs, world=WorldFrame.camera(), start_ns=START)
    assert "/robot/joint_states" not in counts and counts["/robot/joint_commands"] == 60
