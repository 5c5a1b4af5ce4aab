"""``akc-drake evaluate``: reproduce the paper's tables and figures against ground truth.

Renders the calibration poses and each motion once, runs every method on the same measurements,
prints the tables in the paper's layout (ours, the paper's figure in brackets), and writes
``--json`` (DESIGN.md keys) and ``--out DIR`` (``report.md``, ``tables/*.csv``, ``figures/*.png``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from akc_drake.errors import UserError


def _joint_names(args) -> dict | None:
    """``--joint-names`` parsed (None when not given); only with ``--motion-file``."""
    text = getattr(args, "joint_names", None)
    if text is None:
        return None
    if not getattr(args, "motion_file", None):
        raise UserError("--joint-names: names the joints of a --motion-file (a --motion-dir clip's are in its "
                        "mocap_sources.json, key \"names\")")
    from akc_drake.operator.retarget import parse_joint_names

    return parse_joint_names(text)


def _akc_plus(args) -> dict | None:
    """``--akc-plus`` parsed (None when not given); an error when no AKC+ method runs."""
    text = getattr(args, "akc_plus", None)
    if text is None:
        return None
    from akc_drake.config import parse_akc_plus

    settings = parse_akc_plus(text)
    methods = getattr(args, "methods", None)
    if methods is not None and "AKC+" not in methods:
        raise UserError(f"--akc-plus: sets AKC+, but --methods {methods!r} runs none (add AKC+(KF) or AKC+(EKF))")
    return settings


def _filter_settings(args) -> dict | None:
    """``--filter-settings`` parsed (None when not given)."""
    text = getattr(args, "filter_settings", None)
    if text is None:
        return None
    from akc_drake.config import parse_filter_settings

    return parse_filter_settings(text)


def _correctors(args) -> dict:
    """``--add-corrector`` parsed: ``{NAME: import path}`` (empty when not given)."""
    items = getattr(args, "add_corrector", None)
    if not items:
        return {}
    from akc_drake.evaluation.methods import parse_correctors

    try:
        return parse_correctors(items)
    except ValueError as e:
        raise UserError(f"--add-corrector: {e}") from None


def _methods(args, default, correctors: dict) -> tuple[str, ...]:
    """``--methods`` parsed (``default`` when not given, with each of ``correctors``' KF and EKF variants)."""
    from akc_drake.evaluation.methods import parse_methods

    own = tuple(f"{c}({f})" for c in correctors for f in ("KF", "EKF"))
    try:
        methods = parse_methods(args.methods if args.methods is not None else (*default, *own), correctors)
    except ValueError as e:
        raise UserError(
            str(e) if str(e).startswith("--methods") else f"--methods {args.methods!r}: {e}"
        ) from None
    for c in correctors:
        if not any(m.startswith(f"{c}(") for m in methods):
            raise UserError(f"--add-corrector {c}: --methods {args.methods!r} runs none of it "
                            f"(add {c}(KF) or {c}(EKF))")
    return methods


def _motion_file_options(args) -> tuple[str | None, str | None]:
    mf, sk = getattr(args, "motion_file", None), getattr(args, "skeleton", None)
    if mf is None:
        if sk is not None:
            raise UserError(f"--skeleton {sk}: only used with --motion-file FILE.amc")
        return None, None
    p = Path(mf)
    suffix = p.suffix.lower()
    if suffix not in (".bvh", ".amc", ".c3d"):
        raise UserError(
            f"--motion-file {mf}: unknown file type {p.suffix!r} (expected .bvh, .c3d, or .amc with --skeleton)"
        )
    if not p.is_file():
        raise UserError(f"--motion-file {mf}: no such file")
    if suffix == ".amc":
        if sk is None:
            raise UserError(f"--motion-file {mf}: an AMC motion needs its skeleton, --skeleton FILE.asf")
        if Path(sk).suffix.lower() != ".asf":
            raise UserError(f"--skeleton {sk}: expected an .asf file")
        if not Path(sk).is_file():
            raise UserError(f"--skeleton {sk}: no such file")
    elif sk is not None:
        raise UserError(f"--skeleton {sk}: only used with an .amc motion file, not {p.suffix}")
    return str(p), (str(sk) if sk else None)


def _camera(args):
    """``--camera``, read (:func:`~akc_drake.config.parse_camera`)."""
    from akc_drake.config import parse_camera

    return parse_camera(getattr(args, "camera", None) or "default")


def _depth_noise(args):
    """``--depth-noise``, read (:func:`~akc_drake.config.parse_depth_noise`)."""
    from akc_drake.config import parse_depth_noise

    return parse_depth_noise(getattr(args, "depth_noise", None) or "default")


def _body_scale(args) -> float:
    """``--body-scale``, checked (a UserError names the range)."""
    from akc_drake.evaluation.cache import check_body_scale

    try:
        return check_body_scale(getattr(args, "body_scale", 1.0))
    except ValueError as e:
        raise UserError(f"--body-scale: {e}") from None


def _rate_hz(args) -> float:
    """``--rate-hz``, checked (a UserError names a rate outside 1-240 Hz)."""
    rate = getattr(args, "rate_hz", 10.0)
    if not (math.isfinite(rate) and 1.0 <= rate <= 240.0):
        raise UserError(f"--rate-hz must be a frame rate between 1 and 240 Hz, got {rate:g}")
    return float(rate)


def build_config(args):
    """An :class:`~akc_drake.evaluation.experiment.ExperimentConfig` from parsed options.

    Raises:
        UserError: naming the option and its value.
    """
    from akc_drake.evaluation.experiment import ExperimentConfig
    from akc_drake.evaluation.methods import METHODS, MethodOptions

    if args.cycles < 1:
        raise UserError(f"--cycles must be at least 1, got {args.cycles}")
    rate = _rate_hz(args)
    correctors = _correctors(args)
    methods = _methods(args, METHODS, correctors)
    motion_file, skeleton = _motion_file_options(args)
    motions = ("I", "II") if args.motion == "both" else (args.motion,)
    akc_plus = _akc_plus(args)
    try:
        return ExperimentConfig(
            motions=motions,
            cycles=args.cycles,
            seed=args.seed,
            methods=methods,
            weights=args.weights,
            width=getattr(args, "width", 640),
            height=getattr(args, "height", 480),
            rate_hz=rate,
            motion_file=motion_file,
            skeleton=skeleton,
            joint_names=_joint_names(args),
            body=getattr(args, "body", "primitive"),
            detector="mediapipe" if getattr(args, "detector", "sim") == "both" else getattr(args, "detector", "sim"),
            protocol=getattr(args, "protocol", "paper"),
            options=MethodOptions(akc_plus_config=akc_plus, correctors=correctors or None),
            filter_settings=_filter_settings(args),
            camera=_camera(args),
            body_scale=_body_scale(args),
            depth_noise=_depth_noise(args),
        )
    except ValueError as e:
        raise UserError(str(e)) from None


def _check_outputs(args) -> None:
    """Fail before the long run when an output cannot be written."""
    if args.json:
        parent = Path(args.json).resolve().parent
        if parent.exists() and not parent.is_dir():
            raise UserError(f"--json {args.json}: {parent} is not a folder")
        if Path(args.json).is_dir():
            raise UserError(f"--json {args.json}: is a folder, expected a file name")
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise UserError(f"--out {args.out}: exists and is not a folder")


def run(config, progress_bar: bool = True, scheduler: str = "local", n_workers: int | None = None):
    """Run the experiment as tasks (:func:`~akc_drake.evaluation.tasks.evaluate_tasks`) with tqdm progress bars.

    Args:
        config: the experiment.
        progress_bar: show the progress bars (stderr).
        scheduler: "local" (a LocalCluster on this machine's cores), "inprocess" or "tcp://HOST:PORT".
        n_workers: local worker processes (default: one per core).
    """
    from akc_drake.evaluation.tasks import evaluate_tasks

    return evaluate_tasks(
        config,
        scheduler=scheduler,
        n_workers=n_workers,
        progress=progress_bar,
        log=lambda line: print(f"akc-drake evaluate: {line}", file=sys.stderr),
    )


def _export(ev, args) -> None:
    """--export: every method's skeleton per motion, and the RTS smoother's gain (exports/rts_gain.json)."""
    from akc_drake.fileio import write_json as write_plain_json
    from akc_drake.pipeline.export import export_evaluation

    out = Path(args.out) / "exports"
    exp = export_evaluation(ev, args.export, out, frame=args.export_frame)
    write_plain_json(out / "rts_gain.json", exp["rts_gain"])
    print(f"wrote {len(exp['files'])} exports to {out}")
    for motion, gain in exp["rts_gain"].items():
        for stage, g in gain.items():
            print(f"  motion {motion}, {stage}: RMSE forward {g['forward_rmse_cm']:.2f} cm, "
                  f"RTS {g['rts_rmse_cm']:.2f} cm (coverage {g['coverage']:.0%})")


def _rig_clips(args) -> list | None:
    """``--drive rig``: the clip of ``--motion-file`` (evaluated as a one-clip motion set), or None for
    ``--motion-dir``'s clips."""
    if getattr(args, "body", "primitive") != "skinned":
        raise UserError("--drive rig: the rig is the skinned body's; add --body skinned")
    if getattr(args, "motion_file", None):
        if getattr(args, "motion_dir", None):
            raise UserError("--motion-file: not used with --motion-dir")
        mf, sk = _motion_file_options(args)
        from akc_drake.operator.rig_drive import read_clip

        names = _joint_names(args)
        read_clip(mf, sk, roles=names)  # a clip the rig cannot take is one line before the calibration renders
        return [{"name": Path(mf).stem, "path": mf, "skeleton": sk, "window_s": None, "names": names}]
    if not getattr(args, "motion_dir", None):
        raise UserError("--drive rig: give the CMU clip, --motion-file CLIP (or --motion-dir DIR)")
    return None


def run_motion_dir(args) -> int:
    """``evaluate --motion-dir DIR``: every method on every real mocap clip; per-clip and pooled tables."""
    from akc_drake.evaluation.executor import check_scheduler
    from akc_drake.evaluation.motion_set import (
        DEFAULT_METHODS,
        evaluate_motion_dir,
        find_clips,
        motion_dir_tables,
        plot_errors_per_clip,
    )
    from akc_drake.evaluation.report import format_table, write_json, write_tables

    drive = getattr(args, "drive", "angles")
    clips = _rig_clips(args) if drive == "rig" else None
    for opt in ("motion_file", "skeleton"):
        if getattr(args, opt, None) and clips is None:
            raise UserError(f"--{opt.replace('_', '-')}: not used with --motion-dir")
    rate = _rate_hz(args)
    correctors = _correctors(args)
    methods = _methods(args, DEFAULT_METHODS, correctors)
    _check_outputs(args)
    detector = getattr(args, "detector", "sim")
    if detector == "both":
        raise UserError("--detector both: not with --motion-dir (run it once with sim and once with mediapipe; "
                        "the render cache keeps both)")
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise UserError(f"--workers must be at least 1, got {workers}")
    if clips is None:
        find_clips(args.motion_dir)
    scheduler = check_scheduler(getattr(args, "scheduler", "local"))
    result = evaluate_motion_dir(args.motion_dir, methods=methods, seed=args.seed, protocol=args.protocol,
                                 weights=args.weights, body=getattr(args, "body", "primitive"), detector=detector,
                                 scheduler=scheduler, n_workers=workers, drive=drive, clips=clips,
                                 akc_plus=_akc_plus(args), correctors=correctors, rate_hz=rate,
                                 filter_settings=_filter_settings(args), camera=_camera(args),
                                 body_scale=_body_scale(args), depth_noise=_depth_noise(args))
    tables = motion_dir_tables(result)
    for t in tables:
        print(format_table(t))
        print()
    for f in result["failures"]:
        print(f"failed: {f}")
    if args.json:
        write_json(args.json, result)
        print(f"wrote {args.json}")
    if args.out:
        write_tables(tables, args.out)
        plot_errors_per_clip(result, Path(args.out) / "figures" / "error_per_clip.png")
        print(f"wrote {args.out}/tables/*.csv and {args.out}/figures/error_per_clip.png")
    rc = result["render_cache"]
    where = rc["dir"] or "off (AKC_DRAKE_CACHE=off)"
    print(f"render cache {where}: {rc['hits']} session(s) read, {rc['misses']} rendered")
    print(f"{len(result['clips'])} clips, {result['elapsed_s']:.1f} s")
    return 1 if result["failures"] else 0


def main(args) -> int:
    from akc_drake.evaluation.report import format_table, write_evaluation, write_json

    if getattr(args, "motion_dir", None) or getattr(args, "drive", "angles") == "rig":
        return run_motion_dir(args)
    config = build_config(args)
    _check_outputs(args)
    if getattr(args, "export", None):
        from akc_drake.pipeline.export import check_format

        if not args.out:
            raise UserError("--export writes into --out DIR/exports: give --out")
        for f in args.export.split(","):
            if f.strip():
                check_format(f, "--export")
    if config.motion_file:
        # Read the motion file now: a bad file is reported in one line before the calibration renders.
        from akc_drake.operator.retarget import load_motion_file

        load_motion_file(config.motion_file, config.skeleton, names=config.joint_names)
    from akc_drake.evaluation.executor import check_scheduler

    scheduler = check_scheduler(getattr(args, "scheduler", "local"))
    workers = getattr(args, "workers", None)
    if workers is not None and workers < 1:
        raise UserError(f"--workers must be at least 1, got {workers}")
    ev_sim = None
    if getattr(args, "detector", "sim") == "both":  # the simulated detector first, then MediaPipe (reported)
        import dataclasses

        ev_sim = run(dataclasses.replace(config, detector="sim"), scheduler=scheduler, n_workers=workers)
    ev = run(config, scheduler=scheduler, n_workers=workers)
    for table in ev.tables:
        print(format_table(table))
        print()
    from akc_drake.evaluation.detector_metrics import detector_report, format_report, side_by_side

    det = {name: detector_report(run.session) for name, run in ev.runs.items()}
    det_md = "".join(format_report(f"motion {name}", rep) + "\n" for name, rep in det.items())
    print(det_md)
    sections = [f"## The 2D detector ({config.detector}) on the {config.body} operator\n\n" + det_md]
    if ev_sim is not None:
        sections.append(side_by_side(ev_sim.tables, ev.tables, "simulated detector", config.detector))
        print(sections[-1])
    # JSON first (small, what scripts read), then the folder.
    if args.json:
        data = ev.to_json()
        data["detector_metrics"] = {"body": config.body, "detector": config.detector, "motions": det}
        if ev_sim is not None:
            sim = ev_sim.to_json()
            data["sim_detector"] = {k: sim[k] for k in ("results", "arm_length_range_cm") if k in sim}
        write_json(args.json, data)
        print(f"wrote {args.json}")
    if args.out:
        from akc_drake.fileio import atomic_write_text

        files = write_evaluation(ev, args.out, sections)
        head = f"# The 2D detector ({config.detector}) on the {config.body} operator, against ground truth\n\n"
        atomic_write_text(Path(args.out) / "detector.md", head + det_md)
        print(f"wrote {args.out}/report.md, detector.md and {len(files) - 1} more files")
    if getattr(args, "export", None):
        _export(ev, args)
    print(f"calibration {ev.render_s:.1f} s, clips (render + methods) {ev.elapsed_s:.1f} s")
    if ev.failures:
        print(f"{len(ev.failures)} clip(s) failed, left out of the tables:")
        for f in ev.failures:
            print(f"  {f.line()}")
        return 1
    return 0
