"""RealSense .db3 writing and .bag/.db3 playback through pyrealsense2 (no camera needed)."""

from __future__ import annotations

import sys
import time

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.errors import UserError
from akc_drake.io import realsense
from akc_drake.io.recording import RecordingReader, RecordingWriter
from akc_drake.io.sources import BagSource, open_source

try:
    realsense.import_pyrealsense2()
except UserError as e:  # pragma: no cover - depends on the machine
    pytest.skip(f"pyrealsense2 unusable here: {e}", allow_module_level=True)

K = CameraIntrinsics(width=64, height=48, fx=60.0, fy=61.0, cx=31.5, cy=23.5, depth_scale=0.001, rate_hz=10.0)


def _frames(n, seed=0, K=K):
    rng = np.random.default_rng(seed)
    return [
        CameraFrame(
            color=rng.integers(0, 256, (K.height, K.width, 3), dtype=np.uint8),
            depth_m=rng.integers(0, 6000, (K.height, K.width)) * K.depth_scale,
            t=0.5 + 0.1 * i,
            intrinsics=K,
        )
        for i in range(n)
    ]


def test_db3_round_trip(tmp_path):
    frames = _frames(6)
    p = tmp_path / "a.db3"
    assert realsense.write_db3(p, frames, K) == 6
    assert p.stat().st_size > 6 * K.width * K.height * 5
    with BagSource(p) as src:
        assert src.intrinsics == K
        assert src.rate_hz == 10.0
        assert not src.needs_align
        got = list(src)
    assert len(got) == 6
    for a, b in zip(frames, got, strict=True):
        assert np.array_equal(a.color, b.color)
        assert np.abs(a.depth_m - b.depth_m).max() <= K.depth_scale + 1e-12
        assert b.t == pytest.approx(a.t - frames[0].t, abs=1e-9)  # t counts from the first frame
        assert b.extras["timestamp_ms"] == pytest.approx(a.t * 1000.0)
        assert b.intrinsics == K


def test_recording_folder_to_db3_and_back(tmp_path):
    Kr = CameraIntrinsics(
        width=40, height=30, fx=35.0, fy=35.0, cx=19.5, cy=14.5, depth_scale=0.0005, rate_hz=15.0
    )
    with RecordingWriter(tmp_path / "rec", Kr) as w:
        for f in _frames(4, seed=3, K=Kr):
            w.write(f.t, f.color, f.depth_m)
    rec = RecordingReader(tmp_path / "rec")
    realsense.write_db3(tmp_path / "rec.db3", rec, rec.intrinsics)
    src = open_source(f"bag:{tmp_path / 'rec.db3'}")
    try:
        assert isinstance(src, BagSource)
        assert src.intrinsics == Kr
        got = list(src)
    finally:
        src.close()
    assert len(got) == len(rec)
    for a, b in zip(rec, got, strict=True):
        assert np.array_equal(a.color, b.color)
        np.testing.assert_allclose(b.depth_m, a.depth_m, rtol=0, atol=Kr.depth_scale)


def test_slow_consumer_loses_no_frame(tmp_path):
    frames = _frames(8, seed=1)
    realsense.write_db3(tmp_path / "s.db3", frames, K)
    got = []
    with BagSource(tmp_path / "s.db3") as src:
        for f in src:
            time.sleep(0.03)
            got.append(f.extras["frame_number"])
    assert got == list(range(8))


def test_unregistered_depth_is_aligned_to_colour(tmp_path):
    # Depth camera with a wider field of view (fx 40) than colour (fx 60), same centre, identity extrinsic.
    Kd = CameraIntrinsics(
        width=64, height=48, fx=40.0, fy=40.0, cx=31.5, cy=23.5, depth_scale=0.001, rate_hz=10.0
    )
    Kc = CameraIntrinsics(
        width=64, height=48, fx=60.0, fy=60.0, cx=31.5, cy=23.5, depth_scale=0.001, rate_hz=10.0
    )
    depth = np.full((48, 64), 1.5)
    depth[20:28, 28:36] = 1.0  # an 8x8 box 0.5 m nearer, at the centre of the depth image
    frames = [CameraFrame(np.full((48, 64, 3), 10 * i, np.uint8), depth, 0.1 * i, Kc) for i in range(3)]
    realsense.write_db3(tmp_path / "u.db3", frames, Kc, depth_intrinsics=Kd)
    with BagSource(tmp_path / "u.db3") as src:
        assert src.needs_align
        got = list(src)
    assert len(got) == 3
    d = got[0].depth_m
    near = np.isclose(d, 1.0)
    # the box grows by fx_c / fx_d = 1.5 per axis in the colour image: 8 px -> 12 px (+ edge pixels)
    assert 144 <= near.sum() <= 196
    rows, cols = np.nonzero(near)
    assert abs(rows.mean() - 23.5) < 1.0 and abs(cols.mean() - 31.5) < 1.0
    assert np.isclose(d[0, 0], 1.5) and np.isclose(d[-1, -1], 1.5)
    assert np.all(np.isclose(d, 1.0) | np.isclose(d, 1.5) | (d == 0))
    assert (d == 0).mean() < 0.05


def test_write_db3_rejects_bad_input(tmp_path):
    with pytest.raises(UserError, match=r"x\.bag: pyrealsense2 writes only \.db3"):
        realsense.write_db3(tmp_path / "x.bag", _frames(1), K)
    with pytest.raises(UserError, match=r"nofolder: folder not found"):
        realsense.write_db3(tmp_path / "nofolder" / "x.db3", _frames(1), K)
    bad = _frames(2)
    bad[1].color = bad[1].color[:, :10]
    with pytest.raises(ValueError, match=r"frame 1: color must be uint8 \(48, 64, 3\)"):
        realsense.write_db3(tmp_path / "y.db3", bad, K)
    back = _frames(2)
    back[1].t = back[0].t
    with pytest.raises(ValueError, match=r"frame 1: t = .* must be finite and after"):
        realsense.write_db3(tmp_path / "z.db3", back, K)


def test_playback_errors_name_the_file(tmp_path):
    with pytest.raises(UserError, match=r"none\.db3: RealSense recording not found"):
        BagSource(tmp_path / "none.db3")
    (tmp_path / "a.txt").write_text("hello")
    with pytest.raises(UserError, match=r"a\.txt: expected a RealSense \.bag or \.db3 file"):
        BagSource(tmp_path / "a.txt")
    (tmp_path / "junk.bag").write_bytes(b"\x00" * 1000)
    with pytest.raises(UserError, match=r"junk\.bag: not a readable RealSense recording"):
        BagSource(tmp_path / "junk.bag")


def test_missing_pyrealsense2_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "pyrealsense2", None)
    with pytest.raises(UserError, match=r"pip install -e \.\[realsense\]"):
        realsense.import_pyrealsense2()


def test_intrinsics_from_rs_undoes_float32_noise():
    class RsIntrinsics:
        width, height, fx, fy, ppx, ppy = 640, 480, np.float32(615.123), np.float32(615.5), 319.25, 240.75

    K2 = realsense.intrinsics_from_rs(RsIntrinsics, depth_scale=np.float32(0.001), rate_hz=30)
    assert K2.depth_scale == 0.001 and K2.fx == 615.123 and K2.cx == 319.25 and K2.rate_hz == 30.0
