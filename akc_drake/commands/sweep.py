"""``akc-drake sweep``: the AKC weight and shrink-factor sensitivity study (paper §III-E, Fig. 5, Table VII).

Renders the T-pose (calibration) and each motion once (through the render cache), tunes (w1, w2, w3, s) on
each motion's first cycle over a grid, as tasks on ``--scheduler`` (default: a Dask LocalCluster of ``--jobs``
workers; ``inprocess``; or ``tcp://HOST:PORT``, a Dask cluster), applies every optimum to the other cycles of
both motions (cross-motion robustness), prints the optimum and Table VII, and writes ``--json`` and
``--out DIR`` (heatmaps, the s curve, ``sweep.md``, ``tables/table7.csv``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from akc_drake.commands._common import check_output_dir, check_output_file
from akc_drake.errors import UserError


def main(args) -> int:
    from akc_drake.evaluation.executor import TaskFailure, check_scheduler, open_scheduler, run_tasks
    from akc_drake.evaluation.experiment import CYCLE_S, ExperimentConfig, calibrate_session
    from akc_drake.evaluation.report import (
        atomic_write_text,
        format_table,
        report_markdown,
        write_json,
        write_tables,
    )
    from akc_drake.evaluation.sweep import SweepGrid, run_sweep, sweep_figures
    from akc_drake.evaluation.tasks import render_task, session_from_plain, session_specs

    if args.cycles < 1:
        raise UserError(f"--cycles must be at least 1, got {args.cycles}")
    if args.jobs < 1:
        raise UserError(f"--jobs must be at least 1, got {args.jobs}")
    scheduler = check_scheduler(getattr(args, "scheduler", "local"))
    check_output_dir(args.out, "--out")
    check_output_file(args.json, "--json")
    motions = ("I", "II") if args.motion == "both" else (args.motion,)
    config = ExperimentConfig(
        motions=motions, cycles=args.cycles, seed=args.seed, calibration_study=False, weight_study=False
    )
    grid = SweepGrid()

    t0 = time.perf_counter()
    specs = session_specs(config)
    names = ["tpose", *motions]
    with open_scheduler(scheduler, args.jobs) as sched:
        rendered = run_tasks(
            render_task, [{"spec": specs[n]} for n in names], scheduler=sched, desc="render", labels=names
        )
        bad = [r for r in rendered if isinstance(r, TaskFailure)]
        if bad:
            raise UserError(f"rendering {bad[0].line()}")
        sessions = {n: session_from_plain(r["session"]) for n, r in zip(names, rendered, strict=True)}
        opts = config.run_options()  # the protocol's stages (the paper's by default), as evaluate
        dims = calibrate_session(sessions["tpose"], "tpose", opts)
        motion_sessions = {m: sessions[m] for m in motions}
        workers = sched.workers()
        print(f"sweep on {scheduler} ({workers} worker{'s' if workers != 1 else ''})", file=sys.stderr)
        result = run_sweep(motion_sessions, dims, grid, args.jobs, opts, scheduler=sched, show_progress=True)
    elapsed = time.perf_counter() - t0

    print("Optimum weights (tuned on the first cycle; objective = L2 norm of the joints' RMS Euclidean errors):")
    for key, best in result.optimum.items():
        label = "Motions I and II" if key == "both" else f"Motion {key}"
        print(
            f"  {label:17s} w1={best['w1']:g} w2={best['w2']:g} w3={best['w3']:g} s={best['s']:g}  "
            f"({best['objective_cm']:.2f} cm)"
        )
    print()
    print(format_table(result.table7))
    doc = result.to_json()
    doc["config"] = {
        "motion": args.motion,
        "cycles": args.cycles,
        "seed": args.seed,
        "jobs": args.jobs,
        "scheduler": scheduler,
        "workers": result.jobs,
        "rate_hz": config.rate_hz,
        "cycle_s": CYCLE_S,
        "elapsed_s": elapsed,
    }
    if args.json:
        write_json(args.json, doc)
        print(f"wrote {args.json}")
    if args.out:
        out = Path(args.out)
        figs = sweep_figures(result, out / "figures")
        write_tables([result.table7], out)
        lines = [
            f"- **{k}**: w1={b['w1']:g}, w2={b['w2']:g}, w3={b['w3']:g}, s={b['s']:g} ({b['objective_cm']:.2f} cm)"
            for k, b in result.optimum.items()
        ]
        md = report_markdown(
            "akc-drake sweep",
            doc["config"],
            [result.table7],
            figs,
            out,
            ["Optimum per motion (first cycle):\n\n" + "\n".join(lines)],
        )
        atomic_write_text(out / "sweep.md", md)
        print(f"wrote {out}/sweep.md, {len(figs)} figures")
    print(f"took {elapsed:.1f} s")
    return 0
