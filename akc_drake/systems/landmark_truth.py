"""The simulated operator's true landmarks in the camera frame, as a Drake system (for evaluation only)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams, landmarks_from_q


class LandmarkTruth(LeafSystem):
    """The operator's true landmarks in the camera frame from its joint positions (direct feedthrough).

    .. pydrake_system::

        name: LandmarkTruth
        input_ports:
        - q
        output_ports:
        - landmarks_true_C

    ``q`` is the canonical joint vector ``[q_left, q_right]`` (10), ``landmarks_true_C`` the 36 coordinates
    of the ``(12, 3)`` landmarks in C, row-major.

    Args:
        params: the operator's dimensions.
        X_CO: pose of the operator frame O in the camera frame C.
        landmarks_O: ``q (T, 10) -> (T, 12, 3)`` true landmarks in O (default: the primitive operator's,
            :func:`~akc_drake.operator.model.landmarks_from_q`; the skinned body passes its rig's).
    """

    def __init__(self, params: OperatorParams, X_CO: RigidTransform, landmarks_O: Callable | None = None):
        super().__init__()
        self._params = params
        self._landmarks_O = landmarks_O
        self._R = X_CO.rotation().matrix()
        self._p = X_CO.translation()
        self._q = self.DeclareVectorInputPort("q", 2 * NUM_ARM_DOF)
        self.DeclareVectorOutputPort("landmarks_true_C", 3 * NUM_LANDMARKS, self._calc)

    def landmarks_C(self, q: np.ndarray) -> np.ndarray:
        """``(12, 3)`` landmarks in C for the canonical joint vector ``q = [q_left, q_right]``."""
        if self._landmarks_O is not None:
            lm_O = self._landmarks_O(np.asarray(q, float)[None])[0]
        else:
            lm_O = landmarks_from_q(q[:NUM_ARM_DOF], q[NUM_ARM_DOF:], self._params)[0]
        return lm_O @ self._R.T + self._p

    def _calc(self, context, output):
        output.SetFromVector(self.landmarks_C(self._q.Eval(context)).ravel())
