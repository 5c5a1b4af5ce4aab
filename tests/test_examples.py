"""The examples/ folder: your own corrector as a LeafSystem in the mocap diagram (examples/own_leaf_system.py)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from akc_drake.config import PipelineConfig
from akc_drake.core.metrics import arm_length_range
from akc_drake.core.skeleton import INDEX

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_your_leaf_system_replaces_stage_s4_frame_for_frame():
    # The system reads the filter's output of the same frame (its update is offset to the corrector's stage) and
    # the loggers record it as the corrected stage: frame k of "corrected" is the corrector applied to frame k of
    # "estimated", the lengths exact, the filter's shoulders kept.
    ex = _load("own_leaf_system")
    mocap = ex.build(PipelineConfig(motion="I", cycles=1, filter="KF"))
    assert mocap.config.corrector == "none" and mocap.systems["corrector"].get_name() == "SegmentLengthsSystem"
    log, _ = mocap.simulate()
    assert log.corrected.shape == log.estimated.shape == (mocap.num_frames, 12, 3)
    want = ex._segment_lengths()(mocap.dims, "KF", 0.1)
    arms = [INDEX[f"{s}_{j}"] for s in ("left", "right") for j in ("shoulder", "elbow", "wrist")]
    ok = np.isfinite(log.estimated[:, arms]).all(axis=(1, 2))
    assert ok.sum() > 0.8 * len(ok)
    for k in np.flatnonzero(ok):
        np.testing.assert_array_equal(log.corrected[k], want.correct(log.estimated[k]))
    assert max(arm_length_range(log.corrected[ok]).values()) < 1e-12
    ls = INDEX["left_shoulder"]
    np.testing.assert_array_equal(log.corrected[ok][:, ls], log.estimated[ok][:, ls])
    # Not the identity: the elbows and wrists move.
    assert np.nanmax(np.abs(log.corrected[ok] - log.estimated[ok])) > 0.01


def test_the_example_runs_as_a_script(capsys):
    pytest.importorskip("akc_drake.systems.depth_camera_source")
    _load("own_leaf_system").main()
    out = capsys.readouterr().out
    assert "61 frames" in out and out.count("left_wrist") == 2
