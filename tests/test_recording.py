"""Recording folder: round trip, crash safety and the errors the reader gives."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import LANDMARKS, NUM_LANDMARKS
from akc_drake.errors import UserError
from akc_drake.io.recording import (
    RecordingReader,
    RecordingWriter,
    depth_to_units,
    units_to_depth,
    write_recording,
)

K = CameraIntrinsics(width=32, height=24, fx=30.0, fy=31.0, cx=15.5, cy=11.5, depth_scale=0.001, rate_hz=10.0)


def _frames(n, seed=0, truth=True):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        color = rng.integers(0, 256, size=(K.height, K.width, 3), dtype=np.uint8)
        units = rng.integers(0, 8000, size=(K.height, K.width))
        depth = units.astype(np.float64) * K.depth_scale
        tr = rng.normal(size=(NUM_LANDMARKS, 3)) + [0, 0, 2.0] if truth else None
        out.append((0.1 * i + 0.05, color, depth, tr))
    return out


def _write(path, frames, **kw):
    with RecordingWriter(path, K, **kw) as w:
        for t, c, d, tr in frames:
            w.write(t, c, d, tr)
    return path


def test_round_trip_is_bit_exact(tmp_path):
    frames = _frames(5)
    _write(tmp_path / "rec", frames)
    r = RecordingReader(tmp_path / "rec")
    assert len(r) == 5
    assert r.intrinsics == K
    assert r.rate_hz == 10.0
    for (t, c, d, tr), f in zip(frames, r, strict=True):
        assert isinstance(f, CameraFrame)
        assert f.t == t
        assert f.color.dtype == np.uint8 and np.array_equal(f.color, c)
        assert f.depth_m.shape == (K.height, K.width)
        assert np.array_equal(f.depth_m, d)
        np.testing.assert_array_equal(f.truth_C, tr)
        assert f.intrinsics == K
    # indexing agrees with iteration, negative indices work
    assert np.array_equal(r[-1].color, frames[-1][1])
    with pytest.raises(IndexError):
        r[5]
    t, names, lm = r.ground_truth()
    assert names == LANDMARKS
    np.testing.assert_array_equal(t, [f[0] for f in frames])
    np.testing.assert_array_equal(lm, np.stack([f[3] for f in frames]))


def test_files_are_in_the_documented_format(tmp_path):
    frames = _frames(2)
    _write(tmp_path / "rec", frames)
    d = json.loads((tmp_path / "rec" / "intrinsics.json").read_text())
    assert set(d) == {"width", "height", "fx", "fy", "cx", "cy", "depth_scale", "rate_hz"}
    assert d["width"] == 32 and d["fy"] == 31.0
    # colour is stored as BGR by OpenCV: reading it raw gives the channels reversed
    bgr = cv2.imread(str(tmp_path / "rec" / "color" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(bgr[..., ::-1], frames[1][1])
    units = cv2.imread(str(tmp_path / "rec" / "depth" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert units.dtype == np.uint16
    assert np.array_equal(units, np.rint(frames[1][2] / 0.001).astype(np.uint16))
    lines = (tmp_path / "rec" / "timestamps.csv").read_text().splitlines()
    assert lines[0] == "index,t" and lines[1] == "0,0.05" and len(lines) == 3
    with np.load(tmp_path / "rec" / "ground_truth.npz", allow_pickle=False) as z:
        assert z["names"].dtype.kind == "U"
        assert z["landmarks"].shape == (2, NUM_LANDMARKS, 3)


def test_real_recording_has_no_ground_truth(tmp_path):
    _write(tmp_path / "rec", _frames(3, truth=False))
    r = RecordingReader(tmp_path / "rec")
    assert r.ground_truth() is None
    assert r[0].truth_C is None
    assert not (tmp_path / "rec" / "ground_truth.npz").exists()


def test_truth_with_other_names_is_reordered(tmp_path):
    names = ("right_wrist", "nose", "left_shoulder")
    tr = np.array([[1.0, 2, 3], [4, 5, 6], [7, 8, 9]])
    with RecordingWriter(tmp_path / "rec", K, names=names) as w:
        w.write(0.0, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32)), tr)
    r = RecordingReader(tmp_path / "rec")
    f = r[0]
    assert f.truth_C.shape == (NUM_LANDMARKS, 3)
    np.testing.assert_array_equal(f.truth_C[LANDMARKS.index("right_wrist")], [1, 2, 3])
    np.testing.assert_array_equal(f.truth_C[LANDMARKS.index("left_shoulder")], [7, 8, 9])
    assert np.isnan(f.truth_C[LANDMARKS.index("left_elbow")]).all()
    assert r.ground_truth()[1] == names


def test_crash_mid_way_leaves_a_loadable_recording(tmp_path):
    frames = _frames(7)
    w = RecordingWriter(tmp_path / "rec", K, checkpoint_every=3)
    for t, c, d, tr in frames:
        w.write(t, c, d, tr)
    # no close(): as after a crash. A half-written next frame (colour only) is ignored.
    (tmp_path / "rec" / "color" / "000007.png").write_bytes(b"\x89PNG garbage")
    r = RecordingReader(tmp_path / "rec")
    assert len(r) == 7
    assert np.array_equal(r[6].color, frames[6][1])
    t, _, lm = r.ground_truth()
    assert len(t) == 6  # checkpointed at 3 and 6 frames
    np.testing.assert_array_equal(r[5].truth_C, frames[5][3])
    assert r[6].truth_C is None
    assert not list((tmp_path / "rec").glob("**/*.tmp"))


def test_depth_quantisation():
    d = np.array([[0.0, np.nan, -1.0, 0.0004], [0.0006, 1.2344, 65.535, 70.0]])
    u = depth_to_units(d, 0.001)
    assert u.dtype == np.uint16
    np.testing.assert_array_equal(u, [[0, 0, 0, 0], [1, 1234, 65535, 0]])
    want = [[0, 0, 0, 0], [0.001, 1.234, 65.535, 0]]
    np.testing.assert_allclose(units_to_depth(u, 0.001), want, rtol=1e-12)


@settings(max_examples=40, deadline=None)
@given(
    units=st.lists(st.integers(0, 65535), min_size=1, max_size=50),
    scale=st.sampled_from([0.001, 0.0001, 0.00025, 0.002, 1e-3 / 3]),
)
def test_quantised_depth_round_trips_exactly(units, scale):
    u = np.asarray(units, dtype=np.uint16)
    d = units_to_depth(u, scale)
    assert np.array_equal(depth_to_units(d, scale), u)
    assert np.array_equal(units_to_depth(depth_to_units(d, scale), scale), d)


def test_write_recording_from_frames(tmp_path):
    frames = [
        CameraFrame(color=c, depth_m=d, t=t, intrinsics=K, truth_C=tr) for t, c, d, tr in _frames(3, seed=4)
    ]
    write_recording(tmp_path / "rec", frames)
    r = RecordingReader(tmp_path / "rec")
    assert [f.t for f in r] == [f.t for f in frames]
    assert np.array_equal(r[2].depth_m, frames[2].depth_m)


# -- writer errors ----------------------------------------------------------------------------------


def test_writer_rejects_bad_frames(tmp_path):
    with RecordingWriter(tmp_path / "rec", K) as w:
        w.write(0.0, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32)), np.zeros((12, 3)))
        with pytest.raises(ValueError, match="not after"):
            w.write(0.0, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32)), np.zeros((12, 3)))
        with pytest.raises(ValueError, match="color must be uint8"):
            w.write(1.0, np.zeros((24, 31, 3), np.uint8), np.zeros((24, 32)), np.zeros((12, 3)))
        with pytest.raises(ValueError, match="color must be uint8"):
            w.write(1.0, np.zeros((24, 32, 3), np.float32), np.zeros((24, 32)), np.zeros((12, 3)))
        with pytest.raises(ValueError, match="depth must have shape"):
            w.write(1.0, np.zeros((24, 32, 3), np.uint8), np.zeros((32, 24)), np.zeros((12, 3)))
        with pytest.raises(ValueError, match="truth_C is missing"):
            w.write(1.0, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32)), None)
        with pytest.raises(ValueError, match="truth_C must have shape"):
            w.write(1.0, np.zeros((24, 32, 3), np.uint8), np.zeros((24, 32)), np.zeros((11, 3)))
        assert len(w) == 1
    assert len(RecordingReader(tmp_path / "rec")) == 1


def test_writer_refuses_to_overwrite(tmp_path):
    _write(tmp_path / "rec", _frames(1))
    with pytest.raises(UserError, match="already holds a recording"):
        RecordingWriter(tmp_path / "rec", K)
    _write(tmp_path / "rec", _frames(2, seed=1, truth=False), overwrite=True)
    r = RecordingReader(tmp_path / "rec")
    assert len(r) == 2 and r.ground_truth() is None


# -- reader errors: each names the file (and field/line) ------------------------------------------


@pytest.fixture
def rec(tmp_path):
    return _write(tmp_path / "rec", _frames(3))


def test_no_folder(tmp_path):
    with pytest.raises(UserError, match=r"nope: recording folder not found"):
        RecordingReader(tmp_path / "nope")
    (tmp_path / "file").write_text("x")
    with pytest.raises(UserError, match=r"file: not a folder"):
        RecordingReader(tmp_path / "file")


@pytest.mark.parametrize(
    "edit, pattern",
    [
        (lambda d: d.pop("fx"), r"intrinsics\.json: missing field\(s\) fx"),
        (lambda d: d.pop("rate_hz"), r"intrinsics\.json: missing field\(s\) rate_hz"),
        (lambda d: d.update(fy="big"), r"intrinsics\.json: field fy must be a number, got 'big'"),
        (lambda d: d.update(width=-5), r"intrinsics\.json: .*width must be a positive integer, got -5"),
        (lambda d: d.update(depth_scale=0), r"json: .*depth_scale must be a positive number, got 0"),
        (lambda d: d.update(zoom=2), r"intrinsics\.json: unknown field\(s\) zoom"),
    ],
)
def test_bad_intrinsics_names_file_and_field(rec, edit, pattern):
    p = rec / "intrinsics.json"
    d = json.loads(p.read_text())
    edit(d)
    p.write_text(json.dumps(d))
    with pytest.raises(UserError, match=pattern):
        RecordingReader(rec)


def test_missing_or_broken_intrinsics(rec):
    p = rec / "intrinsics.json"
    p.write_text("{not json")
    with pytest.raises(UserError, match=r"intrinsics\.json: not valid JSON"):
        RecordingReader(rec)
    p.unlink()
    with pytest.raises(UserError, match=r"intrinsics\.json: missing"):
        RecordingReader(rec)


def test_missing_frame_png(rec):
    (rec / "depth" / "000001.png").unlink()
    with pytest.raises(UserError, match=r"depth/000001\.png: missing \(frame 1"):
        RecordingReader(rec)


def test_size_mismatch(rec):
    cv2.imwrite(str(rec / "color" / "000002.png"), np.zeros((10, 10, 3), np.uint8))
    r = RecordingReader(rec)
    r[1]
    with pytest.raises(UserError, match=r"color/000002\.png: size 10x10 does not match .* 32x24"):
        r[2]
    cv2.imwrite(str(rec / "depth" / "000000.png"), np.zeros((24, 32), np.uint8))
    with pytest.raises(UserError, match=r"depth/000000\.png: depth must be a single-channel 16-bit PNG"):
        r[0]


def test_unreadable_png(rec):
    (rec / "color" / "000000.png").write_bytes(b"not a png")
    with pytest.raises(UserError, match=r"color/000000\.png: not a readable PNG"):
        RecordingReader(rec)[0]


@pytest.mark.parametrize(
    "text, pattern",
    [
        ("index,t\n0,0.0\n1,0.1\n2,0.1\n", r"csv: line 4: timestamps not increasing \(t = 0\.1 after 0\.1\)"),
        ("index,t\n0,0.2\n1,0.1\n2,0.3\n", r"timestamps\.csv: line 3: timestamps not increasing"),
        ("index,t\n0,0.0\n1,abc\n", r"timestamps\.csv: line 3: t must be a number, got 'abc'"),
        ("index,t\n0,0.0\n2,0.1\n", r"timestamps\.csv: line 3: index must be 1"),
        ("i,time\n0,0.0\n", r"timestamps\.csv: line 1 must be the header 'index,t'"),
        ("index,t\n0,nan\n", r"timestamps\.csv: line 2: t must be finite"),
        ("index,t\n0,0.0,7\n", r"timestamps\.csv: line 2: expected 'index,t'"),
    ],
)
def test_bad_timestamps_name_file_and_line(rec, text, pattern):
    (rec / "timestamps.csv").write_text(text)
    with pytest.raises(UserError, match=pattern):
        RecordingReader(rec)


def test_missing_timestamps(rec):
    (rec / "timestamps.csv").unlink()
    with pytest.raises(UserError, match=r"timestamps\.csv: missing"):
        RecordingReader(rec)


def test_bad_ground_truth(rec):
    p = rec / "ground_truth.npz"
    np.savez(p, t=np.array([0.05, 0.15, 0.25]), names=np.array(["a"]), landmarks=np.zeros((3, 2, 3)))
    with pytest.raises(UserError, match=r"ground_truth\.npz: landmarks must be float \(3, 1, 3\)"):
        RecordingReader(rec)
    np.savez(p, t=np.array([0.05, 0.15, 0.99]), names=np.array(["a"]), landmarks=np.zeros((3, 1, 3)))
    with pytest.raises(UserError, match=r"ground_truth\.npz: t\[2\] = 0\.99 does not match timestamps\.csv"):
        RecordingReader(rec)
    np.savez(p, t=np.array([0.05]), names=np.array(["a"], dtype=object), landmarks=np.zeros((1, 1, 3)))
    with pytest.raises(UserError, match=r"ground_truth\.npz: cannot be read without pickle"):
        RecordingReader(rec)
    np.savez(p, t=np.array([0.05]))
    with pytest.raises(UserError, match=r"ground_truth\.npz: missing array\(s\) names, landmarks"):
        RecordingReader(rec)
    p.write_bytes(b"garbage")
    with pytest.raises(UserError, match=r"ground_truth\.npz: "):
        RecordingReader(rec)
