import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from akc_drake.core.coik import COIKConfig, COIKSolver
from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.systems.constrained_optimization_ik import DIAGNOSTICS, ConstrainedOptimizationIK

DIMS = BodyDimensions.paper_participant()
PERIOD = 0.1
OFFSET = 3e-3  # timing.stage_offset("corrector") with the default 1 ms per stage


def _pose(k: int, rng) -> np.ndarray:
    """Arms of the calibrated lengths moving over time, plus noise; left shoulder depth occluded on odd k."""
    t = 0.1 * k
    pose = np.zeros((12, 3))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        s = np.array([sign * 0.5 * DIMS.SW, -0.3, 2.0])
        a = 0.6 + 0.4 * math.sin(t + sign)
        u = np.array([0.0, math.cos(a), -math.sin(a)])
        e = s + DIMS.upper(side) * u
        w = e + DIMS.lower(side) * np.array([0.0, -0.3, -1.0]) / math.hypot(0.3, 1.0)
        pose[INDEX[f"{side}_shoulder"]], pose[INDEX[f"{side}_elbow"]], pose[INDEX[f"{side}_wrist"]] = s, e, w
        pose[INDEX[f"{side}_index"]] = w + [-sign * 0.02, 0.0, -0.08]
        pose[INDEX[f"{side}_pinky"]] = w + [sign * 0.02, 0.0, -0.07]
        pose[INDEX[f"{side}_hip"]] = [sign * 0.1, 0.2, 2.0]
    pose += rng.normal(0.0, 0.01, pose.shape)
    if k % 2:
        pose[INDEX["left_shoulder"], 2] = pose[INDEX["left_wrist"], 2] + 0.02
    return pose


def test_ports_and_initial_output():
    sys = ConstrainedOptimizationIK(DIMS)
    assert sys.num_input_ports() == 1 and sys.get_input_port(0).get_name() == "landmarks_C"
    assert sys.get_input_port(0).size() == 36
    assert sys.GetOutputPort("landmarks_C_corrected").size() == 36
    assert sys.GetOutputPort("diagnostics").size() == len(DIAGNOSTICS) == 3
    ctx = sys.CreateDefaultContext()
    assert np.all(np.isnan(sys.GetOutputPort("landmarks_C_corrected").Eval(ctx)))
    assert sys.GetOutputPort("diagnostics").Eval(ctx)[0] == 4.0  # held: nothing solved yet


def test_leaf_system_matches_the_core_over_a_sequence():
    rng = np.random.default_rng(0)
    poses = [_pose(k, rng) for k in range(8)]
    config = COIKConfig(lam=0.5, solver="snopt")
    sys = ConstrainedOptimizationIK(DIMS, config, period_s=PERIOD)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    core = COIKSolver(DIMS, config)
    for k, pose in enumerate(poses):
        sys.get_input_port(0).FixValue(ctx, pose.reshape(36))
        sim.AdvanceTo(k * PERIOD + OFFSET + 1e-4)
        out = sys.GetOutputPort("landmarks_C_corrected").Eval(ctx).reshape(12, 3)
        diag = sys.GetOutputPort("diagnostics").Eval(ctx)
        ref = core.solve(pose)
        np.testing.assert_allclose(out, ref.pose, atol=1e-12)
        assert diag[0] == ref.status_code == 0
        assert diag[1] > 0.0
        assert diag[2] == pytest.approx(ref.max_length_error_m, abs=1e-12)
        assert diag[2] < 1e-6


def test_update_happens_at_the_corrector_offset_and_holds_between_samples():
    rng = np.random.default_rng(1)
    sys = ConstrainedOptimizationIK(DIMS, period_s=PERIOD)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    sys.get_input_port(0).FixValue(ctx, _pose(0, rng).reshape(36))
    sim.AdvanceTo(OFFSET - 5e-4)
    assert np.all(np.isnan(sys.GetOutputPort("landmarks_C_corrected").Eval(ctx)))
    sim.AdvanceTo(OFFSET + 5e-4)
    first = sys.GetOutputPort("landmarks_C_corrected").Eval(ctx).copy()
    assert np.all(np.isfinite(first))
    # A new input does not change the output until the next sample.
    sys.get_input_port(0).FixValue(ctx, _pose(5, rng).reshape(36))
    sim.AdvanceTo(PERIOD + OFFSET - 5e-4)
    np.testing.assert_array_equal(sys.GetOutputPort("landmarks_C_corrected").Eval(ctx), first)
    sim.AdvanceTo(PERIOD + OFFSET + 5e-4)
    assert not np.allclose(sys.GetOutputPort("landmarks_C_corrected").Eval(ctx), first)


def test_nan_input_holds_the_previous_output():
    rng = np.random.default_rng(2)
    sys = ConstrainedOptimizationIK(DIMS, period_s=PERIOD)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    sys.get_input_port(0).FixValue(ctx, _pose(0, rng).reshape(36))
    sim.AdvanceTo(OFFSET + 1e-4)
    held = sys.GetOutputPort("landmarks_C_corrected").Eval(ctx).copy()
    sys.get_input_port(0).FixValue(ctx, np.full(36, np.nan))
    sim.AdvanceTo(PERIOD + OFFSET + 1e-4)
    out = sys.GetOutputPort("landmarks_C_corrected").Eval(ctx).reshape(12, 3)
    arm = [INDEX[n] for n in ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist")]
    np.testing.assert_array_equal(out[arm], held.reshape(12, 3)[arm])
    assert sys.GetOutputPort("diagnostics").Eval(ctx)[0] == 4.0


def test_bad_period_is_rejected():
    with pytest.raises(ValueError, match="period_s"):
        ConstrainedOptimizationIK(DIMS, period_s=0.0)
