"""The evaluation's tables in the paper's layout (ours beside the paper's), as text, Markdown, CSV and JSON,
and its figures as PNG.

A :class:`Table` holds our numbers and the paper's for the same cells; :func:`format_table` prints
each cell as ``ours (paper)``. :func:`write_report` writes ``report.md``, one CSV per table and the
figures into a folder. Figures use matplotlib's Agg backend (no display needed).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from akc_drake.fileio import atomic_write, atomic_write_text


@dataclass
class Table:
    """One table: rows x columns of our numbers, the paper's beside them.

    Attributes:
        key: short identifier (``"table1"``), also the CSV file's stem.
        title: the paper's caption (adapted when our set-up differs).
        rows: row labels.
        columns: column labels.
        ours: ``(R, C)`` our values (NaN where not computed).
        paper: ``(R, C)`` the paper's values (NaN where the paper has none).
        ours_std: ``(R, C)`` optional spread (printed as ``±``), e.g. across cycles.
        groups: optional column groups ``[(label, n_columns), ...]`` (e.g. Motion I | Motion II).
        decimals: digits after the point.
        row_decimals: optional per-row digits (overrides ``decimals``), e.g. 3 for correlation rows.
        notes: footnotes printed under the table.
    """

    key: str
    title: str
    rows: list[str]
    columns: list[str]
    ours: np.ndarray
    paper: np.ndarray | None = None
    ours_std: np.ndarray | None = None
    groups: list[tuple[str, int]] | None = None
    decimals: int = 2
    notes: list[str] = field(default_factory=list)
    row_decimals: list[int] | None = None

    def __post_init__(self):
        shape = (len(self.rows), len(self.columns))
        self.ours = np.asarray(self.ours, dtype=float).reshape(shape)
        self.paper = np.full(shape, np.nan) if self.paper is None else np.asarray(self.paper, dtype=float)
        if self.paper.shape != shape:
            raise ValueError(f"Table {self.key}: paper has shape {self.paper.shape}, expected {shape}")
        if self.ours_std is not None:
            self.ours_std = np.asarray(self.ours_std, dtype=float).reshape(shape)
        if self.row_decimals is not None and len(self.row_decimals) != len(self.rows):
            raise ValueError(f"Table {self.key}: row_decimals has {len(self.row_decimals)} entries, "
                             f"there are {len(self.rows)} rows")
        if self.groups is not None and sum(n for _, n in self.groups) != len(self.columns):
            raise ValueError(
                f"Table {self.key}: column groups cover {sum(n for _, n in self.groups)} columns, "
                f"there are {len(self.columns)}"
            )

    @property
    def has_paper(self) -> bool:
        return bool(np.any(np.isfinite(self.paper)))

    def cell(self, i: int, j: int) -> str:
        """The text of cell (i, j): ``ours[±std] (paper)``; ``-`` for a missing value."""
        return _cell_text(
            self.ours[i, j],
            None if self.ours_std is None else self.ours_std[i, j],
            self.paper[i, j],
            self.decimals if self.row_decimals is None else self.row_decimals[i],
            self.has_paper,
        )

    def to_dict(self) -> dict:
        """JSON-ready: title, rows, columns, ours, paper (null where missing), std if any, groups, notes."""
        d = {
            "title": self.title,
            "rows": list(self.rows),
            "columns": list(self.columns),
            "ours": nan_to_none(self.ours),
            "paper": nan_to_none(self.paper),
        }
        if self.ours_std is not None:
            d["ours_std"] = nan_to_none(self.ours_std)
        if self.groups:
            d["groups"] = [[g, n] for g, n in self.groups]
        if self.notes:
            d["notes"] = list(self.notes)
        return d


def _num(v: float, decimals: int) -> str:
    return "-" if not math.isfinite(v) else f"{v:.{decimals}f}"


def _cell_text(v, std, paper, decimals, with_paper) -> str:
    s = _num(v, decimals)
    if std is not None and math.isfinite(std) and math.isfinite(v):
        s += f"±{std:.{decimals}f}"
    if with_paper:
        s += f" ({_num(paper, decimals)})" if math.isfinite(paper) else " (-)"
    return s


def nan_to_none(a):
    """A nested list/float structure with NaN/inf replaced by None (valid JSON)."""
    if isinstance(a, np.ndarray):
        return nan_to_none(a.tolist())
    if isinstance(a, (list, tuple)):
        return [nan_to_none(x) for x in a]
    if isinstance(a, dict):
        return {k: nan_to_none(v) for k, v in a.items()}
    if isinstance(a, (float, np.floating)):
        return float(a) if math.isfinite(a) else None
    if isinstance(a, np.integer):
        return int(a)
    if isinstance(a, np.bool_):
        return bool(a)
    return a


# ------------------------------------------------------------------------------------------- text
def format_table(table: Table) -> str:
    """The table as fixed-width text, in the paper's layout; cells ``ours (paper)``."""
    header = [""] + list(table.columns)
    body = [[r] + [table.cell(i, j) for j in range(len(table.columns))] for i, r in enumerate(table.rows)]
    widths = [max(len(str(row[c])) for row in [header, *body]) for c in range(len(header))]
    lines = [f"{table.key.upper()}: {table.title}"]
    if table.has_paper:
        lines.append("(ours, the paper's figure in brackets)")
    if table.groups:
        parts = [" " * widths[0]]
        c = 1
        for label, n in table.groups:
            w = sum(widths[c : c + n]) + 3 * (n - 1)
            parts.append(label.center(w))
            c += n
        lines.append(" | ".join(parts).rstrip())
    lines.append(" | ".join(str(h).rjust(w) for h, w in zip(header, widths, strict=True)))
    lines.append("-+-".join("-" * w for w in widths))
    for row in body:
        lines.append(" | ".join(str(x).rjust(w) for x, w in zip(row, widths, strict=True)))
    for n in table.notes:
        lines.append(f"  note: {n}")
    return "\n".join(lines)


def table_markdown(table: Table) -> str:
    """The table as a Markdown section (cells ``ours (paper)``)."""
    cols = list(table.columns)
    if table.groups:
        labels = []
        for label, n in table.groups:
            labels.extend([label] * n)
        cols = [f"{g} {c}" for g, c in zip(labels, cols, strict=True)]
    out = [f"### {table.key.capitalize()}: {table.title}", ""]
    if table.has_paper:
        out += ["Ours, the paper's figure in brackets.", ""]
    out.append("| | " + " | ".join(cols) + " |")
    out.append("|---|" + "---|" * len(cols))
    for i, r in enumerate(table.rows):
        out.append(f"| {r} | " + " | ".join(table.cell(i, j) for j in range(len(cols))) + " |")
    for n in table.notes:
        out += ["", f"*{n}*"]
    return "\n".join(out) + "\n"


def table_csv(table: Table) -> str:
    """The table as CSV in long form: ``row, group, column, ours, ours_std, paper`` (empty where missing)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["row", "group", "column", "ours", "ours_std", "paper"])
    groups = []
    if table.groups:
        for label, n in table.groups:
            groups.extend([label] * n)
    else:
        groups = [""] * len(table.columns)

    def f(v):
        return "" if not math.isfinite(v) else repr(float(v))

    for i, r in enumerate(table.rows):
        for j, c in enumerate(table.columns):
            std = np.nan if table.ours_std is None else table.ours_std[i, j]
            w.writerow([r, groups[j], c, f(table.ours[i, j]), f(std), f(table.paper[i, j])])
    return buf.getvalue()


def write_json(path, data: dict) -> Path:
    """Write ``data`` as JSON (NaN -> null), atomically."""
    return atomic_write_text(path, json.dumps(nan_to_none(data), indent=2) + "\n")


# ------------------------------------------------------------------------------------------- figures
def _figure(nrows: int, ncols: int, figsize, **kw):
    """A ``matplotlib.figure.Figure`` (no pyplot: no global state, no GUI backend) and its axes grid."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, squeeze=False, **kw)


#: Line style per method in the figures.
_STYLE = {
    "Truth": dict(color="black", lw=2.0, ls="-"),
    "Raw": dict(color="tab:red", lw=1.0, ls=":"),
    "KF": dict(color="tab:orange", lw=1.2, ls="--"),
    "EKF": dict(color="tab:olive", lw=1.2, ls="--"),
    "AKC(KF)": dict(color="tab:blue", lw=1.5, ls="-"),
    "AKC(EKF)": dict(color="tab:cyan", lw=1.5, ls="-"),
    "AKC+(KF)": dict(color="tab:brown", lw=1.5, ls="-"),
    "AKC+(EKF)": dict(color="tab:pink", lw=1.5, ls="-"),
    "COIK(KF)": dict(color="tab:green", lw=1.2, ls="-."),
    "COIK(EKF)": dict(color="tab:purple", lw=1.2, ls="-."),
}


def _legend_below(fig, ax) -> None:
    """One legend for the figure, under the plots (it never hides a curve)."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 8), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0.0, 0.05, 1.0, 1.0))


def plot_depth_cycles(panels: list[dict], path, title: str = "Depth (z) of occluded joints") -> Path:
    """The paper's Fig. 4: depth of a joint over a few cycles for several methods and the truth.

    Args:
        panels: one dict per subplot with ``title``, ``t`` ``(N,)`` seconds, ``series``
            {label: ``(N,)`` z in m} (a ``"Truth"`` entry is drawn in black).
        path: the PNG to write.
    """
    fig, axes = _figure(len(panels), 1, (8, 2.6 * len(panels)))
    for ax, panel in zip(axes[:, 0], panels, strict=True):
        for label, z in panel["series"].items():
            ax.plot(panel["t"], np.asarray(z) * 100.0, label=label, **_STYLE.get(label, {}))
        ax.set_title(panel["title"], fontsize=10)
        ax.set_ylabel("z (cm)")
        ax.grid(True, alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(title)  # (before the layout, which then leaves it room)
    _legend_below(fig, axes[0, 0])
    return save_png(fig, path)


def plot_arm_lengths(t: np.ndarray, lengths: dict[str, dict[str, np.ndarray]], path, title: str) -> Path:
    """Arm-segment length over time per method (one subplot per segment).

    Args:
        t: ``(T,)`` seconds.
        lengths: {method: {segment: ``(T,)`` metres}}.
        path: the PNG to write.
    """
    segments = list(next(iter(lengths.values())).keys()) if lengths else []
    fig, axes = _figure(len(segments), 1, (8, 2.2 * max(len(segments), 1)), sharex=True)
    for ax, seg in zip(axes[:, 0], segments, strict=True):
        for method, segs in lengths.items():
            ax.plot(t, np.asarray(segs[seg]) * 100.0, label=method, **_STYLE.get(method, {}))
        ax.set_ylabel(f"{seg} (cm)")
        ax.grid(True, alpha=0.3)
        finite = np.concatenate(
            [np.asarray(s[seg])[np.isfinite(s[seg])] for s in lengths.values()] or [[0.0]]
        )
        if finite.size:
            lo, hi = np.percentile(finite * 100.0, [1, 99])
            pad = max(2.0, 0.1 * (hi - lo))
            ax.set_ylim(lo - pad, hi + pad)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle(title)  # (before the layout, which then leaves it room)
    _legend_below(fig, axes[0, 0])
    return save_png(fig, path)


def plot_heatmaps(panels: list[dict], path, title: str) -> Path:
    """Heatmaps of an objective over two weights (the paper's Fig. 5 a-c).

    Args:
        panels: dicts with ``title``, ``x`` values, ``y`` values, ``z`` ``(len(y), len(x))``, ``xlabel``,
            ``ylabel`` and optionally ``best`` ``(x, y)`` to mark.
        path: the PNG to write.
    """
    n = len(panels)
    fig, axes = _figure(1, n, (4.2 * n, 3.8))
    for ax, p in zip(axes[0], panels, strict=True):
        z = np.asarray(p["z"], dtype=float)
        im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(p["x"])), [f"{v:g}" for v in p["x"]], fontsize=7)
        ax.set_yticks(range(len(p["y"])), [f"{v:g}" for v in p["y"]], fontsize=7)
        ax.set_xlabel(p["xlabel"])
        ax.set_ylabel(p["ylabel"])
        ax.set_title(p["title"], fontsize=9)
        if p.get("best") is not None:
            bx, by = p["best"]
            ax.plot(list(p["x"]).index(bx), list(p["y"]).index(by), marker="*", color="red", ms=12)
        fig.colorbar(im, ax=ax, label="L2 norm of joint errors (cm)")
    fig.suptitle(title)
    fig.tight_layout()
    return save_png(fig, path)


def plot_curves(
    x: np.ndarray, curves: dict[str, np.ndarray], path, xlabel: str, ylabel: str, title: str
) -> Path:
    """Line plot of several curves over ``x`` (the paper's Fig. 5 d, the shrink-factor curve)."""
    fig, axes = _figure(1, 1, (6, 3.8))
    ax = axes[0, 0]
    for label, y in curves.items():
        ax.plot(x, y, marker="o", label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return save_png(fig, path)


def save_png(fig, path) -> Path:
    """Write a figure as a PNG (110 dpi), atomically."""
    return atomic_write(path, lambda f: fig.savefig(f, dpi=110, format="png"))


# ------------------------------------------------------------------------------------------- folder
def write_tables(tables: list[Table], out_dir) -> list[Path]:
    """One CSV per table into ``out_dir/tables/<key>.csv``."""
    out = Path(out_dir) / "tables"
    return [atomic_write_text(out / f"{t.key}.csv", table_csv(t)) for t in tables]


def report_markdown(
    title: str,
    config: dict,
    tables: list[Table],
    figures: list[Path],
    out_dir,
    extra: list[str] | None = None,
) -> str:
    """The text of ``report.md``: the configuration, every table, links to the figures."""
    from akc_drake.config import describe_camera

    lines = [f"# {title}", "", "## Configuration", ""]
    for k, v in config.items():
        lines.append(f"- **{k}**: {describe_camera(v) if k == 'camera' else v}")
    lines.append("")
    for para in extra or []:
        lines += [para, ""]
    lines += ["## Tables", ""]
    for t in tables:
        lines.append(table_markdown(t))
    if figures:
        lines += ["## Figures", ""]
        for f in figures:
            rel = os.path.relpath(f, out_dir)
            lines += [f"![{Path(f).stem}]({rel})", ""]
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------- evaluation
#: The methods drawn in the depth figure (the paper's Fig. 4), in drawing order.
FIG4_METHODS = ("Raw", "KF", "COIK(KF)", "AKC(KF)")


def _window(session, exclude_first_cycle: bool, n_cycles: int = 3) -> slice:
    """Frames of the first ``n_cycles`` evaluated cycles (the whole session when it has no cycles)."""
    cycles = session.evaluation_cycles(exclude_first_cycle)
    if session.num_cycles <= 1:
        return slice(0, session.num_frames)
    chosen = cycles[:n_cycles]
    return slice(chosen[0].start, chosen[-1].stop)


def evaluation_figures(ev, out_dir) -> list[Path]:
    """The evaluation's PNG figures in ``out_dir/figures``.

    * ``fig4_depth.png``: depth (z) of the occluded static left shoulder in each motion and of the
      dynamic left elbow in Motion I (or the first motion) over three evaluated cycles, for Raw, KF,
      COIK(KF), AKC(KF) and the truth (the paper's Fig. 4);
    * ``arm_length_<motion>.png``: every arm segment's length over time, per method.

    Args:
        ev: an :class:`akc_drake.evaluation.experiment.Evaluation`.
        out_dir: the output folder.
    """
    from akc_drake.core.skeleton import INDEX, segment_lengths

    fig_dir = Path(out_dir) / "figures"
    excl = ev.config.exclude_first_cycle
    panels = []
    motions = list(ev.runs)
    dyn_motion = "I" if "I" in ev.runs else motions[0]
    rec = bool(ev.config.motion_file)  # (a recording's shoulder is not held still, nor its joints occluded)
    wanted = [(m, "left_shoulder", "left shoulder" if rec else "static left shoulder") for m in motions]
    wanted.append((dyn_motion, "left_elbow", "left elbow" if rec else "dynamic left elbow"))
    for motion, joint, what in wanted:
        run = ev.runs[motion]
        w = _window(run.session, excl)
        j = INDEX[joint]
        series = {"Truth": run.session.truth[w, j, 2]}
        for mname in FIG4_METHODS:
            if mname in run.methods:
                series[mname] = run.methods[mname].estimates[w, j, 2]
        panels.append({"title": f"Motion {motion}: {what}", "t": run.session.t[w], "series": series})
    paths = [
        plot_depth_cycles(
            panels, fig_dir / "fig4_depth.png",
            "Depth (z) of the left shoulder and elbow" if rec else "Depth (z) of occluded joints over three cycles"
        )
    ]
    for motion, run in ev.runs.items():
        segs = ("LUA", "LLA", "RUA", "RLA")
        lengths = {"Truth": {k: v for k, v in segment_lengths(run.session.truth).items() if k in segs}}
        for mname, res in run.methods.items():
            lengths[mname] = {k: v for k, v in segment_lengths(res.estimates).items() if k in segs}
        paths.append(
            plot_arm_lengths(
                run.session.t,
                lengths,
                fig_dir / f"arm_length_{motion}.png",
                f"Arm-segment length over time, Motion {motion}",
            )
        )
    return paths


def write_evaluation(ev, out_dir, sections: list[str] | None = None) -> list[Path]:
    """Write ``report.md``, ``tables/*.csv`` and ``figures/*.png`` of an evaluation into ``out_dir``.

    ``sections``: more Markdown appended to ``report.md`` (e.g. the detector's own figures, or the tables
    with another detector side by side).

    Returns:
        Every file written.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = write_tables(ev.tables, out_dir)
    figures = evaluation_figures(ev, out_dir)
    cfg = ev.to_json()["config"]
    dims = ", ".join(f"{k} {v * 100:.1f} cm" for k, v in ev.dims.as_dict().items())
    extra = [
        f"Body dimensions used by every method (T-pose calibration): {dims}.",
        "Metrics are computed against the rendered operator's true joint centres over every cycle but the "
        "first (the paper's protocol); each cell shows our value with the paper's in brackets.",
    ]
    md = report_markdown("akc-drake evaluation", cfg, ev.tables, figures, out_dir, extra)
    md += "".join("\n" + s for s in sections or [])
    written.append(atomic_write_text(out_dir / "report.md", md))
    return written + figures
