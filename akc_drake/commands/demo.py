"""``akc-drake demo``: the main job, on the built-in simulated scene (no camera, no network).

Calibrates from a rendered T-pose, then teleoperates the dual-arm robot through Motion I and Motion II with
each corrector (Raw, KF, AKC(KF), COIK(KF)) and prints a table comparing them. Writes ``demo.json``, the
plots, the Meshcat recording (``teleop.html``) and the teleop diagram's graph to ``--out`` (default
``out/demo``). The work is done by :func:`akc_drake.teleop.demo.run_demo`; this module only turns the options into
a :class:`~akc_drake.teleop.demo.DemoOptions`.

``--quick`` runs one cycle of each motion (3 by default). ``AKC_DEMO_MAX_FRAMES=N`` in the environment cuts
every motion to N camera frames (for the test suite; not a user option).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from akc_drake.errors import UserError

#: Environment variable that cuts every motion to this many frames (tests only).
MAX_FRAMES_ENV = "AKC_DEMO_MAX_FRAMES"


def _max_frames_from_env() -> int | None:
    raw = os.environ.get(MAX_FRAMES_ENV, "").strip()
    if not raw:
        return None
    try:
        n = int(raw)
    except ValueError:
        raise UserError(f"environment variable {MAX_FRAMES_ENV} must be an integer, got {raw!r}") from None
    if n < 10:
        raise UserError(f"environment variable {MAX_FRAMES_ENV} must be at least 10, got {n}")
    return n


def options_from_args(args):
    """The :class:`~akc_drake.teleop.demo.DemoOptions` for parsed ``akc-drake demo`` arguments."""
    from akc_drake.teleop import DemoOptions

    return DemoOptions(
        quick=bool(args.quick),
        dropout=args.dropout,
        seed=int(args.seed),
        out_dir=Path(args.out),
        html=Path(args.html) if args.html else None,
        record=True,
        max_frames=_max_frames_from_env(),
        ros2_bag=Path(args.ros2_bag) if getattr(args, "ros2_bag", None) else None,
        task=getattr(args, "task", None),
        seeds=getattr(args, "seeds", 5),
        operator=getattr(args, "operator", "closed"),
        body=getattr(args, "body", "primitive"),
        detector=getattr(args, "detector", "sim"),
        hand_model=getattr(args, "hand_model", None),
        progress=sys.stderr.isatty(),
    ).validate()


def _serve(meshcat) -> None:
    """Keep the Meshcat server up until Ctrl-C."""
    print(f"Meshcat is serving the recording at {meshcat.web_url()} (press Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)


def main(args) -> int:
    """Run ``akc-drake demo`` with parsed ``args`` (see ``akc_drake.cli``); returns the exit code."""
    from akc_drake import teleop
    from akc_drake.commands._common import check_output_dir, check_output_file

    opts = options_from_args(args)
    check_output_dir(args.out, "--out")
    for flag, path in (("--json", args.json), ("--html", args.html), ("--ros2-bag", getattr(args, "ros2_bag", None))):
        check_output_file(path, flag)
    if args.meshcat:
        meshcat, err = teleop.make_meshcat()
        if meshcat is None:
            raise UserError(f"--meshcat: Meshcat could not start ({err})")
        print(f"Meshcat: {meshcat.web_url()}", flush=True)
        opts.meshcat = meshcat
    summary = teleop.run_demo(opts, log=lambda line: print(line, flush=True))
    outputs = summary["outputs"]
    if args.json:
        from akc_drake.fileio import write_json

        write_json(args.json, summary)
        outputs["json_copy"] = str(args.json)
    print()
    print(teleop.format_table(summary))
    print()
    print("Wrote:")
    for key in ("json", "json_copy", "html", "graph_svg", "graph_dot"):
        if outputs.get(key):
            print(f"  {outputs[key]}")
    for path in outputs.get("plots", []):
        print(f"  {path}")
    print(f"Done in {summary['wall_s']:.0f} s.")
    if summary["nan_commands"] != 0:
        print(f"error: the robot was commanded with NaN {summary['nan_commands']} time(s)", file=sys.stderr)
        return 1
    if args.meshcat:
        _serve(opts.meshcat)
    return 0


__all__ = ["main", "options_from_args", "MAX_FRAMES_ENV"]
