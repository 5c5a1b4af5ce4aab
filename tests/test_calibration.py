import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.core.calibration import (
    CalibrationReport,
    calibrate,
    calibrate_report,
    load_dims,
    manual,
    robust_mean,
    save_dims,
)
from akc_drake.core.skeleton import INDEX, SEGMENT_NAMES, BodyDimensions
from akc_drake.errors import UserError

TRUE = BodyDimensions(LUA=0.285, LLA=0.270, RUA=0.295, RLA=0.269, SW=0.366)


def tpose(d: BodyDimensions) -> np.ndarray:
    """Operator 2 m from the camera, arms straight out to the sides (x right in the camera frame)."""
    p = np.zeros((12, 3))
    half = d.SW / 2
    # The operator faces the camera: their left is the camera's right (+x).
    p[INDEX["left_shoulder"]] = [half, 0.0, 2.0]
    p[INDEX["left_elbow"]] = [half + d.LUA, 0.0, 2.0]
    p[INDEX["left_wrist"]] = [half + d.LUA + d.LLA, 0.0, 2.0]
    p[INDEX["right_shoulder"]] = [-half, 0.0, 2.0]
    p[INDEX["right_elbow"]] = [-half - d.RUA, 0.0, 2.0]
    p[INDEX["right_wrist"]] = [-half - d.RUA - d.RLA, 0.0, 2.0]
    p[INDEX["left_hip"]] = [0.13, 0.5, 2.0]
    p[INDEX["right_hip"]] = [-0.13, 0.5, 2.0]
    return p


def lpose(d: BodyDimensions) -> np.ndarray:
    """Upper arms out to the sides, forearms pointing up (elbows at 90 degrees)."""
    p = tpose(d)
    p[INDEX["left_wrist"]] = p[INDEX["left_elbow"]] + [0.0, -d.LLA, 0.0]
    p[INDEX["right_wrist"]] = p[INDEX["right_elbow"]] + [0.0, -d.RLA, 0.0]
    return p


def noisy_frames(base: np.ndarray, T: int = 200, sigma: float = 0.002, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return base[None] + rng.normal(0.0, sigma, (T, 12, 3))


def test_tpose_with_noise_nan_and_outliers_recovers_lengths_within_1mm():
    frames = noisy_frames(tpose(TRUE))
    # 25 frames lose a landmark (detector dropout), 10 frames have a wrong elbow depth (occlusion).
    frames[5:30, INDEX["left_elbow"], :] = np.nan
    frames[40:45, INDEX["right_wrist"], 2] = np.inf
    frames[60:70, INDEX["right_elbow"], 2] += 0.4
    dims, report = calibrate_report(frames, "tpose")
    for name in SEGMENT_NAMES:
        assert abs(getattr(dims, name) - getattr(TRUE, name)) < 1e-3, name
    assert report.frames == 200
    assert report.valid_frames["LUA"] == 175 and report.valid_frames["LLA"] == 175
    assert report.valid_frames["RLA"] == 195 and report.valid_frames["SW"] == 200
    # The 10 wrong-depth frames are rejected as outliers for both right-arm segments.
    assert report.used_frames["RUA"] <= 190 and report.used_frames["RLA"] <= 185
    assert all(0.0 < report.std_m[n] < 0.01 for n in SEGMENT_NAMES)
    assert report.elbow_angle_deg["left"] > 170 and report.warnings == []
    assert calibrate(frames) == dims


def test_lpose_calibration_and_posture_check():
    frames = noisy_frames(lpose(TRUE), T=100, seed=1)
    dims, report = calibrate_report(frames, "lpose")
    for name in SEGMENT_NAMES:
        assert abs(getattr(dims, name) - getattr(TRUE, name)) < 1e-3, name
    assert 85 < report.elbow_angle_deg["left"] < 95 and report.warnings == []
    # T-pose frames declared as an L-pose: same lengths, but the report says the posture looks wrong.
    _, wrong = calibrate_report(noisy_frames(tpose(TRUE), T=50), "lpose")
    assert len(wrong.warnings) == 2 and "left median elbow angle" in wrong.warnings[0]


def test_exact_mean_without_noise():
    frames = np.repeat(tpose(TRUE)[None], 12, axis=0)
    dims = calibrate(frames, min_valid_frames=12)
    for name in SEGMENT_NAMES:
        assert getattr(dims, name) == pytest.approx(getattr(TRUE, name), abs=1e-15)


def test_too_few_valid_frames_names_the_segment_and_count():
    frames = noisy_frames(tpose(TRUE), T=20)
    frames[3:, INDEX["right_wrist"]] = np.nan
    with pytest.raises(ValueError, match=r"segment RLA has 3 valid frame\(s\) out of 20; need at least 10"):
        calibrate(frames)
    assert calibrate(frames, min_valid_frames=3).RLA == pytest.approx(TRUE.RLA, abs=5e-3)


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((np.zeros((5, 12, 2)),), {}, r"calibration frames must have shape"),
        ((np.zeros((12, 3)),), {}, r"\(T, 12, 3\)"),
        ((np.zeros((20, 12, 3)), "apose"), {}, "tpose, lpose.*'apose'"),
        ((np.zeros((20, 12, 3)),), {"min_valid_frames": 0}, "min_valid_frames"),
    ],
)
def test_bad_arguments(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        calibrate(*args, **kwargs)


def test_implausible_lengths_are_reported_by_field():
    frames = np.repeat(tpose(TRUE)[None], 20, axis=0)
    frames[:, INDEX["left_wrist"], 0] += 5.0  # 5 m forearm: a unit mistake
    with pytest.raises(ValueError, match="calibration: BodyDimensions.LLA"):
        calibrate(frames)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.1, 0.5), min_size=5, max_size=60), st.integers(0, 3))
def test_robust_mean_ignores_far_outliers(values, n_out):
    v = np.array(values + [50.0] * n_out + [math.nan])
    mean, std, kept = robust_mean(v)
    # The outliers are a minority (at most 3 of >= 8): none survives the median/MAD rejection.
    assert 1 <= kept <= len(values)
    assert min(values) - 1e-12 <= mean <= max(values) + 1e-12
    assert std <= (max(values) - min(values)) + 1e-12


def test_manual_units_and_errors():
    d = manual(LUA=32, LLA=26, RUA=32, RLA=26, SW=33, unit="cm")
    assert d == BodyDimensions.paper_manual()
    assert manual(LUA=0.3, LLA=0.3, RUA=0.3, RLA=0.3, SW=0.3).LUA == 0.3
    with pytest.raises(ValueError, match="unit .*'inch'"):
        manual(LUA=1, LLA=1, RUA=1, RLA=1, SW=1, unit="inch")
    with pytest.raises(ValueError, match="RUA must be a number"):
        manual(LUA=0.3, LLA=0.3, RUA="x", RLA=0.3, SW=0.3)
    with pytest.raises(ValueError, match="BodyDimensions.SW"):
        manual(LUA=0.3, LLA=0.3, RUA=0.3, RLA=0.3, SW=-1)


def test_save_load_round_trip(tmp_path):
    frames = noisy_frames(tpose(TRUE), T=30)
    dims, report = calibrate_report(frames)
    path = save_dims(tmp_path / "dims.json", dims, report)
    assert load_dims(path) == dims
    doc = json.loads(path.read_text())
    assert doc["format"] == "akc-drake-body-dimensions" and doc["units"] == "m"
    assert doc["calibration"]["valid_frames"]["SW"] == 30 and doc["calibration"]["method"] == "tpose"
    # Overwrite in place without leaving temporary files behind.
    save_dims(path, BodyDimensions.paper_manual())
    assert load_dims(path) == BodyDimensions.paper_manual()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dims.json"]
    # A plain mapping in metres is accepted too.
    plain = tmp_path / "plain.json"
    plain.write_text(json.dumps(BodyDimensions.paper_participant().as_dict()))
    assert load_dims(plain) == BodyDimensions.paper_participant()
    assert isinstance(CalibrationReport("manual").as_dict(), dict)


def test_save_into_missing_folder_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="does not exist"):
        save_dims(tmp_path / "nope" / "dims.json", TRUE)


def test_failed_save_keeps_the_existing_file(tmp_path):
    path = save_dims(tmp_path / "dims.json", TRUE)
    before = path.read_text()
    target_dir = tmp_path / "adir"
    target_dir.mkdir()
    with pytest.raises(UserError, match="adir"):
        save_dims(target_dir, TRUE)  # cannot replace a folder with a file
    assert path.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "dims.json"]


@pytest.mark.parametrize(
    "content, match",
    [
        (None, "no such file"),
        ('{"format": "akc-drake-body-dimensions",\n "dimensions": {"LUA": 0.3,,}}', r"JSON \(line 2"),
        ("[1, 2]", "expected a JSON object"),
        ('{"dimensions": {"LUA": 0.3, "LLA": 0.3, "RUA": 0.3, "RLA": 0.3}}', "'dimensions': missing SW"),
        ('{"dimensions": {"LUA": 0.3, "LLA": "long", "RUA": 0.3, "RLA": 0.3, "SW": 0.3}}', "LLA must be a"),
        ('{"units": "cm", "dimensions": {"LUA": 30, "LLA": 30, "RUA": 30, "RLA": 30, "SW": 30}}', "'units'"),
        ('{"version": 9, "dimensions": {}}', "'version' is 9"),
        ('{"LUA": 0.3, "LLA": 0.3, "RUA": 0.3, "RLA": 0.3, "SW": 0.3, "XX": 1}', "unknown key.*XX"),
    ],
)
def test_load_errors_name_the_file_and_field(tmp_path, content, match):
    path = tmp_path / "bad.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(UserError, match=match) as e:
        load_dims(path)
    assert "bad.json" in str(e.value)
