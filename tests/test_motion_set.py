import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from akc_drake.core.skeleton import ARM_JOINTS, INDEX, BodyDimensions
from akc_drake.errors import UserError
from akc_drake.evaluation.motion_set import evaluate_clip, find_clips, motion_dir_tables, plot_errors_per_clip
from akc_drake.evaluation.set_metrics import (
    lost_frames,
    lost_joint_gain,
    paired_errors,
    pooled,
    worst_regression,
    worst_regression_3d,
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


def test_the_held_out_windows_are_the_unused_parts_of_the_sets_takes(tmp_path):
    # data/mocap_windows lists parts of the takes that data/mocap's clips window (the files `make mocap-data`
    # fetches): every file is one of the set's, no window overlaps a set clip's window of the same take, and a
    # clip on the Blender rig carries the same name map as the set's clip of that take.
    repo = Path(__file__).resolve().parents[1]
    windows = json.loads((repo / "data" / "mocap_windows" / "mocap_sources.json").read_text())["clips"]
    manifest = json.loads((repo / "akc_drake" / "data" / "mocap_sources.json").read_text())
    sources = {c["file"]: c for c in manifest["clips"]}
    used: dict[str, list] = {}
    for c in manifest["clips"]:
        if c.get("window_s"):
            used.setdefault(c["file"], []).append(c["window_s"])
    assert len({w["name"] for w in windows}) == len(windows) == 4
    for w in windows:
        f = Path(w["file"])
        assert f.parent == Path("../mocap") and f.name in sources
        a, b = w["window_s"]
        assert 0 <= a < b
        assert all(b <= u0 or a >= u1 for u0, u1 in used[f.name])
        assert w.get("names") == sources[f.name].get("names")
    # Found through the folder's manifest: the files resolve next to it, or the error names the fix.
    d = tmp_path / "mocap_windows"
    d.mkdir()
    shutil.copy(repo / "data" / "mocap_windows" / "mocap_sources.json", d)
    with pytest.raises(UserError, match="make mocap-data"):
        find_clips(d)
    (tmp_path / "mocap").mkdir()
    for name in {Path(w["file"]).name for w in windows}:
        shutil.copy(DATA / "upper_body.bvh", tmp_path / "mocap" / name)
    assert [Path(c["path"]).resolve() for c in find_clips(d)] == [
        (tmp_path / "mocap" / Path(w["file"]).name).resolve() for w in windows]



@pytest.mark.parametrize("manifest", ["mocap_heldout_sources.json", "mocap_heldout2_sources.json",
                                      "mocap_heldout3_sources.json"])
def test_a_held_out_set_pins_archives_and_shares_no_recording_with_the_others(manifest):
    # data/mocap_heldout*_sources.json (make mocap-heldout, mocap-heldout2, mocap-heldout3): each package an archive
    # at a URL with its SHA-256 and a licence; its clips none of the other sets' files (by digest) nor names, nor
    # packages; a clip's file name is unique, so that the fetcher writes each once.
    repo = Path(__file__).resolve().parents[1]
    held = json.loads((repo / "data" / manifest).read_text())
    others = [json.loads((repo / "akc_drake" / "data" / "mocap_sources.json").read_text())]
    others += [json.loads(f.read_text()) for f in sorted((repo / "data").glob("mocap_heldout*_sources.json"))
               if f.name != manifest]
    for pkg in held["packages"].values():
        assert pkg["url"].startswith("https://") and len(pkg["archive_sha256"]) == 64 and pkg["licence"]
    clips = held["clips"]
    assert len({c["file"] for c in clips}) == len({c["name"] for c in clips}) == len(clips) >= 2
    assert all(c["package"] in held["packages"] and len(c["sha256"]) == 64 for c in clips)
    for other in others:
        assert not {c["sha256"] for c in clips} & {c["sha256"] for c in other["clips"]}
        assert not {c["name"] for c in clips} & {c["name"] for c in other["clips"]}
        assert not set(held["packages"]) & set(other["packages"])


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
    assert w["clip"] == "ub" and np.isfinite(w["delta_cm"]) and w["paired"]
    for m in ("AKC(KF)", "AKC+(KF)"):
        p = r["methods"][m]["paired"]
        assert p["filter"] == "KF"
        for j in ARM_JOINTS:  # the paired frames and the corrector's own frames make up its frames
            np.testing.assert_array_equal(np.add(p["n"][j], p["only_n"][j]), r["methods"][m]["n"][j])
    assert "paired" not in r["methods"]["KF"]
    ws = worst_regression([r], "AKC+(KF)", "KF", frames="seen")
    assert ws["clip"] == "ub" and np.isfinite(ws["delta_cm"])
    for j in ARM_JOINTS:  # the seen frames are some of the paired frames
        assert np.all(np.less_equal(r["methods"]["AKC+(KF)"]["paired"]["seen_n"][j],
                                    r["methods"]["AKC+(KF)"]["paired"]["n"][j]))
    g = lost_joint_gain([r], "AKC+(KF)", "KF")
    assert g["pairs"] >= 0
    result = {"protocol": "ours", "methods": methods, "clips": [r], "pooled_rmse_cm": pool,
              "worst_regression": {"AKC+(KF)": w}, "lost_joint_gain": {"AKC+(KF)": g}}
    tables = motion_dir_tables(result)
    assert [t.key for t in tables] == ["clips_x", "clips_y", "clips_z", "pooled"]
    assert tables[-1].ours.shape == (18, 3)
    return result


def test_a_corrector_is_compared_with_its_filter_on_the_frames_both_estimate():
    # The filter has no estimate of the left shoulder's depth in the first two frames (never measured); the
    # corrector rebuilds it there, 10 cm off, and is 1 cm better than the filter on the other frames.
    T = 6
    truth = np.zeros((T, 12, 3))
    base = truth.copy()
    base[:] = 0.02
    base[:2, INDEX["left_shoulder"], 2] = np.nan
    est = truth.copy()
    est[:] = 0.01
    est[:2, INDEX["left_shoulder"], 2] = 0.10
    p = paired_errors(est, base, truth, "KF")
    assert p["n"]["left_shoulder"] == [6, 6, 4] and p["only_n"]["left_shoulder"] == [0, 0, 2]
    np.testing.assert_allclose(p["rmse_cm"]["left_shoulder"], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(p["filter_rmse_cm"]["left_shoulder"], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(p["only_rmse_cm"]["left_shoulder"][2], 10.0)
    assert np.isnan(p["only_rmse_cm"]["left_elbow"][2])

    def clip(paired):
        own = {k: [1.0, 1.0, 1.0] for k in ARM_JOINTS}
        own["left_shoulder"] = [1.0, 1.0, float(np.sqrt((4 * 1.0 + 2 * 100.0) / 6))]  # 5.83 over its own frames
        m = {"rmse_cm": own}
        if paired:
            m["paired"] = p
        kf = {"rmse_cm": {k: [2.0, 2.0, 2.0] for k in ARM_JOINTS}}
        lost = {k: 0.0 for k in ARM_JOINTS}
        lost["left_shoulder"] = 2 / 6
        return {"name": "c", "lost_share": lost, "methods": {"AKC+(KF)": m, "KF": kf}}

    w = worst_regression([clip(True)], "AKC+(KF)", "KF")
    assert w["paired"] and w["delta_cm"] == pytest.approx(-1.0)
    w = worst_regression([clip(False)], "AKC+(KF)", "KF")  # a result from before: each method's own frames
    assert not w["paired"] and w["delta_cm"] == pytest.approx(np.sqrt(204 / 6) - 2.0)
    assert (w["clip"], w["joint"], w["axis"]) == ("c", "left_shoulder", "z")
    g = lost_joint_gain([clip(True)], "AKC+(KF)", "KF")
    assert g["pairs"] == 1 and g["filter_z_cm"] == pytest.approx(2.0) and g["corrected_z_cm"] == pytest.approx(1.0)
    assert g["only_frames"] == 2 and g["only_z_cm"] == pytest.approx(10.0)
    g = lost_joint_gain([clip(False)], "AKC+(KF)", "KF")
    assert g["only_frames"] is None and g["corrected_z_cm"] == pytest.approx(np.sqrt(204 / 6))


def test_the_seen_frames_separate_the_easy_case_from_a_lost_joints_guess():
    # The left elbow is lost on frames 0-2 (its depth failed the occlusion filter): there the corrector's guess is
    # 10 cm off in z and the filter's drift 4 cm. On the frames it is seen the corrector is 1 cm off and the
    # filter 2 cm. The right wrist is seen throughout, and the corrector moves it 3 cm on the last two frames.
    T = 6
    truth = np.zeros((T, 12, 3))
    base = np.full((T, 12, 3), 0.02)
    est = np.full((T, 12, 3), 0.01)
    le, rw = INDEX["left_elbow"], INDEX["right_wrist"]
    base[:3, le, 2], est[:3, le, 2] = 0.04, 0.10
    est[4:, rw, 0] = 0.03
    seen = np.ones((T, 12), bool)
    seen[:3, le] = False
    p = paired_errors(est, base, truth, "KF", seen=seen)
    assert p["seen_n"]["left_elbow"] == [3, 3, 3] and p["n"]["left_elbow"] == [6, 6, 6]
    np.testing.assert_allclose(p["seen_rmse_cm"]["left_elbow"], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(p["seen_filter_rmse_cm"]["left_elbow"], [2.0, 2.0, 2.0])
    np.testing.assert_allclose(p["seen_rmse_cm"]["right_wrist"][0], math.sqrt((4 * 1 + 2 * 9) / 6))
    # The lost frames are the other paired ones: the left elbow's frames 0-2, none of the right wrist's.
    assert p["lost_n"]["left_elbow"] == [3, 3, 3] and p["lost_n"]["right_wrist"] == [0, 0, 0]
    np.testing.assert_allclose(p["lost_rmse_cm"]["left_elbow"], [1.0, 1.0, 10.0])
    np.testing.assert_allclose(p["lost_filter_rmse_cm"]["left_elbow"], [2.0, 2.0, 4.0])
    lost = {k: 0.0 for k in ARM_JOINTS}
    lost["left_elbow"] = 0.5
    r = {"name": "c", "lost_share": lost,
         "methods": {"AKC+(KF)": {"rmse_cm": p["rmse_cm"], "paired": p}, "KF": {"rmse_cm": p["filter_rmse_cm"]}}}
    w = worst_regression([r], "AKC+(KF)", "KF")
    assert (w["joint"], w["axis"]) == ("left_elbow", "z")
    assert w["delta_cm"] == pytest.approx(math.sqrt((300 + 3) / 6) - math.sqrt((48 + 12) / 6))
    ws = worst_regression([r], "AKC+(KF)", "KF", frames="seen")
    assert (ws["joint"], ws["axis"]) == ("right_wrist", "x")
    assert ws["delta_cm"] == pytest.approx(math.sqrt(22 / 6) - 2.0)
    w3 = worst_regression_3d([r], "AKC+(KF)", "KF", frames="seen")
    assert w3["joint"] == "right_wrist" and w3["delta_cm"] == pytest.approx(math.sqrt(22 / 6 + 2) - math.sqrt(12))
    # On its lost frames the guess is 6 cm worse in z and 1 cm better in x and y; no joint without lost frames
    # counts (the right wrist, 0 of them), so the largest 3D increase is the elbow's.
    wl = worst_regression([r], "AKC+(KF)", "KF", frames="lost")
    assert (wl["joint"], wl["axis"]) == ("left_elbow", "z") and wl["delta_cm"] == pytest.approx(6.0)
    wl3 = worst_regression_3d([r], "AKC+(KF)", "KF", frames="lost")
    assert wl3["joint"] == "left_elbow" and wl3["delta_cm"] == pytest.approx(math.sqrt(102) - math.sqrt(24))
    assert wl3["frames"] == 3 and ws["frames"] == 6 and "frames" not in w
    lf = lost_frames([r], "AKC+(KF)", "KF")
    assert (lf["frames"], lf["pairs"], lf["pairs_worse_3d"]) == (3, 1, 1)
    assert lf["corrected_3d_cm"] == pytest.approx(math.sqrt(102)) and lf["filter_3d_cm"] == pytest.approx(math.sqrt(24))
    # A joint never seen, or a result recorded without the mask, is left out of the seen figures.
    seen[:, :] = False
    seen[:, rw] = True
    p2 = paired_errors(est, base, truth, "KF", seen=seen)
    assert p2["seen_n"]["left_elbow"] == [0, 0, 0]
    r["methods"]["AKC+(KF)"]["paired"] = p2
    ws2 = worst_regression([r], "AKC+(KF)", "KF", frames="seen")
    assert ws2["joint"] == "right_wrist" and ws2["delta_cm"] == pytest.approx(ws["delta_cm"])
    del r["methods"]["AKC+(KF)"]["paired"]
    assert worst_regression([r], "AKC+(KF)", "KF", frames="seen") == {"delta_cm": -math.inf}
    with pytest.raises(ValueError, match="frames must be"):
        worst_regression([r], "AKC+(KF)", "KF", frames="unseen")
    result = {"protocol": "ours", "methods": ["KF", "AKC+(KF)"], "clips": [r],
              "pooled_rmse_cm": {"KF": p["filter_rmse_cm"], "AKC+(KF)": p["rmse_cm"]},
              "worst_regression": {"AKC+(KF)": w}, "worst_regression_seen": {"AKC+(KF)": ws},
              "worst_regression_seen_3d": {"AKC+(KF)": w3}, "worst_regression_lost_3d": {"AKC+(KF)": wl3},
              "lost_joint_gain": {"AKC+(KF)": lost_joint_gain([r], "AKC+(KF)", "KF")},
              "lost_frames": {"AKC+(KF)": lf}}
    notes = motion_dir_tables(result)[-1].notes
    assert ("AKC+(KF): worst increase over its filter on the frames the joint was seen (depth passed the "
            "occlusion filter) -0.09 cm (c, right_wrist x, 6 frames)") in notes
    assert ("AKC+(KF): worst 3D increase over its filter on the frames the joint was lost (depth dropped or not "
            f"measured) {math.sqrt(102) - math.sqrt(24):+.2f} cm (c, left_elbow, 3 frames)") in notes
    assert ("AKC+(KF): 3D RMSE over the 3 joint-frames an arm joint was lost: filter 4.90 -> 10.10 cm; worse on 1 "
            "of 1 (clip, joint) pairs") in notes


def test_the_3d_figures_weigh_a_trade_of_one_axis_for_the_others():
    # A lost joint whose corrector is 2 cm worse in z and 6 cm better in y: the worst per-axis increase is +2 cm, the
    # 3D RMSE (the root of the three axes' mean squared errors) falls from sqrt(1 + 64 + 9) to sqrt(1 + 4 + 25).
    def clip(name, ls_corr, ls_filt):
        corr = {k: [1.0, 1.0, 1.0] for k in ARM_JOINTS}
        filt = {k: [1.0, 1.0, 1.0] for k in ARM_JOINTS}
        corr["left_shoulder"], filt["left_shoulder"] = ls_corr, ls_filt
        lost = {k: 0.0 for k in ARM_JOINTS}
        lost["left_shoulder"] = 0.5
        return {"name": name, "lost_share": lost,
                "methods": {"AKC+(EKF)": {"rmse_cm": corr}, "EKF": {"rmse_cm": filt}}}

    clips = [clip("a", [1.0, 2.0, 5.0], [1.0, 8.0, 3.0]), clip("b", [1.0, 1.0, 1.5], [1.0, 1.0, 1.0])]
    w = worst_regression(clips, "AKC+(EKF)", "EKF")
    assert (w["clip"], w["joint"], w["axis"]) == ("a", "left_shoulder", "z") and w["delta_cm"] == pytest.approx(2.0)
    w3 = worst_regression_3d(clips, "AKC+(EKF)", "EKF")
    assert (w3["clip"], w3["joint"]) == ("b", "left_shoulder")
    assert w3["delta_cm"] == pytest.approx(math.sqrt(4.25) - math.sqrt(3.0))
    g = lost_joint_gain(clips, "AKC+(EKF)", "EKF")
    assert g["pairs"] == 2
    assert g["filter_3d_cm"] == pytest.approx((math.sqrt(74.0) + math.sqrt(3.0)) / 2)
    assert g["corrected_3d_cm"] == pytest.approx((math.sqrt(30.0) + math.sqrt(4.25)) / 2)
    result = {"protocol": "ours", "methods": ["EKF", "AKC+(EKF)"], "clips": clips,
              "pooled_rmse_cm": {m: clips[0]["methods"][m]["rmse_cm"] for m in ("EKF", "AKC+(EKF)")},
              "worst_regression": {"AKC+(EKF)": w}, "worst_regression_3d": {"AKC+(EKF)": w3},
              "lost_joint_gain": {"AKC+(EKF)": g}}
    notes = motion_dir_tables(result)[-1].notes
    assert "AKC+(EKF): worst 3D RMSE increase over its filter +0.33 cm (b, left_shoulder)" in notes
    assert any(n.endswith("filter 2.00 -> 3.25 cm; 3D 5.17 -> 3.77") for n in notes)


def test_evaluate_clip_returns_plain_metrics_and_pooling_is_exact():
    assert _result()["clips"][0]["name"] == "ub"


def test_plot_errors_per_clip(tmp_path):
    result = _result()
    path = plot_errors_per_clip(result, tmp_path / "fig.png")
    assert path.stat().st_size > 1000


def _tables_bytes(result):
    return [(t.key, t.ours.tobytes()) for t in motion_dir_tables(result)]


def test_motion_dir_renders_each_clip_once_through_the_cache(tmp_path):
    from akc_drake.evaluation.cache import spec_key
    from akc_drake.evaluation.motion_set import clip_spec, evaluate_motion_dir

    clips = tmp_path / "clips"
    clips.mkdir()
    shutil.copy(DATA / "upper_body.bvh", clips / "a.bvh")
    text = (DATA / "upper_body.bvh").read_text()
    (clips / "b.bvh").write_text(text.replace("Frame Time: 0.025", "Frame Time: 0.05"))  # another clip
    cache = tmp_path / "cache"
    kw = dict(methods=["KF", "AKC+(KF)"], seed=2, protocol="ours", cache=cache, progress=False, tpose_seconds=1.0)

    def entries():
        return sorted(p.name for p in (cache / "renders").rglob("*.npz"))

    first = evaluate_motion_dir(clips, **kw)
    assert first["failures"] == []
    assert first["render_cache"] == {"dir": str(cache), "hits": 0, "misses": 3}  # the T-pose and two clips
    stored = entries()
    assert len(stored) == 3
    second = evaluate_motion_dir(clips, **kw)
    assert second["render_cache"]["hits"] == 3 and second["render_cache"]["misses"] == 0
    assert entries() == stored
    assert [c["render"]["cached"] for c in second["clips"]] == [True, True]
    assert _tables_bytes(first) == _tables_bytes(second)  # bit for bit
    assert json.dumps(first["pooled_rmse_cm"]) == json.dumps(second["pooled_rmse_cm"])

    # The key is the clip's content, not its path or modification time; the body and detector are in it.
    clip = find_clips(clips)[0]
    key = spec_key(clip_spec(clip, seed=2, protocol="ours"))
    assert first["clips"][0]["render"]["key"] == key
    moved = tmp_path / "elsewhere.bvh"
    shutil.copy(clips / "a.bvh", moved)
    assert spec_key(clip_spec({**clip, "path": str(moved)}, seed=2, protocol="ours")) == key
    keys = {key}
    for other in (dict(seed=3, protocol="ours"), dict(seed=2, protocol="paper"),
                  dict(seed=2, protocol="ours", body="skinned"), dict(seed=2, protocol="ours", detector="mediapipe"),
                  dict(seed=2, protocol="ours", width=320, height=240), dict(seed=2, protocol="ours", rate_hz=30.0)):
        keys.add(spec_key(clip_spec(clip, **other)))
    assert len(keys) == 7
    assert spec_key(clip_spec({**clip, "window_s": [0.0, 0.05]}, seed=2, protocol="ours")) != key
    (clips / "a.bvh").write_text(text.replace("Frame Time: 0.025", "Frame Time: 0.0250"))
    assert spec_key(clip_spec(clip, seed=2, protocol="ours")) != key
    third = evaluate_motion_dir(clips, **kw)
    assert third["render_cache"]["hits"] == 2 and third["render_cache"]["misses"] == 1  # only the edited clip
    assert len(entries()) == 4


def test_the_clips_are_retargeted_at_the_camera_rate(tmp_path):
    """``--rate-hz`` with ``--motion-dir``: each clip is the file's own motion sampled at the camera's rate (not
    10 Hz samples interpolated), and the T-pose, the filters and AKC+ run at that rate too."""
    from akc_drake.evaluation.cache import _motion_of
    from akc_drake.evaluation.motion_set import clip_spec, evaluate_motion_dir, tpose_spec
    from akc_drake.operator.retarget import load_motion_file

    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")  # 5 frames at 40 Hz: 0.1 s
    clip = find_clips(tmp_path)[0]
    for rate in (10.0, 30.0):
        motion = _motion_of(clip_spec(clip, seed=0, protocol="ours", rate_hz=rate))
        ref = load_motion_file(tmp_path / "a.bvh", rate_hz=rate)
        np.testing.assert_allclose(np.diff(motion.times), 1.0 / rate, rtol=1e-12)
        np.testing.assert_array_equal(motion.q_left, ref.q_left)
        np.testing.assert_array_equal(motion.q_right, ref.q_right)
    assert tpose_spec(rate_hz=30.0)["intrinsics"]["rate_hz"] == 30.0
    r = evaluate_motion_dir(tmp_path, methods=["KF", "AKC+(KF)"], seed=0, protocol="ours", cache=False,
                            progress=False, tpose_seconds=1.0, rate_hz=30.0)
    assert r["failures"] == [] and r["rate_hz"] == 30.0
    assert r["clips"][0]["frames"] == 4  # t = 0, 1/30, 2/30, 0.1 s (2 frames at 10 Hz)
    titles = [t.title for t in motion_dir_tables(r)]
    assert titles and all(t.endswith("(ours protocol, 30 Hz)") for t in titles), titles
    with pytest.raises(ValueError, match=r"intrinsics\.rate_hz must be a positive number, got 0\.0"):
        evaluate_motion_dir(tmp_path, methods=["KF"], cache=False, progress=False, rate_hz=0.0)


def test_a_placed_camera_renders_the_clips_and_the_t_pose_from_where_it_stands(tmp_path):
    """``--camera`` with ``--motion-dir``: the T-pose and every clip are rendered from the placed camera (their own
    render-cache keys), the result and the tables' titles name it, and the calibration from 3 m gives the same arm
    lengths within the farther camera's depth noise."""
    from akc_drake.config import parse_camera
    from akc_drake.evaluation.cache import spec_key
    from akc_drake.evaluation.motion_set import clip_spec, evaluate_motion_dir

    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")
    far = parse_camera("distance_m=3,height_m=0.6")
    clip = find_clips(tmp_path)[0]
    assert spec_key(clip_spec(clip, camera=far)) != spec_key(clip_spec(clip))
    kw = dict(methods=["KF", "AKC+(KF)"], seed=0, protocol="ours", cache=False, progress=False, tpose_seconds=1.0)
    level = evaluate_motion_dir(tmp_path, **kw)
    placed = evaluate_motion_dir(tmp_path, camera=far, **kw)
    assert level["camera"] == "default" and placed["camera"] == far and placed["failures"] == []
    for seg in ("LUA", "LLA", "RUA", "RLA"):
        assert placed["dims_cm"][seg] == pytest.approx(level["dims_cm"][seg], abs=1.5), seg
    titles = [t.title for t in motion_dir_tables(placed)]
    assert titles and all(t.endswith("(ours protocol, camera 3 m in front, 0.6 m above the pelvis, level)")
                          for t in titles), titles
    with pytest.raises(ValueError, match="unknown camera 'far'"):
        evaluate_motion_dir(tmp_path, camera="far", **kw)
    # A smaller operator (--body-scale): its T-pose calibrates its own, shorter arms.
    small = evaluate_motion_dir(tmp_path, body_scale=0.8, **kw)
    assert small["body_scale"] == 0.8 and level["body_scale"] == 1.0 and small["failures"] == []
    for seg in ("LUA", "LLA", "RUA", "RLA"):
        assert small["dims_cm"][seg] == pytest.approx(0.8 * level["dims_cm"][seg], abs=1.0), seg
    assert all(t.title.endswith("(ours protocol, the operator scaled 0.8)") for t in motion_dir_tables(small))
    with pytest.raises(ValueError, match="body scale"):
        evaluate_motion_dir(tmp_path, body_scale=2.0, **kw)
    # A noisier depth camera (--depth-noise): recorded, in the titles, and its readings scatter more.
    noisy_model = {"sigma_disparity_px": 0.3, "correlation_px": 4.0}
    noisy = evaluate_motion_dir(tmp_path, depth_noise=noisy_model, **kw)
    assert noisy["depth_noise"] == noisy_model and level["depth_noise"] == "default" and noisy["failures"] == []
    assert all(t.title.endswith("(ours protocol, depth noise sigma_disparity_px=0.3, correlation_px=4)")
               for t in motion_dir_tables(noisy))
    assert noisy["pooled_rmse_cm"]["KF"] != level["pooled_rmse_cm"]["KF"]
    with pytest.raises(ValueError, match="unknown field.*loud"):
        evaluate_motion_dir(tmp_path, depth_noise={"loud": 1.0}, **kw)


def test_a_bad_clip_fails_alone(tmp_path, capsys):
    from akc_drake.evaluation.motion_set import evaluate_motion_dir

    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")
    (tmp_path / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    r = evaluate_motion_dir(tmp_path, methods=["KF"], seed=0, protocol="ours", cache=False, progress=True,
                            tpose_seconds=1.0)
    err = capsys.readouterr().err
    assert "T-pose: " in err and "11frame" in err.replace(" ", "")  # the T-pose's 11 frames
    assert "  a: 0frame" in err  # in-process: a bar over the clip's frames (cleared when it ends)
    assert [c["name"] for c in r["clips"]] == ["a"]
    assert len(r["failures"]) == 1 and r["failures"][0].startswith("broken:") and "\n" not in r["failures"][0]
    assert r["render_cache"] == {"dir": None, "hits": 0, "misses": 2}


def test_motion_dir_command_options(tmp_path, capsys):
    from akc_drake.cli import main as cli_main

    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")
    base = ["evaluate", "--motion-dir", str(tmp_path), "--scheduler", "inprocess"]
    assert cli_main(base + ["--detector", "both"]) == 2
    assert "--detector both: not with --motion-dir" in capsys.readouterr().err
    assert cli_main(base + ["--workers", "0"]) == 2
    assert "--workers must be at least 1" in capsys.readouterr().err
    assert cli_main(base + ["--camera", "distance_m=0.1"]) == 2
    assert "--camera: distance_m must be more than 0.3 m" in capsys.readouterr().err
    assert cli_main(base + ["--body-scale", "2"]) == 2
    assert "--body-scale: body scale must be a number from 0.6 to 1.4, got 2.0" in capsys.readouterr().err
    assert cli_main(base + ["--akc-plus", "nope=1"]) == 2
    assert "--akc-plus: unknown AKC+ setting(s) 'nope'" in capsys.readouterr().err
    example = Path(__file__).resolve().parents[1] / "examples" / "segment_lengths.py"
    assert cli_main(base + ["--add-corrector", f"LEN={example}"]) == 2
    assert "--add-corrector: corrector" in capsys.readouterr().err
    assert cli_main(base + ["--add-corrector", f"LEN={example}:SegmentLengths", "--methods", "KF,AKC+(KF)"]) == 2
    assert "--add-corrector LEN: --methods 'KF,AKC+(KF)' runs none of it" in capsys.readouterr().err
    assert cli_main(base + ["--methods", "KF,LEN(KF)"]) == 2
    assert "unknown method 'LEN(KF)'" in capsys.readouterr().err


def test_your_own_corrector_on_the_motion_set_from_the_command_line(tmp_path, monkeypatch):
    # --add-corrector adds NAME(KF) and NAME(EKF) to the default methods; the worst increases, the seen and lost
    # figures are computed for it as for AKC+; the name and path are recorded. On two local workers (which load
    # the file themselves) the numbers are the same.
    from akc_drake.cli import main as cli_main
    from akc_drake.evaluation.motion_set import evaluate_motion_dir

    monkeypatch.setenv("AKC_DRAKE_CACHE", str(tmp_path / "cache"))
    clips = tmp_path / "clips"
    clips.mkdir()
    shutil.copy(DATA / "upper_body.bvh", clips / "a.bvh")
    example = Path(__file__).resolve().parents[1] / "examples" / "segment_lengths.py"
    out = tmp_path / "r.json"
    assert cli_main(["evaluate", "--motion-dir", str(clips), "--scheduler", "inprocess", "--protocol", "ours",
                     "--add-corrector", f"LEN={example}:SegmentLengths", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["correctors"] == {"LEN": f"{example}:SegmentLengths"}
    assert r["methods"][-2:] == ["LEN(KF)", "LEN(EKF)"] and "AKC+(EKF)" in r["methods"]
    for key in ("worst_regression", "worst_regression_seen", "worst_regression_lost_3d", "lost_frames"):
        assert set(r[key]) == {"AKC(KF)", "AKC(EKF)", "AKC+(KF)", "AKC+(EKF)", "LEN(KF)", "LEN(EKF)"}
    clip = r["clips"][0]["methods"]
    assert clip["LEN(KF)"]["paired"]["filter"] == "KF"
    assert max(clip["LEN(KF)"]["arm_length_range_cm"].values()) < 1e-9
    assert clip["LEN(KF)"]["sse_m2"] != clip["KF"]["sse_m2"]
    there = evaluate_motion_dir(clips, methods=["KF", "LEN(KF)"], protocol="ours", scheduler="local", n_workers=2,
                                progress=False, correctors={"LEN": f"{example}:SegmentLengths"})
    assert json.dumps(there["clips"][0]["methods"]["LEN(KF)"]["sse_m2"]) == json.dumps(clip["LEN(KF)"]["sse_m2"])


def test_motion_dir_same_numbers_in_process_and_on_two_local_workers(tmp_path):
    from akc_drake.evaluation.motion_set import evaluate_motion_dir

    shutil.copy(DATA / "upper_body.bvh", tmp_path / "a.bvh")
    text = (DATA / "upper_body.bvh").read_text()
    (tmp_path / "b.bvh").write_text(text.replace("Frame Time: 0.025", "Frame Time: 0.05"))
    kw = dict(methods=["KF", "AKC+(KF)"], seed=1, protocol="paper", cache=tmp_path / "cache", progress=False,
              tpose_seconds=1.0)
    here = evaluate_motion_dir(tmp_path, scheduler="inprocess", **kw)
    there = evaluate_motion_dir(tmp_path, scheduler="local", n_workers=2, **kw)
    assert there["render_cache"]["hits"] == 3  # the workers read what the first run stored
    assert _tables_bytes(here) == _tables_bytes(there)
    for a, b in zip(here["clips"], there["clips"], strict=True):
        for m in kw["methods"]:
            assert json.dumps(a["methods"][m]["sse_m2"]) == json.dumps(b["methods"][m]["sse_m2"])
    # AKC+ settings (--akc-plus) cross to the workers as plain data, are recorded, and change AKC+ alone.
    tuned = {"gate_sigma": 1.0, "constrained_filter": True}
    tuned_here = evaluate_motion_dir(tmp_path, scheduler="inprocess", akc_plus=tuned, **kw)
    tuned_there = evaluate_motion_dir(tmp_path, scheduler="local", n_workers=2, akc_plus=tuned, **kw)
    assert tuned_here["akc_plus"] == tuned_there["akc_plus"] == tuned and here["akc_plus"] is None
    assert _tables_bytes(tuned_here) == _tables_bytes(tuned_there) != _tables_bytes(here)
    pairs = list(zip(here["clips"], tuned_there["clips"], strict=True))
    assert all(json.dumps(a["methods"]["KF"]["sse_m2"]) == json.dumps(b["methods"]["KF"]["sse_m2"]) for a, b in pairs)
    assert any(json.dumps(a["methods"]["AKC+(KF)"]["sse_m2"]) != json.dumps(b["methods"]["AKC+(KF)"]["sse_m2"])
               for a, b in pairs)
    with pytest.raises(ValueError, match="unknown AKC\\+ setting"):
        evaluate_motion_dir(tmp_path, akc_plus={"gate": 1.0}, **kw)
    # The filters' settings (--filter-settings) likewise: recorded, the same on the workers, and they change the KF.
    gated = {"gate_sigma": 2.0, "gate_whole_landmark": True, "max_predict_s": 0.3}
    gated_here = evaluate_motion_dir(tmp_path, scheduler="inprocess", filter_settings=gated, **kw)
    gated_there = evaluate_motion_dir(tmp_path, scheduler="local", n_workers=2, filter_settings=gated, **kw)
    assert gated_here["filter_settings"] == gated_there["filter_settings"] == gated and here["filter_settings"] is None
    assert _tables_bytes(gated_here) == _tables_bytes(gated_there) != _tables_bytes(here)
    assert any(json.dumps(a["methods"]["KF"]["sse_m2"]) != json.dumps(b["methods"]["KF"]["sse_m2"])
               for a, b in zip(here["clips"], gated_here["clips"], strict=True))
    with pytest.raises(ValueError, match="gate_sigma"):
        evaluate_motion_dir(tmp_path, filter_settings={"gate_sigma": -1.0}, **kw)
