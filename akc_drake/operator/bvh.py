"""Biovision Hierarchy (BVH) motion-capture files: reader, writer and forward kinematics.

A BVH file has two parts::

    HIERARCHY
    ROOT Hips
    {
        OFFSET 0 0 0
        CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
        JOINT Spine
        {
            OFFSET 0 10 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {
                OFFSET 0 10 0
            }
        }
    }
    MOTION
    Frames: 2
    Frame Time: 0.0333333
    0 90 0 0 0 0 0 0 0
    0 90 0 0 0 0 45 0 0

Semantics used here (the ones most tools agree on):

* Each joint's local transform is ``Trans(t) * Rot(R)``. ``t`` is the joint's OFFSET, except that an
  axis with a position channel takes the channel's value instead (position channels are the joint's
  absolute translation in its parent's frame, as Blender and MotionBuilder read them).
* ``R`` is the product of the rotation channels in the order they are listed,
  ``R = R_a1(v1) @ R_a2(v2) @ R_a3(v3)`` for ``CHANNELS 3 a1 a2 a3``: intrinsic rotations, the first
  listed outermost. Angles are in degrees; rotations are right-handed (active).
* A joint's global position is the origin of its global frame,
  ``p_j = p_parent + R_parent_global @ t_j``; ``R_j_global = R_parent_global @ R_j``.
* An ``End Site`` is kept as a joint without channels, named ``<parent>_end``, so its position (often the
  hand or the head top) is available.

Lengths are kept in the file's own units (so files round-trip exactly); :meth:`BVHMotion.global_positions`
converts to metres with the motion's ``units`` ("cm" by default, the unit most exporters write).

Errors in a file raise :class:`akc_drake.errors.UserError` whose message starts with ``file:line:``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from akc_drake.errors import UserError
from akc_drake.fileio import atomic_write_text

#: Metres per length unit.
UNIT_TO_METRES: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}

POSITION_CHANNELS: tuple[str, ...] = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS: tuple[str, ...] = ("Xrotation", "Yrotation", "Zrotation")
_CHANNEL_BY_LOWER = {c.lower(): c for c in POSITION_CHANNELS + ROTATION_CHANNELS}
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def unit_scale(units: str) -> float:
    """Metres per unit for ``units`` in {"m", "cm", "mm", "in"}.

    Raises:
        UserError: naming the unknown unit.
    """
    try:
        return UNIT_TO_METRES[str(units).lower()]
    except KeyError:
        raise UserError(f"units must be one of {', '.join(UNIT_TO_METRES)}, got {units!r}") from None


def axis_rotation(axis: str, angle_rad) -> np.ndarray:
    """Right-handed rotation matrices about ``axis`` ("x", "y" or "z") by ``angle_rad``.

    Args:
        axis: the rotation axis, case-insensitive.
        angle_rad: a scalar or an array of shape ``(N,)`` of angles in radians.

    Returns:
        ``(3, 3)`` for a scalar angle, ``(N, 3, 3)`` for an array.
    """
    a = np.asarray(angle_rad, dtype=float)
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones_like(a), np.zeros_like(a)
    k = _AXIS_INDEX[axis.lower()]
    if k == 0:
        rows = ((one, zero, zero), (zero, c, -s), (zero, s, c))
    elif k == 1:
        rows = ((c, zero, s), (zero, one, zero), (-s, zero, c))
    else:
        rows = ((c, -s, zero), (s, c, zero), (zero, zero, one))
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


@dataclass(frozen=True)
class BVHJoint:
    """One node of a BVH hierarchy.

    Attributes:
        name: the joint's name (``<parent>_end`` for an End Site).
        parent: index of the parent joint in :attr:`BVHMotion.joints`, -1 for a root.
        offset: ``(3,)`` OFFSET in the file's units.
        channels: channel names in file order, e.g. ``("Zrotation", "Xrotation", "Yrotation")``.
        end_site: True for an ``End Site`` (no channels, no children).
    """

    name: str
    parent: int
    offset: np.ndarray
    channels: tuple[str, ...] = ()
    end_site: bool = False

    def __post_init__(self):
        off = np.asarray(self.offset, dtype=float).reshape(-1)
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise ValueError(f"BVHJoint {self.name!r}: offset must be 3 finite numbers, got {self.offset!r}")
        object.__setattr__(self, "offset", off)
        chans = tuple(self.channels)
        for c in chans:
            if c not in _CHANNEL_BY_LOWER.values():
                raise ValueError(f"BVHJoint {self.name!r}: unknown channel {c!r}")
        if len(set(chans)) != len(chans):
            raise ValueError(f"BVHJoint {self.name!r}: repeated channel in {chans}")
        if self.end_site and chans:
            raise ValueError(f"BVHJoint {self.name!r}: an End Site has no channels, got {chans}")
        object.__setattr__(self, "channels", chans)


@dataclass
class BVHMotion:
    """A BVH skeleton with its motion.

    Attributes:
        joints: the hierarchy in file (depth-first) order, End Sites included.
        frame_time: seconds per frame (> 0).
        channels: ``(F, C)`` channel values in file order and file units (degrees for rotations).
        units: length unit of the file ("cm", "m", "mm" or "in"), used to convert to metres.
        name: a label (the file's stem when read from disk).
    """

    joints: list[BVHJoint]
    frame_time: float
    channels: np.ndarray
    units: str = "cm"
    name: str = "bvh"
    _columns: list[np.ndarray] = field(init=False, repr=False, default_factory=list)

    def __post_init__(self):
        self.joints = list(self.joints)
        if not self.joints:
            raise ValueError("BVHMotion needs at least one joint")
        unit_scale(self.units)
        ft = float(self.frame_time)
        if not math.isfinite(ft) or ft <= 0.0:
            raise ValueError(
                f"BVHMotion.frame_time must be a positive number of seconds, got {self.frame_time!r}"
            )
        self.frame_time = ft
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"BVHMotion: repeated joint name(s) {', '.join(dup)}")
        for i, j in enumerate(self.joints):
            if not (-1 <= j.parent < i):
                raise ValueError(
                    f"BVHMotion: joint {j.name!r} (index {i}) has parent {j.parent}; parents come first"
                )
            if j.parent >= 0 and self.joints[j.parent].end_site:
                raise ValueError(f"BVHMotion: joint {j.name!r} has an End Site as parent")
        if self.joints[0].parent != -1:
            raise ValueError("BVHMotion: the first joint must be a root (parent -1)")
        # The writer nests children in list order, so the list must be a depth-first pre-order.
        children: list[list[int]] = [[] for _ in self.joints]
        for i, j in enumerate(self.joints):
            if j.parent >= 0:
                children[j.parent].append(i)
        order: list[int] = []

        def visit(i: int) -> None:
            order.append(i)
            for c in children[i]:
                visit(c)

        for i, j in enumerate(self.joints):
            if j.parent == -1:
                visit(i)
        if order != list(range(len(self.joints))):
            raise ValueError(
                "BVHMotion: joints must be listed in depth-first order (each subtree contiguous)"
            )
        ncol = sum(len(j.channels) for j in self.joints)
        ch = np.asarray(self.channels, dtype=float)
        if ch.ndim == 1 and ch.size == 0:
            ch = ch.reshape(0, ncol)
        if ch.ndim != 2 or ch.shape[1] != ncol:
            raise ValueError(f"BVHMotion.channels must have shape (F, {ncol}), got {ch.shape}")
        if not np.all(np.isfinite(ch)):
            bad = np.argwhere(~np.isfinite(ch))[0]
            raise ValueError(f"BVHMotion.channels has a non-finite value at frame {bad[0]}, column {bad[1]}")
        self.channels = ch
        start = 0
        self._columns = []
        for j in self.joints:
            self._columns.append(np.arange(start, start + len(j.channels)))
            start += len(j.channels)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Joint names in hierarchy order (End Sites included)."""
        return tuple(j.name for j in self.joints)

    @property
    def num_frames(self) -> int:
        return int(self.channels.shape[0])

    @property
    def frame_rate(self) -> float:
        """Frames per second."""
        return 1.0 / self.frame_time

    def times(self) -> np.ndarray:
        """``(F,)`` time of each frame in seconds, starting at 0."""
        return np.arange(self.num_frames) * self.frame_time

    def joint_index(self, name: str) -> int:
        """Index of joint ``name`` (a ``KeyError`` listing the names otherwise)."""
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise KeyError(
            f"no joint {name!r} in BVH motion {self.name!r}; joints: {', '.join(self.joint_names)}"
        )

    def column(self, joint: str, channel: str) -> int:
        """Column of :attr:`channels` holding ``channel`` (e.g. "Yrotation") of ``joint``.

        Raises:
            KeyError: naming the joint and its channels when it has no such channel.
        """
        i = self.joint_index(joint)
        chans = self.joints[i].channels
        if channel not in chans:
            raise KeyError(f"joint {joint!r} has no channel {channel!r}; it has {', '.join(chans) or 'none'}")
        return int(self._columns[i][chans.index(channel)])

    def joint_channels(self, name: str) -> np.ndarray:
        """``(F, k)`` channel values of joint ``name`` in its channel order."""
        return self.channels[:, self._columns[self.joint_index(name)]]

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics.

        Returns:
            ``(R, p)``: global rotations ``(F, J, 3, 3)`` and positions ``(F, J, 3)`` in metres.
        """
        F, J = self.num_frames, len(self.joints)
        scale = unit_scale(self.units)
        R = np.empty((F, J, 3, 3))
        p = np.empty((F, J, 3))
        for i, joint in enumerate(self.joints):
            t = np.broadcast_to(joint.offset * scale, (F, 3)).copy()
            R_local = np.broadcast_to(np.eye(3), (F, 3, 3)).copy()
            cols = self._columns[i]
            for k, name in enumerate(joint.channels):
                v = self.channels[:, cols[k]]
                axis = name[0].lower()
                if name.endswith("position"):
                    t[:, _AXIS_INDEX[axis]] = v * scale
                else:
                    # Intrinsic rotations: the channel listed first is the outermost factor.
                    R_local = R_local @ axis_rotation(axis, np.deg2rad(v))
            if joint.parent < 0:
                R[:, i] = R_local
                p[:, i] = t
            else:
                Rp = R[:, joint.parent]
                R[:, i] = Rp @ R_local
                p[:, i] = p[:, joint.parent] + np.einsum("fij,fj->fi", Rp, t)
        return R, p

    def global_positions(self) -> np.ndarray:
        """``(F, n_joints, 3)`` global joint positions in metres, in :attr:`joint_names` order."""
        return self.global_transforms()[1]


# ---------------------------------------------------------------------------------------------- reading


class _Tokens:
    """Whitespace tokens of the HIERARCHY part with their line numbers (comments removed)."""

    def __init__(self, lines: list[str], source: str):
        self.source = source
        self.items: list[tuple[str, int]] = []
        self.motion_line = 0  # line number of the MOTION keyword, 0 if absent
        for lineno, raw in enumerate(lines, start=1):
            text = raw.split("#", 1)[0]
            toks = text.replace("{", " { ").replace("}", " } ").split()
            if toks and toks[0].upper() == "MOTION":
                if len(toks) > 1:
                    raise self.error(lineno, f"unexpected {' '.join(toks[1:])!r} after MOTION")
                self.motion_line = lineno
                break
            if len(toks) > 2 and toks[0].upper() in ("ROOT", "JOINT"):
                # A name with spaces ("JOINT Bip01 L UpperArm"): the rest of the line up to a brace.
                k = next((i for i, t in enumerate(toks) if t in "{}"), len(toks))
                if k > 2:
                    toks = [toks[0], " ".join(toks[1:k])] + toks[k:]
            self.items.extend((t, lineno) for t in toks)
        self.pos = 0
        self.last_line = len(lines)

    def error(self, line: int, message: str) -> UserError:
        return UserError(f"{self.source}:{line}: {message}")

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, what: str) -> tuple[str, int]:
        tok = self.peek()
        if tok is None:
            end = self.motion_line or self.last_line
            raise self.error(end, f"file ends in the HIERARCHY while expecting {what}")
        self.pos += 1
        return tok

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok != word:
            raise self.error(line, f"expected {word!r}, got {tok!r}")
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        return _parse_float(tok, self.source, line, what)


def _parse_float(tok: str, source: str, line: int, what: str) -> float:
    try:
        v = float(tok)
    except ValueError:
        raise UserError(f"{source}:{line}: {what}: {tok!r} is not a number") from None
    if not math.isfinite(v):
        raise UserError(f"{source}:{line}: {what}: {tok!r} is not a finite number")
    return v


def _parse_joint(tk: _Tokens, joints: list[BVHJoint], parent: int, name: str, line: int, kind: str) -> None:
    index = len(joints)
    tk.expect("{")
    offset = None
    channels: tuple[str, ...] | None = None
    # Reserve the slot so children get the right parent index; filled in when the block closes.
    joints.append(None)  # type: ignore[arg-type]
    while True:
        tok, tline = tk.next(f"'}}' closing {kind} {name!r} (opened on line {line})")
        key = tok.upper()
        if tok == "}":
            break
        if key == "OFFSET":
            if offset is not None:
                raise tk.error(tline, f"second OFFSET in {kind} {name!r}")
            offset = [tk.number(f"OFFSET of {name!r}") for _ in range(3)]
        elif key == "CHANNELS":
            if channels is not None:
                raise tk.error(tline, f"second CHANNELS in {kind} {name!r}")
            ntok, nline = tk.next("the number of channels")
            try:
                n = int(ntok)
            except ValueError:
                raise tk.error(nline, f"CHANNELS of {name!r}: {ntok!r} is not a whole number") from None
            if not 0 <= n <= 6:
                raise tk.error(nline, f"CHANNELS of {name!r}: count must be 0..6, got {n}")
            names = []
            for _ in range(n):
                ctok, cline = tk.next(f"channel name of {name!r}")
                canon = _CHANNEL_BY_LOWER.get(ctok.lower())
                if canon is None:
                    raise tk.error(
                        cline,
                        f"CHANNELS of {name!r}: unknown channel {ctok!r} (CHANNELS {n} announces {n} names "
                        f"from {', '.join(POSITION_CHANNELS + ROTATION_CHANNELS)})",
                    )
                if canon in names:
                    raise tk.error(cline, f"CHANNELS of {name!r}: channel {canon} listed twice")
                names.append(canon)
            channels = tuple(names)
        elif key in ("JOINT", "END"):
            if offset is None:
                raise tk.error(tline, f"{kind} {name!r} has no OFFSET before its children")
            if channels is None:
                raise tk.error(line, f"{kind} {name!r} has no CHANNELS")
            if key == "JOINT":
                cname, cline = tk.next("a joint name after JOINT")
                _parse_joint(tk, joints, index, cname, tline, "JOINT")
            else:
                site, sline = tk.next("'Site' after 'End'")
                if site.upper() != "SITE":
                    raise tk.error(sline, f"expected 'End Site', got 'End {site}'")
                _parse_end_site(tk, joints, index, name, tline)
        else:
            raise tk.error(
                tline,
                f"unknown keyword {tok!r} in {kind} {name!r} "
                "(expected OFFSET, CHANNELS, JOINT, End Site or '}')",
            )
    if offset is None:
        raise tk.error(line, f"{kind} {name!r} has no OFFSET")
    if channels is None:
        raise tk.error(line, f"{kind} {name!r} has no CHANNELS")
    joints[index] = BVHJoint(name=name, parent=parent, offset=np.array(offset), channels=channels)


def _parse_end_site(tk: _Tokens, joints: list[BVHJoint], parent: int, parent_name: str, line: int) -> None:
    tk.expect("{")
    offset = None
    while True:
        tok, tline = tk.next(f"'}}' closing the End Site of {parent_name!r} (opened on line {line})")
        if tok == "}":
            break
        if tok.upper() == "OFFSET":
            if offset is not None:
                raise tk.error(tline, f"second OFFSET in the End Site of {parent_name!r}")
            offset = [tk.number(f"OFFSET of the End Site of {parent_name!r}") for _ in range(3)]
        else:
            raise tk.error(
                tline, f"unknown keyword {tok!r} in the End Site of {parent_name!r} (expected OFFSET or '}}')"
            )
    if offset is None:
        raise tk.error(line, f"the End Site of {parent_name!r} has no OFFSET")
    taken = {j.name for j in joints if j is not None}
    name = f"{parent_name}_end"
    k = 2
    while name in taken:
        name = f"{parent_name}_end{k}"
        k += 1
    joints.append(BVHJoint(name=name, parent=parent, offset=np.array(offset), end_site=True))


def parse_bvh(text: str, *, units: str = "cm", source: str = "<string>", name: str = "bvh") -> BVHMotion:
    """Parse the text of a BVH file.

    Args:
        text: the whole file.
        units: length unit of the file ("cm", "m", "mm" or "in").
        source: the file name used in error messages.
        name: a label for the motion.

    Returns:
        The motion.

    Raises:
        UserError: ``source:line: message`` for any problem in the text.
    """
    unit_scale(units)
    lines = text.splitlines()
    if not any(line.split("#", 1)[0].strip() for line in lines):
        raise UserError(f"{source}:1: empty file (expected HIERARCHY)")
    tk = _Tokens(lines, source)
    tok, line = tk.next("HIERARCHY")
    if tok.upper() != "HIERARCHY":
        raise tk.error(line, f"expected HIERARCHY at the start of a BVH file, got {tok!r}")
    joints: list[BVHJoint] = []
    while tk.peek() is not None:
        tok, line = tk.next("ROOT")
        if tok.upper() != "ROOT":
            raise tk.error(line, f"unknown keyword {tok!r} (expected ROOT or MOTION)")
        rname, _ = tk.next("a joint name after ROOT")
        _parse_joint(tk, joints, -1, rname, line, "ROOT")
    if not joints:
        raise tk.error(tk.motion_line or tk.last_line, "no ROOT in the HIERARCHY")
    if not tk.motion_line:
        raise tk.error(tk.last_line, "file ends without a MOTION section")
    names = [j.name for j in joints]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise UserError(f"{source}:{tk.motion_line}: repeated joint name(s) {', '.join(dup)}")
    ncol = sum(len(j.channels) for j in joints)

    # MOTION: line based.
    body = [
        (lineno, lines[lineno - 1].split("#", 1)[0].strip())
        for lineno in range(tk.motion_line + 1, len(lines) + 1)
    ]
    body = [(n, t) for n, t in body if t]
    last = len(lines)

    def header(i: int, key: str) -> tuple[str, int]:
        if i >= len(body):
            raise UserError(f"{source}:{last}: file ends before '{key}'")
        lineno, t = body[i]
        if (
            t.replace(" ", "").replace("\t", "").lower()[: len(key.replace(" ", ""))]
            != key.replace(" ", "").lower()
        ):
            raise UserError(f"{source}:{lineno}: expected '{key} ...', got {t!r}")
        # Take what follows the colon.
        value = t.split(":", 1)[1].strip() if ":" in t else ""
        return value, lineno

    value, fline = header(0, "Frames:")
    try:
        n_frames = int(value)
    except ValueError:
        raise UserError(f"{source}:{fline}: Frames: {value!r} is not a whole number") from None
    if n_frames < 0:
        raise UserError(f"{source}:{fline}: Frames: must be >= 0, got {n_frames}")
    value, tline = header(1, "Frame Time:")
    frame_time = _parse_float(value, source, tline, "Frame Time")
    if frame_time <= 0.0:
        raise UserError(f"{source}:{tline}: Frame Time: must be a positive number of seconds, got {value!r}")
    rows = body[2:]
    if len(rows) < n_frames:
        raise UserError(
            f"{source}:{last}: truncated MOTION: 'Frames: {n_frames}' (line {fline}) but the file ends "
            f"after {len(rows)} frame row(s)"
        )
    if len(rows) > n_frames:
        lineno = rows[n_frames][0]
        raise UserError(
            f"{source}:{lineno}: more frame rows than 'Frames: {n_frames}' (line {fline}) announces"
        )
    data = np.empty((n_frames, ncol))
    for f, (lineno, t) in enumerate(rows):
        vals = t.split()
        if len(vals) != ncol:
            raise UserError(
                f"{source}:{lineno}: frame {f} has {len(vals)} values, the HIERARCHY declares {ncol} channels"
            )
        for k, v in enumerate(vals):
            data[f, k] = _parse_float(v, source, lineno, f"frame {f}, value {k + 1}")
    return BVHMotion(joints=joints, frame_time=frame_time, channels=data, units=units, name=name)


def read_bvh(path: str | os.PathLike, *, units: str = "cm") -> BVHMotion:
    """Read a BVH file.

    Args:
        path: the file.
        units: the file's length unit ("cm" default, "m", "mm" or "in").

    Returns:
        The motion, named after the file's stem.

    Raises:
        UserError: the file cannot be read, or ``file:line: message`` for a problem in it.
    """
    path = os.fspath(path)
    text = read_text_file(path, "BVH")
    stem = os.path.splitext(os.path.basename(path))[0]
    return parse_bvh(text, units=units, source=path, name=stem)


def read_text_file(path: str, kind: str) -> str:
    """The text of a motion-capture file (UTF-8, BOM allowed); a UserError naming ``path`` if it cannot be read.

    Args:
        path: the file.
        kind: what the file should be (e.g. "BVH", "ASF skeleton"), for the message.
    """
    try:
        with open(path, encoding="utf-8-sig", errors="strict") as fh:
            return fh.read()
    except FileNotFoundError:
        raise UserError(f"{path}: no such {kind} file") from None
    except UnicodeDecodeError as e:
        raise UserError(f"{path}: not a text file ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise UserError(f"{path}: cannot read ({e.strerror})") from None


# ---------------------------------------------------------------------------------------------- writing


def _fmt(v: float, precision: int | None) -> str:
    if precision is None:
        return repr(float(v))  # the shortest text that reads back to the same float
    return f"{float(v):.{precision}f}"


def format_bvh(motion: BVHMotion, *, precision: int | None = None) -> str:
    """The text of ``motion`` as a BVH file.

    Args:
        motion: the motion to write.
        precision: decimals for the values; ``None`` writes each float exactly (round-trips bit for bit).

    Returns:
        The file's text.
    """
    out = ["HIERARCHY"]
    joints = motion.joints
    children: list[list[int]] = [[] for _ in joints]
    for i, j in enumerate(joints):
        if j.parent >= 0:
            children[j.parent].append(i)

    def emit(i: int, depth: int) -> None:
        j = joints[i]
        ind = "\t" * depth
        if j.end_site:
            out.append(f"{ind}End Site")
        else:
            out.append(f"{ind}{'ROOT' if j.parent < 0 else 'JOINT'} {j.name}")
        out.append(f"{ind}{{")
        out.append(f"{ind}\tOFFSET " + " ".join(_fmt(v, precision) for v in j.offset))
        if not j.end_site:
            out.append(f"{ind}\tCHANNELS {len(j.channels)}" + "".join(" " + c for c in j.channels))
        for c in children[i]:
            emit(c, depth + 1)
        out.append(f"{ind}}}")

    for i, j in enumerate(joints):
        if j.parent < 0:
            emit(i, 0)
    out.append("MOTION")
    out.append(f"Frames: {motion.num_frames}")
    out.append(f"Frame Time: {_fmt(motion.frame_time, None)}")
    for row in motion.channels:
        out.append(" ".join(_fmt(v, precision) for v in row))
    return "\n".join(out) + "\n"


def write_bvh(path: str | os.PathLike, motion: BVHMotion, *, precision: int | None = None) -> None:
    """Write ``motion`` as a BVH file (see :func:`format_bvh`).

    Args:
        path: the file to write (overwritten).
        motion: the motion.
        precision: decimals for the values; ``None`` (default) round-trips exactly.
    """
    atomic_write_text(os.fspath(path), format_bvh(motion, precision=precision))
