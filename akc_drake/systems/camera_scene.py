"""Building the simulated camera's scene: camera placement, the operator's geometry, the RGB-D sensor, the holds.

Helpers of :class:`~akc_drake.systems.depth_camera_source.DepthCameraSource` (not systems themselves): each
adds systems or geometry to a ``DiagramBuilder``/``SceneGraph``/``MultibodyPlant`` in the order the camera
source needs them. Its public names stay importable from :mod:`akc_drake.systems.depth_camera_source`.

Camera placement: by default the camera is 2.0 m in front of the operator (along +x of the operator frame
O), at chest height (0.45 m above the pelvis), its optical axis horizontal along -x of O, so the operator's
left appears on the image's right.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    Box,
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
    SceneGraph,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, MatrixGain, ZeroOrderHold
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageLabel16I, ImageRgba8U, RgbdSensor

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.operator.model import DEFAULT_CAMERA_DISTANCE_M, DEFAULT_CAMERA_HEIGHT_M, NUM_ARM_DOF, OperatorParams
from akc_drake.operator.motions import OperatorMotion
from akc_drake.operator.sdf import add_operator, operator_position_indices

RENDERER_NAME = "akc_vtk"

@dataclass(frozen=True)
class CameraPlacement:
    """Where the camera is, relative to the operator frame O (pelvis; x forward, y left, z up).

    Attributes:
        distance_m: camera position along +x of O (in front of the operator).
        height_m: camera height above the pelvis (chest height by default).
        lateral_m: camera position along +y of O (toward the operator's left).
        look_at_O: the point the optical axis passes through; None: straight back along -x of O at the
            camera's height (a horizontal optical axis).
    """

    distance_m: float = DEFAULT_CAMERA_DISTANCE_M
    height_m: float = DEFAULT_CAMERA_HEIGHT_M
    lateral_m: float = 0.0
    look_at_O: tuple[float, float, float] | None = None

    def __post_init__(self):
        for name in ("distance_m", "height_m", "lateral_m"):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"CameraPlacement.{name} must be a finite number, got {v!r}")
        if self.distance_m <= 0.3:
            raise ValueError(f"CameraPlacement.distance_m must be more than 0.3 m, got {self.distance_m!r}")

    @classmethod
    def facing_operator(cls, distance_m: float = DEFAULT_CAMERA_DISTANCE_M, height_m: float = DEFAULT_CAMERA_HEIGHT_M,
                        lateral_m: float = 0.0, aim_height_m: float | None = None) -> CameraPlacement:
        """A camera that faces the operator's vertical axis (through the pelvis), its optical axis through the point
        ``aim_height_m`` above the pelvis (None: at the camera's own height, level): ``evaluate --camera`` and the
        config's ``camera`` (``lateral_m``, ``aim_height_m``)."""
        aim = float(height_m) if aim_height_m is None else float(aim_height_m)
        look = None if (lateral_m == 0.0 and aim == height_m) else (0.0, 0.0, aim)
        return cls(distance_m=float(distance_m), height_m=float(height_m), lateral_m=float(lateral_m), look_at_O=look)

    def position_O(self) -> np.ndarray:
        return np.array([self.distance_m, self.lateral_m, self.height_m])

    def X_OC(self) -> RigidTransform:
        """Pose of the camera frame C (x right, y down, z forward) in O."""
        p = self.position_O()
        target = np.array(self.look_at_O, dtype=float) if self.look_at_O is not None else p - [1.0, 0.0, 0.0]
        z = target - p
        if not np.all(np.isfinite(z)) or np.linalg.norm(z) < 1e-9:
            raise ValueError(
                f"CameraPlacement.look_at_O must differ from the camera position, got {self.look_at_O!r}"
            )
        z = z / np.linalg.norm(z)
        x = np.cross(z, [0.0, 0.0, 1.0])
        if np.linalg.norm(x) < 1e-6:
            raise ValueError("CameraPlacement: the optical axis must not be vertical")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p)


def as_X_OC(camera_pose) -> RigidTransform:
    """X_OC from a :class:`CameraPlacement` (None: the default one), a ``RigidTransform`` or a 4x4 matrix."""
    if camera_pose is None:
        return CameraPlacement().X_OC()
    if isinstance(camera_pose, CameraPlacement):
        return camera_pose.X_OC()
    if isinstance(camera_pose, RigidTransform):
        return camera_pose
    try:
        a = np.asarray(camera_pose, dtype=float)
    except (TypeError, ValueError):
        a = None
    if a is not None and a.shape == (4, 4) and np.all(np.isfinite(a)):
        return RigidTransform(a)
    raise ValueError(
        f"camera_pose must be a CameraPlacement, a RigidTransform or a 4x4 matrix, got {camera_pose!r}"
    )


#: The operator bodies a simulated camera can render (``--body``).
BODIES = ("primitive", "skinned")


def check_body(body: str) -> str:
    """``body`` if it names one of :data:`BODIES`, else a ValueError naming the choices."""
    if body not in BODIES:
        raise ValueError(f"body must be one of {', '.join(BODIES)}, got {body!r}")
    return body


def intrinsics_from_config(camera_cfg) -> CameraIntrinsics:
    """:class:`CameraIntrinsics` from an ``akc_drake.config.CameraConfig`` (size, fov_x_deg, rate)."""
    fov = float(camera_cfg.fov_x_deg)
    if not 1.0 < fov < 179.0:
        raise ValueError(f"config.camera.fov_x_deg must be in (1, 179) degrees, got {fov!r}")
    return camera_cfg.intrinsics()


def make_operator_scene(builder: DiagramBuilder, params: OperatorParams, body: str, motion: OperatorMotion,
                        background_wall_m: float | None):
    """Add a SceneGraph (with the VTK renderer) holding the operator and the background wall.

    Args:
        builder: the diagram builder.
        params: the operator's dimensions.
        body: "primitive" (the operator's bodies in a MultibodyPlant) or "skinned" (MakeHuman's body,
            :func:`~akc_drake.operator.skinned.skinned_operator`, checked against the motion's joints).
        motion: the motion the body will play.
        background_wall_m: a wall this far behind the operator (None: no wall).

    Returns:
        ``(scene_graph, plant, instance, skinned)``: the finalised plant (the operator's model instance,
        or None for the skinned body) and the skinned operator (None for the primitive one).
    """
    scene_graph = builder.AddSystem(SceneGraph())
    scene_graph.set_name("scene_graph")
    plant = MultibodyPlant(0.0)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    skinned = instance = None
    if body == "skinned":
        from akc_drake.operator.skinned import skinned_operator

        skinned = skinned_operator(params)
        skinned.check_q(motion.q(), where=f"motion {motion.name}")
    else:
        instance = add_operator(plant, params)
    if background_wall_m is not None:
        plant.RegisterVisualGeometry(plant.world_body(), RigidTransform([-float(background_wall_m), 0.0, 0.5]),
                                     Box(0.05, 8.0, 4.0), "background_wall", np.array([0.78, 0.78, 0.74, 1.0]))
    plant.Finalize()
    scene_graph.AddRenderer(RENDERER_NAME, MakeRenderEngineVtk(RenderEngineVtkParams()))
    return scene_graph, plant, instance, skinned


def connect_operator_pose(builder: DiagramBuilder, scene_graph, plant, instance, skinned, q_port):
    """Pose the operator's geometry from the joint vector on ``q_port`` (``[q_left, q_right]``).

    The skinned body gets a :class:`~akc_drake.systems.skinned_body.SkinnedBody` (deformed meshes); the
    primitive one a MultibodyPositionToGeometryPose (with a permutation when the plant orders its positions
    differently). Returns the SkinnedBody system, or None.
    """
    if skinned is not None:
        from akc_drake.systems.skinned_body import SkinnedBody, register_skinned_body

        source_id, ids = register_skinned_body(scene_graph, skinned)
        skin = builder.AddSystem(SkinnedBody(skinned, ids))
        skin.set_name("skinned_body")
        builder.Connect(q_port, skin.get_input_port())
        builder.Connect(skin.get_output_port(0), scene_graph.get_source_configuration_port(source_id))
        return skin
    to_pose = builder.AddSystem(MultibodyPositionToGeometryPose(plant))
    to_pose.set_name("operator_pose")
    idx = operator_position_indices(plant, instance)
    if np.array_equal(idx, np.arange(plant.num_positions())):
        builder.Connect(q_port, to_pose.get_input_port())
    else:
        P = np.zeros((plant.num_positions(), 2 * NUM_ARM_DOF))
        P[idx, np.arange(2 * NUM_ARM_DOF)] = 1.0
        perm = builder.AddSystem(MatrixGain(P))
        builder.Connect(q_port, perm.get_input_port())
        builder.Connect(perm.get_output_port(), to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(), scene_graph.get_source_pose_port(plant.get_source_id()))
    return None


def add_rgbd_sensor(builder: DiagramBuilder, scene_graph, K: CameraIntrinsics, X_OC: RigidTransform) -> RgbdSensor:
    """Add an ``RgbdSensor`` named "rgbd_sensor" with intrinsics ``K`` at ``X_OC`` (O is the world here),
    rendering through :data:`RENDERER_NAME` (depth range 0.06-25 m), reading ``scene_graph``'s queries."""
    # Drake's image coordinates put pixel i's centre at i + 0.5 (texture coordinates); ours put it at i
    # (akc_drake.core.camera), hence the half-pixel shift of the principal point.
    core = RenderCameraCore(RENDERER_NAME, CameraInfo(K.width, K.height, K.fx, K.fy, K.cx + 0.5, K.cy + 0.5),
                            ClippingRange(0.05, 30.0), RigidTransform())
    sensor = builder.AddSystem(RgbdSensor(scene_graph.world_frame_id(), X_OC, ColorRenderCamera(core, False),
                                          DepthRenderCamera(core, DepthRange(0.06, 25.0))))
    sensor.set_name("rgbd_sensor")
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    return sensor


def export_held_outputs(builder: DiagramBuilder, K: CameraIntrinsics, period: float, offset: float, sensor,
                        depth_port, truth_port, *, render_color: bool, render_label: bool) -> None:
    """Export the camera's outputs, each sampled at the camera rate by a zero-order hold.

    ``color_image`` (or a constant black image without ``render_color``), ``depth_image`` (from
    ``depth_port``), ``label_image`` (or a constant zero image without ``render_label``), ``camera_info``
    (``K``) and ``landmarks_true_C`` (from ``truth_port``).
    """
    def hold(name, model, port):
        zoh = builder.AddSystem(ZeroOrderHold(period, model, offset))
        zoh.set_name(f"hold_{name}")
        builder.Connect(port, zoh.get_input_port())
        builder.ExportOutput(zoh.get_output_port(), name)

    def constant(name, system_name, value):
        source = builder.AddSystem(ConstantValueSource(AbstractValue.Make(value)))
        source.set_name(system_name)
        builder.ExportOutput(source.get_output_port(), name)

    W, H = K.width, K.height
    if render_color:
        hold("color_image", AbstractValue.Make(ImageRgba8U(W, H)), sensor.color_image_output_port())
    else:
        constant("color_image", "no_color", ImageRgba8U(W, H))
    hold("depth_image", AbstractValue.Make(ImageDepth32F(W, H)), depth_port)
    if render_label:
        hold("label_image", AbstractValue.Make(ImageLabel16I(W, H)), sensor.label_image_output_port())
    else:
        constant("label_image", "no_labels", ImageLabel16I(W, H))
    constant("camera_info", "camera_info", K)
    zoh = builder.AddSystem(ZeroOrderHold(period, 3 * NUM_LANDMARKS, offset))
    zoh.set_name("hold_landmarks_true_C")
    builder.Connect(truth_port, zoh.get_input_port())
    builder.ExportOutput(zoh.get_output_port(), "landmarks_true_C")
