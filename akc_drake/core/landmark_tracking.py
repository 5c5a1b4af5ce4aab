"""One camera frame of landmark tracking (stage S3b's numpy part): the KF or EKF step with the frame rules.

:func:`track_step` steps a core filter (:class:`~akc_drake.core.kalman.ConstantVelocityKF` or
:class:`~akc_drake.core.ekf.ExtendedKalmanFilterCV`) by one camera period and applies the per-frame rules of
the pipeline's filter stage; :class:`akc_drake.systems.landmark_kalman_filter.LandmarkKalmanFilter` is the
Drake system around it, holding the filter state and the swap count in its discrete state.

Tracking loss: an unmeasured landmark is predicted for at most ``max_predict_s`` (the config's, 1 s by
default); after that the core filter stops extrapolating it and its status is LOST. With ``nan_when_lost``
a LOST landmark reads NaN instead of its stale held position, so the stages after the filter see it as
missing (AKC holds the arm, FrameMapper raises ``tracking_lost``). Its next measurement re-initialises it.

Left/right swaps: with ``fix_swaps`` a measurement that fits the filter's prediction far better with the
person's left and right exchanged (:func:`~akc_drake.core.kalman.left_right_swapped`: a detector that
mislabelled the body for a frame) is used exchanged, for at most :data:`MAX_SWAP_FRAMES` frames in a row: a
"swap" that lasts longer is the filter's own labelling being wrong (say it started on a mislabelled frame),
and the measurements are then used as labelled until the filter follows them (the gate re-initialises it
after ``gate_max_rejects`` frames).
"""

from __future__ import annotations

import math

import numpy as np

from akc_drake.core.ekf import ExtendedKalmanFilterCV
from akc_drake.core.kalman import LEFT_RIGHT_SWAP, LOST, ConstantVelocityKF, EKFConfig, KFConfig, left_right_swapped
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions

#: The filters the tracking stage can run.
MODES = ("KF", "EKF")
#: The longest run of frames (0.5 s at 10 Hz) that ``fix_swaps`` reads exchanged.
MAX_SWAP_FRAMES = 5


def make_filter(
    mode: str, dims: BodyDimensions | None = None, config: KFConfig | None = None
) -> tuple[str, ConstantVelocityKF | ExtendedKalmanFilterCV]:
    """The core filter of ``mode`` (case-insensitive), with its canonical mode name.

    Args:
        mode: ``"KF"`` or ``"EKF"``.
        dims: calibrated body dimensions (required for the EKF, ignored by the KF).
        config: a :class:`~akc_drake.core.kalman.KFConfig` (KF; an EKFConfig gives its KF part) or an
            :class:`~akc_drake.core.kalman.EKFConfig` (EKF); None for the defaults.

    Returns:
        ``(mode, filter)``: ``"KF"`` or ``"EKF"`` and a new filter over the 12 landmarks.

    Raises:
        ValueError: unknown mode, missing dims for the EKF or a config of the wrong type.
    """
    mode_key = mode.upper() if isinstance(mode, str) else mode
    if mode_key not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if mode_key == "EKF":
        if dims is None:
            raise ValueError("mode 'EKF' needs the body dimensions: pass dims=BodyDimensions(...)")
        if config is not None and not isinstance(config, EKFConfig):
            raise ValueError(f"mode 'EKF' needs an EKFConfig, got {type(config).__name__}")
        return mode_key, ExtendedKalmanFilterCV(dims, config)
    if config is not None and not isinstance(config, KFConfig):
        raise ValueError(f"mode 'KF' needs a KFConfig, got {type(config).__name__}")
    if isinstance(config, EKFConfig):
        config = config.kf_config()
    return mode_key, ConstantVelocityKF(NUM_LANDMARKS, config)


def filter_period(period_s=None, rate_hz=None, *, default_rate_hz: float = 10.0) -> float:
    """The camera period from ``period_s`` or ``rate_hz`` (at most one given; neither: ``1 / default_rate_hz``).

    Raises:
        ValueError: both given, or a value that is not a positive finite number.
    """
    if period_s is not None and rate_hz is not None:
        raise ValueError("give one of period_s and rate_hz, not both")
    if rate_hz is not None:
        if not isinstance(rate_hz, (int, float)) or not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        return 1.0 / float(rate_hz)
    if period_s is None:
        return 1.0 / default_rate_hz
    if not isinstance(period_s, (int, float)) or not (math.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
    return float(period_s)


def track_step(
    f: ConstantVelocityKF | ExtendedKalmanFilterCV,
    z: np.ndarray,
    period_s: float,
    swaps: float = 0.0,
    *,
    fix_swaps: bool = False,
    nan_when_lost: bool = True,
    taken: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Step ``f`` by one camera period with the measurement ``z``, with the swap and lost rules above.

    Args:
        f: the core filter (stepped in place).
        z: ``(12, 3)`` measurement (NaN where missing).
        period_s: the camera period (the filter's ``dt``).
        swaps: consecutive frames read exchanged so far.
        fix_swaps: undo a detector's left/right swap.
        nan_when_lost: NaN for LOST landmarks in the estimate.
        taken: a ``(12, 3)`` array that receives the measurement as the filter took it
            (:func:`taken_measurement`), or None.

    Returns:
        ``(estimate (12, 3), status (12,), swaps)``: the new count of swapped frames (``swaps`` unchanged
        without ``fix_swaps``).
    """
    if fix_swaps:
        if left_right_swapped(z, f.position + period_s * f.velocity):
            if swaps < MAX_SWAP_FRAMES:
                z = z[LEFT_RIGHT_SWAP]
            swaps = min(swaps + 1.0, float(MAX_SWAP_FRAMES))  # past the limit: stays there, z as labelled
        else:
            swaps = 0.0
    estimate = f.step(z, period_s)
    status = f.status
    if nan_when_lost:
        estimate[status == LOST] = np.nan
    if taken is not None:
        taken[...] = taken_measurement(f, z)
    return estimate, status, swaps


def taken_measurement(f, z: np.ndarray) -> np.ndarray:
    """``z`` ``(12, 3)``, the measurement ``f`` was just stepped with, as the filter took it: NaN on each axis
    its innovation gate rejected (an axis measured this step whose age since its last measurement is not 0).

    What a stage after the filter should count as measured (AKC+'s ``landmarks_C_measured``): a reading the gate
    dropped as garbage is no evidence there either, and one that the swap rule exchanged is the exchanged one.
    Without a gate it is ``z`` itself."""
    out = np.array(z, dtype=float, copy=True)
    out[f.axis_age > 0.0] = np.nan
    return out
