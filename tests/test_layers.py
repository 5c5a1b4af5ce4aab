"""The layering is a checked contract: import-linter (configured in pyproject.toml) passes on the package, and
fails on a copy of the package into which an upward import, an import of the CLI layer or a Drake import in
the numpy core has been added."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")

pytestmark = pytest.mark.skipif(not LINT_IMPORTS.exists(), reason="import-linter is a dev dependency")


def _lint(cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(cwd), "NO_COLOR": "1"}
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache"], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
    )


def _copy(tmp_path: Path) -> Path:
    """The package's Python files and pyproject.toml in ``tmp_path`` (grimp reads the copy, not the install)."""
    shutil.copytree(
        ROOT / "akc_drake",
        tmp_path / "akc_drake",
        ignore=shutil.ignore_patterns("__pycache__", "models", "*.json", "*.yaml"),
    )
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    return tmp_path


def test_the_package_keeps_every_contract():
    p = _lint(ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
    assert re.search(r"Contracts: (\d+) kept, 0 broken", p.stdout), p.stdout
    kept = int(re.search(r"Contracts: (\d+) kept", p.stdout).group(1))
    assert kept >= 3  # layers, only the CLI imports commands, no Drake in core but COIK


@pytest.mark.parametrize(
    "module, line, broken",
    [
        # an upward import, hidden in a function as the old cycles were
        ("core/skeleton.py", "def _up():\n    from akc_drake import diagrams\n", "Layers"),
        ("systems/occlusion_filter.py", "import akc_drake.pipeline.runner\n", "Layers"),
        ("operator/bvh.py", "from akc_drake.systems import timing\n", "Layers"),
        # the CLI layer imported from below
        ("diagrams.py", "def _cli():\n    from akc_drake.commands import run\n", "Only the CLI imports"),
        # Drake in the numpy core (coik.py is the one exception)
        ("core/akc.py", "import pydrake.math\n", "core is numpy"),
    ],
)
def test_lint_fails_on_a_forbidden_import_in_a_copy(tmp_path, module, line, broken):
    pkg = _copy(tmp_path)
    assert _lint(pkg).returncode == 0  # the copy itself is clean
    target = pkg / "akc_drake" / module
    target.write_text(target.read_text(encoding="utf-8") + "\n\n" + line, encoding="utf-8")
    p = _lint(pkg)
    assert p.returncode != 0, p.stdout
    assert f"{broken}" in p.stdout and "BROKEN" in p.stdout, p.stdout
    assert str(ROOT) not in p.stdout  # it read the copy
