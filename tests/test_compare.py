"""``akc_drake.evaluation.compare`` and ``akc-drake compare``: figures hand-worked from synthetic clips."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from akc_drake import cli
from akc_drake.core.skeleton import ARM_JOINTS, INDEX, NUM_LANDMARKS
from akc_drake.evaluation.compare import (
    changes,
    corrected_pairs,
    describe,
    format_changes,
    format_glance,
    glance,
    load_run,
)
from akc_drake.evaluation.set_metrics import paired_errors

T = 100
LOST = slice(50, 100)  # the left wrist's depth is lost in the second half


def _method(est, truth):
    e = est - truth
    rec = {"sse_m2": {}, "n": {}, "rmse_cm": {}}
    for joint in ARM_JOINTS:
        ej = e[:, INDEX[joint]]
        rec["sse_m2"][joint] = np.sum(ej**2, axis=0).tolist()
        rec["n"][joint] = [T, T, T]
        rec["rmse_cm"][joint] = (np.sqrt(np.mean(ej**2, axis=0)) * 100).tolist()
    return rec


def _clip(name, wrist_err_lost=0.02):
    """Every arm joint 1 cm off on each axis after the KF and after AKC+(KF), except AKC+'s left wrist: x
    ``wrist_err_lost`` m off over the frames its depth is lost."""
    truth = np.zeros((T, NUM_LANDMARKS, 3))
    kf = truth + 0.01
    akc = kf.copy()
    akc[LOST, INDEX["left_wrist"], 0] = wrist_err_lost
    seen = np.ones((T, NUM_LANDMARKS), dtype=bool)
    seen[LOST, INDEX["left_wrist"]] = False
    m_akc = _method(akc, truth)
    m_akc["paired"] = paired_errors(akc, kf, truth, "KF", seen)
    return {"name": name, "frames": T, "lost_share": {j: 0.5 if j == "left_wrist" else 0.0 for j in ARM_JOINTS},
            "methods": {"KF": _method(kf, truth), "AKC+(KF)": m_akc}}


def _run(wrist_err_lost=0.02, **meta):
    run = {"protocol": "ours", "seed": 0, "rate_hz": 10.0, "camera": "default", "body": "primitive",
           "body_scale": 1.0, "detector": "sim", "drive": "angles", "correctors": {},
           "methods": ["KF", "AKC+(KF)"], "clips": [_clip("a", wrist_err_lost), _clip("b", 0.01)]}
    run.update(meta)
    return run


def test_glance_gives_the_hand_worked_figures():
    (row,) = glance([_run()])
    assert (row["method"], row["filter"], row["frames"]) == ("AKC+(KF)", "KF", 2 * T)
    # all frames: sqrt((50 * 1 + 50 * 4) / 100) = 1.581 cm against 1 cm, on clip a's left wrist x
    w = row["worst"]
    assert (w["clip"], w["joint"], w["axis"]) == ("a", "left_wrist", "x")
    assert w["delta_cm"] == pytest.approx(math.sqrt(2.5) - 1.0, abs=1e-9)
    # the seen frames: no joint worse (every seen frame 1 cm off for both)
    assert row["worst_seen"]["delta_cm"] == pytest.approx(0.0, abs=1e-9)
    # in 3D: sqrt(2.5 + 1 + 1) against sqrt(3)
    assert row["worst_3d"]["delta_cm"] == pytest.approx(math.sqrt(4.5) - math.sqrt(3.0), abs=1e-9)
    # the lost joint-frames (clip a's left wrist, 50 frames; clip b's, 50 frames at 1 cm): pooled 3D
    lost = row["lost"]
    assert lost["frames"] == 100 and lost["pairs"] == 2 and lost["pairs_worse_3d"] == 1
    assert lost["filter_3d_cm"] == pytest.approx(math.sqrt(3.0), abs=1e-9)
    assert lost["corrected_3d_cm"] == pytest.approx(math.sqrt((4.0 + 1.0) / 2 + 2.0), abs=1e-9)
    # pooled arm 3D: the left wrist pooled over both clips, x sqrt((50 * 4 + 150 * 1) / 200)
    wrist = math.sqrt(350 / 200 + 2.0)
    assert row["pooled_3d_cm"][0] == pytest.approx(math.sqrt(3.0), abs=1e-9)
    assert row["pooled_3d_cm"][1] == pytest.approx((5 * math.sqrt(3.0) + wrist) / 6, abs=1e-9)


def test_format_glance_bolds_a_miss_and_says_where():
    text = format_glance(glance([_run(label="mine")]))
    assert "| mine | sim, primitive, `ours`, 10 Hz | 200 | AKC+(KF) | **+0.58** (a left wrist x) / +0.00 |" in text
    assert "+0.58" not in format_glance(glance([_run(0.01)]))


def test_changes_lists_what_crossed_the_target_and_what_moved():
    old, new = _run(label="old"), _run(0.01, label="new")
    ch = changes(old, new, target_cm=0.5, min_change_cm=0.1)
    (s,) = ch["summary"]
    assert s["old"]["worst"]["delta_cm"] == pytest.approx(math.sqrt(2.5) - 1.0)
    assert s["new"]["worst"]["delta_cm"] == pytest.approx(0.0, abs=1e-9)
    (e,) = ch["entries"]  # only clip a's left wrist x moved; nothing else moved at all
    assert (e["clip"], e["joint"], e["axis"]) == ("a", "left_wrist", "x")
    assert e["old_cm"] == pytest.approx(math.sqrt(2.5) - 1.0) and e["new_cm"] == pytest.approx(0.0, abs=1e-9)
    # a move under the threshold that crosses no target is left out
    small = changes(_run(0.0105), _run(0.0106), target_cm=0.5, min_change_cm=0.1)
    assert small["entries"] == []
    # a move under the threshold that crosses the target is listed
    just = changes(_run(0.0186), _run(0.0188), target_cm=0.5, min_change_cm=0.1)  # +0.493 -> +0.506
    assert [(x["clip"], x["axis"]) for x in just["entries"]] == [("a", "x")]
    assert "| AKC+(KF) | a | left wrist | x | +0.58 -> +0.00 |" in format_changes(ch)


def test_changes_refuses_two_different_sets():
    other = _run()
    for c in other["clips"]:
        c["name"] = "z" + c["name"]
    with pytest.raises(ValueError, match="share no clip"):
        changes(_run(), other)


def test_every_corrected_method_is_paired_with_its_filter_a_corrector_of_your_own_too():
    run = _run(methods=["KF", "EKF", "AKC+(KF)", "COIK(KF)", "LEN(KF)", "LEN(EKF)", "Raw"],
               correctors={"LEN": "mine.py:Factory"})
    assert corrected_pairs(run) == [("AKC+(KF)", "KF"), ("COIK(KF)", "KF"), ("LEN(KF)", "KF"), ("LEN(EKF)", "EKF")]
    assert corrected_pairs(_run(methods=["KF", "LEN(KF)"])) == []  # (not a corrector the run names)


def test_describe_names_what_is_not_the_default():
    assert describe(_run()) == "sim, primitive, `ours`, 10 Hz"
    d = describe(_run(drive="rig", seed=2, body_scale=1.2, rate_hz=30.0,
                      camera={"distance_m": 3.0, "height_m": 0.45, "lateral_m": 0.0, "aim_height_m": None}))
    assert d == ("sim, primitive, `ours`, drive rig, 30 Hz, camera distance_m=3,height_m=0.45,lateral_m=0, "
                 "operator x 1.2, seed 2")
    noisy = describe(_run(depth_noise={"sigma_disparity_px": 0.16, "correlation_px": 4.0}))
    assert noisy == "sim, primitive, `ours`, 10 Hz, depth noise sigma_disparity_px=0.16,correlation_px=4"


def test_load_run_says_what_is_wrong(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        load_run(tmp_path / "none.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match="not JSON"):
        load_run(tmp_path / "bad.json")
    (tmp_path / "bench.json").write_text(json.dumps({"tables": {}}))
    with pytest.raises(ValueError, match="not a real-motion evaluation"):
        load_run(tmp_path / "bench.json")
    # a motion set's sources manifest (make mocap-data writes one beside the clips) has clips, not results
    manifest = {"packages": {}, "clips": [{"name": "a", "file": "a.bvh"}]}
    (tmp_path / "mocap_sources.json").write_text(json.dumps(manifest))
    with pytest.raises(ValueError, match="not a real-motion evaluation"):
        load_run(tmp_path / "mocap_sources.json")


def test_cli_compare_prints_and_writes_json(tmp_path, capsys):
    a, b = tmp_path / "before" / "clips.json", tmp_path / "after" / "clips.json"
    for p, run in ((a, _run()), (b, _run(0.01))):
        p.parent.mkdir()
        p.write_text(json.dumps(run))
    out = tmp_path / "cmp.json"
    assert cli.main(["compare", str(b), "--against", str(a), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"{a} -> {b}:" in text  # (the same file name twice: the runs are told apart by their paths)
    data = json.loads(out.read_text())
    assert data["target_cm"] == 0.5 and len(data["runs"]) == 1
    (e,) = data["changes"][0]["entries"]
    assert e["joint"] == "left_wrist" and e["new_cm"] == pytest.approx(0.0, abs=1e-9)
    assert cli.main(["compare", str(b), "--against", str(a), str(a)]) == 2
    assert "give one earlier run per run" in capsys.readouterr().err
    assert cli.main(["compare", str(b), "--methods", "AKC+(KF)"]) == 0 and "AKC+(KF)" in capsys.readouterr().out
    assert cli.main(["compare", str(b), "--methods", "AKC(EKF)"]) == 2
    assert "AKC(EKF) not in the runs (they have AKC+(KF))" in capsys.readouterr().err
    assert cli.main(["compare", str(tmp_path / "none.json")]) == 2
    assert "no such file" in capsys.readouterr().err
    # folders: a run per *.json, each paired with the earlier run of its file name
    assert cli.main(["compare", str(b.parent), "--against", str(a.parent), "--json", str(out)]) == 0
    assert f"{a} -> {b}:" in capsys.readouterr().out
    assert [c["old"] for c in json.loads(out.read_text())["changes"]] == [str(a)]
    (b.parent / "other.json").write_text(json.dumps(_run()))
    assert cli.main(["compare", str(b.parent), "--against", str(a.parent)]) == 2
    assert "no earlier run named as" in capsys.readouterr().err
    (tmp_path / "bench.json").write_text(json.dumps({"tables": {}}))  # (another JSON in a folder: skipped)
    assert cli.main(["compare", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "skipped" in err and "bench.json: not a real-motion evaluation" in err
    assert "no real-motion evaluation (.json) in the folder" in err
