"""``akc-drake demo`` and its logic (akc_drake.teleop): dropout, metrics, table, the command end to end."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from akc_drake import cli, teleop
from akc_drake.core.frames import frame_jitter, rotation_z, transform
from akc_drake.errors import UserError
from akc_drake.operator.motions import make_motion

RATE = 10.0


def test_calibration_from_a_rendered_tpose_finds_the_operator():
    from akc_drake.config import PipelineConfig
    from akc_drake.core.skeleton import BodyDimensions

    calib = teleop.calibrate_from_tpose(PipelineConfig(), seed=1, max_frames=20)
    assert calib.frames == 20
    truth = BodyDimensions.paper_participant().as_dict()
    for name, value in calib.dims.as_dict().items():
        assert value == pytest.approx(truth[name], abs=0.015), name
    assert calib.report.method == "tpose" and not calib.report.warnings


def test_truncate_motion_keeps_the_first_frames():
    m = make_motion("I", 1, 0)
    cut = teleop.truncate_motion(m, 15, RATE)
    assert len(cut.frame_times(RATE)) == 15
    np.testing.assert_array_equal(cut.q_left, m.q_left[: len(cut.times)])
    assert teleop.truncate_motion(m, 10_000, RATE) is m
    with pytest.raises(ValueError, match="max_frames"):
        teleop.truncate_motion(m, 1, RATE)


# ------------------------------------------------------------------------------------------------------------
# Metrics on a hand-made run


def _synthetic_run(n=30, period=0.1, h=0.01, corrector="AKC(KF)") -> teleop.TeleopRun:
    """A run whose target turns at 0.5 rad/s and moves 0.2 m/s along x; the end effector lags 2 cm in y."""
    t = np.arange(n) * period
    target, ee, op = {}, {}, {}
    for side, sign in (("left", 1.0), ("right", -1.0)):
        X = np.stack([transform(rotation_z(0.5 * tk), [0.2 * tk, sign * 0.3, 0.1]) for tk in t])
        target[side] = X
        ee[side] = X[:, :3, 3] + np.array([0.0, 0.02, 0.0])
        # The operator's true mapped wrist: 5 cm ahead in x.
        op[side] = X.copy()
        op[side][:, 0, 3] += 0.05
    # The first 10 frames (the settling second): 40 cm error.
    errors = {s: np.where(np.arange(n) < 10, 0.40, 0.02) for s in teleop.SIDES}
    return teleop.TeleopRun(
        motion="I",
        corrector=corrector,
        rendered=False,
        frames=n,
        period_s=period,
        sim_s=n * period,
        wall_s=n * period / 2.0,
        nan_commands=0,
        position_limit_hits=3,
        velocity_limit_hits=4,
        max_speed_ratio=0.5,
        tracking_lost_share=0.1,
        ik_steps={"left": 301, "right": 301},
        ik_failures={"left": 2, "right": 5},
        ik_failure_kinds={"stuck": 6, "no solution": 1},
        ik_relaxed={"left": 4, "right": 0},
        ik_joint_space={"left": 10, "right": 20},
        error_t={s: (np.arange(n) + 1) * period - h for s in teleop.SIDES},
        errors=errors,
        frame_t=(np.arange(n) + 1) * period - h,
        target=target,
        reachable_target={s: target[s][:, :3, 3].copy() for s in teleop.SIDES},
        ee=ee,
        operator=op,
        dropout=np.zeros(n, dtype=bool),
    )


def test_run_metrics_on_known_numbers():
    run = _synthetic_run()
    m = teleop.run_metrics([run])
    assert m["frames"] == 30
    for s in teleop.SIDES:
        assert m["ee_tracking_error_cm"][s] == pytest.approx(2.0)  # the settling second left out
        # With the settling second: 10 of 30 samples at 40 cm; the median is still 2 cm.
        assert m["ee_tracking_error_cm_with_settling"][s] == pytest.approx(2.0)
        assert m["ee_tracking_error_p95_cm"][s] == pytest.approx(2.0)
        assert m["ee_reachable_error_cm"][s] == pytest.approx(2.0)
        assert m["ee_operator_error_cm"][s] == pytest.approx(math.hypot(5.0, 2.0))
        assert m["target_unreachable_share"][s] == 0.0
        assert m["jitter"]["angular_rad_s"][s] == pytest.approx(0.5)
        assert m["jitter"]["linear_m_s"][s] == pytest.approx(0.2)
        assert m["operator_jitter"]["linear_m_s"][s] == pytest.approx(0.2)
        assert m["target_operator_rotation_error_deg"][s] == pytest.approx(0.0, abs=1e-6)
    turned = _synthetic_run()
    for s in teleop.SIDES:
        turned.operator[s][:, :3, :3] = turned.operator[s][:, :3, :3] @ rotation_z(0.2)
    assert teleop.run_metrics([turned])["target_operator_rotation_error_deg"]["left"] == pytest.approx(
        math.degrees(0.2))
    assert m["ik_failures"] == 7 and m["ik_steps"] == 602
    assert m["ik_failure_kinds"] == {"stuck": 6, "no solution": 1}
    assert m["ik_orientation_relaxed"] == 4 and m["ik_joint_space_steps"] == 30
    assert m["position_limit_hits"] == 3 and m["velocity_limit_hits"] == 4
    assert m["realtime_factor"] == pytest.approx(2.0)
    assert m["tracking_lost_share"] == pytest.approx(0.1)


def test_run_metrics_splits_the_target_error_into_its_constant_part_and_the_smoothings_share():
    run = _synthetic_run()
    # Synthetic: the target is 5 cm behind the operator in x on every frame (a pure offset); the unsmoothed
    # targets are 3 cm off in x and alternately +/- 4 cm in y (noise around a 3 cm offset).
    for s in teleop.SIDES:
        U = run.operator[s].copy()
        U[:, 0, 3] -= 0.03
        U[:, 1, 3] += np.where(np.arange(run.frames) % 2 == 0, 0.04, -0.04)
        run.unsmoothed[s] = U
    m = teleop.run_metrics([run])
    for s in teleop.SIDES:
        assert m["target_operator_error_cm"][s] == pytest.approx(5.0)
        assert m["target_operator_offset_cm"][s] == pytest.approx(5.0)  # all of it constant
        assert m["target_operator_error_unsmoothed_cm"][s] == pytest.approx(5.0)  # hypot(3, 4)
    run.target["left"][:, 1, 3] += np.where(np.arange(run.frames) % 2 == 0, 0.12, -0.12)
    m = teleop.run_metrics([run])
    # 20 frames after settling, 10 at +12 and 10 at -12 cm: the median cancels, the offset stays 5 cm.
    assert m["target_operator_offset_cm"]["right"] == pytest.approx(5.0)
    assert m["target_operator_error_cm"]["left"] == pytest.approx(13.0)
    assert m["target_operator_offset_cm"]["left"] == pytest.approx(5.0)
    assert m["target_operator_error_unsmoothed_cm"]["right"] == pytest.approx(5.0)
    # A few outliers (3 of 20 frames 1 m off) do not make an offset: the median, not the mean.
    run.target["right"][-3:, 2, 3] += 1.0
    assert teleop.run_metrics([run])["target_operator_offset_cm"]["right"] == pytest.approx(5.0)
    # Clipping reported apart: the error over the frames whose target was not clipped.
    assert m["target_operator_error_unclipped_cm"]["right"] == pytest.approx(5.0)
    run.clipped = {s: np.arange(run.frames) >= run.frames - 3 for s in teleop.SIDES}  # the outliers' frames
    m = teleop.run_metrics([run])
    assert m["target_operator_error_p95_cm"]["right"] > 50.0
    assert m["target_operator_error_unclipped_p95_cm"]["right"] == pytest.approx(5.0)
    assert m["target_operator_error_unclipped_cm"]["left"] == pytest.approx(13.0)
    assert m["workspace_clipped_share"]["right"] == pytest.approx(3 / 20)
    # Without unsmoothed targets the share is unknown, not zero.
    run.unsmoothed = {}
    assert teleop.run_metrics([run])["target_operator_error_unsmoothed_cm"]["left"] is None


def test_run_metrics_with_the_settling_second_included_when_it_dominates():
    run = _synthetic_run(n=15)  # 10 of 15 samples in the settling second
    m = teleop.run_metrics([run])
    assert m["ee_tracking_error_cm"]["left"] == pytest.approx(2.0)
    assert m["ee_tracking_error_cm_with_settling"]["left"] == pytest.approx(40.0)


def test_run_metrics_pools_runs_without_bridging_them():
    a, b = _synthetic_run(), _synthetic_run()
    # Shift b far away: a pair spanning the two runs would show a huge speed.
    for s in teleop.SIDES:
        b.target[s][:, 0, 3] += 10.0
    m = teleop.run_metrics([a, b])
    assert m["frames"] == 60
    assert m["jitter"]["linear_m_s"]["left"] == pytest.approx(0.2)
    expected = frame_jitter(a.target["left"][a.frame_t >= 1.0], 0.1)
    assert m["jitter"]["angular_rad_s"]["left"] == pytest.approx(expected[0])
    assert m["ik_failures"] == 14


def test_run_metrics_unreachable_targets_and_missing_samples():
    run = _synthetic_run()
    run.reachable_target["left"][20:, 0] -= 0.1  # the guard pulled the last 10 targets in
    run.target["right"][25:] = np.nan  # no samples for the last 5 frames
    m = teleop.run_metrics([run])
    assert m["target_unreachable_share"]["left"] == pytest.approx(10 / 20)
    assert m["target_unreachable_share"]["right"] == 0.0
    assert math.isfinite(m["jitter"]["linear_m_s"]["right"])
    with pytest.raises(ValueError, match="no runs"):
        teleop.run_metrics([])


def test_format_table_lists_every_corrector_and_the_headline():
    runs = [_synthetic_run(corrector=c) for c in teleop.CORRECTORS]
    per_run = []
    for r in runs:
        m = teleop.run_metrics([r])
        m.update({"motion": r.motion, "corrector": r.corrector, "rendered": False})
        per_run.append(m)
    summary = {
        "config": {"motions": ["I"], "settling_s": 1.0},
        "runs": per_run,
        "correctors": {r.corrector: teleop.run_metrics([r]) for r in runs},
        "frames": 30,
        "rendered_run": None,
        "realtime_factor": None,
        "ee_tracking_error_cm": {"left": 2.0, "right": 2.0},
        "nan_commands": 0,
        "ik_failures": 28,
    }
    text = teleop.format_table(summary)
    for c in teleop.CORRECTORS:
        assert f"\n{c} " in text
    assert "Motion I (30 frames" in text and "Both motions" in text and "(operator)" in text
    assert "2.0/2.0" in text and "0.50/0.50" in text and "3/4" in text
    assert "IK failures 28" in text


# ------------------------------------------------------------------------------------------------------------
# Options and the command


def test_demo_options_validation():
    assert teleop.DemoOptions(quick=True).num_cycles == teleop.QUICK_CYCLES
    assert teleop.DemoOptions().num_cycles == teleop.FULL_CYCLES
    assert teleop.DemoOptions(cycles=2, quick=True).num_cycles == 2
    for bad, match in (
        ({"dropout": 1.2}, "--dropout"),
        ({"dropout": float("inf")}, "--dropout"),
        ({"cycles": 0}, "cycles"),
        ({"max_frames": 3}, "max_frames"),
        ({"correctors": ("AKC",)}, "correctors"),
        ({"out_dir": " "}, "--out"),
        ({"task": "stack"}, "--task"),
        ({"task": "pick-place", "seeds": 0}, "--seeds"),
    ):
        with pytest.raises(UserError, match=match):
            teleop.DemoOptions(**bad).validate()


def test_cli_rejects_a_bad_dropout(capsys, tmp_path):
    assert cli.main(["demo", "--dropout", "1.5", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "--dropout" in err and "1.5" in err
    assert not (tmp_path / "o").exists()


def test_cli_rejects_a_bad_frame_cap(capsys, monkeypatch, tmp_path):
    monkeypatch.setenv("AKC_DEMO_MAX_FRAMES", "many")
    assert cli.main(["demo", "--quick", "--out", str(tmp_path)]) == 2
    assert "AKC_DEMO_MAX_FRAMES" in capsys.readouterr().err


def test_demo_command_end_to_end(tmp_path):
    """``akc-drake demo --quick --json`` in a subprocess, cut to 12 frames per motion (the full --quick run
    takes about 80 s on two shared cores; see the report)."""
    out = tmp_path / "demo"
    js = tmp_path / "summary.json"
    env = dict(os.environ, AKC_DEMO_MAX_FRAMES="12")
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "akc_drake.cli",
            "demo",
            "--quick",
            "--dropout",
            "0.25",
            "--out",
            str(out),
            "--json",
            str(js),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    s = json.loads(js.read_text())
    assert s == json.loads((out / "demo.json").read_text()) | {"outputs": s["outputs"]}
    # The DESIGN.md contract.
    assert s["frames"] == 24
    assert s["nan_commands"] == 0
    assert isinstance(s["ik_failures"], int) and s["ik_failures"] >= 0
    assert set(s["ee_tracking_error_cm"]) == {"left", "right"}
    assert all(v is not None and 0 <= v < 200 for v in s["ee_tracking_error_cm"].values())
    assert s["realtime_factor"] > 0
    assert set(s["realtime_factor_replay"]) == set(teleop.CORRECTORS)
    # Every corrector ran on both motions, plus the rendered AKC(KF) run.
    assert len(s["runs"]) == 2 * len(teleop.CORRECTORS) + 2
    assert sum(r["rendered"] for r in s["runs"]) == 2
    # Dropout: 25 % of 12 frames = 3 per motion, in every replay.
    assert s["dropout"]["I"]["frames"] == 3 and s["dropout"]["II"]["frames"] == 3
    assert all(r["dropout_frames"] == 3 for r in s["runs"] if not r["rendered"])
    for m in ("I", "II"):
        bursts = s["dropout"][m]["bursts_start_duration_s"]
        assert sum(d for _, d in bursts) == pytest.approx(0.3)
    assert s["calibration"]["frames"] == 12
    # The main job's default is the real pipeline: MediaPipe on the rendered skinned body.
    assert (s["config"]["body"], s["config"]["detector"]) == ("skinned", "mediapipe")
    for name in (
        "demo.json",
        "teleop.html",
        "teleop.dot",
        "paths_motion_I.png",
        "paths_motion_II.png",
        "tracking_error.png",
    ):
        assert (out / name).stat().st_size > 1000, name
    assert Path(s["outputs"]["html"]) == out / "teleop.html"
    # The printed table and the list of files.
    assert "Both motions (24 frames per corrector)" in res.stdout
    assert "AKC(KF) with the camera rendered in the diagram" in res.stdout
    assert str(out / "demo.json") in res.stdout
