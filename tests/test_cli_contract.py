"""The command line as a contract: DESIGN.md's flags exist, every flag is documented with its default, shared
flags are spelled and checked the same way everywhere, and usage mistakes are one line with exit code 2."""

import argparse

import pytest

from akc_drake import cli

# DESIGN.md, "Contracts that other tools rely on": the flags each command line names.
DESIGN_FLAGS = {
    "demo": ["--quick", "--dropout", "--task", "--seeds", "--out", "--json", "--meshcat", "--html"],
    "evaluate": ["--motion", "--motion-file", "--skeleton", "--motion-dir", "--cycles", "--seed", "--body",
                 "--detector", "--protocol", "--methods", "--weights", "--out", "--json"],
    "sweep": ["--motion", "--cycles", "--jobs", "--out", "--json"],
    "graph": ["--diagram", "--out"],
    "record": ["--motion", "--cycles", "--body", "--out"],
    "run": ["--source", "--detector", "--teleop", "--json"],
    "calibrate": ["--source", "--pose", "--frames", "--out"],
    "bench": ["--json"],
}


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def _option(p: argparse.ArgumentParser, flag: str) -> argparse.Action:
    return next(a for a in p._actions if flag in a.option_strings)


def _usage_error(argv, capsys) -> str:
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err  # one line, no usage block and no traceback
    return err


def test_design_flags_exist():
    subs = _subparsers()
    for command, flags in DESIGN_FLAGS.items():
        options = {s for a in subs[command]._actions for s in a.option_strings}
        missing = [f for f in flags if f not in options]
        assert not missing, f"{command}: {missing}"


def test_design_choices():
    subs = _subparsers()
    assert _option(subs["evaluate"], "--weights").choices == ("Wa", "Wb", "Wc")
    assert _option(subs["evaluate"], "--protocol").choices == ("paper", "ours")
    assert _option(subs["graph"], "--diagram").choices == ("mocap", "teleop")
    assert _option(subs["calibrate"], "--pose").choices == ("tpose", "lpose")
    assert _option(subs["calibrate"], "--frames").default == 100
    assert _option(subs["demo"], "--task").choices == ("pick-place",)
    for name in ("Raw", "KF", "EKF", "COIK(KF)", "AKC(KF)", "AKC(EKF)", "AKC+(KF)", "AKC+(EKF)"):
        assert name in cli.METHODS


def test_every_option_documented_with_its_default():
    for command, p in _subparsers().items():
        fmt = p._get_formatter()
        for a in p._actions:
            if not a.option_strings or a.help == argparse.SUPPRESS or isinstance(a, argparse._HelpAction):
                continue
            assert a.help, f"{command} {a.option_strings[0]}: no help text"
            text = fmt._expand_help(a)
            if a.default not in (None, False):
                assert "default" in text, f"{command} {a.option_strings[0]}: default not shown: {text!r}"


def test_shared_flags_spelled_and_checked_alike():
    subs = _subparsers()
    for command, p in subs.items():
        flags = {s for a in p._actions for s in a.option_strings}
        if "--body" in flags:
            assert _option(p, "--body").choices == ("primitive", "skinned"), command
        if "--detector" in flags:
            assert set(_option(p, "--detector").choices) >= {"sim", "mediapipe"}, command
        if "--seed" in flags:
            seed = _option(p, "--seed")
            assert seed.type is cli._seed and seed.default == 0, command
        if "--cycles" in flags:
            assert _option(p, "--cycles").type is int, command
    # evaluate's --workers is accepted by sweep too (as its --jobs)
    args = cli.build_parser().parse_args(["sweep", "--workers", "3"])
    assert args.jobs == 3


@pytest.mark.parametrize("command", ["demo", "evaluate", "sweep", "record", "run", "soak"])
def test_negative_seed_is_one_line_exit_2(command, capsys):
    extra = ["--out", "x"] if command == "record" else []
    err = _usage_error([command, "--seed", "-1", *extra], capsys)
    assert err.startswith(f"akc-drake {command}: error: argument --seed:")
    assert "-1" in err


def test_bad_value_and_missing_flag_are_one_line(capsys):
    err = _usage_error(["evaluate", "--cycles", "abc"], capsys)
    assert "argument --cycles" in err and "'abc'" in err
    err = _usage_error(["record", "--motion", "I"], capsys)
    assert "--out" in err and "required" in err
    err = _usage_error(["run", "--corrector", "AKC++"], capsys)
    assert "argument --corrector" in err and "AKC++" in err


def test_run_takes_skeleton_for_amc_motion():
    args = cli.build_parser().parse_args(["run", "--motion", "clip.amc", "--skeleton", "clip.asf"])
    from akc_drake.commands.run import _config

    assert _config(args).skeleton == "clip.asf"


def test_run_takes_akc_plus_settings(capsys):
    from akc_drake.commands.run import _config

    args = cli.build_parser().parse_args(["run", "--corrector", "AKC+", "--akc-plus", "gate_sigma=2.5,nis_alpha=0.1"])
    assert _config(args).akc_plus == {"gate_sigma": 2.5, "nis_alpha": 0.1}
    assert cli.main(["run", "--akc-plus", "gate_sigma=2.5"]) == 2  # (the default corrector is the paper's AKC)
    assert "add --corrector AKC+" in capsys.readouterr().err
    assert cli.main(["run", "--corrector", "AKC+", "--akc-plus", "gate_sigm=2.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown AKC+ setting(s) 'gate_sigm'" in err
    assert cli.main(["evaluate", "--methods", "Raw,KF", "--akc-plus", "gate_sigma=2.5"]) == 2
    assert "runs none" in capsys.readouterr().err
    assert cli.main(["evaluate", "--akc-plus", "gate_sigma=-1"]) == 2
    assert "gate_sigma must be a finite number >= 0" in capsys.readouterr().err


def test_evaluate_takes_a_camera_placement(capsys):
    from akc_drake.commands.evaluate import build_config

    args = cli.build_parser().parse_args(["evaluate", "--camera", "distance_m=3,lateral_m=-0.5"])
    assert build_config(args).camera == {"distance_m": 3.0, "height_m": 0.45, "lateral_m": -0.5, "aim_height_m": None}
    assert build_config(cli.build_parser().parse_args(["evaluate"])).camera == "default"
    assert cli.main(["evaluate", "--camera", "distance=3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--camera: unknown field(s) distance (known: distance_m, height_m" in err


def test_run_cycles_named(capsys):
    assert cli.main(["run", "--cycles", "0"]) == 2
    assert capsys.readouterr().err.strip() == "akc-drake run: error: --cycles must be at least 1, got 0"


def test_graph_out_is_a_file(tmp_path, capsys):
    f = tmp_path / "taken.json"
    f.write_text("{}")
    assert cli.main(["graph", "--diagram", "mocap", "--out", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and "not a folder" in err
    assert cli.main(["graph", "--diagram", "mocap", "--out", str(f / "sub")]) == 2
    assert "not a folder" in capsys.readouterr().err
    assert f.read_text() == "{}"


@pytest.mark.parametrize(
    "argv, flag",
    [
        (["run", "--json", "{dir}"], "--json"),
        (["run", "--json", "{file}/x.json"], "--json"),
        (["run", "--out", "{file}"], "--out"),
        (["soak", "--minutes", "0.05", "--json", "{dir}"], "--json"),
        (["demo", "--quick", "--body", "primitive", "--detector", "sim", "--json", "{dir}"], "--json"),
        (["demo", "--quick", "--body", "primitive", "--detector", "sim", "--html", "{file}/t.html"], "--html"),
        (["demo", "--quick", "--body", "primitive", "--detector", "sim", "--out", "{file}"], "--out"),
        (["calibrate", "--out", "{file}/dims.json"], "--out"),
        (["sweep", "--json", "{dir}"], "--json"),
        (["sweep", "--out", "{file}"], "--out"),
    ],
)
def test_unwritable_outputs_fail_before_the_work(argv, flag, tmp_path, capsys):
    """An output path that cannot be written is one line naming the flag, exit 2, before anything runs
    (it used to be a traceback after the run, losing its results)."""
    taken = tmp_path / "taken.txt"
    taken.write_text("keep")
    argv = [a.format(dir=tmp_path, file=taken) for a in argv]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"error: {flag} " in err, err
    assert taken.read_text() == "keep"


def test_os_error_on_a_path_is_one_line(monkeypatch, capsys):
    import akc_drake.commands.graph as graph

    def fail(args):
        raise IsADirectoryError(21, "Is a directory", "/some/out.json")

    monkeypatch.setattr(graph, "main", fail)
    assert cli.main(["graph", "--diagram", "mocap", "--out", "x"]) == 2
    assert capsys.readouterr().err == "akc-drake graph: error: /some/out.json: Is a directory\n"


def test_record_tells_how_a_primitive_recording_replays():
    from akc_drake.commands.record import replay_note

    assert "--body skinned" in replay_note("primitive") and "MediaPipe" in replay_note("primitive")
    assert replay_note("skinned") is None


def test_evaluate_rate_reaches_the_experiment_and_is_checked(capsys):
    from akc_drake.commands.evaluate import build_config

    args = cli.build_parser().parse_args(["evaluate", "--motion", "I", "--rate-hz", "30"])
    assert build_config(args).rate_hz == 30.0
    assert build_config(cli.build_parser().parse_args(["evaluate"])).rate_hz == 10.0
    assert cli.main(["evaluate", "--rate-hz", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--rate-hz must be a frame rate between 1 and 240 Hz, got 0" in err
    assert cli.main(["evaluate", "--motion-dir", "data/mocap", "--rate-hz", "300"]) == 2
    assert "--rate-hz must be a frame rate between 1 and 240 Hz, got 300" in capsys.readouterr().err
