"""Tests of the OcclusionFilter LeafSystem (stage S3a)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from akc_drake.core.occlusion import occlusion_filter
from akc_drake.core.skeleton import INDEX, NUM_LANDMARKS
from akc_drake.systems.measurement_replay import MeasurementReplay
from akc_drake.systems.occlusion_filter import AddOcclusionFilter, OcclusionFilter


def frame(seed=0):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.5, 0.5, (NUM_LANDMARKS, 3)) * [1.0, 1.0, 0.5] + [0, 0, 2]  # (a body's depths: within 0.5 m)
    pixels = np.array([[30.0 + 50.0 * j, 240.0] for j in range(NUM_LANDMARKS)])
    vis = np.full(NUM_LANDMARKS, 0.9)
    pixels[INDEX["right_elbow"]] = pixels[INDEX["right_wrist"]] + [10.0, 10.0]  # occluded elbow
    vis[INDEX["left_hip"]] = 0.3  # low visibility
    return points, pixels, vis


def test_ports_names_and_sizes():
    system = OcclusionFilter(640)
    assert [system.get_input_port(i).get_name() for i in range(3)] == ["landmarks_C", "visibility", "pixels"]
    assert [system.get_input_port(i).size() for i in range(3)] == [36, 12, 24]
    assert [system.get_output_port(i).get_name() for i in range(2)] == ["landmarks_C_accepted", "rejected"]
    assert [system.get_output_port(i).size() for i in range(2)] == [36, 24]
    # stateless, direct feedthrough from every input to every output
    context = system.CreateDefaultContext()
    assert context.num_total_states() == 0
    for i in range(3):
        for o in range(2):
            assert system.HasDirectFeedthrough(i, o)


def test_outputs_equal_the_core_function():
    points, pixels, vis = frame()
    system = OcclusionFilter(640, visibility_threshold=0.7, proximity=0.05)
    context = system.CreateDefaultContext()
    system.GetInputPort("landmarks_C").FixValue(context, points.reshape(-1))
    system.GetInputPort("visibility").FixValue(context, vis)
    system.GetInputPort("pixels").FixValue(context, pixels.reshape(-1))
    accepted = system.GetOutputPort("landmarks_C_accepted").Eval(context).reshape(NUM_LANDMARKS, 3)
    flags = system.GetOutputPort("rejected").Eval(context)
    expected, info = occlusion_filter(points, pixels, vis, 640)
    np.testing.assert_array_equal(accepted, expected)
    np.testing.assert_array_equal(flags[:12], info.rejected.astype(float))
    np.testing.assert_array_equal(flags[12:], info.depth_dropped.astype(float))
    # the hand-made cases really happened
    assert np.isnan(accepted[INDEX["left_hip"]]).all() and flags[INDEX["left_hip"]] == 1.0
    assert np.isnan(accepted[INDEX["right_elbow"], 2]) and flags[12 + INDEX["right_elbow"]] == 1.0
    np.testing.assert_array_equal(accepted[INDEX["right_elbow"], :2], points[INDEX["right_elbow"], :2])
    assert flags.sum() == 2.0
    # parameters reach the core: a smaller radius keeps the elbow's depth, a low threshold the hip
    loose = OcclusionFilter(640, visibility_threshold=0.2, proximity=0.01)
    c2 = loose.CreateDefaultContext()
    loose.GetInputPort("landmarks_C").FixValue(c2, points.reshape(-1))
    loose.GetInputPort("visibility").FixValue(c2, vis)
    loose.GetInputPort("pixels").FixValue(c2, pixels.reshape(-1))
    np.testing.assert_array_equal(loose.GetOutputPort("landmarks_C_accepted").Eval(c2), points.reshape(-1))


def test_a_depth_read_on_the_background_is_dropped_unless_the_check_is_off():
    points, pixels, vis = frame()
    le = INDEX["left_elbow"]
    points[le] *= 3.6 / points[le, 2]  # (the wall 1.5 m behind the shoulder and the wrist)
    for margin, dropped in ((0.6, True), (None, False), (2.0, False)):
        system = OcclusionFilter(640, background_m=margin)
        context = system.CreateDefaultContext()
        for name, value in (("landmarks_C", points), ("visibility", vis), ("pixels", pixels)):
            system.GetInputPort(name).FixValue(context, value.reshape(-1))
        flags = system.GetOutputPort("rejected").Eval(context)
        accepted = system.GetOutputPort("landmarks_C_accepted").Eval(context).reshape(NUM_LANDMARKS, 3)
        assert flags[12 + le] == float(dropped) and np.isnan(accepted[le, 2]) == dropped
    for bad in (-0.5, 0.0, "0.6"):  # (refused as the core function refuses them, before anything is declared)
        with pytest.raises(ValueError, match="background_m"):
            OcclusionFilter(640, background_m=bad)


def test_a_hip_read_on_a_hand_in_front_of_it_is_dropped_unless_the_check_is_off():
    # The hips level at 2 m; the right hand 45 cm in front, 8 cm across the right hip's ray, and the hip reading it.
    points = np.array([[0.1 * j - 0.6, 0.05 * j - 0.4, 2.0] for j in range(NUM_LANDMARKS)])
    rh, lh, rw = INDEX["right_hip"], INDEX["left_hip"], INDEX["right_wrist"]
    points[lh], points[rh] = [0.1, 0.45, 2.0], [-0.08, 0.45, 2.0]
    points[rw] = np.array([-0.08, 0.45, 2.0]) * 1.55 / 2.0 + [0.08, 0.0, 0.0]
    points[rh] *= 1.55 / 2.0  # (the same pixel, read on the hand)
    vis = np.full(NUM_LANDMARKS, 0.95)
    for reach, dropped in ((0.12, True), (None, False), (0.05, False)):
        system = OcclusionFilter(640, hand_reach_m=reach)
        context = system.CreateDefaultContext()
        system.GetInputPort("landmarks_C").FixValue(context, points.reshape(-1))
        system.GetInputPort("visibility").FixValue(context, vis)
        flags = system.GetOutputPort("rejected").Eval(context)
        assert flags[12:].tolist() == [float(dropped and i == rh) for i in range(NUM_LANDMARKS)]
    assert OcclusionFilter(640).hand_reach_m == 0.12
    for bad in (-0.5, 0.0, "0.12"):
        with pytest.raises(ValueError, match="hand_reach_m"):
            OcclusionFilter(640, hand_reach_m=bad)


def test_unconnected_visibility_and_pixels_pass_landmarks_through():
    points, _, _ = frame()
    points[3] = np.nan
    system = OcclusionFilter(640)
    context = system.CreateDefaultContext()
    system.GetInputPort("landmarks_C").FixValue(context, points.reshape(-1))
    out = system.GetOutputPort("landmarks_C_accepted").Eval(context)
    np.testing.assert_array_equal(out, points.reshape(-1))
    np.testing.assert_array_equal(system.GetOutputPort("rejected").Eval(context), np.zeros(24))


def test_add_helper_wires_a_diagram():
    points, pixels, vis = frame(1)
    builder = DiagramBuilder()
    src_l = builder.AddSystem(ConstantVectorSource(points.reshape(-1)))
    src_v = builder.AddSystem(ConstantVectorSource(vis))
    src_p = builder.AddSystem(ConstantVectorSource(pixels.reshape(-1)))
    occ = AddOcclusionFilter(
        builder, src_l.get_output_port(), src_v.get_output_port(), src_p.get_output_port(), image_width=640
    )
    builder.ExportOutput(occ.GetOutputPort("landmarks_C_accepted"), "accepted")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    out = diagram.GetOutputPort("accepted").Eval(context).reshape(NUM_LANDMARKS, 3)
    np.testing.assert_array_equal(out, occlusion_filter(points, pixels, vis, 640)[0])
    assert occ.get_name() == "OcclusionFilter"


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((0,), {}, "image_width"),
        ((640,), {"visibility_threshold": -0.1}, "visibility_threshold"),
        ((640,), {"proximity": float("inf")}, "proximity"),
    ],
)
def test_bad_parameters(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        OcclusionFilter(*args, **kwargs)


def test_with_a_period_it_holds_the_last_accepted_depths_as_the_core_function_over_the_sequence():
    # Three frames: the right elbow seen, then hidden behind its wrist (its depth read on the forearm 40 cm in
    # front, x, y deprojected there: 2.0 / 2.4 of the joint's), then seen again.
    period, e = 0.1, INDEX["right_elbow"]
    points, pixels, vis = frame(2)
    P = np.repeat(points[None], 3, axis=0)
    X = np.repeat(pixels[None], 3, axis=0)
    V = np.repeat(vis[None], 3, axis=0)
    joint = np.array([0.3, -0.2, 2.4])
    P[:, e] = joint
    P[1, e] = joint * 2.0 / 2.4
    X[[0, 2], e] = X[[0, 2], INDEX["right_wrist"]] + [0.0, 150.0]  # apart in frames 0 and 2
    builder = DiagramBuilder()
    src = builder.AddSystem(MeasurementReplay(P, V, X, period_s=period))
    occ = AddOcclusionFilter(builder, src.GetOutputPort("landmarks_C"), src.GetOutputPort("visibility"),
                             src.GetOutputPort("pixels"), image_width=640, period_s=period)
    stateless = AddOcclusionFilter(builder, src.GetOutputPort("landmarks_C"), src.GetOutputPort("visibility"),
                                   src.GetOutputPort("pixels"), image_width=640, name="stateless")
    diagram = builder.Build()
    assert occ.CreateDefaultContext().num_discrete_state_groups() == 1
    assert stateless.CreateDefaultContext().num_total_states() == 0
    sim = Simulator(diagram)
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    for k in range(3):
        sim.AdvanceTo(k * period + 0.005)  # after the replay's and the filter's updates of frame k
        root = sim.get_context()
        out = occ.GetOutputPort("landmarks_C_accepted").Eval(occ.GetMyContextFromRoot(root)).reshape(-1, 3)
        expected, info = occlusion_filter(P[k], X[k], V[k], 640, held=held)
        np.testing.assert_array_equal(out, expected)
        flat = stateless.GetOutputPort("landmarks_C_accepted").Eval(stateless.GetMyContextFromRoot(root))
        np.testing.assert_array_equal(flat.reshape(-1, 3), occlusion_filter(P[k], X[k], V[k], 640)[0])
        if k == 1:
            assert info.depth_dropped[e]
            np.testing.assert_allclose(out[e, :2], joint[:2], rtol=1e-12)  # back on the joint, not 5 cm short
            np.testing.assert_allclose(flat.reshape(-1, 3)[e, :2], P[1, e, :2])
    np.testing.assert_array_equal(
        occ.GetMyContextFromRoot(sim.get_context()).get_discrete_state(0).get_value(), held.reshape(-1))


def test_hold_rays_off_keeps_the_deprojected_x_y_and_a_bad_period_is_refused():
    points, pixels, vis = frame()
    e = INDEX["right_elbow"]
    for hold, expect in ((False, points[e, :2]), (True, points[e, :2] * 3.0 / points[e, 2])):
        system = OcclusionFilter(640, period_s=0.1, hold_rays=hold)
        context = system.CreateDefaultContext()
        context.SetDiscreteState(0, np.full(3 * NUM_LANDMARKS, 3.0))
        system.GetInputPort("landmarks_C").FixValue(context, points.reshape(-1))
        system.GetInputPort("visibility").FixValue(context, vis)
        system.GetInputPort("pixels").FixValue(context, pixels.reshape(-1))
        out = system.GetOutputPort("landmarks_C_accepted").Eval(context).reshape(-1, 3)
        np.testing.assert_allclose(out[e, :2], expect, rtol=1e-12)
    for bad in (0.0, -1.0, float("inf")):
        with pytest.raises(ValueError, match="period_s"):
            OcclusionFilter(640, period_s=bad)


def test_one_run_of_the_core_filter_serves_both_outputs_and_the_update(monkeypatch):
    import akc_drake.systems.occlusion_filter as module

    calls = []
    real = module.occlusion_filter
    monkeypatch.setattr(module, "occlusion_filter", lambda *a, **k: calls.append(1) or real(*a, **k))
    points, pixels, vis = frame()
    system = OcclusionFilter(640, period_s=0.1)
    context = system.CreateDefaultContext()
    for name, value in (("landmarks_C", points), ("visibility", vis), ("pixels", pixels)):
        system.GetInputPort(name).FixValue(context, value.reshape(-1))
    accepted = system.GetOutputPort("landmarks_C_accepted").Eval(context)
    flags = system.GetOutputPort("rejected").Eval(context)
    state = system.EvalUniquePeriodicDiscreteUpdate(context)
    assert len(calls) == 1
    held = np.full((NUM_LANDMARKS, 3), np.nan)
    expected, info = real(points, pixels, vis, 640, held=held)
    np.testing.assert_array_equal(accepted, expected.reshape(-1))
    np.testing.assert_array_equal(flags, np.concatenate((info.rejected, info.depth_dropped)).astype(float))
    np.testing.assert_array_equal(state.get_vector(0).get_value(), held.reshape(-1))
    # a new input is a new run
    system.GetInputPort("landmarks_C").FixValue(context, (points + 0.01).reshape(-1))
    system.GetOutputPort("landmarks_C_accepted").Eval(context)
    assert len(calls) == 2
