"""akc-drake: markerless upper-body motion capture from one RGB-D camera, corrected by
Arm Kinematic Correction (AKC), driving a dual-arm mobile manipulator as one Drake diagram.

The algorithms live in :mod:`akc_drake.core` (pure numpy, no Drake except the COIK program);
the Drake LeafSystems that wrap them live in :mod:`akc_drake.systems`.
"""

__version__ = "0.1.0"

# AKC+'s per-frame modules run compiled (Cython) when built from the source on disk, else as source: decided
# here, before any of them is imported (akc_drake/compiled.py).
from akc_drake import compiled as _compiled  # noqa: E402

_compiled.install_finder()
