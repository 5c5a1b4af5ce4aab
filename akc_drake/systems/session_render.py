"""Rendering a whole motion frame by frame, without a simulator: the evaluation's fast path.

:func:`render_session` reuses one :class:`~akc_drake.systems.depth_camera_source.DepthCameraSource` and its
context, renders each frame once, runs the landmark extraction of stage S2 on it (the simulated detector or
MediaPipe, :func:`make_detector`), and returns the raw measurements with the ground truth as a
:class:`Session`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from akc_drake.core.camera import CameraFrame, CameraIntrinsics, Detector
from akc_drake.core.depth_noise import StereoDepthNoise
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.operator.model import OperatorParams
from akc_drake.operator.motions import OperatorMotion


@dataclass
class Session:
    """A rendered motion with its raw stage-S2 measurements and the ground truth.

    Attributes:
        t: ``(T,)`` frame times (seconds from the motion's start).
        raw: ``(T, 12, 3)`` raw landmarks in C from the extractor (NaN where missing).
        visibility: ``(T, 12)`` detector visibility.
        pixels: ``(T, 12, 2)`` detected pixels.
        truth: ``(T, 12, 3)`` true landmarks in C.
        intrinsics: the camera.
        motion_name: the motion's name.
        cycle_starts: start times of the motion's cycles (or None).
        X_OC: ``(4, 4)`` camera pose in the operator frame.
        render_s: ``(T,)`` seconds spent rendering each frame (colour if rendered, depth, noise).
        extract_s: ``(T,)`` seconds spent in detection + depth lookup + deprojection.
    """

    t: np.ndarray
    raw: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray
    truth: np.ndarray
    intrinsics: CameraIntrinsics
    motion_name: str = ""
    cycle_starts: np.ndarray | None = None
    X_OC: np.ndarray = field(default_factory=lambda: np.eye(4))
    render_s: np.ndarray | None = None
    extract_s: np.ndarray | None = None

    @property
    def landmarks_C(self) -> np.ndarray:
        """Alias of :attr:`raw`."""
        return self.raw

    @property
    def source_time_s(self) -> np.ndarray | None:
        """``(T,)`` time of stages S1 + S2 per frame (render + extraction), seconds."""
        if self.render_s is None or self.extract_s is None:
            return None
        return self.render_s + self.extract_s

    def __len__(self) -> int:
        return len(self.t)


def images_needed(detector: Detector | None) -> tuple[bool, bool]:
    """``(colour, label)``: which images ``detector`` looks at, so a source renders only those.

    A detector declares ``needs_color`` / ``needs_label`` (both assumed True when absent); None stands for the
    default :class:`~akc_drake.core.sim_detector.SimulatedDetector`, which reads depth only.
    """
    if detector is None:
        from akc_drake.core.sim_detector import SimulatedDetector

        detector = SimulatedDetector
    return bool(getattr(detector, "needs_color", True)), bool(getattr(detector, "needs_label", True))


#: The detectors a simulated session can use (``--detector``).
DETECTORS = ("sim", "mediapipe")


def make_detector(detector, seed: int = 0, pose_model=None) -> Detector:
    """A Detector from a name ("sim": :class:`~akc_drake.core.sim_detector.SimulatedDetector`, "mediapipe":
    :class:`~akc_drake.io.mediapipe_detector.MediaPipeDetector`), or ``detector`` itself when it is one.

    Raises:
        ValueError: an unknown name. UserError: MediaPipe or its model missing.
    """
    if detector is None or detector == "sim":
        from akc_drake.core.sim_detector import SimulatedDetector

        return SimulatedDetector(seed=seed)
    if detector == "mediapipe":
        from akc_drake.io.mediapipe_detector import MediaPipeDetector

        return MediaPipeDetector(model_path=pose_model)
    if isinstance(detector, str):
        raise ValueError(f"detector must be one of {', '.join(DETECTORS)}, got {detector!r}")
    return detector


def rig_drive_for(rig_clip: dict, motion: OperatorMotion, skinned):
    """The :class:`~akc_drake.operator.rig_drive.RigDrive` of ``rig_clip`` (``{"path", "skeleton",
    "window_s"}``, optionally ``"names"``: role -> joint, as ``--joint-names``) on the skinned body, sampled at
    ``motion``'s frame times.

    Raises:
        UserError: no skinned body (``--drive rig`` needs ``--body skinned``), or a clip the rig cannot take.
    """
    from akc_drake.errors import UserError
    from akc_drake.operator.rig_drive import RigDrive, read_clip

    if skinned is None:
        raise UserError(f"{rig_clip.get('path')}: the rig drive needs the skinned body (--body skinned)")
    rate = 1.0 / float(motion.times[1] - motion.times[0])
    clip = read_clip(rig_clip["path"], rig_clip.get("skeleton"), rate_hz=rate, window_s=rig_clip.get("window_s"),
                     name=motion.name, roles=rig_clip.get("names"))
    t = motion.times - motion.start
    if len(clip.times) != len(t) or not np.allclose(clip.times, t, atol=1e-6):
        raise ValueError(f"{rig_clip['path']}: the clip's samples ({len(clip.times)}) are not the motion's ({len(t)})")
    return RigDrive(clip, skinned)


def render_session(
    motion: OperatorMotion,
    intrinsics: CameraIntrinsics | None = None,
    camera_pose=None,
    noise: StereoDepthNoise | None = None,
    seed: int = 0,
    detector: Detector | str | None = None,
    *,
    body: str = "primitive",
    params: OperatorParams | None = None,
    progress: Callable[[int, int], None] | None = None,
    frame_callback: Callable[[CameraFrame], None] | None = None,
    render_color: bool | None = None,
    background_wall_m: float | None = 1.5,
    window: int | None = None,
    surface_offset_m=None,
    depth_rule: str | None = None,
    rig_clip: dict | None = None,
) -> Session:
    """Render ``motion`` frame by frame and extract raw landmarks, without a simulator.

    One :class:`DepthCameraSource` and one context are reused; each frame (``t_k = k / rate``) is rendered
    once, corrupted with the same noise the diagram would apply, passed to ``detector`` and through the
    extractor's depth lookup, surface-to-centre correction and deprojection
    (:func:`~akc_drake.core.landmark_extraction.extract_landmarks`).
    The values equal what the mocap diagram's LandmarkExtractor computes for the same frames.

    Args:
        motion: the operator's motion.
        intrinsics: the camera (default: 640x480, 10 Hz).
        camera_pose: :class:`CameraPlacement`, RigidTransform X_OC or 4x4 (default placement).
        noise: depth error model (default: :class:`StereoDepthNoise`).
        seed: seeds the depth noise, and the default detector.
        detector: any Detector, or a name of :data:`DETECTORS` (default "sim": ``SimulatedDetector(seed=seed)``;
            "mediapipe": MediaPipe on the rendered colour image).
        body: "primitive" or "skinned" (see :class:`DepthCameraSource`).
        params: the operator (default: the paper's participant).
        progress: called as ``progress(k + 1, T)`` after each frame.
        frame_callback: called with each :class:`CameraFrame` (e.g. to record it); the frame owns its
            arrays, so it may be kept.
        render_color: render the colour image; None: only when the detector or ``frame_callback`` needs it
            (a detector declares ``needs_color = False`` to skip it; the frame then carries a black image).
        background_wall_m: see :class:`DepthCameraSource`.
        window: depth-lookup window (pixels; None: the extractor's default for the camera,
            :func:`~akc_drake.core.landmark_extraction.default_depth_window`).
        depth_rule: the depth lookup's rule, ``nearest`` or ``median`` (None: the extractor's default,
            :data:`~akc_drake.core.landmark_extraction.DEFAULT_DEPTH_RULE`).
        surface_offset_m: the extractor's surface-to-centre depth offsets
            (:func:`~akc_drake.core.landmark_extraction.surface_offsets`; None: the same defaults as
            :class:`~akc_drake.systems.landmark_extractor.LandmarkExtractor`, 0: off).
        rig_clip: ``{"path", "skeleton", "window_s"}`` of the CMU clip ``motion`` was retargeted from: the
            skinned body is then driven by the clip bone by bone (:mod:`akc_drake.operator.rig_drive`: spine,
            clavicles, neck and head move too) and the truth is the posed rig's; ``motion`` only sets the
            frame times. None: the body follows ``motion``'s 10 angles.

    Returns:
        A :class:`Session`.
    """
    from akc_drake.core.landmark_extraction import (
        DEFAULT_DEPTH_RULE,
        check_extractor_options,
        default_depth_window,
        extract_landmarks,
        surface_offsets,
    )
    from akc_drake.systems.depth_camera_source import DepthCameraSource

    K = intrinsics or CameraIntrinsics()
    offsets = surface_offsets(surface_offset_m)
    window = default_depth_window(K) if window is None else window
    depth_rule = DEFAULT_DEPTH_RULE if depth_rule is None else depth_rule
    owned = isinstance(detector, str)  # a detector made here from its name is closed here
    detector = make_detector(detector, seed)
    try:
        check_extractor_options(detector, K, window, None, depth_rule)
    except ValueError:
        if owned and hasattr(detector, "close"):
            detector.close()
        raise
    needs_color, need_label = images_needed(detector)
    if render_color is None:
        render_color = frame_callback is not None or needs_color
    source = DepthCameraSource(
        motion,
        intrinsics=K,
        camera_pose=camera_pose,
        noise=noise,
        seed=seed,
        params=params,
        render_label=need_label,
        background_wall_m=background_wall_m,
        body=body,
    )
    drive = None if rig_clip is None else rig_drive_for(rig_clip, motion, source.skinned)
    if drive is not None:
        source.skinned_system.drive_rig(drive)
        X_CO = source.X_OC.inverse()
        R_CO, p_CO = X_CO.rotation().matrix(), X_CO.translation()
    context = source.CreateDefaultContext()
    sensor_ctx = source.sensor.GetMyContextFromRoot(context)
    noise_ctx = source.noise_system.GetMyContextFromRoot(context)
    truth_ctx = source.truth_system.GetMyContextFromRoot(context)
    color_port = source.sensor.color_image_output_port()
    label_port = source.sensor.label_image_output_port()
    depth_port = source.noise_system.get_output_port()
    truth_port = source.truth_system.get_output_port()

    times = np.arange(int(math.floor(motion.duration * K.rate_hz + 1e-9)) + 1) / K.rate_hz
    T = len(times)
    raw = np.full((T, NUM_LANDMARKS, 3), np.nan)
    vis = np.zeros((T, NUM_LANDMARKS))
    pix = np.full((T, NUM_LANDMARKS, 2), np.nan)
    truth = np.full((T, NUM_LANDMARKS, 3), np.nan)
    render_s = np.zeros(T)
    extract_s = np.zeros(T)
    black = np.zeros((K.height, K.width, 3), dtype=np.uint8)
    black.flags.writeable = False
    for k, t in enumerate(times):
        t0 = time.perf_counter()
        context.SetTime(float(t))
        # Copies: the frame owns its arrays (Drake reuses its image buffers for the next frame).
        color = np.ascontiguousarray(color_port.Eval(sensor_ctx).data[:, :, :3]) if render_color else black
        depth = depth_port.Eval(noise_ctx).data[:, :, 0].copy()
        label = label_port.Eval(sensor_ctx).data[:, :, 0].copy() if need_label else None
        if drive is None:
            truth[k] = truth_port.Eval(truth_ctx).reshape(NUM_LANDMARKS, 3)
        else:
            truth[k] = drive.landmarks_O[drive.index(t)] @ R_CO.T + p_CO
        t1 = time.perf_counter()
        frame = CameraFrame(
            color=color, depth_m=depth, t=float(t), intrinsics=K, truth_C=truth[k], label=label
        )
        raw[k], vis[k], pix[k] = extract_landmarks(frame, detector, window=window, surface_offset_m=offsets,
                                                   depth_rule=depth_rule)
        t2 = time.perf_counter()
        render_s[k], extract_s[k] = t1 - t0, t2 - t1
        if frame_callback is not None:
            frame_callback(frame)
        if progress is not None:
            progress(k + 1, T)
    if owned and hasattr(detector, "close"):
        detector.close()
    return Session(
        t=times,
        raw=raw,
        visibility=vis,
        pixels=pix,
        truth=truth,
        intrinsics=K,
        motion_name=motion.name,
        cycle_starts=None if motion.cycle_starts is None else motion.cycle_starts - motion.start,
        X_OC=source.X_OC.GetAsMatrix4(),
        render_s=render_s,
        extract_s=extract_s,
    )
