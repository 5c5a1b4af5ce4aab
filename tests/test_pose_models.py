"""MediaPipe's pose models by name, and the .task bundles built from bare landmark networks."""

from __future__ import annotations

import io
import os
import tarfile
import zipfile

import numpy as np
import pytest

from akc_drake.core.camera import CameraFrame, CameraIntrinsics
from akc_drake.core.skeleton import INDEX
from akc_drake.errors import UserError
from akc_drake.io import mediapipe_detector as mpd
from akc_drake.io import pose_models as pm

pytest.importorskip("mediapipe", reason="the 'mediapipe' extra is not installed")


@pytest.fixture
def full_task(monkeypatch):
    monkeypatch.delenv(pm.POSE_MODEL_ENV, raising=False)
    try:
        return mpd.find_pose_model("full")
    except UserError as e:
        pytest.skip(f"no pose model here: {e}")


@pytest.fixture(scope="module")
def astronaut():
    skdata = pytest.importorskip("skimage.data")
    img = skdata.astronaut()  # (512, 512, 3) uint8 RGB, shipped with scikit-image
    K = CameraIntrinsics(width=512, height=512, fx=500.0, fy=500.0, cx=255.5, cy=255.5)
    return CameraFrame(color=img, depth_m=np.zeros((512, 512)), t=0.0, intrinsics=K)


def _without_metadata(tflite: bytes) -> bytes:
    """The network with its TFLITE_METADATA entry removed (what the npm package ships)."""
    import flatbuffers
    from mediapipe.tasks.metadata import schema_py_generated as schema

    model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(tflite, 0))
    model.metadata = [m for m in model.metadata if m.name != b"TFLITE_METADATA"]
    b = flatbuffers.Builder(len(tflite))
    b.Finish(model.Pack(b), file_identifier=b"TFL3")
    return bytes(b.Output())


def test_built_bundle_detects_exactly_as_the_shipped_one(full_task, astronaut, tmp_path):
    bare = _without_metadata(zipfile.ZipFile(full_task).read("pose_landmarks_detector.tflite"))
    assert pm._metadata_entry(bare) is None
    (tmp_path / "bare.tflite").write_bytes(bare)
    built = pm.build_pose_task(tmp_path / "bare.tflite", full_task, tmp_path / "pose_landmarker_x.task")
    with zipfile.ZipFile(built) as z:
        assert sorted(z.namelist()) == ["pose_detector.tflite", "pose_landmarks_detector.tflite"]
        assert z.read("pose_detector.tflite") == zipfile.ZipFile(full_task).read("pose_detector.tflite")
        assert pm._metadata_entry(z.read("pose_landmarks_detector.tflite")) is not None
    # The same inputs, the same bytes (the model's SHA-256 is in the render cache's key: a rebuild must keep it).
    again = pm.build_pose_task(tmp_path / "bare.tflite", full_task, tmp_path / "again.task")
    assert again.read_bytes() == built.read_bytes()
    assert {i.date_time for i in zipfile.ZipFile(built).infolist()} == {(1980, 1, 1, 0, 0, 0)}  # (not the build's time)
    with mpd.MediaPipeDetector(model_path=full_task) as a, mpd.MediaPipeDetector(model_path=built) as b:
        da, db = a.detect(astronaut), b.detect(astronaut)
    assert da.person_found and db.person_found
    np.testing.assert_array_equal(da.uv, db.uv)
    np.testing.assert_array_equal(da.visibility, db.visibility)


def test_bare_network_is_refused_by_mediapipe(full_task, tmp_path):
    """Without the metadata entry MediaPipe cannot load the bundle: the entry is what the build adds."""
    ref = zipfile.ZipFile(full_task)
    p = tmp_path / "bare.task"
    with zipfile.ZipFile(p, "w") as z:
        z.writestr("pose_detector.tflite", ref.read("pose_detector.tflite"))
        z.writestr("pose_landmarks_detector.tflite", _without_metadata(ref.read("pose_landmarks_detector.tflite")))
    with pytest.raises(UserError, match=r"bare\.task: cannot load the MediaPipe pose model"):
        mpd.MediaPipeDetector(model_path=p)


def test_build_names_a_bad_file(full_task, tmp_path):
    bad = tmp_path / "pose_landmark_heavy.tflite"
    bad.write_bytes(b"\0" * 64)
    with pytest.raises(UserError, match=r"pose_landmark_heavy\.tflite: not a TFLite model"):
        pm.build_pose_task(bad, full_task, tmp_path / "out.task")
    with pytest.raises(UserError, match=r"missing\.tflite: file not found"):
        pm.build_pose_task(tmp_path / "missing.tflite", full_task, tmp_path / "out.task")
    with pytest.raises(UserError, match=r"nope\.tgz: file not found"):
        pm.landmark_networks(tmp_path / "nope.tgz")


def test_names_and_the_environment(full_task, monkeypatch, tmp_path):
    assert mpd.find_pose_model("full") == full_task
    monkeypatch.setattr(mpd, "SHARED_MODEL", tmp_path / "pose_landmarker_full.task")
    with pytest.raises(UserError, match=r"pose_landmarker_heavy\.task: MediaPipe's heavy pose model is not "
                                        r"installed; 'make install' builds it .*@mediapipe/pose"):
        mpd.find_pose_model("heavy")
    (tmp_path / "pose_landmarker_heavy.task").write_bytes(b"x")
    assert mpd.find_pose_model("heavy") == tmp_path / "pose_landmarker_heavy.task"
    monkeypatch.setenv(pm.POSE_MODEL_ENV, "heavy")
    assert mpd.find_pose_model() == tmp_path / "pose_landmarker_heavy.task"
    assert mpd.find_pose_model(str(full_task)) == full_task  # an explicit path wins over the environment
    monkeypatch.setenv(pm.POSE_MODEL_ENV, str(tmp_path / "nope.task"))
    with pytest.raises(UserError, match=r"nope\.task: pose model file not found"):
        mpd.find_pose_model()


def test_installed_heavy_model_finds_the_astronaut(monkeypatch, astronaut):
    monkeypatch.delenv(pm.POSE_MODEL_ENV, raising=False)
    try:
        path = mpd.find_pose_model("heavy")
    except UserError as e:
        pytest.skip(f"heavy model not built here: {e}")
    with mpd.MediaPipeDetector(model_path=path) as d:
        det = d.detect(astronaut)
    assert det.person_found
    # The full model's test (test_mediapipe_detector.py) checked these pixels by hand on the image.
    np.testing.assert_allclose(det.uv[INDEX["right_shoulder"]], [107, 242], atol=30)
    assert det.visibility[INDEX["left_shoulder"]] > 0.9


@pytest.fixture
def share(monkeypatch, tmp_path):
    """A share folder holding a (dummy) full model only, no pose model named anywhere."""
    monkeypatch.setenv(pm.POSE_MODEL_ENV, "restored-after-the-test")
    monkeypatch.delenv(pm.POSE_MODEL_ENV)
    monkeypatch.setattr(mpd, "SHARED_MODEL", tmp_path / "pose_landmarker_full.task")
    (tmp_path / "pose_landmarker_full.task").write_bytes(b"full")
    return tmp_path


def test_the_default_is_heavy_when_installed(share, capsys):
    assert pm.DEFAULT_POSE_MODEL == "heavy"
    (share / "pose_landmarker_heavy.task").write_bytes(b"heavy")
    assert mpd.find_pose_model() == share / "pose_landmarker_heavy.task"
    assert mpd.find_pose_model("") == share / "pose_landmarker_heavy.task"
    assert capsys.readouterr().err == ""


def test_a_missing_default_falls_back_to_full_with_one_warning(share, capsys):
    assert mpd.find_pose_model() == share / "pose_landmarker_full.task"
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1
    assert str(share / "pose_landmarker_heavy.task") in err[0]
    assert "'make install' builds it" in err[0] and "using the full model" in err[0]
    # The fallback is now the process's (and its workers') named model: no second warning, same file.
    assert os.environ[pm.POSE_MODEL_ENV] == "full"
    assert mpd.find_pose_model() == share / "pose_landmarker_full.task"
    assert capsys.readouterr().err == ""


def test_an_explicitly_named_missing_model_is_an_error(share, monkeypatch, capsys):
    with pytest.raises(UserError, match=r"pose_landmarker_heavy\.task: MediaPipe's heavy pose model is not installed"):
        mpd.find_pose_model("heavy")
    monkeypatch.setenv(pm.POSE_MODEL_ENV, "lite")
    with pytest.raises(UserError, match=r"pose_landmarker_lite\.task: MediaPipe's lite pose model is not installed"):
        mpd.find_pose_model()
    from akc_drake import cli

    capsys.readouterr()
    assert cli.main(["bench", "--quick", "--pose-model", "heavy"]) == 2  # checked before the command runs
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "pose_landmarker_heavy.task: MediaPipe's heavy pose model is not installed" in err[0]


def test_the_render_cache_keys_the_resolved_default(share):
    from akc_drake.evaluation import cache as C

    spec = {"detector": "mediapipe"}

    def named(path):
        return C.dependency_fingerprint({**spec, "options": {"pose_model": str(path)}})

    heavy = share / "pose_landmarker_heavy.task"
    heavy.write_bytes(b"heavy")
    C._pose_model_sha256_of.cache_clear()
    try:
        assert C.dependency_fingerprint(spec) == named(heavy) != named(share / "pose_landmarker_full.task")
        heavy.unlink()
        C._pose_model_sha256_of.cache_clear()  # the memo is per (model, $AKC_DRAKE_POSE_MODEL), not per file on disk
        assert C.dependency_fingerprint(spec) == named(share / "pose_landmarker_full.task")
    finally:
        C._pose_model_sha256_of.cache_clear()


def _tarball(path, members: dict[str, bytes]):
    with tarfile.open(path, "w:gz") as tf:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tf.addfile(info, io.BytesIO(data))
    return path


def test_a_tarball_other_than_the_pinned_one_is_refused(tmp_path, capsys):
    """A local archive with the right member names but other bytes: the SHA-512 check refuses it, nothing is built."""
    members = {f"package/pose_landmark_{n}.tflite": b"\0\0\0\0TFL3 altered" for n in pm.BUILT_MODELS}
    tgz = _tarball(tmp_path / "pose.tgz", members)
    with pytest.raises(UserError, match=r"pose\.tgz: SHA-512 sha512-\S+ differs from the pinned sha512-DFZsNWTs"):
        pm.landmark_networks(tgz)
    (tmp_path / "share").mkdir()
    assert pm.main([str(tmp_path / "share"), "--tarball", str(tgz)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "differs from the pinned" in err[0] and "--pose-model full still works" in err[0]
    assert list((tmp_path / "share").iterdir()) == []
