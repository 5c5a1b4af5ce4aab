"""AKC weight and shrink-factor sensitivity study (paper §III-E, Fig. 5 and Table VII).

As in the paper, the weights are tuned on the **first cycle** of each motion: for every grid point
``(w1, w2, w3, s)`` (with ``w4 = w5 = 100``), AKC runs over the first cycle's KF-filtered landmarks and
the objective is the L2 norm, over the left and right shoulders and elbows, of each joint's RMS
Euclidean error against the truth (cm; Table IX's "L2-norm"). "both" is the mean of the two motions'
objectives. The optimum per motion (and for both) is then applied to every other cycle of its own and
of the other motion (cross-motion robustness, Table VII).

The KF runs once per motion; the grid is split into chunks, each a :func:`sweep_chunk` task on the
evaluation's executor (:func:`~akc_drake.evaluation.executor.run_tasks`: in this process, on a Dask
``LocalCluster`` of ``jobs`` workers, or on a Dask cluster at ``tcp://HOST:PORT``). A task receives plain numpy
arrays and floats (the tuning frames, the dimensions, its weight tuples) and returns an array of objectives; the
values do not depend on where or in how many chunks they run. Figures are drawn on
``matplotlib.figure.Figure`` (no pyplot state).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.evaluation.report import plot_heatmaps, save_png

#: The joints of the objective (Table IX): both elbows and both shoulders.
OBJECTIVE_JOINTS: tuple[str, ...] = ("left_elbow", "right_elbow", "left_shoulder", "right_shoulder")
_OBJ_IDX = np.array([INDEX[j] for j in OBJECTIVE_JOINTS], dtype=np.intp)
#: w4 and w5 (shoulder width, anatomical plausibility) stay at the paper's 100 (§III-E).
W45 = 100.0


@dataclass(frozen=True)
class SweepGrid:
    """The grid of the study.

    Attributes:
        w1, w2, w3: values of the elbow-, shoulder-spatial and temporal-consistency weights.
        s: shrink-factor values searched jointly with the weights.
        s_curve: shrink-factor values of the s curve (Fig. 5 d), at each motion's best (w1, w2, w3).
    """

    w1: tuple[float, ...] = (0.0, 1.0, 2.0, 4.0, 8.0)
    w2: tuple[float, ...] = (0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)
    w3: tuple[float, ...] = (0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)
    s: tuple[float, ...] = (0.7, 0.8, 0.9, 1.0)
    s_curve: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)

    def __post_init__(self):
        for name in ("w1", "w2", "w3", "s", "s_curve"):
            vals = tuple(float(v) for v in getattr(self, name))
            if name != "s_curve" and not vals:
                raise ValueError(f"SweepGrid.{name} must not be empty")
            if any(not math.isfinite(v) or v < 0 for v in vals):
                raise ValueError(f"SweepGrid.{name} must hold finite values >= 0, got {vals}")
            if name in ("s", "s_curve") and any(not 0 < v <= 2 for v in vals):
                raise ValueError(f"SweepGrid.{name}: shrink factors must be in (0, 2], got {vals}")
            if len(set(vals)) != len(vals):
                raise ValueError(f"SweepGrid.{name} repeats a value: {vals}")
            object.__setattr__(self, name, vals)

    @property
    def shape(self) -> tuple[int, int, int, int]:
        return (len(self.w1), len(self.w2), len(self.w3), len(self.s))

    def points(self) -> np.ndarray:
        """``(N, 4)`` every (w1, w2, w3, s) of the grid, in C order of :attr:`shape`."""
        g = np.meshgrid(self.w1, self.w2, self.w3, self.s, indexing="ij")
        return np.stack([a.ravel() for a in g], axis=1)

    def as_dict(self) -> dict:
        return {k: list(getattr(self, k)) for k in ("w1", "w2", "w3", "s", "s_curve")}


# ============================================================================================ objective
def tuning_frames(session) -> slice:
    """The frames weights are tuned on: the first cycle (the whole session when it has one cycle)."""
    return session.cycle_slices()[0]


def objective_cm(est: np.ndarray, truth: np.ndarray) -> float:
    """L2 norm over :data:`OBJECTIVE_JOINTS` of the RMS Euclidean error (cm) of ``est`` vs ``truth``.

    Frames where a joint's estimate or truth is NaN are left out of that joint's RMS; a joint with no
    valid frame makes the objective infinite (the weight set lost the arm).
    """
    d = est[:, _OBJ_IDX] - truth[:, _OBJ_IDX]
    sq = np.einsum("tjk,tjk->tj", d, d)
    ok = np.isfinite(sq)
    n = ok.sum(axis=0)
    if np.any(n == 0):
        return float("inf")
    rms = np.sqrt(np.where(ok, sq, 0.0).sum(axis=0) / n)
    return float(np.sqrt(np.sum((rms * 100.0) ** 2)))


def weights_from_point(point) -> object:
    """An ``AKCWeights`` from a grid point (w1, w2, w3, s), with w4 = w5 = 100."""
    from akc_drake.core.akc import AKCWeights

    w1, w2, w3, s = (float(v) for v in point)
    return AKCWeights(w1=w1, w2=w2, w3=w3, w4=W45, w5=W45, s=s)


def evaluate_point(point, filtered: np.ndarray, truth: np.ndarray, dims: BodyDimensions) -> float:
    """The objective of one weight set on one motion's tuning frames (AKC run from a fresh state)."""
    from akc_drake.core.akc import ArmKinematicCorrector

    akc = ArmKinematicCorrector(dims, weights_from_point(point))
    est = np.empty_like(filtered)
    for k in range(filtered.shape[0]):
        est[k] = akc.correct(filtered[k]).pose
    return objective_cm(est, truth)


def sweep_chunk(item: dict) -> dict:
    """Task: the objectives of a chunk of grid points on every motion.

    Args:
        item: ``{"start": index of the first point, "points": (n, 4), "filtered": [(T, 12, 3) per motion],
            "truth": [(T, 12, 3) per motion], "dims": [LUA, LLA, RUA, RLA, SW]}`` (plain arrays and floats).

    Returns:
        ``{"start": int, "objective": (n_motions, n) cm}``.
    """
    dims = BodyDimensions(*[float(v) for v in item["dims"]])
    points = np.asarray(item["points"], dtype=float).reshape(-1, 4)
    out = np.empty((len(item["filtered"]), len(points)))
    for m, (filtered, truth) in enumerate(zip(item["filtered"], item["truth"], strict=True)):
        for i, p in enumerate(points):
            out[m, i] = evaluate_point(p, filtered, truth, dims)
    return {"start": int(item["start"]), "objective": out}


def evaluate_points(
    points: np.ndarray,
    data: dict[str, tuple[np.ndarray, np.ndarray]],
    dims: BodyDimensions,
    scheduler="inprocess",
    progress: Callable[[int], None] | None = None,
    chunks: int = 32,
    show_progress: bool = False,
) -> dict[str, np.ndarray]:
    """Objective of every point on every motion, as :func:`sweep_chunk` tasks on ``scheduler``.

    Args:
        points: ``(N, 4)`` grid points (w1, w2, w3, s).
        data: ``{motion: (filtered (T, 12, 3), truth (T, 12, 3))}`` of the tuning frames.
        dims: the calibrated body dimensions.
        scheduler: "inprocess", "local", "tcp://HOST:PORT" or an open
            :class:`~akc_drake.evaluation.executor.Scheduler`.
        progress: called with the number of points finished (times motions) as chunks complete.
        chunks: how many tasks the points are split into (the values do not depend on it).
        show_progress: show a progress bar over the tasks.

    Returns:
        ``{motion: (N,) objective in cm}``.

    Raises:
        RuntimeError: a chunk failed (its one-line reason).
    """
    from akc_drake.evaluation.executor import TaskFailure, run_tasks

    points = np.asarray(points, dtype=float).reshape(-1, 4)
    motions = list(data)
    filtered = [np.ascontiguousarray(data[m][0], dtype=float) for m in motions]
    truth = [np.ascontiguousarray(data[m][1], dtype=float) for m in motions]
    dims_list = [float(v) for v in dims.as_array()]
    N = len(points)
    result = np.empty((len(motions), N))
    if N == 0:
        return {m: result[i] for i, m in enumerate(motions)}
    bounds = np.linspace(0, N, min(N, max(1, int(chunks))) + 1).astype(int)
    items = [
        {"start": int(a), "points": points[a:b], "filtered": filtered, "truth": truth, "dims": dims_list}
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        if b > a
    ]

    def done(_i, res):
        if progress is not None and not isinstance(res, TaskFailure):
            progress(res["objective"].shape[1] * len(motions))

    results = run_tasks(
        sweep_chunk,
        items,
        scheduler=scheduler,
        desc="sweep",
        labels=[f"points {it['start']}-{it['start'] + len(it['points']) - 1}" for it in items],
        progress=show_progress,
        on_result=done,
    )
    for res in results:
        if isinstance(res, TaskFailure):
            raise RuntimeError(f"sweep chunk {res.line()}")
        start, vals = res["start"], res["objective"]
        result[:, start : start + vals.shape[1]] = vals
    return {m: result[i] for i, m in enumerate(motions)}


# ============================================================================================ study
@dataclass
class SweepResult:
    """The outcome of :func:`run_sweep`.

    Attributes:
        grid: the grid.
        objective: ``{motion | "both": (n_w1, n_w2, n_w3, n_s)}`` objective in cm.
        s_curve: ``{motion | "both": (len(grid.s_curve),)}`` objective along the s curve.
        optimum: ``{motion | "both": {"w1", "w2", "w3", "s", "objective_cm"}}``.
        cross: Table VII rows: ``[{"motion", "tuned_on", "weights", "joint", "rmse_cm", "rmse_cm_std"}]``.
        table7: the cross-motion table (ours beside the paper's).
        jobs: worker processes used; elapsed_s: wall time.
    """

    grid: SweepGrid
    objective: dict[str, np.ndarray]
    s_curve: dict[str, np.ndarray]
    optimum: dict[str, dict]
    cross: list[dict] = field(default_factory=list)
    table7: object | None = None
    jobs: int = 1
    elapsed_s: float = 0.0
    tuning_frames: dict[str, int] = field(default_factory=dict)
    dims: BodyDimensions | None = None

    def to_json(self) -> dict:
        from akc_drake.evaluation.report import nan_to_none

        d = {
            "grid": self.grid.as_dict(),
            "objective": "L2 norm over elbows and shoulders of the RMS Euclidean error (cm), first cycle",
            "optimum": self.optimum,
            "s_curve": {k: {"s": list(self.grid.s_curve), "objective_cm": v} for k, v in self.s_curve.items()},
            "objective_cm": {k: v for k, v in self.objective.items()},
            "cross_motion": self.cross,
            "tuning_frames": self.tuning_frames,
            "jobs": self.jobs,
            "elapsed_s": self.elapsed_s,
        }
        if self.dims is not None:
            d["dims_cm"] = {k: v * 100.0 for k, v in self.dims.as_dict().items()}
        if self.table7 is not None:
            d["tables"] = {"table7": self.table7.to_dict()}
        return nan_to_none(d)


def _argmin(values: np.ndarray) -> tuple[int, ...]:
    v = np.where(np.isfinite(values), values, np.inf)
    return tuple(int(i) for i in np.unravel_index(int(np.argmin(v)), v.shape))


def run_sweep(
    sessions: dict,
    dims: BodyDimensions,
    grid: SweepGrid | None = None,
    jobs: int = 1,
    options=None,
    progress: Callable[[int], None] | None = None,
    *,
    scheduler=None,
    show_progress: bool = False,
) -> SweepResult:
    """The sensitivity study over the motions in ``sessions``.

    Args:
        sessions: ``{motion: Session}`` (e.g. ``{"I": ..., "II": ...}``); each session renders once.
        dims: calibrated body dimensions (the T-pose calibration).
        grid: the grid (default :class:`SweepGrid`).
        jobs: worker processes of the local cluster (with ``scheduler`` None: 1 runs in this process,
            more on a Dask ``LocalCluster`` of ``jobs`` workers).
        options: :class:`~akc_drake.evaluation.methods.MethodOptions` for the occlusion filter and KF.
        progress: called with units done (one unit = one weight set on one motion's tuning frames, or one
            full-session AKC run of the cross-motion study).
        scheduler: "inprocess", "local", "tcp://HOST:PORT" or an open
            :class:`~akc_drake.evaluation.executor.Scheduler` (the grid's chunks run there).
        show_progress: show progress bars over the grid's tasks.

    Returns:
        The :class:`SweepResult`.
    """
    from akc_drake.evaluation.executor import Scheduler, open_scheduler

    if isinstance(jobs, bool) or not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    if scheduler is None:
        scheduler = "inprocess" if jobs == 1 else "local"
    if not isinstance(scheduler, Scheduler):
        with open_scheduler(scheduler, int(jobs)) as sched:
            return run_sweep(
                sessions, dims, grid, jobs, options, progress, scheduler=sched, show_progress=show_progress
            )
    from akc_drake.evaluation.methods import MethodRunner

    t0 = time.perf_counter()
    grid = grid or SweepGrid()
    if not sessions:
        raise ValueError("the sweep needs at least one motion session")
    full: dict[str, np.ndarray] = {}
    tuning: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name, s in sessions.items():
        filtered, _ = MethodRunner(s, dims, None, options).filtered("KF")
        full[name] = filtered
        sl = tuning_frames(s)
        tuning[name] = (filtered[sl], s.truth[sl])

    points = grid.points()
    flat = evaluate_points(points, tuning, dims, scheduler, progress, show_progress=show_progress)
    objective = {m: v.reshape(grid.shape) for m, v in flat.items()}
    if len(objective) > 1:
        objective["both"] = np.mean([objective[m] for m in sessions], axis=0)

    # The s curve at each key's best (w1, w2, w3); its points also compete for the optimum.
    optimum: dict[str, dict] = {}
    s_curve: dict[str, np.ndarray] = {}
    best_w = {k: _argmin(v)[:3] for k, v in objective.items()}
    if grid.s_curve:
        curve_pts = []
        for key in objective:
            i1, i2, i3 = best_w[key]
            curve_pts += [(grid.w1[i1], grid.w2[i2], grid.w3[i3], s) for s in grid.s_curve]
        curve_vals = evaluate_points(
            np.array(curve_pts), tuning, dims, scheduler, progress, chunks=4, show_progress=show_progress
        )
        n = len(grid.s_curve)
        for k_i, key in enumerate(objective):
            rows = slice(k_i * n, (k_i + 1) * n)
            if key == "both":
                s_curve[key] = np.mean([curve_vals[m][rows] for m in sessions], axis=0)
            else:
                s_curve[key] = curve_vals[key][rows]
    for key, obj in objective.items():
        idx = _argmin(obj)
        best = {
            "w1": grid.w1[idx[0]],
            "w2": grid.w2[idx[1]],
            "w3": grid.w3[idx[2]],
            "s": grid.s[idx[3]],
            "objective_cm": float(obj[idx]),
        }
        if key in s_curve and np.any(np.isfinite(s_curve[key])):
            j = int(np.argmin(np.where(np.isfinite(s_curve[key]), s_curve[key], np.inf)))
            if s_curve[key][j] < best["objective_cm"]:
                best["s"], best["objective_cm"] = grid.s_curve[j], float(s_curve[key][j])
        optimum[key] = best

    result = SweepResult(
        grid,
        objective,
        s_curve,
        optimum,
        jobs=scheduler.workers(),
        dims=dims,
        tuning_frames={m: int(tuning[m][0].shape[0]) for m in sessions},
    )
    result.cross = cross_motion(sessions, full, dims, optimum, progress)
    result.table7 = cross_motion_table(result.cross, list(sessions))
    result.elapsed_s = time.perf_counter() - t0
    return result


def cross_motion(
    sessions: dict,
    filtered: dict[str, np.ndarray],
    dims: BodyDimensions,
    optimum: dict[str, dict],
    progress: Callable[[int], None] | None = None,
) -> list[dict]:
    """Left-arm RMSE (mean ± std over the evaluated cycles) of every motion with every tuned weight set."""
    from akc_drake.core import metrics
    from akc_drake.evaluation.methods import run_akc

    rows = []
    for motion, s in sessions.items():
        cycles = s.evaluation_cycles(True)
        for tuned_on, best in optimum.items():
            point = (best["w1"], best["w2"], best["w3"], best["s"])
            from akc_drake.core.akc import ArmKinematicCorrector

            est = run_akc(ArmKinematicCorrector(dims, weights_from_point(point)), filtered[motion])[0]
            if progress is not None:
                progress(1)
            for joint in ("shoulder", "elbow"):
                j = INDEX[f"left_{joint}"]
                per = np.array([metrics.rmse_per_axis(est[sl, j], s.truth[sl, j])[0] for sl in cycles], dtype=float)
                with np.errstate(all="ignore"):
                    mean = np.nanmean(per, axis=0) * 100.0
                    std = np.nanstd(per, axis=0) * 100.0
                rows.append(
                    {
                        "motion": motion,
                        "tuned_on": tuned_on,
                        "weights": {k: best[k] for k in ("w1", "w2", "w3", "s")},
                        "joint": f"left_{joint}",
                        "rmse_cm": {a: float(v) for a, v in zip("xyz", mean, strict=True)},
                        "rmse_cm_std": {a: float(v) for a, v in zip("xyz", std, strict=True)},
                        "cycles": len(cycles),
                    }
                )
    return rows


#: Our tuned weight set that plays the part of each of the paper's presets in Table VII.
_PAPER_PRESET_OF = {"I": "Wa", "II": "Wb", "both": "Wc"}


def cross_motion_table(rows: list[dict], motions: list[str]):
    """Table VII in the paper's layout with our tuned weights (W_I ~ Wa, W_II ~ Wb, W_both ~ Wc)."""
    from akc_drake.evaluation.report import Table
    from akc_drake.resources import paper_results

    paper = paper_results()["table7_left_arm_rmse_29_cycles_cm"]
    order = [("I", "I"), ("II", "II"), ("I", "II"), ("II", "I"), ("I", "both"), ("II", "both")]
    order = [(m, w) for m, w in order if m in motions and any(r["tuned_on"] == w for r in rows)]
    if not order:
        order = [(m, w) for m in motions for w in dict.fromkeys(r["tuned_on"] for r in rows)]
    labels, ours, std, ref = [], [], [], []
    for motion, tuned in order:
        got = {r["joint"]: r for r in rows if r["motion"] == motion and r["tuned_on"] == tuned}
        pk = paper.get(f"{motion}_{_PAPER_PRESET_OF.get(tuned, '')}")
        for a, axis in enumerate("xyz"):
            labels.append(f"Motion {motion} using W_{tuned}, {axis}")
            ours.append([got["left_shoulder"]["rmse_cm"][axis], got["left_elbow"]["rmse_cm"][axis]])
            std.append([got["left_shoulder"]["rmse_cm_std"][axis], got["left_elbow"]["rmse_cm_std"][axis]])
            ref.append([pk["shoulder"][a], pk["elbow"][a]] if pk else [np.nan, np.nan])
    t = Table(
        "table7",
        "RMSE (cm) of the evaluated cycles with the weights tuned on each motion, left arm",
        labels,
        ["Shoulder", "Elbow"],
        np.array(ours, dtype=float).reshape(len(labels), 2),
        np.array(ref, dtype=float).reshape(len(labels), 2),
        ours_std=np.array(std, dtype=float).reshape(len(labels), 2),
    )
    t.notes.append(
        "W_I, W_II, W_both: our optimum on the first cycle of Motion I, II, both; the paper's figures "
        "are for its Wa (tuned on I), Wb (II), Wc (both)."
    )
    return t


def plot_curves(x, curves: dict[str, np.ndarray], path, xlabel: str, ylabel: str, title: str) -> Path:
    """Curves over ``x`` (the paper's Fig. 5 d, the shrink-factor curve), written as a PNG."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.8), layout="tight")
    ax = fig.subplots()
    for label, y in curves.items():
        ax.plot(x, y, marker="o", label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    return save_png(fig, path)


def sweep_figures(result: SweepResult, out_dir) -> list[Path]:
    """Heatmaps through each optimum (Fig. 5 a-c) and the s curve (Fig. 5 d) as PNG in ``out_dir``."""
    out_dir = Path(out_dir)
    g = result.grid
    paths = []
    for key, obj in result.objective.items():
        i1, i2, i3, i_s = _argmin(obj)
        s = g.s[i_s]
        panels = [
            {
                "title": f"w1 = {g.w1[i1]:g}, s = {s:g}",
                "x": g.w3,
                "y": g.w2,
                "z": obj[i1, :, :, i_s],
                "xlabel": "w3 (temporal)",
                "ylabel": "w2 (shoulder)",
                "best": (g.w3[i3], g.w2[i2]),
            },
            {
                "title": f"w3 = {g.w3[i3]:g}, s = {s:g}",
                "x": g.w2,
                "y": g.w1,
                "z": obj[:, :, i3, i_s],
                "xlabel": "w2 (shoulder)",
                "ylabel": "w1 (elbow)",
                "best": (g.w2[i2], g.w1[i1]),
            },
            {
                "title": f"w2 = {g.w2[i2]:g}, s = {s:g}",
                "x": g.w3,
                "y": g.w1,
                "z": obj[:, i2, :, i_s],
                "xlabel": "w3 (temporal)",
                "ylabel": "w1 (elbow)",
                "best": (g.w3[i3], g.w1[i1]),
            },
        ]
        label = "Motions I and II" if key == "both" else f"Motion {key}"
        paths.append(
            plot_heatmaps(
                panels,
                out_dir / f"sweep_heatmap_{key}.png",
                f"Effect of the AKC weights, {label} (first cycle)",
            )
        )
    if result.s_curve:
        curves = {("Motions I and II" if k == "both" else f"Motion {k}"): v for k, v in result.s_curve.items()}
        paths.append(
            plot_curves(
                np.array(g.s_curve),
                curves,
                out_dir / "sweep_s_curve.png",
                "shrink factor s",
                "L2 norm of joint errors (cm)",
                "Effect of the search shrink factor",
            )
        )
    return paths
