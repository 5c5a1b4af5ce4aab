"""HandApertureDetector (akc_drake.systems.hand_aperture): a hand detector on each camera frame, in a diagram."""

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS
from akc_drake.io.hand_detector import HandMeasurement
from akc_drake.systems.gripper_command import GripperCommand
from akc_drake.systems.hand_aperture import HandApertureDetector


class _FakeHands:
    """Answers with a pinch on the right hand from frame 3 on, the left hand never found; records its inputs."""

    def __init__(self):
        self.calls = []

    def detect(self, frame, wrists=None):
        self.calls.append((frame.t, frame.color.shape, float(frame.depth_m[0, 0]), wrists))
        m = HandMeasurement.empty()
        m.found[1] = True
        m.aperture_m[1] = 0.015 if len(self.calls) > 3 else 0.1
        return m


def _diagram(K, with_pixels):
    builder = DiagramBuilder()
    det = _FakeHands()
    hands = builder.AddSystem(HandApertureDetector(det, K, 0.1, 0.001))
    color = ImageRgba8U(K.width, K.height)
    depth = ImageDepth32F(K.width, K.height)
    depth.mutable_data[:] = 1.5
    c = builder.AddSystem(ConstantValueSource(AbstractValue.Make(color)))
    d = builder.AddSystem(ConstantValueSource(AbstractValue.Make(depth)))
    builder.Connect(c.get_output_port(), hands.GetInputPort("color_image"))
    builder.Connect(d.get_output_port(), hands.GetInputPort("depth_image"))
    if with_pixels:
        px = np.arange(2 * NUM_LANDMARKS, dtype=float)
        p = builder.AddSystem(ConstantVectorSource(px))
        builder.Connect(p.get_output_port(), hands.GetInputPort("pixels"))
    cmd = builder.AddSystem(GripperCommand(0.1, 0.004))
    builder.Connect(hands.GetOutputPort("thumb_index_m"), cmd.GetInputPort("thumb_index_m"))
    return builder.Build(), det, hands, cmd


def test_measures_each_frame_and_the_gripper_follows():
    K = CameraIntrinsics(width=64, height=48)
    diagram, det, hands, cmd = _diagram(K, with_pixels=False)
    sim = Simulator(diagram)
    sim.AdvanceTo(0.25)
    ctx = sim.get_context()
    hctx = hands.GetMyContextFromRoot(ctx)
    # three frames (t = 0, 0.1, 0.2, at the 1 ms offset), each the whole RGB image and the depth
    assert [round(c[0], 3) for c in det.calls] == [0.001, 0.101, 0.201]
    assert det.calls[0][1:] == ((48, 64, 3), 1.5, None)
    out = hands.GetOutputPort("thumb_index_m").Eval(hctx)
    assert np.isnan(out[0]) and out[1] == 0.1
    np.testing.assert_array_equal(hands.GetOutputPort("hands_found").Eval(hctx), [0.0, 1.0])
    np.testing.assert_array_equal(cmd.GetOutputPort("closed").Eval(cmd.GetMyContextFromRoot(ctx)), [0.0, 0.0])
    sim.AdvanceTo(0.45)
    np.testing.assert_array_equal(cmd.GetOutputPort("closed").Eval(cmd.GetMyContextFromRoot(sim.get_context())),
                                  [0.0, 1.0])


def test_the_pose_wrists_are_passed_when_connected():
    K = CameraIntrinsics(width=64, height=48)
    diagram, det, _, _ = _diagram(K, with_pixels=True)
    Simulator(diagram).AdvanceTo(0.05)
    wrists = det.calls[0][3]
    px = np.arange(2 * NUM_LANDMARKS, dtype=float).reshape(NUM_LANDMARKS, 2)
    np.testing.assert_array_equal(wrists, px[[LANDMARKS.index("left_wrist"), LANDMARKS.index("right_wrist")]])


def test_the_teleop_diagram_takes_the_hands_from_the_camera_or_a_replay():
    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import Measurements, build_teleop_diagram
    from akc_drake.operator.motions import pick_place

    cfg = PipelineConfig(camera=CameraConfig(width=160, height=120))
    motion = pick_place(0)
    dims = BodyDimensions.paper_participant()
    names = lambda td: {s.get_name() for s in td.diagram.GetSystems()}  # noqa: E731
    # rendered frames: the hand detector looks at the camera's images
    td = build_teleop_diagram(cfg, motion=motion, dims=dims, hand_detector=_FakeHands(), log_stages=False)
    assert "HandApertureDetector" in names(td) and "HandApertureSource" not in names(td)
    # replayed frames: the measured apertures are replayed
    n = 5
    meas = Measurements(np.zeros((n, NUM_LANDMARKS, 3)), np.ones((n, NUM_LANDMARKS)), np.zeros((n, NUM_LANDMARKS, 2)))
    ap = np.tile([0.1, 0.015], (n, 1))
    td = build_teleop_diagram(cfg, replay=meas, motion=motion, dims=dims, hand_apertures=ap, log_stages=False)
    assert "HandApertureSource" in names(td) and "HandApertureDetector" not in names(td)
    src = next(s for s in td.diagram.GetSystems() if s.get_name() == "HandApertureSource")
    ctx = td.diagram.CreateDefaultContext()
    np.testing.assert_array_equal(src.get_output_port().Eval(src.GetMyContextFromRoot(ctx)), [0.1, 0.015])


def test_the_rendered_teleop_run_gives_the_hand_detector_the_frame_and_its_pose_wrists():
    """In the teleop diagram the hand detector runs after the extractor, on the same frame, with its wrists."""
    from pydrake.systems.analysis import Simulator

    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import build_teleop_diagram
    from akc_drake.operator.motions import pick_place

    cfg = PipelineConfig(camera=CameraConfig(width=160, height=120))
    det = _FakeHands()
    td = build_teleop_diagram(cfg, motion=pick_place(0), dims=BodyDimensions.paper_participant(), hand_detector=det,
                              log_stages=False, keep_history=False)
    sim = Simulator(td.diagram)
    sim.AdvanceTo(0.15)
    assert [round(c[0], 3) for c in det.calls] == [0.002, 0.102]
    assert det.calls[0][1] == (120, 160, 3)
    ext = td.ports.pixels
    px = ext.Eval(ext.get_system().GetMyContextFromRoot(sim.get_context())).reshape(NUM_LANDMARKS, 2)
    np.testing.assert_array_equal(det.calls[1][3], px[[LANDMARKS.index("left_wrist"), LANDMARKS.index("right_wrist")]])


class _KnuckleHands(_FakeHands):
    """The right hand found with its index knuckle 40 px right of and 10 px above its pinky knuckle."""

    def detect(self, frame, wrists=None):
        m = super().detect(frame, wrists)
        h = np.zeros((21, 3))
        h[5], h[17] = (100.0, 50.0, -4.0), (60.0, 60.0, 0.0)
        m.landmarks_px[1] = h
        return m


def test_the_knuckle_lines_go_out_and_to_the_frame_mapper():
    """Hands' knuckle line of each found hand is an output (NaN for a hand not found), and in the rendered teleop
    diagram it feeds the FrameMapper's wrist frames (before, the closed loop's wrist frames had only the pose's
    two hand points)."""
    from akc_drake.config import CameraConfig, PipelineConfig
    from akc_drake.core.control_frames import hands_knuckle_vector
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.diagrams import build_teleop_diagram
    from akc_drake.operator.motions import pick_place

    K = CameraIntrinsics(width=64, height=48)
    builder = DiagramBuilder()
    hands = builder.AddSystem(HandApertureDetector(_KnuckleHands(), K, 0.1, 0.001))
    for name, img in (("color_image", ImageRgba8U(64, 48)), ("depth_image", ImageDepth32F(64, 48))):
        src = builder.AddSystem(ConstantValueSource(AbstractValue.Make(img)))
        builder.Connect(src.get_output_port(), hands.GetInputPort(name))
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(0.05)
    out = hands.GetOutputPort("hand_knuckles").Eval(hands.GetMyContextFromRoot(sim.get_context()))
    assert np.all(np.isnan(out[:3]))
    h = np.zeros((21, 3))
    h[5], h[17] = (100.0, 50.0, -4.0), (60.0, 60.0, 0.0)
    np.testing.assert_allclose(out[3:], hands_knuckle_vector(h, K))
    np.testing.assert_allclose(out[3:], [40.0 / K.fx, -10.0 / K.fy, -4.0 / K.fx])

    cfg = PipelineConfig(camera=CameraConfig(width=160, height=120))
    td = build_teleop_diagram(cfg, motion=pick_place(0), dims=BodyDimensions.paper_participant(),
                              hand_detector=_KnuckleHands(), log_stages=False, keep_history=False)
    sim = Simulator(td.diagram)
    sim.AdvanceTo(0.15)
    mapper = td.mapper
    seen = mapper.GetInputPort("hand_knuckles").Eval(mapper.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_allclose(seen[3:], hands_knuckle_vector(h, td.intrinsics))
