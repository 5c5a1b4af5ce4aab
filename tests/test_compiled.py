"""akc_drake.compiled: AKC+'s per-frame modules compiled with Cython, the source kept as the reference."""

import importlib.machinery
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from akc_drake import compiled

# AKC+ over two bench sessions (Motion I and II: self-occlusion, dropouts), as the evaluation runs it (the KF's
# output, the occlusion filter's measurement, the KF's variance), without the variance, and with no measurement.
_RUN = textwrap.dedent(
    """
    import sys
    import numpy as np
    from akc_drake.bench.core import synthetic_measurements
    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus
    out = []
    for motion, seed in (("I", 3), ("II", 5)):
        inp = synthetic_measurements(cycles=2, seed=seed, motion=motion).run_stages()
        for use_m, use_v in ((True, True), (True, False), (False, False)):
            k = ArmKinematicCorrectorPlus(inp.dims)
            for p, m, v in zip(inp.kf, inp.accepted, inp.kf_var):
                out.append(k.correct(p, m if use_m else None, v if use_v else None).pose)
    np.save(sys.argv[1], np.stack(out))
    """
)


def _run(tmp_path, name, pure, prelude=""):
    env = dict(os.environ)
    env.pop(compiled.PURE_PYTHON_ENV, None)
    if pure:
        env[compiled.PURE_PYTHON_ENV] = "1"
    out = tmp_path / f"{name}.npy"
    code = prelude + _RUN + "\nimport akc_drake.compiled as c\nprint(c.build_state())\n"
    r = subprocess.run([sys.executable, "-c", code, str(out)], env=env, capture_output=True, text=True, check=True)
    return np.load(out), r.stdout.strip()


def test_the_installed_package_runs_every_hot_module_compiled():
    # `make install` builds them; a missing or stale build would silently cost the bench its speed target.
    if os.environ.get(compiled.PURE_PYTHON_ENV, "").strip() not in ("", "0"):
        pytest.skip(f"{compiled.PURE_PYTHON_ENV} is set: the source runs by request")
    import akc_drake.core.akc_plus  # noqa: F401 (imports all five)

    assert compiled.stale_modules() == []
    assert compiled.status() == {m: "compiled" for m in compiled.COMPILED_MODULES}
    assert compiled.build_state() == "compiled"
    for m in compiled.COMPILED_MODULES:
        assert sys.modules[m].__file__.endswith(tuple(importlib.machinery.EXTENSION_SUFFIXES))


# Cython is a build dependency only: the locals are typed for the compiler (``x: float``; ``cython.Py_ssize_t``
# under ``TYPE_CHECKING``), so with its module unimportable both builds still run, and give the same poses.
_NO_CYTHON = "import sys\nsys.modules['cython'] = None  # (import cython: ImportError)\n"


@pytest.mark.parametrize("prelude", ["", _NO_CYTHON], ids=["as-installed", "cython-unimportable"])
def test_compiled_and_source_give_bit_identical_poses(tmp_path, prelude):
    a, state_a = _run(tmp_path, "compiled", pure=False, prelude=prelude)
    b, state_b = _run(tmp_path, "source", pure=True, prelude=prelude)
    assert state_b == "source"
    assert state_a == ("source" if os.environ.get(compiled.PURE_PYTHON_ENV) else "compiled")
    assert a.shape == b.shape == (6 * 121, 12, 3)  # (2 cycles of 6 s at 10 Hz, both ends)
    assert np.isfinite(a).mean() > 0.9  # (real poses, not NaN throughout)
    np.testing.assert_array_equal(a, b)  # NaN where NaN, every other bit equal


def _fake_package(tmp_path, build=True):
    """A package directory with two 'compiled' modules (empty files with the extension suffix)."""
    pkg = tmp_path / "akc_drake"
    (pkg / "core").mkdir(parents=True)
    mods = ("akc_drake.core.one", "akc_drake.core.two")
    for m in mods:
        name = m.rsplit(".", 1)[1]
        (pkg / "core" / f"{name}.py").write_text(f"WHO = '{name} source'\n")
        if build:
            (pkg / "core" / f"{name}{importlib.machinery.EXTENSION_SUFFIXES[0]}").write_bytes(b"")
    return pkg, mods


def test_stale_modules_compares_the_build_record_with_the_source_on_disk(tmp_path):
    pkg, mods = _fake_package(tmp_path)
    # No record: every built module is stale.
    assert compiled.stale_modules(pkg, mods) == list(mods)
    out = compiled.write_manifest(pkg, mods)
    assert out == pkg / compiled.MANIFEST
    rec = json.loads(out.read_text())
    assert set(rec) == set(mods) and all(len(v) == 64 for v in rec.values())
    assert compiled.stale_modules(pkg, mods) == []
    # An edit after the build: that module only.
    (pkg / "core" / "two.py").write_text("WHO = 'edited'\n")
    assert compiled.stale_modules(pkg, mods) == ["akc_drake.core.two"]
    # The record written elsewhere (a wheel's build directory) holds the digests of the source given.
    other = tmp_path / "build" / "akc_drake"
    compiled.write_manifest(pkg, mods, out_dir=other)
    assert json.loads((other / compiled.MANIFEST).read_text())["akc_drake.core.two"] == compiled.source_digest(
        pkg / "core" / "two.py")


def test_nothing_built_is_never_stale(tmp_path):
    pkg, mods = _fake_package(tmp_path, build=False)
    assert compiled.extension_path(mods[0], pkg) is None
    assert compiled.stale_modules(pkg, mods) == []


def test_source_finder_imports_the_source_beside_a_compiled_file(tmp_path):
    pkg, mods = _fake_package(tmp_path)
    finder = compiled.SourceFinder(mods[:1], pkg)
    assert finder.find_spec("akc_drake.core.two") is None  # (not listed: the normal import decides)
    spec = finder.find_spec("akc_drake.core.one")
    assert spec.origin == str(pkg / "core" / "one.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.WHO == "one source"


def test_source_path_names_only_modules_of_the_package():
    assert compiled.source_path("akc_drake.core.akc_plus").name == "akc_plus.py"
    assert compiled.source_path("akc_drake.core.akc_plus").is_file()
    with pytest.raises(ValueError, match="not a module of akc_drake"):
        compiled.source_path("numpy.linalg")


def test_a_stale_build_runs_the_source_with_a_warning(tmp_path):
    # A copy of the package whose build record no longer matches one source: that module imports as source.
    import shutil

    import akc_drake

    root = tmp_path / "copy"
    shutil.copytree(os.path.dirname(akc_drake.__file__), root / "akc_drake",
                    ignore=shutil.ignore_patterns("__pycache__"))
    if compiled.extension_path("akc_drake.core.akc_plus_lengths", root / "akc_drake") is None:
        pytest.skip("the package is not built (run `make install`)")
    src = root / "akc_drake" / "core" / "akc_plus_lengths.py"
    src.write_text(src.read_text() + "\n# edited after the build\n")
    code = ("import warnings, sys; warnings.simplefilter('always'); sys.path.insert(0, sys.argv[1]);"
            "import akc_drake, akc_drake.core.akc_plus; assert akc_drake.__file__.startswith(sys.argv[1]);"
            "print(akc_drake.compiled.status()['akc_drake.core.akc_plus_lengths'],"
            " akc_drake.compiled.status()['akc_drake.core.akc_plus'])")
    env = {k: v for k, v in os.environ.items() if k != compiled.PURE_PYTHON_ENV}
    r = subprocess.run([sys.executable, "-c", code, str(root)], env=env, capture_output=True, text=True,
                       check=True, cwd=tmp_path)
    assert r.stdout.split() == ["source", "compiled"]
    assert "akc_plus_lengths do not match the source on disk" in r.stderr


def test_make_install_recompiles_when_a_compiled_modules_source_changes():
    # The Makefile's rule, dry run (`make -n`) as if akc_plus.py had just been edited (`-W`): `make install` (and so
    # `make test`, `make demo`, `make bench`) rebuilds the compiled modules before anything runs them.
    import shutil
    from pathlib import Path

    import akc_drake

    root = Path(akc_drake.__file__).resolve().parents[1]
    if shutil.which("make") is None or not (root / "Makefile").is_file():
        pytest.skip("needs make and the source tree's Makefile")
    for src in ("akc_drake/core/akc_plus.py", "akc_drake/core/arm_geometry.py"):
        r = subprocess.run(["make", "-n", "-W", src, "install"], cwd=root, capture_output=True, text=True, check=True)
        assert "setup.py -q build_ext --inplace" in r.stdout, r.stdout[-2000:]
