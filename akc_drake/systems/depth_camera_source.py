"""Stage S1 in simulation: an RGB-D camera looking at the rendered operator.

:class:`DepthCameraSource` is a Diagram: the operator's joint trajectory (kinematic playback) poses the
operator model in a SceneGraph, ``RenderEngineVtk`` renders colour, depth and labels through an
``RgbdSensor``, a stereo depth-noise model (:mod:`akc_drake.core.depth_noise`) corrupts the depth, and
zero-order holds sample everything at the camera rate (a camera takes a frame at ``t_k = k / rate``; the
holds keep it until the next one). Self-occlusion is real: whatever surface is nearest the camera at a
pixel is what the depth image reads there.

:func:`~akc_drake.systems.session_render.render_session` (importable from here too) renders a whole motion
without a simulator (the evaluation's fast path): it reuses one DepthCameraSource and its context, renders
each frame once, runs the landmark extraction of stage S2 on it, and returns the raw measurements with the
ground truth.

``body="skinned"`` shows MakeHuman's body (:mod:`akc_drake.operator.skinned`, deformable geometry driven by
:class:`~akc_drake.systems.skinned_body.SkinnedBody`) instead of the primitive operator.

Camera placement: by default the camera is 2.0 m in front of the operator (along +x of the operator frame
O), at chest height (0.45 m above the pelvis), its optical axis horizontal along -x of O, so the operator's
left appears on the image's right.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Box as _Box
from pydrake.geometry import (
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
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantValueSource, MatrixGain, TrajectorySource, ZeroOrderHold
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.systems.sensors import (
    CameraInfo,
    ImageDepth32F,
    ImageLabel16I,
    ImageRgba8U,
    RgbdSensor,
)
from pydrake.trajectories import PiecewisePolynomial

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.depth_noise import StereoDepthNoise, frame_rng
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.operator.model import (
    DEFAULT_CAMERA_DISTANCE_M,
    DEFAULT_CAMERA_HEIGHT_M,
    NUM_ARM_DOF,
    OperatorParams,
    landmarks_from_q,
)
from akc_drake.operator.motions import OperatorMotion
from akc_drake.operator.sdf import add_operator, operator_position_indices
from akc_drake.systems import timing

RENDERER_NAME = "akc_vtk"

#: The operator bodies a simulated camera can render (``--body``).
BODIES = ("primitive", "skinned")


def check_body(body: str) -> str:
    """``body`` if it names one of :data:`BODIES`, else a ValueError naming the choices."""
    if body not in BODIES:
        raise ValueError(f"body must be one of {', '.join(BODIES)}, got {body!r}")
    return body


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


def _as_X_OC(camera_pose) -> RigidTransform:
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


class StereoDepthNoiseSystem(LeafSystem):
    """Applies the stereo depth-noise model to an ideal depth image (direct feedthrough).

    The noise of the frame at time ``t`` is drawn from ``frame_rng(seed, round(t * rate_hz))``, so a frame's
    noise depends only on the seed and the frame index.

    .. pydrake_system::

        name: StereoDepthNoiseSystem
        input_ports:
        - depth_image_ideal
        output_ports:
        - depth_image
    """

    def __init__(self, intrinsics: CameraIntrinsics, noise: StereoDepthNoise, seed: int = 0):
        """Args:
        intrinsics: the camera (focal length and rate).
        noise: the depth error model.
        seed: noise seed.
        """
        super().__init__()
        self._K = intrinsics
        self._noise = noise
        self._seed = int(seed)
        model = AbstractValue.Make(ImageDepth32F(intrinsics.width, intrinsics.height))
        self._in = self.DeclareAbstractInputPort("depth_image_ideal", model)
        self.DeclareAbstractOutputPort(
            "depth_image",
            lambda: AbstractValue.Make(ImageDepth32F(intrinsics.width, intrinsics.height)),
            self._calc,
            prerequisites_of_calc={self.time_ticket(), self._in.ticket()},
        )

    def noisy_depth(self, ideal_m: np.ndarray, t: float) -> np.ndarray:
        """The measured depth ``(H, W)`` float32 (0 invalid) for an ideal depth image taken at ``t``."""
        k = int(round(t * self._K.rate_hz))
        return self._noise.apply(ideal_m, self._K.fx, frame_rng(self._seed, k))

    def _calc(self, context, output):
        ideal = self._in.Eval(context).data[:, :, 0]
        img = output.get_mutable_value()
        img.mutable_data[:, :, 0] = self.noisy_depth(ideal, context.get_time())


class LandmarkTruth(LeafSystem):
    """The operator's true landmarks in the camera frame from its joint positions (direct feedthrough).

    .. pydrake_system::

        name: LandmarkTruth
        input_ports:
        - q
        output_ports:
        - landmarks_true_C
    """

    def __init__(self, params: OperatorParams, X_CO: RigidTransform, landmarks_O: Callable | None = None):
        """Args:
        params: the operator's dimensions.
        X_CO: pose of the operator frame O in the camera frame C.
        landmarks_O: ``q (T, 10) -> (T, 12, 3)`` true landmarks in O (default: the primitive operator's,
            :func:`~akc_drake.operator.model.landmarks_from_q`; the skinned body passes its rig's).
        """
        super().__init__()
        self._params = params
        self._landmarks_O = landmarks_O
        self._R = X_CO.rotation().matrix()
        self._p = X_CO.translation()
        self._q = self.DeclareVectorInputPort("q", 2 * NUM_ARM_DOF)
        self.DeclareVectorOutputPort("landmarks_true_C", 3 * NUM_LANDMARKS, self._calc)

    def landmarks_C(self, q: np.ndarray) -> np.ndarray:
        """``(12, 3)`` landmarks in C for the canonical joint vector ``q = [q_left, q_right]``."""
        if self._landmarks_O is not None:
            lm_O = self._landmarks_O(np.asarray(q, float)[None])[0]
        else:
            lm_O = landmarks_from_q(q[:NUM_ARM_DOF], q[NUM_ARM_DOF:], self._params)[0]
        return lm_O @ self._R.T + self._p

    def _calc(self, context, output):
        output.SetFromVector(self.landmarks_C(self._q.Eval(context)).ravel())


class DepthCameraSource(Diagram):
    """Stage S1 in simulation: the operator performing a motion, seen by a simulated RGB-D camera.

    Frames are sampled at ``intrinsics.rate_hz`` with offset ``timing.stage_offset("source")`` (= 0), held in
    zero-order holds, so every output is constant between two frames. Diagram time ``t`` plays the motion at
    ``motion.start + t``.

    .. pydrake_system::

        name: DepthCameraSource
        output_ports:
        - color_image
        - depth_image
        - label_image
        - camera_info
        - landmarks_true_C

    ``color_image`` is ImageRgba8U, ``depth_image`` ImageDepth32F in metres (0 invalid, after the noise
    model), ``label_image`` ImageLabel16I (each pixel's body index in :attr:`plant`; all zero when
    ``render_label`` is False), ``camera_info`` an AbstractValue holding the
    :class:`~akc_drake.core.camera.CameraIntrinsics`, ``landmarks_true_C`` the 36 true landmark coordinates
    (row-major (12, 3), camera frame C, for evaluation only).
    """

    def __init__(
        self,
        motion: OperatorMotion,
        *,
        intrinsics: CameraIntrinsics | None = None,
        camera_pose=None,
        noise: StereoDepthNoise | None = None,
        seed: int = 0,
        params: OperatorParams | None = None,
        render_label: bool = True,
        background_wall_m: float | None = 1.5,
        render_color: bool = True,
        body: str = "primitive",
    ):
        """Args:
        motion: the operator's joint trajectory.
        intrinsics: the camera (default: D435-like 640x480 at 10 Hz).
        camera_pose: a :class:`CameraPlacement` (default), a ``RigidTransform`` X_OC or a 4x4 matrix.
        noise: the depth error model (default :class:`~akc_drake.core.depth_noise.StereoDepthNoise`).
        seed: depth-noise seed.
        params: the operator's dimensions (default: the paper's participant).
        render_label: render the label image (costs a third render per frame).
        render_color: render the colour image; False exports a constant black image instead, which halves the
            cost of a frame when the detector does not look at colour (the simulated detector).
        background_wall_m: a wall this far behind the operator (None: no wall, empty background).
        body: "primitive" (the operator built from primitives, fast) or "skinned" (MakeHuman's body on the
            CMU-MB rig, :mod:`akc_drake.operator.skinned`, deformable geometry a real detector sees; its
            true landmarks are the rig's joint centres).
        """
        super().__init__()
        if not isinstance(motion, OperatorMotion):
            raise ValueError(f"motion must be an OperatorMotion, got {type(motion).__name__}")
        K = intrinsics or CameraIntrinsics()
        self.intrinsics = K
        self.params = params or OperatorParams()
        self.noise = noise if noise is not None else StereoDepthNoise()
        self.seed = int(seed)
        self.motion = motion
        self.render_label = bool(render_label)
        self.X_OC = _as_X_OC(camera_pose)
        self.body = check_body(body)
        self.skinned = None
        period = 1.0 / K.rate_hz
        offset = timing.stage_offset("source")

        builder = DiagramBuilder()
        scene_graph = builder.AddSystem(SceneGraph())
        scene_graph.set_name("scene_graph")
        plant = MultibodyPlant(0.0)
        plant.RegisterAsSourceForSceneGraph(scene_graph)
        if self.body == "skinned":
            from akc_drake.operator.skinned import skinned_operator
            from akc_drake.systems.skinned_body import SkinnedBody, register_skinned_body

            self.skinned = skinned_operator(self.params)
            self.skinned.check_q(motion.q(), where=f"motion {motion.name}")
            self.instance = None
        else:
            self.instance = add_operator(plant, self.params)
        if background_wall_m is not None:
            plant.RegisterVisualGeometry(
                plant.world_body(),
                RigidTransform([-float(background_wall_m), 0.0, 0.5]),
                _Box(0.05, 8.0, 4.0),
                "background_wall",
                np.array([0.78, 0.78, 0.74, 1.0]),
            )
        plant.Finalize()
        self.plant = plant  # MultibodyPositionToGeometryPose keeps a reference only: keep the plant alive.
        scene_graph.AddRenderer(RENDERER_NAME, MakeRenderEngineVtk(RenderEngineVtkParams()))

        traj = PiecewisePolynomial.FirstOrderHold(motion.times - motion.start, motion.q().T)
        q_source = builder.AddSystem(TrajectorySource(traj))
        q_source.set_name("operator_trajectory")
        if self.skinned is not None:
            source_id, ids = register_skinned_body(scene_graph, self.skinned)
            skin = builder.AddSystem(SkinnedBody(self.skinned, ids))
            skin.set_name("skinned_body")
            builder.Connect(q_source.get_output_port(), skin.get_input_port())
            builder.Connect(skin.get_output_port(0), scene_graph.get_source_configuration_port(source_id))
            self.skinned_system = skin
        else:
            to_pose = builder.AddSystem(MultibodyPositionToGeometryPose(plant))
            to_pose.set_name("operator_pose")
        idx = operator_position_indices(plant, self.instance) if self.skinned is None else None
        if self.skinned is not None:
            pass
        elif np.array_equal(idx, np.arange(plant.num_positions())):
            builder.Connect(q_source.get_output_port(), to_pose.get_input_port())
        else:
            P = np.zeros((plant.num_positions(), 2 * NUM_ARM_DOF))
            P[idx, np.arange(2 * NUM_ARM_DOF)] = 1.0
            perm = builder.AddSystem(MatrixGain(P))
            builder.Connect(q_source.get_output_port(), perm.get_input_port())
            builder.Connect(perm.get_output_port(), to_pose.get_input_port())
        if self.skinned is None:
            builder.Connect(to_pose.get_output_port(), scene_graph.get_source_pose_port(plant.get_source_id()))

        # Drake's image coordinates put pixel i's centre at i + 0.5 (texture coordinates); ours put it at i
        # (akc_drake.core.camera), hence the half-pixel shift of the principal point.
        core = RenderCameraCore(
            RENDERER_NAME,
            CameraInfo(K.width, K.height, K.fx, K.fy, K.cx + 0.5, K.cy + 0.5),
            ClippingRange(0.05, 30.0),
            RigidTransform(),
        )
        sensor = builder.AddSystem(
            RgbdSensor(
                scene_graph.world_frame_id(),
                self.X_OC,
                ColorRenderCamera(core, False),
                DepthRenderCamera(core, DepthRange(0.06, 25.0)),
            )
        )
        sensor.set_name("rgbd_sensor")
        builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
        self.sensor = sensor

        noise_sys = builder.AddSystem(StereoDepthNoiseSystem(K, self.noise, self.seed))
        noise_sys.set_name("depth_noise")
        builder.Connect(sensor.depth_image_32F_output_port(), noise_sys.get_input_port())
        self.noise_system = noise_sys

        truth = builder.AddSystem(
            LandmarkTruth(
                self.params,
                self.X_OC.inverse(),
                None if self.skinned is None else self.skinned.landmarks_O,
            )
        )
        truth.set_name("landmark_truth")
        builder.Connect(q_source.get_output_port(), truth.get_input_port())
        self.truth_system = truth

        def hold(name, model, port):
            zoh = builder.AddSystem(ZeroOrderHold(period, model, offset))
            zoh.set_name(f"hold_{name}")
            builder.Connect(port, zoh.get_input_port())
            builder.ExportOutput(zoh.get_output_port(), name)

        self.render_color = bool(render_color)
        if self.render_color:
            hold(
                "color_image",
                AbstractValue.Make(ImageRgba8U(K.width, K.height)),
                sensor.color_image_output_port(),
            )
        else:
            black = builder.AddSystem(ConstantValueSource(AbstractValue.Make(ImageRgba8U(K.width, K.height))))
            black.set_name("no_color")
            builder.ExportOutput(black.get_output_port(), "color_image")
        hold("depth_image", AbstractValue.Make(ImageDepth32F(K.width, K.height)), noise_sys.get_output_port())
        if self.render_label:
            hold(
                "label_image",
                AbstractValue.Make(ImageLabel16I(K.width, K.height)),
                sensor.label_image_output_port(),
            )
        else:
            blank = builder.AddSystem(
                ConstantValueSource(AbstractValue.Make(ImageLabel16I(K.width, K.height)))
            )
            blank.set_name("no_labels")
            builder.ExportOutput(blank.get_output_port(), "label_image")
        info = builder.AddSystem(ConstantValueSource(AbstractValue.Make(K)))
        info.set_name("camera_info")
        builder.ExportOutput(info.get_output_port(), "camera_info")
        zoh = builder.AddSystem(ZeroOrderHold(period, 3 * NUM_LANDMARKS, offset))
        zoh.set_name("hold_landmarks_true_C")
        builder.Connect(truth.get_output_port(), zoh.get_input_port())
        builder.ExportOutput(zoh.get_output_port(), "landmarks_true_C")
        builder.BuildInto(self)
        self.set_name("depth_camera_source")

    def body_names_by_label(self) -> dict[int, str]:
        """Label value -> body name for the label image (the label is the plant's body index, or the
        skinned body's region)."""
        if self.skinned is not None:
            from akc_drake.operator.skinned import REGIONS
            from akc_drake.systems.skinned_body import REGION_LABEL_BASE

            return {REGION_LABEL_BASE + k: f"skinned_{n}" for k, n in enumerate(REGIONS)}
        return {int(i): self.plant.get_body(i).name() for i in self.plant.GetBodyIndices(self.instance)}


def AddDepthCameraSource(builder: DiagramBuilder, motion: OperatorMotion, **kwargs) -> DepthCameraSource:
    """Add a :class:`DepthCameraSource` to ``builder`` and return it (keywords: as its constructor)."""
    source = builder.AddSystem(DepthCameraSource(motion, **kwargs))
    return source


def intrinsics_from_config(camera_cfg) -> CameraIntrinsics:
    """:class:`CameraIntrinsics` from an ``akc_drake.config.CameraConfig`` (size, fov_x_deg, rate)."""
    W, H = int(camera_cfg.width), int(camera_cfg.height)
    fov = float(camera_cfg.fov_x_deg)
    if not 1.0 < fov < 179.0:
        raise ValueError(f"config.camera.fov_x_deg must be in (1, 179) degrees, got {fov!r}")
    f = (W / 2.0) / math.tan(math.radians(fov) / 2.0)
    return CameraIntrinsics(
        width=W, height=H, fx=f, fy=f, cx=(W - 1) / 2.0, cy=(H - 1) / 2.0, rate_hz=float(camera_cfg.rate_hz)
    )


def add_sim_camera_source(builder: DiagramBuilder, cfg, motion: OperatorMotion | None = None):
    """Add the simulated camera described by a ``PipelineConfig`` (``akc_drake.config``).

    Args:
        builder: the diagram builder.
        cfg: the pipeline configuration (``camera``, ``motion``, ``cycles``, ``seed``, ``skeleton``).
        motion: a motion to play instead of ``cfg.motion``.

    Returns:
        ``(source, intrinsics, num_frames)``: the added :class:`DepthCameraSource` (without label rendering:
        its ``label_image`` is all zero), its intrinsics and the number of camera frames the motion spans.
    """
    from akc_drake.operator.motions import make_motion

    cam = cfg.camera
    K = intrinsics_from_config(cam)
    placement = CameraPlacement(distance_m=float(cam.distance_m), height_m=float(cam.height_m))
    if motion is None:
        name = str(cfg.motion)
        if name.strip().lower() in ("i", "ii", "1", "2", "motion_i", "motion_ii"):
            motion = make_motion(name, int(cfg.cycles), int(cfg.seed), target_O=tuple(placement.position_O()))
        else:
            from akc_drake.operator.retarget import motion_from_spec

            motion = motion_from_spec(
                name,
                cycles=int(cfg.cycles),
                seed=int(cfg.seed),
                skeleton=cfg.skeleton or None,
                rate_hz=K.rate_hz,
            )
    noise = StereoDepthNoise(
        baseline_m=float(cam.baseline_m), sigma_disparity_px=float(cam.disparity_noise_px)
    )
    # The pipeline's simulated detector reads depth and truth only: skip the label render (~5 ms a frame).
    source = builder.AddSystem(
        DepthCameraSource(
            motion,
            intrinsics=K,
            camera_pose=placement,
            noise=noise,
            seed=int(cfg.seed),
            render_label=False,
            body=getattr(cfg, "body", "primitive"),
        )
    )
    return source, K, len(motion.frame_times(K.rate_hz))


# The frame-by-frame renderer of whole sessions lives in its own module; its names stay importable from here.
from akc_drake.systems.session_render import (  # noqa: E402
    DETECTORS,
    Session,
    images_needed,
    make_detector,
    render_session,
)

__all__ = [
    "BODIES",
    "DETECTORS",
    "CameraPlacement",
    "DepthCameraSource",
    "LandmarkTruth",
    "Session",
    "StereoDepthNoiseSystem",
    "AddDepthCameraSource",
    "add_sim_camera_source",
    "check_body",
    "images_needed",
    "intrinsics_from_config",
    "make_detector",
    "render_session",
]
