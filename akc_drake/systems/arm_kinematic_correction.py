"""Stage S4: Arm Kinematic Correction as a Drake LeafSystem: the paper's AKC (:mod:`akc_drake.core.akc`) or
our AKC+ (:mod:`akc_drake.core.akc_plus`, which also reads the occlusion filter's output)."""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from akc_drake.core.akc import AKCWeights, ArmKinematicCorrector
from akc_drake.core.akc_plus import AKCPlusConfig, ArmKinematicCorrectorPlus
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing

#: Entries of the ``diagnostics`` output port, in order.
DIAGNOSTICS: tuple[str, ...] = (
    "chosen_left",
    "chosen_right",
    "fallback_left",
    "fallback_right",
    "held_left",
    "held_right",
    "cost_left",
    "cost_right",
)
_POSE_SIZE = 3 * NUM_LANDMARKS


class ArmKinematicCorrection(LeafSystem):
    """Replaces the filtered arm joints by the AKC-corrected ones (paper §II-D), at the camera rate.

    .. pydrake_system::

        name: ArmKinematicCorrection
        input_ports:
        - landmarks_C
        - landmarks_C_measured (AKC+ only)
        - landmarks_C_variance (AKC+ only, optional)
        output_ports:
        - landmarks_C_corrected
        - diagnostics

    ``landmarks_C`` and ``landmarks_C_corrected`` carry the ``(12, 3)`` pose in the camera frame, flattened
    row-major (36 numbers, NaN where missing). ``diagnostics`` is ``[chosen_left, chosen_right,
    fallback_left, fallback_right, held_left, held_right, cost_left, cost_right]`` (see
    :class:`~akc_drake.core.akc.AKCResult`; chosen is -1 and cost NaN for a held arm).

    State (discrete, three groups): the corrector's state (previous corrected arm joints and validity
    flags: 20 for AKC, 101 for AKC+), the last corrected pose (36) and the last diagnostics (8). A periodic
    discrete update at the camera period, offset by ``timing.stage_offset("corrector")``, reads the input and
    the corrector state, runs :meth:`ArmKinematicCorrector.correct` and writes all three groups; the outputs are the
    state, so the system has no direct feedthrough. Before the first update the pose is NaN.

    Args:
        dims: the calibrated body dimensions.
        weights: cost weights and shrink factor (default: the paper's ``Wb``).
        rate_hz: the camera rate (AKC+ scales its per-frame settings to its period).
        stage_offset_s: the per-stage offset of :func:`akc_drake.systems.timing.stage_offset`.
        anatomical_check: hold an arm whose chosen configuration has an impossible elbow angle (see
            :class:`~akc_drake.core.akc.ArmKinematicCorrector`); on in the teleop diagram (paper AKC only).
        corrector: "AKC" (the paper's) or "AKC+" (ours; then the input ``landmarks_C_measured`` takes the
            occlusion filter's output of the same frame, whose seen depths AKC+ keeps, and the optional input
            ``landmarks_C_variance`` the filter's posterior variance of each coordinate of ``landmarks_C``
            (36 numbers; left unconnected, AKC+ runs without the covariance, see
            :class:`~akc_drake.core.akc_plus.ArmKinematicCorrectorPlus`).
        plus_config: AKC+ settings (None: the defaults).
    """

    def __init__(
        self,
        dims: BodyDimensions,
        weights: AKCWeights | None = None,
        *,
        rate_hz: float = timing.DEFAULT_CAMERA_RATE_HZ,
        stage_offset_s: float = timing.DEFAULT_STAGE_OFFSET_S,
        anatomical_check: bool = False,
        corrector: str = "AKC",
        plus_config: AKCPlusConfig | None = None,
    ):
        super().__init__()
        if corrector not in ("AKC", "AKC+"):
            raise ValueError(f"corrector must be AKC or AKC+, got {corrector!r}")
        if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        # The core object is created once; each update loads the context's state into it and back out.
        if corrector == "AKC+":
            self._akc = ArmKinematicCorrectorPlus(dims, plus_config, period_s=1.0 / float(rate_hz))
        else:
            self._akc = ArmKinematicCorrector(dims, weights, anatomical_check=anatomical_check)
        self._plus = corrector == "AKC+"
        self._period = 1.0 / float(rate_hz)

        self._u = self.DeclareVectorInputPort("landmarks_C", _POSE_SIZE)
        self._m = self.DeclareVectorInputPort("landmarks_C_measured", _POSE_SIZE) if self._plus else None
        self._var = self.DeclareVectorInputPort("landmarks_C_variance", _POSE_SIZE) if self._plus else None
        self._x_akc = self.DeclareDiscreteState(BasicVector(self._akc.get_state_vector()))
        self._x_pose = self.DeclareDiscreteState(BasicVector(np.full(_POSE_SIZE, np.nan)))
        initial_diag = np.array([-1.0, -1.0, 0.0, 0.0, 1.0, 1.0, np.nan, np.nan])
        self._x_diag = self.DeclareDiscreteState(BasicVector(initial_diag))
        self.DeclareStateOutputPort("landmarks_C_corrected", self._x_pose)
        self.DeclareStateOutputPort("diagnostics", self._x_diag)
        self.DeclarePeriodicDiscreteUpdateEvent(
            period_sec=self._period,
            offset_sec=timing.stage_offset("corrector", stage_offset_s),
            update=self._update,
        )

    @property
    def corrector(self) -> ArmKinematicCorrector | ArmKinematicCorrectorPlus:
        """The wrapped core corrector (its state is whatever the last update left in it)."""
        return self._akc

    @property
    def period_s(self) -> float:
        return self._period

    def _update(self, context, discrete_state) -> None:
        pose = self._u.Eval(context).reshape(NUM_LANDMARKS, 3)
        self._akc.set_state_vector(context.get_discrete_state(self._x_akc).get_value())
        if self._plus:
            var = None
            if self._var.HasValue(context):
                var = self._var.Eval(context).reshape(NUM_LANDMARKS, 3)
            r = self._akc.correct(pose, self._m.Eval(context).reshape(NUM_LANDMARKS, 3), var)
        else:
            r = self._akc.correct(pose)
        discrete_state.get_mutable_vector(self._x_akc).SetFromVector(self._akc.get_state_vector())
        discrete_state.get_mutable_vector(self._x_pose).SetFromVector(r.pose.reshape(-1))
        diag = np.concatenate([r.chosen, r.fallback, r.held, r.cost]).astype(float)
        discrete_state.get_mutable_vector(self._x_diag).SetFromVector(diag)

