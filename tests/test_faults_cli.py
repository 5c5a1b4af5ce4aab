"""Bad files and options (issue 9, part 3): one clear line naming the file, line or field, exit code 2, no
traceback, and nothing already written is lost."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from akc_drake import cli
from akc_drake.core.camera import CameraIntrinsics
from akc_drake.fileio import atomic_save_npz as save_npz_atomic
from akc_drake.fileio import write_json
from akc_drake.io.recording import RecordingWriter

DATA = Path(__file__).parent / "data" / "mocap"
BVH = (DATA / "upper_body.bvh").read_text()
ASF = (DATA / "tiny.asf").read_text()
AMC = (DATA / "tiny.amc").read_text()
K = CameraIntrinsics(width=64, height=48, fx=60.0, fy=60.0, cx=31.5, cy=23.5, rate_hz=10.0)


def _first_motion_row(text: str) -> int:
    lines = text.split("\n")
    return next(i for i, line in enumerate(lines) if line.strip() and line.strip()[0] in "-0123456789")


def _bvh_variants() -> dict[str, tuple[str | bytes, str]]:
    """name -> (file content, text the error must contain)."""
    lines = BVH.split("\n")
    row = _first_motion_row(BVH)
    values = lines[row].split()

    def with_row(new_row: str) -> str:
        return "\n".join([*lines[:row], new_row, *lines[row + 1 :]])

    return {
        "truncated_motion": (BVH[: len(BVH) - 150], "truncated"),
        "truncated_hierarchy": (BVH[:900], ".bvh:"),
        "empty": ("", "empty"),
        "binary": (b"HIERARCHY\x00\xff\xfe", "not a text file"),
        "nan_value": (with_row(" ".join([*values[:3], "nan", *values[4:]])), "not a finite number"),
        "short_row": (with_row(" ".join(values[:-3])), "channels"),
        "negative_frame_time": (BVH.replace("Frame Time:", "Frame Time: -1 #"), "Frame Time"),
    }


def _run(argv, capsys) -> tuple[int, list[str], str]:
    rc = cli.main(argv)
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    return rc, lines, captured.out


def _assert_one_line_error(rc, lines, *must_contain):
    assert rc == 2
    assert len(lines) == 1, lines
    assert "Traceback" not in lines[0] and "error:" in lines[0]
    for text in must_contain:
        assert text in lines[0], (text, lines[0])


# ------------------------------------------------------------------------------------------------ mocap files
@pytest.mark.parametrize("name", list(_bvh_variants()))
def test_bad_bvh_files(tmp_path, capsys, name):
    content, expected = _bvh_variants()[name]
    path = tmp_path / f"{name}.bvh"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    rc, lines, _ = _run(["evaluate", "--motion-file", str(path), "--cycles", "1", "--methods", "Raw"], capsys)
    _assert_one_line_error(rc, lines, str(path), expected)


def test_truncated_bvh_names_the_line(tmp_path, capsys):
    path = tmp_path / "cut.bvh"
    path.write_text(BVH[: len(BVH) - 150])
    rc, lines, _ = _run(["evaluate", "--motion-file", str(path)], capsys)
    _assert_one_line_error(rc, lines)
    assert lines[0].split("error: ", 1)[1].startswith(f"{path}:")  # FILE:LINE: reason
    assert lines[0].split(f"{path}:", 1)[1].split(":", 1)[0].isdigit()


@pytest.mark.parametrize(
    "amc, asf, expected",
    [
        (AMC[: 2 * len(AMC) // 3], ASF, "tiny.amc:"),
        (AMC, ASF[: len(ASF) // 2], "tiny.asf:"),
        (AMC.replace("\nroot 0 ", "\nroot abc ", 1), ASF, "not a number"),
    ],
    ids=["truncated_amc", "truncated_asf", "malformed_amc"],
)
def test_bad_asf_amc_files(tmp_path, capsys, amc, asf, expected):
    (tmp_path / "tiny.amc").write_text(amc)
    (tmp_path / "tiny.asf").write_text(asf)
    rc, lines, _ = _run(["evaluate", "--motion-file", str(tmp_path / "tiny.amc"),
                         "--skeleton", str(tmp_path / "tiny.asf"), "--methods", "Raw"], capsys)
    _assert_one_line_error(rc, lines, expected)


def test_truncated_bvh_from_the_installed_command_is_one_line_and_exit_2(tmp_path):
    """The issue's acceptance check, through a real process: no traceback, one line on stderr."""
    path = tmp_path / "cut.bvh"
    path.write_text(BVH[: len(BVH) - 150])
    proc = subprocess.run(
        [sys.executable, "-m", "akc_drake.cli", "evaluate", "--motion-file", str(path)],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and str(path) in lines[0] and "Traceback" not in proc.stderr
    assert proc.stdout == ""


# ------------------------------------------------------------------------------------------------ recordings
def _recording(path: Path, n: int = 4) -> Path:
    rng = np.random.default_rng(1)
    with RecordingWriter(path, K) as w:
        for i in range(n):
            w.write(0.1 * i, rng.integers(0, 256, (48, 64, 3), dtype=np.uint8), np.full((48, 64), 2.0), None)
    return path


def _edit_intrinsics(rec: Path, **changes) -> None:
    p = rec / "intrinsics.json"
    d = json.loads(p.read_text())
    d.update(changes)
    p.write_text(json.dumps(d))


@pytest.mark.parametrize(
    "break_it, expected",
    [
        (lambda r: (r / "color" / "000002.png").unlink(), "000002.png"),
        (lambda r: (r / "depth" / "000003.png").unlink(), "000003.png"),
        (lambda r: _edit_intrinsics(r, width=640), "does not match intrinsics.json"),
        (lambda r: _edit_intrinsics(r, fx=-615.0), "fx"),
        (lambda r: _edit_intrinsics(r, fx="wide"), "fx"),
        (lambda r: _edit_intrinsics(r, lens="fisheye"), "lens"),
        (lambda r: (r / "intrinsics.json").write_text("{not json"), "intrinsics.json"),
        (lambda r: (r / "intrinsics.json").unlink(), "intrinsics.json"),
        (lambda r: (r / "timestamps.csv").write_text("index,t\n0,0.0\n1,zero\n"), "line 3"),
        (lambda r: (r / "timestamps.csv").write_text("index,t\n0,0.2\n1,0.1\n"), "timestamps.csv"),
    ],
    ids=["missing_color", "missing_depth", "wrong_size", "negative_fx", "fx_not_a_number", "unknown_field",
         "intrinsics_not_json", "no_intrinsics", "bad_timestamp", "time_goes_back"],
)
def test_bad_recording_folders(tmp_path, capsys, break_it, expected):
    rec = _recording(tmp_path / "rec")
    break_it(rec)
    rc, lines, _ = _run(["run", "--source", f"recording:{rec}", "--json", str(tmp_path / "r.json")], capsys)
    _assert_one_line_error(rc, lines, str(rec), expected)
    assert not (tmp_path / "r.json").exists()


@pytest.mark.parametrize("content", [b"", b"\x00" * 64, bytes(range(256)) * 8],
                         ids=["empty", "zeros", "noise"])
def test_unreadable_bag(tmp_path, capsys, content):
    bag = tmp_path / "session.bag"
    bag.write_bytes(content)
    rc, lines, _ = _run(["run", "--source", f"bag:{bag}"], capsys)
    _assert_one_line_error(rc, lines, str(bag))


def test_missing_bag_and_unknown_source(tmp_path, capsys):
    rc, lines, _ = _run(["run", "--source", f"bag:{tmp_path / 'nope.bag'}"], capsys)
    _assert_one_line_error(rc, lines, "nope.bag")
    rc, lines, _ = _run(["run", "--source", "webcam:0"], capsys)
    _assert_one_line_error(rc, lines, "webcam")


# ------------------------------------------------------------------------------------------------ config
@pytest.mark.parametrize(
    "text, expected",
    [
        ("cycles: many\n", ["line 1", "field cycles", "many"]),
        ("motion: I\ncycle: 2\n", ["line 2", "unknown key 'cycle'"]),
        ("camera:\n  width: wide\n", ["line 2", "field camera.width"]),
        ("camera: {rate_hz: 10, fps: 30}\n", ["unknown key 'camera.fps'"]),
        ("gate_sigma: [1, 2]\n", ["field gate_sigma"]),
        ("cycles: [1\n", ["not a valid YAML config", "line 2"]),
        ("filter: UKF\n", ["config.filter", "UKF"]),
        ("cycles: 0\n", ["config.cycles"]),
        ("- 1\n- 2\n", ["dict"]),
        ("dims: {LUA: -0.3, LLA: 0.27, RUA: 0.3, RLA: 0.27, SW: 0.36}\n", ["LUA", "-0.3"]),
        ("max_predict_s: 0\n", ["max_predict_s"]),
    ],
    ids=["wrong_type", "unknown_key", "nested_wrong_type", "nested_unknown_key", "list_for_float",
         "yaml_syntax", "bad_choice", "zero_cycles", "not_a_mapping", "negative_dims", "zero_predict"],
)
def test_bad_yaml_config(tmp_path, capsys, text, expected):
    cfg = tmp_path / "run.yaml"
    cfg.write_text(text)
    rc, lines, _ = _run(["run", "--config", str(cfg)], capsys)
    _assert_one_line_error(rc, lines, str(cfg), *expected)


@pytest.mark.parametrize(
    "content, expected",
    [
        ({"LUA": -0.3, "LLA": 0.27, "RUA": 0.3, "RLA": 0.27, "SW": 0.36}, ["LUA", "-0.3"]),
        ({"LUA": 30.0, "LLA": 0.27, "RUA": 0.3, "RLA": 0.27, "SW": 0.36}, ["LUA", "30"]),
        ({"LUA": 0.0, "LLA": 0.27, "RUA": 0.3, "RLA": 0.27, "SW": 0.36}, ["LUA"]),
        ({"LUA": "long", "LLA": 0.27, "RUA": 0.3, "RLA": 0.27, "SW": 0.36}, ["LUA", "long"]),
        ({"LUA": 0.3, "LLA": 0.27, "RUA": 0.3, "RLA": 0.27}, ["SW"]),
        ('{"LUA": 0.3, "LL', ["not valid JSON"]),
    ],
    ids=["negative", "absurd", "zero", "not_a_number", "missing_field", "truncated_json"],
)
def test_bad_body_dimensions(tmp_path, capsys, content, expected):
    dims = tmp_path / "dims.json"
    dims.write_text(content if isinstance(content, str) else json.dumps(content))
    rc, lines, _ = _run(["run", "--dims", str(dims)], capsys)
    _assert_one_line_error(rc, lines, str(dims), *expected)


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["run", "--seconds", "-1"], "--seconds"),
        (["evaluate", "--cycles", "0"], "--cycles"),
        (["evaluate", "--methods", "Raw,UKF"], "UKF"),
        (["evaluate", "--motion-file", "walk.c3d"], "walk.c3d"),
        (["record", "--cycles", "0", "--out", "x"], "--cycles"),
    ],
)
def test_bad_options(capsys, argv, expected):
    rc, lines, _ = _run(argv, capsys)
    _assert_one_line_error(rc, lines, expected)


# ------------------------------------------------------------------------------------------------ outputs
def test_a_failing_run_leaves_earlier_outputs_intact(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    previous = {"frames": 61, "note": "an earlier, valid result"}
    (out / "r.json").write_text(json.dumps(previous))
    save_npz_atomic(out / "poses.npz", t=np.arange(3.0))
    before = (out / "poses.npz").read_bytes()
    bad = tmp_path / "cut.bvh"
    bad.write_text(BVH[:900])
    rc, lines, _ = _run(["evaluate", "--motion-file", str(bad), "--json", str(out / "r.json"),
                         "--out", str(out)], capsys)
    _assert_one_line_error(rc, lines, str(bad))
    rc, lines, _ = _run(["run", "--source", f"recording:{tmp_path / 'none'}", "--json", str(out / "r.json"),
                         "--out", str(out)], capsys)
    _assert_one_line_error(rc, lines, "none")
    assert json.loads((out / "r.json").read_text()) == previous
    assert (out / "poses.npz").read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == ["poses.npz", "r.json"]


def test_writes_are_atomic_a_failed_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "summary.json"
    write_json(target, {"frames": 10})
    with pytest.raises(TypeError):
        write_json(target, {"frames": object()})  # not serialisable: fails half-way through
    assert json.loads(target.read_text()) == {"frames": 10}
    npz = tmp_path / "poses.npz"
    save_npz_atomic(npz, t=np.arange(4.0))
    with pytest.raises(ValueError):
        save_npz_atomic(npz, t=np.arange(4.0), bad=np.array([object()], dtype=object))
    with np.load(npz, allow_pickle=False) as data:
        np.testing.assert_array_equal(data["t"], np.arange(4.0))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["poses.npz", "summary.json"]


# ------------------------------------------------------------------------------------------------ security
PACKAGE = Path(__file__).resolve().parents[1] / "akc_drake"
PICKLERS = ("pickle", "cPickle", "dill", "shelve", "marshal", "joblib")


def _calls(tree):
    import ast

    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
            owner = f.value.id if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) else ""
            yield name, owner, node


def test_no_pickle_no_shell_and_meshcat_on_localhost_in_the_package_source():
    import ast

    problems = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        where = path.relative_to(PACKAGE.parent)
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names]
                if isinstance(node, ast.ImportFrom):
                    names.append(node.module)
                if any(n and n.split(".")[0] in PICKLERS for n in names):
                    problems.append(f"{where}:{node.lineno}: imports a pickle module")
        for name, owner, call in _calls(tree):
            kw = {k.arg: k.value for k in call.keywords}
            if isinstance(kw.get("allow_pickle"), ast.Constant) and kw["allow_pickle"].value is True:
                problems.append(f"{where}:{call.lineno}: allow_pickle=True")
            if name == "load" and owner in ("np", "numpy"):
                flag = kw.get("allow_pickle")
                if not (isinstance(flag, ast.Constant) and flag.value is False):
                    problems.append(f"{where}:{call.lineno}: np.load without allow_pickle=False")
            if isinstance(kw.get("shell"), ast.Constant) and kw["shell"].value:
                problems.append(f"{where}:{call.lineno}: shell=True")
            if (owner == "os" and name in ("system", "popen", "execv", "execvp")) or name in ("eval", "exec"):
                problems.append(f"{where}:{call.lineno}: {owner + '.' if owner else ''}{name}()")
            if name in ("expandvars",):
                problems.append(f"{where}:{call.lineno}: expands environment variables in a path")
            if name == "Meshcat" and not call.args and not call.keywords:
                problems.append(f"{where}:{call.lineno}: Meshcat() listens on every interface")
    assert not problems, "\n".join(problems)


class _FakeMeshcat:
    instances: list = []

    def __init__(self, params=None):
        self.params = params
        _FakeMeshcat.instances.append(self)

    def web_url(self):
        raise _Stop("enough: the server would start here")


class _Stop(Exception):
    pass


def test_meshcat_servers_listen_on_localhost_only(monkeypatch):
    import pydrake.geometry

    _FakeMeshcat.instances.clear()
    monkeypatch.setattr(pydrake.geometry, "Meshcat", _FakeMeshcat)
    with pytest.raises(_Stop):
        cli.main(["run", "--teleop", "--meshcat", "--motion", "tpose"])
    from akc_drake import teleop

    meshcat, reason = teleop.make_meshcat()
    assert reason is None and meshcat is _FakeMeshcat.instances[-1]
    assert len(_FakeMeshcat.instances) == 2
    for m in _FakeMeshcat.instances:
        assert m.params is not None and m.params.host == "localhost"


def test_paths_from_a_config_file_are_never_run_by_a_shell(tmp_path, capsys):
    marker = tmp_path / "pwned"
    for text in (f"motion: $(touch {marker}).bvh\n", f"motion: '`touch {marker}`.bvh'\n",
                 f"motion: x.amc\nskeleton: ; touch {marker}\n"):
        cfg = tmp_path / "evil.yaml"
        cfg.write_text(text)
        rc, lines, _ = _run(["run", "--config", str(cfg)], capsys)
        _assert_one_line_error(rc, lines, "not found")
    rc, lines, _ = _run(["run", "--source", f"recording:$(touch {marker})"], capsys)
    _assert_one_line_error(rc, lines, "not found")
    assert not marker.exists()
