"""The Acclaim skeleton (ASF) and motion (AMC) in memory, and their forward kinematics (see
:mod:`akc_drake.operator.asf_amc` for the definitions)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from akc_drake.operator.bvh import UNIT_TO_METRES, axis_rotation, unit_scale

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
