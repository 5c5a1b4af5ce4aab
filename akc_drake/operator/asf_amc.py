"""Acclaim skeleton (ASF) and motion (AMC) files, as used by the CMU motion-capture database.

An ASF file describes the skeleton in a rest pose: the root (``:root``), one block per bone
(``:bonedata``: id, name, a unit ``direction`` in the global rest frame, ``length``,
``axis ax ay az ORDER`` giving the bone's local coordinate system, ``dof`` and ``limits``) and the
parent/child relations (``:hierarchy``). ``:units`` gives the length scale (CMU: ``length 0.45``, the
data being in inches: metres = value / 0.45 * 0.0254) and the angle unit. An AMC file lists, frame by
frame, each bone's dof values in its ``dof`` order.

Forward kinematics (the Acclaim definition, written with column vectors):

* ``C`` is the bone's axis rotation, built from the three ``axis`` angles (about x, y, z) in the listed
  order, the first listed applied first: ``axis ... XYZ`` gives ``C = Rz @ Ry @ Rx``.
* ``M`` is the bone's motion rotation built the same way from its rotation dofs in ``dof`` order
  (``dof rx ry rz`` gives ``M = Rz @ Ry @ Rx``).
* The bone's global rotation is ``G = G_parent @ C @ M @ C^-1`` (the spec's row-vector
  ``L = C^-1 M C``), and its distal end is ``end = start + G @ (length * direction)`` (plus any
  translation dofs, expressed in the axis frame C). ``start`` is the parent's end (the root's
  position for children of the root).
* The root uses ``orientation`` (with ``:root axis``) as its C and the AMC values in ``:root order``;
  translation dofs give the root's position (absolute, replacing ``:root position`` on that axis).

Errors in a file raise :class:`akc_drake.errors.UserError` whose message starts with ``file:line:``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from akc_drake.errors import UserError
from akc_drake.operator.bvh import UNIT_TO_METRES, axis_rotation, read_text_file, unit_scale

ROTATION_DOFS = ("rx", "ry", "rz")
TRANSLATION_DOFS = ("tx", "ty", "tz")
BONE_DOFS = ROTATION_DOFS + TRANSLATION_DOFS + ("l",)
ROOT_DOFS = ("TX", "TY", "TZ", "RX", "RY", "RZ")


def _fixed_axes_rotation(order: str, angles_xyz_rad: np.ndarray) -> np.ndarray:
    """Rotation from per-axis angles applied in ``order`` (first letter applied first).

    Args:
        order: a permutation of "XYZ" (any case).
        angles_xyz_rad: ``(..., 3)`` angles about x, y and z, radians.

    Returns:
        ``(..., 3, 3)``: ``R_last @ ... @ R_first``.
    """
    a = np.asarray(angles_xyz_rad, dtype=float)
    R = np.broadcast_to(np.eye(3), a.shape[:-1] + (3, 3)).copy()
    for axis in order.lower():
        R = axis_rotation(axis, a[..., "xyz".index(axis)]) @ R
    return R


@dataclass(frozen=True)
class ASFBone:
    """One ``begin ... end`` block of ``:bonedata`` (values as written in the file).

    Attributes:
        id: the bone's id.
        name: the bone's name.
        direction: ``(3,)`` direction of the bone in the global rest frame.
        length: the bone's length in file units (before the ``:units length`` scale).
        axis: ``(3,)`` angles about x, y, z of the bone's local frame, in the file's angle unit.
        axis_order: order those angles are applied in, e.g. "XYZ".
        dof: the bone's degrees of freedom in AMC order, from rx ry rz tx ty tz l.
        limits: one ``(low, high)`` per dof (may be infinite).
        bodymass, cofmass: optional values, kept for writing.
    """

    id: int
    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str = "XYZ"
    dof: tuple[str, ...] = ()
    limits: tuple[tuple[float, float], ...] = ()
    bodymass: float | None = None
    cofmass: float | None = None

    def __post_init__(self):
        d = np.asarray(self.direction, dtype=float).reshape(-1)
        a = np.asarray(self.axis, dtype=float).reshape(-1)
        if d.shape != (3,) or not np.all(np.isfinite(d)):
            raise ValueError(
                f"ASF bone {self.name!r}: direction must be 3 finite numbers, got {self.direction!r}"
            )
        if a.shape != (3,) or not np.all(np.isfinite(a)):
            raise ValueError(f"ASF bone {self.name!r}: axis must be 3 finite numbers, got {self.axis!r}")
        object.__setattr__(self, "direction", d)
        object.__setattr__(self, "axis", a)
        if not math.isfinite(self.length) or self.length < 0:
            raise ValueError(f"ASF bone {self.name!r}: length must be >= 0, got {self.length!r}")
        if sorted(self.axis_order.upper()) != ["X", "Y", "Z"]:
            raise ValueError(
                f"ASF bone {self.name!r}: axis order must be a permutation of XYZ, got {self.axis_order!r}"
            )
        object.__setattr__(self, "axis_order", self.axis_order.upper())
        dof = tuple(str(x).lower() for x in self.dof)
        for x in dof:
            if x not in BONE_DOFS:
                raise ValueError(f"ASF bone {self.name!r}: unknown dof {x!r} (known: {' '.join(BONE_DOFS)})")
        if len(set(dof)) != len(dof):
            raise ValueError(f"ASF bone {self.name!r}: repeated dof in {dof}")
        object.__setattr__(self, "dof", dof)
        lim = tuple((float(lo), float(hi)) for lo, hi in self.limits)
        if lim and len(lim) != len(dof):
            raise ValueError(f"ASF bone {self.name!r}: {len(lim)} limits for {len(dof)} dof")
        object.__setattr__(self, "limits", lim)


@dataclass
class ASFSkeleton:
    """An Acclaim skeleton.

    Attributes:
        bones: bones in ``:bonedata`` order.
        parents: bone name -> parent name ("root" for children of the root).
        name: ``:name``.
        version: ``:version`` text.
        mass_scale, length_scale: ``:units`` mass and length multipliers.
        angle_unit: "deg" or "rad" (``:units angle``), for ``axis``, ``limits`` and ``orientation``.
        root_order: AMC order of the root's dofs, e.g. ``("TX", "TY", "TZ", "RX", "RY", "RZ")``.
        root_axis: rotation order of ``root_orientation``, e.g. "XYZ".
        root_position: ``(3,)`` in file units.
        root_orientation: ``(3,)`` angles about x, y, z.
        documentation: the ``:documentation`` lines.
        length_unit: the unit a length means after dividing by ``length_scale`` ("in" for CMU data).
        children_order: for each parent, its children in ``:hierarchy`` order (for writing).
        namespace: ``:namespace`` (optional).
        skin: the ``:skin`` lines (file names of skins; kept for writing, not used).
    """

    bones: list[ASFBone]
    parents: dict[str, str]
    name: str = "skeleton"
    version: str = "1.10"
    mass_scale: float = 1.0
    length_scale: float = 1.0
    angle_unit: str = "deg"
    root_order: tuple[str, ...] = ROOT_DOFS
    root_axis: str = "XYZ"
    root_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    root_orientation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    documentation: tuple[str, ...] = ()
    length_unit: str = "in"
    children_order: dict[str, tuple[str, ...]] = field(default_factory=dict)
    namespace: str | None = None
    skin: tuple[str, ...] = ()

    def __post_init__(self):
        self.bones = list(self.bones)
        names = [b.name for b in self.bones]
        if "root" in names:
            raise ValueError("ASF: a bone may not be called 'root'")
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"ASF: repeated bone name(s) {', '.join(dup)}")
        self.angle_unit = self.angle_unit.lower()
        if self.angle_unit not in ("deg", "rad"):
            raise ValueError(f"ASF: angle unit must be deg or rad, got {self.angle_unit!r}")
        unit_scale(self.length_unit)
        if not (math.isfinite(self.length_scale) and self.length_scale > 0):
            raise ValueError(f"ASF: :units length must be a positive number, got {self.length_scale!r}")
        order = tuple(x.upper() for x in self.root_order)
        for x in order:
            if x not in ROOT_DOFS:
                raise ValueError(f"ASF: unknown root dof {x!r} (known: {' '.join(ROOT_DOFS)})")
        if len(set(order)) != len(order):
            raise ValueError(f"ASF: repeated root dof in {order}")
        self.root_order = order
        if sorted(self.root_axis.upper()) != ["X", "Y", "Z"]:
            raise ValueError(f"ASF: root axis must be a permutation of XYZ, got {self.root_axis!r}")
        self.root_axis = self.root_axis.upper()
        self.root_position = np.asarray(self.root_position, dtype=float).reshape(3)
        self.root_orientation = np.asarray(self.root_orientation, dtype=float).reshape(3)
        known = set(names) | {"root"}
        for b in names:
            if b not in self.parents:
                raise ValueError(f"ASF: bone {b!r} has no parent in the hierarchy")
        for child, parent in self.parents.items():
            if child not in known or child == "root":
                raise ValueError(f"ASF: hierarchy names unknown bone {child!r}")
            if parent not in known:
                raise ValueError(f"ASF: hierarchy names unknown parent {parent!r} of {child!r}")
        # Topological order from the root (also detects cycles).
        kids: dict[str, list[str]] = {n: [] for n in known}
        for n in names:
            kids[self.parents[n]].append(n)
        for p, ordered in self.children_order.items():
            if p in kids and sorted(ordered) == sorted(kids[p]):
                kids[p] = list(ordered)
        self.children_order = {p: tuple(c) for p, c in kids.items() if c}
        topo: list[str] = []
        stack = ["root"]
        while stack:
            n = stack.pop()
            if n != "root":
                topo.append(n)
            stack.extend(reversed(kids[n]))
        if len(topo) != len(names):
            missing = sorted(set(names) - set(topo))
            raise ValueError(f"ASF: bone(s) {', '.join(missing)} not connected to the root (a cycle?)")
        self._topo = topo
        self._index = {n: i for i, n in enumerate(names)}

    @property
    def bone_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bones)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """``("root", bone names...)``: the order of :meth:`AMCMotion.global_positions`."""
        return ("root",) + self.bone_names

    def bone(self, name: str) -> ASFBone:
        """The bone called ``name`` (a ``KeyError`` listing the names otherwise)."""
        try:
            return self.bones[self._index[name]]
        except KeyError:
            raise KeyError(
                f"no bone {name!r} in skeleton {self.name!r}; bones: {', '.join(self.bone_names)}"
            ) from None

    @property
    def metres_per_unit(self) -> float:
        """Metres per file length unit: ``1 / length_scale * unit``."""
        return UNIT_TO_METRES[self.length_unit.lower()] / self.length_scale

    def angle_to_rad(self, values) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        return np.deg2rad(v) if self.angle_unit == "deg" else v

    def dof_names(self, bone: str) -> tuple[str, ...]:
        """The AMC value order of ``bone`` (``root_order`` for "root")."""
        return self.root_order if bone == "root" else self.bone(bone).dof


def _fk(skel: ASFSkeleton, values: dict[str, np.ndarray], n_frames: int, angles_rad: bool):
    """Global rotations ``(F, n+1, 3, 3)``, bone starts and ends ``(F, n+1, 3)`` in metres."""
    F = n_frames
    nb = len(skel.bones)
    scale = skel.metres_per_unit
    to_rad = (lambda v: v) if angles_rad else np.deg2rad
    R = np.empty((F, nb + 1, 3, 3))
    start = np.empty((F, nb + 1, 3))
    end = np.empty((F, nb + 1, 3))

    # Root.
    C = _fixed_axes_rotation(skel.root_axis, skel.angle_to_rad(skel.root_orientation))
    pos = np.broadcast_to(skel.root_position * scale, (F, 3)).copy()
    rot = np.zeros((F, 3))
    rv = values.get("root", np.zeros((F, 0)))
    rot_order = ""
    for k, d in enumerate(skel.root_order):
        axis = "xyz".index(d[1].lower())
        if d[0] == "T":
            pos[:, axis] = rv[:, k] * scale
        else:
            rot[:, axis] = to_rad(rv[:, k])
            rot_order += d[1]
    M = _fixed_axes_rotation(rot_order, rot)
    R[:, 0] = C @ M @ C.T
    start[:, 0] = pos
    end[:, 0] = pos
    index = {n: i + 1 for i, n in enumerate(skel.bone_names)}
    index["root"] = 0
    for name in skel._topo:
        b = skel.bone(name)
        i = index[name]
        pi = index[skel.parents[name]]
        C = _fixed_axes_rotation(b.axis_order, skel.angle_to_rad(b.axis))
        v = values.get(name, np.zeros((F, 0)))
        rot = np.zeros((F, 3))
        trans = np.zeros((F, 3))
        dl = np.zeros(F)
        rot_order = ""
        for k, d in enumerate(b.dof):
            if d[0] == "r":
                rot[:, "xyz".index(d[1])] = to_rad(v[:, k])
                rot_order += d[1]
            elif d[0] == "t":
                trans[:, "xyz".index(d[1])] = v[:, k]
            else:
                dl = v[:, k]
        M = _fixed_axes_rotation(rot_order, rot)
        R[:, i] = R[:, pi] @ C @ M @ C.T
        bone_vec = (b.length + dl)[:, None] * b.direction[None, :] + (C @ trans.T).T
        start[:, i] = end[:, pi]
        end[:, i] = end[:, pi] + np.einsum("fij,fj->fi", R[:, i], bone_vec * scale)
    return R, start, end


@dataclass
class AMCMotion:
    """An AMC motion on its skeleton.

    Attributes:
        skeleton: the ASF skeleton.
        frame_numbers: ``(F,)`` frame numbers as written in the file.
        values: bone name ("root" included) -> ``(F, k)`` dof values in the bone's dof order, file units.
        frame_time: seconds per frame (CMU data is 120 Hz).
        angle_unit: unit of the AMC's angles, "deg" or "rad".
        fully_specified: whether the file says ``:FULLY-SPECIFIED``.
        bone_order: the order bones are written in each frame.
        name: a label (the file's stem when read from disk).
    """

    skeleton: ASFSkeleton
    frame_numbers: np.ndarray
    values: dict[str, np.ndarray]
    frame_time: float = 1.0 / 120.0
    angle_unit: str = "deg"
    fully_specified: bool = True
    bone_order: tuple[str, ...] = ()
    name: str = "amc"

    def __post_init__(self):
        self.frame_numbers = np.asarray(self.frame_numbers, dtype=np.int64).reshape(-1)
        F = self.frame_numbers.shape[0]
        ft = float(self.frame_time)
        if not math.isfinite(ft) or ft <= 0:
            raise ValueError(
                f"AMCMotion.frame_time must be a positive number of seconds, got {self.frame_time!r}"
            )
        self.frame_time = ft
        self.angle_unit = self.angle_unit.lower()
        if self.angle_unit not in ("deg", "rad"):
            raise ValueError(f"AMCMotion.angle_unit must be deg or rad, got {self.angle_unit!r}")
        vals = {}
        for bone, v in self.values.items():
            dof = self.skeleton.dof_names(bone)
            a = np.asarray(v, dtype=float)
            if a.shape != (F, len(dof)):
                raise ValueError(
                    f"AMCMotion.values[{bone!r}] must have shape ({F}, {len(dof)}), got {a.shape}"
                )
            if not np.all(np.isfinite(a)):
                raise ValueError(f"AMCMotion.values[{bone!r}] has a non-finite value")
            vals[bone] = a
        self.values = vals
        order = (
            tuple(self.bone_order)
            if self.bone_order
            else tuple(n for n in self.skeleton.joint_names if n in vals)
        )
        if sorted(order) != sorted(vals):
            raise ValueError(
                f"AMCMotion.bone_order {order} does not list exactly the bones with values {sorted(vals)}"
            )
        self.bone_order = order

    @property
    def num_frames(self) -> int:
        return int(self.frame_numbers.shape[0])

    @property
    def joint_names(self) -> tuple[str, ...]:
        """``("root", bone names...)``: the order of :meth:`global_positions`."""
        return self.skeleton.joint_names

    def times(self) -> np.ndarray:
        """``(F,)`` time of each frame in seconds, starting at 0."""
        return np.arange(self.num_frames) * self.frame_time

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Forward kinematics.

        Returns:
            ``(R, start, end)``: global rotations ``(F, n_bones+1, 3, 3)`` and the proximal and distal
            end of each bone ``(F, n_bones+1, 3)`` in metres (index 0 is the root; its start and end
            are its position).
        """
        return _fk(self.skeleton, self.values, self.num_frames, self.angle_unit == "rad")

    def global_positions(self) -> np.ndarray:
        """``(F, n_bones+1, 3)`` in metres: the root, then the distal end of each bone in ASF order."""
        return self.global_transforms()[2]

    def bone_start_positions(self) -> np.ndarray:
        """``(F, n_bones+1, 3)`` in metres: the root, then the proximal end (the joint) of each bone.

        For CMU data the start of ``lhumerus`` is the left shoulder, of ``lradius`` the elbow, of
        ``lwrist`` the wrist.
        """
        return self.global_transforms()[1]


# ---------------------------------------------------------------------------------------------- reading


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


# ---------------------------------------------------------------------------------------------- writing


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
    with open(os.fspath(path), "w", encoding="utf-8", newline="\n") as fh:
        fh.write(format_asf(skel))


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
    with open(os.fspath(path), "w", encoding="utf-8", newline="\n") as fh:
        fh.write(format_amc(motion, asf_name=asf_name))
