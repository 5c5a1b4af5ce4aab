"""Diagram builders: the mocap pipeline (S1-S4) and the teleoperation diagram (S1-S5 + robot).

``build_mocap_diagram(config)`` wires::

    DepthCameraSource -> LandmarkExtractor -> OcclusionFilter -> LandmarkKalmanFilter -> ArmKinematicCorrection
                                                                  (none | KF | EKF)        (none | AKC | COIK)

and logs every stage with VectorLogSink. ``build_teleop_diagram(config)`` adds FrameMapper, one differential IK
per arm, the position-controlled robot (MultibodyPlant + SceneGraph) and, optionally, Meshcat.

Both take ``replay=`` (recorded measurements, see :class:`~akc_drake.systems.measurement_replay.MeasurementReplay`)
in place of the rendered camera, so the same pipeline can be run many times on one rendering, and
``frame_source=`` (a real camera or a recording, see :mod:`akc_drake.io.sources`).

Follows the ``AddX(builder, ...)`` style: each ``Add...`` helper adds and wires a subsystem and returns it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import VectorLogSink, ZeroOrderHold

from akc_drake.config import PipelineConfig
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing
from akc_drake.systems.stage_logs import MocapLog, read_logs  # (part of this module's API)

POSE_SIZE = 3 * NUM_LANDMARKS

#: Pipeline stages whose pose output is logged, in pipeline order.
STAGES = ("raw", "accepted", "estimated", "corrected", "truth")


@dataclass
class Measurements:
    """Recorded stage-S2 output to replay: what the extractor produced for each camera frame.

    Attributes:
        landmarks_C: ``(T, 12, 3)``; visibility: ``(T, 12)``; pixels: ``(T, 12, 2)``; truth_C: ``(T, 12, 3)`` or None.
    """

    landmarks_C: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray
    truth_C: np.ndarray | None = None

    @property
    def num_frames(self) -> int:
        return int(np.asarray(self.landmarks_C).shape[0])

    @classmethod
    def from_session(cls, session) -> Measurements:
        """From any object with ``raw``/``landmarks_C``, ``visibility``, ``pixels`` and ``truth`` arrays."""
        raw = getattr(session, "raw", None)
        if raw is None:
            raw = session.landmarks_C
        return cls(raw, session.visibility, session.pixels, getattr(session, "truth", None))


def resolve_dims(cfg: PipelineConfig, default: BodyDimensions | None = None) -> BodyDimensions:
    """The body dimensions AKC/COIK/EKF use: ``cfg.dims`` when set, else ``default`` (else the paper's participant)."""
    if cfg.dims:
        return BodyDimensions.from_dict(dict(cfg.dims), where="config.dims")
    return default if default is not None else BodyDimensions.paper_participant()


def camera_period(cfg: PipelineConfig) -> float:
    return 1.0 / float(cfg.camera.rate_hz)


def _config_for_source(cfg: PipelineConfig | None, frame_source) -> PipelineConfig:
    """Validate ``cfg``; with a real frame source, take the camera's rate and image size from it."""
    import dataclasses

    cfg = (cfg or PipelineConfig()).validate()
    if frame_source is not None:
        K = frame_source.intrinsics
        camera = dataclasses.replace(cfg.camera, rate_hz=float(getattr(frame_source, "rate_hz", K.rate_hz)),
                                     width=int(K.width), height=int(K.height))
        cfg = dataclasses.replace(cfg, camera=camera)
    return cfg


def sim_camera(cfg: PipelineConfig):
    """``(intrinsics, placement, noise)`` of the simulated camera described by ``cfg.camera``."""
    from akc_drake.systems.depth_camera_source import CameraPlacement

    cam = cfg.camera
    return (
        cam.intrinsics(),
        CameraPlacement.facing_operator(cam.distance_m, cam.height_m, cam.lateral_m, cam.aim_height_m),
        cam.depth_noise(),
    )


@dataclass
class MocapPorts:
    """The output ports of each stage of a mocap pipeline (what the loggers and S5 connect to)."""

    raw: OutputPort
    visibility: OutputPort
    pixels: OutputPort
    truth: OutputPort | None
    accepted: OutputPort
    estimated: OutputPort
    corrected: OutputPort
    systems: dict = field(default_factory=dict)


def AddMeasurementSource(builder: DiagramBuilder, cfg: PipelineConfig, *, replay: Measurements | None = None,
                         frame_source=None, detector=None, motion=None, operator_input: bool = False) -> dict:
    """Add stage S1 + S2: the rendered camera and the landmark extractor, a replay, or a real frame source.

    ``operator_input``: the rendered operator's posture comes from the camera source's ``q_operator`` input
    (the closed-loop operator) instead of ``motion``.

    Returns:
        ``{"landmarks_C", "visibility", "pixels", "truth"}`` output ports, ``"systems"``: the systems added, and
        ``"owned"``: what this function made that holds a resource until closed (the MediaPipe detector it makes
        for a ``frame_source`` given without a ``detector``); :class:`MocapDiagram` closes it.
    """
    period = camera_period(cfg)
    systems = {}
    owned = []  # what this function made and someone must close (a default MediaPipe detector)
    if replay is not None:
        from akc_drake.systems.measurement_replay import MeasurementReplay

        src = builder.AddSystem(
            MeasurementReplay(replay.landmarks_C, replay.visibility, replay.pixels, replay.truth_C,
                              period_s=period, stage_offset_s=cfg.stage_offset_s)
        )
        src.set_name("MeasurementReplay")
        systems["source"] = src
        return {
            "landmarks_C": src.GetOutputPort("landmarks_C"),
            "visibility": src.GetOutputPort("visibility"),
            "pixels": src.GetOutputPort("pixels"),
            "truth": src.GetOutputPort("landmarks_true_C"),
            "systems": systems,
            "num_frames": replay.num_frames,
            "owned": owned,
        }

    from akc_drake.systems.landmark_extractor import LandmarkExtractor

    if frame_source is not None:
        from akc_drake.systems.frame_source import FrameSourceSystem

        src = builder.AddSystem(FrameSourceSystem(frame_source, period_s=period, stage_offset_s=cfg.stage_offset_s))
        src.set_name("DepthCameraSource")
        intrinsics = frame_source.intrinsics
        num_frames = len(frame_source) if hasattr(frame_source, "__len__") else None
        if detector is None:
            from akc_drake.io.mediapipe_detector import MediaPipeDetector

            detector = MediaPipeDetector()
            owned.append(detector)
    else:
        from akc_drake.systems.depth_camera_source import DepthCameraSource, images_needed

        if motion is None:
            from akc_drake.operator.retarget import motion_from_spec

            motion = motion_from_spec(cfg.motion, cycles=cfg.cycles, seed=cfg.seed, skeleton=cfg.skeleton or None,
                                      rate_hz=cfg.camera.rate_hz, names=cfg.joint_names or None)
        intrinsics, placement, noise = sim_camera(cfg)
        # Render only the images the detector looks at (the simulated detector needs depth only).
        needs_color, needs_label = images_needed(detector)
        src = builder.AddSystem(
            DepthCameraSource(motion, intrinsics=intrinsics, camera_pose=placement, noise=noise, seed=cfg.seed,
                              render_color=needs_color or cfg.camera.render_color, render_label=needs_label,
                              body=cfg.body, q_input=operator_input)
        )
        src.set_name("DepthCameraSource")
        num_frames = int(np.floor(motion.duration * cfg.camera.rate_hz + 1e-9)) + 1
        # detector None -> the extractor's simulated detector (uses the render's labels and the truth)
    systems["source"] = src
    # A source whose depth is not a measured surface (a video with a constant --depth) gets no
    # surface-to-centre offset.
    offsets = 0.0 if getattr(frame_source, "depth_is_surface", True) is False else None
    ext = builder.AddSystem(
        LandmarkExtractor(intrinsics, detector=detector, period_s=period, stage_offset_s=cfg.stage_offset_s,
                          seed=cfg.seed, surface_offset_m=offsets, window=cfg.depth_window_px or None,
                          depth_rule=cfg.depth_rule)
    )
    if src.HasOutputPort("camera_info") and ext.HasInputPort("camera_info"):
        builder.Connect(src.GetOutputPort("camera_info"), ext.GetInputPort("camera_info"))
    ext.set_name("LandmarkExtractor")
    systems["extractor"] = ext
    for name in ("color_image", "depth_image", "label_image", "landmarks_true_C"):
        if ext.HasInputPort(name) and src.HasOutputPort(name):
            builder.Connect(src.GetOutputPort(name), ext.GetInputPort(name))
    # Ground truth sampled at the extractor's instant, so that it lines up with the frame it belongs to.
    zoh = builder.AddSystem(ZeroOrderHold(period, POSE_SIZE, timing.stage_offset("extractor", cfg.stage_offset_s)))
    zoh.set_name("truth_sample")
    builder.Connect(src.GetOutputPort("landmarks_true_C"), zoh.get_input_port())
    systems["truth_sample"] = zoh
    return {
        "landmarks_C": ext.GetOutputPort("landmarks_C"),
        "visibility": ext.GetOutputPort("visibility"),
        "pixels": ext.GetOutputPort("pixels"),
        "truth": zoh.get_output_port(),
        "systems": systems,
        "num_frames": num_frames,
        "intrinsics": intrinsics,
        "owned": owned,
    }


def AddMocapPipeline(builder: DiagramBuilder, cfg: PipelineConfig, dims: BodyDimensions, source: dict,
                     *, image_width: int | None = None, teleop: bool = False) -> MocapPorts:
    """Add stages S3 and S4 after ``source`` (from :func:`AddMeasurementSource`).

    The occlusion filter always runs; the filter is ``cfg.filter`` (none | KF | EKF) and the corrector
    ``cfg.corrector`` (none | AKC | AKC+ | COIK). A stage set to none passes its input through. The filter's
    innovation gate is ``cfg.resolved_gate_sigma(teleop)`` (by default on for teleoperation only; an innovation within
    ``cfg.resolved_gate_speed_m_s()`` times the time since the last reading always passes) and its longest
    extrapolation ``cfg.resolved_max_predict_s(teleop)``; with ``teleop`` the filter also undoes a detector's
    left/right swap, AKC holds an arm whose chosen configuration is anatomically impossible, and AKC+ keeps a seen
    wrist against its forearm's fit (``AKCPlusConfig.seen_wrist_anchor``, unless ``cfg.akc_plus`` sets it).
    """
    from akc_drake.core.akc import WEIGHT_PRESETS
    from akc_drake.systems.occlusion_filter import OcclusionFilter

    period = camera_period(cfg)
    systems = dict(source["systems"])
    width = image_width or cfg.camera.width
    occ = builder.AddSystem(
        OcclusionFilter(width, visibility_threshold=cfg.visibility_threshold, proximity=cfg.proximity,
                        period_s=period, stage_offset_s=cfg.stage_offset_s)
    )
    occ.set_name("OcclusionFilter")
    builder.Connect(source["landmarks_C"], occ.GetInputPort("landmarks_C"))
    builder.Connect(source["visibility"], occ.GetInputPort("visibility"))
    builder.Connect(source["pixels"], occ.GetInputPort("pixels"))
    systems["occlusion"] = occ
    accepted = occ.GetOutputPort("landmarks_C_accepted")

    estimated = accepted
    if cfg.filter != "none":
        from akc_drake.core.kalman import EKFConfig, KFConfig
        from akc_drake.systems.landmark_kalman_filter import LandmarkKalmanFilter

        opts = cfg.filter_settings(teleop)
        kf_config = EKFConfig(**opts) if cfg.filter == "EKF" else KFConfig(**opts)
        kf = builder.AddSystem(
            LandmarkKalmanFilter(mode=cfg.filter, dims=dims, config=kf_config, period_s=period,
                                 stage_offset_s=cfg.stage_offset_s, fix_left_right_swaps=teleop)
        )
        kf.set_name("LandmarkKalmanFilter")
        builder.Connect(accepted, kf.GetInputPort("landmarks_C"))
        systems["filter"] = kf
        estimated = kf.GetOutputPort("landmarks_C_estimated")

    corrected = estimated
    if cfg.corrector in ("AKC", "AKC+"):
        from akc_drake.core.akc_plus_config import akc_plus_config
        from akc_drake.systems.arm_kinematic_correction import ArmKinematicCorrection

        # (AKC+ keeps a seen wrist against its forearm's fit in the teleop diagram: the wrist is the robot's command.)
        plus = akc_plus_config(cfg.akc_plus or None, cfg.filter, teleop) if cfg.corrector == "AKC+" else None
        akc = builder.AddSystem(
            ArmKinematicCorrection(dims, WEIGHT_PRESETS[cfg.weights], rate_hz=cfg.camera.rate_hz,
                                   stage_offset_s=cfg.stage_offset_s, anatomical_check=teleop,
                                   corrector=cfg.corrector, plus_config=plus)
        )
        akc.set_name("ArmKinematicCorrection")
        builder.Connect(estimated, akc.GetInputPort("landmarks_C"))
        if cfg.corrector == "AKC+":
            # What was measured: as the filter took it (its gate's garbage dropped, a swap undone), else as accepted.
            filt = systems.get("filter")
            taken = filt.GetOutputPort("landmarks_C_taken") if filt is not None else accepted
            builder.Connect(taken, akc.GetInputPort("landmarks_C_measured"))
            # The filter's posterior variance: AKC+'s statistical tests (without it, its no-covariance rules).
            if filt is not None and filt.HasOutputPort("landmarks_C_variance"):
                builder.Connect(filt.GetOutputPort("landmarks_C_variance"), akc.GetInputPort("landmarks_C_variance"))
        systems["corrector"] = akc
        corrected = akc.GetOutputPort("landmarks_C_corrected")
    elif cfg.corrector == "COIK":
        from akc_drake.core.coik import COIKConfig
        from akc_drake.systems.constrained_optimization_ik import ConstrainedOptimizationIK

        coik = builder.AddSystem(
            ConstrainedOptimizationIK(dims, COIKConfig(solver=cfg.coik_solver), period_s=period,
                                      stage_offset_s=cfg.stage_offset_s)
        )
        coik.set_name("ConstrainedOptimizationIK")
        builder.Connect(estimated, coik.GetInputPort("landmarks_C"))
        systems["corrector"] = coik
        corrected = coik.GetOutputPort("landmarks_C_corrected")

    return MocapPorts(
        raw=source["landmarks_C"], visibility=source["visibility"], pixels=source["pixels"],
        truth=source.get("truth"), accepted=accepted, estimated=estimated, corrected=corrected, systems=systems,
    )


def AddStageLoggers(builder: DiagramBuilder, ports: MocapPorts, period_s: float) -> dict[str, VectorLogSink]:
    """A VectorLogSink per stage output (and visibility, and the corrector's diagnostics).

    The loggers publish at the camera rate with no offset, i.e. at ``t_{k+1}`` they record frame ``k``, which every
    stage has finished by then (see :mod:`akc_drake.systems.timing`). :func:`read_logs` undoes that shift.
    """
    loggers = {}
    named = {
        "raw": ports.raw, "accepted": ports.accepted, "estimated": ports.estimated,
        "corrected": ports.corrected, "truth": ports.truth, "visibility": ports.visibility,
    }
    corrector = ports.systems.get("corrector")
    if corrector is not None and corrector.HasOutputPort("diagnostics"):
        named["diagnostics"] = corrector.GetOutputPort("diagnostics")
    kf = ports.systems.get("filter")
    if kf is not None and kf.HasOutputPort("tracking_status"):
        named["tracking_status"] = kf.GetOutputPort("tracking_status")
    for name, port in named.items():
        if port is None:
            continue
        log = builder.AddSystem(VectorLogSink(port.size(), period_s))
        log.set_name(f"log_{name}")
        builder.Connect(port, log.get_input_port())
        loggers[name] = log
    return loggers


def _progress_advance(simulator: Simulator, t_end: float, step: float, progress: bool, desc: str) -> float:
    """Advance ``simulator`` to ``t_end`` in chunks with a tqdm bar; returns the wall time taken."""
    from tqdm import tqdm

    start = time.perf_counter()
    t0 = simulator.get_context().get_time()
    n = max(int(math.ceil((t_end - t0) / step)), 1)
    with tqdm(total=n, desc=desc, unit="frame", disable=not progress, leave=False) as bar:
        for k in range(1, n + 1):
            simulator.AdvanceTo(min(t0 + k * step, t_end))
            bar.update(1)
    return time.perf_counter() - start


@dataclass
class MocapDiagram:
    """A built mocap diagram and what is needed to run it and read its output.

    A detector the builder made itself (MediaPipe's pose landmarker for a ``frame_source`` built without a
    ``detector``; MediaPipe Hands in a teleop diagram built without a ``hand_detector``) holds a MediaPipe graph and
    its thread until it is closed: :meth:`close`, or a ``with`` block, releases them (later simulations then fail in
    the detector). A detector you pass stays yours to close. Unclosed, they are closed at the interpreter's exit.
    """

    diagram: Diagram
    config: PipelineConfig
    dims: BodyDimensions
    ports: MocapPorts
    loggers: dict[str, VectorLogSink]
    num_frames: int | None
    intrinsics: object = None
    owned: list = field(default_factory=list, repr=False)

    def close(self) -> None:
        """Close the detectors the builder made (see the class); closing twice is a no-op."""
        while self.owned:
            self.owned.pop().close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def systems(self) -> dict:
        return self.ports.systems

    def duration(self, num_frames: int | None = None) -> float:
        n = num_frames if num_frames is not None else self.num_frames
        if n is None:
            raise ValueError("the source has no known length: give num_frames")
        # Run until the loggers have recorded frame n-1 (at tick n).
        return n * camera_period(self.config) + 0.5 * timing.DEFAULT_STAGE_OFFSET_S

    def simulate(self, num_frames: int | None = None, *, progress: bool = False) -> tuple[MocapLog, float]:
        """Run the diagram over the source's frames.

        Returns:
            The per-frame :class:`MocapLog` and the wall-clock seconds the simulation took.
        """
        simulator = Simulator(self.diagram)
        simulator.Initialize()
        period = camera_period(self.config)
        wall = _progress_advance(simulator, self.duration(num_frames), period, progress, "mocap")
        n = num_frames if num_frames is not None else self.num_frames
        return read_logs(self.loggers, simulator.get_context(), period, n), wall


def build_mocap_diagram(cfg: PipelineConfig | None = None, *, replay: Measurements | None = None,
                        frame_source=None, detector=None, dims: BodyDimensions | None = None,
                        motion=None) -> MocapDiagram:
    """Build the mocap diagram S1 -> S4 for ``cfg`` (default :class:`~akc_drake.config.PipelineConfig`).

    Args:
        cfg: the pipeline configuration.
        replay: recorded measurements to replay instead of rendering.
        frame_source: a real frame source (recording, bag, RealSense, video) instead of rendering.
        detector: the 2D detector for ``frame_source`` (default: MediaPipe) or the render (default: simulated).
        dims: body dimensions (default: ``cfg.dims``, else the simulated operator's).
        motion: an :class:`~akc_drake.operator.motions.OperatorMotion` to render instead of ``cfg.motion``.
    """
    cfg = _config_for_source(cfg, frame_source)
    dims = dims if dims is not None else resolve_dims(cfg)
    builder = DiagramBuilder()
    source = AddMeasurementSource(builder, cfg, replay=replay, frame_source=frame_source, detector=detector,
                                  motion=motion)
    ports = AddMocapPipeline(builder, cfg, dims, source)
    loggers = AddStageLoggers(builder, ports, camera_period(cfg))
    for name in ("landmarks_C", "visibility"):
        builder.ExportOutput(source[name], name)
    builder.ExportOutput(ports.corrected, "landmarks_C_corrected")
    if ports.truth is not None:
        builder.ExportOutput(ports.truth, "landmarks_true_C")
    diagram = builder.Build()
    diagram.set_name("mocap")
    return MocapDiagram(diagram, cfg, dims, ports, loggers, source.get("num_frames"), source.get("intrinsics"),
                        owned=source["owned"])


# --------------------------------------------------------------------------------------------------------------
# Teleoperation (S5)


@dataclass
class TeleopDiagram(MocapDiagram):
    """A built teleop diagram: the mocap part plus the mapper, the IK, the robot and the monitor."""

    mapper: object = None
    station: object = None
    ik: dict = field(default_factory=dict)
    monitor: object = None
    meshcat: object = None
    ik_time_step: float = 0.01
    clip_log: object = None
    gripper: object = None
    operator: object = None

    def simulate(self, num_frames: int | None = None, *, duration: float | None = None, progress: bool = False,
                 simulator: Simulator | None = None):
        """Run the teleoperation over the source's frames (or for ``duration`` seconds).

        Returns:
            ``(MocapLog, wall_seconds)``; the robot-side figures are on :attr:`monitor`.
        """
        sim = simulator or Simulator(self.diagram)
        sim.set_target_realtime_rate(0.0)
        sim.Initialize()
        period = camera_period(self.config)
        t_end = duration if duration is not None else self.duration(num_frames)
        wall = _progress_advance(sim, t_end, period, progress, "teleop")
        n = num_frames if num_frames is not None else (self.num_frames if duration is None else None)
        log = read_logs(self.loggers, sim.get_context(), period, n)
        self._last_context = sim.get_context()
        return log, wall


#: The Meshcat camera of the teleop view (world, metres): front left of the robot, looking at the robot, the
#: table and the operator's skeletons standing at the robot's left.
TELEOP_CAMERA_W = (2.0, 2.0, 1.7)
TELEOP_CAMERA_TARGET_W = (0.25, 0.55, 0.9)


def build_teleop_diagram(cfg: PipelineConfig | None = None, *, replay: Measurements | None = None,
                         frame_source=None, detector=None, dims: BodyDimensions | None = None, motion=None,
                         meshcat=None, lcm=None, time_step: float = 0.005, ik_time_step: float = 0.01,
                         keep_history: bool = True, mapping=None, log_stages: bool = True,
                         torso_model=None, smoothing: bool = True, workspace: bool = True,
                         hand_dropout=None, hand_apertures=None, hand_detector=None,
                         hand_knuckles=None, operator=None, motion_limits: bool | tuple | None = None) -> TeleopDiagram:
    """Build the teleoperation diagram: mocap (S1-S4) -> FrameMapper -> differential IK per arm -> robot.

    Args:
        cfg, replay, frame_source, detector, dims, motion: as :func:`build_mocap_diagram`.
        meshcat: a Meshcat to draw the robot, the raw (red) and corrected (blue) skeletons and the camera.
        lcm: a ``pydrake.lcm.DrakeLcm`` to publish the arm commands, measured arm positions and wrist targets on
            (:func:`~akc_drake.systems.lcm_publishers.AddLcmPublishers`; channels in README "Using the output").
        time_step: the robot plant's discrete step, seconds (5 ms: the PD actuators are implicit in the discrete
            solver, so this is stable, and it keeps the whole teleop loop at over 2x realtime on two cores).
        ik_time_step: the differential IK period, seconds.
        keep_history: keep the monitor's full history (for plots); off for long runs.
        mapping: the operator-to-robot :class:`~akc_drake.core.frames.RobotMapping` (default:
            :func:`~akc_drake.core.frames.calibrated_mapping` of ``dims``: the operator's reach scaled to the
            robot's, shoulders on shoulders).
        log_stages: add the per-stage VectorLogSinks (off for long runs: their logs grow with time).
        torso_model: a calibrated :class:`~akc_drake.core.frames.TorsoModel` (the torso carried by the hips);
            None: eq. (17)'s torso from the shoulders.
        smoothing: One Euro smoothing on SE(3) of the torso and wrist frames
            (:data:`~akc_drake.core.smoothing.WRIST_SMOOTHING`, :data:`~akc_drake.core.smoothing.TORSO_SMOOTHING`),
            with the wrist frames' hand vector rebuilt and kept off their mirror (``robust_wrist``).
        workspace: clip each target into its arm's :class:`~akc_drake.core.frames.Workspace`.
        hand_dropout: ``(frames,)`` bool, frames in which the hand channel is blanked too (``--dropout``).
        hand_apertures: ``(frames, 2)`` measured thumb-index distances to replay as the hand channel (e.g.
            MediaPipe Hands run on the rendered frames, with ``replay``).
        hand_knuckles: ``(frames, 2, 3)`` MediaPipe Hands' knuckle vectors measured on the replayed frames
            (:func:`~akc_drake.core.control_frames.hands_knuckle_vector`), for the wrist frames (with ``replay``).
        hand_detector: the hand detector on the camera's frames (default: MediaPipe Hands,
            :class:`~akc_drake.io.hand_detector.HandDetector`, on a ``frame_source``'s frames, or on the render of
            a ``motion`` with a hand closure when ``cfg.detector`` is ``mediapipe``).
        operator: a :class:`~akc_drake.operator.closed_loop.ClosedLoopOperator` (with ``motion``, its plan, and no
            ``replay``): the rendered operator watches the robot's tool and corrects it
            (:class:`~akc_drake.systems.operator_controller.OperatorController`, on :attr:`TeleopDiagram.operator`).
        motion_limits: each arm's command within its acceleration and jerk limits too
            (:class:`~akc_drake.robot.joint_motion_limiter.JointMotionLimiter`): None for ``cfg.arm_limits``
            (:class:`~akc_drake.config.ArmLimitsConfig`; by default :func:`~akc_drake.robot.model.arm_motion_limits`),
            True for the model's, ``(acceleration, jerk)`` arrays for others, False without. The
            :class:`~akc_drake.systems.teleop_monitor.TeleopMonitor` measures the commands against the same
            acceleration limits (the model's without the limiter).

    When ``motion`` has a hand closure (:attr:`~akc_drake.operator.motions.OperatorMotion.hand_closed`, e.g. the
    pick-and-place motion), the grippers are commanded from the hands: a
    :class:`~akc_drake.systems.gripper_command.HandApertureSource` (the thumb-index distance) feeds a
    :class:`~akc_drake.systems.gripper_command.GripperCommand` (pinch with hysteresis) wired to the station's
    finger inputs.
    """
    from akc_drake.core import smoothing as sm
    from akc_drake.core.frames import Workspace, calibrated_mapping
    from akc_drake.robot.diff_ik import AddArmDifferentialIK, make_arm_ik_plant
    from akc_drake.robot.model import arm_motion_limits, nominal_ee_pose
    from akc_drake.robot.station import AddRobotStation
    from akc_drake.systems.frame_mapper import FrameMapper
    from akc_drake.systems.teleop_monitor import TeleopMonitor

    cfg = _config_for_source(cfg, frame_source)
    dims = dims if dims is not None else resolve_dims(cfg)
    period = camera_period(cfg)
    builder = DiagramBuilder()
    from akc_drake.systems.skinned_body import hands_follow

    with hands_follow(motion):  # a rendered skinned body closes its hands as the motion does
        source = AddMeasurementSource(builder, cfg, replay=replay, frame_source=frame_source, detector=detector,
                                      motion=motion, operator_input=operator is not None)
    ports = AddMocapPipeline(builder, cfg, dims, source, teleop=True)
    loggers = AddStageLoggers(builder, ports, period) if log_stages else {}

    src = source["systems"]["source"]
    closes = motion is not None and getattr(motion, "hand_closed", None) is not None
    # Hands measured on the camera's frames: a real camera's, or a render of a motion whose hands close; their
    # knuckle lines also go to the FrameMapper's wrist frames (as the replays' recorded ones do).
    camera_hands = replay is None and hand_apertures is None and src.HasOutputPort("color_image") and (
        hand_detector is not None or frame_source is not None or (closes and cfg.detector == "mediapipe"))
    mapper = builder.AddSystem(
        FrameMapper(mapping if mapping is not None else calibrated_mapping(dims),
                    X_TE_home_left=nominal_ee_pose("left"), X_TE_home_right=nominal_ee_pose("right"),
                    period_s=period, stage_offset_s=cfg.stage_offset_s, torso_model=torso_model,
                    wrist_smoothing=sm.WRIST_SMOOTHING if smoothing else None,
                    torso_smoothing=sm.TORSO_SMOOTHING if smoothing else None,
                    workspace={s: Workspace.for_side(s) for s in ("left", "right")} if workspace else None,
                    robust_wrist=smoothing, torso_hold=sm.TORSO_HOLD if smoothing else None,
                    hand_knuckles_replay=hand_knuckles, hand_knuckles_input=bool(camera_hands))
    )
    mapper.set_name("FrameMapper")
    builder.Connect(ports.corrected, mapper.GetInputPort("landmarks_C"))

    station = AddRobotStation(builder, time_step=time_step, meshcat=meshcat, weld_base=True)
    ik = {}
    for side in ("left", "right"):
        limits = cfg.arm_limits.resolve(*arm_motion_limits(side)) if motion_limits is None else motion_limits
        arm = AddArmDifferentialIK(builder, make_arm_ik_plant(side), side, ik_time_step,
                                   measured_q_port=station.arm_position_output[side], motion_limits=limits)
        arm.integrator.set_name(f"DifferentialIK_{side}")
        builder.Connect(mapper.GetOutputPort(f"X_TE_desired_{side}"), arm.X_TE_desired_input)
        builder.Connect(arm.q_commanded_output, station.arm_position_input[side])
        # Feeding the IK's joint velocities forward removes most of the PD lag (17 mm -> 3 mm on a moving target).
        builder.Connect(arm.v_commanded_output, station.arm_velocity_input[side])
        ik[side] = arm

    monitor = builder.AddSystem(TeleopMonitor(
        station.plant, station.robot, ik_time_step, keep_history,
        acceleration_limits={s: ik[s].limiter.limits[1] for s in ik if ik[s].limiter is not None}))
    monitor.set_name("TeleopMonitor")
    for side in ("left", "right"):
        builder.Connect(mapper.GetOutputPort(f"X_TE_desired_{side}"), monitor.GetInputPort(f"X_TE_desired_{side}"))
        builder.Connect(ik[side].q_commanded_output, monitor.GetInputPort(f"q_commanded_{side}"))
    builder.Connect(mapper.GetOutputPort("tracking_lost"), monitor.GetInputPort("tracking_lost"))
    clip_log = builder.AddSystem(VectorLogSink(2, period))
    clip_log.set_name("log_workspace_clipped")
    builder.Connect(mapper.GetOutputPort("workspace_clipped"), clip_log.get_input_port())
    builder.Connect(station.robot_state_output, monitor.GetInputPort("robot_state"))
    controller = None
    if operator is not None:  # the closed loop: the operator watches the robot's tool
        from akc_drake.systems.operator_controller import OperatorController

        if replay is not None or frame_source is not None:
            raise ValueError("build_teleop_diagram: operator needs a rendered motion (no replay, no frame_source)")
        watched = None if station.scene is None else ("object", station.scene)  # the box, while carried
        controller = builder.AddSystem(OperatorController(operator, station.plant, station.robot, watched=watched))
        controller.set_name("OperatorController")
        builder.Connect(station.plant.get_state_output_port(), controller.GetInputPort("plant_state"))
        builder.Connect(controller.GetOutputPort("q_operator"), source["systems"]["source"].GetInputPort("q_operator"))

    gripper = None
    if camera_hands or closes:
        from akc_drake.systems.gripper_command import GripperCommand, HandApertureSource

        if camera_hands:  # the hands measured on the camera's frames (MediaPipe Hands)
            from akc_drake.systems.hand_aperture import HandApertureDetector

            if hand_detector is None:
                from akc_drake.io.hand_detector import HandDetector

                hand_detector = HandDetector()
                source["owned"].append(hand_detector)
            # after the extractor (its pose wrists of the same frame tell the hands apart), before the gripper
            hands = builder.AddSystem(HandApertureDetector(hand_detector, source["intrinsics"], period,
                                                           timing.stage_offset("filter", cfg.stage_offset_s)))
            hands.set_name("HandApertureDetector")
            for name in ("color_image", "depth_image"):
                builder.Connect(src.GetOutputPort(name), hands.GetInputPort(name))
            builder.Connect(source["pixels"], hands.GetInputPort("pixels"))
            builder.Connect(hands.GetOutputPort("hand_knuckles"), mapper.GetInputPort("hand_knuckles"))
        else:
            hands = builder.AddSystem(HandApertureSource(motion, period, seed=cfg.seed, dropout=hand_dropout,
                                                         apertures=hand_apertures))
            hands.set_name("HandApertureSource")
        gripper = builder.AddSystem(GripperCommand(period, timing.stage_offset("mapper", cfg.stage_offset_s)))
        gripper.set_name("GripperCommand")
        builder.Connect(hands.GetOutputPort("thumb_index_m"), gripper.GetInputPort("thumb_index_m"))
        for side in ("left", "right"):
            builder.Connect(gripper.GetOutputPort(f"{side}_opening"), station.gripper_input[side])

    if meshcat is not None:
        meshcat.SetCameraPose(TELEOP_CAMERA_W, TELEOP_CAMERA_TARGET_W)
        from akc_drake.systems.skeleton_visualizer import SkeletonVisualizer

        skel = builder.AddSystem(SkeletonVisualizer(meshcat, period_s=period,
                                                    offset_s=timing.stage_offset("mapper", cfg.stage_offset_s)))
        skel.set_name("SkeletonVisualizer")
        builder.Connect(ports.raw, skel.GetInputPort("landmarks_C_raw"))
        builder.Connect(ports.corrected, skel.GetInputPort("landmarks_C_corrected"))

    if lcm is not None:
        from akc_drake.systems.lcm_publishers import AddLcmPublishers

        sides = ("left", "right")
        AddLcmPublishers(builder, lcm, q_commanded={s: ik[s].q_commanded_output for s in sides},
                         q_measured=station.arm_position_output,
                         X_TE_desired={s: mapper.GetOutputPort(f"X_TE_desired_{s}") for s in sides},
                         tracking_lost=mapper.GetOutputPort("tracking_lost"), command_period_s=ik_time_step,
                         frame_period_s=period, frame_offset_s=timing.stage_offset("mapper", cfg.stage_offset_s))

    for side in ("left", "right"):
        builder.ExportOutput(ik[side].q_commanded_output, f"q_commanded_{side}")
    builder.ExportOutput(mapper.GetOutputPort("tracking_lost"), "tracking_lost")
    diagram = builder.Build()
    diagram.set_name("teleop")
    return TeleopDiagram(
        diagram, cfg, dims, ports, loggers, source.get("num_frames"), source.get("intrinsics"),
        owned=source["owned"], mapper=mapper, station=station, ik=ik, monitor=monitor, meshcat=meshcat,
        ik_time_step=ik_time_step, clip_log=clip_log, gripper=gripper, operator=controller,
    )
