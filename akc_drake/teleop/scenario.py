"""One teleoperation run: the scenario's constants, calibration from a rendered T-pose, rendering, the run.

See :mod:`akc_drake.teleop` for what the demo does and measures.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from akc_drake.robot.ik_status import IKStatusCounter, quiet_drake_warnings

#: The correctors compared: display name -> (filter, corrector) of the PipelineConfig.
CORRECTORS: dict[str, tuple[str, str]] = {
    "Raw": ("none", "none"),
    "KF": ("KF", "none"),
    "AKC(KF)": ("KF", "AKC"),
    "AKC+(KF)": ("KF", "AKC+"),  # ours: AKC with a temporally consistent candidate choice (core/akc_plus.py)
    "COIK(KF)": ("KF", "COIK"),
}
#: The configuration whose figures are the headline (and that is also run with rendering and recorded).
MAIN_CORRECTOR = "AKC(KF)"
#: The motions teleoperated, in order.
MOTIONS: tuple[str, ...] = ("I", "II")
#: Cycles per motion: ``--quick`` and the default.
QUICK_CYCLES = 1
FULL_CYCLES = 3
#: Seconds at the start of a run left out of the headline figures (the jump from the home pose).
SETTLING_S = 1.0
#: T-pose frames averaged by the calibration (paper §III-F).
CALIBRATION_FRAMES = 100
#: Length range of one burst of lost frames (seconds) for ``--dropout``.
DROPOUT_BURST_S: tuple[float, float] = (0.5, 3.0)
#: Seconds left between the two recorded runs in the Meshcat animation.
RECORDING_GAP_S = 1.0
SIDES = ("left", "right")


# ------------------------------------------------------------------------------------------------------------
# Motions and rendering


def truncate_motion(motion, max_frames: int, rate_hz: float):
    """``motion`` cut to its first ``max_frames`` camera frames (for quick checks); unchanged when shorter."""
    from akc_drake.operator.motions import OperatorMotion

    if max_frames is None:
        return motion
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 2:
        raise ValueError(f"max_frames must be an integer >= 2, got {max_frames!r}")
    t_last = motion.start + (max_frames - 1) / rate_hz
    if t_last >= motion.end:
        return motion
    keep = motion.times <= t_last + 1e-9
    m = int(np.count_nonzero(keep))
    if m < 2:
        raise ValueError(f"motion {motion.name!r} has too few samples for {max_frames} frames")
    cycles = None if motion.cycle_starts is None else motion.cycle_starts[motion.cycle_starts <= t_last]
    return OperatorMotion(motion.times[:m], motion.q_left[:m], motion.q_right[:m], motion.name, cycles)


def render_motion(motion, cfg, *, seed: int = 0, progress: bool = False, frame_callback=None, detector=None):
    """Render ``motion`` with the camera of ``cfg`` (:func:`~akc_drake.diagrams.sim_camera`), with a tqdm bar.

    A skinned body's hands close as the motion's ``hand_closed`` says; ``frame_callback`` is called with each
    :class:`~akc_drake.core.camera.CameraFrame` (e.g. to run the hand detector on it); ``detector``: a pose
    detector object to use instead of ``cfg.detector``'s (the caller closes it).

    Returns:
        The :class:`~akc_drake.systems.depth_camera_source.Session`.
    """
    from tqdm import tqdm

    from akc_drake.diagrams import sim_camera
    from akc_drake.systems.depth_camera_source import render_session
    from akc_drake.systems.skinned_body import hands_follow

    intrinsics, placement, noise = sim_camera(cfg)
    n = len(motion.frame_times(intrinsics.rate_hz))
    with tqdm(
        total=n,
        desc=f"render {motion.name}",
        unit="frame",
        file=sys.stderr,
        disable=not progress,
        leave=False,
    ) as bar, hands_follow(motion):
        return render_session(
            motion,
            intrinsics,
            placement,
            noise,
            seed=seed,
            detector=detector if detector is not None else getattr(cfg, "detector", None),
            body=getattr(cfg, "body", "primitive"),
            progress=lambda k, total: bar.update(1),
            frame_callback=frame_callback,
        )


@dataclass
class Calibration:
    """The demo's T-pose calibration.

    Attributes:
        dims: the calibrated body dimensions.
        report: the :class:`~akc_drake.core.calibration.CalibrationReport`.
        frames: frames averaged.
        wall_s: seconds spent (render + filter + calibration).
    """

    dims: object
    report: object
    frames: int
    wall_s: float
    torso: object = None


def calibrate_from_tpose(
    cfg,
    *,
    seed: int = 0,
    frames: int = CALIBRATION_FRAMES,
    progress: bool = False,
    max_frames: int | None = None,
) -> Calibration:
    """Render a held T-pose, run it through the occlusion filter and the KF, calibrate on ``frames`` frames.

    Args:
        cfg: the pipeline configuration (its camera; the filter is forced to KF, no corrector).
        seed: motion sway, depth noise and detector seed.
        frames: frames to average (the paper: 100).
        progress: show a progress bar.
        max_frames: render at most this many frames (quick checks); ``frames`` is capped to it.
    """
    import dataclasses

    from akc_drake.core.calibration import calibrate_report
    from akc_drake.diagrams import Measurements, build_mocap_diagram
    from akc_drake.operator.motions import make_motion

    t0 = time.perf_counter()
    rate = float(cfg.camera.rate_hz)
    motion = make_motion("tpose", 1, seed)
    if max_frames is not None:
        motion = truncate_motion(motion, max_frames, rate)
        frames = min(frames, max_frames)
    session = render_motion(motion, cfg, seed=seed, progress=progress)
    kf_cfg = dataclasses.replace(cfg, filter="KF", corrector="none").validate()
    built = build_mocap_diagram(kf_cfg, replay=Measurements.from_session(session))
    n = min(frames, built.num_frames)
    log, _ = built.simulate(n)
    dims, report = calibrate_report(log.estimated[:n], "tpose")
    from akc_drake.core.control_frames import calibrate_torso

    torso = calibrate_torso(log.estimated[:n])  # the hip-carried torso, its vertical from the trunk
    return Calibration(dims, report, n, time.perf_counter() - t0, torso)


# ------------------------------------------------------------------------------------------------------------
# One teleoperation run


@dataclass
class TeleopRun:
    """One teleoperation run and what the robot side of the loop measured.

    Times are relative to the run's start. Per-frame arrays hold one sample per camera frame ``k``, taken at
    ``t_k + period - ik_period`` (the end of the frame's period, when frame ``k``'s target is still the one
    commanded).

    Attributes:
        motion, corrector: what was run (corrector as in :data:`CORRECTORS`).
        rendered: True when the camera frames were rendered inside the diagram (else replayed).
        frames: camera frames run.
        period_s: camera period.
        sim_s, wall_s: simulated and wall-clock seconds of the simulation.
        nan_commands, position_limit_hits, velocity_limit_hits, max_speed_ratio, acceleration_limit_hits,
            max_acceleration_ratio: from the monitor.
        tracking_lost_share: share of IK-period samples with either side's tracking lost.
        ik_steps, ik_failures: per side (:class:`IKStatusCounter`); ik_failure_kinds: per status.
        ik_relaxed, ik_joint_space: per side, IK steps the position-only fallback, the joint-space move drove.
        error_t, errors: per side, the monitor's target-to-achieved distances (m) and their times.
        frame_t: ``(frames,)`` per-frame sample times.
        target: per side ``(frames, 4, 4)`` X_TE_desired (NaN where no sample).
        reachable_target: per side ``(frames, 3)`` the target position after the IK's reach guard.
        ee: per side ``(frames, 3)`` achieved end-effector position in T.
        operator: per side ``(frames, 4, 4)`` the operator's true wrist frame mapped to the robot (NaN when
            unknown): what a perfect pipeline would command.
        dropout: ``(frames,)`` bool, frames blanked by ``--dropout``.
    """

    motion: str
    corrector: str
    rendered: bool
    frames: int
    period_s: float
    sim_s: float
    wall_s: float
    nan_commands: int
    position_limit_hits: int
    velocity_limit_hits: int
    max_speed_ratio: float
    tracking_lost_share: float
    ik_steps: dict
    ik_failures: dict
    ik_failure_kinds: dict
    error_t: dict
    errors: dict
    frame_t: np.ndarray
    target: dict
    reachable_target: dict
    ee: dict
    operator: dict
    dropout: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    clipped: dict = field(default_factory=dict)
    ik_relaxed: dict = field(default_factory=dict)
    ik_joint_space: dict = field(default_factory=dict)
    box_pose: np.ndarray | None = None
    box_contacts: tuple = ()
    gripper_closed: np.ndarray | None = None
    unsmoothed: dict = field(default_factory=dict)
    acceleration_limit_hits: int = 0
    max_acceleration_ratio: float = 0.0

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.nan


def _frame_sample_indices(hist_t: np.ndarray, start: float, n: int, period: float, h: float) -> np.ndarray:
    """Index in the monitor history of each frame's sample (at ``start + (k + 1) period - h``); -1: none."""
    want = start + (np.arange(n) + 1) * period - h
    if hist_t.size == 0:
        return np.full(n, -1)
    idx = np.clip(np.searchsorted(hist_t, want), 0, hist_t.size - 1)
    prev = np.clip(idx - 1, 0, hist_t.size - 1)
    best = np.where(np.abs(hist_t[prev] - want) < np.abs(hist_t[idx] - want), prev, idx)
    return np.where(np.abs(hist_t[best] - want) < 0.5 * h, best, -1)


def operator_targets(truth_C: np.ndarray | None, n: int, mapping, workspace=None) -> dict[str, np.ndarray]:
    """Per side ``(n, 4, 4)``: the operator's true wrist frame mapped to the robot, ``X_TE``, through the same
    mapping as the pipeline's targets, workspace clip included (``workspace``: per side a
    :class:`~akc_drake.core.frames.Workspace`, None: no clip); NaN where degenerate or unknown."""
    from akc_drake.core.frames import robot_targets

    out = {s: np.full((n, 4, 4), np.nan) for s in SIDES}
    if truth_C is None:
        return out
    truth = np.asarray(truth_C, dtype=float)
    for k in range(min(n, truth.shape[0])):
        if not np.all(np.isfinite(truth[k])):
            continue
        X_l, X_r = robot_targets(truth[k], mapping)
        for side, X in zip(SIDES, (X_l, X_r), strict=True):
            if X is not None:
                if workspace is not None:
                    X[:3, 3] = workspace[side].clip(X[:3, 3])[0]
                out[side][k] = X
    return out


def _box_pose(td, sim) -> np.ndarray | None:
    """The box's (``object``) pose in the world at the end of the run, 4x4 (None without a scene)."""
    st = td.station
    if st.scene is None:
        return None
    plant_ctx = st.plant.GetMyContextFromRoot(sim.get_context())
    return st.plant.GetBodyByName("object", st.scene).EvalPoseInWorld(plant_ctx).GetAsMatrix4()


def _box_contacts(td, sim) -> tuple[str, ...]:
    """Names of the bodies touching the box at the end of the run (point and hydroelastic contacts)."""
    st = td.station
    if st.scene is None:
        return ()
    plant = st.plant
    plant_ctx = plant.GetMyContextFromRoot(sim.get_context())
    box = plant.GetBodyByName("object", st.scene).index()
    results = plant.get_contact_results_output_port().Eval(plant_ctx)
    inspector = st.scene_graph.model_inspector()
    names = set()
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        a, b = info.bodyA_index(), info.bodyB_index()
        if box in (a, b):
            names.add(plant.get_body(b if a == box else a).name())
    for i in range(results.num_hydroelastic_contacts()):
        surface = results.hydroelastic_contact_info(i).contact_surface()
        bodies = [plant.GetBodyFromFrameId(inspector.GetFrameId(g)).index() for g in (surface.id_M(), surface.id_N())]
        if box in bodies:
            other = bodies[1] if bodies[0] == box else bodies[0]
            names.add(plant.get_body(other).name())
    return tuple(sorted(names))


def _clipped_frames(td, sim, n: int) -> dict[str, np.ndarray]:
    """Per side ``(n,)`` bool: frames whose target the FrameMapper clipped into the arm's workspace."""
    data = td.clip_log.FindLog(sim.get_context()).data().T
    out = {}
    for k, side in enumerate(SIDES):
        v = np.zeros(n, dtype=bool)
        # One sample per camera tick after the mapper's update; the first (t = start) is the initial state.
        vals = data[1 : n + 1, k] > 0.5 if data.shape[0] > 1 else np.zeros(0, dtype=bool)
        v[: len(vals)] = vals
        out[side] = v
    return out


def _unsmoothed_targets(td, sim, n: int, start: float, period: float, torso_model) -> dict[str, np.ndarray]:
    """Per side ``(n, 4, 4)``: the targets the same tracker gives without the wrist smoothing, from the
    corrected landmarks the diagram logged (for the smoothing's added latency); NaN when unknown."""
    from akc_drake.core.control_frames import ControlFrameTracker

    out = {s: np.full((n, 4, 4), np.nan) for s in SIDES}
    log = td.loggers.get("corrected")
    if log is None:
        return out
    data = log.FindLog(sim.get_context())
    times, values = data.sample_times(), data.data().T
    # The same torso (smoothed and held) and workspace clip as the FrameMapper's: the difference is the wrist
    # smoothing alone.
    mine = td.mapper.tracker
    tracker = ControlFrameTracker(td.mapper.mapping, torso_model=torso_model, wrist_smoothing=None,
                                  torso_smoothing=mine.torso_smoothing, torso_hold=mine.torso_hold,
                                  workspace=mine.workspace, robust_wrist=mine.robust_wrist)
    state = tracker.initial_state()
    for k in range(n):
        j = int(np.searchsorted(times, start + (k + 1) * period - 1e-9))
        if j >= len(times):
            break
        kn = td.mapper.hand_knuckles_replay
        knuckles = None if kn is None or not len(kn) else kn[min(k, len(kn) - 1)]
        state, targets, _, _ = tracker.step(state, start + k * period, values[j].reshape(-1, 3), knuckles)
        for side, X in zip(SIDES, targets, strict=True):
            if X is not None:
                out[side][k] = X
    return out


def make_meshcat():
    """A Meshcat server on localhost (Drake's default would listen on every interface): ``(meshcat, None)``, or
    ``(None, reason)`` when it cannot start."""
    try:
        from pydrake.geometry import Meshcat, MeshcatParams

        params = MeshcatParams()
        params.host = "localhost"
        return Meshcat(params), None
    except Exception as e:  # a port range in use, no sockets allowed, ...
        return None, f"{type(e).__name__}: {e}"




def run_teleop(
    cfg,
    dims,
    *,
    corrector: str = MAIN_CORRECTOR,
    replay=None,
    motion=None,
    num_frames: int | None = None,
    meshcat=None,
    start_time: float = 0.0,
    dropout: np.ndarray | None = None,
    truth_C: np.ndarray | None = None,
    progress: bool = False,
    torso_model=None,
    settle_s: float = 0.0,
    **diagram_kwargs,
):
    """Build the teleop diagram for ``corrector`` and run it once.

    Args:
        cfg: the pipeline configuration (its filter and corrector are set from ``corrector``).
        dims: the calibrated body dimensions.
        corrector: a key of :data:`CORRECTORS`.
        replay: :class:`~akc_drake.diagrams.Measurements` to replay; None: render ``motion`` in the diagram.
        motion: the operator motion (for the rendering source; its name labels the run).
        num_frames: frames to run (default: all of the source's).
        meshcat: a Meshcat to draw (and record) the run in.
        start_time: the simulation's start time (the Meshcat recording puts runs one after the other).
        dropout: ``(frames,)`` bool, the frames the replay had blanked (for the report only).
        truth_C: ``(frames, 12, 3)`` the operator's true landmarks in C (default: the replay's), for the
            error to the operator.
        progress: show a progress bar.
        torso_model: the calibrated :class:`~akc_drake.core.frames.TorsoModel` (None: eq. 17's torso).
        settle_s: simulate this much longer after the last frame (the robot holds the last targets; e.g. for
            a placed object to come to rest before it is scored).
        **diagram_kwargs: passed to :func:`~akc_drake.diagrams.build_teleop_diagram`.

    Returns:
        ``(TeleopRun, TeleopDiagram)``.
    """
    import dataclasses

    from pydrake.math import RigidTransform
    from pydrake.systems.analysis import Simulator

    from akc_drake.diagrams import build_teleop_diagram, camera_period

    if corrector not in CORRECTORS:
        raise ValueError(f"corrector must be one of {', '.join(CORRECTORS)}, got {corrector!r}")
    if replay is None and motion is None:
        raise ValueError("run_teleop: give replay (measurements) or motion (to render)")
    filt, corr = CORRECTORS[corrector]
    cfg = dataclasses.replace(cfg, filter=filt, corrector=corr).validate()
    td = build_teleop_diagram(
        cfg,
        replay=replay,
        motion=motion,
        dims=dims,
        meshcat=meshcat,
        keep_history=True,
        torso_model=torso_model,
        **diagram_kwargs,
    )
    n = int(num_frames if num_frames is not None else td.num_frames)
    if n < 1:
        raise ValueError(f"run_teleop: need at least one frame, got {n}")
    period = camera_period(cfg)
    h = float(td.ik_time_step)
    sim = Simulator(td.diagram)
    counter = IKStatusCounter(td.ik, h, start_time)
    sim.set_monitor(counter)
    sim.get_mutable_context().SetTime(float(start_time))
    t_end = float(start_time) + td.duration(n) + float(settle_s)
    with quiet_drake_warnings():
        _, wall = td.simulate(duration=t_end, simulator=sim, progress=progress)

    mon = td.monitor
    hist = mon.history_arrays()
    hist_t = np.asarray(hist["t"], dtype=float)
    idx = _frame_sample_indices(hist_t, float(start_time), n, period, h)
    found = idx >= 0
    target, reach, ee = {}, {}, {}
    for side in SIDES:
        T = np.full((n, 4, 4), np.nan)
        E = np.full((n, 3), np.nan)
        if found.any():
            T[found] = np.asarray(hist[f"target_{side}"])[idx[found]]
            E[found] = np.asarray(hist[f"ee_{side}"])[idx[found]][:, :3, 3]
        R = np.full((n, 3), np.nan)
        guard = td.ik[side].pose_guard
        for k in np.flatnonzero(found & np.all(np.isfinite(T), axis=(1, 2))):
            R[k] = guard.project(RigidTransform(T[k])).translation()
        target[side], reach[side], ee[side] = T, R, E
    lost = np.asarray(hist["lost"], dtype=float).reshape(-1, 2) if len(hist["lost"]) else np.zeros((0, 2))
    truth = truth_C if truth_C is not None else (replay.truth_C if replay is not None else None)
    run = TeleopRun(
        motion=getattr(motion, "name", None) or "replay",
        corrector=corrector,
        rendered=replay is None,
        frames=n,
        period_s=period,
        sim_s=t_end - float(start_time),
        wall_s=float(wall),
        nan_commands=int(mon.nan_commands),
        position_limit_hits=int(mon.position_limit_hits),
        velocity_limit_hits=int(mon.velocity_limit_hits),
        max_speed_ratio=float(mon.max_speed_ratio),
        acceleration_limit_hits=int(mon.acceleration_limit_hits),
        max_acceleration_ratio=float(mon.max_acceleration_ratio),
        tracking_lost_share=float(np.mean(np.any(lost > 0.5, axis=1))) if lost.size else math.nan,
        ik_steps=dict(counter.steps),
        ik_failures=dict(counter.failures),
        ik_failure_kinds=dict(counter.kinds),
        ik_relaxed=dict(counter.relaxed),
        ik_joint_space=dict(counter.joint_space),
        box_pose=_box_pose(td, sim),
        box_contacts=_box_contacts(td, sim),
        gripper_closed=None
        if td.gripper is None
        else np.array(td.gripper.GetOutputPort("closed").Eval(td.gripper.GetMyContextFromRoot(sim.get_context()))),
        error_t={s: mon.ee_error_times(s) - float(start_time) for s in SIDES},
        errors={s: mon.ee_errors(s) for s in SIDES},
        frame_t=(np.arange(n) + 1) * period - h,
        target=target,
        reachable_target=reach,
        ee=ee,
        operator=operator_targets(truth, n, td.mapper.mapping, td.mapper.tracker.workspace),
        dropout=np.zeros(n, dtype=bool) if dropout is None else np.asarray(dropout, dtype=bool)[:n],
        clipped=_clipped_frames(td, sim, n),
        unsmoothed=_unsmoothed_targets(td, sim, n, float(start_time), period, torso_model),
    )
    return run, td
