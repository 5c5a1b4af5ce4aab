"""System graphs: Drake's Graphviz export, made deterministic, rendered to SVG with graphviz's ``dot``."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

from akc_drake.fileio import atomic_write_bytes

# Drake names graph nodes after global system ids (s12, cluster12diagram, _12), which change with the
# number of systems created earlier in the process. Renumbering them in order of first appearance makes
# the text depend only on the diagram, so the committed graphs can be checked for staleness.
_ID = re.compile(r"(?<![A-Za-z0-9])(clusters|cluster|Source_|s|_)(\d+)")


def normalize_dot(text: str) -> str:
    """Renumber Drake's system ids in order of first appearance and sort the edges (deterministic text)."""
    mapping: dict[str, str] = {}

    def repl(m: re.Match) -> str:
        key = m.group(2)
        if key not in mapping:
            mapping[key] = str(len(mapping) + 1)
        return m.group(1) + mapping[key]

    renumbered = _ID.sub(repl, text)
    # Drake lists the edges of a diagram in an order that depends on memory addresses: sort each run of edges.
    lines = renumbered.split("\n")
    out: list[str] = []
    run: list[str] = []
    for line in lines:
        if " -> " in line:
            run.append(line)
            continue
        out.extend(sorted(run))
        run = []
        out.append(line)
    out.extend(sorted(run))
    return "\n".join(out)


def diagram_dot(diagram, max_depth: int = 2) -> str:
    """The diagram's Graphviz text (deterministic)."""
    return normalize_dot(diagram.GetGraphvizString(max_depth=max_depth))


def _write_atomic(path: Path, data: str | bytes) -> None:
    atomic_write_bytes(path, data.encode() if isinstance(data, str) else data)


def render_svg(dot_text: str) -> bytes | None:
    """SVG bytes from graphviz's ``dot``, or None when ``dot`` is not installed."""
    exe = shutil.which("dot")
    if exe is None:
        return None
    res = subprocess.run([exe, "-Tsvg"], input=dot_text.encode(), capture_output=True, check=False)
    if res.returncode != 0:
        raise RuntimeError(f"dot failed: {res.stderr.decode(errors='replace').strip()}")
    return res.stdout


def write_graph(diagram, out_dir: str | Path, name: str, max_depth: int = 2) -> dict[str, Path | None]:
    """Write ``out_dir/name.dot`` and (when ``dot`` exists) ``out_dir/name.svg``.

    Returns:
        ``{"dot": path, "svg": path or None}``.
    """
    out = Path(out_dir)
    text = diagram_dot(diagram, max_depth=max_depth)
    dot_path = out / f"{name}.dot"
    _write_atomic(dot_path, text)
    svg = render_svg(text)
    svg_path = None
    if svg is not None:
        svg_path = out / f"{name}.svg"
        _write_atomic(svg_path, svg)
    return {"dot": dot_path, "svg": svg_path}
