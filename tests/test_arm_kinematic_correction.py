import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from akc_drake.core.akc import AKCWeights, ArmKinematicCorrector
from akc_drake.core.skeleton import INDEX, BodyDimensions
from akc_drake.systems.arm_kinematic_correction import DIAGNOSTICS, ArmKinematicCorrection


def frame(k: int) -> np.ndarray:
    """A moving, partly occluded pose; some frames lose a wrist or an elbow."""
    p = np.zeros((12, 3))
    t = 0.3 * k
    p[INDEX["left_shoulder"]] = [0.17, 0.0, 2.0]
    p[INDEX["right_shoulder"]] = [-0.17, 0.01, 2.01]
    p[INDEX["left_elbow"]] = [0.27 + 0.03 * math.sin(t), 0.16, 1.62]  # elbow depth = wrist depth (occluded)
    p[INDEX["right_elbow"]] = [-0.28, 0.15 + 0.03 * math.cos(t), 1.85]
    p[INDEX["left_wrist"]] = [0.33, 0.05 + 0.02 * t, 1.62]
    p[INDEX["right_wrist"]] = [-0.31, 0.02, 1.60]
    p[6:10] = p[[4, 5, 4, 5]] + 0.03
    p[INDEX["left_hip"]] = [0.13, 0.5, 2.0]
    p[INDEX["right_hip"]] = [-0.13, 0.5, 2.0]
    if k == 4:
        p[INDEX["left_wrist"]] = np.nan
    if k == 6:
        p[INDEX["right_elbow"], :2] = np.nan
    if k == 8:
        p[INDEX["left_elbow"]] = [0.9, 0.9, 1.6]  # far out of reach: eq. (9) fallback
    return p


def test_ports_and_declarations():
    sys = ArmKinematicCorrection(BodyDimensions.paper_participant())
    assert sys.get_input_port(0).get_name() == "landmarks_C" and sys.get_input_port(0).size() == 36
    assert [sys.get_output_port(i).get_name() for i in range(2)] == ["landmarks_C_corrected", "diagnostics"]
    assert sys.get_output_port(1).size() == len(DIAGNOSTICS) == 8
    assert not sys.HasAnyDirectFeedthrough()
    attr = sys.GetUniquePeriodicDiscreteUpdateAttribute()
    assert attr.period_sec() == pytest.approx(0.1) and attr.offset_sec() == pytest.approx(0.003)
    ctx = sys.CreateDefaultContext()
    assert np.all(np.isnan(sys.get_output_port(0).Eval(ctx)))
    np.testing.assert_array_equal(sys.get_output_port(1).Eval(ctx)[:6], [-1, -1, 0, 0, 1, 1])


def test_bad_rate_is_rejected():
    with pytest.raises(ValueError, match="rate_hz"):
        ArmKinematicCorrection(BodyDimensions.paper_participant(), rate_hz=0.0)


def test_outputs_equal_the_core_over_a_sequence_of_updates():
    dims = BodyDimensions.paper_participant()
    weights = AKCWeights.preset("Wc")
    sys = ArmKinematicCorrection(dims, weights, rate_hz=10.0)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    u = sys.get_input_port(0)
    core = ArmKinematicCorrector(dims, weights)
    seen_fallback = seen_held = False
    previous = np.full(36, np.nan)
    for k in range(12):
        u.FixValue(ctx, frame(k).reshape(-1))
        # The update for frame k happens at t_k + 3 ms; just before it the output is still frame k-1's.
        sim.AdvanceTo(0.1 * k + 0.002)
        before = sys.get_output_port(0).Eval(ctx).copy()
        sim.AdvanceTo(0.1 * k + 0.05)
        out = sys.get_output_port(0).Eval(ctx)
        diag = sys.get_output_port(1).Eval(ctx)
        r = core.correct(frame(k))
        np.testing.assert_array_equal(out, r.pose.reshape(-1))
        np.testing.assert_array_equal(diag[:6], np.concatenate([r.chosen, r.fallback, r.held]).astype(float))
        np.testing.assert_array_equal(diag[6:], r.cost)
        np.testing.assert_array_equal(before, previous)
        previous = out.copy()
        seen_fallback |= bool(r.fallback.any())
        seen_held |= bool(r.held.any())
        np.testing.assert_array_equal(ctx.get_discrete_state(0).get_value(), core.get_state_vector())
    assert seen_fallback and seen_held
    assert np.all(np.isfinite(out))


def test_two_contexts_do_not_share_state():
    dims = BodyDimensions.paper_participant()
    sys = ArmKinematicCorrection(dims)
    a, b = Simulator(sys), Simulator(sys)
    sys.get_input_port(0).FixValue(a.get_mutable_context(), frame(0).reshape(-1))
    sys.get_input_port(0).FixValue(b.get_mutable_context(), frame(3).reshape(-1))
    a.AdvanceTo(0.35)
    b.AdvanceTo(0.05)
    # b has seen one frame only: same as a fresh core on frame 3 (no temporal term from a's history).
    out_b = sys.get_output_port(0).Eval(b.get_context())
    np.testing.assert_array_equal(out_b, ArmKinematicCorrector(dims).correct(frame(3)).pose.reshape(-1))


def test_akc_plus_system_keeps_a_seen_arm():
    """corrector="AKC+": a second input takes the occlusion filter's output; an exact seen arm is unchanged."""
    from pydrake.systems.framework import DiagramBuilder

    from akc_drake.core.skeleton import segment_lengths

    pose = np.zeros((12, 3))
    pose[:, 2] = 2.0
    pose[INDEX["left_shoulder"]] = [0.18, 0.0, 2.0]
    pose[INDEX["right_shoulder"]] = [-0.18, 0.0, 2.0]
    pose[INDEX["left_elbow"]] = [0.25, 0.2, 1.85]
    pose[INDEX["right_elbow"]] = [-0.25, 0.2, 1.85]
    pose[INDEX["left_wrist"]] = [0.3, 0.05, 1.65]
    pose[INDEX["right_wrist"]] = [-0.3, 0.05, 1.65]
    lens = segment_lengths(pose[None])
    dims = BodyDimensions(**{k: float(v[0]) for k, v in lens.items()})
    builder = DiagramBuilder()
    sys_ = builder.AddSystem(ArmKinematicCorrection(dims, corrector="AKC+"))
    builder.ExportInput(sys_.GetInputPort("landmarks_C"), "pose")
    builder.ExportInput(sys_.GetInputPort("landmarks_C_measured"), "measured")
    builder.ExportOutput(sys_.GetOutputPort("landmarks_C_corrected"), "out")
    diagram = builder.Build()
    from pydrake.systems.analysis import Simulator

    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    diagram.get_input_port(0).FixValue(ctx, pose.ravel())
    diagram.get_input_port(1).FixValue(ctx, pose.ravel())
    sim.AdvanceTo(0.25)
    out = diagram.get_output_port(0).Eval(ctx).reshape(12, 3)
    np.testing.assert_allclose(out[:6], pose[:6], atol=1e-9)
    with pytest.raises(ValueError, match="AKC or AKC\\+"):
        ArmKinematicCorrection(dims, corrector="XYZ")


def _plus_with_variance(dims, rate_hz=10.0):
    """A diagram of the AKC+ system with its three inputs exported (pose, measured, variance) and its corrected
    pose; returns (diagram, simulator, context)."""
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    sys_ = builder.AddSystem(ArmKinematicCorrection(dims, corrector="AKC+", rate_hz=rate_hz))
    for name in ("landmarks_C", "landmarks_C_measured", "landmarks_C_variance"):
        builder.ExportInput(sys_.GetInputPort(name), name)
    builder.ExportOutput(sys_.GetOutputPort("landmarks_C_corrected"), "out")
    diagram = builder.Build()
    sim = Simulator(diagram)
    return diagram, sim, sim.get_mutable_context()


def test_akc_plus_system_uses_the_filter_variance_when_connected():
    """The optional input landmarks_C_variance reaches the core: the system equals the core given the variance,
    and differs from the core without it (a lagging filtered wrist that the variance marks)."""

    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus

    dims = BodyDimensions.paper_participant()
    poses = [frame(k) for k in range(6)]
    for p in poses:
        p[INDEX["left_wrist"]] = [0.33, 0.05, 1.62]
        p[INDEX["left_elbow"]] = [0.3, 0.2, 1.8]
    measured = [p.copy() for p in poses]
    for q in measured:
        q[INDEX["left_wrist"], 2] = 1.66  # the filter's wrist lags 4 cm behind a consistent measurement
    var = np.full((12, 3), 1e-5)
    var[:, 2] = 1.5e-3
    diagram, sim, ctx = _plus_with_variance(dims)
    core, blind = ArmKinematicCorrectorPlus(dims), ArmKinematicCorrectorPlus(dims)
    for k in range(6):
        diagram.get_input_port(0).FixValue(ctx, poses[k].ravel())
        diagram.get_input_port(1).FixValue(ctx, measured[k].ravel())
        diagram.get_input_port(2).FixValue(ctx, var.ravel())
        sim.AdvanceTo(0.1 * k + 0.05)
        out = diagram.get_output_port(0).Eval(ctx).reshape(12, 3)
        want = core.correct(poses[k], measured[k], var).pose
        other = blind.correct(poses[k], measured[k]).pose
        np.testing.assert_allclose(out, want, atol=1e-12, equal_nan=True)
    assert np.nanmax(np.abs(want - other)) > 1e-3


def test_akc_plus_system_scales_its_settings_to_the_camera_rate():
    """At 30 Hz the system's AKC+ is the core built for a 1/30 s frame period (:func:`~akc_drake.core.
    akc_plus_config.per_frame`), not the one with the 10 Hz settings per frame."""

    from akc_drake.core.akc_plus import ArmKinematicCorrectorPlus

    dims = BodyDimensions.paper_participant()
    poses = [frame(k) for k in range(12)]
    measured = [p.copy() for p in poses]
    for k, q in enumerate(measured):
        q[INDEX["left_wrist"], 2] += 0.01 * k  # a measurement running away from the filter's wrist
    var = np.full((12, 3), 1e-5)
    var[:, 2] = 1.5e-3
    diagram, sim, ctx = _plus_with_variance(dims, rate_hz=30.0)
    core, at_10_hz = ArmKinematicCorrectorPlus(dims, None, 1.0 / 30.0), ArmKinematicCorrectorPlus(dims)
    gap = 0.0
    for k in range(12):
        for i, v in enumerate((poses[k], measured[k], var)):
            diagram.get_input_port(i).FixValue(ctx, v.ravel())
        sim.AdvanceTo(k / 30.0 + 1.0 / 60.0)
        out = diagram.get_output_port(0).Eval(ctx).reshape(12, 3)
        want = core.correct(poses[k], measured[k], var).pose
        np.testing.assert_allclose(out, want, atol=1e-12, equal_nan=True)
        gap = max(gap, float(np.nanmax(np.abs(want - at_10_hz.correct(poses[k], measured[k], var).pose))))
    assert gap > 1e-4  # (0.14 mm here: the wrist's running NIS weighs per frame at every rate, the rest is scaled)
