"""AKC+'s per-frame modules, compiled with Cython when the package is built, and how to tell which one runs.

The corrector's hot path is plain-float Python (``core/akc_plus*.py``, ``core/arm_geometry.py``). ``setup.py``
compiles those modules, unchanged, with Cython into extension modules beside their source (an editable install
builds them in place): the same Python semantics, bit-identical outputs, and about a third less time per frame
(README "Development" and "Corrector time"). The source stays the reference; nothing is written twice.

At ``import akc_drake`` a finder decides, per module, which one is imported:

* the compiled module, when it exists and was built from the source now on disk (``_compiled_sources.json``,
  written by the build, holds each source's SHA-256);
* the source, with one warning, when the source changed after the build (an edit, a ``git checkout``): stale
  compiled code never runs. ``make install`` (or ``python setup.py build_ext --inplace``) rebuilds;
* the source, silently, when ``AKC_DRAKE_PURE_PYTHON=1`` is set: for a debugger, a line profiler or cProfile,
  which do not see inside compiled functions.

:func:`status` tells which one each module is.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import json
import os
import sys
import warnings
from pathlib import Path

#: The modules the build compiles (dotted names). Each must import as plain Python too.
COMPILED_MODULES = (
    "akc_drake.core.akc_plus",
    "akc_drake.core.akc_plus_evidence",
    "akc_drake.core.akc_plus_lengths",
    "akc_drake.core.akc_plus_search",
    "akc_drake.core.akc_plus_torso",
    "akc_drake.core.arm_geometry",
)
#: The build's record of the sources it compiled, relative to the package directory.
MANIFEST = Path("core") / "_compiled_sources.json"
#: The environment variable that runs the source of every compiled module.
PURE_PYTHON_ENV = "AKC_DRAKE_PURE_PYTHON"

_PACKAGE_DIR = Path(__file__).resolve().parent


def source_path(module: str, package_dir: Path = _PACKAGE_DIR) -> Path:
    """The ``.py`` file of ``module`` (a name in :data:`COMPILED_MODULES`) under ``package_dir``."""
    parts = module.split(".")
    if parts[0] != "akc_drake" or len(parts) < 2:
        raise ValueError(f"not a module of akc_drake: {module!r}")
    return package_dir.joinpath(*parts[1:-1], parts[-1] + ".py")


def extension_path(module: str, package_dir: Path = _PACKAGE_DIR) -> Path | None:
    """The compiled module beside ``module``'s source for this interpreter, or None if none was built."""
    src = source_path(module, package_dir)
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        p = src.with_name(src.stem + suffix)
        if p.is_file():
            return p
    return None


def source_digest(path: Path) -> str:
    """SHA-256 of a file's bytes, hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def write_manifest(package_dir: Path = _PACKAGE_DIR, modules=COMPILED_MODULES, out_dir: Path | None = None) -> Path:
    """Record the digest of each compiled module's source under ``package_dir`` (the build calls this once it has
    compiled them), in ``out_dir`` (the package directory the compiled modules go to; default ``package_dir``)."""
    digests = {m: source_digest(source_path(m, package_dir)) for m in modules}
    out = Path(out_dir if out_dir is not None else package_dir) / MANIFEST
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
    return out


def stale_modules(package_dir: Path = _PACKAGE_DIR, modules=COMPILED_MODULES) -> list[str]:
    """The modules whose compiled file exists but was not built from the source now on disk (or whose build
    left no record): importing the compiled file would run other code than the source says."""
    built = [m for m in modules if extension_path(m, package_dir) is not None]
    if not built:
        return []
    try:
        recorded = json.loads((package_dir / MANIFEST).read_text())
    except (OSError, ValueError):
        recorded = {}
    return [m for m in built if recorded.get(m) != source_digest(source_path(m, package_dir))]


class SourceFinder(importlib.abc.MetaPathFinder):
    """Imports the listed modules from their ``.py`` source even where a compiled module sits beside it."""

    def __init__(self, modules, package_dir: Path = _PACKAGE_DIR):
        self.modules = frozenset(modules)
        self.package_dir = package_dir

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in self.modules:
            return None
        return importlib.util.spec_from_file_location(fullname, source_path(fullname, self.package_dir))


def install_finder() -> SourceFinder | None:
    """Put a :class:`SourceFinder` first on ``sys.meta_path`` for the modules that must run as source (all of
    them with ``AKC_DRAKE_PURE_PYTHON`` set; else the stale ones, with a warning). Called by ``akc_drake``'s
    ``__init__``, before any of them is imported."""
    if os.environ.get(PURE_PYTHON_ENV, "").strip() not in ("", "0"):
        modules = list(COMPILED_MODULES)
    else:
        modules = stale_modules()
        if modules:
            warnings.warn(
                "akc_drake: the compiled module(s) " + ", ".join(m.rsplit(".", 1)[1] for m in modules)
                + " do not match the source on disk; running the source (slower). Rebuild with `make install` or"
                " `python setup.py build_ext --inplace`.",
                RuntimeWarning,
                stacklevel=2,
            )
    if not modules:
        return None
    finder = SourceFinder(modules)
    sys.meta_path.insert(0, finder)
    return finder


def status() -> dict[str, str]:
    """Per compiled module: ``"compiled"`` or ``"source"``, as it is (or would be) imported in this process."""
    out = {}
    for m in COMPILED_MODULES:
        mod = sys.modules.get(m)
        spec = mod.__spec__ if mod is not None else importlib.util.find_spec(m)
        origin = spec.origin if spec is not None else ""
        out[m] = "compiled" if origin and not origin.endswith(".py") else "source"
    return out


def build_state() -> str:
    """``"compiled"`` when every module in :data:`COMPILED_MODULES` runs compiled, ``"source"`` when none does,
    else ``"mixed"`` (the bench records it: the corrector's speed depends on it)."""
    kinds = set(status().values())
    return kinds.pop() if len(kinds) == 1 else "mixed"
