"""Accuracy metrics of the paper's evaluation (§III): RMSE per axis, Pearson's r with its p-value,
arm-length range, RMS Euclidean distance and the L2 norm over joints.

Inputs are in metres. A frame where either the estimate or the truth of a joint has a non-finite
coordinate is left out of every metric of that joint, and counted out of ``valid_frames``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np
from scipy.special import betainc

from akc_drake.core.skeleton import ARM_JOINTS, INDEX, SEGMENT_NAMES, check_pose, segment_lengths

#: The arm segments whose length range the paper reports (Table VI).
ARM_SEGMENTS: tuple[str, ...] = ("LUA", "LLA", "RUA", "RLA")
AXES: tuple[str, ...] = ("x", "y", "z")


def _paired(est, true) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(est, true, valid)`` for two ``(T, 3)`` series; ``valid`` marks frames finite in both."""
    e = np.asarray(est, dtype=float)
    t = np.asarray(true, dtype=float)
    for name, a in (("est", e), ("true", t)):
        if a.ndim != 2 or a.shape[1] != 3:
            raise ValueError(f"{name} must have shape (T, 3), got {a.shape}")
    if e.shape != t.shape:
        raise ValueError(f"est and true must have the same shape, got {e.shape} and {t.shape}")
    valid = np.isfinite(e).all(axis=1) & np.isfinite(t).all(axis=1)
    return e, t, valid


def rmse_per_axis(est, true) -> tuple[np.ndarray, int]:
    """Root-mean-square error along x, y and z.

    Args:
        est: ``(T, 3)`` estimated positions of one joint.
        true: ``(T, 3)`` reference positions.

    Returns:
        ``(rmse (3,), valid_frames)``; ``rmse`` is NaN when no frame is valid.
    """
    e, t, valid = _paired(est, true)
    n = int(valid.sum())
    if n == 0:
        return np.full(3, np.nan), 0
    d = e[valid] - t[valid]
    return np.sqrt(np.mean(d * d, axis=0)), n


def pearson(x, y) -> tuple[float, float]:
    """Pearson's correlation coefficient and its two-sided p-value for two finite 1-D series.

    Equal to ``scipy.stats.pearsonr`` where that is defined. Fewer than 2 samples, or a constant
    series, has no correlation: ``r`` is NaN and ``p`` is 1.0 (no evidence of correlation).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1 or x.shape != y.shape:
        raise ValueError(f"x and y must be 1-D of the same length, got {x.shape} and {y.shape}")
    n = x.size
    if n < 2 or np.all(x == x[0]) or np.all(y == y[0]):
        return math.nan, 1.0
    xm = x - x.mean()
    ym = y - y.mean()
    nx = float(np.linalg.norm(xm))
    ny = float(np.linalg.norm(ym))
    if nx == 0.0 or ny == 0.0:
        return math.nan, 1.0
    r = float(np.clip(np.dot(xm / nx, ym / ny), -1.0, 1.0))
    if n == 2:
        return r, 1.0
    # Under H0, r on [-1, 1] is (2 B - 1) with B ~ Beta(n/2 - 1, n/2 - 1); two-sided tail, by symmetry:
    # p = 2 P(r > |r_obs|) = 2 I_{(1 - |r|)/2}(a, a).
    a = n / 2.0 - 1.0
    p = float(2.0 * betainc(a, a, 0.5 * (1.0 - abs(r))))
    return r, min(p, 1.0)


def pearson_per_axis(est, true) -> tuple[np.ndarray, np.ndarray, int]:
    """Pearson's r between estimate and truth along x, y, z, over the valid frames.

    Returns:
        ``(r (3,), p (3,), valid_frames)``; see :func:`pearson` for the degenerate cases.
    """
    e, t, valid = _paired(est, true)
    r = np.empty(3)
    p = np.empty(3)
    for k in range(3):
        r[k], p[k] = pearson(e[valid, k], t[valid, k])
    return r, p, int(valid.sum())


def segment_length_series(traj) -> dict[str, np.ndarray]:
    """``{segment: (T,) lengths}`` of a trajectory ``(T, 12, 3)``; NaN where a landmark is missing."""
    a = check_pose(traj, name="trajectory", allow_trajectory=True)
    if a.ndim != 3:
        raise ValueError(f"trajectory must have shape (T, 12, 3), got {a.shape}")
    a = np.where(np.isfinite(a), a, np.nan)
    return segment_lengths(a)


def arm_length_range(traj, segments: Sequence[str] = ARM_SEGMENTS) -> dict[str, float]:
    """Range (max - min over the frames where it is finite) of each segment's length, metres.

    Args:
        traj: ``(T, 12, 3)`` trajectory.
        segments: which segments; the paper's four arm segments by default.

    Returns:
        ``{segment: range}``; NaN for a segment with no finite frame.
    """
    unknown = [s for s in segments if s not in SEGMENT_NAMES]
    if unknown:
        names = ", ".join(map(repr, unknown))
        raise ValueError(f"unknown segment(s) {names}; known: {', '.join(SEGMENT_NAMES)}")
    series = segment_length_series(traj)
    out = {}
    for name in segments:
        v = series[name]
        v = v[np.isfinite(v)]
        out[name] = float(v.max() - v.min()) if v.size else math.nan
    return out


def rms_euclidean(est, true) -> float:
    """RMS of the 3D distance between estimate and truth of one joint over the valid frames (NaN if none)."""
    e, t, valid = _paired(est, true)
    if not valid.any():
        return math.nan
    d = e[valid] - t[valid]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


def l2_norm(values: Mapping[str, float] | Iterable[float]) -> float:
    """L2 norm of per-joint errors (e.g. the RMS Euclidean errors of the paper's Table IX).

    NaN if any value is NaN (an error that could not be measured is not silently dropped).
    """
    v = np.asarray(list(values.values()) if isinstance(values, Mapping) else list(values), dtype=float)
    if v.ndim != 1:
        raise ValueError(f"values must be a flat sequence of numbers, got shape {v.shape}")
    return float(np.sqrt(np.sum(v * v))) if v.size else 0.0


def joint_errors(est, true, joints: Sequence[str] = ARM_JOINTS) -> dict[str, dict]:
    """Per-joint error table between two trajectories.

    Args:
        est: ``(T, 12, 3)`` estimated trajectory.
        true: ``(T, 12, 3)`` reference trajectory.
        joints: landmark names; the six arm joints by default.

    Returns:
        ``{joint: {"rmse_cm": {"x","y","z"}, "corr": {"x","y","z"}, "p": {"x","y","z"},
        "rms_euclidean_cm": float, "valid_frames": int}}``.
    """
    e = check_pose(est, name="est", allow_trajectory=True)
    t = check_pose(true, name="true", allow_trajectory=True)
    if e.ndim != 3:
        raise ValueError(f"est must have shape (T, 12, 3), got {e.shape}")
    if e.shape != t.shape:
        raise ValueError(f"est and true must have the same shape, got {e.shape} and {t.shape}")
    out = {}
    for name in joints:
        if name not in INDEX:
            raise ValueError(f"unknown joint {name!r}")
        j = INDEX[name]
        rmse, n = rmse_per_axis(e[:, j], t[:, j])
        r, p, _ = pearson_per_axis(e[:, j], t[:, j])
        out[name] = {
            "rmse_cm": {ax: float(100.0 * rmse[k]) for k, ax in enumerate(AXES)},
            "corr": {ax: float(r[k]) for k, ax in enumerate(AXES)},
            "p": {ax: float(p[k]) for k, ax in enumerate(AXES)},
            "rms_euclidean_cm": 100.0 * rms_euclidean(e[:, j], t[:, j]),
            "valid_frames": n,
        }
    return out
