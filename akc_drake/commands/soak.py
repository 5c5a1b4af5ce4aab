"""``akc-drake soak``: a long simulated teleoperation session with random tracking loss; see
:mod:`akc_drake.pipeline.soak` for what runs and the JSON keys (``--json``).

Exit code 0 when every check passes, 1 otherwise, 2 for a bad option.
"""

from __future__ import annotations

import sys

from akc_drake.pipeline.soak import MAX_POSITION_VARIANCE_M2, MAX_RSS_GROWTH_MB, run_soak, soak_measurements

__all__ = ["MAX_POSITION_VARIANCE_M2", "MAX_RSS_GROWTH_MB", "main", "run_soak", "soak_measurements"]


def main(args) -> int:
    """Run ``akc-drake soak`` with parsed ``args`` (see ``akc_drake.cli``); returns the exit code."""
    from akc_drake.commands._common import check_output_file
    from akc_drake.fileio import write_json

    check_output_file(args.json, "--json")
    summary = run_soak(args.minutes, motion=args.motion, dropout=args.dropout, garbage=args.garbage,
                       seed=args.seed, sample_s=args.sample_s, progress=sys.stderr.isatty())
    if args.json:
        write_json(args.json, summary)
    c = summary["checks"]
    print(
        f"soak: {summary['simulated_s'] / 60:.1f} min simulated in {summary['wall_s']:.0f} s "
        f"(x{summary['realtime_factor']:.1f}), {summary['dropout_share']:.0%} of frames lost in "
        f"{summary['bursts']} bursts, {summary['garbage_share']:.0%} garbage"
    )
    speed = c["max_joint_speed_ratio"]["value"]
    variance = c["max_position_variance_m2"]["value"]
    print(
        f"  NaN commands {c['nan_commands']['value']}, max joint speed {speed:.3f} of the limit, memory "
        f"growth {c['rss_growth_mb']['value']:+.1f} MB, largest position variance {variance:.3g} m^2, "
        f"tracking lost {summary['tracking_lost_share']:.0%}"
    )
    failed = [name for name, check in c.items() if not check["ok"]]
    if failed:
        print(f"akc-drake soak: FAILED: {', '.join(failed)}", file=sys.stderr)
        return 1
    print("  all checks passed")
    return 0
