"""Helpers shared by the subcommands: body dimensions from ``--dims``, output paths checked before the work."""

from __future__ import annotations

import os
from pathlib import Path

from akc_drake.errors import UserError


def load_dims_option(path: str | None):
    """BodyDimensions from ``--dims FILE.json`` (None when not given)."""
    if not path:
        return None
    from akc_drake.core.calibration import load_dims

    return load_dims(path)


def _nearest_existing(p: Path) -> Path:
    existing = p
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    return existing


def check_output_file(path: str | None, flag: str) -> None:
    """Fail before any work when ``flag``'s file cannot be written: one line naming the flag and the path.

    Args:
        path: the file the command will write (nothing is checked when None or empty).
        flag: the option that named it, e.g. ``"--json"``.

    Raises:
        UserError: ``path`` is a folder, a parent of it is a file, or its nearest existing folder is read-only.
    """
    if not path:
        return
    p = Path(path)
    if p.is_dir():
        raise UserError(f"{flag} {path}: is a folder, expected a file name")
    existing = _nearest_existing(p.parent)
    if not existing.is_dir():
        raise UserError(f"{flag} {path}: {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{flag} {path}: cannot write into {existing}")


def check_output_dir(path: str | None, flag: str) -> None:
    """Fail before any work when ``flag``'s folder cannot be created or written into (see check_output_file)."""
    if not path:
        return
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UserError(f"{flag} {path}: exists and is not a folder")
    existing = _nearest_existing(p)
    if not existing.is_dir():
        raise UserError(f"{flag} {path}: {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{flag} {path}: cannot write into {existing}")
