"""Tests of the report writer: tables in the paper's layout, CSV, JSON, Markdown and the PNG figures."""

from __future__ import annotations

import csv
import io
import json
import math

import numpy as np
import pytest
from test_evaluation import synthetic_session

from akc_drake.evaluation.experiment import ExperimentConfig, run_experiment
from akc_drake.evaluation.report import (
    Table,
    format_table,
    nan_to_none,
    plot_curves,
    plot_heatmaps,
    table_csv,
    table_markdown,
    write_evaluation,
    write_json,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _table():
    return Table(
        "table1",
        "Avg. RMSE (cm) of an occluded static left shoulder",
        ["x", "y", "z"],
        ["Raw", "AKC", "Raw", "AKC"],
        np.array([[1.234, 2.0, 3.0, np.nan], [4.0, 5.0, 6.0, 7.0], [8.0, 9.0, 10.0, 11.0]]),
        np.array([[3.71, 2.06, 2.30, 2.42], [1.74, 1.89, 1.41, 3.43], [34.86, 3.27, 28.54, 5.23]]),
        groups=[("Motion I", 2), ("Motion II", 2)],
    )


def test_format_table_shows_ours_beside_the_paper():
    text = format_table(_table())
    lines = text.splitlines()
    assert lines[0].startswith("TABLE1: Avg. RMSE")
    assert "Motion I" in lines[2] and "Motion II" in lines[2]
    z_row = next(line for line in lines if line.lstrip().startswith("z |"))
    assert "8.00 (34.86)" in z_row and "11.00 (5.23)" in z_row
    x_row = next(line for line in lines if line.lstrip().startswith("x |"))
    assert "1.23 (3.71)" in x_row and "- (2.42)" in x_row  # a missing value of ours is "-"
    # Every body row has the same width (aligned columns).
    body = [line for line in lines[3:] if "|" in line]
    assert len({len(line) for line in body}) == 1


def test_table_without_paper_figures_prints_ours_only():
    t = Table("t", "title", ["a"], ["c1", "c2"], np.array([[1.0, 2.5]]), row_decimals=[1])
    text = format_table(t)
    assert "1.0" in text and "2.5" in text and "(" not in text.split("\n", 1)[1]


def test_table_shape_errors():
    with pytest.raises(ValueError, match="paper has shape"):
        Table("t", "title", ["a"], ["b"], np.zeros((1, 1)), np.zeros((2, 1)))
    with pytest.raises(ValueError, match="column groups"):
        Table("t", "title", ["a"], ["b", "c"], np.zeros((1, 2)), groups=[("g", 3)])
    with pytest.raises(ValueError, match="row_decimals"):
        Table("t", "title", ["a"], ["b"], np.zeros((1, 1)), row_decimals=[1, 2])


def test_csv_long_form_round_trips_the_numbers():
    t = _table()
    rows = list(csv.DictReader(io.StringIO(table_csv(t))))
    assert len(rows) == 12
    assert rows[0] == {
        "row": "x",
        "group": "Motion I",
        "column": "Raw",
        "ours": "1.234",
        "ours_std": "",
        "paper": "3.71",
    }
    nan_row = rows[3]
    assert nan_row["group"] == "Motion II" and nan_row["column"] == "AKC" and nan_row["ours"] == ""
    for r in rows:
        i, j = ["x", "y", "z"].index(r["row"]), rows.index(r) % 4
        if r["ours"]:
            assert float(r["ours"]) == t.ours[i, j]
        assert float(r["paper"]) == t.paper[i, j]


def test_markdown_and_json_forms():
    t = _table()
    md = table_markdown(t)
    assert md.startswith("### Table1: Avg. RMSE")
    assert "| | Motion I Raw | Motion I AKC | Motion II Raw | Motion II AKC |" in md
    assert "| z | 8.00 (34.86) |" in md
    d = json.loads(json.dumps(t.to_dict()))
    assert d["ours"][0][3] is None and d["paper"][2][0] == 34.86
    assert d["groups"] == [["Motion I", 2], ["Motion II", 2]]


def test_nan_to_none_and_write_json(tmp_path):
    data = {"a": np.array([1.0, np.nan]), "b": np.float64(np.inf), "c": [np.int64(3), np.bool_(True)]}
    assert nan_to_none(data) == {"a": [1.0, None], "b": None, "c": [3, True]}
    p = write_json(tmp_path / "deep" / "x.json", data)
    assert json.loads(p.read_text()) == {"a": [1.0, None], "b": None, "c": [3, True]}
    assert sorted(f.name for f in p.parent.iterdir()) == ["x.json"]  # no temp file left


def _is_png(path, min_w=300, min_h=200):
    import matplotlib.image as mpimg

    assert path.read_bytes()[:8] == PNG_MAGIC
    img = mpimg.imread(path)
    assert img.shape[0] >= min_h and img.shape[1] >= min_w
    assert np.ptp(img[..., :3]) > 0.2  # something is drawn


def test_heatmap_and_curve_figures(tmp_path):
    z = np.arange(6, dtype=float).reshape(2, 3)
    p = plot_heatmaps(
        [{"title": "t", "x": [0, 1, 2], "y": [0, 5], "z": z, "xlabel": "w3", "ylabel": "w2", "best": (0, 0)}],
        tmp_path / "h.png",
        "heat",
    )
    _is_png(p)
    q = plot_curves(np.array([0.5, 1.0]), {"I": np.array([3.0, 2.0])}, tmp_path / "c.png", "s", "cm", "curve")
    _is_png(q)


@pytest.fixture(scope="module")
def small_evaluation():
    sessions = {
        "tpose": synthetic_session("tpose", frames=100, seed=1),
        "lpose": synthetic_session("lpose", frames=100, seed=2),
        "I": synthetic_session("I", cycles=2, seed=3),
        "II": synthetic_session("II", cycles=2, seed=4),
    }
    cfg = ExperimentConfig(cycles=2, methods=("Raw", "KF", "AKC(KF)", "COIK(KF)"), width=320, height=240)
    return run_experiment(cfg, sessions)


def test_write_evaluation_folder(tmp_path, small_evaluation):
    ev = small_evaluation
    files = write_evaluation(ev, tmp_path / "out")
    out = tmp_path / "out"
    assert (out / "report.md") in files
    md = (out / "report.md").read_text()
    assert (
        "# akc-drake evaluation" in md
        and "### Table1:" in md
        and "![fig4_depth](figures/fig4_depth.png)" in md
        and "- **camera**: default camera" in md
    )
    for t in ev.tables:
        rows = list(csv.DictReader((out / "tables" / f"{t.key}.csv").open()))
        assert len(rows) == len(t.rows) * len(t.columns)
    _is_png(out / "figures" / "fig4_depth.png")
    for m in ("I", "II"):
        _is_png(out / "figures" / f"arm_length_{m}.png")
    # Columns of methods that ran are filled in.
    keys = [t.key for t in ev.tables]
    assert "table1" in keys and "table6" in keys
    t1 = next(t for t in ev.tables if t.key == "table1")
    assert all(math.isfinite(v) for v in t1.ours.ravel())


def test_the_report_names_a_placed_camera_in_words(tmp_path):
    from akc_drake.evaluation.report import report_markdown

    camera = {"distance_m": 2.5, "height_m": 1.1, "lateral_m": 0.0, "aim_height_m": 0.45}
    md = report_markdown("t", {"camera": camera, "seed": 0}, [], [], tmp_path)
    assert "- **camera**: camera 2.5 m in front, 1.1 m above the pelvis, aimed 0.45 m above the pelvis" in md
    assert "- **seed**: 0" in md
