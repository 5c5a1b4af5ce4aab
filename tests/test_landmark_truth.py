"""LandmarkTruth: the simulated operator's true landmarks, moved into the camera frame."""

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw

from akc_drake.operator.model import NUM_ARM_DOF, OperatorParams, landmarks_from_q
from akc_drake.systems.landmark_truth import LandmarkTruth


def _eval(system, q):
    ctx = system.CreateDefaultContext()
    system.get_input_port().FixValue(ctx, q)
    return system.get_output_port().Eval(ctx).reshape(12, 3)


def test_landmarks_are_the_operators_moved_into_the_camera_frame():
    params = OperatorParams()
    X_CO = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.05, -0.4, 2.0])
    system = LandmarkTruth(params, X_CO)
    q = np.linspace(-0.5, 0.6, 2 * NUM_ARM_DOF)
    out = _eval(system, q)
    lm_O = landmarks_from_q(q[:NUM_ARM_DOF], q[NUM_ARM_DOF:], params)[0]
    expected = np.array([X_CO.multiply(p) for p in lm_O])
    np.testing.assert_allclose(out, expected, atol=1e-14)
    np.testing.assert_array_equal(out, system.landmarks_C(q))
    # Rigid: the distances between landmarks are those in O.
    d = np.linalg.norm(out[:, None] - out[None], axis=2)
    np.testing.assert_allclose(d, np.linalg.norm(lm_O[:, None] - lm_O[None], axis=2), atol=1e-14)


def test_a_given_rig_replaces_the_primitive_operator():
    calls = []

    def rig(q):  # (T, 10) -> (T, 12, 3)
        calls.append(q.shape)
        return np.tile(np.arange(36.0).reshape(1, 12, 3), (len(q), 1, 1)) + q[:, :1, None]

    system = LandmarkTruth(OperatorParams(), RigidTransform([0.0, 0.0, 1.0]), rig)
    out = _eval(system, np.full(2 * NUM_ARM_DOF, 0.5))
    np.testing.assert_array_equal(out, np.arange(36.0).reshape(12, 3) + 0.5 + [0.0, 0.0, 1.0])
    assert calls == [(1, 2 * NUM_ARM_DOF)]
