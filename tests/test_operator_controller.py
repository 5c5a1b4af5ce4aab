"""OperatorController (akc_drake/systems/operator_controller.py): the closed-loop operator in a diagram, seeing
only the robot's state: it outputs the plan's posture until its delayed view of the tool's error acts, then moves
its wrist target toward where the tool should be."""

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from akc_drake.operator.closed_loop import ClosedLoopOperator
from akc_drake.operator.motions import PICK_BOX_T
from akc_drake.robot.model import add_dual_arm_robot, ee_frame, torso_frame
from akc_drake.systems.operator_controller import OperatorController


@pytest.fixture(scope="module")
def parts():
    from akc_drake.core.frames import calibrated_mapping
    from akc_drake.operator.model import OperatorParams
    from akc_drake.operator.motions import pick_place_plan

    mapping = calibrated_mapping(OperatorParams().dims)
    motion, plan = pick_place_plan(0, mapping=mapping)
    plant = MultibodyPlant(0.0)
    robot = add_dual_arm_robot(plant, weld_base=True)
    plant.Finalize()
    return ClosedLoopOperator(motion, mapping, tool_plan=plan), plant, robot


def test_the_operator_corrects_toward_the_aim_after_its_delay(parts):
    op, plant, robot = parts
    ctx = plant.CreateDefaultContext()
    x0 = plant.GetPositionsAndVelocities(ctx)
    T = torso_frame(plant, robot)
    home = ee_frame(plant, "right", robot).CalcPose(ctx, T).translation()
    # the robot sits in its home posture for 0.3 s, then its right arm moves (and stays there): it follows
    plant.GetJointByName("arm_right_4_joint").set_angle(ctx, plant.GetJointByName("arm_right_4_joint").get_angle(
        ctx) + 0.4)
    x1 = plant.GetPositionsAndVelocities(ctx)
    tool = ee_frame(plant, "right", robot).CalcPose(ctx, T).translation()
    assert np.linalg.norm(tool - home) > 0.05
    builder = DiagramBuilder()
    traj = PiecewisePolynomial.ZeroOrderHold([0.0, 0.3, 10.0], np.column_stack([x0, x1, x1]))
    src = builder.AddSystem(TrajectorySource(traj))
    ctrl = builder.AddSystem(OperatorController(op, plant, robot))
    builder.Connect(src.get_output_port(), ctrl.GetInputPort("plant_state"))
    diagram = builder.Build()
    sim = Simulator(diagram)
    q0 = ctrl.GetOutputPort("q_operator").Eval(ctrl.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_array_equal(q0, op.plan.q()[0])  # at the start: the plan's posture
    np.testing.assert_allclose(ctrl.tool_position(ctrl.GetMyContextFromRoot(sim.get_context())), home)
    sim.AdvanceTo(1.4)  # the plan rests still for 1.5 s; the tool, off the aim, stays where it moved
    t, c = ctrl.offsets()
    # nothing while the robot sat at home, nor for the delay after it moved
    assert np.all(c[t < 0.3 + op.correction.params.delay_s] == 0.0)
    aim = op.plan_tool(1.4)[0]
    direction = (aim - tool) / np.linalg.norm(aim - tool)
    assert np.linalg.norm(c[-1]) > 0.02
    assert float(c[-1] @ direction) / np.linalg.norm(c[-1]) > 0.999  # toward the aim
    q = ctrl.GetOutputPort("q_operator").Eval(ctrl.GetMyContextFromRoot(sim.get_context()))
    assert np.max(np.abs(q[5:] - op.plan.q()[0][5:])) > 0.01  # the right arm moved
    np.testing.assert_array_equal(q[:5], op.plan.q()[0][:5])


def test_in_the_teleop_diagram_the_camera_renders_the_operator_s_posture(parts):
    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import build_teleop_diagram

    op, _, _ = parts
    cfg = PipelineConfig(camera=CameraConfig(width=160, height=120))
    td = build_teleop_diagram(cfg, motion=op.plan, dims=BodyDimensions.paper_participant(), operator=op,
                              log_stages=False, keep_history=False)
    assert td.operator is not None and td.operator.get_name() == "OperatorController"
    sim = Simulator(td.diagram)
    sim.AdvanceTo(0.25)
    root = sim.get_context()
    src = next(s for s in td.diagram.GetSystems() if s.get_name() == "DepthCameraSource")
    q_in = src.GetInputPort("q_operator").Eval(src.GetMyContextFromRoot(root))
    q_out = td.operator.GetOutputPort("q_operator").Eval(td.operator.GetMyContextFromRoot(root))
    np.testing.assert_array_equal(q_in, q_out)  # the camera's operator is the controller's
    assert len(td.operator.trace) == 12  # updates at 0.01, 0.03, ..., 0.23 s
    t, tool, box = td.operator.watched()  # what it saw: the robot's tool on its way, the box where the scene has it
    np.testing.assert_allclose(t, 0.01 + 0.02 * np.arange(12))
    assert np.all(np.isfinite(tool)) and np.all(np.abs(tool) < 1.0)
    np.testing.assert_allclose(box, np.tile(box[0], (12, 1)), atol=3e-3)  # settling on the table only
    np.testing.assert_allclose(box[0, :2], PICK_BOX_T[:2], atol=0.01)
    assert 6.0 < td.operator.grasp_time() < 7.0  # the plan's hand first closes after ~6.5 s
