"""The paper's experiments (§III): calibration, Motion I and II through every method, Tables I-IX.

The evaluation renders each motion once (:func:`render_sessions`) and feeds the same measurements to
every method (:func:`run_experiment`), so the comparison is fair and the run is fast:

1. Calibration (§III, Table VIII): the T-pose (and L-pose) session goes through the occlusion filter and
   the KF, and :func:`akc_drake.core.calibration.calibrate` averages the arm lengths over its 100 frames.
   The T-pose result is what every method uses. "Truth" is the operator's true lengths (the paper's
   Vicon column) and "Manual" the truth with the paper's ruler errors (Table VIII Manual - Vicon).
2. Each motion runs through every method (:mod:`akc_drake.evaluation.methods`); per-frame stage times
   are measured in the same run (Table III).
3. Metrics against the ground truth, per joint and axis, over every cycle but the first (the one the
   paper used to tune the weights): "Avg. RMSE" and "Avg. Corr" are the mean over cycles of the per-cycle
   value, as in the paper (Table VII prints the spread across cycles).
4. Table VII re-runs AKC(KF) with the paper's three weight presets; Table IX re-runs it with each
   calibration.

Units: metres inside, centimetres in tables and JSON (as in the paper); times in milliseconds.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import ARM_JOINTS, INDEX, SEGMENT_NAMES, BodyDimensions, segment_lengths
from akc_drake.evaluation.methods import (
    METHODS,
    MethodOptions,
    MethodResult,
    MethodRunner,
    make_akc,
    parse_methods,
    run_akc,
)
from akc_drake.evaluation.report import Table, nan_to_none
from akc_drake.evaluation.session import Session

#: Period of one cycle of Motion I and II (paper §III), seconds.
CYCLE_S = 6.0
#: The four arm segments whose length AKC keeps constant (Table VI).
ARM_SEGMENTS: tuple[str, ...] = ("LUA", "LLA", "RUA", "RLA")
#: Calibration methods of Tables VIII-IX, in the paper's column order (our "Truth" is its "Vicon").
CALIBRATIONS: tuple[str, ...] = ("Manual", "Truth", "T-pose", "L-pose")
_PAPER_CALIBRATION = {"Manual": "Manual", "Truth": "Vicon", "T-pose": "T-pose", "L-pose": "L-pose"}
AXES = ("x", "y", "z")

Progress = Callable[[int, str], None]


@dataclass
class ExperimentConfig:
    """What to run.

    Attributes:
        motions: the motions ("I", "II") to evaluate; ignored when ``motion_file`` is set.
        cycles: cycles of 6 s per motion.
        seed: seed of the renderer's noise and the motions' natural variation.
        methods: the methods to compare (names of :data:`~akc_drake.evaluation.methods.METHODS`).
        weights: the AKC weight preset for the main runs ("Wa" | "Wb" | "Wc").
        width, height: image size in pixels (the intrinsics scale with it).
        rate_hz: camera rate.
        calibration_frames: frames of the held T-pose / L-pose (the paper: 100).
        motion_file, skeleton: a BVH (or AMC + ASF) recording driving the operator instead of Motion I/II.
        exclude_first_cycle: leave the first cycle out of the metrics (the paper's protocol).
        weight_study: also run Table VII (AKC(KF) with Wa, Wb, Wc).
        calibration_study: also run Tables VIII-IX (AKC(KF) with each calibration; renders the L-pose).
        options: occlusion-filter, filter and COIK settings.
        body: the rendered operator, "primitive" or "skinned" (``--body``).
        detector: the 2D detector on the renders, "sim" or "mediapipe" (``--detector``).
    """

    motions: tuple[str, ...] = ("I", "II")
    cycles: int = 30
    seed: int = 0
    methods: tuple[str, ...] = METHODS
    weights: str = "Wb"
    width: int = 640
    height: int = 480
    rate_hz: float = 10.0
    calibration_frames: int = 100
    motion_file: str | None = None
    skeleton: str | None = None
    exclude_first_cycle: bool = True
    weight_study: bool = True
    calibration_study: bool = True
    options: MethodOptions = field(default_factory=MethodOptions)
    body: str = "primitive"
    detector: str = "sim"

    def __post_init__(self):
        self.methods = parse_methods(self.methods)
        if isinstance(self.cycles, bool) or not isinstance(self.cycles, (int, np.integer)) or self.cycles < 1:
            raise ValueError(f"cycles must be a positive integer, got {self.cycles!r}")
        if self.weights not in ("Wa", "Wb", "Wc"):
            raise ValueError(f"weights must be Wa, Wb or Wc, got {self.weights!r}")
        for name in ("width", "height", "calibration_frames"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if self.width < 32 or self.height < 24:
            raise ValueError(f"image size {self.width}x{self.height} is too small (at least 32x24)")
        if not self.rate_hz > 0:
            raise ValueError(f"rate_hz must be positive, got {self.rate_hz!r}")
        self.motions = tuple(self.motions)
        for m in self.motions:
            if m not in ("I", "II"):
                raise ValueError(f"motion must be I or II, got {m!r}")
        if not self.motions and self.motion_file is None:
            raise ValueError("no motion to evaluate")
        if self.body not in ("primitive", "skinned"):
            raise ValueError(f"--body must be primitive or skinned, got {self.body!r}")
        if self.detector not in ("sim", "mediapipe"):
            raise ValueError(f"--detector must be sim or mediapipe, got {self.detector!r}")

    @property
    def motion_names(self) -> tuple[str, ...]:
        """The evaluated sessions' names: the motions, or the file's stem."""
        return (Path(self.motion_file).stem,) if self.motion_file else self.motions

    def intrinsics(self) -> CameraIntrinsics:
        """D435-like intrinsics (615 px focal length at 640x480) scaled to the image size."""
        return scaled_intrinsics(self.width, self.height, self.rate_hz)

    def as_dict(self) -> dict:
        d = {k: v for k, v in asdict(self).items() if k != "options"}
        d["methods"] = list(self.methods)
        d["motions"] = list(self.motions)
        d["options"] = {
            "visibility_threshold": self.options.visibility_threshold,
            "proximity": self.options.proximity,
        }
        return d


def scaled_intrinsics(width: int, height: int, rate_hz: float = 10.0) -> CameraIntrinsics:
    """The default (640x480) intrinsics scaled to ``width`` x ``height`` (same field of view)."""
    base = CameraIntrinsics()
    f = base.fx * width / base.width
    return CameraIntrinsics(
        width=int(width),
        height=int(height),
        fx=f,
        fy=base.fy * width / base.width,
        cx=(width - 1) / 2.0,
        cy=(height - 1) / 2.0,
        depth_scale=base.depth_scale,
        rate_hz=float(rate_hz),
    )


# ============================================================================================ rendering
def render_sessions(
    config: ExperimentConfig, progress: Progress | None = None, cache=None
) -> dict[str, Session]:
    """Render every session the experiment needs, once: ``"tpose"``, ``"lpose"`` (calibration study)
    and each motion (or the motion file), through the render cache (:mod:`akc_drake.evaluation.cache`).

    Args:
        config: the experiment.
        progress: called ``progress(frames_done, session_name)`` as frames are rendered (or read).
        cache: the render cache: None (the default folder), False (off) or a folder.

    Returns:
        ``{name: Session}``.
    """
    from akc_drake.evaluation.cache import cached_render
    from akc_drake.evaluation.tasks import session_specs

    return {
        name: cached_render(spec, progress, cache)[0] for name, spec in session_specs(config).items()
    }


def frames_to_render(config: ExperimentConfig) -> int:
    """How many frames :func:`render_sessions` renders (for a progress bar; a file's length is unknown: 0).

    A motion of duration ``D`` is sampled at ``k / rate`` for ``k = 0 .. floor(D * rate)``.
    """
    def frames(seconds: float) -> int:
        return int(np.floor(seconds * config.rate_hz + 1e-9)) + 1

    n = frames(config.calibration_frames / config.rate_hz) * (2 if config.calibration_study else 1)
    if not config.motion_file:
        n += len(config.motions) * frames(config.cycles * CYCLE_S)
    return n


# ============================================================================================ metrics
def _metrics():
    from akc_drake.core import metrics

    return metrics


def joint_cycle_metrics(est: np.ndarray, truth: np.ndarray, cycles: list[slice]) -> dict:
    """Per-cycle RMSE and Pearson r of one joint's ``(T, 3)`` trajectory against the truth.

    Returns:
        dict with ``rmse`` ``(C, 3)`` m, ``r`` ``(C, 3)``, ``p`` ``(C, 3)`` and ``valid`` ``(C,)``
        (frames used).
    """
    m = _metrics()
    C = len(cycles)
    rmse = np.full((C, 3), np.nan)
    r = np.full((C, 3), np.nan)
    p = np.full((C, 3), np.nan)
    valid = np.zeros(C, dtype=int)
    for c, sl in enumerate(cycles):
        e, g = est[sl], truth[sl]
        rm, n = m.rmse_per_axis(e, g)
        rmse[c] = rm
        valid[c] = int(n)
        rc, pc, _ = m.pearson_per_axis(e, g)
        r[c], p[c] = rc, pc
    return {"rmse": rmse, "r": r, "p": p, "valid": valid}


def _nanmean(a, axis=0):
    a = np.asarray(a, dtype=float)
    with np.errstate(all="ignore"):
        cnt = np.sum(np.isfinite(a), axis=axis)
        s = np.nansum(a, axis=axis)
        return np.where(cnt > 0, s / np.maximum(cnt, 1), np.nan)


def _nanstd(a, axis=0):
    a = np.asarray(a, dtype=float)
    mu = _nanmean(a, axis)
    with np.errstate(all="ignore"):
        cnt = np.sum(np.isfinite(a), axis=axis)
        d = np.where(np.isfinite(a), a - np.expand_dims(mu, axis), 0.0)
        return np.where(cnt > 0, np.sqrt(np.sum(d * d, axis=axis) / np.maximum(cnt, 1)), np.nan)


def summarize_joint(est: np.ndarray, truth: np.ndarray, cycles: list[slice]) -> dict:
    """The JSON/table numbers of one joint: cycle-averaged RMSE (cm) and r, their spread, pooled values."""
    pc = joint_cycle_metrics(est, truth, cycles)
    m = _metrics()
    idx = np.concatenate([np.arange(sl.start, sl.stop) for sl in cycles])
    rm_all, n_all = m.rmse_per_axis(est[idx], truth[idx])
    r_all, p_all, _ = m.pearson_per_axis(est[idx], truth[idx])
    return {
        "rmse_cm": _nanmean(pc["rmse"]) * 100.0,
        "rmse_cm_std": _nanstd(pc["rmse"]) * 100.0,
        "corr": _nanmean(pc["r"]),
        "rmse_pooled_cm": np.asarray(rm_all) * 100.0,
        "corr_pooled": np.asarray(r_all),
        "corr_p_pooled": np.asarray(p_all),
        "valid_frames": int(n_all),
        "cycles": len(cycles),
    }


def rms_euclidean_cycles(est: np.ndarray, truth: np.ndarray, cycles: list[slice]) -> float:
    """Mean over cycles of the per-cycle RMS Euclidean error of one joint ``(T, 3)``, metres."""
    m = _metrics()
    vals = [m.rms_euclidean(est[sl], truth[sl]) for sl in cycles]
    return float(_nanmean(np.array(vals, dtype=float)))


def length_range(traj: np.ndarray, frames: np.ndarray | None = None) -> dict[str, float]:
    """max - min of every arm segment's length over ``frames`` of ``traj`` ``(T, 12, 3)``, metres."""
    if frames is not None:
        traj = traj[frames]
    if traj.shape[0] == 0:
        return {s: float("nan") for s in ARM_SEGMENTS}
    rng = _metrics().arm_length_range(traj)
    return {s: float(rng[s]) for s in ARM_SEGMENTS}


def calibrate_session(session: Session, pose: str, options: MethodOptions | None = None) -> BodyDimensions:
    """Arm lengths from a held pose as in the paper: the KF-filtered landmarks of the session, averaged."""
    from akc_drake.core.calibration import calibrate

    runner = MethodRunner(session, BodyDimensions.paper_participant(), None, options)
    filtered, _ = runner.filtered("KF")
    res = calibrate(filtered, pose)
    return res[0] if isinstance(res, tuple) else res


def true_dimensions(session: Session) -> BodyDimensions:
    """The operator's true segment lengths: the median over the session's ground truth."""
    lens = segment_lengths(session.truth)
    return BodyDimensions(**{k: float(np.nanmedian(lens[k])) for k in SEGMENT_NAMES})


def manual_dimensions(truth: BodyDimensions) -> BodyDimensions:
    """A ruler measurement of the operator: the truth plus the paper's ruler errors.

    The errors are Table VIII's Manual - Vicon columns.

    For the default operator (the paper's participant) this gives exactly the paper's Manual column.
    """
    man, vic = BodyDimensions.paper_manual().as_dict(), BodyDimensions.paper_participant().as_dict()
    t = truth.as_dict()
    return BodyDimensions(**{k: t[k] + man[k] - vic[k] for k in SEGMENT_NAMES})


# ============================================================================================ experiment
@dataclass
class MotionRun:
    """Everything computed for one motion."""

    session: Session
    methods: dict[str, MethodResult]
    weight_runs: dict[str, np.ndarray] = field(default_factory=dict)
    calibration_runs: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class Evaluation:
    """The result of :func:`run_experiment`.

    Attributes:
        config: the configuration.
        calibrations: {"Manual" | "Truth" | "T-pose" | "L-pose": BodyDimensions}.
        dims: the dimensions every method used (the T-pose calibration).
        runs: {motion: MotionRun}.
        results: JSON rows (motion, method, joint, rmse_cm, corr, valid_frames, ...).
        arm_length_range_cm: JSON rows (motion, method, segment, range_cm).
        timing_ms: JSON rows (motion, method, mean, max, stages).
        tables: the paper's tables with our numbers.
        elapsed_s: wall time of the method runs and metrics.
    """

    config: ExperimentConfig
    calibrations: dict[str, BodyDimensions]
    dims: BodyDimensions
    runs: dict[str, MotionRun]
    results: list[dict]
    arm_length_range_cm: list[dict]
    timing_ms: list[dict]
    tables: list[Table]
    elapsed_s: float = 0.0
    render_s: float = 0.0
    #: Clips whose task failed (:class:`~akc_drake.evaluation.executor.TaskFailure`), left out of the tables.
    failures: list = field(default_factory=list)

    def to_json(self) -> dict:
        """The ``--json`` document (DESIGN.md keys, plus ``tables``, ``paper``, ``calibration``)."""
        from akc_drake.resources import paper_results

        cfg = self.config
        config = {
            "motion": cfg.motion_file
            if cfg.motion_file
            else ("both" if len(cfg.motions) == 2 else cfg.motions[0]),
            "cycles": cfg.cycles if not cfg.motion_file else None,
            "seed": cfg.seed,
            "rate_hz": cfg.rate_hz,
            "weights": cfg.weights,
            "methods": list(cfg.methods),
            "width": cfg.width,
            "height": cfg.height,
            "motion_file": cfg.motion_file,
            "skeleton": cfg.skeleton,
            "calibration": "tpose",
            "calibration_frames": cfg.calibration_frames,
            "excluded_cycles": 1 if cfg.exclude_first_cycle else 0,
            "visibility_threshold": cfg.options.visibility_threshold,
            "proximity": cfg.options.proximity,
            "elapsed_s": self.elapsed_s,
            "render_s": self.render_s,
        }
        frames = {
            m: {
                "frames": r.session.num_frames,
                "cycles": r.session.num_cycles,
                "evaluated_frames": int(r.session.evaluation_mask(cfg.exclude_first_cycle).sum()),
            }
            for m, r in self.runs.items()
        }
        return nan_to_none(
            {
                "config": config,
                "sessions": frames,
                "calibration": {
                    k: {s: v * 100.0 for s, v in d.as_dict().items()} for k, d in self.calibrations.items()
                },
                "dims_cm": {s: v * 100.0 for s, v in self.dims.as_dict().items()},
                "results": self.results,
                "arm_length_range_cm": self.arm_length_range_cm,
                "timing_ms": self.timing_ms,
                "failures": [{"clip": f.label, "error": f.error, "attempts": f.attempts} for f in self.failures],
                "tables": {t.key: t.to_dict() for t in self.tables},
                "paper": paper_results(),
            }
        )


def _axes_dict(v) -> dict:
    return {a: float(x) for a, x in zip(AXES, np.asarray(v, dtype=float), strict=True)}


def run_experiment(
    config: ExperimentConfig,
    sessions: dict[str, Session],
    progress: Progress | None = None,
) -> Evaluation:
    """Calibrate, run every method on every motion, compute every metric and table.

    Args:
        config: what to run.
        sessions: ``{"tpose": ..., ["lpose": ...,] <motion>: ...}`` as from :func:`render_sessions`
            (or built by hand: any session whose ``motion`` is a key of the paper's tables gets the paper's
            figures beside it).
        progress: called ``progress(units, label)``; one unit per frame processed by one method.

    Returns:
        The :class:`Evaluation`.

    Raises:
        ValueError: a needed session is missing (naming it).
    """
    t_start = time.perf_counter()
    if "tpose" not in sessions:
        raise ValueError("the experiment needs a 'tpose' session for the calibration")
    names = config.motion_names
    for name in names:
        if name not in sessions:
            raise ValueError(f"no session for motion {name!r} (have: {', '.join(sessions)})")
    opts = config.options

    # ---- calibration (Table VIII)
    tpose_dims = calibrate_session(sessions["tpose"], "tpose", opts)
    truth_dims = true_dimensions(sessions["tpose"])
    calibrations = {"Manual": manual_dimensions(truth_dims), "Truth": truth_dims, "T-pose": tpose_dims}
    if config.calibration_study and "lpose" in sessions:
        calibrations["L-pose"] = calibrate_session(sessions["lpose"], "lpose", opts)
    if progress is not None:
        progress(sum(sessions[p].num_frames for p in ("tpose", "lpose") if p in sessions), "calibration")

    # ---- methods
    runs = {name: run_motion(config, sessions[name], tpose_dims, calibrations, progress) for name in names}
    ev = assemble_evaluation(config, calibrations, tpose_dims, runs)
    ev.elapsed_s = time.perf_counter() - t_start
    return ev


def run_motion(
    config: ExperimentConfig,
    s: Session,
    tpose_dims: BodyDimensions,
    calibrations: dict[str, BodyDimensions],
    progress: Progress | None = None,
) -> MotionRun:
    """Every configured method on one motion's measurements (plus the weight and calibration studies).

    This is the unit of work of a distributed evaluation (:mod:`akc_drake.evaluation.tasks`).
    """
    name = s.motion
    opts = config.options
    runner = MethodRunner(s, tpose_dims, config.weights, opts)
    results = {}
    for method in config.methods:
        results[method] = runner.run(method)
        if progress is not None:
            progress(s.num_frames, f"{name} {method}")
    run = MotionRun(s, results)
    if config.weight_study:
        filtered, _ = runner.filtered("KF")
        for preset in ("Wa", "Wb", "Wc"):
            if preset == config.weights and "AKC(KF)" in results:
                run.weight_runs[preset] = results["AKC(KF)"].estimates
            else:
                run.weight_runs[preset] = run_akc(make_akc(tpose_dims, preset), filtered)[0]
            if progress is not None:
                progress(s.num_frames, f"{name} AKC {preset}")
    if config.calibration_study:
        filtered, _ = runner.filtered("KF")
        for cal, dims in calibrations.items():
            if cal == "T-pose" and "AKC(KF)" in results:
                run.calibration_runs[cal] = results["AKC(KF)"].estimates
            else:
                run.calibration_runs[cal] = run_akc(make_akc(dims, config.weights), filtered)[0]
            if progress is not None:
                progress(s.num_frames, f"{name} AKC {cal}")
    return run


def assemble_evaluation(
    config: ExperimentConfig,
    calibrations: dict[str, BodyDimensions],
    dims: BodyDimensions,
    runs: dict[str, MotionRun],
) -> Evaluation:
    """The :class:`Evaluation` (rows and tables) of the motions' runs, however they were computed."""
    ev = Evaluation(
        config=config,
        calibrations=calibrations,
        dims=dims,
        runs=runs,
        results=[],
        arm_length_range_cm=[],
        timing_ms=[],
        tables=[],
    )
    _fill_rows(ev)
    ev.tables = build_tables(ev)
    return ev


def work_units(config: ExperimentConfig, sessions: dict[str, Session]) -> int:
    """The total of ``progress`` units :func:`run_experiment` reports (for a progress bar)."""
    n = sum(sessions[p].num_frames for p in ("tpose", "lpose") if p in sessions)
    per = len(config.methods) + (3 if config.weight_study else 0)
    if config.calibration_study:
        per += len(CALIBRATIONS) if "lpose" in sessions else len(CALIBRATIONS) - 1
    for name in config.motion_names:
        if name in sessions:
            n += sessions[name].num_frames * per
    return n


def _fill_rows(ev: Evaluation) -> None:
    excl = ev.config.exclude_first_cycle
    for motion, run in ev.runs.items():
        s = run.session
        cycles = s.evaluation_cycles(excl)
        mask = s.evaluation_mask(excl)
        for method, res in run.methods.items():
            for joint in ARM_JOINTS:
                j = INDEX[joint]
                st = summarize_joint(res.estimates[:, j], s.truth[:, j], cycles)
                ev.results.append(
                    {
                        "motion": motion,
                        "method": method,
                        "joint": joint,
                        "rmse_cm": _axes_dict(st["rmse_cm"]),
                        "corr": _axes_dict(st["corr"]),
                        "valid_frames": st["valid_frames"],
                        "rmse_cm_std": _axes_dict(st["rmse_cm_std"]),
                        "rmse_pooled_cm": _axes_dict(st["rmse_pooled_cm"]),
                        "corr_pooled": _axes_dict(st["corr_pooled"]),
                        "corr_p_pooled": _axes_dict(st["corr_p_pooled"]),
                        "rms_euclidean_cm": rms_euclidean_cycles(res.estimates[:, j], s.truth[:, j], cycles)
                        * 100.0,
                        "cycles": st["cycles"],
                    }
                )
            rng = length_range(res.estimates, mask)
            for seg in ARM_SEGMENTS:
                ev.arm_length_range_cm.append(
                    {"motion": motion, "method": method, "segment": seg, "range_cm": rng[seg] * 100.0}
                )
            # Table III: per-stage and total times, milliseconds, over the evaluated frames.
            stages = {}
            for stage, tt in res.stage_time_s.items():
                v = np.asarray(tt)[mask]
                stages[stage] = {
                    "mean": float(_nanmean(v) * 1e3),
                    "max": float(np.nanmax(v) * 1e3) if np.any(np.isfinite(v)) else float("nan"),
                }
            proc = res.processing_time_s()[mask]
            total = res.total_time_s()[mask]
            row = {
                "motion": motion,
                "method": method,
                "mean": float(np.mean(proc) * 1e3),
                "max": float(np.max(proc) * 1e3),
                "stages": stages,
                "total_mean": float(_nanmean(total) * 1e3),
                "total_max": float(np.nanmax(total) * 1e3) if np.any(np.isfinite(total)) else float("nan"),
            }
            if res.status is not None:
                st_vals, counts = np.unique(res.status[mask], return_counts=True)
                row["status_counts"] = {str(k): int(c) for k, c in zip(st_vals, counts, strict=True)}
            ev.timing_ms.append(row)
        ev.arm_length_range_cm.extend(
            {"motion": motion, "method": "Truth", "segment": seg, "range_cm": v * 100.0}
            for seg, v in length_range(s.truth, mask).items()
        )


# ============================================================================================ tables
def _paper():
    from akc_drake.resources import paper_results

    return paper_results()


def _result(ev: Evaluation, motion: str, method: str, joint: str) -> dict | None:
    for r in ev.results:
        if r["motion"] == motion and r["method"] == method and r["joint"] == joint:
            return r
    return None


def _rmse_cols(ev, motion, method, joint) -> list[float]:
    r = _result(ev, motion, method, joint)
    return [np.nan] * 3 if r is None else [r["rmse_cm"][a] for a in AXES]


def _corr_xz(ev, motion, method, joint) -> list[float]:
    r = _result(ev, motion, method, joint)
    return [np.nan] * 2 if r is None else [r["corr"]["x"], r["corr"]["z"]]


def _static_table(ev, key, title, joint, columns, paper_key) -> Table:
    """Tables I and IV: RMSE x, y, z of a static shoulder, methods per motion."""
    paper = _paper()[paper_key]
    motions = list(ev.runs)
    cols, groups, ours, ref = [], [], [], []
    for m in motions:
        groups.append((f"Motion {m}", len(columns)))
        for label, method in columns:
            cols.append(label)
            ours.append(_rmse_cols(ev, m, method, joint))
            ref.append(paper.get(m, {}).get(label, [np.nan] * 3))
    return Table(
        key,
        title,
        list(AXES),
        cols,
        np.array(ours, dtype=float).T,
        np.array(ref, dtype=float).T,
        groups=groups,
    )


def _dynamic_table(ev, key, title, joint, columns, paper_key) -> Table:
    """Tables II and V: RMSE x, y, z and Pearson r (x, z) of a dynamic elbow in one motion."""
    paper = _paper()[paper_key]
    motion = "I" if "I" in ev.runs else next(iter(ev.runs))
    with_paper = motion == "I"
    rows = ["Avg. RMSE, x (cm)", "Avg. RMSE, y (cm)", "Avg. RMSE, z (cm)", "Avg. Corr (x)", "Avg. Corr (z)"]
    ours, ref = [], []
    for label, method in columns:
        ours.append(_rmse_cols(ev, motion, method, joint) + _corr_xz(ev, motion, method, joint))
        if with_paper:
            ref.append(paper["rmse_cm"].get(label, [np.nan] * 3) + paper["corr_x_z"].get(label, [np.nan] * 2))
        else:
            ref.append([np.nan] * 5)
    t = Table(
        key, title.format(motion=motion), rows, [c for c, _ in columns], np.array(ours).T, np.array(ref).T
    )
    t.row_decimals = [2, 2, 2, 3, 3]
    t.notes.append("Pearson correlation averaged over cycles; NaN frames left out of RMSE and r.")
    return t


def _timing_table(ev) -> Table:
    """Table III: mean per-frame computation time (ms) of each layer; max total per frame for COIK and AKC."""
    paper = _paper()["table3_compute_time_ms"]
    cols = ["Raw", "KF", "COIK", "AKC"]
    rows, ours, ref = [], [], []

    def stage_mean(motion, method, stages):
        for r in ev.timing_ms:
            if r["motion"] == motion and r["method"] == method:
                vals = [r["stages"][s]["mean"] for s in stages if s in r["stages"]]
                return float(np.sum(vals)) if vals else np.nan
        return np.nan

    def total_max(method):
        vals = [r["total_max"] for r in ev.timing_ms if r["method"] == method]
        vals = [v for v in vals if v is not None and np.isfinite(v)]
        return max(vals) if vals else np.nan

    for m in ev.runs:
        rows.append(f"Motion {m}")
        ours.append(
            [
                stage_mean(m, "Raw", ["source"]),
                stage_mean(m, "KF", ["occlusion", "filter"]),
                stage_mean(m, "COIK(KF)", ["corrector"]),
                stage_mean(m, "AKC(KF)", ["corrector"]),
            ]
        )
        ref.append([paper.get(m, {}).get(c, np.nan) for c in cols])
    rows.append("Max total")
    ours.append([np.nan, np.nan, total_max("COIK(KF)"), total_max("AKC(KF)")])
    ref.append([np.nan, np.nan, paper["max_total_ms"]["COIK"], paper["max_total_ms"]["AKC"]])
    t = Table(
        "table3",
        "Averaged computation time (ms) of various mocap algorithms",
        rows,
        cols,
        np.array(ours),
        np.array(ref),
    )
    t.notes.append(
        "Raw = render + simulated detection + depth lookup (the paper's: MediaPipe Holistic on an i9); "
        "KF = occlusion filter + KF; COIK, AKC = the correction layer alone; "
        "max total = source + filter + correction, worst frame over all motions."
    )
    return t


def _range_table(ev) -> Table:
    """Table VI: range of arm-length variation over all evaluated frames of all motions (cm)."""
    paper = _paper()["table6_arm_length_range_cm"]
    cols = ["Truth", "Raw", "KF", "EKF", "COIK(iteration limit)", "COIK(feasible)", "AKC"]
    paper_cols = ["Vicon", "Raw", "KF", "EKF", "COIK(iteration limit)", "COIK(feasible)", "AKC"]
    excl = ev.config.exclude_first_cycle

    def pooled(method_names, status_pred=None):
        chunks = []
        for run in ev.runs.values():
            mask = run.session.evaluation_mask(excl)
            for mn in method_names:
                if mn == "Truth":
                    chunks.append(run.session.truth[mask])
                elif mn in run.methods:
                    res = run.methods[mn]
                    sel = mask.copy()
                    if status_pred is not None:
                        sel &= status_pred(res.status)
                    chunks.append(res.estimates[sel])
        if not chunks:
            return {s: np.nan for s in ARM_SEGMENTS}
        # Range per method, then the largest (each method's own variation, not the spread between methods).
        out = {s: np.nan for s in ARM_SEGMENTS}
        for ch in chunks:
            r = length_range(ch)
            for s in ARM_SEGMENTS:
                if np.isfinite(r[s]):
                    out[s] = r[s] if not np.isfinite(out[s]) else max(out[s], r[s])
        return out

    coik = ["COIK(KF)", "COIK(EKF)"]
    colvals = [
        pooled(["Truth"]),
        pooled(["Raw"]),
        pooled(["KF"]),
        pooled(["EKF"]),
        pooled(coik, lambda st: st != "success"),
        pooled(coik, lambda st: st == "success"),
        pooled(["AKC(KF)", "AKC(EKF)"]),
    ]
    ours = np.array([[cv[s] * 100.0 for cv in colvals] for s in ARM_SEGMENTS])
    ref = np.array([[paper[c][paper["segments"].index(s)] for c in paper_cols] for s in ARM_SEGMENTS])
    t = Table(
        "table6",
        f"Range of arm length variation during Motion {' & '.join(ev.runs)} (cm)",
        list(ARM_SEGMENTS),
        cols,
        ours,
        ref,
        decimals=1,
    )
    t.notes.append(
        "Truth = the rendered operator's joint centres (the paper's Vicon column shows marker artefacts); "
        "COIK split by solver status per frame; AKC = both AKC(KF) and AKC(EKF)."
    )
    return t


def _weights_table(ev) -> Table | None:
    """Table VII: left-arm RMSE over the evaluated cycles per weight preset (mean ± std across cycles)."""
    if not ev.config.weight_study:
        return None
    paper = _paper()["table7_left_arm_rmse_29_cycles_cm"]
    rows, ours, std, ref = [], [], [], []
    order = [("I", "Wa"), ("II", "Wb"), ("I", "Wb"), ("II", "Wa"), ("I", "Wc"), ("II", "Wc")]
    motions = list(ev.runs)
    if ev.config.motion_file:
        order = [(motions[0], w) for w in ("Wa", "Wb", "Wc")]
    for motion, preset in order:
        if motion not in ev.runs:
            continue
        run = ev.runs[motion]
        cycles = run.session.evaluation_cycles(ev.config.exclude_first_cycle)
        est = run.weight_runs[preset]
        stats = {}
        for joint in ("shoulder", "elbow"):
            j = INDEX[f"left_{joint}"]
            pc = joint_cycle_metrics(est[:, j], run.session.truth[:, j], cycles)
            stats[joint] = (_nanmean(pc["rmse"]) * 100.0, _nanstd(pc["rmse"]) * 100.0)
        pk = paper.get(f"{motion}_{preset}")
        for a, axis in enumerate(AXES):
            rows.append(f"Motion {motion} using {preset}, {axis}")
            ours.append([stats["shoulder"][0][a], stats["elbow"][0][a]])
            std.append([stats["shoulder"][1][a], stats["elbow"][1][a]])
            ref.append([pk["shoulder"][a], pk["elbow"][a]] if pk else [np.nan, np.nan])
    n_cyc = max(len(r.session.evaluation_cycles(ev.config.exclude_first_cycle)) for r in ev.runs.values())
    t = Table(
        "table7",
        f"RMSE (cm) of {n_cyc} motion cycles with different weights (Wa, Wb, Wc) for the left arm, AKC(KF)",
        rows,
        ["Shoulder", "Elbow"],
        np.array(ours),
        np.array(ref),
        ours_std=np.array(std),
    )
    return t


def _calibration_tables(ev) -> list[Table]:
    """Tables VIII (arm lengths per calibration) and IX (RMS Euclidean errors of AKC(KF) per calibration)."""
    paper8 = _paper()["table8_arm_length_by_calibration_cm"]
    paper9 = _paper()["table9_rms_euclidean_error_by_calibration_cm"]
    cols = [c for c in CALIBRATIONS if c in ev.calibrations]
    segs = paper8["segments"]  # LUA, RUA, LLA, RLA, SW
    ours8 = np.array([[ev.calibrations[c].as_dict()[s] * 100.0 for c in cols] for s in segs])
    ref8 = np.array([[paper8[_PAPER_CALIBRATION[c]][segs.index(s)] for c in cols] for s in segs])
    t8 = Table(
        "table8",
        "Arm length for the arm-length measurement methods (cm)",
        list(segs),
        cols,
        ours8,
        ref8,
        decimals=1,
    )
    t8.notes.append(
        "Truth = the rendered operator (the paper's Vicon); Manual = truth + the paper's ruler errors; "
        "T-pose/L-pose = KF-filtered landmarks of a held pose, averaged."
    )
    tables = [t8]
    if not ev.config.calibration_study:
        return tables
    joints = [
        ("LELB", "left_elbow"),
        ("RELB", "right_elbow"),
        ("LSHO", "left_shoulder"),
        ("RSHO", "right_shoulder"),
    ]
    m = _metrics()
    ours9 = np.full((len(joints) + 1, len(cols)), np.nan)
    for c_i, cal in enumerate(cols):
        vals = []
        for _label, joint in joints:
            j = INDEX[joint]
            per_motion = []
            for run in ev.runs.values():
                if cal not in run.calibration_runs:
                    continue
                cycles = run.session.evaluation_cycles(ev.config.exclude_first_cycle)
                per_motion.append(
                    rms_euclidean_cycles(run.calibration_runs[cal][:, j], run.session.truth[:, j], cycles)
                )
            vals.append(float(_nanmean(np.array(per_motion, dtype=float))) * 100.0 if per_motion else np.nan)
        ours9[: len(joints), c_i] = vals
        ours9[len(joints), c_i] = float(m.l2_norm(np.array(vals)))
    rows9 = [lab for lab, _ in joints] + ["L2-norm"]
    ref9 = np.array([[paper9[_PAPER_CALIBRATION[c]][r] for c in cols] for r in range(len(rows9))])
    t9 = Table(
        "table9",
        "Averaged RMS Euclidean distance errors (cm) and L2 norm for the calibration methods, "
        f"AKC(KF), Motion {' & '.join(ev.runs)}",
        rows9,
        cols,
        ours9,
        ref9,
        decimals=1,
    )
    tables.append(t9)
    return tables


def build_tables(ev: Evaluation) -> list[Table]:
    """Every table of the paper that the configured methods allow, in the paper's order."""
    have = set(ev.config.methods)
    tables: list[Table] = []
    if {"Raw", "KF", "COIK(KF)", "AKC(KF)"} & have:
        cols = [("Raw", "Raw"), ("KF", "KF"), ("COIK", "COIK(KF)"), ("AKC", "AKC(KF)")]
        tables.append(
            _static_table(
                ev,
                "table1",
                "Avg. RMSE (cm) of an occluded static left shoulder",
                "left_shoulder",
                cols,
                "table1_static_left_shoulder_rmse_cm",
            )
        )
        tables.append(
            _dynamic_table(
                ev,
                "table2",
                "Occluded dynamic left elbow in Motion {motion}",
                "left_elbow",
                cols,
                "table2_dynamic_left_elbow_motion_I",
            )
        )
        tables.append(_timing_table(ev))
    if {"KF", "EKF", "AKC(KF)", "AKC(EKF)"} & have:
        cols = [("KF", "KF"), ("EKF", "EKF"), ("AKC(KF)", "AKC(KF)"), ("AKC(EKF)", "AKC(EKF)")]
        tables.append(
            _static_table(
                ev,
                "table4",
                "Avg. RMSE (cm) of an occluded static right shoulder",
                "right_shoulder",
                cols,
                "table4_static_right_shoulder_rmse_cm",
            )
        )
        tables.append(
            _dynamic_table(
                ev,
                "table5",
                "Occluded dynamic right elbow in Motion {motion}",
                "right_elbow",
                cols,
                "table5_dynamic_right_elbow_motion_I",
            )
        )
    tables.append(_range_table(ev))
    t7 = _weights_table(ev)
    if t7 is not None:
        tables.append(t7)
    tables.extend(_calibration_tables(ev))
    if ev.config.motion_file:
        # The paper's figures are for its Motion I and II; beside a recording they would mislead. Only the
        # calibration lengths (the same operator) keep them.
        for t in tables:
            if t.key != "table8":
                t.paper[:] = np.nan
    return tables
