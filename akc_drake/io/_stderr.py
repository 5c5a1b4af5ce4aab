"""Silencing native libraries' log lines (MediaPipe's TFLite/absl, FFmpeg) on file descriptor 2.

Those libraries write INFO/WARNING lines straight to fd 2, below Python; a user mistake should read as one
line (``akc-drake <cmd>: error: ...``), and a normal run should not be drowned in them. Errors still reach
the user: they are raised as Python exceptions, which this does not touch. Set ``AKC_DRAKE_NATIVE_LOGS=1``
to keep the lines.
"""

from __future__ import annotations

import contextlib
import os
import sys

#: Set to 1 to let native libraries log to stderr.
QUIET_OFF_ENV = "AKC_DRAKE_NATIVE_LOGS"


@contextlib.contextmanager
def quiet_native_stderr():
    """Redirect file descriptor 2 to the null device for the duration of the block (unless disabled)."""
    if os.environ.get(QUIET_OFF_ENV, "") not in ("", "0"):
        yield
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no real fd 2: nothing to silence
        yield
        return
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 2)
        finally:
            os.close(devnull)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
