"""Stage S3b: the constant-velocity KF or the bone-length EKF (paper eq. 1-6) as a sampled Drake system."""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem, OutputPort

from akc_drake.core.kalman import (
    LEFT_RIGHT_SWAP,
    LOST,
    UNINITIALISED,
    ConstantVelocityKF,
    EKFConfig,
    ExtendedKalmanFilterCV,
    KFConfig,
    left_right_swapped,
)
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing

_J = NUM_LANDMARKS
MODES = ("KF", "EKF")
#: The longest run of frames (0.5 s at 10 Hz) that ``fix_left_right_swaps`` reads exchanged.
MAX_SWAP_FRAMES = 5


class LandmarkKalmanFilter(LeafSystem):
    """Filters the accepted landmarks at the camera rate with a KF or the constrained EKF.

    .. pydrake_system::

        name: LandmarkKalmanFilter
        input_ports:
        - landmarks_C
        output_ports:
        - landmarks_C_estimated
        - tracking_status

    ``landmarks_C`` and ``landmarks_C_estimated`` are the ``(12, 3)`` camera-frame landmarks flattened
    row-major (36; NaN in the input where missing, NaN in the output only for axes never measured).
    ``tracking_status`` is 12 codes of :mod:`akc_drake.core.kalman`: 0 UNINITIALISED, 1 TRACKING,
    2 PREDICTING, 3 LOST. An unconnected input counts as "nothing measured" (prediction only).

    Tracking loss: an unmeasured landmark is predicted for at most ``max_predict_s`` (the config's, 1 s by
    default); after that the core filter stops extrapolating it and its status is LOST. With
    ``nan_when_lost`` (the default) a LOST landmark reads NaN on ``landmarks_C_estimated`` instead of its
    stale held position, so the stages after the filter see it as missing (AKC holds the arm, FrameMapper
    raises ``tracking_lost``). Its next measurement re-initialises it.

    Left/right swaps: with ``fix_left_right_swaps`` a measurement that fits the filter's prediction far
    better with the person's left and right exchanged (:func:`~akc_drake.core.kalman.left_right_swapped`: a
    detector that mislabelled the body for a frame) is used exchanged, for at most :data:`MAX_SWAP_FRAMES`
    frames in a row: a "swap" that lasts longer is the filter's own labelling being wrong (say it started on
    a mislabelled frame), and the measurements are then used as labelled until the filter follows them (the
    gate re-initialises it after ``gate_max_rejects`` frames).

    State (discrete, four groups): the whole core filter state
    (:meth:`~akc_drake.core.kalman.ConstantVelocityKF.get_state_vector`, so a context can be cloned
    and a simulation replayed), the last estimate (36), the last status (12) and the count of
    consecutive swapped frames (1). A periodic discrete update at the camera period, offset by
    ``timing.stage_offset("filter")``, loads the filter state into the core filter (created once),
    steps it by one camera period with the input and writes the groups back; the outputs are state,
    so the system has no direct feedthrough.

    Args:
        mode: ``"KF"`` (:class:`~akc_drake.core.kalman.ConstantVelocityKF`) or ``"EKF"``
            (:class:`~akc_drake.core.kalman.ExtendedKalmanFilterCV`, needs ``dims``).
        dims: calibrated body dimensions (required for the EKF, ignored by the KF).
        config: a :class:`~akc_drake.core.kalman.KFConfig` (KF) or
            :class:`~akc_drake.core.kalman.EKFConfig` (EKF); None for the defaults.
        period_s: camera period, seconds (also the filter's ``dt``).
        rate_hz: alternatively the camera rate (give one of ``period_s``, ``rate_hz``).
        stage_offset_s: the per-stage offset of :func:`akc_drake.systems.timing.stage_offset`.
        nan_when_lost: output NaN for LOST landmarks (see above); False outputs the core filter's held
            estimate.
        fix_left_right_swaps: undo a detector's left/right swap (see above); on in the teleop diagram.

    Raises:
        ValueError: unknown mode, missing dims for the EKF, wrong config type or a bad period.
    """

    def __init__(
        self,
        mode: str = "KF",
        *,
        dims: BodyDimensions | None = None,
        config: KFConfig | None = None,
        period_s: float | None = None,
        rate_hz: float | None = None,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
        nan_when_lost: bool = True,
        fix_left_right_swaps: bool = False,
    ):
        super().__init__()
        self._nan_when_lost = bool(nan_when_lost)
        self._fix_swaps = bool(fix_left_right_swaps)
        mode_key = mode.upper() if isinstance(mode, str) else mode
        if mode_key not in MODES:
            raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        self.mode = mode_key
        self._period = _period(period_s, rate_hz)
        if mode_key == "EKF":
            if dims is None:
                raise ValueError("mode 'EKF' needs the body dimensions: pass dims=BodyDimensions(...)")
            if config is not None and not isinstance(config, EKFConfig):
                raise ValueError(f"mode 'EKF' needs an EKFConfig, got {type(config).__name__}")
            self._filter = ExtendedKalmanFilterCV(dims, config)
        else:
            if config is not None and not isinstance(config, KFConfig):
                raise ValueError(f"mode 'KF' needs a KFConfig, got {type(config).__name__}")
            if isinstance(config, EKFConfig):
                config = config.kf_config()
            self._filter = ConstantVelocityKF(_J, config)

        self._u = self.DeclareVectorInputPort("landmarks_C", 3 * _J)
        self._x_filter = self.DeclareDiscreteState(BasicVector(self._filter.get_state_vector()))
        self._x_estimate = self.DeclareDiscreteState(BasicVector(np.full(3 * _J, np.nan)))
        self._x_status = self.DeclareDiscreteState(BasicVector(np.full(_J, float(UNINITIALISED))))
        self._x_swaps = self.DeclareDiscreteState(BasicVector([0.0]))
        self.DeclareStateOutputPort("landmarks_C_estimated", self._x_estimate)
        self.DeclareStateOutputPort("tracking_status", self._x_status)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self._period,
            offset_sec=timing.stage_offset("filter", stage_offset_s),
            update=self._update,
        )
        self._missing = np.full((_J, 3), np.nan)

    @property
    def filter(self) -> ConstantVelocityKF | ExtendedKalmanFilterCV:
        """The wrapped core filter (its state is whatever the last update left in it)."""
        return self._filter

    @property
    def period_s(self) -> float:
        """The camera period (and filter ``dt``), seconds."""
        return self._period

    def filter_state_index(self) -> int:
        """Index of the discrete state group holding the core filter state."""
        return int(self._x_filter)

    def _update(self, context, discrete_state) -> None:
        if self._u.HasValue(context):
            z = self._u.Eval(context).reshape(_J, 3)
        else:
            z = self._missing
        f = self._filter
        f.set_state_vector(context.get_discrete_state(self._x_filter).get_value())
        if self._fix_swaps:
            swaps = context.get_discrete_state(self._x_swaps).get_value()[0]
            if left_right_swapped(z, f.position + self._period * f.velocity):
                if swaps < MAX_SWAP_FRAMES:
                    z = z[LEFT_RIGHT_SWAP]
                swaps = min(swaps + 1.0, float(MAX_SWAP_FRAMES))  # past the limit: stays there, z as labelled
            else:
                swaps = 0.0
            discrete_state.get_mutable_vector(self._x_swaps).SetFromVector([swaps])
        estimate = f.step(z, self._period)
        status = f.status
        if self._nan_when_lost:
            estimate[status == LOST] = np.nan
        discrete_state.get_mutable_vector(self._x_filter).SetFromVector(f.get_state_vector())
        discrete_state.get_mutable_vector(self._x_estimate).SetFromVector(estimate.reshape(-1))
        discrete_state.get_mutable_vector(self._x_status).SetFromVector(status.astype(np.float64))


def _period(period_s, rate_hz) -> float:
    if period_s is not None and rate_hz is not None:
        raise ValueError("give one of period_s and rate_hz, not both")
    if rate_hz is not None:
        if not isinstance(rate_hz, (int, float)) or not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        return 1.0 / float(rate_hz)
    if period_s is None:
        return 1.0 / timing.DEFAULT_CAMERA_RATE_HZ
    if not isinstance(period_s, (int, float)) or not (math.isfinite(period_s) and period_s > 0):
        raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
    return float(period_s)


def AddLandmarkKalmanFilter(
    builder: DiagramBuilder,
    landmarks_C: OutputPort | None = None,
    *,
    mode: str = "KF",
    dims: BodyDimensions | None = None,
    config: KFConfig | None = None,
    period_s: float | None = None,
    rate_hz: float | None = None,
    stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
    name: str = "LandmarkKalmanFilter",
) -> LandmarkKalmanFilter:
    """Add a :class:`LandmarkKalmanFilter` to ``builder`` and connect its input.

    Args:
        builder: the diagram builder.
        landmarks_C: output port to connect to the filter's ``landmarks_C`` (None: leave it).
        mode, dims, config, period_s, rate_hz, stage_offset_s: as for :class:`LandmarkKalmanFilter`.
        name: the system's name.

    Returns:
        The added system.
    """
    system = builder.AddSystem(
        LandmarkKalmanFilter(
            mode,
            dims=dims,
            config=config,
            period_s=period_s,
            rate_hz=rate_hz,
            stage_offset_s=stage_offset_s,
        )
    )
    system.set_name(name)
    if landmarks_C is not None:
        builder.Connect(landmarks_C, system.get_input_port(0))
    return system
