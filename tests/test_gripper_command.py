"""HandApertureSource and GripperCommand (akc_drake.systems.gripper_command) in a small diagram."""

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from akc_drake.core.gripper import OPEN_HAND_APERTURE_M, PINCH_APERTURE_M, GripperHysteresis
from akc_drake.operator.motions import OperatorMotion
from akc_drake.systems.gripper_command import GripperCommand, HandApertureSource


def _motion():
    t = np.arange(0.0, 2.01, 0.01)
    closed = np.column_stack([np.zeros_like(t), (t >= 1.0).astype(float)])  # the right hand closes at 1 s
    q = np.zeros((len(t), 5))
    return OperatorMotion(t, q, q, "pinch", hand_closed=closed)


def test_the_right_gripper_closes_when_the_right_hand_pinches():
    builder = DiagramBuilder()
    hands = builder.AddSystem(HandApertureSource(_motion(), 0.1, seed=0, noise_m=0.0))
    cmd = builder.AddSystem(GripperCommand(0.1, 0.004))
    builder.Connect(hands.get_output_port(), cmd.GetInputPort("thumb_index_m"))
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    cctx = cmd.GetMyContextFromRoot(ctx)
    hctx = hands.GetMyContextFromRoot(ctx)
    h = GripperHysteresis()
    sim.AdvanceTo(0.55)
    np.testing.assert_allclose(hands.get_output_port().Eval(hctx), [OPEN_HAND_APERTURE_M] * 2)
    np.testing.assert_array_equal(cmd.GetOutputPort("closed").Eval(cctx), [0.0, 0.0])
    assert cmd.GetOutputPort("right_opening").Eval(cctx)[0] == h.open_m
    sim.AdvanceTo(1.25)
    np.testing.assert_allclose(hands.get_output_port().Eval(hctx), [OPEN_HAND_APERTURE_M, PINCH_APERTURE_M])
    np.testing.assert_array_equal(cmd.GetOutputPort("closed").Eval(cctx), [0.0, 1.0])
    assert cmd.GetOutputPort("right_opening").Eval(cctx)[0] == h.closed_m
    assert cmd.GetOutputPort("left_opening").Eval(cctx)[0] == h.open_m


def test_dropped_frames_are_nan_and_keep_the_gripper():
    mask = np.zeros(21, dtype=bool)
    mask[12:] = True  # the person is lost from 1.2 s on
    builder = DiagramBuilder()
    hands = builder.AddSystem(HandApertureSource(_motion(), 0.1, seed=0, noise_m=0.0, dropout=mask))
    cmd = builder.AddSystem(GripperCommand(0.1, 0.004))
    builder.Connect(hands.get_output_port(), cmd.GetInputPort("thumb_index_m"))
    sim = Simulator(builder.Build())
    sim.AdvanceTo(1.85)
    ctx = sim.get_context()
    assert np.all(np.isnan(hands.get_output_port().Eval(hands.GetMyContextFromRoot(ctx))))
    np.testing.assert_array_equal(cmd.GetOutputPort("closed").Eval(cmd.GetMyContextFromRoot(ctx)), [0.0, 1.0])


def test_the_hand_channel_counts_frames_from_any_start_time():
    """A run recorded after others starts at t0 > 0: frame k is still the motion at k periods from its start."""
    builder = DiagramBuilder()
    hands = builder.AddSystem(HandApertureSource(_motion(), 0.1, seed=0, noise_m=0.0))
    sim = Simulator(builder.Build())
    sim.get_mutable_context().SetTime(40.0)
    sim.AdvanceTo(40.55)
    out = hands.get_output_port().Eval(hands.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_allclose(out, [OPEN_HAND_APERTURE_M] * 2)
    sim.AdvanceTo(41.25)
    out = hands.get_output_port().Eval(hands.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_allclose(out, [OPEN_HAND_APERTURE_M, PINCH_APERTURE_M])


def test_measured_apertures_are_replayed_and_a_missing_hand_keeps_the_gripper():
    """A hand detector's measurements (NaN: the hand not found) replace the simulated channel."""
    ap = np.full((12, 2), 0.10)
    ap[4:9, 1] = 0.015  # the right hand pinches in frames 4-8 ...
    ap[6:8, 1] = np.nan  # ... and is lost in frames 6 and 7: the gripper stays closed
    ap[3:6, 0] = np.nan  # the open left hand lost: stays open
    builder = DiagramBuilder()
    hands = builder.AddSystem(HandApertureSource(_motion(), 0.1, apertures=ap))
    cmd = builder.AddSystem(GripperCommand(0.1, 0.004))
    builder.Connect(hands.get_output_port(), cmd.GetInputPort("thumb_index_m"))
    sim = Simulator(builder.Build())
    closed = []
    for k in range(12):
        sim.AdvanceTo(k * 0.1 + 0.05)
        ctx = sim.get_context()
        np.testing.assert_array_equal(hands.get_output_port().Eval(hands.GetMyContextFromRoot(ctx)), ap[k])
        closed.append(cmd.GetOutputPort("closed").Eval(cmd.GetMyContextFromRoot(ctx)).copy())
    closed = np.array(closed)
    np.testing.assert_array_equal(closed[:, 0], 0.0)
    np.testing.assert_array_equal(closed[:, 1], [0, 0, 0, 0, 1, 1, 1, 1, 1, 0, 0, 0])
