"""Helpers shared by the subcommands: body dimensions from ``--dims``."""

from __future__ import annotations


def load_dims_option(path: str | None):
    """BodyDimensions from ``--dims FILE.json`` (None when not given)."""
    if not path:
        return None
    from akc_drake.core.calibration import load_dims

    return load_dims(path)
