"""The evaluation as independent tasks on :func:`~akc_drake.evaluation.executor.run_tasks` (in-process, local
cores or a Dask cluster), with the same results bit for bit whatever runs them.

Two kinds of task, both module-level functions on plain dicts returning plain dicts (numpy arrays, strings,
numbers; never an object of the package):

* :func:`render_task`: one calibration pose (T-pose, L-pose) rendered through the render cache;
* :func:`clip_task`: **the unit of work**, one clip x detector x body: its session rendered once (through the
  cache, :mod:`akc_drake.evaluation.cache`) or read from a session ``.npz``, then every method on the same
  measurements, the weight study and the calibration study
  (:func:`~akc_drake.evaluation.experiment.run_motion`, the code the in-process evaluation runs).

:func:`evaluate_tasks` runs the calibration renders, calibrates here (cheap and deterministic), runs one clip task
per motion, and assembles the :class:`~akc_drake.evaluation.experiment.Evaluation` here from the returned arrays
(:func:`~akc_drake.evaluation.experiment.assemble_evaluation`). A clip whose task fails (a bad file, a crash) is
left out of the tables and reported as one line in ``Evaluation.failures``; the other clips complete.

Wall-clock measurements (per-frame stage times for Table III, ``source_time_s``) are measurements of the
machine that ran the task; every other number is identical across schedulers.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import BodyDimensions
from akc_drake.evaluation.executor import TaskFailure, open_scheduler, run_tasks
from akc_drake.evaluation.session import Session

_SESSION_ARRAYS = ("t", "raw", "visibility", "pixels", "truth", "cycle_starts", "source_time_s")


# ============================================================================================ plain data
def session_to_plain(s: Session) -> dict:
    """A :class:`Session` as plain data (arrays, the intrinsics as a dict, the name)."""
    d = {k: np.asarray(getattr(s, k)) for k in _SESSION_ARRAYS}
    d["intrinsics"] = s.intrinsics.as_dict()
    d["motion"] = s.motion
    return d


def session_from_plain(d: dict) -> Session:
    """Inverse of :func:`session_to_plain`."""
    return Session(
        **{k: d[k] for k in _SESSION_ARRAYS},
        intrinsics=CameraIntrinsics.from_dict(dict(d["intrinsics"])),
        motion=d["motion"],
    )


def dims_to_plain(dims: BodyDimensions) -> dict:
    return {k: float(v) for k, v in dims.as_dict().items()}


def dims_from_plain(d: dict) -> BodyDimensions:
    return BodyDimensions(**{k: float(v) for k, v in d.items()})


def _is_plain_value(v) -> bool:
    if v is None or isinstance(v, (bool, int, float, str)):
        return True
    if isinstance(v, (list, tuple)):
        return all(_is_plain_value(x) for x in v)
    if isinstance(v, dict):
        return all(isinstance(k, str) and _is_plain_value(x) for k, x in v.items())
    return False


def config_to_plain(config) -> dict:
    """An :class:`~akc_drake.evaluation.experiment.ExperimentConfig` as plain data.

    Every field of plain values crosses as is (tuples as lists); ``options`` crosses as its plain fields.

    Raises:
        ValueError: a field (or option) holds an object that cannot be sent to a worker.
    """
    out = {}
    for f in dataclasses.fields(config):
        v = getattr(config, f.name)
        if f.name == "options":
            opts = {}
            for g in dataclasses.fields(v):
                ov = getattr(v, g.name)
                if not _is_plain_value(ov):
                    raise ValueError(f"options.{g.name} = {ov!r} cannot be sent to a worker (not plain data)")
                opts[g.name] = list(ov) if isinstance(ov, tuple) else ov
            out["options"] = opts
        elif _is_plain_value(v):
            out[f.name] = list(v) if isinstance(v, tuple) else v
        else:
            raise ValueError(f"config.{f.name} = {v!r} cannot be sent to a worker (not plain data)")
    return out


def config_from_plain(d: dict):
    """Inverse of :func:`config_to_plain`."""
    from akc_drake.evaluation.experiment import ExperimentConfig
    from akc_drake.evaluation.methods import MethodOptions

    kw = {}
    for f in dataclasses.fields(ExperimentConfig):
        if f.name not in d:
            continue
        v = d[f.name]
        if f.name == "options":
            v = MethodOptions(**{k: (tuple(x) if isinstance(x, list) else x) for k, x in v.items()})
        elif isinstance(v, list):
            v = tuple(v)
        kw[f.name] = v
    return ExperimentConfig(**kw)


def run_to_plain(run) -> dict:
    """A :class:`~akc_drake.evaluation.experiment.MotionRun` as plain data (the session included)."""
    return {
        "session": session_to_plain(run.session),
        "methods": {
            name: {
                "estimates": r.estimates,
                "stage_time_s": dict(r.stage_time_s),
                "status": None if r.status is None else np.asarray(r.status).astype(str),
            }
            for name, r in run.methods.items()
        },
        "weight_runs": dict(run.weight_runs),
        "calibration_runs": dict(run.calibration_runs),
    }


def run_from_plain(d: dict):
    """Inverse of :func:`run_to_plain`."""
    from akc_drake.evaluation.experiment import MotionRun
    from akc_drake.evaluation.methods import MethodResult

    methods = {
        name: MethodResult(name, m["estimates"], dict(m["stage_time_s"]), m["status"])
        for name, m in d["methods"].items()
    }
    return MotionRun(
        session_from_plain(d["session"]),
        methods,
        weight_runs=dict(d["weight_runs"]),
        calibration_runs=dict(d["calibration_runs"]),
    )


# ============================================================================================ specs
def session_specs(config) -> dict[str, dict]:
    """The render specs of every session an experiment needs: ``tpose`` (+ ``lpose``) and each motion."""
    from akc_drake.evaluation.cache import render_spec
    from akc_drake.evaluation.experiment import CYCLE_S

    intr = config.intrinsics()
    common = {"intrinsics": intr, "seed": config.seed}
    for extra in ("body", "detector", "camera", "body_scale", "depth_noise"):
        if hasattr(config, extra):
            common[extra] = getattr(config, extra)
    common["options"] = render_options(config)
    calib_s = config.calibration_frames / config.rate_hz
    specs = {}
    for pose in ["tpose"] + (["lpose"] if config.calibration_study else []):
        specs[pose] = render_spec(
            pose, {"kind": "hold", "pose": pose, "seconds": calib_s}, frames=config.calibration_frames, **common
        )
    if config.motion_file:
        name = config.motion_names[0]
        specs[name] = render_spec(
            name, {"kind": "file", "path": config.motion_file, "skeleton": config.skeleton,
                   **({"names": dict(config.joint_names)} if config.joint_names else {})}, **common
        )
    else:
        for name in config.motions:
            specs[name] = render_spec(
                name, {"kind": "builtin", "name": name, "cycles": config.cycles}, cycle_s=CYCLE_S, **common
            )
    return specs


def render_options(config) -> dict:
    """Extra ``render_session`` keyword arguments the config implies (its protocol's, when it has one)."""
    protocol = getattr(config, "protocol", None)
    if protocol is None:
        return {}
    try:
        from akc_drake.evaluation.protocol import render_kwargs
    except ImportError:
        return {}
    return dict(render_kwargs(protocol))


# ============================================================================================ tasks
def render_task(item: dict) -> dict:
    """Task: ``{"spec": render spec, "cache": folder | None | False}`` -> ``{"session", "cached", "seconds"}``."""
    from akc_drake.evaluation.cache import cached_render

    t0 = time.perf_counter()
    session, hit = cached_render(item["spec"], cache=item.get("cache"))
    return {"session": session_to_plain(session), "cached": bool(hit), "seconds": time.perf_counter() - t0}


def clip_task(item: dict) -> dict:
    """Task, the unit of work: one clip, rendered once (or read), through every method.

    Args:
        item: ``{"config": config_to_plain(...), "dims": T-pose dims, "calibrations": {name: dims},
            "cache": folder | None | False}`` plus the clip: ``"spec"`` (a render spec) or ``"session_npz"``
            (a recorded session file, :meth:`Session.save_npz`).

    Returns:
        ``{"run": run_to_plain(...), "cached": bool, "render_s": s, "methods_s": s}``.
    """
    from akc_drake.evaluation.experiment import run_motion

    t0 = time.perf_counter()
    if item.get("session_npz"):
        session, hit = Session.load_npz(item["session_npz"]), True
    else:
        from akc_drake.evaluation.cache import cached_render

        session, hit = cached_render(item["spec"], cache=item.get("cache"))
    t1 = time.perf_counter()
    config = config_from_plain(item["config"])
    calibrations = {k: dims_from_plain(v) for k, v in item["calibrations"].items()}
    run = run_motion(config, session, dims_from_plain(item["dims"]), calibrations)
    return {
        "run": run_to_plain(run),
        "cached": bool(hit),
        "render_s": t1 - t0,
        "methods_s": time.perf_counter() - t1,
    }


# ============================================================================================ driver
def evaluate_tasks(
    config,
    *,
    scheduler: str = "local",
    n_workers: int | None = None,
    cache=None,
    clips: dict[str, dict] | None = None,
    progress: bool = True,
    retries: int = 2,
    log: Callable[[str], None] | None = None,
):
    """The whole experiment of ``config`` as tasks: calibration renders, then one :func:`clip_task` per motion.

    Args:
        config: the :class:`~akc_drake.evaluation.experiment.ExperimentConfig`.
        scheduler: "inprocess", "local" or "tcp://HOST:PORT" (see :func:`run_tasks`).
        n_workers: local worker processes (default: one per core).
        cache: the render cache (None: the default folder, False: off, or a folder).
        clips: ``{name: {"spec": ...} | {"session_npz": ...}}`` instead of the config's motions (e.g. one per
            file of a folder); the config's calibration poses are rendered as usual.
        progress: show the progress bars.
        retries: see :func:`run_tasks`.
        log: called with one line per failed clip (default: nothing).

    Returns:
        The :class:`~akc_drake.evaluation.experiment.Evaluation` of the clips that completed, with
        ``render_s`` (wall time of the calibration renders), ``elapsed_s`` (the clips), and ``failures``
        (one :class:`TaskFailure` per failed clip).

    Raises:
        ValueError: when a calibration pose or every clip fails (nothing to report).
    """
    from akc_drake.evaluation.experiment import assemble_evaluation, calibrate_all

    specs = session_specs(config)
    poses = [p for p in ("tpose", "lpose") if p in specs]
    if clips is None:
        clips = {name: {"spec": specs[name]} for name in config.motion_names}
    cache_arg = None if cache is None else (False if cache is False else str(cache))
    with open_scheduler(scheduler, n_workers) as sched:
        t0 = time.perf_counter()
        rendered = run_tasks(
            render_task,
            [{"spec": specs[p], "cache": cache_arg} for p in poses],
            scheduler=sched,
            desc="calibration",
            labels=poses,
            retries=retries,
            progress=progress,
        )
        bad = [r for r in rendered if isinstance(r, TaskFailure)]
        if bad:
            raise ValueError(f"calibration pose {bad[0].line()}")
        cal_sessions = {p: session_from_plain(r["session"]) for p, r in zip(poses, rendered, strict=True)}
        tpose_dims, calibrations = calibrate_all(config, cal_sessions)
        render_s = time.perf_counter() - t0

        t1 = time.perf_counter()
        base = {
            "config": config_to_plain(config),
            "dims": dims_to_plain(tpose_dims),
            "calibrations": {k: dims_to_plain(v) for k, v in calibrations.items()},
            "cache": cache_arg,
        }
        names = list(clips)
        results = run_tasks(
            clip_task,
            [{**base, **clips[n]} for n in names],
            scheduler=sched,
            desc="clips",
            labels=names,
            retries=retries,
            progress=progress,
        )
    runs, failed = {}, []
    for name, res in zip(names, results, strict=True):
        if isinstance(res, TaskFailure):
            failed.append(res)
            if log is not None:
                log(f"clip {res.line()}")
        else:
            runs[name] = run_from_plain(res["run"])
    if not runs:
        raise ValueError("every clip failed: " + "; ".join(f.line() for f in failed))
    ev = assemble_evaluation(config, calibrations, tpose_dims, runs)
    ev.render_s = render_s
    ev.elapsed_s = time.perf_counter() - t1
    ev.failures = failed
    return ev
