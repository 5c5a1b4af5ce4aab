"""The per-frame log of a mocap diagram: each stage's VectorLogSink read back into arrays, one row per camera frame.

:func:`akc_drake.diagrams.AddStageLoggers` adds the loggers; :func:`read_logs` reads them after a simulation into a
:class:`MocapLog` (both also importable from :mod:`akc_drake.diagrams`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.systems.primitives import VectorLogSink

from akc_drake.core.skeleton import NUM_LANDMARKS


@dataclass
class MocapLog:
    """Per-frame poses of every stage, as arrays (frame ``k`` = camera frame taken at ``t[k]``)."""

    t: np.ndarray
    raw: np.ndarray
    accepted: np.ndarray
    estimated: np.ndarray
    corrected: np.ndarray
    truth: np.ndarray
    visibility: np.ndarray
    diagnostics: np.ndarray | None = None
    tracking_status: np.ndarray | None = None

    def save_npz(self, path) -> None:
        """Save as a compressed .npz (no pickled objects), atomically."""
        from akc_drake.fileio import atomic_save_npz

        atomic_save_npz(path, **{k: v for k, v in self.__dict__.items() if v is not None})


def read_logs(loggers: dict[str, VectorLogSink], root_context, period_s: float,
              num_frames: int | None = None) -> MocapLog:
    """Read the stage loggers into a :class:`MocapLog` (dropping the t = 0 sample and shifting by one frame)."""
    out = {}
    t = None
    for name, log in loggers.items():
        data = log.FindLog(root_context)
        times = data.sample_times()
        values = data.data().T  # (samples, size)
        # Keep one sample per camera tick (forced publishes may add duplicates at the end).
        ticks = np.rint(times / period_s).astype(int)
        _, first = np.unique(ticks, return_index=True)
        values, ticks = values[first], ticks[first]
        keep = ticks >= 1
        values, ticks = values[keep], ticks[keep]
        if num_frames is not None:
            values, ticks = values[:num_frames], ticks[:num_frames]
        if t is None:
            t = (ticks - 1) * period_s
        if name in ("raw", "accepted", "estimated", "corrected", "truth"):
            values = values.reshape(-1, NUM_LANDMARKS, 3)
        out[name] = values
    n = len(t)
    nan_pose = np.full((n, NUM_LANDMARKS, 3), np.nan)
    return MocapLog(
        t=t,
        raw=out.get("raw", nan_pose), accepted=out.get("accepted", nan_pose),
        estimated=out.get("estimated", nan_pose), corrected=out.get("corrected", nan_pose),
        truth=out.get("truth", nan_pose), visibility=out.get("visibility", np.full((n, NUM_LANDMARKS), np.nan)),
        diagnostics=out.get("diagnostics"), tracking_status=out.get("tracking_status"),
    )
