"""Writing files safely: every output goes to a temporary file in the same folder and is then renamed, so a crash
or an interrupted run never leaves half a file and never destroys an earlier result."""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np


def atomic_write(path: str | Path, writer: Callable, *, binary: bool = True, fsync: bool = False) -> Path:
    """Call ``writer(file)`` on a temporary file next to ``path``, then rename it to ``path``.

    Args:
        path: the destination (its folder is created).
        writer: writes the content to the open file object.
        binary: open the temporary file in binary (default) or UTF-8 text mode.
        fsync: flush the content to the disk before the rename (for small files that must survive a power cut).
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
    try:
        with os.fdopen(fd, "wb" if binary else "w", **({} if binary else {"encoding": "utf-8"})) as f:
            writer(f)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600 files: give the usual permissions
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def _umask() -> int:
    """The process's umask, read without changing it (``os.umask`` can only be read by setting it, which would
    race with other threads creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:  # Linux >= 4.7
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return _probe_umask()


def _probe_umask() -> int:
    """The umask seen on a file created with mode 0o777 (where /proc/self/status has no ``Umask:`` line)."""
    fd, probe = -1, ""
    for _ in range(100):
        probe = os.path.join(tempfile.gettempdir(), f".akc-umask-{os.getpid()}-{os.urandom(6).hex()}")
        try:
            fd = os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o777)
            break
        except FileExistsError:
            continue
    if fd < 0:
        return 0o022
    try:
        return 0o777 & ~os.fstat(fd).st_mode
    finally:
        os.close(fd)
        os.unlink(probe)


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return atomic_write(path, lambda f: f.write(data))


def atomic_write_text(path: str | Path, text: str, *, fsync: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    return atomic_write(path, lambda f: f.write(text), binary=False, fsync=fsync)


def atomic_save_npz(path: str | Path, **arrays) -> Path:
    """``np.savez_compressed`` to ``path`` atomically; refuses arrays of Python objects (they would need pickle)."""
    data = {k: np.asarray(v) for k, v in arrays.items()}
    pickled = [k for k, a in data.items() if a.dtype.hasobject]
    if pickled:
        raise ValueError(f"{path}: array(s) {', '.join(pickled)} hold Python objects (that needs pickle)")
    return atomic_write(path, lambda f: np.savez_compressed(f, **data))


def jsonable(x):
    """``x`` with numpy scalars/arrays turned into Python numbers/lists and non-finite floats into None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_json(path: str | Path, data) -> Path:
    """Write ``data`` as indented JSON atomically; numpy values are converted, NaN and inf become null."""
    text = json.dumps(jsonable(data), indent=2, allow_nan=False) + "\n"
    return atomic_write_text(path, text)


def atomic_write_via_path(path: str | Path, writer: Callable[[Path], object]) -> Path:
    """Atomically write ``path`` with a library that writes to a file name (ezc3d, rosbags).

    ``writer(tmp)`` writes a temporary file ``tmp`` next to ``path`` (same suffix, so libraries that choose the
    format from it still work); it is then renamed to ``path``. On any error the temporary file is removed and an
    earlier ``path`` is left untouched.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=f".tmp{p.suffix}", dir=p.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        tmp_path.unlink()  # the writer creates it (some libraries refuse to overwrite)
        writer(tmp_path)
        if not tmp_path.is_file():
            raise OSError(f"{p}: the writer produced no file")
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, p)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return p
