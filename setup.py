"""Build hook: compiles AKC+'s per-frame modules (``akc_drake.compiled.COMPILED_MODULES``) with Cython.

The metadata is in pyproject.toml. The modules are plain Python (language level 3); their source stays importable
and is what runs when the compiled module is missing or stale (see akc_drake/compiled.py).

Typed locals. The hot functions declare their float locals and parameters with ordinary annotations (``ax:
float``, several to a line: ``ax: float; ay: float``), which Cython compiles as C doubles: arithmetic without a
Python float object per operation, the largest cost of the untyped build. List indices that are only ever indices
are annotated ``cython.Py_ssize_t``, with ``cython`` imported under ``typing.TYPE_CHECKING`` alone. In Python
both are inert (local annotations are never evaluated), so Cython stays a build dependency. The outputs stay
bit-identical to the source's (tests/test_compiled.py): a C double follows IEEE 754 as a Python float does, the
build forbids fused multiply-adds (below), and the math functions are still Python's (``math.hypot`` is not C's
``hypot``). A name so declared must hold a float wherever it is assigned: the compiled module raises TypeError
where the source would have stored, say, a tuple.
"""

import importlib.util
import os
from pathlib import Path

from Cython.Build import cythonize
from setuptools import setup
from setuptools.command.build_ext import build_ext

_ROOT = Path(__file__).resolve().parent
# akc_drake/compiled.py by path: importing the package would import numpy and more before they are installed.
_spec = importlib.util.spec_from_file_location("_akc_drake_compiled", _ROOT / "akc_drake" / "compiled.py")
compiled = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compiled)

_SOURCES = [str(compiled.source_path(m, Path("akc_drake"))) for m in compiled.COMPILED_MODULES]


class BuildExtAndRecord(build_ext):
    """build_ext, then the record of the sources compiled (read at import to refuse stale compiled modules)."""

    def finalize_options(self):
        super().finalize_options()
        if self.parallel is None:  # (one compiler per core: the five modules take ~40 s on one)
            self.parallel = os.cpu_count() or 1

    def run(self):
        super().run()
        out = _ROOT / "akc_drake" if self.inplace else Path(self.build_lib) / "akc_drake"
        compiled.write_manifest(_ROOT / "akc_drake", out_dir=out)


_EXTENSIONS = cythonize(_SOURCES, language_level=3, build_dir="build/cython", quiet=True)
for _ext in _EXTENSIONS:
    # No fused multiply-add (GCC contracts a * b + c by default where the target has it, e.g. aarch64): Python
    # rounds every operation, and the compiled C doubles must too (bit-identical outputs, above).
    _ext.extra_compile_args.append("-ffp-contract=off")

setup(
    ext_modules=_EXTENSIONS,
    cmdclass={"build_ext": BuildExtAndRecord},
)
