import subprocess
import sys

from akc_drake import cli

SUBCOMMANDS = ("demo", "evaluate", "sweep", "graph", "record", "run", "calibrate", "bench")


def test_help_lists_every_subcommand():
    out = subprocess.run(
        [sys.executable, "-m", "akc_drake.cli", "--help"], capture_output=True, text=True, check=True
    ).stdout
    for name in SUBCOMMANDS:
        assert name in out


def test_usage_errors_exit_2(capsys):
    assert cli.main([]) == 2
    try:
        cli.main(["graph", "--diagram", "nonsense", "--out", "x"])
    except SystemExit as e:
        assert e.code == 2
    else:  # pragma: no cover - argparse always exits on a bad choice
        raise AssertionError("argparse accepted a bad --diagram")
