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


def akc_plus_record(settings) -> dict | None:
    """AKC+ settings as a result records them: the fields given (a dict), every field (an ``AKCPlusConfig``), or
    None for the defaults."""
    if settings is None or isinstance(settings, dict):
        return None if not settings else dict(settings)
    import dataclasses

    return dataclasses.asdict(settings)


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
        joint_names: the motion file's joint-name map (role -> joint; :func:`~akc_drake.operator.retarget.
            find_arm_joints`), or None for the names it finds.
        exclude_first_cycle: leave the first cycle out of the metrics (the paper's protocol).
        weight_study: also run Table VII (AKC(KF) with Wa, Wb, Wc).
        calibration_study: also run Tables VIII-IX (AKC(KF) with each calibration; renders the L-pose).
        options: occlusion-filter settings (visibility threshold, proximity), AKC+'s settings
            (``akc_plus_config``, ``--akc-plus``), correctors of your own (``correctors``, ``--add-corrector``; the
            methods may name them) and, under ``protocol="ours"``, the filter and COIK settings.
        protocol: "paper" (the stages and table definitions as the paper describes them) or "ours"
            (:mod:`akc_drake.evaluation.protocol`).
        filter_settings: the KF's and the EKF's settings changed from the protocol's, field -> value (plain
            data; ``--filter-settings``, :func:`~akc_drake.config.parse_filter_settings`), or None.
        body: the rendered operator, "primitive" or "skinned" (``--body``).
        detector: the 2D detector on the renders, "sim" or "mediapipe" (``--detector``).
        camera: the camera's placement, "default" or the fields of :func:`~akc_drake.config.parse_camera`
            (``--camera``); Motions I and II reach toward it wherever it is.
        body_scale: the rendered operator's size, every length times this (``--body-scale``,
            :meth:`~akc_drake.operator.model.OperatorParams.scaled`; the calibration sees it as it is).
        depth_noise: the camera's depth error model, "default" or the fields of
            :func:`~akc_drake.config.parse_depth_noise` (``--depth-noise``; the calibration's too).
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
    joint_names: dict | None = None
    exclude_first_cycle: bool = True
    weight_study: bool = True
    calibration_study: bool = True
    options: MethodOptions = field(default_factory=MethodOptions)
    body: str = "primitive"
    detector: str = "sim"
    protocol: str = "paper"
    filter_settings: dict | None = None
    camera: str | dict = "default"
    body_scale: float = 1.0
    depth_noise: str | dict = "default"

    def __post_init__(self):
        from akc_drake.evaluation.protocol import PROTOCOLS

        if self.protocol not in PROTOCOLS:
            raise ValueError(f"protocol must be one of {', '.join(PROTOCOLS)}, got {self.protocol!r}")
        self.methods = parse_methods(self.methods, self.options.correctors or ())
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
        from akc_drake.evaluation.cache import camera_placement, check_body_scale

        camera_placement(self.camera)  # (an unknown camera fails here)
        check_body_scale(self.body_scale)
        from akc_drake.config import depth_noise_model

        depth_noise_model(self.depth_noise)  # (an unknown field or a bad value fails here)
        if self.options.akc_plus_config is not None:
            from akc_drake.core.akc_plus_config import akc_plus_config

            akc_plus_config(self.options.akc_plus_config)  # (a bad setting fails here, not in every worker)
        if self.filter_settings:
            from akc_drake.evaluation.protocol import with_filter_settings

            with_filter_settings(self.options, self.filter_settings)  # (likewise)

    def run_options(self) -> MethodOptions:
        """The stage settings the methods run with: the protocol's, with this config's occlusion thresholds, filter
        settings and AKC+ settings (over the protocol's own: :func:`~akc_drake.evaluation.protocol.with_akc_plus`)."""
        import dataclasses

        from akc_drake.evaluation.protocol import method_options, with_akc_plus, with_filter_settings

        if self.protocol == "ours":
            return with_filter_settings(self.options, self.filter_settings)
        return with_filter_settings(with_akc_plus(dataclasses.replace(
            method_options(self.protocol),
            visibility_threshold=self.options.visibility_threshold,
            proximity=self.options.proximity,
            correctors=self.options.correctors,
        ), self.options.akc_plus_config), self.filter_settings)

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
            "correctors": dict(self.options.correctors or {}),
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
            "joint_names": dict(cfg.joint_names) if cfg.joint_names else None,
            "calibration": "tpose",
            "calibration_frames": cfg.calibration_frames,
            "excluded_cycles": 1 if cfg.exclude_first_cycle else 0,
            "visibility_threshold": cfg.options.visibility_threshold,
            "proximity": cfg.options.proximity,
            "akc_plus": akc_plus_record(cfg.options.akc_plus_config),
            "camera": dict(cfg.camera) if isinstance(cfg.camera, dict) else cfg.camera,
            "body_scale": cfg.body_scale,
            "depth_noise": dict(cfg.depth_noise) if isinstance(cfg.depth_noise, dict) else cfg.depth_noise,
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
    # ---- calibration (Table VIII)
    tpose_dims, calibrations = calibrate_all(config, sessions)
    if progress is not None:
        progress(sum(sessions[p].num_frames for p in ("tpose", "lpose") if p in sessions), "calibration")

    # ---- methods
    runs = {name: run_motion(config, sessions[name], tpose_dims, calibrations, progress) for name in names}
    ev = assemble_evaluation(config, calibrations, tpose_dims, runs)
    ev.elapsed_s = time.perf_counter() - t_start
    return ev


def calibrate_all(
    config: ExperimentConfig, sessions: dict[str, Session]
) -> tuple[BodyDimensions, dict[str, BodyDimensions]]:
    """The T-pose dimensions every method uses, and every calibration of Tables VIII-IX.

    ``sessions`` needs ``"tpose"`` (and ``"lpose"`` for the L-pose column of the calibration study).
    """
    opts = config.run_options()
    tpose_dims = calibrate_session(sessions["tpose"], "tpose", opts)
    truth_dims = true_dimensions(sessions["tpose"])
    calibrations = {"Manual": manual_dimensions(truth_dims), "Truth": truth_dims, "T-pose": tpose_dims}
    if config.calibration_study and "lpose" in sessions:
        calibrations["L-pose"] = calibrate_session(sessions["lpose"], "lpose", opts)
    return tpose_dims, calibrations


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
    opts = config.run_options()
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
def build_tables(ev: Evaluation) -> list[Table]:
    """Every table of the paper that the configured methods allow (:mod:`akc_drake.evaluation.tables`)."""
    from akc_drake.evaluation.tables import build_tables as _build

    return _build(ev)
