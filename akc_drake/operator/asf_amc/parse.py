"""Reading ASF skeleton and AMC motion files; every problem is a UserError starting with ``file:line:``."""

from __future__ import annotations

import math
import os

import numpy as np

from akc_drake.errors import UserError
from akc_drake.operator.asf_amc.model import BONE_DOFS, ROOT_DOFS, AMCMotion, ASFBone, ASFSkeleton
from akc_drake.operator.bvh import read_text_file, unit_scale


def _tokens(line: str) -> list[str]:
    """Tokens of an ASF line: comments removed, commas and parentheses are whitespace."""
    text = line.split("#", 1)[0]
    return text.replace(",", " ").replace("(", " ").replace(")", " ").split()


def _num(tok: str, source: str, line: int, what: str, *, allow_inf: bool = False) -> float:
    try:
        v = float(tok)
    except ValueError:
        raise UserError(f"{source}:{line}: {what}: {tok!r} is not a number") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise UserError(f"{source}:{line}: {what}: {tok!r} is not a finite number")
    return v


def _nums(toks: list[str], n: int, source: str, line: int, what: str) -> list[float]:
    if len(toks) != n:
        raise UserError(f"{source}:{line}: {what} needs {n} number(s), got {len(toks)}: {' '.join(toks)!r}")
    return [_num(t, source, line, what) for t in toks]


def parse_asf(text: str, *, length_unit: str = "in", source: str = "<string>") -> ASFSkeleton:
    """Parse the text of an ASF skeleton file.

    Args:
        text: the whole file.
        length_unit: the unit of a length divided by ``:units length`` ("in" for CMU data).
        source: the file name used in error messages.

    Returns:
        The skeleton.

    Raises:
        UserError: ``source:line: message`` for any problem in the text.
    """
    unit_scale(length_unit)
    lines = text.splitlines()
    if not any(_tokens(x) for x in lines):
        raise UserError(f"{source}:1: empty file (expected an ASF skeleton)")

    def err(line: int, msg: str) -> UserError:
        return UserError(f"{source}:{line}: {msg}")

    info: dict = {
        "name": "skeleton",
        "version": "1.10",
        "mass_scale": 1.0,
        "length_scale": 1.0,
        "angle_unit": "deg",
        "root_order": ROOT_DOFS,
        "root_axis": "XYZ",
        "root_position": np.zeros(3),
        "root_orientation": np.zeros(3),
    }
    documentation: list[str] = []
    skin: list[str] = []
    bones: list[ASFBone] = []
    parents: dict[str, str] = {}
    children_order: dict[str, tuple[str, ...]] = {}
    parent_lines: dict[str, int] = {}
    section = None
    seen_sections: set[str] = set()
    bone: dict | None = None
    bone_line = 0
    limits_pending = 0  # limit pairs still expected on continuation lines
    hierarchy_state = "none"  # none -> open -> closed

    def finish_bone(line: int) -> None:
        nonlocal bone
        assert bone is not None
        for key in ("name", "direction", "length"):
            if key not in bone:
                raise err(bone_line, f"bone block has no {key}")
        if limits_pending:
            raise err(line, f"bone {bone['name']!r}: {limits_pending} limit pair(s) missing")
        dof = bone.get("dof", ())
        lim = bone.get("limits", [])
        if lim and len(lim) != len(dof):
            raise err(bone_line, f"bone {bone['name']!r}: {len(lim)} limit pairs for {len(dof)} dof")
        if "axis" not in bone:
            raise err(bone_line, f"bone {bone['name']!r} has no axis")
        try:
            bones.append(
                ASFBone(
                    id=bone.get("id", len(bones) + 1),
                    name=bone["name"],
                    direction=bone["direction"],
                    length=bone["length"],
                    axis=bone["axis"][0],
                    axis_order=bone["axis"][1],
                    dof=dof,
                    limits=tuple(lim),
                    bodymass=bone.get("bodymass"),
                    cofmass=bone.get("cofmass"),
                )
            )
        except ValueError as e:
            raise err(bone_line, str(e)) from None
        bone = None

    for lineno, raw in enumerate(lines, start=1):
        stripped = raw.split("#", 1)[0].strip()
        if section == "documentation" and not stripped.startswith(":"):
            documentation.append(raw.rstrip())
            continue
        if section == "skin" and stripped and not stripped.startswith(":"):
            skin.append(stripped)
            continue
        toks = _tokens(raw)
        if not toks:
            continue
        head = toks[0]
        if head.startswith(":"):
            key = head[1:].lower()
            if bone is not None:
                raise err(
                    lineno, f"bone block opened on line {bone_line} is not closed with 'end' before {head}"
                )
            if key in seen_sections and key in ("units", "root", "bonedata", "hierarchy"):
                raise err(lineno, f"second {head} section")
            seen_sections.add(key)
            if key == "version":
                info["version"] = " ".join(toks[1:])
                section = None
            elif key == "name":
                info["name"] = " ".join(toks[1:]) or "skeleton"
                section = None
            elif key == "namespace":
                info["namespace"] = " ".join(toks[1:]) or None
                section = None
            elif key == "documentation":
                section = key
                rest = raw.split("#", 1)[0].strip()[len(head) :].strip()
                if rest:
                    documentation.append("   " + rest)
            elif key in ("units", "root", "bonedata", "hierarchy", "skin"):
                if len(toks) > 1:
                    raise err(lineno, f"unexpected {' '.join(toks[1:])!r} after {head}")
                section = key
                if key == "hierarchy":
                    hierarchy_state = "expect_begin"
            else:
                raise err(
                    lineno,
                    f"unknown keyword {head!r} (expected :version, :name, :namespace, :units, "
                    ":documentation, :root, :bonedata, :hierarchy or :skin)",
                )
            continue
        key = head.lower()
        if section == "units":
            if key not in ("mass", "length", "angle") or len(toks) != 2:
                raise err(
                    lineno, f"in :units expected 'mass X', 'length X' or 'angle deg|rad', got {stripped!r}"
                )
            if key == "angle":
                if toks[1].lower() not in ("deg", "rad"):
                    raise err(lineno, f"angle unit must be deg or rad, got {toks[1]!r}")
                info["angle_unit"] = toks[1].lower()
            else:
                v = _num(toks[1], source, lineno, f":units {key}")
                if v <= 0:
                    raise err(lineno, f":units {key} must be positive, got {toks[1]!r}")
                info["mass_scale" if key == "mass" else "length_scale"] = v
        elif section == "root":
            if key == "order":
                order = tuple(t.upper() for t in toks[1:])
                for t in order:
                    if t not in ROOT_DOFS:
                        raise err(lineno, f"unknown root dof {t!r} in order (known: {' '.join(ROOT_DOFS)})")
                if len(set(order)) != len(order):
                    raise err(lineno, f"repeated dof in root order {' '.join(order)!r}")
                info["root_order"] = order
            elif key == "axis":
                if len(toks) != 2 or sorted(toks[1].upper()) != ["X", "Y", "Z"]:
                    raise err(lineno, f"root axis must be a permutation of XYZ, got {' '.join(toks[1:])!r}")
                info["root_axis"] = toks[1].upper()
            elif key in ("position", "orientation"):
                info[f"root_{key}"] = np.array(_nums(toks[1:], 3, source, lineno, f"root {key}"))
            else:
                raise err(
                    lineno, f"unknown keyword {head!r} in :root (expected order, axis, position, orientation)"
                )
        elif section == "bonedata":
            if bone is None:
                if key != "begin" or len(toks) != 1:
                    raise err(lineno, f"expected 'begin' to open a bone block, got {stripped!r}")
                bone = {}
                bone_line = lineno
                continue
            if limits_pending and _is_number(head):
                pair = [_num(t, source, lineno, "limits", allow_inf=True) for t in toks]
                if len(pair) != 2:
                    raise err(lineno, f"a limit is a pair (low high), got {len(pair)} number(s)")
                bone["limits"].append(tuple(pair))
                limits_pending -= 1
                continue
            if limits_pending:
                raise err(lineno, f"bone {bone.get('name', '?')!r}: {limits_pending} limit pair(s) missing")
            if key == "end":
                finish_bone(lineno)
            elif key == "id":
                if len(toks) != 2:
                    raise err(lineno, f"id needs one whole number, got {' '.join(toks[1:])!r}")
                try:
                    bone["id"] = int(toks[1])
                except ValueError:
                    raise err(lineno, f"id: {toks[1]!r} is not a whole number") from None
            elif key == "name":
                if len(toks) != 2:
                    raise err(lineno, f"name needs one word, got {' '.join(toks[1:])!r}")
                if toks[1] == "root" or any(b.name == toks[1] for b in bones):
                    raise err(lineno, f"bone name {toks[1]!r} used twice (or 'root')")
                bone["name"] = toks[1]
            elif key == "direction":
                bone["direction"] = _nums(toks[1:], 3, source, lineno, "direction")
            elif key == "length":
                (length,) = _nums(toks[1:], 1, source, lineno, "length")
                if length < 0:
                    raise err(lineno, f"length must be >= 0, got {toks[1]!r}")
                bone["length"] = length
            elif key == "axis":
                if len(toks) != 5 or sorted(toks[4].upper()) != ["X", "Y", "Z"]:
                    raise err(
                        lineno,
                        f"axis needs three angles and an order such as XYZ, got {' '.join(toks[1:])!r}",
                    )
                bone["axis"] = (_nums(toks[1:4], 3, source, lineno, "axis"), toks[4].upper())
            elif key == "dof":
                dof = tuple(t.lower() for t in toks[1:])
                for t in dof:
                    if t not in BONE_DOFS:
                        raise err(lineno, f"unknown dof {t!r} (known: {' '.join(BONE_DOFS)})")
                if len(set(dof)) != len(dof):
                    raise err(lineno, f"repeated dof in {' '.join(dof)!r}")
                bone["dof"] = dof
            elif key == "limits":
                if "dof" not in bone:
                    raise err(lineno, "limits before dof")
                vals = [_num(t, source, lineno, "limits", allow_inf=True) for t in toks[1:]]
                if len(vals) % 2:
                    raise err(lineno, f"limits come in pairs (low high), got {len(vals)} number(s)")
                bone["limits"] = [tuple(vals[k : k + 2]) for k in range(0, len(vals), 2)]
                limits_pending = len(bone["dof"]) - len(bone["limits"])
                if limits_pending < 0:
                    raise err(lineno, f"{len(bone['limits'])} limit pairs for {len(bone['dof'])} dof")
            elif key in ("bodymass", "cofmass"):
                (bone[key],) = _nums(toks[1:], 1, source, lineno, key)
            else:
                raise err(
                    lineno,
                    f"unknown keyword {head!r} in a bone block (expected id, name, direction, "
                    "length, axis, dof, limits, bodymass, cofmass or end)",
                )
        elif section == "hierarchy":
            if hierarchy_state == "expect_begin":
                if key != "begin" or len(toks) != 1:
                    raise err(lineno, f"expected 'begin' after :hierarchy, got {stripped!r}")
                hierarchy_state = "open"
            elif hierarchy_state == "open":
                if key == "end" and len(toks) == 1:
                    hierarchy_state = "closed"
                    continue
                if len(toks) < 2:
                    raise err(lineno, f"a hierarchy line is 'parent child...', got {stripped!r}")
                parent = toks[0]
                if parent in children_order:
                    children_order[parent] = children_order[parent] + tuple(toks[1:])
                else:
                    children_order[parent] = tuple(toks[1:])
                for child in toks[1:]:
                    if child in parents:
                        raise err(
                            lineno,
                            f"bone {child!r} already has parent {parents[child]!r} "
                            f"(line {parent_lines[child]})",
                        )
                    parents[child] = parent
                    parent_lines[child] = lineno
            else:
                raise err(lineno, f"unexpected {stripped!r} after the hierarchy's 'end'")
        else:
            raise err(lineno, f"unexpected {stripped!r} outside any section")

    last = len(lines)
    if bone is not None:
        raise err(last, f"file ends inside the bone block opened on line {bone_line}")
    if "bonedata" not in seen_sections:
        raise err(last, "no :bonedata section")
    if hierarchy_state in ("expect_begin", "open"):
        raise err(last, "file ends inside :hierarchy (missing 'end')")
    if not bones:
        raise err(last, "no bones in :bonedata")
    names = {b.name for b in bones}
    for child, parent in parents.items():
        if child not in names:
            raise err(parent_lines[child], f"hierarchy names unknown bone {child!r}")
        if parent != "root" and parent not in names:
            raise err(parent_lines[child], f"hierarchy names unknown parent {parent!r}")
    for b in bones:
        if b.name not in parents:
            raise err(last, f"bone {b.name!r} does not appear in :hierarchy")
    try:
        return ASFSkeleton(
            bones=bones,
            parents=parents,
            documentation=tuple(documentation),
            skin=tuple(skin),
            length_unit=length_unit,
            children_order=children_order,
            **info,
        )
    except ValueError as e:
        raise err(last, str(e)) from None


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def read_asf(path: str | os.PathLike, *, length_unit: str = "in") -> ASFSkeleton:
    """Read an ASF skeleton file.

    Args:
        path: the file.
        length_unit: what a length means after dividing by ``:units length`` ("in" for CMU data).

    Returns:
        The skeleton.

    Raises:
        UserError: the file cannot be read, or ``file:line: message`` for a problem in it.
    """
    path = os.fspath(path)
    return parse_asf(read_text_file(path, "ASF"), length_unit=length_unit, source=path)


def parse_amc(
    text: str,
    skeleton: ASFSkeleton,
    *,
    frame_rate: float = 120.0,
    source: str = "<string>",
    name: str = "amc",
) -> AMCMotion:
    """Parse the text of an AMC motion file.

    Args:
        text: the whole file.
        skeleton: the ASF skeleton the motion was captured on.
        frame_rate: frames per second (AMC files do not store it; CMU data is 120 Hz).
        source: the file name used in error messages.
        name: a label for the motion.

    Returns:
        The motion.

    Raises:
        UserError: ``source:line: message`` for any problem in the text.
    """
    if not (isinstance(frame_rate, (int, float)) and math.isfinite(frame_rate) and frame_rate > 0):
        raise UserError(f"frame_rate must be a positive number of frames per second, got {frame_rate!r}")
    lines = text.splitlines()
    if not any(_tokens(x) for x in lines):
        raise UserError(f"{source}:1: empty file (expected AMC frames)")
    dofs = {n: skeleton.dof_names(n) for n in skeleton.joint_names}
    expected = [n for n in skeleton.joint_names if dofs[n]]
    angle_unit = skeleton.angle_unit
    fully = False
    frame_numbers: list[int] = []
    frame_lines: list[int] = []
    rows: list[dict[str, list[float]]] = []
    bone_order: list[str] = []

    def close_frame() -> None:
        if not rows:
            return
        missing = [n for n in expected if n not in rows[-1]]
        if missing:
            raise UserError(
                f"{source}:{frame_lines[-1]}: frame {frame_numbers[-1]} lacks bone(s) {', '.join(missing)}"
            )

    for lineno, raw in enumerate(lines, start=1):
        toks = raw.split("#", 1)[0].split()
        if not toks:
            continue
        head = toks[0]
        if head.startswith(":"):
            if rows:
                raise UserError(f"{source}:{lineno}: keyword {head!r} after the first frame")
            key = head.upper()
            if key == ":FULLY-SPECIFIED":
                fully = True
            elif key == ":DEGREES":
                angle_unit = "deg"
            elif key == ":RADIANS":
                angle_unit = "rad"
            else:
                raise UserError(
                    f"{source}:{lineno}: unknown keyword {head!r} "
                    "(expected :FULLY-SPECIFIED, :DEGREES or :RADIANS)"
                )
            continue
        if len(toks) == 1 and head.lstrip("+-").isdigit():
            close_frame()
            frame_numbers.append(int(head))
            frame_lines.append(lineno)
            rows.append({})
            continue
        if not rows:
            raise UserError(f"{source}:{lineno}: expected a frame number before {head!r}")
        if head not in dofs:
            raise UserError(f"{source}:{lineno}: unknown bone {head!r} (not in skeleton {skeleton.name!r})")
        if head in rows[-1]:
            raise UserError(f"{source}:{lineno}: bone {head!r} appears twice in frame {frame_numbers[-1]}")
        want = len(dofs[head])
        if len(toks) - 1 != want:
            raise UserError(
                f"{source}:{lineno}: bone {head!r} has {len(toks) - 1} value(s), its dof "
                f"({' '.join(dofs[head]) or 'none'}) needs {want}"
            )
        rows[-1][head] = [
            _num(t, source, lineno, f"bone {head!r} value {k + 1}") for k, t in enumerate(toks[1:])
        ]
        if len(rows) == 1:
            bone_order.append(head)
    close_frame()
    if not rows:
        raise UserError(f"{source}:{len(lines)}: no frames in the AMC file")
    present = [n for n in skeleton.joint_names if n in rows[0] or n in expected]
    values = {
        n: np.array([r[n] for r in rows], dtype=float).reshape(len(rows), len(dofs[n])) for n in present
    }
    order = tuple(bone_order) + tuple(n for n in present if n not in bone_order)
    return AMCMotion(
        skeleton=skeleton,
        frame_numbers=np.array(frame_numbers),
        values=values,
        frame_time=1.0 / float(frame_rate),
        angle_unit=angle_unit,
        fully_specified=fully,
        bone_order=order,
        name=name,
    )


def read_amc(
    path: str | os.PathLike,
    skeleton: ASFSkeleton | str | os.PathLike,
    *,
    frame_rate: float = 120.0,
    length_unit: str = "in",
) -> AMCMotion:
    """Read an AMC motion file.

    Args:
        path: the AMC file.
        skeleton: its skeleton, or the path of its ASF file.
        frame_rate: frames per second (CMU data: 120).
        length_unit: used when ``skeleton`` is a path (see :func:`read_asf`).

    Returns:
        The motion, named after the file's stem.

    Raises:
        UserError: a file cannot be read, or ``file:line: message`` for a problem in it.
    """
    if not isinstance(skeleton, ASFSkeleton):
        skeleton = read_asf(skeleton, length_unit=length_unit)
    path = os.fspath(path)
    stem = os.path.splitext(os.path.basename(path))[0]
    return parse_amc(read_text_file(path, "AMC"), skeleton, frame_rate=frame_rate, source=path, name=stem)
