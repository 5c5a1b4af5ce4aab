"""FrameSourceSystem: a frame source stepped through a Drake simulation."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import NUM_LANDMARKS
from akc_drake.errors import SourceError
from akc_drake.io.recording import RecordingWriter
from akc_drake.io.sources import RecordingSource
from akc_drake.systems.frame_source import AddFrameSource, FrameSourceState, FrameSourceSystem

K = CameraIntrinsics(width=16, height=12, fx=15.0, fy=15.0, cx=7.5, cy=5.5, depth_scale=0.001, rate_hz=10.0)


def _images(n, seed=0):
    rng = np.random.default_rng(seed)
    colors = [rng.integers(0, 256, (12, 16, 3), dtype=np.uint8) for _ in range(n)]
    depths = [rng.integers(0, 4000, (12, 16)) * 0.001 for _ in range(n)]
    return colors, depths


@pytest.fixture
def recording(tmp_path):
    colors, depths = _images(4)
    truths = [np.arange(3 * NUM_LANDMARKS, dtype=float).reshape(NUM_LANDMARKS, 3) + 100 * i for i in range(4)]
    with RecordingWriter(tmp_path / "rec", K) as w:
        for i in range(4):
            w.write(0.1 * i, colors[i], depths[i], truths[i])
    return RecordingSource(tmp_path / "rec"), colors, depths, truths


def _build(source, **kw):
    builder = DiagramBuilder()
    sys_ = AddFrameSource(builder, source, **kw)
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.Initialize()
    return sys_, diagram, sim


def _outputs(sys_, diagram, sim):
    ctx = sys_.GetMyContextFromRoot(sim.get_context())
    return {
        "color": sys_.GetOutputPort("color_image").Eval(ctx).data.copy(),
        "depth": sys_.GetOutputPort("depth_image").Eval(ctx).data.copy(),
        "label": sys_.GetOutputPort("label_image").Eval(ctx).data.copy(),
        "info": sys_.GetOutputPort("camera_info").Eval(ctx),
        "truth": sys_.GetOutputPort("landmarks_true_C").Eval(ctx).copy(),
        "finished": float(sys_.GetOutputPort("finished").Eval(ctx)[0]),
        "index": int(sys_.GetOutputPort("frame_index").Eval(ctx)[0]),
    }


def test_steps_through_a_recording(recording):
    source, colors, depths, truths = recording
    sys_, diagram, sim = _build(source)
    assert sys_.period_s == pytest.approx(0.1)
    out = _outputs(sys_, diagram, sim)
    assert out["index"] == -1 and out["finished"] == 0.0 and np.isnan(out["truth"]).all()
    assert not out["color"][..., :3].any()
    for k in range(4):
        sim.AdvanceTo(0.1 * k + 0.05)
        out = _outputs(sys_, diagram, sim)
        assert out["index"] == k
        assert out["color"].shape == (12, 16, 4)
        assert np.array_equal(out["color"][..., :3], colors[k])
        assert np.all(out["color"][..., 3] == 255)
        assert out["depth"].dtype == np.float32 and out["depth"].shape == (12, 16, 1)
        np.testing.assert_allclose(out["depth"][..., 0], depths[k], rtol=0, atol=1e-6)
        assert out["label"].dtype == np.int16 and not out["label"].any()
        assert out["info"] == K
        np.testing.assert_array_equal(out["truth"], truths[k].ravel())
        assert out["finished"] == 0.0
    # past the end: holds the last frame and says it is finished
    sim.AdvanceTo(1.0)
    out = _outputs(sys_, diagram, sim)
    assert out["finished"] == 1.0 and out["index"] == 3
    assert np.array_equal(out["color"][..., :3], colors[3])
    assert sys_.error is None


def test_random_access_source_replays_in_a_new_simulation(recording):
    source, colors, _, _ = recording
    sys_, diagram, sim = _build(source)
    sim.AdvanceTo(0.25)
    assert _outputs(sys_, diagram, sim)["index"] == 2
    sim2 = Simulator(diagram)
    sim2.AdvanceTo(0.05)
    out = _outputs(sys_, diagram, sim2)
    assert out["index"] == 0 and np.array_equal(out["color"][..., :3], colors[0])
    assert sys_.error is None


class _ListSource:
    """An in-order-only source (like a live camera) that can fail at a given frame."""

    def __init__(self, frames, fail_at=None, rate_hz=10.0):
        self.frames, self.fail_at, self.rate_hz, self.intrinsics = frames, fail_at, rate_hz, K
        self.pulled = 0

    def __iter__(self):
        for i, f in enumerate(self.frames):
            if i == self.fail_at:
                raise SourceError("camera unplugged")
            self.pulled += 1
            yield f

    def close(self):
        pass


def _camera_frames(n):
    colors, depths = _images(n, seed=5)
    return [CameraFrame(colors[i], depths[i], 0.1 * i, K) for i in range(n)], colors


def test_in_order_source_and_no_truth():
    frames, colors = _camera_frames(3)
    src = _ListSource(frames)
    sys_, diagram, sim = _build(src, period_s=0.05)
    sim.AdvanceTo(0.12)  # updates at 0, 0.05, 0.10
    out = _outputs(sys_, diagram, sim)
    assert out["index"] == 2 and np.array_equal(out["color"][..., :3], colors[2])
    assert np.isnan(out["truth"]).all()
    assert src.pulled == 3
    sim.AdvanceTo(0.5)
    assert _outputs(sys_, diagram, sim)["finished"] == 1.0
    assert sys_.error is None
    # an in-order source cannot be rewound by a second simulation: recorded, not raised
    sim2 = Simulator(diagram)
    sim2.AdvanceTo(0.01)
    assert isinstance(sys_.error, SourceError) and "cannot go back to frame 0" in str(sys_.error)
    assert _outputs(sys_, diagram, sim2)["finished"] == 1.0


def test_source_error_mid_run_is_recorded_and_held():
    frames, colors = _camera_frames(5)
    sys_, diagram, sim = _build(_ListSource(frames, fail_at=2))
    sim.AdvanceTo(0.65)  # must not raise
    out = _outputs(sys_, diagram, sim)
    assert isinstance(sys_.error, SourceError) and str(sys_.error) == "camera unplugged"
    assert out["finished"] == 1.0 and out["index"] == 1
    assert np.array_equal(out["color"][..., :3], colors[1])


def test_bad_frame_size_is_recorded():
    frames, _ = _camera_frames(2)
    frames[1] = CameraFrame(np.zeros((5, 5, 3), np.uint8), np.zeros((5, 5)), 0.1, K)
    sys_, diagram, sim = _build(_ListSource(frames))
    sim.AdvanceTo(0.3)
    assert isinstance(sys_.error, SourceError) and "frame 1: color must be uint8 (12, 16, 3)" in str(
        sys_.error
    )
    assert _outputs(sys_, diagram, sim)["index"] == 0


def test_nan_depth_becomes_zero():
    frames, _ = _camera_frames(1)
    frames[0].depth_m[0, 0] = np.nan
    sys_, diagram, sim = _build(_ListSource(frames))
    sim.AdvanceTo(0.01)
    assert _outputs(sys_, diagram, sim)["depth"][0, 0, 0] == 0.0


def test_rejects_what_is_not_a_source():
    with pytest.raises(ValueError, match="source.intrinsics must be a CameraIntrinsics"):
        FrameSourceSystem([1, 2, 3])
    with pytest.raises(ValueError, match="period_s must be a positive number"):
        FrameSourceSystem(_ListSource([]), period_s=0.0)


def test_ports_and_state_type(recording):
    source = recording[0]
    s = FrameSourceSystem(source)
    names = [s.get_output_port(i).get_name() for i in range(s.num_output_ports())]
    assert names == [
        "color_image",
        "depth_image",
        "label_image",
        "camera_info",
        "landmarks_true_C",
        "finished",
        "frame_index",
    ]
    assert s.num_input_ports() == 0
    ctx = s.CreateDefaultContext()
    assert isinstance(ctx.get_abstract_state(0).get_value(), FrameSourceState)
    assert s.GetOutputPort("landmarks_true_C").size() == 36
