"""``akc-drake bench --quick``: the command runs end to end and every figure it reports is finite.

The values themselves are machine-dependent and not asserted (no timing assertions); the helpers that
compute them (statistics, timing, the atomic JSON writer, the synthetic input) are checked on known data.
"""

import json
import math

import numpy as np
import pytest

from akc_drake import bench, cli


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "bench.json"
    code = cli.main(["bench", "--quick", "--json", str(out)])
    return code, out


def test_quick_bench_writes_finite_contract_figures(quick_run, capsys):
    code, out = quick_run
    assert code == 0
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["quick"] is True
    for key in ("akc_us_per_frame", "akc_plus_us_per_frame", "kf_us_per_frame", "ekf_us_per_frame",
                "mocap_diagram_fps", "teleop_realtime_factor", "render_extract_fps", "memory_growth_pct",
                "peak_rss_mb"):
        assert _finite(data[key]), key
        if key != "memory_growth_pct":
            assert data[key] > 0, key
    assert set(data["coik_ms_per_frame"]) == {"snopt", "ipopt", "nlopt"}
    for solver, ms in data["coik_ms_per_frame"].items():
        status = data["core"]["coik_status"][solver]
        if status == "unavailable":
            assert ms is None
        else:
            assert _finite(ms) and ms > 0, solver
            assert _finite(data["coik_over_akc"][solver]) and data["coik_over_akc"][solver] > 0
            assert math.isclose(sum(status.values()), 1.0)


def test_quick_bench_reports_median_and_max_of_every_core_stage(quick_run):
    _, out = quick_run
    data = json.loads(out.read_text(encoding="utf-8"))
    for name in ("occlusion", "kf", "ekf", "akc", "akc_plus", "frames"):
        s = data["core"][name]
        assert s["n"] > 0
        assert 0 < s["median"] <= s["max"], name
        assert s["unit"] == "us"
    # Every stage system was stepped by a simulator, and the paper's Table III is reported beside ours.
    for name in ("OcclusionFilter", "LandmarkKalmanFilter(KF)", "LandmarkKalmanFilter(EKF)",
                 "ArmKinematicCorrection", "ConstrainedOptimizationIK(snopt)", "FrameMapper"):
        assert _finite(data["systems"][name]["per_frame_us"]) and data["systems"][name]["per_frame_us"] > 0
    stages = {row["stage"]: row for row in data["paper_table3_ms"]}
    assert stages["AKC"]["paper_I"] == pytest.approx(11.03)
    assert _finite(stages["AKC"]["ours"]["median"])
    assert data["machine"]["drake"]
    mem = data["memory"]
    assert len(mem["rss_mb"]["t_s"]) == len(mem["rss_mb"]["rss"]) >= 3
    assert all(_finite(v) and v > 0 for v in mem["rss_mb"]["rss"])
    assert set(data["targets"]) >= {"akc_us_per_frame", "mocap_diagram_fps", "memory_growth_pct"}


def test_quick_bench_prints_the_report(quick_run, capsys):
    # The fixture ran in another test; run the formatter on its JSON-equivalent output instead of re-running.
    _, out = quick_run
    data = json.loads(out.read_text(encoding="utf-8"))
    text = bench.format_report(data)
    assert "core: AKC" in text and "Table III" in text and "teleop" in text
    assert "skinned operator: skinning" in text


def test_quick_bench_measures_the_skinned_operator(quick_run):
    _, out = quick_run
    data = json.loads(out.read_text(encoding="utf-8"))
    sk = data["skinned"]
    assert sk["available"] is True and sk["points"] > 10000
    assert _finite(data["skinning_ms_per_frame"]) and data["skinning_ms_per_frame"] > 0
    assert data["targets"]["skinning_ms_per_frame"]["target"] == "<= 2"
    if sk.get("mediapipe", {}).get("available", True):
        assert _finite(data["skinned_mediapipe_fps"]) and sk["frames"] >= 3
        assert 0.0 <= sk["person_found_share"] <= 1.0


def test_summarize_median_max_and_nan_handling():
    s = bench.summarize([3.0, 1.0, 2.0, float("nan"), 10.0], "us")
    assert s["median"] == 2.5 and s["max"] == 10.0 and s["n"] == 4 and s["mean"] == 4.0
    empty = bench.summarize([], "ms")
    assert empty["n"] == 0 and math.isnan(empty["median"])


def test_time_calls_runs_every_input_each_pass_after_warmup():
    seen = []
    resets = []
    ns = bench.time_calls(seen.append, [1, 2, 3], repeats=2, warmup=2, before_pass=lambda: resets.append(1))
    assert ns.shape == (6,) and np.all(ns >= 0)
    assert seen == [1, 2, 1, 2, 3, 1, 2, 3]
    assert len(resets) == 3


def test_write_json_atomic_replaces_and_maps_nan_to_null(tmp_path):
    p = tmp_path / "sub" / "b.json"
    bench.write_json_atomic(p, {"a": np.float64(1.5), "b": float("nan"), "c": np.arange(2)})
    bench.write_json_atomic(p, {"a": 2.0, "b": [np.int64(3)]})
    assert json.loads(p.read_text()) == {"a": 2.0, "b": [3]}
    assert [f.name for f in p.parent.iterdir()] == ["b.json"]
    bench.write_json_atomic(p, {"x": float("inf")})
    assert json.loads(p.read_text()) == {"x": None}


def test_synthetic_measurements_are_the_truth_plus_bounded_noise_and_occlusion():
    inp = bench.synthetic_measurements(cycles=1, seed=3).run_stages()
    assert inp.raw.shape == inp.truth.shape == (inp.num_frames, 12, 3)
    assert inp.dt == pytest.approx(0.1)
    err_xy = np.abs(inp.raw[..., :2] - inp.truth[..., :2])
    assert np.all(err_xy < 0.05)  # 10 sigma of 5 mm
    # The occlusion filter rejected something (dropouts) and the KF estimate is finite after the first frame.
    assert np.isnan(inp.accepted).any()
    assert np.all(np.isfinite(inp.kf[5:]))
    # AKC output keeps the calibrated arm lengths.
    lf = np.linalg.norm(inp.akc[:, 2] - inp.akc[:, 4], axis=-1)
    np.testing.assert_allclose(lf, inp.dims.LLA, atol=1e-9)


def test_bench_rejects_a_folder_as_json(tmp_path, capsys):
    assert cli.main(["bench", "--quick", "--json", str(tmp_path)]) == 2
    assert "is a folder" in capsys.readouterr().err
