"""Tests of the LandmarkKalmanFilter LeafSystem (stage S3b)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from akc_drake.core.kalman import (
    PREDICTING,
    TRACKING,
    UNINITIALISED,
    ConstantVelocityKF,
    EKFConfig,
    ExtendedKalmanFilterCV,
    KFConfig,
)
from akc_drake.core.skeleton import NUM_LANDMARKS, BodyDimensions
from akc_drake.systems import timing
from akc_drake.systems.landmark_kalman_filter import AddLandmarkKalmanFilter, LandmarkKalmanFilter

DIMS = BodyDimensions.paper_participant()


def measurements(T, seed=0):
    rng = np.random.default_rng(seed)
    base = rng.uniform(-0.4, 0.4, (NUM_LANDMARKS, 3)) + [0, 0, 2]
    vel = rng.normal(scale=0.2, size=(NUM_LANDMARKS, 3))
    noise = rng.normal(size=(T, NUM_LANDMARKS, 3)) * [0.01, 0.01, 0.05]
    z = base + vel * (0.1 * np.arange(T))[:, None, None] + noise
    z[rng.random((T, NUM_LANDMARKS)) < 0.15] = np.nan
    z[rng.random((T, NUM_LANDMARKS)) < 0.2, 2] = np.nan
    z[:4, 7] = np.nan
    return z


def step_system(system, context, z):
    """One discrete update with input ``z`` fixed; returns the outputs after it."""
    system.get_input_port(0).FixValue(context, z.reshape(-1))
    context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
    est = system.GetOutputPort("landmarks_C_estimated").Eval(context).reshape(NUM_LANDMARKS, 3)
    status = system.GetOutputPort("tracking_status").Eval(context)
    return est.copy(), status.copy()


@pytest.mark.parametrize("mode", ["KF", "EKF"])
def test_system_matches_core_filter_and_cloned_context_replays(mode):
    z = measurements(40)
    system = LandmarkKalmanFilter(mode, dims=DIMS, period_s=0.1)
    core = ConstantVelocityKF() if mode == "KF" else ExtendedKalmanFilterCV(DIMS)
    context = system.CreateDefaultContext()
    clone, second_half = None, []
    for k in range(len(z)):
        if k == 20:
            clone = context.Clone()
        est, status = step_system(system, context, z[k])
        ref = core.step(z[k], 0.1)
        np.testing.assert_array_equal(np.isnan(est), np.isnan(ref))
        np.testing.assert_allclose(est, ref, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(status, core.status)
        if k >= 20:
            second_half.append((est, status))
    assert np.isfinite(est).all()
    # replay the second half from the clone: identical, bit for bit
    for k in range(20, 40):
        est_r, status_r = step_system(system, clone, z[k])
        np.testing.assert_array_equal(est_r, second_half[k - 20][0])
        np.testing.assert_array_equal(status_r, second_half[k - 20][1])
    idx = system.filter_state_index()
    np.testing.assert_array_equal(
        clone.get_discrete_state(idx).get_value(), context.get_discrete_state(idx).get_value()
    )


@pytest.mark.parametrize("mode", ["KF", "EKF"])
def test_variance_output_is_the_core_filters_posterior_variance(mode):
    # AKC+ reads it to test what the camera sees: NaN before the first update and for axes never measured,
    # then the core filter's position_variance, growing while a depth is dropped.
    z = measurements(12)
    z[6:, 3, 2] = np.nan
    system = LandmarkKalmanFilter(mode, dims=DIMS, period_s=0.1)
    core = ConstantVelocityKF() if mode == "KF" else ExtendedKalmanFilterCV(DIMS)
    context = system.CreateDefaultContext()
    port = system.GetOutputPort("landmarks_C_variance")
    assert port.size() == 36 and np.isnan(port.Eval(context)).all()
    dropped = []
    for k in range(len(z)):
        step_system(system, context, z[k])
        core.step(z[k], 0.1)
        var = port.Eval(context)
        np.testing.assert_array_equal(var, np.asarray(core.position_variance).reshape(-1))
        dropped.append(var.reshape(NUM_LANDMARKS, 3)[3, 2])
    if mode == "KF":  # (the EKF's bone constraints inform a dropped depth)
        assert np.all(np.diff(dropped[6:]) > 0)  # the dropped depth's variance grows every frame
    assert dropped[-1] > dropped[5]
    assert np.nanmax(var) > 0 and np.nanmin(var) > 0


@pytest.mark.parametrize("mode", ["KF", "EKF"])
def test_taken_output_is_the_input_as_the_gate_took_it(mode):
    """``landmarks_C_taken``: without a gate the input itself; with one, NaN on the landmark whose reading it
    rejected (a 1 m jump), the rest as measured."""
    rng = np.random.default_rng(3)  # (everything measured, smoothly: a rejection is the only NaN)
    z = (rng.uniform(-0.4, 0.4, (NUM_LANDMARKS, 3)) + [0, 0, 2] + 0.01 * np.arange(12)[:, None, None]
         + rng.normal(size=(12, NUM_LANDMARKS, 3)) * [0.005, 0.005, 0.02])
    cfg = EKFConfig(gate_sigma=5.0, gate_whole_landmark=True)
    plain, gated = (LandmarkKalmanFilter(mode, dims=DIMS, period_s=0.1, config=c) for c in (None, cfg))
    cp, cg = plain.CreateDefaultContext(), gated.CreateDefaultContext()
    port_p, port_g = plain.GetOutputPort("landmarks_C_taken"), gated.GetOutputPort("landmarks_C_taken")
    assert port_g.size() == 36 and np.isnan(port_g.Eval(cg)).all()
    for k in range(len(z) - 1):
        step_system(plain, cp, z[k])
        step_system(gated, cg, z[k])
        np.testing.assert_array_equal(port_p.Eval(cp), z[k].reshape(-1))
        np.testing.assert_array_equal(port_g.Eval(cg), z[k].reshape(-1))
    jump = z[-1].copy()
    jump[4, 0] += 1.0
    step_system(gated, cg, jump)
    taken = port_g.Eval(cg).reshape(NUM_LANDMARKS, 3)
    assert np.isnan(taken[4]).all()
    np.testing.assert_array_equal(np.delete(taken, 4, axis=0), np.delete(jump, 4, axis=0))


def test_outputs_before_first_update_and_unconnected_input_predicts():
    system = LandmarkKalmanFilter("KF")
    context = system.CreateDefaultContext()
    assert np.isnan(system.get_output_port(0).Eval(context)).all()
    np.testing.assert_array_equal(system.get_output_port(1).Eval(context), np.full(12, UNINITIALISED))
    z = np.tile([0.0, 0.0, 2.0], (NUM_LANDMARKS, 1))
    step_system(system, context, z)
    fresh = system.CreateDefaultContext()
    fresh.SetDiscreteState(context.get_discrete_state().Clone())
    # no input at all: prediction only, status PREDICTING
    fresh.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(fresh))
    np.testing.assert_array_equal(system.get_output_port(1).Eval(fresh), np.full(12, PREDICTING))
    np.testing.assert_allclose(system.get_output_port(0).Eval(fresh), z.reshape(-1), atol=1e-12)


def test_ports_event_timing_and_no_feedthrough():
    system = LandmarkKalmanFilter("EKF", dims=DIMS, rate_hz=10.0, stage_offset_s=0.002)
    assert system.get_input_port(0).get_name() == "landmarks_C" and system.get_input_port(0).size() == 36
    assert system.GetOutputPort("landmarks_C_estimated").size() == 36
    assert system.GetOutputPort("tracking_status").size() == 12
    assert not system.HasAnyDirectFeedthrough()
    attr = system.GetUniquePeriodicDiscreteUpdateAttribute()
    assert attr is not None
    assert attr.period_sec() == pytest.approx(0.1)
    assert attr.offset_sec() == pytest.approx(timing.stage_offset("filter", 0.002))
    assert system.period_s == pytest.approx(0.1)
    assert isinstance(system.filter, ExtendedKalmanFilterCV)


def test_simulated_in_a_diagram_at_the_camera_rate():
    target = np.tile([0.1, -0.2, 2.0], (NUM_LANDMARKS, 1))
    target[:, 0] += 0.05 * np.arange(NUM_LANDMARKS)
    builder = DiagramBuilder()
    src = builder.AddSystem(ConstantVectorSource(target.reshape(-1)))
    kf = AddLandmarkKalmanFilter(builder, src.get_output_port(), mode="KF", rate_hz=10.0)
    builder.ExportOutput(kf.GetOutputPort("landmarks_C_estimated"), "est")
    builder.ExportOutput(kf.GetOutputPort("tracking_status"), "status")
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(0.95)
    ctx = sim.get_context()
    np.testing.assert_allclose(diagram.GetOutputPort("est").Eval(ctx), target.reshape(-1), atol=1e-12)
    np.testing.assert_array_equal(diagram.GetOutputPort("status").Eval(ctx), np.full(12, TRACKING))
    # ten updates happened (t = 0.002, 0.102, ..., 0.902): the core filter's last dt is the period
    assert kf.filter._dt == pytest.approx(0.1)


def test_config_reaches_the_core_and_bad_arguments_raise():
    system = LandmarkKalmanFilter("kf", config=KFConfig(sigma_z=0.2))
    assert system.mode == "KF" and system.filter.config.sigma_z == 0.2
    ekf = LandmarkKalmanFilter("EKF", dims=DIMS, config=EKFConfig(sigma_c=0.05))
    assert ekf.filter.config.sigma_c == 0.05
    # an EKFConfig is accepted by the KF (its KF part is used)
    assert LandmarkKalmanFilter("KF", config=EKFConfig(sigma_x=0.02)).filter.config.sigma_x == 0.02
    with pytest.raises(ValueError, match="mode"):
        LandmarkKalmanFilter("UKF")
    with pytest.raises(ValueError, match="dims"):
        LandmarkKalmanFilter("EKF")
    with pytest.raises(ValueError, match="EKFConfig"):
        LandmarkKalmanFilter("EKF", dims=DIMS, config=KFConfig())
    with pytest.raises(ValueError, match="period_s"):
        LandmarkKalmanFilter("KF", period_s=0.0)
    with pytest.raises(ValueError, match="rate_hz"):
        LandmarkKalmanFilter("KF", rate_hz=-10.0)
    with pytest.raises(ValueError, match="not both"):
        LandmarkKalmanFilter("KF", rate_hz=10.0, period_s=0.1)
