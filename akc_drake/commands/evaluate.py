"""``akc-drake evaluate``: reproduce the paper's tables and figures against ground truth.

Renders the calibration poses and each motion once, runs every method on the same measurements,
prints the tables in the paper's layout (ours, the paper's figure in brackets), and writes
``--json`` (DESIGN.md keys) and ``--out DIR`` (``report.md``, ``tables/*.csv``, ``figures/*.png``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from akc_drake.errors import UserError


def _motion_file_options(args) -> tuple[str | None, str | None]:
    mf, sk = getattr(args, "motion_file", None), getattr(args, "skeleton", None)
    if mf is None:
        if sk is not None:
            raise UserError(f"--skeleton {sk}: only used with --motion-file FILE.amc")
        return None, None
    p = Path(mf)
    suffix = p.suffix.lower()
    if suffix not in (".bvh", ".amc"):
        raise UserError(
            f"--motion-file {mf}: unknown file type {p.suffix!r} (expected .bvh, or .amc with --skeleton)"
        )
    if not p.is_file():
        raise UserError(f"--motion-file {mf}: no such file")
    if suffix == ".amc":
        if sk is None:
            raise UserError(f"--motion-file {mf}: an AMC motion needs its skeleton, --skeleton FILE.asf")
        if Path(sk).suffix.lower() != ".asf":
            raise UserError(f"--skeleton {sk}: expected an .asf file")
        if not Path(sk).is_file():
            raise UserError(f"--skeleton {sk}: no such file")
    elif sk is not None:
        raise UserError(f"--skeleton {sk}: only used with an .amc motion file, not {p.suffix}")
    return str(p), (str(sk) if sk else None)


def build_config(args):
    """An :class:`~akc_drake.evaluation.experiment.ExperimentConfig` from parsed options.

    Raises:
        UserError: naming the option and its value.
    """
    from akc_drake.evaluation.experiment import ExperimentConfig
    from akc_drake.evaluation.methods import parse_methods

    if args.cycles < 1:
        raise UserError(f"--cycles must be at least 1, got {args.cycles}")
    try:
        methods = parse_methods(args.methods)
    except ValueError as e:
        raise UserError(
            str(e) if str(e).startswith("--methods") else f"--methods {args.methods!r}: {e}"
        ) from None
    motion_file, skeleton = _motion_file_options(args)
    motions = ("I", "II") if args.motion == "both" else (args.motion,)
    try:
        return ExperimentConfig(
            motions=motions,
            cycles=args.cycles,
            seed=args.seed,
            methods=methods,
            weights=args.weights,
            width=getattr(args, "width", 640),
            height=getattr(args, "height", 480),
            motion_file=motion_file,
            skeleton=skeleton,
        )
    except ValueError as e:
        raise UserError(str(e)) from None


def _check_outputs(args) -> None:
    """Fail before the long run when an output cannot be written."""
    if args.json:
        parent = Path(args.json).resolve().parent
        if parent.exists() and not parent.is_dir():
            raise UserError(f"--json {args.json}: {parent} is not a folder")
        if Path(args.json).is_dir():
            raise UserError(f"--json {args.json}: is a folder, expected a file name")
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise UserError(f"--out {args.out}: exists and is not a folder")


def run(config, progress_bar: bool = True):
    """Render the sessions and run the experiment with tqdm progress bars (on stderr)."""
    from tqdm import tqdm

    from akc_drake.evaluation.experiment import frames_to_render, render_sessions, run_experiment, work_units

    total = frames_to_render(config) or None
    with tqdm(
        total=total,
        desc="render",
        unit="frame",
        file=sys.stderr,
        disable=not progress_bar,
        dynamic_ncols=True,
    ) as bar:

        def on_frame(n, name):
            bar.set_postfix_str(name, refresh=False)
            bar.update(n)

        t0 = time.perf_counter()
        sessions = render_sessions(config, on_frame)
        render_s = time.perf_counter() - t0
    with tqdm(
        total=work_units(config, sessions),
        desc="evaluate",
        unit="frame",
        file=sys.stderr,
        disable=not progress_bar,
        dynamic_ncols=True,
    ) as bar:

        def on_work(n, label):
            bar.set_postfix_str(label, refresh=False)
            bar.update(n)

        ev = run_experiment(config, sessions, on_work)
    ev.render_s = render_s
    return ev


def main(args) -> int:
    from akc_drake.evaluation.report import format_table, write_evaluation, write_json

    config = build_config(args)
    _check_outputs(args)
    if config.motion_file:
        # Read the motion file now: a bad file is reported in one line before the calibration renders.
        from akc_drake.operator.retarget import load_motion_file

        load_motion_file(config.motion_file, config.skeleton)
    ev = run(config)
    for table in ev.tables:
        print(format_table(table))
        print()
    # JSON first (small, what scripts read), then the folder.
    if args.json:
        write_json(args.json, ev.to_json())
        print(f"wrote {args.json}")
    if args.out:
        files = write_evaluation(ev, args.out)
        print(f"wrote {args.out}/report.md and {len(files) - 1} more files")
    print(f"rendering {ev.render_s:.1f} s, methods and metrics {ev.elapsed_s:.1f} s")
    return 0
