"""Stage S3b: the constant-velocity KF or the bone-length EKF (paper eq. 1-6) as a sampled Drake system.

The per-frame logic (filter choice, the left/right swap rule, NaN for lost landmarks, the period check) is
:mod:`akc_drake.core.landmark_tracking`; ``MODES`` and ``MAX_SWAP_FRAMES`` stay importable from here.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem, OutputPort

from akc_drake.core.kalman import UNINITIALISED, ConstantVelocityKF, ExtendedKalmanFilterCV, KFConfig
from akc_drake.core.landmark_tracking import MAX_SWAP_FRAMES, MODES, filter_period, make_filter, track_step
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing

_J = NUM_LANDMARKS


class LandmarkKalmanFilter(LeafSystem):
    """Filters the accepted landmarks at the camera rate with a KF or the constrained EKF.

    .. pydrake_system::

        name: LandmarkKalmanFilter
        input_ports:
        - landmarks_C
        output_ports:
        - landmarks_C_estimated
        - tracking_status
        - landmarks_C_variance
        - landmarks_C_taken

    ``landmarks_C`` and ``landmarks_C_estimated`` are the ``(12, 3)`` camera-frame landmarks flattened
    row-major (36; NaN in the input where missing, NaN in the output only for axes never measured or, with
    ``nan_when_lost``, LOST). ``tracking_status`` is 12 codes of :mod:`akc_drake.core.kalman`:
    0 UNINITIALISED, 1 TRACKING, 2 PREDICTING, 3 LOST. An unconnected input counts as "nothing measured"
    (prediction only). Tracking loss and left/right swaps: :mod:`akc_drake.core.landmark_tracking`.
    ``landmarks_C_variance`` is the filter's posterior variance of each coordinate of the estimate (36, m^2,
    the core filter's ``position_variance``; NaN for axes never measured), which AKC+ reads to test what the
    camera sees (:class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus`). ``landmarks_C_taken`` (36) is the
    input as the filter took it (:func:`~akc_drake.core.landmark_tracking.taken_measurement`): NaN where its
    innovation gate rejected a reading, exchanged where the swap rule exchanged the sides; the diagrams give it to
    AKC+ as what was measured (a garbage reading the gate dropped moved AKC+'s arm by a metre).

    State (discrete, six groups): the whole core filter state
    (:meth:`~akc_drake.core.kalman.ConstantVelocityKF.get_state_vector`, so a context can be cloned
    and a simulation replayed), the last estimate (36), the last status (12), the count of
    consecutive swapped frames (1), the last posterior variance (36) and the last measurement as taken (36). A
    periodic discrete update at the camera period, offset by ``timing.stage_offset("filter")``, loads the filter
    state into the core filter (created once), steps it by one camera period with the input and writes the groups
    back; the outputs are state, so the system has no direct feedthrough.

    Args:
        mode: ``"KF"`` or ``"EKF"`` (needs ``dims``); see :func:`~akc_drake.core.landmark_tracking.make_filter`.
        dims: calibrated body dimensions (required for the EKF, ignored by the KF).
        config: a :class:`~akc_drake.core.kalman.KFConfig` (KF) or :class:`~akc_drake.core.kalman.EKFConfig`
            (EKF); None for the defaults.
        period_s: camera period, seconds (also the filter's ``dt``).
        rate_hz: alternatively the camera rate (give one of ``period_s``, ``rate_hz``).
        stage_offset_s: the per-stage offset of :func:`akc_drake.systems.timing.stage_offset`.
        nan_when_lost: output NaN for LOST landmarks; False outputs the core filter's held estimate.
        fix_left_right_swaps: undo a detector's left/right swap; on in the teleop diagram.

    Raises:
        ValueError: unknown mode, missing dims for the EKF, wrong config type or a bad period.
    """

    def __init__(self, mode: str = "KF", *, dims: BodyDimensions | None = None, config: KFConfig | None = None,
                 period_s: float | None = None, rate_hz: float | None = None,
                 stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S, nan_when_lost: bool = True,
                 fix_left_right_swaps: bool = False):
        super().__init__()
        self._nan_when_lost = bool(nan_when_lost)
        self._fix_swaps = bool(fix_left_right_swaps)
        self.mode, self._filter = make_filter(mode, dims, config)
        self._period = filter_period(period_s, rate_hz, default_rate_hz=timing.DEFAULT_CAMERA_RATE_HZ)
        self._u = self.DeclareVectorInputPort("landmarks_C", 3 * _J)
        self._x_filter = self.DeclareDiscreteState(BasicVector(self._filter.get_state_vector()))
        self._x_estimate = self.DeclareDiscreteState(BasicVector(np.full(3 * _J, np.nan)))
        self._x_status = self.DeclareDiscreteState(BasicVector(np.full(_J, float(UNINITIALISED))))
        self._x_swaps = self.DeclareDiscreteState(BasicVector([0.0]))
        self._x_variance = self.DeclareDiscreteState(BasicVector(np.full(3 * _J, np.nan)))
        self._x_taken = self.DeclareDiscreteState(BasicVector(np.full(3 * _J, np.nan)))
        self.DeclareStateOutputPort("landmarks_C_estimated", self._x_estimate)
        self.DeclareStateOutputPort("tracking_status", self._x_status)
        self.DeclareStateOutputPort("landmarks_C_variance", self._x_variance)
        self.DeclareStateOutputPort("landmarks_C_taken", self._x_taken)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self._period, offset_sec=timing.stage_offset("filter", stage_offset_s), update=self._update
        )
        self._missing = np.full((_J, 3), np.nan)
        self._taken = np.empty((_J, 3))

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
        z = self._u.Eval(context).reshape(_J, 3) if self._u.HasValue(context) else self._missing
        self._filter.set_state_vector(context.get_discrete_state(self._x_filter).get_value())
        swaps = context.get_discrete_state(self._x_swaps).get_value()[0]
        estimate, status, swaps = track_step(self._filter, z, self._period, swaps, fix_swaps=self._fix_swaps,
                                             nan_when_lost=self._nan_when_lost, taken=self._taken)
        if self._fix_swaps:
            discrete_state.get_mutable_vector(self._x_swaps).SetFromVector([swaps])
        discrete_state.get_mutable_vector(self._x_filter).SetFromVector(self._filter.get_state_vector())
        discrete_state.get_mutable_vector(self._x_estimate).SetFromVector(estimate.reshape(-1))
        discrete_state.get_mutable_vector(self._x_status).SetFromVector(status.astype(np.float64))
        discrete_state.get_mutable_vector(self._x_variance).SetFromVector(
            np.asarray(self._filter.position_variance, dtype=np.float64).reshape(-1)
        )
        discrete_state.get_mutable_vector(self._x_taken).SetFromVector(self._taken.reshape(-1))


def AddLandmarkKalmanFilter(builder: DiagramBuilder, landmarks_C: OutputPort | None = None, *, mode: str = "KF",
                            dims: BodyDimensions | None = None, config: KFConfig | None = None,
                            period_s: float | None = None, rate_hz: float | None = None,
                            stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
                            name: str = "LandmarkKalmanFilter") -> LandmarkKalmanFilter:
    """Add a :class:`LandmarkKalmanFilter` named ``name`` to ``builder``, connect ``landmarks_C`` (an output
    port, or None to leave the input) to its input and return it; the other arguments as for the system."""
    system = builder.AddSystem(LandmarkKalmanFilter(mode, dims=dims, config=config, period_s=period_s,
                                                    rate_hz=rate_hz, stage_offset_s=stage_offset_s))
    system.set_name(name)
    if landmarks_C is not None:
        builder.Connect(landmarks_C, system.get_input_port(0))
    return system


__all__ = ["MAX_SWAP_FRAMES", "MODES", "AddLandmarkKalmanFilter", "LandmarkKalmanFilter"]
