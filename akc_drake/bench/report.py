"""The whole benchmark run (:func:`run_bench`), its targets, Table III beside the paper's, and the text report.
"""


from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict

from akc_drake.bench.core import (
    BENCH_FORMAT,
    TARGETS,
    BenchSettings,
    _load_average,
    bench_core,
    machine_info,
    rendered_measurements,
    synthetic_measurements,
)
from akc_drake.bench.render import bench_mediapipe, bench_memory, bench_rendering, bench_skinned, bench_teleop
from akc_drake.bench.systems import bench_mocap, bench_systems


# ================================================================================================ the run
def _target_status(value, key: str) -> dict:
    op, bound = TARGETS[key]
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        met = None
    else:
        met = bool(value <= bound if op == "<=" else value >= bound if op == ">=" else value < bound)
    return {"value": value, "target": f"{op} {bound:g}", "met": met}


def paper_table3(result: dict) -> list[dict]:
    """The paper's Table III (averaged per-frame computation time, ms) beside ours (ms).

    The paper's figures are per-frame averages on a 13th-gen i9 with MediaPipe Holistic as its "Raw" stage;
    ours are medians and means of the same stage on this machine. "Raw" is our rendering + simulated
    detection + depth lookup (and MediaPipe alone when installed).
    """
    from akc_drake.resources import paper_results

    paper = paper_results()["table3_compute_time_ms"]
    core = result.get("core", {})
    rows = []

    def ours(summary: dict | None, scale: float) -> dict:
        if not summary or not summary.get("n"):
            return {"median": None, "mean": None, "max": None}
        return {k: summary[k] * scale for k in ("median", "mean", "max")}

    render = result.get("rendering", {}).get("ms_per_frame")
    mp = result.get("mediapipe", {}).get("ms_per_frame")
    raw_I, raw_II = paper["I"]["Raw"], paper["II"]["Raw"]
    rows.append({"stage": "Raw", "paper_I": raw_I, "paper_II": raw_II, "ours": ours(render, 1.0),
                 "ours_what": "render 640x480 + simulated detector + depth lookup"})
    if mp:
        rows.append({"stage": "Raw (MediaPipe only)", "paper_I": raw_I, "paper_II": raw_II,
                     "ours": ours(mp, 1.0), "ours_what": "MediaPipe PoseLandmarker on a 640x480 render"})
    rows.append({"stage": "KF", "paper_I": paper["I"]["KF"], "paper_II": paper["II"]["KF"],
                 "ours": ours(core.get("kf"), 1e-3), "ours_what": "constant-velocity KF, 12 landmarks"})
    rows.append({"stage": "EKF", "paper_I": None, "paper_II": None,
                 "ours": ours(core.get("ekf"), 1e-3), "ours_what": "bone-length EKF, 12 landmarks"})
    rows.append({"stage": "COIK", "paper_I": paper["I"]["COIK"], "paper_II": paper["II"]["COIK"],
                 "ours": ours(core.get("coik_snopt"), 1.0), "ours_what": "COIK, SNOPT, warm start"})
    rows.append({"stage": "AKC", "paper_I": paper["I"]["AKC"], "paper_II": paper["II"]["AKC"],
                 "ours": ours(core.get("akc"), 1e-3), "ours_what": "AKC, both arms"})
    return rows


def run_bench(settings: BenchSettings | None = None, progress: Callable[[str], None] | None = None) -> dict:
    """Run every benchmark in this process and return the JSON-able result (see the module docstring)."""
    s = settings or BenchSettings.full()
    start = time.perf_counter()
    result: dict = {"format": BENCH_FORMAT, "quick": s.quick, "settings": asdict(s)}
    result["machine"] = machine_info()

    def section(name: str, fn: Callable[[], dict]) -> dict:
        t0 = time.perf_counter()
        out = fn()
        result.setdefault("section_wall_s", {})[name] = time.perf_counter() - t0
        result[name] = out
        return out

    # Input: a rendered Motion I session (its render/extract times are the renderer's own breakdown).
    def make_input() -> dict:
        if progress is not None:
            progress("input: rendering Motion I")
        try:
            inp = rendered_measurements(cycles=s.cycles, body=s.body, detector=s.detector)
        except (ImportError, RuntimeError) as e:  # no renderer: synthetic measurements instead
            inp = synthetic_measurements(cycles=s.cycles)
            inp.kind = f"synthetic (rendering failed: {e})"
        make_input.inp = inp.run_stages()
        return {"kind": inp.kind, "frames": inp.num_frames, "rate_hz": 1.0 / inp.dt,
                "width": inp.intrinsics.width, "height": inp.intrinsics.height}

    section("input", make_input)
    inp = make_input.inp
    core = section("core", lambda: bench_core(inp, s, progress))
    section("systems", lambda: bench_systems(inp, core, s, progress))
    mocap = section("mocap_diagram", lambda: bench_mocap(inp, s, progress))
    render = section("rendering", lambda: bench_rendering(s, progress))
    section("mediapipe", lambda: bench_mediapipe(s, progress))
    skinned = section("skinned", lambda: bench_skinned(s, progress))
    teleop = section("teleop", lambda: bench_teleop(s, progress))
    memory = section("memory", lambda: bench_memory(s, progress))

    result["load_average_at_end"] = _load_average()
    # The contract keys (DESIGN.md) and the other headline figures.
    coik = {name: core[f"coik_{name}"]["median"] for name in ("snopt", "ipopt", "nlopt")}
    result.update(
        akc_us_per_frame=core["akc"]["median"],
        kf_us_per_frame=core["kf"]["median"],
        ekf_us_per_frame=core["ekf"]["median"],
        coik_ms_per_frame=coik,
        mocap_diagram_fps=mocap["AKC(KF)"]["fps"]["median"],
        teleop_realtime_factor=teleop["realtime_factor"],
        akc_us_per_frame_max=core["akc"]["max"],
        akc_plus_us_per_frame=core["akc_plus"]["median"],
        akc_plus_us_per_frame_mean=core["akc_plus"]["mean"],
        akc_plus_us_per_frame_max=core["akc_plus"]["max"],
        kf_us_per_frame_max=core["kf"]["max"],
        ekf_us_per_frame_max=core["ekf"]["max"],
        coik_ms_per_frame_max={name: core[f"coik_{name}"]["max"] for name in coik},
        coik_over_akc=core["coik_over_akc"],
        render_extract_ms_per_frame=render["ms_per_frame"]["median"],
        render_extract_fps=render["fps"],
        mediapipe_ms_per_frame=(result["mediapipe"]["ms_per_frame"]["median"]
                                if result["mediapipe"].get("available") else None),
        memory_growth_pct=memory["growth_pct"],
        peak_rss_mb=memory["peak_rss_mb"],
        skinning_ms_per_frame=(skinned["skinning_ms_per_frame"]["median"] if skinned.get("available") else None),
        skinned_mediapipe_fps=skinned.get("fps"),
    )
    result["targets"] = {
        "akc_us_per_frame": _target_status(result["akc_us_per_frame"], "akc_us_per_frame"),
        "akc_plus_us_per_frame": _target_status(result["akc_plus_us_per_frame"], "akc_plus_us_per_frame"),
        "kf_us_per_frame": _target_status(result["kf_us_per_frame"], "kf_us_per_frame"),
        "ekf_us_per_frame": _target_status(result["ekf_us_per_frame"], "ekf_us_per_frame"),
        "coik_snopt_ms_per_frame": _target_status(coik["snopt"], "coik_snopt_ms_per_frame"),
        "coik_over_akc_snopt": _target_status(core["coik_over_akc"].get("snopt"), "coik_over_akc_snopt"),
        "mocap_diagram_fps": _target_status(result["mocap_diagram_fps"], "mocap_diagram_fps"),
        "render_extract_fps": _target_status(result["render_extract_fps"], "render_extract_fps"),
        "teleop_realtime_factor": _target_status(result["teleop_realtime_factor"], "teleop_realtime_factor"),
        "memory_growth_pct": _target_status(result["memory_growth_pct"], "memory_growth_pct"),
        "skinning_ms_per_frame": _target_status(result["skinning_ms_per_frame"], "skinning_ms_per_frame"),
        "skinned_mediapipe_fps": _target_status(result["skinned_mediapipe_fps"], "skinned_mediapipe_fps"),
    }
    result["paper_table3_ms"] = paper_table3(result)
    result["elapsed_s"] = time.perf_counter() - start
    return result


# ================================================================================================ report
def _f(v, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}g}"


_MET = {True: "yes", False: "NO", None: "-"}


def format_report(result: dict) -> str:
    """A plain-text summary: the figures with median, max and target, then Table III beside the paper's."""
    core, targets = result["core"], result["targets"]
    m = result["machine"]
    lines = [
        f"akc-drake bench{' --quick' if result['quick'] else ''}: {m['cpu']}, {m['cpus_usable']} cores, "
        f"drake {m['drake']}, python {m['python']}, AKC+ {m.get('akc_plus_modules', '?')}; "
        f"input: {result['input']['kind']} ({result['input']['frames']} frames)",
        "",
        f"{'figure':<46}{'median':>10}{'max':>10}  {'target':<9}{'met':>4}",
    ]

    def line(name: str, med, mx=None, target_key: str | None = None) -> None:
        t = targets.get(target_key, {}) if target_key else {}
        met = _MET[t.get("met")] if t else ""
        lines.append(f"{name:<46}{_f(med):>10}{_f(mx):>10}  {t.get('target', ''):<9}{met:>4}")

    def stat(name: str, summary: dict | None, target_key: str | None = None) -> None:
        summary = summary or {}
        line(name, summary.get("median"), summary.get("max"), target_key)

    stat("core: occlusion filter [us]", core["occlusion"])
    stat("core: KF [us]", core["kf"], "kf_us_per_frame")
    stat("core: EKF [us]", core["ekf"], "ekf_us_per_frame")
    stat("core: AKC, both arms [us]", core["akc"], "akc_us_per_frame")
    stat("core: AKC+ (KF covariance), both arms [us]", core["akc_plus"], "akc_plus_us_per_frame")
    stat("core: control frames, eq. 17 [us]", core["frames"])
    for name in ("snopt", "ipopt", "nlopt"):
        key = "coik_snopt_ms_per_frame" if name == "snopt" else None
        stat(f"core: COIK {name} [ms]", core[f"coik_{name}"], key)
    for name, ratio in core["coik_over_akc"].items():
        line(f"COIK {name} / AKC [x]", ratio, None, "coik_over_akc_snopt" if name == "snopt" else None)
    lines += ["", f"{'stage system alone in a Simulator [us/frame]':<46}{'total':>10}{'net':>10}{'core':>10}"
                  f"{'overhead':>10}"]
    for name, v in result["systems"].items():
        if name == "baseline":
            lines.append(f"{'MeasurementReplay (the baseline)':<46}{_f(v['per_frame_us']):>10}")
        else:
            lines.append(f"{name:<46}{_f(v['per_frame_us']):>10}{_f(v['net_us']):>10}{_f(v['core_us']):>10}"
                         f"{_f(v['overhead_us']):>10}")
    lines.append("")
    for label, v in result["mocap_diagram"].items():
        stat(f"mocap diagram replay, {label} [frames/s]", v["fps"],
             "mocap_diagram_fps" if label == "AKC(KF)" else None)
    r = result["rendering"]
    stat("rendering + extraction 640x480 [ms]", r["ms_per_frame"])
    line("rendering + extraction 640x480 [frames/s]", r["fps"], None, "render_extract_fps")
    mp = result["mediapipe"]
    if mp.get("available"):
        stat("MediaPipe PoseLandmarker 640x480 [ms]", mp["ms_per_frame"])
    else:
        lines.append(f"{'MediaPipe':<46}skipped: {mp.get('reason', '')}")
    sk = result.get("skinned", {})
    if sk.get("available"):
        stat("skinned operator: skinning [ms]", sk["skinning_ms_per_frame"], "skinning_ms_per_frame")
        if "fps" in sk:
            stat("skinned render + MediaPipe 640x480 [ms]", sk["render_mediapipe_ms_per_frame"])
            line("skinned render + MediaPipe 640x480 [frames/s]", sk["fps"], None, "skinned_mediapipe_fps")
        else:
            lines.append(f"{'skinned render + MediaPipe':<46}skipped: {sk['mediapipe'].get('reason', '')}")
    else:
        lines.append(f"{'skinned operator':<46}skipped: {sk.get('reason', '')}")
    line("teleop diagram, rendering at 10 Hz [x realtime]", result["teleop"]["realtime_factor"], None,
         "teleop_realtime_factor")
    mem = result["memory"]
    line(f"memory: RSS growth {_f(mem['growth_from_s'])}-{_f(mem['simulated_s'])} s simulated [%]",
         mem["growth_pct"], None, "memory_growth_pct")
    line("memory: peak RSS during that run [MB]", mem["peak_rss_mb"])
    line("memory run: realtime factor [x]", mem["realtime_factor"])
    lines += [
        "",
        "Table III, per-frame computation time [ms]: the paper's (13th-gen i9, MediaPipe Holistic) and ours",
        f"{'stage':<22}{'paper I':>9}{'paper II':>10}{'ours med':>11}{'ours mean':>11}{'ours max':>11}",
    ]
    for rr in result["paper_table3_ms"]:
        o = rr["ours"]
        lines.append(f"{rr['stage']:<22}{_f(rr['paper_I'], 4):>9}{_f(rr['paper_II'], 4):>10}"
                     f"{_f(o['median']):>11}{_f(o['mean']):>11}{_f(o['max']):>11}")
    lines += ["", f"total {result['elapsed_s']:.1f} s"]
    return "\n".join(lines)

