"""Stage S3b: the constant-velocity KF or the bone-length EKF (paper eq. 1-6) as a sampled Drake system."""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem, OutputPort

from akc_drake.core.kalman import (
    UNINITIALISED,
    ConstantVelocityKF,
    EKFConfig,
    ExtendedKalmanFilterCV,
    KFConfig,
)
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing

_J = NUM_LANDMARKS
MODES = ("KF", "EKF")


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

    State (discrete, three groups): the whole core filter state
    (:meth:`~akc_drake.core.kalman.ConstantVelocityKF.get_state_vector`, so a context can be cloned
    and a simulation replayed), the last estimate (36) and the last status (12). A periodic discrete
    update at the camera period, offset by ``timing.stage_offset("filter")``, loads the filter state
    into the core filter (created once), steps it by one camera period with the input and writes
    all three groups back; the outputs are state, so the system has no direct feedthrough.

    Args:
        mode: ``"KF"`` (:class:`~akc_drake.core.kalman.ConstantVelocityKF`) or ``"EKF"``
            (:class:`~akc_drake.core.kalman.ExtendedKalmanFilterCV`, needs ``dims``).
        dims: calibrated body dimensions (required for the EKF, ignored by the KF).
        config: a :class:`~akc_drake.core.kalman.KFConfig` (KF) or
            :class:`~akc_drake.core.kalman.EKFConfig` (EKF); None for the defaults.
        period_s: camera period, seconds (also the filter's ``dt``).
        rate_hz: alternatively the camera rate (give one of ``period_s``, ``rate_hz``).
        stage_offset_s: the per-stage offset of :func:`akc_drake.systems.timing.stage_offset`.

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
    ):
        super().__init__()
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
        estimate = f.step(z, self._period)
        discrete_state.get_mutable_vector(self._x_filter).SetFromVector(f.get_state_vector())
        discrete_state.get_mutable_vector(self._x_estimate).SetFromVector(estimate.reshape(-1))
        discrete_state.get_mutable_vector(self._x_status).SetFromVector(f.status.astype(np.float64))


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
