import numpy as np
from pydrake.systems.analysis import Simulator

from akc_drake.systems.measurement_replay import MeasurementReplay


def test_replay_outputs_frames_at_extractor_times():
    T = 5
    L = np.arange(T * 12 * 3, dtype=float).reshape(T, 12, 3)
    V = np.linspace(0, 1, T * 12).reshape(T, 12)
    P = -np.arange(T * 24, dtype=float).reshape(T, 12, 2)
    sys = MeasurementReplay(L, V, P, period_s=0.1)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    assert np.isnan(sys.GetOutputPort("landmarks_C").Eval(ctx)).all()
    for k in range(T + 2):
        sim.AdvanceTo(0.1 * k + 0.0015)
        kk = min(k, T - 1)
        np.testing.assert_array_equal(sys.GetOutputPort("landmarks_C").Eval(ctx), L[kk].ravel())
        np.testing.assert_array_equal(sys.GetOutputPort("visibility").Eval(ctx), V[kk])
        np.testing.assert_array_equal(sys.GetOutputPort("pixels").Eval(ctx), P[kk].ravel())
        assert sys.GetOutputPort("frame_index").Eval(ctx)[0] == kk
    assert np.isnan(sys.GetOutputPort("landmarks_true_C").Eval(ctx)).all()
