"""The demo's logic: teleoperate the simulated robot from the rendered operator; compare the correctors.

:func:`run_demo` does the whole job of ``akc-drake demo``:

1. **Calibrate** from a rendered T-pose: its first 100 frames, through the occlusion filter and the KF (the
   mocap diagram on a replay), averaged by :func:`~akc_drake.core.calibration.calibrate_report`.
2. **Render** Motion I and Motion II once each
   (:func:`~akc_drake.systems.depth_camera_source.render_session`). With ``dropout > 0``, the same bursts of
   lost frames (the whole person, 0.5-3 s each, seeded: :func:`akc_drake.faults.inject_dropouts`) are
   blanked in every corrector's replay.
3. **Teleoperate** the robot with each corrector (:data:`CORRECTORS`: Raw, KF, AKC(KF), COIK(KF)) by
   replaying the same measurements through the teleop diagram, and once more with the AKC(KF) pipeline
   *rendering* its camera frames inside the diagram (the realtime factor of the full pipeline).
4. **Report**: a table per motion and pooled (:func:`format_table`), ``demo.json``, the end-effector paths
   and the tracking error over time (PNG), the Meshcat recording of the AKC(KF) runs as a standalone HTML
   page and the teleop diagram's graph (.dot/.svg).

What is measured (the robot side of the loop, :class:`~akc_drake.systems.teleop_monitor.TeleopMonitor`):

* **End-effector tracking error**: distance between the mapped target ``X_TE_desired`` (the FrameMapper's
  output, before the IK's reach guard) and the achieved end-effector position, sampled once per camera
  frame at the end of the frame's period (``t_k + 0.09 s``). The first target jumps from the robot's home
  pose to the operator's mapped wrist, so the headline ``ee_tracking_error_cm`` is the median **after the
  first second** (:data:`SETTLING_S`); ``ee_tracking_error_cm_with_settling`` includes it.
* **Error to the operator**: distance between the achieved end effector and the operator's *true* wrist
  mapped to the robot (the ground truth through the same mapping), same samples: what correctors are for.
* **Control-frame jitter**: RMS angular (rad/s) and linear (m/s) speed of ``X_TE_desired`` between
  consecutive camera frames (:func:`~akc_drake.core.frames.frame_jitter`), after the first second; the
  operator's true mapped wrist gives the reference (the motion's own speed).
* **Limit hits**: IK-period samples where a commanded joint is within 1e-3 rad of a position limit, or where
  a joint's commanded step reaches 97 % of its velocity limit (counted per arm).
* **IK failures**: differential-IK steps (100 Hz, per arm) whose status was not "solution found" ("no
  solution" or "stuck"). Counted by :class:`IKStatusCounter`, a simulator monitor that reads each
  integrator's status once after every IK update.
* **NaN commands**: IK-period samples where a joint command was not finite (must be 0).
* **Realtime factor**: simulated seconds / wall-clock seconds of ``simulate`` (construction excluded).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write, atomic_write_text

#: The correctors compared: display name -> (filter, corrector) of the PipelineConfig.
CORRECTORS: dict[str, tuple[str, str]] = {
    "Raw": ("none", "none"),
    "KF": ("KF", "none"),
    "AKC(KF)": ("KF", "AKC"),
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


def render_motion(motion, cfg, *, seed: int = 0, progress: bool = False):
    """Render ``motion`` with the camera of ``cfg`` (:func:`~akc_drake.diagrams.sim_camera`), with a tqdm bar.

    Returns:
        The :class:`~akc_drake.systems.depth_camera_source.Session`.
    """
    from tqdm import tqdm

    from akc_drake.diagrams import sim_camera
    from akc_drake.systems.depth_camera_source import render_session

    intrinsics, placement, noise = sim_camera(cfg)
    n = len(motion.frame_times(intrinsics.rate_hz))
    with tqdm(
        total=n,
        desc=f"render {motion.name}",
        unit="frame",
        file=sys.stderr,
        disable=not progress,
        leave=False,
    ) as bar:
        return render_session(
            motion, intrinsics, placement, noise, seed=seed, progress=lambda k, total: bar.update(1)
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
    return Calibration(dims, report, n, time.perf_counter() - t0)


# ------------------------------------------------------------------------------------------------------------
# One teleoperation run


class IKStatusCounter:
    """A simulator monitor counting the differential-IK steps per arm and those without a solution.

    :meth:`~akc_drake.robot.diff_ik.ArmDifferentialIK.status` is only the latest step's status, so it is
    read after every IK update: the simulator calls the monitor at the end of each step, and at a call at time
    ``t`` the latest IK update is the one at ``ceil(t / h) - 1`` periods (updates at ``t`` itself are applied
    at the start of the next step). Each update is counted once; the diagram's plant steps (2 ms) are
    shorter than the IK period (10 ms), so no update is missed.

    Args:
        ik: ``{"left": ArmDifferentialIK, "right": ArmDifferentialIK}``.
        time_step: the IK period, seconds.
        start_time: the run's start time; IK updates before it are not counted.

    Attributes:
        steps: per side, IK updates seen.
        failures: per side, updates whose status was not "solution found".
        kinds: per status name ("no solution", "stuck"), updates with it (both arms).
    """

    _NAMES = {1: "no solution", 2: "stuck"}

    def __init__(self, ik: dict, time_step: float, start_time: float = 0.0):
        from pydrake.multibody.inverse_kinematics import DifferentialInverseKinematicsStatus

        self._ik = ik
        self._h = float(time_step)
        if not (math.isfinite(self._h) and self._h > 0):
            raise ValueError(f"time_step must be a positive number of seconds, got {time_step!r}")
        self._first = math.ceil(float(start_time) / self._h - 1e-6)
        self._ok = DifferentialInverseKinematicsStatus.kSolutionFound
        self._last = {s: None for s in ik}
        self.steps = dict.fromkeys(ik, 0)
        self.failures = dict.fromkeys(ik, 0)
        self.kinds: dict[str, int] = {}

    def __call__(self, root_context):
        from pydrake.systems.framework import EventStatus

        t = root_context.get_time()
        j = math.ceil(t / self._h - 1e-6) - 1
        if j < self._first:
            return EventStatus.Succeeded()
        for side, arm in self._ik.items():
            last = self._last[side]
            if last is not None and j <= last:
                continue
            self._last[side] = j
            self.steps[side] += 1
            status = arm.status(root_context)
            if status != self._ok:
                self.failures[side] += 1
                name = self._NAMES.get(int(status), str(status))
                self.kinds[name] = self.kinds.get(name, 0) + 1
        return EventStatus.Succeeded()

    @property
    def total_failures(self) -> int:
        return int(sum(self.failures.values()))


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
        nan_commands, position_limit_hits, velocity_limit_hits, max_speed_ratio: from the monitor.
        tracking_lost_share: share of IK-period samples with either side's tracking lost.
        ik_steps, ik_failures: per side (:class:`IKStatusCounter`); ik_failure_kinds: per status.
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


def operator_targets(truth_C: np.ndarray | None, n: int, mapping) -> dict[str, np.ndarray]:
    """Per side ``(n, 4, 4)``: the operator's true wrist frame mapped to the robot, ``X_TE`` (NaN where
    degenerate or unknown)."""
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
                out[side][k] = X
    return out


@contextlib.contextmanager
def quiet_drake_warnings():
    """Silence Drake's per-step warnings (e.g. the IK's "stuck" notices) while the demo counts them itself."""
    logger = logging.getLogger("drake")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


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
        cfg, replay=replay, motion=motion, dims=dims, meshcat=meshcat, keep_history=True
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
    t_end = float(start_time) + td.duration(n)
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
        tracking_lost_share=float(np.mean(np.any(lost > 0.5, axis=1))) if lost.size else math.nan,
        ik_steps=dict(counter.steps),
        ik_failures=dict(counter.failures),
        ik_failure_kinds=dict(counter.kinds),
        error_t={s: mon.ee_error_times(s) - float(start_time) for s in SIDES},
        errors={s: mon.ee_errors(s) for s in SIDES},
        frame_t=(np.arange(n) + 1) * period - h,
        target=target,
        reachable_target=reach,
        ee=ee,
        operator=operator_targets(truth, n, td.mapper.mapping),
        dropout=np.zeros(n, dtype=bool) if dropout is None else np.asarray(dropout, dtype=bool)[:n],
    )
    return run, td


# ------------------------------------------------------------------------------------------------------------
# Metrics


def _median_cm(values) -> float | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.median(v) * 100.0) if v.size else None


def _p95_cm(values) -> float | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.percentile(v, 95) * 100.0) if v.size else None


def pooled_jitter(sequences: list[np.ndarray], period_s: float) -> tuple[float, float]:
    """:func:`~akc_drake.core.frames.frame_jitter` over several ``(T, 4, 4)`` sequences, no pair spanning two.

    Returns:
        ``(rms angular speed rad/s, rms linear speed m/s)``; NaN when there is no consecutive pair.
    """
    from akc_drake.core.frames import frame_jitter

    parts = []
    for X in sequences:
        parts += [np.asarray(X, dtype=float).reshape(-1, 4, 4), np.full((1, 4, 4), np.nan)]
    if not parts:
        return math.nan, math.nan
    return frame_jitter(np.concatenate(parts), period_s)


def run_metrics(runs: list[TeleopRun], settling_s: float = SETTLING_S) -> dict:
    """The figures of one run, or pooled over several (samples concatenated; jitter over consecutive frames of
    the same run only).

    Returns:
        A dict: ``frames``; per side (``{"left", "right"}``): ``ee_tracking_error_cm`` (median after
        ``settling_s``), ``ee_tracking_error_cm_with_settling``, ``ee_tracking_error_p95_cm``,
        ``ee_reachable_error_cm`` (to the target after the IK's reach guard), ``ee_operator_error_cm`` (to the
        operator's true mapped wrist), ``target_unreachable_share``, ``jitter`` and ``operator_jitter`` (the
        true mapped wrist's, for reference; each ``angular_rad_s``, ``linear_m_s``); totals:
        ``position_limit_hits``, ``velocity_limit_hits``, ``ik_steps``, ``ik_failures``, ``nan_commands``;
        ``tracking_lost_share``, ``dropout_frames``, ``sim_s``, ``wall_s``, ``realtime_factor``.
    """
    if not runs:
        raise ValueError("run_metrics: no runs")
    period = runs[0].period_s
    after = [r.frame_t >= settling_s for r in runs]

    def per_frame(fn, side: str) -> np.ndarray:
        return np.concatenate([fn(r, side)[a] for r, a in zip(runs, after, strict=True)])

    keys = ("err", "err_all", "p95", "reach", "op", "unreach", "jang", "jlin", "oang", "olin")
    v: dict[str, dict] = {k: {} for k in keys}
    for side in SIDES:
        e_after = np.concatenate([r.errors[side][r.error_t[side] >= settling_s] for r in runs])
        v["err"][side] = _median_cm(e_after)
        v["p95"][side] = _p95_cm(e_after)
        v["err_all"][side] = _median_cm(np.concatenate([r.errors[side] for r in runs]))
        v["reach"][side] = _median_cm(
            per_frame(lambda r, s: np.linalg.norm(r.reachable_target[s] - r.ee[s], axis=1), side)
        )
        v["op"][side] = _median_cm(
            per_frame(lambda r, s: np.linalg.norm(r.operator[s][:, :3, 3] - r.ee[s], axis=1), side)
        )
        gap = per_frame(
            lambda r, s: np.linalg.norm(r.reachable_target[s] - r.target[s][:, :3, 3], axis=1), side
        )
        gap = gap[np.isfinite(gap)]
        v["unreach"][side] = float(np.mean(gap > 1e-6)) if gap.size else None
        v["jang"][side], v["jlin"][side] = pooled_jitter(
            [r.target[side][a] for r, a in zip(runs, after, strict=True)], period
        )
        v["oang"][side], v["olin"][side] = pooled_jitter(
            [r.operator[side][a] for r, a in zip(runs, after, strict=True)], period
        )
    sim_s = sum(r.sim_s for r in runs)
    wall = sum(r.wall_s for r in runs)
    lost = [(r.tracking_lost_share, r.sim_s) for r in runs if math.isfinite(r.tracking_lost_share)]
    return {
        "frames": int(sum(r.frames for r in runs)),
        "ee_tracking_error_cm": v["err"],
        "ee_tracking_error_cm_with_settling": v["err_all"],
        "ee_tracking_error_p95_cm": v["p95"],
        "ee_reachable_error_cm": v["reach"],
        "ee_operator_error_cm": v["op"],
        "target_unreachable_share": v["unreach"],
        "jitter": {"angular_rad_s": v["jang"], "linear_m_s": v["jlin"]},
        "operator_jitter": {"angular_rad_s": v["oang"], "linear_m_s": v["olin"]},
        "position_limit_hits": int(sum(r.position_limit_hits for r in runs)),
        "velocity_limit_hits": int(sum(r.velocity_limit_hits for r in runs)),
        "max_joint_speed_ratio": float(max(r.max_speed_ratio for r in runs)),
        "ik_steps": int(sum(sum(r.ik_steps.values()) for r in runs)),
        "ik_failures": int(sum(sum(r.ik_failures.values()) for r in runs)),
        "ik_failure_kinds": _sum_dicts(r.ik_failure_kinds for r in runs),
        "nan_commands": int(sum(r.nan_commands for r in runs)),
        "tracking_lost_share": (sum(x * w for x, w in lost) / sum(w for _, w in lost)) if lost else None,
        "dropout_frames": int(sum(int(np.count_nonzero(r.dropout)) for r in runs)),
        "sim_s": sim_s,
        "wall_s": wall,
        "realtime_factor": sim_s / wall if wall > 0 else None,
    }


def _sum_dicts(dicts) -> dict:
    out: dict = {}
    for d in dicts:
        for k, v in d.items():
            out[k] = out.get(k, 0) + int(v)
    return out


# ------------------------------------------------------------------------------------------------------------
# Plots


def _save_figure(fig, path: Path) -> Path:
    """Save a matplotlib figure atomically (temp file, then rename)."""
    return atomic_write(path, lambda f: fig.savefig(f, dpi=110, format=path.suffix.lstrip(".") or "png"))


_COLORS = {"Raw": "tab:red", "KF": "tab:orange", "AKC(KF)": "tab:blue", "COIK(KF)": "tab:green"}


def plot_paths(runs: list[TeleopRun], path: Path, title: str = "") -> Path:
    """End-effector paths of one motion: a row per corrector, top (x-y) and side (x-z) views per arm.

    Each panel shows the operator's true wrist mapped to the robot frame T (grey), the mapped target
    ``X_TE_desired`` (dashed) and the achieved end-effector position (solid).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    views = [
        ("left", (1, 0), "top"),
        ("left", (0, 2), "side"),
        ("right", (1, 0), "top"),
        ("right", (0, 2), "side"),
    ]
    axis_name = {0: "x forward (m)", 1: "y left (m)", 2: "z up (m)"}
    fig, axes = plt.subplots(len(runs), 4, figsize=(16, 3.6 * len(runs)), squeeze=False)
    for i, run in enumerate(runs):
        color = _COLORS.get(run.corrector, "tab:purple")
        for j, (side, (a, b), view) in enumerate(views):
            ax = axes[i, j]
            op, tg, ee = run.operator[side][:, :3, 3], run.target[side][:, :3, 3], run.ee[side]
            ax.plot(
                op[:, a], op[:, b], color="0.55", lw=3.0, alpha=0.6, label="operator wrist (true, mapped)"
            )
            ax.plot(tg[:, a], tg[:, b], "--", color=color, lw=1.0, label="target X_TE_desired")
            ax.plot(ee[:, a], ee[:, b], "-", color="k", lw=1.0, label="achieved end effector")
            ax.set_xlabel(axis_name[a])
            ax.set_ylabel(axis_name[b])
            ax.set_aspect("equal", adjustable="datalim")
            ax.grid(True, alpha=0.3)
            ax.set_title(f"{run.corrector}: {side} arm, {view} view", fontsize=9)
            if i == 0 and j == 0:
                ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or f"Motion {runs[0].motion}: end-effector paths in the robot torso frame T")
    fig.tight_layout()
    try:
        return _save_figure(fig, path)
    finally:
        plt.close(fig)


def plot_errors(
    runs_by_motion: dict[str, list[TeleopRun]], path: Path, settling_s: float = SETTLING_S
) -> Path:
    """Tracking error (target to achieved, cm) over time: a row per motion, a column per arm, a line per
    corrector; the settling second is marked and dropped-out frames are shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    motions = list(runs_by_motion)
    fig, axes = plt.subplots(len(motions), 2, figsize=(14, 3.8 * len(motions)), squeeze=False)
    for i, name in enumerate(motions):
        for j, side in enumerate(SIDES):
            ax = axes[i, j]
            for run in runs_by_motion[name]:
                ax.plot(
                    run.error_t[side],
                    100.0 * run.errors[side],
                    lw=1.0,
                    color=_COLORS.get(run.corrector, "tab:purple"),
                    label=run.corrector,
                )
            runs = runs_by_motion[name]
            if runs and runs[0].dropout.any():
                P = runs[0].period_s
                for k in np.flatnonzero(runs[0].dropout):
                    ax.axvspan(k * P, (k + 1) * P, color="0.85", lw=0)
            ax.axvline(settling_s, color="0.4", ls=":", lw=1.0)
            ax.set_yscale("symlog", linthresh=1.0)
            ax.set_ylim(bottom=0.0)
            ax.set_xlabel("time (s)")
            ax.set_ylabel("target - achieved (cm)")
            ax.set_title(f"Motion {name}, {side} arm", fontsize=10)
            ax.grid(True, alpha=0.3)
            if i == 0 and j == 0:
                ax.legend(fontsize=8)
    fig.tight_layout()
    try:
        return _save_figure(fig, path)
    finally:
        plt.close(fig)


# ------------------------------------------------------------------------------------------------------------
# The demo


@dataclass
class DemoOptions:
    """What :func:`run_demo` runs.

    Attributes:
        quick: one cycle of each motion (instead of :data:`FULL_CYCLES`).
        cycles: cycles per motion (overrides ``quick``).
        dropout: share of frames lost in bursts of 0.5-3 s, in [0, 1] (replays only).
        seed: motion variation, depth noise, detector and dropout seed.
        out_dir: output folder.
        html: where to write the Meshcat recording (default ``out_dir/teleop.html``).
        record: record the AKC(KF) runs in Meshcat and write the HTML page.
        meshcat: an existing Meshcat to use (else one is created when ``record``).
        plots, graph: write the figures and the diagram's graph.
        render_run: also run AKC(KF) with the camera rendered in the diagram (the realtime factor).
        max_frames: cut every motion to this many frames (quick checks and tests).
        correctors: which of :data:`CORRECTORS` to compare.
        config: the base :class:`~akc_drake.config.PipelineConfig` (camera, weights, ...).
        progress: progress bars on stderr.
    """

    quick: bool = False
    cycles: int | None = None
    dropout: float = 0.0
    seed: int = 0
    out_dir: str | Path = "out/demo"
    html: str | Path | None = None
    record: bool = True
    meshcat: object = None
    plots: bool = True
    graph: bool = True
    render_run: bool = True
    max_frames: int | None = None
    correctors: tuple[str, ...] = tuple(CORRECTORS)
    config: object = None
    progress: bool = False

    def validate(self) -> DemoOptions:
        """Check the options; raises UserError naming the option."""
        d = self.dropout
        if (
            isinstance(d, bool)
            or not isinstance(d, (int, float))
            or not math.isfinite(d)
            or not 0.0 <= d <= 1.0
        ):
            raise UserError(f"--dropout must be a share of frames in [0, 1], got {d!r}")
        if self.cycles is not None and (
            isinstance(self.cycles, bool) or not isinstance(self.cycles, int) or self.cycles < 1
        ):
            raise UserError(f"cycles must be a positive integer, got {self.cycles!r}")
        if self.max_frames is not None and (
            isinstance(self.max_frames, bool) or not isinstance(self.max_frames, int) or self.max_frames < 10
        ):
            raise UserError(f"max_frames must be an integer >= 10, got {self.max_frames!r}")
        unknown = [c for c in self.correctors if c not in CORRECTORS]
        if unknown or not self.correctors:
            raise UserError(
                f"correctors must be among {', '.join(CORRECTORS)}, got {list(self.correctors)!r}"
            )
        if not str(self.out_dir).strip():
            raise UserError("--out: empty folder name")
        return self

    @property
    def num_cycles(self) -> int:
        if self.cycles is not None:
            return int(self.cycles)
        return QUICK_CYCLES if self.quick else FULL_CYCLES


def _make_meshcat():
    """A Meshcat server on localhost (None, with the reason, when it cannot start)."""
    try:
        from pydrake.geometry import Meshcat, MeshcatParams

        params = MeshcatParams()
        params.host = "localhost"
        return Meshcat(params), None
    except Exception as e:  # a port range in use, no sockets allowed, ...
        return None, f"{type(e).__name__}: {e}"


def _prepare_out_dir(out: Path) -> Path:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UserError(f"--out {out}: cannot create the folder: {e.strerror or e}") from None
    if not os.access(out, os.W_OK):
        raise UserError(f"--out {out}: the folder is not writable")
    return out


def run_demo(opts: DemoOptions, *, log: Callable[[str], None] = print) -> dict:
    """Run the demo (see the module docstring) and write its outputs; returns the summary (``demo.json``).

    Args:
        opts: the options.
        log: where progress lines go (``print`` by default).

    Returns:
        The summary dict, also written to ``opts.out_dir/demo.json``; ``summary["outputs"]`` lists the files.
    """
    import dataclasses

    from akc_drake.fileio import write_json
    from akc_drake.config import PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import Measurements, camera_period
    from akc_drake.faults import inject_dropouts
    from akc_drake.operator.motions import make_motion

    opts.validate()
    t_start = time.perf_counter()
    out = _prepare_out_dir(Path(opts.out_dir))
    cfg = (opts.config if opts.config is not None else PipelineConfig()).validate()
    cfg = dataclasses.replace(cfg, seed=int(opts.seed))
    rate = float(cfg.camera.rate_hz)
    period = camera_period(cfg)
    cycles = opts.num_cycles

    meshcat, meshcat_error = opts.meshcat, None
    if meshcat is None and opts.record:
        meshcat, meshcat_error = _make_meshcat()
        if meshcat is None:
            log(f"warning: Meshcat could not start ({meshcat_error}); no HTML recording will be written")

    # 1. Calibration from a rendered T-pose.
    log(
        f"Calibrating from a rendered T-pose ({min(CALIBRATION_FRAMES, opts.max_frames or 10**9)} "
        "frames, occlusion filter + KF) ..."
    )
    calib = calibrate_from_tpose(cfg, seed=opts.seed, progress=opts.progress, max_frames=opts.max_frames)
    true_dims = BodyDimensions.paper_participant()
    calib_err = {k: 100.0 * (getattr(calib.dims, k) - getattr(true_dims, k)) for k in true_dims.as_dict()}
    log(
        "  calibrated (cm): "
        + ", ".join(f"{k} {100 * v:.1f} ({calib_err[k]:+.1f})" for k, v in calib.dims.as_dict().items())
    )
    for w in calib.report.warnings:
        log(f"  warning: {w}")

    runs: dict[str, list[TeleopRun]] = {}
    rendered: list[TeleopRun] = []
    render_info: dict[str, dict] = {}
    dropout_info: dict[str, dict] = {}
    graph_diagram = None
    rec_time = 0.0
    if meshcat is not None:
        # Draw live only when the user watches (--meshcat); the recording is what the HTML page shows.
        meshcat.StartRecording(set_visualizations_while_recording=opts.meshcat is not None)
    with quiet_drake_warnings():
        for m_index, name in enumerate(MOTIONS):
            motion = make_motion(name, cycles, opts.seed)
            if opts.max_frames is not None:
                motion = truncate_motion(motion, opts.max_frames, rate)
            log(
                f"Motion {name}: rendering {len(motion.frame_times(rate))} frames "
                f"({cycles} cycle{'s' if cycles > 1 else ''}) ..."
            )
            session = render_motion(motion, cfg, seed=opts.seed, progress=opts.progress)
            render_info[name] = {
                "frames": len(session),
                "render_ms_per_frame": 1e3 * float(np.mean(session.render_s)),
                "extract_ms_per_frame": 1e3 * float(np.mean(session.extract_s)),
            }
            meas = Measurements.from_session(session)
            mask = np.zeros(meas.num_frames, dtype=bool)
            bursts = []
            if opts.dropout > 0:
                # The whole person is lost (NaN landmarks and pixels, visibility 0), in seeded bursts.
                meas, plan = inject_dropouts(
                    meas,
                    opts.dropout,
                    seed=[int(opts.seed), m_index, 0xD20],
                    burst_s=DROPOUT_BURST_S,
                    rate_hz=rate,
                    kinds=("person",),
                )
                mask = plan.frames
                bursts = [[round(b.start * period, 6), round(b.num_frames * period, 6)] for b in plan.bursts]
            dropout_info[name] = {"frames": int(mask.sum()), "bursts_start_duration_s": bursts}
            runs[name] = []
            for corrector in opts.correctors:
                record = meshcat is not None and corrector == MAIN_CORRECTOR
                run, td = run_teleop(
                    cfg,
                    calib.dims,
                    corrector=corrector,
                    replay=meas,
                    motion=motion,
                    meshcat=meshcat if record else None,
                    start_time=rec_time if record else 0.0,
                    dropout=mask,
                    progress=opts.progress,
                )
                if record:
                    rec_time = math.ceil(rec_time + run.sim_s + RECORDING_GAP_S)
                runs[name].append(run)
                m = run_metrics([run])
                log(
                    f"  {corrector:9s} replay: {run.frames} frames in {run.wall_s:5.1f} s "
                    f"(x{run.realtime_factor:.2f} realtime), EE error L/R "
                    f"{_lr(m['ee_tracking_error_cm'])} cm, "
                    f"NaN commands {run.nan_commands}"
                )
            if opts.render_run:
                run, td = run_teleop(
                    cfg,
                    calib.dims,
                    corrector=MAIN_CORRECTOR,
                    motion=motion,
                    num_frames=meas.num_frames,
                    truth_C=session.truth,
                    progress=opts.progress,
                )
                rendered.append(run)
                graph_diagram = td.diagram
                log(
                    f"  {MAIN_CORRECTOR} with rendering: {run.frames} frames in {run.wall_s:5.1f} s "
                    f"(x{run.realtime_factor:.2f} realtime)"
                )
    outputs: dict[str, object] = {}
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
        html = Path(opts.html) if opts.html else out / "teleop.html"
        try:
            atomic_write_text(html, meshcat.StaticHtml())
            outputs["html"] = str(html)
        except OSError as e:
            raise UserError(f"--html {html}: cannot write: {e.strerror or e}") from None
    if opts.graph:
        from akc_drake.graphs import write_graph

        if graph_diagram is None:
            from akc_drake.diagrams import build_teleop_diagram

            graph_diagram = build_teleop_diagram(
                dataclasses.replace(cfg, filter="KF", corrector="AKC")
            ).diagram
        paths = write_graph(graph_diagram, out, "teleop")
        outputs["graph_dot"] = str(paths["dot"])
        outputs["graph_svg"] = str(paths["svg"]) if paths["svg"] is not None else None
        if paths["svg"] is None:
            log("note: graphviz's 'dot' is not installed, so the diagram was written as .dot only")
    if opts.plots:
        figs = []
        for name, rs in runs.items():
            figs.append(str(plot_paths(rs, out / f"paths_motion_{name}.png")))
        figs.append(str(plot_errors(runs, out / "tracking_error.png")))
        outputs["plots"] = figs

    summary = _summary(
        opts, cfg, cycles, calib, true_dims, calib_err, runs, rendered, render_info, dropout_info
    )
    summary["outputs"] = outputs
    summary["wall_s"] = time.perf_counter() - t_start
    json_path = out / "demo.json"
    outputs["json"] = str(json_path)
    write_json(json_path, summary)
    return summary


def _summary(
    opts, cfg, cycles, calib, true_dims, calib_err, runs, rendered, render_info, dropout_info
) -> dict:
    all_runs = [r for rs in runs.values() for r in rs] + list(rendered)
    by_corrector = {c: [r for rs in runs.values() for r in rs if r.corrector == c] for c in opts.correctors}
    correctors = {c: run_metrics(rs) for c, rs in by_corrector.items() if rs}
    main = correctors.get(MAIN_CORRECTOR) or next(iter(correctors.values()))
    render_metrics = run_metrics(rendered) if rendered else None
    per_run = []
    for r in all_runs:
        m = run_metrics([r])
        m.update({"motion": r.motion, "corrector": r.corrector, "rendered": r.rendered})
        per_run.append(m)
    return {
        "config": {
            "quick": bool(opts.quick),
            "cycles": cycles,
            "motions": list(runs),
            "seed": int(opts.seed),
            "dropout": float(opts.dropout),
            "rate_hz": float(cfg.camera.rate_hz),
            "width": int(cfg.camera.width),
            "height": int(cfg.camera.height),
            "weights": cfg.weights,
            "correctors": {
                c: {"filter": CORRECTORS[c][0], "corrector": CORRECTORS[c][1]} for c in opts.correctors
            },
            "settling_s": SETTLING_S,
            "max_frames": opts.max_frames,
        },
        "definitions": {
            "frames": "camera frames teleoperated per corrector (all motions)",
            "ee_tracking_error_cm": (
                f"{MAIN_CORRECTOR}, both motions: median distance between the mapped target X_TE_desired "
                "and the achieved end-effector position, sampled once per camera frame, after the first "
                f"{SETTLING_S:g} s "
                "(the jump from the home pose); ee_tracking_error_cm_with_settling includes it"
            ),
            "ee_operator_error_cm": "median distance from the achieved end effector to the operator's true "
            "wrist "
            "mapped to the robot (ground truth through the same mapping), after settling",
            "jitter": "RMS angular (rad/s) and linear (m/s) speed of X_TE_desired between camera frames, "
            "after settling",
            "nan_commands": "IK-period samples with a non-finite joint command, all runs of the demo",
            "ik_failures": "differential-IK steps (100 Hz per arm) whose status was not 'solution found' "
            "('no solution' or 'stuck'; the command is held), all runs of the demo",
            "limit_hits": "IK-period samples with a joint command within 1e-3 rad of a position limit "
            "(position_limit_hits) or a step at >= 97% of a velocity limit (velocity_limit_hits)",
            "realtime_factor": f"{MAIN_CORRECTOR} with the camera rendered in the diagram (S1-S5, robot): "
            "simulated / wall-clock seconds; realtime_factor_replay is per corrector on "
            "replayed measurements (the recorded run draws to Meshcat too)",
            "dropout": "frames blanked in bursts in the replays (not in the rendered run)",
        },
        "calibration": {
            "pose": "tpose",
            "frames": calib.frames,
            "dims_m": calib.dims.as_dict(),
            "true_dims_m": true_dims.as_dict(),
            "error_cm": calib_err,
            "report": calib.report.as_dict(),
        },
        "frames": main["frames"],
        "nan_commands": int(sum(r.nan_commands for r in all_runs)),
        "ik_failures": int(sum(sum(r.ik_failures.values()) for r in all_runs)),
        "ee_tracking_error_cm": main["ee_tracking_error_cm"],
        "ee_tracking_error_cm_with_settling": main["ee_tracking_error_cm_with_settling"],
        "ee_operator_error_cm": main["ee_operator_error_cm"],
        "jitter": main["jitter"],
        "realtime_factor": render_metrics["realtime_factor"] if render_metrics else None,
        "realtime_factor_replay": {c: m["realtime_factor"] for c, m in correctors.items()},
        "rendering": render_info,
        "rendered_run": render_metrics,
        "dropout": dropout_info,
        "correctors": correctors,
        "runs": per_run,
    }


# ------------------------------------------------------------------------------------------------------------
# The table


def _fmt(v, spec: str = ".1f") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return format(v, spec)


def _lr(d: dict, spec: str = ".1f") -> str:
    return f"{_fmt(d.get('left'), spec)}/{_fmt(d.get('right'), spec)}"


def format_table(summary: dict) -> str:
    """The comparison table of a demo summary, per motion and pooled, as text.

    Columns: EE error (median after the settling second, then including it), the error to the operator's true
    mapped wrist, the control-frame jitter, limit hits (position/velocity), IK steps without a solution, NaN
    commands, the share of time with tracking lost and the replay's realtime factor. The "(operator)" row is
    the jitter of the operator's true wrist mapped to the robot: the motion's own speed, for reference.
    """
    cols = (
        ("", 10, ""),
        ("EE error", 12, "L/R cm"),
        ("w/ settle", 12, "L/R cm"),
        ("vs operator", 13, "L/R cm"),
        ("jitter", 13, "L/R rad/s"),
        ("jitter", 13, "L/R m/s"),
        ("limit hits", 12, "pos/vel"),
        ("IK fail", 9, "steps"),
        ("NaN", 6, "cmds"),
        ("lost", 7, "%"),
        ("RTF", 7, "replay"),
    )
    header = "".join(f"{name:>{w}s}" if name else " " * w for name, w, _ in cols)
    units = "".join(f"{u:>{w}s}" if u else " " * w for _, w, u in cols)

    def row(name: str, m: dict) -> str:
        j = m["jitter"]
        lost = m.get("tracking_lost_share")
        cells = (
            _lr(m["ee_tracking_error_cm"]),
            _lr(m["ee_tracking_error_cm_with_settling"]),
            _lr(m["ee_operator_error_cm"]),
            _lr(j["angular_rad_s"], ".2f"),
            _lr(j["linear_m_s"], ".3f"),
            f"{m['position_limit_hits']}/{m['velocity_limit_hits']}",
            str(m["ik_failures"]),
            str(m["nan_commands"]),
            _fmt(None if lost is None else 100.0 * lost, ".0f"),
            _fmt(m["realtime_factor"], ".2f"),
        )
        return f"{name:10s}" + "".join(f"{c:>{w}s}" for c, (_, w, _) in zip(cells, cols[1:], strict=True))

    def reference(m: dict) -> str:
        j = m["operator_jitter"]
        widths = [w for _, w, _ in cols]
        pad = " " * sum(widths[1:4])
        return (
            f"{'(operator)':10s}{pad}{_lr(j['angular_rad_s'], '.2f'):>{widths[4]}s}"
            f"{_lr(j['linear_m_s'], '.3f'):>{widths[5]}s}"
        )

    lines = []
    for motion in summary["config"]["motions"]:
        rs = [r for r in summary["runs"] if r["motion"] == motion and not r["rendered"]]
        if not rs:
            continue
        lines.append(f"Motion {motion} ({rs[0]['frames']} frames, {rs[0]['sim_s']:.1f} s)")
        lines += [header, units, *(row(r["corrector"], r) for r in rs), reference(rs[0]), ""]
    correctors = summary["correctors"]
    lines.append(f"Both motions ({summary['frames']} frames per corrector)")
    lines += [header, units, *(row(c, m) for c, m in correctors.items())]
    lines += [reference(next(iter(correctors.values()))), ""]
    rr = summary.get("rendered_run")
    if rr:
        lines.append(
            f"{MAIN_CORRECTOR} with the camera rendered in the diagram: realtime factor "
            f"{_fmt(summary['realtime_factor'], '.2f')} ({rr['frames']} frames in {rr['wall_s']:.1f} s), "
            f"EE error L/R {_lr(rr['ee_tracking_error_cm'])} cm, NaN commands {rr['nan_commands']}"
        )
    lines.append(
        f"Headline ({MAIN_CORRECTOR}, after the first {summary['config']['settling_s']:g} s): EE tracking "
        f"error L/R {_lr(summary['ee_tracking_error_cm'])} cm; NaN commands {summary['nan_commands']}, "
        f"IK failures {summary['ik_failures']} (all runs)"
    )
    return "\n".join(lines)
