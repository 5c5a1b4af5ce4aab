"""Stage S4 (baseline): the COIK program of eq. (16) as a sampled Drake system."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from akc_drake.core.coik import STATE_SIZE, STATUS_CODES, COIKConfig, COIKSolver
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing

POSE_SIZE = 3 * NUM_LANDMARKS
#: Layout of the ``diagnostics`` output.
DIAGNOSTICS = ("status", "solve_time_s", "max_length_error_m")


class ConstrainedOptimizationIK(LeafSystem):
    """Corrects the filtered pose with COIK (paper eq. 16), once per camera frame.

    .. pydrake_system::

        name: ConstrainedOptimizationIK
        input_ports:
        - landmarks_C
        output_ports:
        - landmarks_C_corrected
        - diagnostics

    ``landmarks_C`` and ``landmarks_C_corrected`` are the ``(12, 3)`` camera-frame pose flattened row-major
    (36). ``diagnostics`` is ``[status, solve_time_s, max_length_error_m]`` with status 0 success, 1 iteration
    limit, 2 infeasible, 3 failed, 4 held (nothing to solve; the previous output is held). Before the first
    update the corrected pose is NaN and the status is 4.

    State: discrete groups ``corrected`` (36), ``diagnostics`` (3) and ``solver`` (the previous solution and a
    has-previous flag, 19). A periodic discrete update at the camera period, offset by
    ``timing.stage_offset("corrector")``, runs the solver; outputs are the state.

    Args:
        dims: calibrated arm lengths and shoulder width.
        config: COIK options (λ, solver, iteration limit, elbow bounds).
        period_s: camera period, seconds.
        stage_offset_s: per-stage offset (see :mod:`akc_drake.systems.timing`).
    """

    def __init__(
        self,
        dims: BodyDimensions,
        config: COIKConfig | None = None,
        *,
        period_s: float = 1.0 / timing.DEFAULT_CAMERA_RATE_HZ,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
    ):
        super().__init__()
        if not (np.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"period_s must be a positive number of seconds, got {period_s!r}")
        self._solver = COIKSolver(dims, config)
        self._input = self.DeclareVectorInputPort("landmarks_C", BasicVector(POSE_SIZE))
        self._corrected = self.DeclareDiscreteState(np.full(POSE_SIZE, np.nan))
        self._diagnostics = self.DeclareDiscreteState(np.array([float(STATUS_CODES["held"]), 0.0, np.nan]))
        self._state = self.DeclareDiscreteState(self._solver.get_state_vector())
        self.DeclareStateOutputPort("landmarks_C_corrected", self._corrected)
        self.DeclareStateOutputPort("diagnostics", self._diagnostics)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=period_s,
            offset_sec=timing.stage_offset("corrector", stage_offset_s),
            update=self._update,
        )

    @property
    def solver(self) -> COIKSolver:
        """The core solver this system runs (its state is moved in and out of the context on each update)."""
        return self._solver

    def _update(self, context, discrete_state) -> None:
        pose = self._input.Eval(context).reshape(NUM_LANDMARKS, 3)
        state = context.get_discrete_state(self._state).get_value()
        assert state.shape == (STATE_SIZE,)
        self._solver.set_state_vector(state)
        result = self._solver.solve(pose)
        discrete_state.get_mutable_vector(self._corrected).SetFromVector(result.pose.reshape(POSE_SIZE))
        discrete_state.get_mutable_vector(self._diagnostics).SetFromVector(
            np.array([float(result.status_code), result.solve_time_s, result.max_length_error_m])
        )
        discrete_state.get_mutable_vector(self._state).SetFromVector(self._solver.get_state_vector())
