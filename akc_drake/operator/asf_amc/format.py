"""Writing ASF skeleton and AMC motion files (atomically, through :mod:`akc_drake.fileio`); they read back
to equal values."""

from __future__ import annotations

import math
import os

from akc_drake.fileio import atomic_write_text
from akc_drake.operator.asf_amc.model import AMCMotion, ASFSkeleton


def _fmt(v: float) -> str:
    v = float(v)
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v)  # the shortest text that reads back to the same float


def format_asf(skel: ASFSkeleton) -> str:
    """The text of ``skel`` as an ASF file (reads back to an equal skeleton)."""
    out = [
        f":version {skel.version}",
        f":name {skel.name}",
    ]
    if skel.namespace:
        out.append(f":namespace {skel.namespace}")
    out += [
        ":units",
        f"  mass {_fmt(skel.mass_scale)}",
        f"  length {_fmt(skel.length_scale)}",
        f"  angle {skel.angle_unit}",
    ]
    if skel.documentation:
        out.append(":documentation")
        out.extend(line for line in skel.documentation)
    out += [
        ":root",
        "   order " + " ".join(skel.root_order),
        f"   axis {skel.root_axis}",
        "   position " + " ".join(_fmt(v) for v in skel.root_position),
        "   orientation " + " ".join(_fmt(v) for v in skel.root_orientation),
        ":bonedata",
    ]
    for b in skel.bones:
        out += [
            "  begin",
            f"     id {b.id}",
            f"     name {b.name}",
            "     direction " + " ".join(_fmt(v) for v in b.direction),
            f"     length {_fmt(b.length)}",
            "     axis " + " ".join(_fmt(v) for v in b.axis) + f" {b.axis_order}",
        ]
        if b.bodymass is not None:
            out.append(f"     bodymass {_fmt(b.bodymass)}")
        if b.cofmass is not None:
            out.append(f"     cofmass {_fmt(b.cofmass)}")
        if b.dof:
            out.append("     dof " + " ".join(b.dof))
        for k, (lo, hi) in enumerate(b.limits):
            out.append(("     limits " if k == 0 else "            ") + f"({_fmt(lo)} {_fmt(hi)})")
        out.append("  end")
    if skel.skin:
        out.append(":skin")
        out.extend("  " + line for line in skel.skin)
    out += [":hierarchy", "  begin"]
    for parent in ("root",) + skel.bone_names:
        kids = skel.children_order.get(parent)
        if kids:
            out.append(f"    {parent} " + " ".join(kids))
    out.append("  end")
    return "\n".join(out) + "\n"


def write_asf(path: str | os.PathLike, skel: ASFSkeleton) -> None:
    """Write ``skel`` as an ASF file (see :func:`format_asf`)."""
    atomic_write_text(os.fspath(path), format_asf(skel))


def format_amc(motion: AMCMotion, *, asf_name: str | None = None) -> str:
    """The text of ``motion`` as an AMC file (reads back to equal values).

    Args:
        motion: the motion.
        asf_name: written in the leading comment line, for people reading the file.

    Returns:
        The file's text.
    """
    out = [f"# AMC motion written by akc_drake{' for ' + asf_name if asf_name else ''}"]
    if motion.fully_specified:
        out.append(":FULLY-SPECIFIED")
    out.append(":DEGREES" if motion.angle_unit == "deg" else ":RADIANS")
    for f, number in enumerate(motion.frame_numbers):
        out.append(str(int(number)))
        for bone in motion.bone_order:
            out.append(bone + "".join(" " + _fmt(v) for v in motion.values[bone][f]))
    return "\n".join(out) + "\n"


def write_amc(path: str | os.PathLike, motion: AMCMotion, *, asf_name: str | None = None) -> None:
    """Write ``motion`` as an AMC file (see :func:`format_amc`)."""
    atomic_write_text(os.fspath(path), format_amc(motion, asf_name=asf_name))
