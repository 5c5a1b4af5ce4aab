"""``akc-drake bench [--json FILE] [--quick]``: measure the speed of every stage, side by side in one process.

Prints the figures (median, max, target) and the paper's Table III beside ours; ``--json`` writes them all
(DESIGN.md keys plus medians, maxima, memory, machine info and the paper's figures), atomically.
``--quick`` is the CI-sized run (well under a minute). Progress goes to stderr.
"""

from __future__ import annotations

import sys
from pathlib import Path

from akc_drake.errors import UserError


def _check_json_path(path: str) -> None:
    """Fail before the run when ``--json`` cannot be written."""
    p = Path(path)
    if p.is_dir():
        raise UserError(f"--json {path}: is a folder, expected a file name")
    parent = p.resolve().parent
    if parent.exists() and not parent.is_dir():
        raise UserError(f"--json {path}: {parent} is not a folder")


def main(args) -> int:
    from tqdm import tqdm

    from akc_drake.bench import BenchSettings, format_report, run_bench, write_json_atomic

    if args.json:
        _check_json_path(args.json)
    import dataclasses

    settings = BenchSettings.quick_run() if args.quick else BenchSettings.full()
    settings = dataclasses.replace(
        settings, body=getattr(args, "body", "primitive"), detector=getattr(args, "detector", "sim")
    )
    with tqdm(desc="bench", unit="step", file=sys.stderr, dynamic_ncols=True, leave=False,
              disable=not sys.stderr.isatty()) as bar:

        def progress(msg: str) -> None:
            bar.set_postfix_str(msg, refresh=False)
            bar.update(1)

        result = run_bench(settings, progress)
    print(format_report(result))
    if args.json:
        write_json_atomic(args.json, result)
        print(f"wrote {args.json}")
    return 0
