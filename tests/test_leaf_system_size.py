"""Each LeafSystem is a thin wrapper over a numpy core: at most 150 lines (docstring, ports, state, calcs)."""

import ast
from pathlib import Path

import akc_drake

MAX_LINES = 150
PACKAGE = Path(akc_drake.__file__).parent


def leaf_systems(root: Path = PACKAGE):
    """``(path, class name, lines)`` of every class in ``root`` whose bases name LeafSystem."""
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ClassDef) and any("LeafSystem" in ast.unparse(b) for b in node.bases):
                yield path.relative_to(root), node.name, node.end_lineno - node.lineno + 1


def test_every_leaf_system_is_at_most_150_lines():
    found = list(leaf_systems())
    names = {name for _, name, _ in found}
    assert {"LandmarkExtractor", "LandmarkKalmanFilter", "FrameSourceSystem", "SkeletonVisualizer",
            "StereoDepthNoiseSystem", "LandmarkTruth"} <= names  # the scan sees the systems
    too_long = [f"{path}: {name} has {n} lines" for path, name, n in found if n > MAX_LINES]
    assert not too_long, "; ".join(too_long) + f" (at most {MAX_LINES}: move its logic into akc_drake/core/)"


def test_the_scan_counts_a_class_from_its_header_to_its_last_line(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(151))
    (tmp_path / "big.py").write_text(f"class Big(LeafSystem):\n{body}\n\n\nclass Other:\n    pass\n")
    assert list(leaf_systems(tmp_path)) == [(Path("big.py"), "Big", 152)]


MAX_MODULE_LINES = 700


def test_no_module_of_the_package_is_over_700_lines():
    """Rooms by concern: a module that grows past 700 lines is split (the layering keeps the split honest)."""
    sizes = {p.relative_to(PACKAGE): len(p.read_text().splitlines()) for p in PACKAGE.rglob("*.py")}
    assert len(sizes) > 50 and max(sizes.values()) > 300  # the scan sees the package
    too_long = sorted(f"{p}: {n} lines" for p, n in sizes.items() if n > MAX_MODULE_LINES)
    assert not too_long, "; ".join(too_long) + f" (at most {MAX_MODULE_LINES})"
