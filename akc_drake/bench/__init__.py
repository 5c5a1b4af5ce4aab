"""Speed and memory benchmark of every stage, run side by side in one process (``akc-drake bench``).

A package by concern: :mod:`~akc_drake.bench.core` (settings, statistics, the input session, the numpy core
stages), :mod:`~akc_drake.bench.systems` (each LeafSystem alone, the mocap diagram),
:mod:`~akc_drake.bench.render` (rendering + extraction, MediaPipe, the skinned operator, teleop, memory) and
:mod:`~akc_drake.bench.report` (the whole run, the targets, the text report). The names below are the
package's public interface (see :mod:`akc_drake.bench.core` for what every figure means).
"""

from akc_drake.bench.core import (
    BENCH_FORMAT,
    TARGETS,
    BenchInput,
    BenchSettings,
    bench_core,
    machine_info,
    peak_rss_bytes,
    rendered_measurements,
    rss_bytes,
    summarize,
    synthetic_measurements,
    time_calls,
    write_json_atomic,
)
from akc_drake.bench.render import bench_mediapipe, bench_memory, bench_rendering, bench_skinned, bench_teleop
from akc_drake.bench.report import format_report, paper_table3, run_bench
from akc_drake.bench.systems import bench_mocap, bench_systems

__all__ = [
    "BENCH_FORMAT",
    "TARGETS",
    "BenchInput",
    "BenchSettings",
    "bench_core",
    "bench_mediapipe",
    "bench_memory",
    "bench_mocap",
    "bench_rendering",
    "bench_skinned",
    "bench_systems",
    "bench_teleop",
    "format_report",
    "machine_info",
    "paper_table3",
    "peak_rss_bytes",
    "rendered_measurements",
    "rss_bytes",
    "run_bench",
    "summarize",
    "synthetic_measurements",
    "time_calls",
    "write_json_atomic",
]
