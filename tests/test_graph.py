"""System graphs: `akc-drake graph` writes .dot and .svg, and the committed graphs in diagrams/ are current."""

import shutil
from pathlib import Path

import pytest

from akc_drake.cli import main
from akc_drake.commands.graph import build_named_diagram
from akc_drake.graphs import diagram_dot, normalize_dot

REPO = Path(__file__).resolve().parent.parent


def test_normalize_dot_renumbers_ids_in_order():
    text = "digraph _17 {\nsubgraph cluster17diagram {\ns23 [a];\ns9 [b];\ns23:y0:e -> s9:u0:w\n}\n}"
    assert normalize_dot(text) == "digraph _1 {\nsubgraph cluster1diagram {\ns2 [a];\ns3 [b];\ns2:y0:e -> s3:u0:w\n}\n}"


@pytest.mark.parametrize(
    "name, expected",
    [
        ("mocap", ["DepthCameraSource", "LandmarkExtractor", "OcclusionFilter", "LandmarkKalmanFilter",
                   "ArmKinematicCorrection"]),
        ("teleop", ["FrameMapper", "DifferentialIK_left", "DifferentialIK_right", "MultibodyPlant",
                    "ArmKinematicCorrection"]),
    ],
)
def test_graph_command_writes_named_systems(tmp_path, name, expected):
    assert main(["graph", "--diagram", name, "--out", str(tmp_path)]) == 0
    dot = (tmp_path / f"{name}.dot").read_text()
    for system in expected:
        assert system in dot
    if shutil.which("dot"):
        svg = (tmp_path / f"{name}.svg").read_text()
        assert svg.lstrip().startswith("<?xml") and "</svg>" in svg
        for system in expected:
            assert system in svg


@pytest.mark.parametrize("name", ["mocap", "teleop"])
def test_committed_graphs_are_current(name):
    committed = REPO / "diagrams" / f"{name}.dot"
    assert committed.exists(), f"diagrams/{name}.dot is missing: run `make graphs`"
    fresh = diagram_dot(build_named_diagram(name))
    assert committed.read_text() == fresh, f"diagrams/{name}.dot is stale: run `make graphs` and commit the result"
