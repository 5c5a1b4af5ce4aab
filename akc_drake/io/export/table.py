"""CSV and TRC (OpenSim) writers and readers for landmark trajectories.

CSV: one row per frame, a ``time`` column, then one column per landmark axis named with MediaPipe's landmark
names (``left_shoulder_x``, ...), metres, ``NaN`` for a missing value. Values are written with ``repr`` (the
shortest text that reads back to the same float).

TRC (Motion Analysis "Track Row Column", the marker format OpenSim reads, see OpenSim's "Marker (.trc) Files"):
tab-separated; three header lines (``PathFileType 4 (X/Y/Z) name``, the key names ``DataRate CameraRate
NumFrames NumMarkers Units OrigDataRate OrigDataStartFrame OrigNumFrames`` and their values), two label rows
(``Frame# Time`` and the marker names, each over its three columns; then ``X1 Y1 Z1 X2 ...``), a blank row, then
one row per frame: frame number (from 1), time, and x y z per marker. Units ``mm``; a missing marker's three
fields are left empty (OpenSim reads them as NaN).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from akc_drake.core.skeleton import LANDMARKS
from akc_drake.fileio import atomic_write_text

AXES = ("x", "y", "z")


def _num(v: float) -> str:
    return repr(float(v)) if math.isfinite(v) else "NaN"


def csv_columns(names=LANDMARKS) -> list[str]:
    """``["time", "left_shoulder_x", "left_shoulder_y", ...]``."""
    return ["time"] + [f"{n}_{a}" for n in names for a in AXES]


def format_csv(t: np.ndarray, points: np.ndarray, names=LANDMARKS) -> str:
    """The CSV text of ``points`` ``(T, J, 3)`` at times ``t`` ``(T,)``."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(csv_columns(names))
    flat = np.asarray(points, dtype=float).reshape(len(t), -1)
    for ti, row in zip(t, flat, strict=True):
        w.writerow([_num(ti)] + [_num(v) for v in row])
    return buf.getvalue()


def write_csv(path, t, points, names=LANDMARKS) -> Path:
    """Write :func:`format_csv` atomically."""
    return atomic_write_text(path, format_csv(t, points, names))


def read_csv(path) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Read a CSV written by :func:`write_csv`: ``(t, names, points (T, J, 3))``."""
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    names = [h[:-2] for h in header[1::3]]
    data = np.array([[float(v) for v in r] for r in body], dtype=float).reshape(len(body), -1)
    return data[:, 0], names, data[:, 1:].reshape(len(body), len(names), 3)


def format_trc(t: np.ndarray, points_mm: np.ndarray, names, *, file_name: str = "markers.trc", rate_hz: float) -> str:
    """The TRC text of marker positions ``(T, M, 3)`` in millimetres (already in the Y-up frame)."""
    T, M = len(t), len(names)
    rate = f"{rate_hz:.6g}"
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate}\t{rate}\t{T}\t{M}\tmm\t{rate}\t1\t{T}",
        "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t",
        "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, M + 1)),
        "",
    ]
    P = np.asarray(points_mm, dtype=float)
    for k in range(T):
        fields = [str(k + 1), repr(float(t[k]))]
        for m in range(M):
            p = P[k, m]
            fields += [repr(float(v)) for v in p] if np.all(np.isfinite(p)) else ["", "", ""]
        lines.append("\t".join(fields))
    return "\n".join(lines) + "\n"


def write_trc(path, t, points_mm, names, *, rate_hz: float) -> Path:
    """Write :func:`format_trc` atomically (the header names the file)."""
    return atomic_write_text(path, format_trc(t, points_mm, names, file_name=Path(path).name, rate_hz=rate_hz))


def read_trc(path) -> dict:
    """An independent TRC parser (header keys, marker names, data in the file's units; empty fields are NaN).

    Returns:
        dict with ``header`` (key -> value strings), ``markers`` (names), ``frame`` (T,), ``t`` (T,),
        ``points`` (T, M, 3).
    """
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    if not lines[0].startswith("PathFileType"):
        raise ValueError(f"{path}: not a TRC file (first line {lines[0][:40]!r})")
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t"), strict=True))
    markers = [m for m in lines[3].split("\t")[2:] if m]
    M, T = int(header["NumMarkers"]), int(header["NumFrames"])
    if len(markers) != M:
        raise ValueError(f"{path}: {len(markers)} marker names for NumMarkers {M}")
    rows = [ln for ln in lines[5:] if ln.strip()]
    if len(rows) != T:
        raise ValueError(f"{path}: {len(rows)} data rows for NumFrames {T}")
    data = np.full((T, 2 + 3 * M), np.nan)
    for k, ln in enumerate(rows):
        parts = ln.split("\t")
        data[k, : len(parts)] = [float(v) if v.strip() else np.nan for v in parts]
    return {
        "header": header,
        "markers": markers,
        "frame": data[:, 0].astype(int),
        "t": data[:, 1],
        "points": data[:, 2:].reshape(T, M, 3),
    }
