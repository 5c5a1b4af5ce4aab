"""ROS 2 bags without ROS: MCAP files with standard message types, written with ``rosbags`` (pure Python).

Topics (all stamps = session start + frame time; message definitions are embedded, so Foxglove, ``ros2 bag
play`` and ``rosbags`` read the file without our code):

=============================== ============================== ====================================================
topic                           type                           content
=============================== ============================== ====================================================
``/akc/skeleton/<stage>``       visualization_msgs/MarkerArray per frame: the landmarks (SPHERE_LIST, one colour per
                                                               stage) and the bones (LINE_LIST), in ``frame_id``
``/tf_static``                  tf2_msgs/TFMessage             once: ``world -> camera`` (the estimated world frame)
``/tf``                         tf2_msgs/TFMessage             per frame: ``world -> operator_torso`` and
                                                               ``operator_torso -> operator_{left,right}_wrist``
                                                               (the control frames of eq. 17, from the corrected
                                                               skeleton)
``/tf``                         tf2_msgs/TFMessage             with a robot: ``robot_torso ->``
                                                               ``{left,right}_wrist_target`` (the IK's targets) and
                                                               ``{left,right}_ee`` (the achieved end effectors)
``/robot/joint_commands``       sensor_msgs/JointState         the robot's commanded joint positions (teleop)
``/robot/joint_states``         sensor_msgs/JointState         the robot's measured positions and velocities
``/camera/color/camera_info``   sensor_msgs/CameraInfo         per frame, when the intrinsics are known
``/camera/color/image_raw``     sensor_msgs/Image              per frame (rgb8), when images are given
=============================== ============================== ====================================================

The bag is written as a rosbag2 folder in a temporary directory next to the target; its single ``.mcap`` file is
then renamed to the target, so a failure never leaves half a file. Read it back with
``rosbags.highlevel.AnyReader([Path("x.mcap")])``.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from akc_drake.core.frames import torso_of, wrist_in_torso
from akc_drake.core.skeleton import INDEX, LANDMARKS, SEGMENTS
from akc_drake.core.world_frame import WorldFrame

#: Bones drawn in the MarkerArray (pairs of landmark names): the arm segments, shoulders, trunk, hips and hands.
BONES: tuple[tuple[str, str], ...] = tuple(SEGMENTS.values()) + (
    ("left_hip", "right_hip"),
    ("left_shoulder", "left_hip"),
    ("right_shoulder", "right_hip"),
    ("left_wrist", "left_index"),
    ("left_wrist", "left_pinky"),
    ("left_index", "left_pinky"),
    ("right_wrist", "right_index"),
    ("right_wrist", "right_pinky"),
    ("right_index", "right_pinky"),
)
#: RGBA per stage.
STAGE_COLOURS = {
    "raw": (0.9, 0.2, 0.2, 1.0),
    "accepted": (0.9, 0.6, 0.1, 1.0),
    "filtered": (0.2, 0.7, 0.2, 1.0),
    "corrected": (0.2, 0.4, 0.95, 1.0),
    "truth": (0.6, 0.6, 0.6, 1.0),
}
WORLD, CAMERA, TORSO, ROBOT_TORSO = "world", "camera", "operator_torso", "robot_torso"


@dataclass
class JointSeries:
    """Joint values over time for a JointState topic.

    Attributes:
        t: ``(N,)`` seconds from the session start.
        names: the joint names.
        position: ``(N, n)``.
        velocity: ``(N, n)`` or None.
    """

    t: np.ndarray
    names: list[str]
    position: np.ndarray
    velocity: np.ndarray | None = None


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


class _Msgs:
    """Message constructors from a typestore."""

    def __init__(self):
        self.ts = ts = _typestore()
        T = ts.types
        self.Time, self.Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
        self.Duration = T["builtin_interfaces/msg/Duration"]
        self.Point, self.Vector3 = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Vector3"]
        self.Quaternion, self.Pose = T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Pose"]
        self.Transform = T["geometry_msgs/msg/Transform"]
        self.TransformStamped = T["geometry_msgs/msg/TransformStamped"]
        self.ColorRGBA = T["std_msgs/msg/ColorRGBA"]
        self.Marker, self.MarkerArray = T["visualization_msgs/msg/Marker"], T["visualization_msgs/msg/MarkerArray"]
        self.TFMessage, self.JointState = T["tf2_msgs/msg/TFMessage"], T["sensor_msgs/msg/JointState"]
        self.CameraInfo, self.Image = T["sensor_msgs/msg/CameraInfo"], T["sensor_msgs/msg/Image"]
        self.RegionOfInterest = T["sensor_msgs/msg/RegionOfInterest"]

    def stamp(self, ns: int):
        return self.Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))

    def header(self, ns: int, frame_id: str):
        return self.Header(stamp=self.stamp(ns), frame_id=frame_id)

    def transform(self, ns: int, parent: str, child: str, R: np.ndarray, p: np.ndarray):
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(R).as_quat()
        return self.TransformStamped(
            header=self.header(ns, parent),
            child_frame_id=child,
            transform=self.Transform(
                translation=self.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                rotation=self.Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)),
            ),
        )

    def marker(self, ns: int, frame_id: str, name: str, mid: int, kind: int, pts, rgba, scale: float):
        return self.Marker(
            header=self.header(ns, frame_id),
            ns=name,
            id=mid,
            type=kind,
            action=0,
            pose=self.Pose(
                position=self.Point(x=0.0, y=0.0, z=0.0), orientation=self.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
            ),
            scale=self.Vector3(x=scale, y=scale, z=scale),
            color=self.ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
            lifetime=self.Duration(sec=0, nanosec=300_000_000),
            frame_locked=False,
            points=[self.Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in pts],
            colors=[],
            texture_resource="",
            texture=self.ts.types["sensor_msgs/msg/CompressedImage"](
                header=self.header(0, ""), format="", data=np.zeros(0, dtype=np.uint8)
            ),
            uv_coordinates=[],
            text="",
            mesh_resource="",
            mesh_file=self.ts.types["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
            mesh_use_embedded_materials=False,
        )


SPHERE_LIST, LINE_LIST = 7, 5


def skeleton_markers(msgs: _Msgs, ns: int, frame_id: str, stage: str, pose: np.ndarray):
    """The MarkerArray of one pose ``(12, 3)`` (finite landmarks and the bones between finite landmarks)."""
    rgba = STAGE_COLOURS.get(stage, (1.0, 1.0, 1.0, 1.0))
    ok = np.isfinite(pose).all(axis=1)
    joints = pose[ok]
    lines = []
    for a, b in BONES:
        if ok[INDEX[a]] and ok[INDEX[b]]:
            lines += [pose[INDEX[a]], pose[INDEX[b]]]
    return msgs.MarkerArray(
        markers=[
            msgs.marker(ns, frame_id, f"{stage}/joints", 0, SPHERE_LIST, joints, rgba, 0.04),
            msgs.marker(ns, frame_id, f"{stage}/bones", 1, LINE_LIST, lines, rgba, 0.015),
        ]
    )


def _joint_state(msgs: _Msgs, ns: int, names, q, v=None):
    empty = np.zeros(0, dtype=np.float64)
    return msgs.JointState(
        header=msgs.header(ns, ""),
        name=list(names),
        position=np.asarray(q, dtype=np.float64),
        velocity=empty if v is None else np.asarray(v, dtype=np.float64),
        effort=empty,
    )


def _camera_info(msgs: _Msgs, ns: int, K) -> object:
    """CameraInfo of our CameraIntrinsics (or any object with the same fields)."""
    fx, fy, cx, cy = float(K.fx), float(K.fy), float(K.cx), float(K.cy)
    return msgs.CameraInfo(
        header=msgs.header(ns, CAMERA),
        height=int(K.height),
        width=int(K.width),
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], dtype=np.float64),
        r=np.eye(3).reshape(-1),
        p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], dtype=np.float64),
        binning_x=0,
        binning_y=0,
        roi=msgs.RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def write_ros2_bag(
    path,
    t: np.ndarray,
    skeletons: dict[str, np.ndarray],
    *,
    world: WorldFrame | None = None,
    frame: str = "world",
    joint_commands: JointSeries | None = None,
    joint_states: JointSeries | None = None,
    robot_frames: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
    intrinsics=None,
    images: Iterable[np.ndarray] | None = None,
    start_ns: int | None = None,
) -> dict[str, int]:
    """Write a ROS 2 MCAP bag (see the module docstring).

    Args:
        path: the ``.mcap`` file.
        t: ``(T,)`` frame times, seconds from the session start.
        skeletons: stage -> ``(T, 12, 3)`` landmarks in the camera frame C, metres, NaN where missing.
        world: the world frame (``world -> camera`` on ``/tf_static``); None: identity.
        frame: ``"world"`` (markers in the world frame) or ``"camera"`` (markers in the camera frame).
        joint_commands, joint_states: the robot's commands and state, when there is a robot.
        robot_frames: ``{child frame: (t (N,), X (N, 4, 4))}`` poses in the robot's torso frame (the mapped wrist
            targets), written on ``/tf`` with parent ``robot_torso`` (non-finite poses are skipped).
        intrinsics: a :class:`~akc_drake.core.camera.CameraIntrinsics` for ``camera_info``.
        images: per frame ``(H, W, 3)`` uint8 RGB images for ``image_raw`` (optional).
        start_ns: the session start, ns since the epoch (default: now).

    Returns:
        The number of messages written per topic.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    if frame not in ("world", "camera"):
        raise ValueError(f"frame must be 'world' or 'camera', got {frame!r}")
    world = world if world is not None else WorldFrame.camera()
    t = np.asarray(t, dtype=float)
    start = int(time.time() * 1e9) if start_ns is None else int(start_ns)
    stamps = [start + int(round(ti * 1e9)) for ti in t]
    msgs = _Msgs()
    ts = msgs.ts
    counts: dict[str, int] = {}
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{target.stem}.", dir=target.parent))
    bagdir = tmpdir / "bag"
    try:
        with Writer(bagdir, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            conns = {}

            def put(topic: str, msg, ns: int) -> None:
                kind = type(msg).__msgtype__
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, kind, typestore=ts)
                w.write(conns[topic], ns, ts.serialize_cdr(msg, kind))
                counts[topic] = counts.get(topic, 0) + 1

            put("/tf_static", msgs.TFMessage(transforms=[
                msgs.transform(start, WORLD, CAMERA, world.R_CW.T, world.to_world(np.zeros(3)))]), start)
            fid = WORLD if frame == "world" else CAMERA
            for stage, P in skeletons.items():
                P = np.asarray(P, dtype=float)
                Pf = world.to_world(P) if frame == "world" else P
                for k, ns in enumerate(stamps):
                    put(f"/akc/skeleton/{stage}", skeleton_markers(msgs, ns, fid, stage, Pf[k]), ns)
            corrected = skeletons.get("corrected")
            if corrected is not None:
                for k, ns in enumerate(stamps):
                    pose = np.asarray(corrected[k], dtype=float)
                    torso = torso_of(pose)
                    if torso is None:
                        continue
                    R_C0, o_C = torso
                    tfs = [msgs.transform(ns, WORLD, TORSO, world.R_CW.T @ R_C0, world.to_world(o_C))]
                    for side, X in zip(("left", "right"), wrist_in_torso(pose, torso), strict=True):
                        if X is not None:
                            tfs.append(msgs.transform(ns, TORSO, f"operator_{side}_wrist", X[:3, :3], X[:3, 3]))
                    put("/tf", msgs.TFMessage(transforms=tfs), ns)
            for topic, series in (("/robot/joint_commands", joint_commands), ("/robot/joint_states", joint_states)):
                if series is None:
                    continue
                for k, tk in enumerate(np.asarray(series.t, dtype=float)):
                    ns = start + int(round(tk * 1e9))
                    v = None if series.velocity is None else series.velocity[k]
                    put(topic, _joint_state(msgs, ns, series.names, series.position[k], v), ns)
            robot_tfs: dict[int, list] = {}  # one TFMessage per instant with every robot frame of that instant
            for child, (tr, Xs) in (robot_frames or {}).items():
                for tk, X in zip(np.asarray(tr, dtype=float), np.asarray(Xs, dtype=float), strict=True):
                    if np.all(np.isfinite(X)):
                        ns = start + int(round(tk * 1e9))
                        robot_tfs.setdefault(ns, []).append(msgs.transform(ns, ROBOT_TORSO, child, X[:3, :3], X[:3, 3]))
            for ns in sorted(robot_tfs):
                put("/tf", msgs.TFMessage(transforms=robot_tfs[ns]), ns)
            if intrinsics is not None:
                for ns in stamps:
                    put("/camera/color/camera_info", _camera_info(msgs, ns, intrinsics), ns)
            if images is not None:
                for ns, img in zip(stamps, images, strict=False):
                    a = np.ascontiguousarray(img, dtype=np.uint8)
                    put("/camera/color/image_raw", msgs.Image(
                        header=msgs.header(ns, CAMERA), height=a.shape[0], width=a.shape[1], encoding="rgb8",
                        is_bigendian=0, step=3 * a.shape[1], data=a.reshape(-1)), ns)
        produced = list(bagdir.glob("*.mcap"))
        if len(produced) != 1:
            raise OSError(f"{target}: the bag writer produced {len(produced)} .mcap files")
        produced[0].replace(target)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return counts


def read_ros2_bag(path) -> dict[str, list[tuple[int, object]]]:
    """Read every message of an MCAP bag with ``rosbags``: topic -> ``[(stamp_ns, message), ...]``."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list] = {}
    with AnyReader([Path(path)], default_typestore=_typestore()) as r:
        for conn, ns, raw in r.messages():
            out.setdefault(conn.topic, []).append((ns, r.deserialize(raw, conn.msgtype)))
    return out


__all__ = ["JointSeries", "write_ros2_bag", "read_ros2_bag", "skeleton_markers", "BONES", "LANDMARKS"]
