"""``akc-drake graph --diagram mocap|teleop --out DIR``: the system graph as .dot and .svg."""

from __future__ import annotations

import sys

from akc_drake.commands._common import check_output_dir
from akc_drake.graphs import write_graph


def build_named_diagram(name: str):
    """The default diagram called ``name`` ("mocap" or "teleop"), built with the default config."""
    from akc_drake import diagrams
    from akc_drake.config import PipelineConfig

    cfg = PipelineConfig()
    if name == "mocap":
        return diagrams.build_mocap_diagram(cfg).diagram
    if name == "teleop":
        return diagrams.build_teleop_diagram(cfg).diagram
    raise ValueError(f"--diagram must be mocap or teleop, got {name!r}")


def main(args) -> int:
    check_output_dir(args.out, "--out")
    diagram = build_named_diagram(args.diagram)
    paths = write_graph(diagram, args.out, args.diagram)
    print(f"wrote {paths['dot']}")
    if paths["svg"] is None:
        print(
            "note: graphviz's 'dot' is not installed, so no SVG was written "
            "(install it with: sudo apt-get install graphviz)",
            file=sys.stderr,
        )
    else:
        print(f"wrote {paths['svg']}")
    return 0
