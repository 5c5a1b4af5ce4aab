"""Packaging: the wheel carries the models and runs on its own; one OpenCV; ``pip check`` passes.

Offline and fast: the wheel is built from a copy of the sources (``pip wheel --no-deps --no-build-isolation``)
and installed (``pip install --no-deps``) into a fresh venv. The venv sees the dependencies through one ``.pth``
line to a folder of links to exactly the installed distributions that the wheel's requirements (with or without
the extras) reach from ``.venv``, the way ``pip install akc-drake[...]`` would have installed them. The
project's own editable install is not among them, so everything ``akc_drake`` loads comes from the wheel.
"""

from __future__ import annotations

import importlib.metadata as md
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]
PY = sys.executable
TIMEOUT = 300

def _run(cmd, **kw) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=TIMEOUT, env=env, **kw)


def _ok(p: subprocess.CompletedProcess) -> str:
    assert p.returncode == 0, f"{p.args}\n{p.stdout}\n{p.stderr}"
    return p.stdout


def _closure(names_and_extras: list[tuple[str, set[str]]]) -> dict[str, md.Distribution]:
    """The installed distributions reached from the given requirements (markers evaluated with their extras)."""
    seen: dict[str, md.Distribution] = {}
    extras_done: dict[str, set[str]] = {}
    todo = list(names_and_extras)
    while todo:
        name, extras = todo.pop()
        key = canonicalize_name(name)
        if key in seen and extras <= extras_done[key]:
            continue
        dist = md.distribution(name)  # PackageNotFoundError: a requirement is not installed in .venv
        seen[key] = dist
        extras_done[key] = extras_done.get(key, set()) | extras
        for spec in dist.requires or []:
            req = Requirement(spec)
            envs = [{"extra": e} for e in (extras_done[key] or {""})] + [{"extra": ""}]
            if req.marker is None or any(req.marker.evaluate(env) for env in envs):
                todo.append((req.name, set(req.extras)))
    return seen


def _wheel_requirements(wheel: Path) -> list[str]:
    with zipfile.ZipFile(wheel) as z:
        meta = next(n for n in z.namelist() if n.endswith(".dist-info/METADATA"))
        text = z.read(meta).decode()
    return [line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("Requires-Dist:")]


def _deps_view(wheel: Path, extras: set[str], where: Path) -> tuple[Path, dict[str, md.Distribution]]:
    """A folder of links to the distributions the wheel needs with ``extras``, as ``pip install`` leaves them."""
    roots = []
    for spec in _wheel_requirements(wheel):
        req = Requirement(spec)
        if req.marker is None or any(req.marker.evaluate({"extra": e}) for e in extras | {""}):
            roots.append((req.name, set(req.extras)))
    dists = _closure(roots)
    where.mkdir()
    owners: dict[str, list[str]] = {}
    for name, dist in dists.items():
        site = Path(dist.locate_file(""))
        for top in sorted({f.parts[0] for f in dist.files or [] if f.parts and f.parts[0] != ".."}):
            owners.setdefault(top, []).append(name)
            if not (where / top).exists():
                (where / top).symlink_to(site / top)
    shared = {top: names for top, names in owners.items() if len(names) > 1 and top != "__pycache__"}
    assert not shared, f"several installed distributions own the same files: {shared}"
    return where, dists


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The project's wheel, built from a copy of the sources (the working tree gets no build/ folder)."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        if (ROOT / name).exists():
            shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "akc_drake", src / "akc_drake", ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path_factory.mktemp("wheel")
    _ok(_run([PY, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "--no-index", src, "-w", out]))
    (whl,) = out.glob("akc_drake-*.whl")
    return whl


def _venv(tmp: Path, wheel: Path, extras: set[str]) -> tuple[Path, dict[str, md.Distribution]]:
    venv = tmp / "venv"
    _ok(_run([PY, "-m", "venv", "--without-pip", venv]))
    vpy = venv / "bin" / "python"
    view, dists = _deps_view(wheel, extras, tmp / "deps")
    site = Path(_ok(_run([vpy, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"])).strip())
    (site / "_akc_deps.pth").write_text(f"{view}\n")
    _ok(_run([PY, "-m", "pip", "--python", vpy, "install", "-q", "--no-deps", "--no-index", wheel]))
    return venv, dists


def test_the_wheel_carries_the_models_and_the_paper_figures(wheel):
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    for f in (
        "akc_drake/models/dual_arm_manipulator.urdf",
        "akc_drake/models/operator.sdf",
        "akc_drake/models/teleop_scene.sdf",
        "akc_drake/models/operator_meshes/unit_sphere.obj",
        "akc_drake/data/paper_results.json",
    ):
        assert f in names, f
    assert not any(n.startswith(("tests/", "build/")) for n in names)
    # every data file the repository tracks under models/ and data/ (a new asset must be listed in
    # pyproject's [tool.setuptools.package-data])
    tracked = subprocess.run(["git", "ls-files", "akc_drake/models", "akc_drake/data"], cwd=ROOT,
                             capture_output=True, text=True)
    if tracked.returncode == 0:
        missing = [f for f in tracked.stdout.split() if f not in names]
        assert not missing, f"not in the wheel: {missing}"


def test_the_wheel_runs_in_a_fresh_venv_without_the_extras(wheel, tmp_path):
    venv, dists = _venv(tmp_path, wheel, set())
    assert "mediapipe" not in dists and "pyrealsense2" not in dists
    vpy = venv / "bin" / "python"
    _ok(_run([PY, "-m", "pip", "--python", vpy, "check"]))
    probe = (
        "import json, cv2, akc_drake, akc_drake.resources as r\n"
        "from pydrake.multibody.plant import MultibodyPlant\n"
        "from akc_drake.robot.model import add_dual_arm_robot\n"
        "add_dual_arm_robot(MultibodyPlant(0.0))\n"
        "print(json.dumps({'pkg': akc_drake.__file__, 'models': str(r.MODELS_DIR), 'cv2': cv2.__version__,"
        " 'robot': str(r.model_path('dual_arm_manipulator.urdf')), 'operator': str(r.model_path('operator.sdf'))}))"
    )
    info = json.loads(_ok(_run([vpy, "-c", probe], cwd=tmp_path)).strip().splitlines()[-1])
    for key in ("pkg", "models", "robot", "operator"):
        assert info[key].startswith(str(venv)), (key, info[key])  # from the wheel, not the source tree
    # `akc-drake demo --quick`, shorter: the teleop diagram (robot and rendered operator models) for 0.3 s
    out = tmp_path / "run.json"
    _ok(_run([venv / "bin" / "akc-drake", "run", "--source", "sim", "--motion", "tpose", "--teleop",
              "--seconds", "0.3", "--json", out], cwd=tmp_path))
    s = json.loads(out.read_text())
    assert s["frames"] == 3 and s["teleop"]["nan_commands"] == 0 and s["frames_with_person"] == 3


def test_with_the_extras_one_opencv_serves_mediapipe_and_us(wheel, tmp_path):
    pytest.importorskip("mediapipe")
    venv, dists = _venv(tmp_path, wheel, {"mediapipe", "realsense"})
    cv2_owners = [n for n, d in dists.items() if any(f.parts[:1] == ("cv2",) for f in d.files or [])]
    assert len(cv2_owners) == 1, cv2_owners
    vpy = venv / "bin" / "python"
    _ok(_run([PY, "-m", "pip", "--python", vpy, "check"]))
    probe = "import cv2, mediapipe, akc_drake.io.mediapipe_detector as m; print(cv2.__file__)"
    assert _ok(_run([vpy, "-c", probe], cwd=tmp_path)).strip().startswith(str(tmp_path / "deps" / "cv2"))
