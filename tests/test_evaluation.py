"""Tests of the evaluation: sessions, methods, the experiment and the ``evaluate`` command.

The experiment tests run on synthetic sessions built here (true arm trajectories of Motion I / II
seen by a pinhole camera, with the depth of a hidden joint replaced by the depth of the surface in
front of it, plus noise), so they are fast and do not need the renderer. The end-to-end CLI test
renders (small images, one cycle) and is skipped only while the renderer is not installed.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from akc_drake.cli import main as cli_main
from akc_drake.core.camera import CameraIntrinsics, project
from akc_drake.core.skeleton import ARM_JOINTS, INDEX, NUM_LANDMARKS, BodyDimensions, segment_lengths
from akc_drake.errors import UserError
from akc_drake.evaluation import methods as M
from akc_drake.evaluation.experiment import (
    ExperimentConfig,
    manual_dimensions,
    run_experiment,
    true_dimensions,
    work_units,
)
from akc_drake.evaluation.session import Session, cycle_starts_for, session_from_render

RATE = 10.0
CYCLE = 6.0
INTR = CameraIntrinsics(width=320, height=240, fx=307.5, fy=307.5, cx=159.5, cy=119.5)
DIMS = BodyDimensions.paper_participant()


# ============================================================================ synthetic sessions
def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def synthetic_truth(motion: str, frames: int, seed: int = 0, dims: BodyDimensions = DIMS) -> np.ndarray:
    """True landmarks ``(T, 12, 3)`` in C of an operator 2 m in front of the camera.

    ``motion``: "I" (T-pose -> arm pointing at the camera -> T-pose, 6 s), "II" (upper arm at the
    camera, elbow flexion 0 -> 90 deg -> 0), "tpose", "lpose". The torso sways by about a centimetre.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / RATE
    T = frames
    sway = 0.01 * np.stack(
        [
            np.sin(2 * np.pi * 0.13 * t + rng.uniform(0, 6)),
            0.5 * np.sin(2 * np.pi * 0.21 * t + rng.uniform(0, 6)),
            np.sin(2 * np.pi * 0.17 * t + rng.uniform(0, 6)),
        ],
        axis=1,
    )
    X = np.full((T, NUM_LANDMARKS, 3), np.nan)
    centre = np.array([0.0, -0.25, 2.0])
    phase = 0.5 * (1 - np.cos(2 * np.pi * t / CYCLE))  # 0 -> 1 -> 0 per cycle
    for side, sx in (("left", 1.0), ("right", -1.0)):
        sh = centre + np.array([sx * dims.SW / 2, 0.0, 0.0]) + sway
        X[:, INDEX[f"{side}_shoulder"]] = sh
        X[:, INDEX[f"{side}_hip"]] = sh + np.array([-sx * 0.03, 0.5, 0.02])
        lu, lf = dims.upper(side), dims.lower(side)
        if motion == "I":
            phi = np.radians(88.0) * phase
            du = np.stack([sx * np.cos(phi), np.zeros(T), -np.sin(phi)], axis=1)
            df = du
        elif motion == "II":
            psi = np.radians(90.0) * phase
            # The upper arm points at the camera, swinging a little outwards as the elbow flexes.
            du = np.stack([sx * (0.1 + 0.25 * phase), np.full(T, 0.05), -np.ones(T)], axis=1)
            df = np.stack([np.full(T, sx * 0.05), -np.sin(psi), -np.cos(psi)], axis=1)
        elif motion == "tpose":
            du = df = np.tile([sx, 0.0, 0.0], (T, 1))
        elif motion == "lpose":
            du = np.tile([sx, 0.0, 0.0], (T, 1))
            df = np.tile([0.0, -1.0, 0.0], (T, 1))
        else:
            raise ValueError(motion)
        du, df = _unit(du), _unit(df)
        el = sh + lu * du
        wr = el + lf * df
        X[:, INDEX[f"{side}_elbow"]] = el
        X[:, INDEX[f"{side}_wrist"]] = wr
        side_dir = _unit(np.cross(df, np.array([0.0, 0.0, 1.0])) + 1e-9)
        X[:, INDEX[f"{side}_index"]] = wr + 0.08 * df + 0.02 * side_dir
        X[:, INDEX[f"{side}_pinky"]] = wr + 0.07 * df - 0.02 * side_dir
    return X


#: Fractions along (upper arm, forearm) sampled as occluding surface points, per proximal joint.
_FRACS = np.linspace(0.0, 1.0, 21)


def _occluders(truth: np.ndarray, side: str, prox: str) -> np.ndarray:
    """``(T, N, 3)`` points on the limb distal to ``prox`` (the surfaces that can hide it)."""
    sh, el, wr = (truth[:, INDEX[f"{side}_{n}"]] for n in ("shoulder", "elbow", "wrist"))
    f = _FRACS[None, :, None]
    fore = el[:, None] + f * (wr - el)[:, None]
    hand = truth[:, [INDEX[f"{side}_index"], INDEX[f"{side}_pinky"]]]
    if prox == "elbow":
        return np.concatenate([fore[:, 4:], hand], axis=1)
    upper = sh[:, None] + f * (el - sh)[:, None]
    return np.concatenate([upper[:, 4:], fore, hand], axis=1)


def synthetic_measurements(truth: np.ndarray, seed: int = 0, intr: CameraIntrinsics = INTR):
    """Raw landmarks, visibility and pixels as a depth camera + 2D detector would give them.

    The depth read at a proximal joint's pixel is that of the nearest limb surface covering it: a
    point of the distal limb (upper arm, forearm, hand) of the same arm whose image lies within the
    limb's image radius and which is nearer the camera; a limb is a 5 cm-radius cylinder, so the
    surface is 5 cm in front of the sampled axis point. Depth noise is added everywhere; the
    detector's visibility drops below 0.7 for only half of the hidden frames (so the proximity
    check matters).
    """
    rng = np.random.default_rng(seed + 1000)
    T = truth.shape[0]
    pixels = project(truth, intr) + rng.normal(0.0, 0.7, (T, NUM_LANDMARKS, 2))
    z = truth[..., 2] + rng.normal(0.0, 0.008, (T, NUM_LANDMARKS))
    vis = np.clip(0.95 + rng.normal(0, 0.02, (T, NUM_LANDMARKS)), 0, 1)
    limb_r = 0.05
    for side in ("left", "right"):
        for prox in ("shoulder", "elbow"):
            j = INDEX[f"{side}_{prox}"]
            occ = _occluders(truth, side, prox)
            uv = project(occ, intr)
            r_px = limb_r * intr.fx / occ[..., 2]
            cover = (np.linalg.norm(uv - pixels[:, j, None], axis=-1) < r_px) & (
                occ[..., 2] < truth[:, j, None, 2] - limb_r
            )
            zs = np.where(cover, occ[..., 2] - limb_r, np.inf).min(axis=1)
            hit = np.isfinite(zs)
            z[hit, j] = zs[hit] + rng.normal(0, 0.008, hit.sum())
            vis[hit & (rng.random(T) < 0.5), j] = 0.3
    raw = np.stack(
        [(pixels[..., 0] - intr.cx) * z / intr.fx, (pixels[..., 1] - intr.cy) * z / intr.fy, z], axis=-1
    )
    return raw, vis, pixels


def synthetic_session(motion: str, cycles: int = 2, seed: int = 0, frames: int | None = None) -> Session:
    n = frames if frames is not None else int(cycles * CYCLE * RATE)
    truth = synthetic_truth(motion, n, seed)
    raw, vis, pix = synthetic_measurements(truth, seed)
    t = np.arange(n) / RATE
    cyc = CYCLE if motion in ("I", "II") else None
    return Session(
        t, raw, vis, pix, truth, INTR, motion, cycle_starts_for(t, cyc), source_time_s=np.full(n, 0.02)
    )


@pytest.fixture(scope="module")
def sessions():
    return {
        "tpose": synthetic_session("tpose", frames=100, seed=1),
        "lpose": synthetic_session("lpose", frames=100, seed=2),
        "I": synthetic_session("I", cycles=2, seed=3),
        "II": synthetic_session("II", cycles=2, seed=4),
    }


@pytest.fixture(scope="module")
def evaluation(sessions):
    cfg = ExperimentConfig(motions=("I", "II"), cycles=2, width=INTR.width, height=INTR.height)
    done = []
    ev = run_experiment(cfg, sessions, progress=lambda n, label: done.append(n))
    assert sum(done) == work_units(cfg, sessions)
    return ev


# ============================================================================ session
def test_synthetic_session_has_real_occlusion(sessions):
    s = sessions["II"]
    j = INDEX["left_shoulder"]
    err_z = np.abs(s.raw[:, j, 2] - s.truth[:, j, 2])
    err_xy = np.abs(s.raw[:, j, :2] - s.truth[:, j, :2])
    assert np.mean(err_z > 0.10) > 0.5  # the shoulder is hidden behind the arm most of the time
    assert np.median(err_xy) < 0.05
    # T-pose: nothing hidden
    tp = sessions["tpose"]
    assert np.max(np.abs(tp.raw[..., 2] - tp.truth[..., 2])) < 0.05


def test_session_roundtrip_npz(tmp_path, sessions):
    s = sessions["I"]
    p = s.save_npz(tmp_path / "sub" / "I.npz")
    r = Session.load_npz(p)
    for name in ("t", "raw", "visibility", "pixels", "truth", "cycle_starts", "source_time_s"):
        np.testing.assert_array_equal(getattr(r, name), getattr(s, name))
    assert r.intrinsics == s.intrinsics and r.motion == "I"
    assert list(tmp_path.joinpath("sub").iterdir()) == [p]  # no temp file left behind


def test_session_load_errors_name_the_file(tmp_path, sessions):
    with pytest.raises(UserError, match="nope.npz"):
        Session.load_npz(tmp_path / "nope.npz")
    bad = tmp_path / "bad.npz"
    bad.write_text("not a zip")
    with pytest.raises(UserError, match="bad.npz"):
        Session.load_npz(bad)
    partial = tmp_path / "partial.npz"
    np.savez(partial, t=np.arange(3.0))
    with pytest.raises(UserError, match=r"partial.npz: missing field\(s\) raw"):
        Session.load_npz(partial)


def test_session_validation_names_the_field():
    t = np.arange(5) / RATE
    z = np.zeros((5, NUM_LANDMARKS, 3))
    with pytest.raises(ValueError, match="Session.raw"):
        Session(t, z[:4], np.zeros((5, 12)), np.zeros((5, 12, 2)), z)
    with pytest.raises(ValueError, match="strictly increasing"):
        Session(t[::-1], z, np.zeros((5, 12)), np.zeros((5, 12, 2)), z)
    with pytest.raises(ValueError, match="cycle_starts"):
        Session(t, z, np.zeros((5, 12)), np.zeros((5, 12, 2)), z, cycle_starts=[1, 3])


def test_cycles_and_evaluation_mask():
    t = np.arange(121) / RATE  # 2 cycles of 6 s sampled at 10 Hz, plus the end sample
    cs = cycle_starts_for(t, CYCLE)
    np.testing.assert_array_equal(cs, [0, 60])  # the sample at 12.0 s joins the second cycle
    z = np.zeros((121, NUM_LANDMARKS, 3))
    s = Session(t, z, np.zeros((121, 12)), np.zeros((121, 12, 2)), z, cycle_starts=cs)
    m = s.evaluation_mask()
    assert m.sum() == 61 and not m[:60].any()
    assert [(c.start, c.stop) for c in s.evaluation_cycles()] == [(60, 121)]
    one = s.subset(slice(0, 60))
    assert one.num_cycles == 1 and one.evaluation_mask().all()  # a single cycle is used whole
    np.testing.assert_array_equal(cycle_starts_for(t, None), [0])


def test_session_from_render_adapter():
    class Rendered:
        def __init__(self):
            n = 160
            self.t = np.arange(n) / RATE
            self.landmarks_C = np.ones((n, 12, 3))
            self.visibility = np.ones((n, 12))
            self.pixels = np.ones((n, 12, 2))
            self.truth = np.ones((n, 12, 3))

    s = session_from_render(Rendered(), intrinsics=INTR, motion="II", cycle_s=CYCLE)
    assert s.num_frames == 160 and s.motion == "II"
    np.testing.assert_array_equal(s.cycle_starts, [0, 60, 120])
    assert np.isnan(s.source_time_s).all()
    with pytest.raises(ValueError, match="pixels"):
        session_from_render({"t": [0.0], "landmarks_C": 0, "visibility": 0, "truth": 0})


# ============================================================================ methods
def test_parse_methods():
    assert M.parse_methods("Raw, KF,AKC(KF) ,COIK( EKF )") == ("Raw", "KF", "AKC(KF)", "COIK(EKF)")
    assert M.parse_method("AKC(EKF)") == M.MethodSpec("AKC(EKF)", True, "EKF", "AKC")
    with pytest.raises(ValueError, match="unknown method 'AKC'"):
        M.parse_methods("Raw,AKC")
    with pytest.raises(ValueError, match="more than once"):
        M.parse_methods("KF,KF")
    with pytest.raises(ValueError, match="no method"):
        M.parse_methods(" , ")


def test_methods_are_the_compositions_of_the_core_stages(sessions):
    from akc_drake.core.akc import WEIGHT_PRESETS, ArmKinematicCorrector
    from akc_drake.core.kalman import ConstantVelocityKF, ExtendedKalmanFilterCV
    from akc_drake.core.occlusion import occlusion_filter

    s = sessions["II"].subset(slice(0, 40))
    runner = M.MethodRunner(s, DIMS, "Wb")
    raw = runner.run("Raw")
    np.testing.assert_array_equal(raw.estimates, s.raw)
    # Independent composition, frame by frame.
    kf, ekf, akc = (
        ConstantVelocityKF(),
        ExtendedKalmanFilterCV(DIMS),
        ArmKinematicCorrector(DIMS, WEIGHT_PRESETS["Wb"]),
    )
    exp_kf, exp_ekf, exp_akc = [], [], []
    held = np.full((NUM_LANDMARKS, 3), np.nan)  # (ours: the occlusion filter holds the last accepted positions)
    for k in range(s.num_frames):
        acc, _ = occlusion_filter(s.raw[k], s.pixels[k], s.visibility[k], s.intrinsics.width, held=held)
        exp_kf.append(kf.step(acc, 0.1))
        exp_ekf.append(ekf.step(acc, 0.1))
        exp_akc.append(akc.correct(exp_kf[-1]).pose)
    np.testing.assert_allclose(runner.run("KF").estimates, exp_kf, rtol=0, atol=1e-12)
    np.testing.assert_allclose(runner.run("EKF").estimates, exp_ekf, rtol=0, atol=1e-12)
    res = runner.run("AKC(KF)")
    np.testing.assert_allclose(res.estimates, exp_akc, rtol=0, atol=1e-12)
    assert set(res.stage_time_s) == {"source", "occlusion", "filter", "corrector"}
    for stage in ("occlusion", "filter", "corrector"):
        assert np.all(res.stage_time_s[stage] > 0) and np.all(res.stage_time_s[stage] < 1.0)
    # The shared KF prefix is the same array for KF and AKC(KF) (computed once).
    assert res.stage_time_s["filter"] is runner.run("KF").stage_time_s["filter"]
    assert runner.run("AKC(KF)") is res
    # COIK: a status per frame.
    coik = runner.run("COIK(KF)")
    assert coik.status.shape == (s.num_frames,)
    assert set(coik.status) <= {"success", "iteration_limit", "infeasible", "failed", "held"}


def test_run_method_function(sessions):
    s = sessions["I"].subset(slice(0, 20))
    est, times = M.run_method("AKC(EKF)", s, DIMS, "Wa")
    assert est.shape == (20, 12, 3) and np.isfinite(est[:, :6]).all()
    lens = segment_lengths(est)
    for seg in ("LUA", "LLA", "RUA", "RLA"):
        np.testing.assert_allclose(lens[seg], getattr(DIMS, seg), atol=1e-9)
    assert times["corrector"].shape == (20,)


# ============================================================================ experiment
def test_calibrations(evaluation, sessions):
    cal = evaluation.calibrations
    assert set(cal) == {"Manual", "Truth", "T-pose", "L-pose"}
    truth = true_dimensions(sessions["tpose"])
    for seg in ("LUA", "LLA", "RUA", "RLA", "SW"):
        assert getattr(truth, seg) == pytest.approx(getattr(DIMS, seg), abs=1e-9)
        # A T-pose seen without occlusion calibrates to within 1.5 cm.
        assert abs(getattr(cal["T-pose"], seg) - getattr(DIMS, seg)) < 0.015
    assert manual_dimensions(DIMS) == BodyDimensions.paper_manual()
    assert evaluation.dims == cal["T-pose"]


def test_json_has_every_method_joint_axis(evaluation):
    doc = json.loads(json.dumps(evaluation.to_json()))  # valid JSON (NaN -> null)
    assert doc["config"]["motion"] == "both" and doc["config"]["weights"] == "Wb"
    rows = doc["results"]
    keys = {(r["motion"], r["method"], r["joint"]) for r in rows}
    assert keys == {(m, meth, j) for m in ("I", "II") for meth in M.METHODS for j in ARM_JOINTS}
    assert len(rows) == len(keys)
    for r in rows:
        for metric in ("rmse_cm", "corr"):
            assert set(r[metric]) == {"x", "y", "z"}
            for a in "xyz":
                v = r[metric][a]
                assert v is not None and math.isfinite(v), (r["motion"], r["method"], r["joint"], metric, a)
        assert r["valid_frames"] > 0
        assert all(-1.0 <= r["corr"][a] <= 1.0 for a in "xyz")
    # AKC keeps the calibrated arm lengths: range below 1e-6 cm.
    ranges = doc["arm_length_range_cm"]
    akc = [r for r in ranges if r["method"].startswith("AKC")]
    assert len(akc) == 2 * 4 * 4  # 2 motions x AKC(KF), AKC(EKF), AKC+(KF), AKC+(EKF) x 4 segments
    assert all(r["range_cm"] < 1e-6 for r in akc)
    raw = [r["range_cm"] for r in ranges if r["method"] == "Raw"]
    assert max(raw) > 5.0
    timing = {(r["motion"], r["method"]): r for r in doc["timing_ms"]}
    assert set(timing) == {(m, meth) for m in ("I", "II") for meth in M.METHODS}
    for row in timing.values():  # structure only: the values are wall-clock times
        assert all(math.isfinite(s["mean"]) and s["mean"] >= 0 for s in row["stages"].values())
    assert timing[("I", "Raw")]["stages"]["source"]["mean"] == pytest.approx(20.0)
    assert set(doc["tables"]) == {f"table{i}" for i in range(1, 10)}
    assert doc["paper"]["table1_static_left_shoulder_rmse_cm"]["I"]["AKC"] == [2.06, 1.89, 3.27]


def test_rmse_is_the_cycle_average_on_evaluated_frames(evaluation, sessions):
    s = sessions["II"]
    j = INDEX["left_elbow"]
    row = next(
        r
        for r in evaluation.results
        if r["motion"] == "II" and r["method"] == "Raw" and r["joint"] == "left_elbow"
    )
    sl = slice(60, 120)  # the second cycle; the first is left out
    e, g = s.raw[sl, j], s.truth[sl, j]
    ok = np.isfinite(e).all(axis=1)
    expected = np.sqrt(np.mean((e[ok] - g[ok]) ** 2, axis=0)) * 100
    np.testing.assert_allclose([row["rmse_cm"][a] for a in "xyz"], expected, rtol=1e-9)
    assert row["valid_frames"] == ok.sum()
    r_x = np.corrcoef(e[ok, 0], g[ok, 0])[0, 1]
    assert row["corr"]["x"] == pytest.approx(r_x, abs=1e-9)


def test_akc_corrects_the_hidden_shoulder(evaluation):
    def z(method, motion="II", joint="left_shoulder"):
        return next(
            r["rmse_cm"]["z"]
            for r in evaluation.results
            if r["motion"] == motion and r["method"] == method and r["joint"] == joint
        )

    assert z("Raw") > 10.0  # by construction the raw shoulder depth is that of the arm in front
    assert z("AKC(KF)") < 0.5 * z("Raw")
    assert z("AKC(KF)") < 0.5 * z("KF")  # the paper's Motion II finding (Table I)
    assert z("AKC(EKF)") < z("Raw")


def test_tables_in_paper_layout(evaluation):
    tables = {t.key: t for t in evaluation.tables}
    t1 = tables["table1"]
    assert t1.rows == ["x", "y", "z"]
    assert t1.columns == ["Raw", "KF", "COIK", "AKC", "AKC+"] * 2
    assert t1.groups == [("Motion I", 5), ("Motion II", 5)]
    assert t1.paper[2, 0] == 34.86 and t1.paper[2, 8] == 5.23 and np.isnan(t1.paper[2, 9])
    assert np.isfinite(t1.ours).all()
    row = next(
        r
        for r in evaluation.results
        if r["motion"] == "II" and r["method"] == "AKC(KF)" and r["joint"] == "left_shoulder"
    )
    assert t1.ours[2, 8] == pytest.approx(row["rmse_cm"]["z"])
    t3 = tables["table3"]
    assert t3.ours[0, 0] == pytest.approx(20.0)  # the session's source time
    assert np.isfinite(t3.ours[2, 2:]).all()  # max total of COIK and AKC
    t6 = tables["table6"]
    assert t6.ours[:, t6.columns.index("AKC")].max() < 1e-6
    assert t6.ours[:, t6.columns.index("Truth")].max() < 1e-6  # rigid synthetic arms
    t7 = tables["table7"]
    assert len(t7.rows) == 18 and np.isfinite(t7.ours).all() and t7.ours_std is not None
    t8 = tables["table8"]
    assert t8.columns == ["Manual", "Truth", "T-pose", "L-pose"]
    np.testing.assert_allclose(t8.ours[:, 0], [32.0, 32.0, 26.0, 26.0, 33.0])
    t9 = tables["table9"]
    np.testing.assert_allclose(t9.ours[4], np.sqrt(np.sum(t9.ours[:4] ** 2, axis=0)))


def test_your_own_corrector_in_the_paper_experiment(sessions):
    # A corrector of your own (--add-corrector) runs beside the others; the paper's tables have no column for it, so
    # an extra table lists every method's RMSE per arm joint and axis; its rows are the results' figures.
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "examples" / "segment_lengths.py"
    opts = M.MethodOptions(correctors={"LEN": f"{example}:SegmentLengths"})
    cfg = ExperimentConfig(motions=("I",), cycles=2, width=INTR.width, height=INTR.height, options=opts,
                           methods=("KF", "AKC+(KF)", "LEN(KF)"), weight_study=False, calibration_study=False)
    assert cfg.as_dict()["options"]["correctors"] == {"LEN": f"{example}:SegmentLengths"}
    ev = run_experiment(cfg, sessions)
    t = {t.key: t for t in ev.tables}["every_method"]
    assert t.columns == ["KF", "AKC+(KF)", "LEN(KF)"] and t.groups == [("Motion I", 3)]
    assert len(t.rows) == 18 and t.rows[2] == "left_shoulder z" and np.isnan(t.paper).all()
    row = next(r for r in ev.results if r["motion"] == "I" and r["method"] == "LEN(KF)" and r["joint"] == "left_wrist")
    assert t.ours[t.rows.index("left_wrist x"), 2] == pytest.approx(row["rmse_cm"]["x"])
    ranges = [r["range_cm"] for r in ev.arm_length_range_cm if r["method"] == "LEN(KF)"]
    assert len(ranges) == 4 and max(ranges) < 1e-9
    with pytest.raises(ValueError, match="unknown method 'LEN\\(KF\\)'"):
        ExperimentConfig(motions=("I",), methods=("KF", "LEN(KF)"))
    # Without a corrector of your own the paper's tables are all there is.
    assert "every_method" not in {t.key for t in run_experiment(
        ExperimentConfig(motions=("I",), cycles=2, width=INTR.width, height=INTR.height, methods=("KF", "AKC+(KF)"),
                         weight_study=False, calibration_study=False), sessions).tables}


def test_config_validation():
    with pytest.raises(ValueError, match="cycles"):
        ExperimentConfig(cycles=0)
    with pytest.raises(ValueError, match="weights"):
        ExperimentConfig(weights="Wz")
    with pytest.raises(ValueError, match="unknown method"):
        ExperimentConfig(methods=("Raw", "Nope"))
    with pytest.raises(ValueError, match="tpose"):
        run_experiment(ExperimentConfig(), {})


# ============================================================================ command line
@pytest.mark.parametrize(
    "argv, message",
    [
        (["--methods", "Raw,Foo"], "unknown method 'Foo'"),
        (["--cycles", "0"], "--cycles"),
        (["--motion-file", "x.txt"], "unknown file type"),
        (["--motion-file", "{tmp}/walk.amc"], "needs its skeleton"),
        (["--motion-file", "{tmp}/missing.bvh"], "no such file"),
        (["--motion-file", "{tmp}/missing.c3d"], "no such file"),
        (["--skeleton", "{tmp}/s.asf"], "only used with"),
    ],
)
def test_evaluate_cli_errors(tmp_path, capsys, argv, message):
    (tmp_path / "walk.amc").write_text(":FULLY-SPECIFIED\n")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert cli_main(["evaluate", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_evaluate_cli_end_to_end(tmp_path, capsys):
    pytest.importorskip("akc_drake.systems.depth_camera_source", reason="renderer not installed yet")
    out, js = tmp_path / "report", tmp_path / "eval.json"
    argv = [
        "evaluate",
        "--motion",
        "II",
        "--cycles",
        "1",
        "--width",
        "160",
        "--height",
        "120",
        "--methods",
        "Raw,KF,AKC(KF),COIK(KF)",
        "--out",
        str(out),
        "--json",
        str(js),
    ]
    assert cli_main(argv) == 0
    printed = capsys.readouterr().out
    assert "TABLE1" in printed and "(34.86)" not in printed  # Motion II only: its paper column is 28.54
    assert "(28.54)" in printed
    doc = json.loads(js.read_text())
    keys = {(r["method"], r["joint"]) for r in doc["results"]}
    assert keys == {(m, j) for m in ("Raw", "KF", "AKC(KF)", "COIK(KF)") for j in ARM_JOINTS}
    assert all(r["range_cm"] < 1e-6 for r in doc["arm_length_range_cm"] if r["method"] == "AKC(KF)")
    for r in doc["results"]:
        assert all(v is not None and math.isfinite(v) for v in r["rmse_cm"].values())
    assert (out / "report.md").is_file() and (out / "tables" / "table1.csv").is_file()
    assert (out / "figures" / "fig4_depth.png").is_file()
    assert (out / "figures" / "arm_length_II.png").is_file()


def test_evaluate_cli_joint_names(tmp_path, capsys):
    """A file whose joints the aliases do not find: one line naming them, then --joint-names maps them."""
    pytest.importorskip("akc_drake.systems.depth_camera_source", reason="renderer not installed yet")
    import re
    from pathlib import Path

    text = (Path(__file__).parent / "data" / "mocap" / "upper_body.bvh").read_text()
    for old, new in (("LeftArm", "ShoulderL"), ("RightArm", "ShoulderR"), ("LeftShoulder", "ClavL"),
                     ("RightShoulder", "ClavR")):
        text = re.sub(rf"JOINT {old}\b", f"JOINT {new}", text)
    bvh = tmp_path / "renamed.bvh"
    bvh.write_text(text)
    base = ["evaluate", "--motion-file", str(bvh), "--width", "160", "--height", "120", "--methods", "Raw,KF"]
    assert cli_main(base) == 2
    err = capsys.readouterr().err
    assert "no joint for left_shoulder" in err and "ShoulderL" in err and "Traceback" not in err
    for bad, message in (("left_shoulder:ShoulderL", "is not role=joint"), ("left_knee=ShoulderL", "unknown role"),
                         ("left_shoulder=Nope", "'Nope'"), (str(tmp_path / "none.json"), "cannot read")):
        assert cli_main([*base, "--joint-names", bad]) == 2
        assert message in capsys.readouterr().err
    assert cli_main(["evaluate", "--joint-names", "left_shoulder=ShoulderL"]) == 2
    assert "--motion-file" in capsys.readouterr().err
    names = tmp_path / "names.json"
    names.write_text(json.dumps({"left_shoulder": "ShoulderL", "right_shoulder": "ShoulderR"}))
    js = tmp_path / "renamed.json"
    assert cli_main([*base, "--joint-names", str(names), "--json", str(js)]) == 0
    doc = json.loads(js.read_text())
    assert doc["config"]["joint_names"] == {"left_shoulder": "ShoulderL", "right_shoulder": "ShoulderR"}
    assert doc["config"]["akc_plus"] is None  # (AKC+'s settings: the defaults)
    # The same motion as the original file's, so the same raw errors.
    orig = tmp_path / "orig.json"
    argv = ["evaluate", "--motion-file", str(Path(__file__).parent / "data" / "mocap" / "upper_body.bvh"),
            "--width", "160", "--height", "120", "--methods", "Raw,KF", "--json", str(orig)]
    assert cli_main(argv) == 0
    a = {(r["motion"], r["method"], r["joint"]): r["rmse_cm"] for r in doc["results"]}
    b = {(r["motion"], r["method"], r["joint"]): r["rmse_cm"] for r in json.loads(orig.read_text())["results"]}
    assert list(a.values()) == list(b.values()) and len(a) == 2 * len(ARM_JOINTS)


def test_evaluate_cli_motion_file(tmp_path, capsys):
    pytest.importorskip("akc_drake.systems.depth_camera_source", reason="renderer not installed yet")
    from pathlib import Path

    bvh = Path(__file__).parent / "data" / "mocap" / "upper_body.bvh"
    js = tmp_path / "file.json"
    argv = [
        "evaluate",
        "--motion-file",
        str(bvh),
        "--width",
        "160",
        "--height",
        "120",
        "--methods",
        "Raw,KF,AKC(KF)",
        "--json",
        str(js),
    ]
    assert cli_main(argv) == 0
    printed = capsys.readouterr().out
    assert "Motion upper_body" in printed and "(34.86)" not in printed  # no paper figures beside a recording
    # nor the paper's scenario in the titles (its shoulder held still and occluded): the joint
    assert "TABLE1: Avg. RMSE (cm) of the left shoulder" in printed and "occluded static" not in printed
    assert "TABLE2: The left elbow in Motion upper_body" in printed
    doc = json.loads(js.read_text())
    assert doc["config"]["motion_file"] == str(bvh) and doc["config"]["cycles"] is None
    assert {r["motion"] for r in doc["results"]} == {"upper_body"}
    assert doc["sessions"]["upper_body"]["cycles"] == 1
    # The whole file is evaluated (no cycle left out).
    assert doc["sessions"]["upper_body"]["evaluated_frames"] == doc["sessions"]["upper_body"]["frames"]
    assert all(r["range_cm"] < 1e-6 for r in doc["arm_length_range_cm"] if r["method"] == "AKC(KF)")
