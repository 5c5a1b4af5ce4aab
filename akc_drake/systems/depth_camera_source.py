"""Stage S1 in simulation: an RGB-D camera looking at the rendered operator.

:class:`DepthCameraSource` is a Diagram: the operator's joint trajectory (kinematic playback) poses the
operator model in a SceneGraph, ``RenderEngineVtk`` renders colour, depth and labels through an
``RgbdSensor``, a stereo depth-noise model (:class:`~akc_drake.systems.stereo_depth_noise.StereoDepthNoiseSystem`
over :mod:`akc_drake.core.depth_noise`) corrupts the depth, and zero-order holds sample everything at the
camera rate (a camera takes a frame at ``t_k = k / rate``; the holds keep it until the next one).
Self-occlusion is real: whatever surface is nearest the camera at a pixel is what the depth image reads there.
The scene-building helpers and :class:`CameraPlacement` are in :mod:`akc_drake.systems.camera_scene`.

:func:`~akc_drake.systems.session_render.render_session` (importable from here too) renders a whole motion
without a simulator (the evaluation's fast path): it reuses one DepthCameraSource and its context, renders
each frame once, runs the landmark extraction of stage S2 on it, and returns the raw measurements with the
ground truth.

``body="skinned"`` shows MakeHuman's body (:mod:`akc_drake.operator.skinned`, deformable geometry driven by
:class:`~akc_drake.systems.skinned_body.SkinnedBody`) instead of the primitive operator.
"""

from __future__ import annotations

from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import PassThrough, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.depth_noise import StereoDepthNoise
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams
from akc_drake.operator.motions import OperatorMotion
from akc_drake.systems import timing
from akc_drake.systems.camera_scene import (
    BODIES,
    RENDERER_NAME,
    CameraPlacement,
    add_rgbd_sensor,
    as_X_OC,
    check_body,
    connect_operator_pose,
    export_held_outputs,
    intrinsics_from_config,
    make_operator_scene,
)
from akc_drake.systems.landmark_truth import LandmarkTruth
from akc_drake.systems.stereo_depth_noise import StereoDepthNoiseSystem


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

    Args:
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
        q_input: take the operator's posture ``[q_left, q_right]`` from an input port ``q_operator`` (e.g. the
            closed-loop :class:`~akc_drake.systems.operator_controller.OperatorController`) instead of playing
            ``motion`` (which still sets the hands' closure and the body's checks).
    """

    def __init__(self, motion: OperatorMotion, *, intrinsics: CameraIntrinsics | None = None, camera_pose=None,
                 noise: StereoDepthNoise | None = None, seed: int = 0, params: OperatorParams | None = None,
                 render_label: bool = True, background_wall_m: float | None = 1.5, render_color: bool = True,
                 body: str = "primitive", q_input: bool = False):
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
        self.render_color = bool(render_color)
        self.X_OC = as_X_OC(camera_pose)
        self.body = check_body(body)

        builder = DiagramBuilder()
        scene_graph, self.plant, self.instance, self.skinned = make_operator_scene(
            builder, self.params, self.body, motion, background_wall_m
        )  # MultibodyPositionToGeometryPose keeps a reference only: self.plant keeps the plant alive.
        if q_input:  # the posture comes from outside (e.g. the closed-loop operator), the motion is the plan
            q_source = builder.AddSystem(PassThrough(2 * NUM_ARM_DOF))
            q_source.set_name("operator_posture")
            builder.ExportInput(q_source.get_input_port(), "q_operator")
        else:
            traj = PiecewisePolynomial.FirstOrderHold(motion.times - motion.start, motion.q().T)
            q_source = builder.AddSystem(TrajectorySource(traj))
            q_source.set_name("operator_trajectory")
        self.skinned_system = connect_operator_pose(
            builder, scene_graph, self.plant, self.instance, self.skinned, q_source.get_output_port()
        )
        self.sensor = add_rgbd_sensor(builder, scene_graph, K, self.X_OC)
        self.noise_system = builder.AddSystem(StereoDepthNoiseSystem(K, self.noise, self.seed))
        self.noise_system.set_name("depth_noise")
        builder.Connect(self.sensor.depth_image_32F_output_port(), self.noise_system.get_input_port())
        landmarks_O = None if self.skinned is None else self.skinned.landmarks_O
        self.truth_system = builder.AddSystem(LandmarkTruth(self.params, self.X_OC.inverse(), landmarks_O))
        self.truth_system.set_name("landmark_truth")
        builder.Connect(q_source.get_output_port(), self.truth_system.get_input_port())
        export_held_outputs(builder, K, 1.0 / K.rate_hz, timing.stage_offset("source"), self.sensor,
                            self.noise_system.get_output_port(), self.truth_system.get_output_port(),
                            render_color=self.render_color, render_label=self.render_label)
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
    return builder.AddSystem(DepthCameraSource(motion, **kwargs))


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
    placement = CameraPlacement.facing_operator(cam.distance_m, cam.height_m, cam.lateral_m, cam.aim_height_m)
    if motion is None:
        name = str(cfg.motion)
        if name.strip().lower() in ("i", "ii", "1", "2", "motion_i", "motion_ii"):
            motion = make_motion(name, int(cfg.cycles), int(cfg.seed), target_O=tuple(placement.position_O()))
        else:
            from akc_drake.operator.retarget import motion_from_spec

            motion = motion_from_spec(name, cycles=int(cfg.cycles), seed=int(cfg.seed),
                                      skeleton=cfg.skeleton or None, rate_hz=K.rate_hz,
                                      names=cfg.joint_names or None)
    noise = cam.depth_noise()
    # The pipeline's simulated detector reads depth and truth only: skip the label render (~5 ms a frame).
    source = builder.AddSystem(DepthCameraSource(motion, intrinsics=K, camera_pose=placement, noise=noise,
                                                 seed=int(cfg.seed), render_label=False,
                                                 body=getattr(cfg, "body", "primitive")))
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
    "RENDERER_NAME",
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
