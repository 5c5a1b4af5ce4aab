import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from akc_drake.core.skeleton import ARM_JOINTS, BodyDimensions
from akc_drake.errors import UserError
from akc_drake.evaluation.motion_set import (
    evaluate_clip,
    find_clips,
    lost_joint_gain,
    motion_dir_tables,
    plot_errors_per_clip,
    pooled,
    worst_regression,
)

DATA = Path(__file__).parent / "data" / "mocap"


def test_find_clips_from_files_and_from_a_manifest(tmp_path):
    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")
    shutil.copy(DATA / "tiny.amc", tmp_path / "b.amc")
    shutil.copy(DATA / "tiny.asf", tmp_path / "b.asf")
    clips = find_clips(tmp_path)
    assert [c["name"] for c in clips] == ["a", "b"]
    assert clips[1]["skeleton"].endswith("b.asf")
    (tmp_path / "mocap_sources.json").write_text(json.dumps(
        {"clips": [{"name": "w", "file": "a.bvh", "window_s": [0.0, 0.5]}]}))
    clips = find_clips(tmp_path)
    assert clips == [{"name": "w", "path": str(tmp_path / "a.bvh"), "skeleton": None, "window_s": [0.0, 0.5],
                      "names": None, "activity": ""}]
    with pytest.raises(UserError, match="no such folder"):
        find_clips(tmp_path / "nope")
    (tmp_path / "mocap_sources.json").write_text(json.dumps({"clips": [{"name": "x", "file": "gone.bvh"}]}))
    with pytest.raises(UserError, match="missing"):
        find_clips(tmp_path)


def _result():
    clip = {"name": "ub", "path": str(DATA / "upper_body.bvh"), "skeleton": None, "window_s": None, "names": None}
    dims = BodyDimensions.paper_participant().as_dict()
    methods = ["KF", "AKC(KF)", "AKC+(KF)"]
    r = evaluate_clip({"clip": clip, "dims": dims, "methods": methods, "seed": 3, "protocol": "ours"})
    json.dumps(r)  # plain data
    assert set(r["methods"]) == set(methods)
    for m in methods:
        for j in ARM_JOINTS:
            rm = r["methods"][m]["rmse_cm"][j]
            sse, n = r["methods"][m]["sse_m2"][j], r["methods"][m]["n"][j]
            np.testing.assert_allclose(rm, np.sqrt(np.array(sse) / np.array(n)) * 100.0)
    rng = r["methods"]["AKC+(KF)"]["arm_length_range_cm"]
    assert max(rng.values()) < 1e-3
    pool = pooled([r, r], methods)
    for j in ARM_JOINTS:
        np.testing.assert_allclose(pool["KF"][j], r["methods"]["KF"]["rmse_cm"][j])
    w = worst_regression([r], "AKC+(KF)", "KF")
    assert w["clip"] == "ub" and np.isfinite(w["delta_cm"])
    g = lost_joint_gain([r], "AKC+(KF)", "KF")
    assert g["pairs"] >= 0
    result = {"protocol": "ours", "methods": methods, "clips": [r], "pooled_rmse_cm": pool,
              "worst_regression": {"AKC+(KF)": w}, "lost_joint_gain": {"AKC+(KF)": g}}
    tables = motion_dir_tables(result)
    assert [t.key for t in tables] == ["clips_x", "clips_y", "clips_z", "pooled"]
    assert tables[-1].ours.shape == (18, 3)
    return result


def test_evaluate_clip_returns_plain_metrics_and_pooling_is_exact():
    assert _result()["clips"][0]["name"] == "ub"


def test_plot_errors_per_clip(tmp_path):
    result = _result()
    path = plot_errors_per_clip(result, tmp_path / "fig.png")
    assert path.stat().st_size > 1000
