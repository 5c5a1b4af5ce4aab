"""Evaluation on a set of real motion-capture clips: ``akc-drake evaluate --motion-dir DIR``.

Each clip (a BVH, or an AMC with its ASF, listed in ``DIR/mocap_sources.json`` or found in ``DIR``) drives the
simulated operator (:func:`~akc_drake.operator.retarget.load_motion_file`), is rendered through the simulated
RGB-D camera and detector once, and every method runs on the same measurements. The unit of work is
:func:`evaluate_clip`, a module-level function on plain data returning plain (JSON-able) data, mapped over the
clips by :func:`~akc_drake.evaluation.executor.run_tasks`. The same operator does every clip, so one T-pose
calibration serves all of them.

Per clip and method, the RMSE of each arm joint and axis over the whole clip, the squared-error sums and counts
(so that the pooled RMSE over all clips is exact), the share of frames whose depth the camera loses for each
joint (the occlusion filter drops or rejects it), the arm-length range and the corrector's time per frame.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import ARM_JOINTS, INDEX
from akc_drake.errors import UserError
from akc_drake.evaluation.set_metrics import (
    AXES,
    LOST_SHARE,
    lost_frames,
    lost_joint_gain,
    paired_errors,
    pooled,
    worst_regression,
    worst_regression_3d,
)

#: Methods of the real-motion set by default (COIK is slow and is not what the set is for).
DEFAULT_METHODS: tuple[str, ...] = ("KF", "EKF", "AKC(KF)", "AKC+(KF)", "AKC(EKF)", "AKC+(EKF)")
MANIFEST = "mocap_sources.json"


def find_clips(motion_dir) -> list[dict]:
    """The clips of ``motion_dir``: from its ``mocap_sources.json`` (with windows and name maps), else every
    ``*.bvh``, every ``*.c3d`` and every ``*.amc`` that has an ``.asf`` of the same stem (or a single ``.asf``)
    beside it.

    Raises:
        UserError: the folder does not exist, or holds no clip, or a listed file is missing.
    """
    d = Path(motion_dir)
    if not d.is_dir():
        raise UserError(f"--motion-dir {d}: no such folder")
    man = d / MANIFEST
    clips: list[dict] = []
    if man.is_file():
        try:
            data = json.loads(man.read_text())
            entries = data["clips"]
        except (json.JSONDecodeError, KeyError, TypeError) as e:
            raise UserError(f"{man}: not a motion-set manifest ({e})") from None
        for e in entries:
            clip = {
                "name": str(e["name"]),
                "path": str(d / e["file"]),
                "skeleton": str(d / e["skeleton"]) if e.get("skeleton") else None,
                "window_s": list(e["window_s"]) if e.get("window_s") else None,
                "names": dict(e["names"]) if e.get("names") else None,
                "activity": e.get("activity", ""),
            }
            if not Path(clip["path"]).is_file():
                raise UserError(f"{man}: clip {clip['name']}: file {clip['path']} is missing (run: make mocap-data)")
            clips.append(clip)
    else:
        asfs = sorted(d.glob("*.asf"))
        for p in sorted(d.iterdir()):
            if p.suffix.lower() in (".bvh", ".c3d"):
                clips.append({"name": p.stem, "path": str(p), "skeleton": None, "window_s": None, "names": None})
            elif p.suffix.lower() == ".amc":
                sk = p.with_suffix(".asf")
                if not sk.is_file() and len(asfs) == 1:
                    sk = asfs[0]
                if not sk.is_file():
                    raise UserError(f"{p}: an AMC motion needs its ASF skeleton ({p.stem}.asf) beside it")
                clips.append({"name": p.stem, "path": str(p), "skeleton": str(sk), "window_s": None, "names": None})
    if not clips:
        raise UserError(f"--motion-dir {d}: no .bvh, .c3d or .amc clip (and no {MANIFEST})")
    return clips


def clip_motion(clip: dict):
    """The operator motion of one clip (its window cut out, restarting at t = 0)."""
    from akc_drake.evaluation.cache import window_motion
    from akc_drake.operator.retarget import load_motion_file

    m = load_motion_file(clip["path"], clip.get("skeleton"), names=clip.get("names"))
    win = clip.get("window_s")
    if win:
        m = window_motion(m, win, clip["name"])
    return m


def clip_spec(
    clip: dict,
    *,
    protocol: str = "paper",
    seed: int = 0,
    body: str = "primitive",
    detector: str = "sim",
    width: int = 640,
    height: int = 480,
    drive: str = "angles",
    rate_hz: float = 10.0,
    camera: str | dict = "default",
    body_scale: float = 1.0,
    depth_noise: str | dict = "default",
) -> dict:
    """The render spec (:func:`~akc_drake.evaluation.cache.render_spec`) of one clip: its file's and skeleton's
    content, its joint-name map and window, the seed, the camera (its rate ``rate_hz``, which the clip is retargeted
    at, its placement and its depth noise), the body, the detector and the protocol's depth extraction: everything
    that changes its rendered session (and the body's scale), so that the render cache keys it.

    Raises:
        UserError: the clip's file is missing.
    """
    from akc_drake.evaluation.cache import render_spec
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.evaluation.protocol import render_kwargs

    motion = {"kind": "file", "path": clip["path"], "skeleton": clip.get("skeleton")}
    if clip.get("names"):
        motion["names"] = dict(clip["names"])
    if clip.get("window_s"):
        motion["window_s"] = [float(x) for x in clip["window_s"]]
    options = dict(render_kwargs(protocol))
    if drive == "rig":  # the skinned body driven by the clip bone by bone (render_session's rig_clip)
        options["rig_clip"] = {"path": str(Path(clip["path"]).resolve()), "skeleton": clip.get("skeleton") and
                               str(Path(clip["skeleton"]).resolve()), "window_s": motion.get("window_s")}
        if clip.get("names"):  # (a rig without CMU names: found by role, as the 10-angle path finds its arms)
            options["rig_clip"]["names"] = dict(clip["names"])
    return render_spec(
        clip["name"],
        motion,
        intrinsics=scaled_intrinsics(width, height, rate_hz),
        seed=seed,
        body=body,
        detector=detector,
        camera=camera,
        options=options,
        body_scale=body_scale,
        depth_noise=depth_noise,
    )


def tpose_spec(*, protocol: str = "paper", seed: int = 0, body: str = "primitive", detector: str = "sim",
               seconds: float = 10.0, width: int = 640, height: int = 480, rate_hz: float = 10.0,
               camera: str | dict = "default", body_scale: float = 1.0, depth_noise: str | dict = "default") -> dict:
    """The render spec of the calibration T-pose held ``seconds`` (same camera, placement, frame rate and depth
    noise, body and detector as the clips)."""
    from akc_drake.evaluation.cache import render_spec
    from akc_drake.evaluation.experiment import scaled_intrinsics
    from akc_drake.evaluation.protocol import render_kwargs

    return render_spec(
        "tpose",
        {"kind": "hold", "pose": "tpose", "seconds": float(seconds)},
        intrinsics=scaled_intrinsics(width, height, rate_hz),
        seed=seed,
        body=body,
        detector=detector,
        camera=camera,
        options=render_kwargs(protocol),
        body_scale=body_scale,
        depth_noise=depth_noise,
    )


def render_clip(spec: dict, cache=None, progress=None):
    """The :class:`~akc_drake.evaluation.session.Session` of a spec (:func:`clip_spec`, :func:`tpose_spec`),
    through the content-addressed render cache (:func:`~akc_drake.evaluation.cache.cached_render`).

    Args:
        spec: the render spec.
        cache: None (the default folder), False (off) or a folder.
        progress: called ``progress(frames, name)`` as frames render.

    Returns:
        ``(session, hit)``.
    """
    from akc_drake.evaluation.cache import cached_render

    return cached_render(spec, progress=progress, cache=cache)


def evaluate_clip(item: dict) -> dict:
    """Evaluate every method on one clip: the unit of work of :func:`evaluate_motion_dir` (plain in, plain out).

    Args:
        item: ``{"clip": find_clips() entry, "dims": {segment: metres}, "methods": [...], "seed": int,
            "protocol": "paper" | "ours", "weights": "Wa" | "Wb" | "Wc"}``, optionally ``"body"``
            ("primitive" | "skinned"), ``"detector"`` ("sim" | "mediapipe"), ``"cache"`` (None: the default
            render cache, False: off, or a folder), ``"akc_plus"`` (AKC+ settings, field -> value, or None),
            ``"filter_settings"`` (the filters' settings changed from the protocol's, field -> value, or None),
            ``"correctors"`` (correctors of your own, name -> import path, which the worker imports),
            ``"camera"`` (the camera's placement: "default" or :func:`~akc_drake.config.parse_camera`'s fields),
            ``"body_scale"`` (the operator's size, ``OperatorParams.scaled``), ``"depth_noise"`` (the depth error
            model: "default" or :func:`~akc_drake.config.parse_depth_noise`'s fields) and
            ``"frame_progress"`` (a progress bar over the clip's frames as they render, on stderr).

    Returns:
        ``{"name", "frames", "duration_s", "lost_share": {joint: share}, "render": {"key", "cached",
        "seconds"}, "methods": {method: {"rmse_cm": {joint: [x, y, z]}, "sse_m2": {joint: [..]}, "n":
        {joint: [..]}, "corr": {joint: [..]}, "arm_length_range_cm": {segment: cm}, "corrector_us": mean µs
        per frame or None, and for a corrector run with its filter "paired": :func:`paired_errors`}}}``.
    """
    from akc_drake.core import metrics
    from akc_drake.core.skeleton import BodyDimensions
    from akc_drake.evaluation.cache import spec_key
    from akc_drake.evaluation.methods import MethodRunner, parse_method
    from akc_drake.evaluation.protocol import method_options, with_akc_plus, with_filter_settings

    clip = item["clip"]
    protocol = item.get("protocol", "paper")
    spec = clip_spec(clip, protocol=protocol, seed=int(item.get("seed", 0)), body=item.get("body", "primitive"),
                     detector=item.get("detector", "sim"), drive=item.get("drive", "angles"),
                     rate_hz=float(item.get("rate_hz", 10.0)), camera=item.get("camera", "default"),
                     body_scale=float(item.get("body_scale", 1.0)),
                     depth_noise=item.get("depth_noise", "default"))
    t0 = time.perf_counter()
    if item.get("frame_progress"):  # in-process only: a worker's stderr is not the user's terminal
        from tqdm import tqdm

        with tqdm(desc=f"  {clip['name']}", unit="frame", file=sys.stderr, leave=False, dynamic_ncols=True) as bar:
            session, hit = render_clip(spec, cache=item.get("cache"), progress=lambda n, _name: bar.update(n))
    else:
        session, hit = render_clip(spec, cache=item.get("cache"))
    render_s = time.perf_counter() - t0
    dims = BodyDimensions(**item["dims"])
    options = with_filter_settings(method_options(protocol), item.get("filter_settings"))
    if item.get("akc_plus"):
        options = with_akc_plus(options, dict(item["akc_plus"]))
    own = dict(item.get("correctors") or {})
    if own:
        options = dataclasses.replace(options, correctors=own)
    runner = MethodRunner(session, dims, item.get("weights", "Wb"), options)
    accepted, _ = runner.occlusion()
    seen = np.isfinite(accepted[:, :, 2])  # (T, 12): the depths the occlusion filter passed
    lost = {j: float(np.mean(~seen[:, INDEX[j]])) for j in ARM_JOINTS}
    out = {
        "name": clip["name"],
        "activity": clip.get("activity", ""),
        "frames": int(session.num_frames),
        "duration_s": float(session.t[-1] - session.t[0]),
        "lost_share": lost,
        "toward_camera_share": _toward_camera_share(session.truth),
        "render": {"key": spec_key(spec), "cached": bool(hit), "seconds": render_s},
        "methods": {},
    }
    estimates = {}
    for method in item["methods"]:
        res = runner.run(method)
        est = res.estimates
        m_out = {"rmse_cm": {}, "sse_m2": {}, "n": {}, "corr": {}}
        for joint in ARM_JOINTS:
            j = INDEX[joint]
            e = est[:, j] - session.truth[:, j]
            ok = np.isfinite(e)
            m_out["sse_m2"][joint] = [float(np.sum(np.where(ok[:, a], e[:, a], 0.0) ** 2)) for a in range(3)]
            m_out["n"][joint] = [int(ok[:, a].sum()) for a in range(3)]
            m_out["rmse_cm"][joint] = [
                math.sqrt(s / n) * 100.0 if n else float("nan")
                for s, n in zip(m_out["sse_m2"][joint], m_out["n"][joint], strict=True)
            ]
            r, _, _ = metrics.pearson_per_axis(est[:, j], session.truth[:, j])
            m_out["corr"][joint] = [float(x) for x in np.asarray(r, dtype=float)]
        rng = metrics.arm_length_range(est)
        m_out["arm_length_range_cm"] = {s: float(rng[s]) * 100.0 for s in ("LUA", "LLA", "RUA", "RLA")}
        tc = res.stage_time_s.get("corrector")
        m_out["corrector_us"] = float(np.mean(tc) * 1e6) if tc is not None else None
        out["methods"][method] = m_out
        estimates[method] = est
    for method in item["methods"]:
        spec = parse_method(method, own)
        if spec.corrector != "none" and spec.filter in estimates:
            out["methods"][method]["paired"] = paired_errors(estimates[method], estimates[spec.filter],
                                                             session.truth, spec.filter,
                                                             seen=seen)
    return out


def _toward_camera_share(truth: np.ndarray) -> float:
    """Share of frames in which a wrist is at least 20 cm nearer the camera than its shoulder."""
    d = []
    for side in ("left", "right"):
        d.append(truth[:, INDEX[f"{side}_shoulder"], 2] - truth[:, INDEX[f"{side}_wrist"], 2])
    reach = np.nanmax(np.stack(d, axis=1), axis=1)
    return float(np.mean(reach > 0.20))


def evaluate_motion_dir(
    motion_dir,
    *,
    methods=DEFAULT_METHODS,
    seed: int = 0,
    protocol: str = "paper",
    weights: str = "Wb",
    body: str = "primitive",
    detector: str = "sim",
    scheduler: str = "inprocess",
    n_workers: int | None = None,
    cache=None,
    progress: bool = True,
    tpose_seconds: float = 10.0,
    drive: str = "angles",
    clips: list | None = None,
    akc_plus: dict | None = None,
    correctors: dict | None = None,
    rate_hz: float = 10.0,
    filter_settings: dict | None = None,
    camera: str | dict = "default",
    body_scale: float = 1.0,
    depth_noise: str | dict = "default",
) -> dict:
    """Calibrate once on a rendered T-pose, then :func:`evaluate_clip` on every clip of ``motion_dir``.

    Every session (the T-pose and each clip x body x detector x seed x camera x protocol) goes through the
    render cache (:mod:`akc_drake.evaluation.cache`): rendered once, reused by every method and later run.

    Args:
        motion_dir: the folder of clips (:func:`find_clips`).
        methods, seed, protocol, weights: what runs on the clips.
        body: "primitive" or "skinned" (the operator the camera sees).
        detector: "sim" or "mediapipe".
        scheduler: "inprocess", "local" or "tcp://HOST:PORT" (:func:`~akc_drake.evaluation.executor.run_tasks`).
        n_workers: local worker processes (default: one per core).
        cache: the render cache (None: the default folder, False: off, or a folder).
        progress: show the progress bars: over the clips, and in-process over each clip's frames too.
        tpose_seconds: length of the calibration T-pose.
        drive: "angles" (the operator's 10 angles) or "rig" (the skinned body driven by each clip bone by bone,
            :mod:`akc_drake.operator.rig_drive`; a rig without CMU bone names is mapped by role, and a clip
            whose arms or spine cannot be found fails with a line naming it).
        clips: evaluate these clips (:func:`find_clips` entries) instead of ``motion_dir``'s.
        akc_plus: AKC+ settings, field -> value (:func:`~akc_drake.core.akc_plus_config.akc_plus_config`;
            ``--akc-plus``), or None for the defaults.
        correctors: correctors of your own, name -> import path
            (:func:`~akc_drake.evaluation.methods.parse_correctors`; ``--add-corrector``), which ``methods`` may name
            as ``NAME(KF)`` / ``NAME(EKF)``; compared with their filters as AKC and AKC+ are.
        rate_hz: the camera's frame rate (10 Hz: the paper's). The clips are retargeted at it and the T-pose is
            rendered at it; the filters and AKC+ take their period from the sessions (a RealSense streams at 30).
            One that is not a positive number is refused by the camera's intrinsics (ValueError) before anything
            renders.
        filter_settings: the KF's and the EKF's settings changed from the protocol's, field -> value
            (:func:`~akc_drake.config.parse_filter_settings`; ``--filter-settings``), or None; the calibration's
            filter too.
        camera: the camera's placement, "default" or :func:`~akc_drake.config.parse_camera`'s (the T-pose's too).
        body_scale: the operator's size: every length times this (``--body-scale``; the T-pose's too).
        depth_noise: the depth error model, "default" or :func:`~akc_drake.config.parse_depth_noise`'s fields
            (``--depth-noise``; the T-pose's too).

    Returns:
        ``{"protocol", "seed", "rate_hz", "camera", "depth_noise", "body", "detector", "akc_plus", "filter_settings",
        "correctors", "methods", "dims_cm",
        "clips": [evaluate_clip results],
        "failures": [...], "pooled_rmse_cm", "worst_regression", "worst_regression_3d", "worst_regression_seen",
        "worst_regression_seen_3d" (the same over the frames each joint was seen), "worst_regression_lost",
        "worst_regression_lost_3d" (over the frames each joint was lost), "lost_joint_gain", "lost_frames",
        "render_cache": {"dir", "hits", "misses"}, "elapsed_s"}``.
    """
    from akc_drake.config import depth_noise_model
    from akc_drake.evaluation.cache import _resolve, camera_placement, check_body_scale
    from akc_drake.evaluation.executor import TaskFailure, run_tasks
    from akc_drake.evaluation.experiment import akc_plus_record, calibrate_session
    from akc_drake.evaluation.protocol import check_protocol, method_options, with_filter_settings

    check_protocol(protocol)
    camera_placement(camera)  # (an unknown camera, size or depth noise fails here, before anything renders)
    body_scale = check_body_scale(body_scale)
    depth_noise_model(depth_noise)
    filter_settings = dict(filter_settings) if filter_settings else None
    options = with_filter_settings(method_options(protocol), filter_settings)  # (a bad setting fails here)
    if akc_plus:
        from akc_drake.core.akc_plus_config import akc_plus_config

        akc_plus_config(akc_plus)  # (an unknown or bad setting is an error before anything renders)
    settings = akc_plus_record(akc_plus)  # (plain data: it crosses to the workers)
    t0 = time.perf_counter()
    clips = find_clips(motion_dir) if clips is None else list(clips)
    from tqdm import tqdm

    spec = tpose_spec(protocol=protocol, seed=seed, body=body, detector=detector, seconds=tpose_seconds,
                      rate_hz=rate_hz, camera=camera, body_scale=body_scale, depth_noise=depth_noise)
    with tqdm(desc="T-pose", unit="frame", file=sys.stderr, disable=not progress, dynamic_ncols=True) as bar:
        tpose, tpose_hit = render_clip(spec, cache=cache, progress=lambda n, _name: bar.update(n))
    dims = calibrate_session(tpose, "tpose", options)
    cache_arg = None if cache is None else (False if cache is False else str(cache))
    items = [
        {"clip": c, "dims": dims.as_dict(), "methods": list(methods), "seed": seed, "protocol": protocol,
         "weights": weights, "body": body, "detector": detector, "cache": cache_arg, "drive": drive,
         "akc_plus": settings, "correctors": dict(correctors or {}), "rate_hz": float(rate_hz), "camera": camera,
         "body_scale": float(body_scale), "depth_noise": depth_noise, "filter_settings": filter_settings,
         "frame_progress": bool(progress) and scheduler == "inprocess"}
        for c in clips
    ]
    raw = run_tasks(evaluate_clip, items, scheduler=scheduler, n_workers=n_workers, desc="clips",
                    labels=[c["name"] for c in clips], progress=progress)
    results = [r for r in raw if not isinstance(r, TaskFailure)]
    failures = [r.line() for r in raw if isinstance(r, TaskFailure)]
    hits = int(tpose_hit) + sum(1 for r in results if r["render"]["cached"])
    root = _resolve(cache)
    out = {
        "protocol": protocol,
        "seed": seed,
        "rate_hz": float(rate_hz),
        "camera": camera,
        "depth_noise": depth_noise,
        "body": body,
        "body_scale": float(body_scale),
        "detector": detector,
        "drive": drive,
        "akc_plus": settings,
        "filter_settings": filter_settings,
        "correctors": dict(correctors or {}),
        "methods": list(methods),
        "dims_cm": {k: v * 100.0 for k, v in dims.as_dict().items()},
        "clips": results,
        "failures": failures,
        "pooled_rmse_cm": pooled(results, methods),
        "worst_regression": {},
        "worst_regression_3d": {},
        "worst_regression_seen": {},
        "worst_regression_seen_3d": {},
        "worst_regression_lost": {},
        "worst_regression_lost_3d": {},
        "lost_joint_gain": {},
        "lost_frames": {},
        "render_cache": {"dir": None if root is None else str(root), "hits": hits,
                         "misses": 1 + len(results) - hits},
    }
    for corr in ("AKC", "AKC+", *(correctors or {})):
        for filt in ("KF", "EKF"):
            name = f"{corr}({filt})"
            if name in methods and filt in methods:
                out["worst_regression"][name] = worst_regression(results, name, filt)
                out["worst_regression_3d"][name] = worst_regression_3d(results, name, filt)
                for frames in ("seen", "lost"):
                    out[f"worst_regression_{frames}"][name] = worst_regression(results, name, filt, frames)
                    out[f"worst_regression_{frames}_3d"][name] = worst_regression_3d(results, name, filt, frames)
                out["lost_joint_gain"][name] = lost_joint_gain(results, name, filt)
                out["lost_frames"][name] = lost_frames(results, name, filt)
    out["elapsed_s"] = time.perf_counter() - t0
    return out


def _setup(result: dict) -> str:
    """", skinned body, mediapipe detector" when not the default primitive body and simulated detector, ", 30
    Hz" when not the default 10 Hz camera and the camera's placement when not the default one."""
    from akc_drake.config import describe_camera, describe_depth_noise

    body, det, camera = result.get("body", "primitive"), result.get("detector", "sim"), result.get("camera", "default")
    rate, scale = float(result.get("rate_hz", 10.0)), float(result.get("body_scale", 1.0))
    noise = result.get("depth_noise", "default")
    return ("" if (body, det) == ("primitive", "sim") else f", {body} body, {det} detector") + (
        "" if rate == 10.0 else f", {rate:g} Hz") + ("" if camera == "default" else f", {describe_camera(camera)}") + (
        "" if scale == 1.0 else f", the operator scaled {scale:g}") + (
        "" if noise in (None, "default") else f", {describe_depth_noise(noise)}")


def motion_dir_tables(result: dict) -> list:
    """Per-clip tables (mean arm-joint RMSE per axis and method) and the pooled table (per joint and axis)."""
    from akc_drake.evaluation.report import Table

    methods = result["methods"]
    tables = []
    for axis_i, ax in enumerate(AXES):
        rows = [c["name"] for c in result["clips"]]
        vals = [[float(np.mean([c["methods"][m]["rmse_cm"][j][axis_i] for j in ARM_JOINTS])) for m in methods]
                for c in result["clips"]]
        t = Table(f"clips_{ax}", f"Mean {ax} RMSE (cm) over the six arm joints, per clip "
                  f"({result['protocol']} protocol{_setup(result)})", rows, list(methods), np.array(vals))
        tables.append(t)
    rows, vals = [], []
    for joint in ARM_JOINTS:
        for axis_i, ax in enumerate(AXES):
            rows.append(f"{joint} {ax}")
            vals.append([result["pooled_rmse_cm"][m][joint][axis_i] for m in methods])
    t = Table("pooled", f"Pooled RMSE (cm) over {len(result['clips'])} real mocap clips "
              f"({result['protocol']} protocol{_setup(result)})", rows, list(methods), np.array(vals))
    seen_on = " on the frames the joint was seen (depth passed the occlusion filter)"
    lost_on = " on the frames the joint was lost (depth dropped or not measured)"
    for key, what, on in (("worst_regression", "worst increase", None),
                          ("worst_regression_3d", "worst 3D RMSE increase", None),
                          ("worst_regression_seen", "worst increase", seen_on),
                          ("worst_regression_seen_3d", "worst 3D increase", seen_on),
                          ("worst_regression_lost_3d", "worst 3D increase", lost_on)):
        # (All but the first are absent from results before session 26 (3D), 30 (seen) or 31 (lost).)
        for name, w in (result[key] if key == "worst_regression" else result.get(key, {})).items():
            if "clip" in w:
                where = on or (" on the frames both estimate" if w.get("paired") else "")
                at = f"{w['joint']} {w['axis']}" if "axis" in w else w["joint"]
                at += f", {w['frames']} frames" if "frames" in w else ""
                t.notes.append(f"{name}: {what} over its filter{where} {w['delta_cm']:+.2f} cm ({w['clip']}, {at})")
    for name, g in result["lost_joint_gain"].items():
        if g["pairs"]:
            d3 = (f"; 3D {g['filter_3d_cm']:.2f} -> {g['corrected_3d_cm']:.2f}"
                  if g.get("filter_3d_cm") is not None else "")
            t.notes.append(f"{name}: z RMSE on the {g['pairs']} (clip, joint) pairs the camera loses "
                           f"(>= {LOST_SHARE:.0%} of frames): filter {g['filter_z_cm']:.2f} -> "
                           f"{g['corrected_z_cm']:.2f} cm{d3}")
        lf = result.get("lost_frames", {}).get(name)  # (absent before session 31)
        if lf and lf["frames"]:
            t.notes.append(f"{name}: 3D RMSE over the {lf['frames']} joint-frames an arm joint was lost: filter "
                           f"{lf['filter_3d_cm']:.2f} -> {lf['corrected_3d_cm']:.2f} cm; worse on "
                           f"{lf['pairs_worse_3d']} of {lf['pairs']} (clip, joint) pairs")
        if g.get("only_frames"):
            t.notes.append(f"{name}: a depth on {g['only_frames']} joint-frames where its filter has none "
                           f"(z RMSE {g['only_z_cm']:.2f} cm there)")
    tables.append(t)
    return tables


def plot_errors_per_clip(result: dict, path) -> Path:
    """Bar chart of the mean 3D arm-joint RMSE per clip and method (matplotlib.figure.Figure, no pyplot)."""
    from matplotlib.figure import Figure

    from akc_drake.fileio import atomic_write_bytes

    methods = result["methods"]
    clips = result["clips"]
    fig = Figure(figsize=(max(6.0, 0.9 * len(clips) + 2), 4.0), layout="constrained")
    ax = fig.add_subplot()
    width = 0.8 / max(len(methods), 1)
    x = np.arange(len(clips))
    for k, m in enumerate(methods):
        vals = [float(np.mean([np.sqrt(np.sum(np.square(c["methods"][m]["rmse_cm"][j]))) for j in ARM_JOINTS]))
                for c in clips]
        ax.bar(x + (k - (len(methods) - 1) / 2) * width, vals, width, label=m)
    ax.set_xticks(x, [c["name"] for c in clips], rotation=30, ha="right")
    ax.set_ylabel("mean arm-joint 3D RMSE (cm)")
    ax.set_title(f"Error per real mocap clip and method ({result['protocol']} protocol{_setup(result)})")
    ax.legend(fontsize=7, ncols=min(len(methods), 3))
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, buf.getvalue())
    return path
