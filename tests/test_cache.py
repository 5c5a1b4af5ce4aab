"""The render cache (akc_drake.evaluation.cache): computed once, reused, renders again when the spec changes."""

from __future__ import annotations

import numpy as np
import pytest

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.evaluation import cache as C
from akc_drake.evaluation.session import Session

INTR = CameraIntrinsics(width=160, height=120, fx=154.0, fy=154.0, cx=79.5, cy=59.5)


class CountingRenderer:
    """A stand-in renderer: a small deterministic session per spec; counts its calls."""

    def __init__(self):
        self.calls: list[dict] = []

    def __call__(self, spec, progress=None):
        self.calls.append(spec)
        rng = np.random.default_rng(spec["seed"])
        T = 8
        truth = rng.normal(size=(T, 12, 3))
        if progress is not None:
            progress(T, spec["name"])
        return Session(
            np.arange(T) / 10.0,
            truth + 0.01,
            np.ones((T, 12)),
            rng.normal(size=(T, 12, 2)),
            truth,
            INTR,
            spec["name"],
            source_time_s=np.full(T, 0.05),
        )


def spec(**kw):
    base = dict(intrinsics=INTR, seed=1)
    base.update(kw)
    return C.render_spec("I", {"kind": "builtin", "name": "I", "cycles": 2}, **base)


def test_second_call_does_not_render_and_a_changed_spec_does(tmp_path):
    r = CountingRenderer()
    frames = []
    s1, hit1 = C.cached_render(spec(), cache=tmp_path, render=r, progress=lambda n, name: frames.append(n))
    s2, hit2 = C.cached_render(spec(), cache=tmp_path, render=r, progress=lambda n, name: frames.append(n))
    assert (hit1, hit2) == (False, True) and len(r.calls) == 1
    assert frames == [8, 8]  # a hit reports its frames at once
    for k in ("t", "raw", "visibility", "pixels", "truth", "cycle_starts", "source_time_s"):
        assert getattr(s1, k).tobytes() == getattr(s2, k).tobytes()
    assert s2.intrinsics == INTR and s2.motion == "I"
    # Any change of the spec renders again: seed, camera, cycles, detector.
    C.cached_render(spec(seed=2), cache=tmp_path, render=r)
    C.cached_render(spec(intrinsics=CameraIntrinsics()), cache=tmp_path, render=r)
    C.cached_render(
        C.render_spec("I", {"kind": "builtin", "name": "I", "cycles": 3}, intrinsics=INTR, seed=1),
        cache=tmp_path,
        render=r,
    )
    C.cached_render(spec(detector="mediapipe"), cache=tmp_path, render=r)
    C.cached_render(spec(options={"surface_offset_m": 0.0}), cache=tmp_path, render=r)
    assert len(r.calls) == 6
    assert len({C.spec_key(s) for s in r.calls}) == 6
    assert C._render_kwargs(spec(options={"surface_offset_m": 0.0})) == {"surface_offset_m": 0.0}
    # Each entry is the session plus its spec, under renders/<k[:2]>/<k>.npz.
    key = C.spec_key(spec())
    assert (tmp_path / "renders" / key[:2] / f"{key}.npz").is_file()
    assert (tmp_path / "renders" / key[:2] / f"{key}.json").is_file()


def test_a_renderer_change_renders_again(tmp_path, monkeypatch):
    r = CountingRenderer()
    C.cached_render(spec(), cache=tmp_path, render=r)
    monkeypatch.setattr(C, "renderer_fingerprint", lambda: "another renderer")
    C.cached_render(spec(), cache=tmp_path, render=r)
    assert len(r.calls) == 2


def test_fingerprint_covers_the_renderer_not_the_evaluation():
    import akc_drake

    fp = C.renderer_fingerprint()
    assert len(fp) == 64 and fp == C.renderer_fingerprint()
    root = __import__("pathlib").Path(akc_drake.__file__).parent
    files = {str(p.relative_to(root)) for p in C.fingerprint_files()}
    assert "systems/depth_camera_source.py" in files and "operator/motions.py" in files
    assert "__init__.py" in files  # the version
    assert {"operator/skinned.py", "core/skinning.py", "io/mediapipe_detector.py", "operator/bvh.py"} <= files
    assert "evaluation/session.py" in files  # the stored format
    # What only reads sessions is not in it: editing a corrector or a filter keeps the renders.
    assert not files & {"core/akc.py", "core/akc_plus.py", "core/kalman.py", "evaluation/methods.py"}
    assert "core/_compiled_sources.json" not in files  # rewritten by every rebuild of the compiled corrector
    assert not any(f.startswith("commands/") for f in files)
    assert any(f.endswith(".sdf") for f in files)  # the models


def test_dependencies_of_the_body_and_detector_are_in_the_key(monkeypatch):
    assert "mediapipe" not in C.dependency_fingerprint(spec())
    assert "mediapipe" in C.dependency_fingerprint(spec(detector="mediapipe"))
    assert "anny" in C.dependency_fingerprint(spec(body="skinned"))
    key = C.spec_key(spec(detector="mediapipe"))
    monkeypatch.setattr(C, "_pose_model_sha256", lambda model: "another model")
    assert C.spec_key(spec(detector="mediapipe")) != key
    assert C.spec_key(spec()) == C.spec_key(spec())


def test_motion_files_count_by_content(tmp_path):
    r = CountingRenderer()
    a = tmp_path / "a" / "clip.bvh"
    a.parent.mkdir()
    a.write_text("HIERARCHY one")
    b = tmp_path / "b" / "clip.bvh"
    b.parent.mkdir()
    b.write_text("HIERARCHY one")

    def file_spec(p):
        return C.render_spec("clip", {"kind": "file", "path": str(p), "skeleton": None}, intrinsics=INTR)

    C.cached_render(file_spec(a), cache=tmp_path / "c", render=r)
    C.cached_render(file_spec(b), cache=tmp_path / "c", render=r)  # same content elsewhere: a hit
    assert len(r.calls) == 1
    import os

    os.utime(b, (1e9, 1e9))  # a new modification time, same content: a hit
    C.cached_render(file_spec(b), cache=tmp_path / "c", render=r)
    assert len(r.calls) == 1
    b.write_text("HIERARCHY two")
    C.cached_render(file_spec(b), cache=tmp_path / "c", render=r)
    assert len(r.calls) == 2
    from akc_drake.errors import UserError

    with pytest.raises(UserError, match="missing.bvh: no such motion file"):
        file_spec(tmp_path / "missing.bvh")


def test_damaged_entry_renders_again(tmp_path):
    r = CountingRenderer()
    C.cached_render(spec(), cache=tmp_path, render=r)
    key = C.spec_key(spec())
    (tmp_path / "renders" / key[:2] / f"{key}.npz").write_bytes(b"garbage")
    s, hit = C.cached_render(spec(), cache=tmp_path, render=r)
    assert not hit and len(r.calls) == 2 and s.num_frames == 8
    assert C.cached_render(spec(), cache=tmp_path, render=r)[1]


def test_location_off_usage_and_clear(tmp_path, monkeypatch):
    monkeypatch.setenv("AKC_DRAKE_CACHE", str(tmp_path / "env"))
    assert C.cache_dir() == tmp_path / "env"
    monkeypatch.delenv("AKC_DRAKE_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert C.cache_dir() == tmp_path / "xdg" / "akc-drake"
    monkeypatch.setenv("AKC_DRAKE_CACHE", "off")
    assert C.cache_dir() is None
    r = CountingRenderer()
    C.cached_render(spec(), render=r)
    C.cached_render(spec(), render=r)
    assert len(r.calls) == 2  # off: never stored
    assert C.cache_usage() == {"path": None, "sessions": 0, "bytes": 0}
    monkeypatch.setenv("AKC_DRAKE_CACHE", str(tmp_path / "env"))
    C.cached_render(spec(), render=r)
    C.cached_render(spec(seed=5), render=r)
    usage = C.cache_usage()
    assert usage["sessions"] == 2 and usage["bytes"] > 0 and usage["path"] == str(tmp_path / "env")
    assert C.clear_cache() == usage
    assert C.cache_usage()["sessions"] == 0
    C.cached_render(spec(), render=r)
    assert len(r.calls) == 5
    assert C.cached_render(spec(), cache=False, render=r)[1] is False
    with pytest.raises(ValueError, match="unknown motion kind"):
        C.render_spec("x", {"kind": "video"}, intrinsics=INTR)


def test_cache_command(tmp_path, monkeypatch, capsys):
    from akc_drake.cli import main as cli_main

    monkeypatch.setenv("AKC_DRAKE_CACHE", str(tmp_path))
    r = CountingRenderer()
    C.cached_render(spec(), render=r)
    assert cli_main(["cache"]) == 0
    assert capsys.readouterr().out.startswith(f"render cache {tmp_path}: 1 sessions (")
    assert cli_main(["cache", "--clear"]) == 0
    assert f"render cache {tmp_path}: removed 1 sessions" in capsys.readouterr().out
    assert C.cache_usage()["sessions"] == 0
    monkeypatch.setenv("AKC_DRAKE_CACHE", "off")
    assert cli_main(["cache"]) == 0
    assert "off" in capsys.readouterr().out


def test_a_rig_driven_clip_counts_by_content_too(tmp_path):
    a = tmp_path / "a.bvh"
    a.write_text("HIERARCHY one")
    b = tmp_path / "b" / "a.bvh"
    b.parent.mkdir()
    b.write_text("HIERARCHY one")

    def rig_spec(p, window=None):
        rig = {"path": str(p), "skeleton": None, "window_s": window}
        return C.render_spec("clip", {"kind": "file", "path": str(p), "skeleton": None}, intrinsics=INTR,
                             body="skinned", options={"rig_clip": rig})

    assert C.spec_key(rig_spec(a)) == C.spec_key(rig_spec(b))
    assert C.spec_key(rig_spec(a, [0.0, 1.0])) != C.spec_key(rig_spec(a))
    b.write_text("HIERARCHY two")
    assert C.spec_key(rig_spec(a)) != C.spec_key(rig_spec(b))


def test_the_pose_model_named_by_the_environment_is_in_the_key(tmp_path, monkeypatch):
    """The default pose model follows ``$AKC_DRAKE_POSE_MODEL``; changing it within one process changes the key."""
    a, b = tmp_path / "a.task", tmp_path / "b.task"
    a.write_bytes(b"model a")
    b.write_bytes(b"model b")
    spec = {"detector": "mediapipe"}
    monkeypatch.setenv("AKC_DRAKE_POSE_MODEL", str(a))
    fa = C.dependency_fingerprint(spec)
    monkeypatch.setenv("AKC_DRAKE_POSE_MODEL", str(b))
    fb = C.dependency_fingerprint(spec)
    assert fa != fb
    monkeypatch.setenv("AKC_DRAKE_POSE_MODEL", str(a))
    assert C.dependency_fingerprint(spec) == fa
    assert C.dependency_fingerprint({"detector": "mediapipe", "options": {"pose_model": str(b)}}) == fb


def test_a_camera_placement_is_in_the_key_and_reaches_the_renderer(tmp_path):
    """``--camera``: a placed camera keys its own renders, the renderer gets its pose, Motions I and II reach toward
    it, and a rendered T-pose from 3 m, or from above aimed at the chest, has its joints where that camera sees
    them (the truth is in the camera frame)."""
    from akc_drake.config import parse_camera
    from akc_drake.core.skeleton import INDEX
    from akc_drake.evaluation.motion_set import tpose_spec

    far = parse_camera("distance_m=3")
    high = parse_camera("distance_m=2.5,height_m=1.1,aim_height_m=0.45")
    r = CountingRenderer()
    for camera in ("default", far, high, far):
        C.cached_render(spec(camera=camera), cache=tmp_path, render=r)
    assert len(r.calls) == 3  # the second far camera is read back
    assert C.camera_placement("default") is None and "camera_pose" not in C._render_kwargs(spec())
    placement = C._render_kwargs(spec(camera=high))["camera_pose"]
    X = placement.X_OC()
    assert np.allclose(X.translation(), [2.5, 0.0, 1.1])
    axis = X.rotation().matrix()[:, 2]  # the optical axis passes through the chest, 0.45 m above the pelvis
    t = -X.translation()[0] / axis[0]
    assert np.allclose(X.translation() + t * axis, [0.0, 0.0, 0.45])
    with pytest.raises(ValueError, match="unknown camera 'top'"):
        C.camera_placement("top")
    near_target = C._motion_of(spec())
    far_target = C._motion_of(spec(camera=far))
    assert not np.allclose(near_target.q_left, far_target.q_left)  # the reach aims at the camera 1 m farther
    hips = [INDEX["left_hip"], INDEX["right_hip"]]
    shoulders = [INDEX["left_shoulder"], INDEX["right_shoulder"]]
    level = C.render_uncached(tpose_spec(seconds=0.2, body="primitive"))
    seen_far = C.render_uncached(tpose_spec(seconds=0.2, body="primitive", camera=far))
    seen_high = C.render_uncached(tpose_spec(seconds=0.2, body="primitive", camera=high))
    pelvis = [s.truth[0, hips].mean(axis=0) for s in (level, seen_far, seen_high)]
    assert pelvis[0] == pytest.approx([0.0, 0.45, 2.0], abs=1e-9)
    assert pelvis[1] == pytest.approx([0.0, 0.45, 3.0], abs=1e-9)
    chest = seen_high.truth[0, shoulders].mean(axis=0)
    # Seen from 1.1 m above the pelvis, tilted down: the pelvis is farther than the shoulders and lower in the
    # image; the chest 0.45 m up is on the optical axis, the shoulders (0.05 m above it) just above the centre.
    assert pelvis[2][2] > chest[2] and pelvis[2][1] > 0.4 and -0.06 < chest[1] < -0.04
    assert np.isfinite(seen_high.raw[0, shoulders + hips, 2]).all()  # the simulated detector still finds them


def test_a_depth_noise_model_is_in_the_key_and_reaches_the_renderer():
    """``--depth-noise``: another model keys its own renders (the default's key unchanged: no field) and the
    renderer gets that model; a rendered T-pose's depth readings carry its error."""
    from akc_drake.config import parse_depth_noise
    from akc_drake.core.skeleton import INDEX
    from akc_drake.evaluation.motion_set import tpose_spec

    real = parse_depth_noise("sigma_disparity_px=0.3,correlation_px=4")
    assert "depth_noise" not in spec() and "depth_noise" not in spec(depth_noise="default")
    assert spec(depth_noise=real)["depth_noise"] == real
    assert len({C.spec_key(spec()), C.spec_key(spec(depth_noise=real))}) == 2
    noise = C._render_kwargs(spec(depth_noise=real))["noise"]
    assert (noise.sigma_disparity_px, noise.correlation_px) == (0.3, 4.0)
    assert "noise" not in C._render_kwargs(spec())
    with pytest.raises(ValueError, match="unknown depth noise"):
        spec(depth_noise="loud")
    # The same T-pose through both models: the correlated one's joint depths scatter several times more.
    spread = {}
    for name, model in (("default", "default"), ("real", real)):
        session = C.render_uncached(tpose_spec(seconds=1.0, depth_noise=model))
        shoulders = [INDEX["left_shoulder"], INDEX["right_shoulder"]]
        spread[name] = np.nanstd(session.raw[:, shoulders, 2] - session.truth[:, shoulders, 2], axis=0).mean()
    assert spread["real"] > 3.0 * spread["default"], spread


def test_a_scaled_operator_is_in_the_key_and_reaches_the_renderer():
    """``--body-scale``: a scaled operator keys its own renders (the default's key unchanged: no field), the
    renderer gets the scaled ``OperatorParams``, and a rendered T-pose has the scaled arms."""
    from akc_drake.core.skeleton import segment_lengths
    from akc_drake.evaluation.motion_set import tpose_spec

    assert "body_scale" not in spec() and "body_scale" not in spec(body_scale=1.0)
    assert spec(body_scale=0.8)["body_scale"] == 0.8
    assert len({C.spec_key(spec()), C.spec_key(spec(body_scale=0.8)), C.spec_key(spec(body_scale=1.2))}) == 3
    assert C._render_kwargs(spec(body_scale=0.8))["params"].dims.LUA == pytest.approx(0.8 * 0.288)
    for bad in (0.5, 1.5, True, "1"):
        with pytest.raises(ValueError, match="body scale must be a number from 0.6 to 1.4"):
            C.check_body_scale(bad)
    small = C.render_uncached(tpose_spec(seconds=0.2, body_scale=0.8))
    lengths = segment_lengths(small.truth[0])
    assert lengths["LUA"] == pytest.approx(0.8 * 0.288, abs=1e-9)
    assert lengths["RLA"] == pytest.approx(0.8 * 0.27, abs=1e-9)
