"""C3D motion files (marker trajectories) as the operator's input: the arm joints' positions from the markers.

A C3D file holds labelled 3D points, not a skeleton. The joint of each role comes from the first of these that
the file has (labels compared without a ``Subject:`` prefix and without case; a group's markers averaged):

* the role's own name (``left_shoulder``, ...: akc-drake's own C3D export, ``run --export c3d``);
* a joint centre computed by the lab's model: Plug-in Gait's ``LSJC``, ``LEJC``, ``LWJC`` (and ``R...``);
* the Plug-in Gait / CMU markers on the bony landmarks: the shoulder ``LSHO`` (acromion), the elbow ``LELB``
  (lateral epicondyle), the wrist between ``LWRA`` and ``LWRB`` (the radial and ulnar styloids); the pelvis
  between ``LASI``, ``RASI``, ``LPSI``, ``RPSI`` (CMU's waist markers ``LFWT``, ``RFWT``, ``LBWT``, ``RBWT``;
  without a pelvis, the lower thorax ``T10``, ``STRN``: what the up axis is found from);
* markers in pairs either side of a joint, whose midpoint is nearer its centre than one skin marker (the marker
  set of DART's C3D recordings, Georgia Tech's): the shoulder between ``LFSH`` and ``LBSH`` (front and back), the
  elbow between ``LELB`` and ``LIEL`` (the lateral and the inner, medial, epicondyle: before ``LELB`` alone), the
  wrist between ``LOWR`` and ``LIWR`` (outer and inner).

Markers sit on the skin, 3-5 cm from the joint centres, so the segment directions carry a few degrees of that
offset (what the retargeting takes from a file is directions: :mod:`akc_drake.operator.retarget`). A marker's
gaps (invalid frames, NaN in ezc3d) are filled by linear interpolation in time (held before the first and after
the last valid frame); a marker with no valid frame counts as absent. A ``names`` map (role -> label) overrides
the choice for a marker set these names miss; ``LFSH+LBSH`` there averages a group of markers.
"""

from __future__ import annotations

import os

import numpy as np

from akc_drake.errors import UserError

#: Per role, the label groups tried in order (a group's markers are averaged); "{s}" is "L" or "R".
MARKER_RULES: dict[str, tuple[tuple[str, ...], ...]] = {
    "shoulder": (("{side}_shoulder",), ("{s}SJC",), ("{s}SHO",), ("{s}FSH", "{s}BSH")),
    "elbow": (("{side}_elbow",), ("{s}EJC",), ("{s}ELB", "{s}IEL"), ("{s}ELB",)),
    "wrist": (("{side}_wrist",), ("{s}WJC",), ("{s}WRA", "{s}WRB"), ("{s}WRA",), ("{s}WRB",), ("{s}OWR", "{s}IWR")),
    "hip": (("{side}_hip",), ("{s}HJC",)),
    "index": (("{side}_index",),),
    "pinky": (("{side}_pinky",),),
}
#: The pelvis (the "hips" role), when neither hip joint is found.
PELVIS_RULES: tuple[tuple[str, ...], ...] = (
    ("LASI", "RASI", "LPSI", "RPSI"),
    ("LFWT", "RFWT", "LBWT", "RBWT"),
    ("LASI", "RASI"),
    ("LFWT", "RFWT"),
    ("T10", "STRN"),  # (no pelvis: the lower thorax, below the shoulders all the same)
    ("T10",),
    ("STRN",),
)


def read_c3d(path) -> dict:
    """Read a C3D file with ezc3d: ``{"labels", "rate_hz", "units", "points" (T, M, 3)}`` (invalid points NaN).

    Raises:
        UserError: the file cannot be read as C3D.
    """
    import ezc3d

    try:
        c = ezc3d.c3d(os.fspath(path))
    except Exception as e:  # noqa: BLE001 - ezc3d raises plain RuntimeError/IOError with its own text
        raise UserError(f"{os.fspath(path)}: not a readable C3D file ({e})") from None
    pts = np.asarray(c["data"]["points"], dtype=float)  # (4, M, T)
    point = c["parameters"]["POINT"]
    return {
        "labels": [str(s) for s in point["LABELS"]["value"]],
        "rate_hz": float(point["RATE"]["value"][0]),
        "units": point["UNITS"]["value"][0] if "UNITS" in point else "",
        "points": pts[:3].transpose(2, 1, 0),
    }


def _label(label) -> str:
    """A label as compared: without a ``Subject:`` prefix, surrounding spaces or case."""
    return str(label).rsplit(":", 1)[-1].strip().upper()


def fill_gaps(x: np.ndarray) -> np.ndarray | None:
    """``x`` ``(T, 3)`` with its invalid frames (any coordinate not finite) interpolated linearly in time, held
    before the first and after the last valid frame; None when no frame is valid."""
    ok = np.all(np.isfinite(x), axis=1)
    if not ok.any():
        return None
    if ok.all():
        return x
    t = np.arange(x.shape[0])
    return np.stack([np.interp(t, t[ok], x[ok, k]) for k in range(3)], axis=1)


def c3d_joint_positions(labels, points, names: dict | None = None, *, source: str = "c3d"):
    """The arm joints' positions from a C3D file's markers (the rules of the module docstring).

    Args:
        labels: the M point labels.
        points: ``(T, M, 3)`` positions, NaN where invalid.
        names: optional role -> label map (roles as :data:`akc_drake.operator.retarget.ROLES`); a label
            ``A+B`` is the mean of markers ``A`` and ``B``.
        source: the file name for error messages.

    Returns:
        ``(positions (T, J, 3), joint_names)``: one joint per role found, named by the role ("left_shoulder", ...,
        "hips").

    Raises:
        UserError: a role's label in ``names`` is not in the file or has no valid frame, or a shoulder, elbow or
            wrist is found in neither way (the message lists the labels).
    """
    P = np.asarray(points, dtype=float)
    key = {}
    for i, lab in enumerate(labels):
        key.setdefault(_label(lab), i)
    filled: dict[int, np.ndarray | None] = {}

    def marker(label: str) -> np.ndarray | None:
        i = key.get(_label(label))
        if i is None:
            return None
        if i not in filled:
            filled[i] = fill_gaps(P[:, i])
        return filled[i]

    def group(labels_: tuple[str, ...]) -> np.ndarray | None:
        xs = [marker(lab) for lab in labels_]
        return None if any(x is None for x in xs) else np.mean(xs, axis=0)

    def named(role: str) -> np.ndarray:
        """The name map's marker (or ``A+B`` group) for ``role``; a label absent or never valid is one line."""
        group_labels = tuple(names[role].split("+"))
        x = group(group_labels)
        if x is None:
            bad = [lab for lab in group_labels if marker(lab) is None]
            raise UserError(f"{source}: the name map sets {role} = {names[role]!r}, but "
                            f"{', '.join(map(repr, bad))} is no marker with a valid frame (a group is A+B; "
                            f"labels: {', '.join(map(str, labels))})")
        return x

    from akc_drake.operator.retarget import ROLES

    out_names: list[str] = []
    out: list[np.ndarray] = []
    names = dict(names or {})
    unknown = [k for k in names if k not in ROLES]
    if unknown:
        raise UserError(f"{source}: unknown role(s) {', '.join(map(repr, unknown))} in the name map; known: "
                        f"{', '.join(ROLES)}")
    for side in ("left", "right"):
        for part, rules in MARKER_RULES.items():
            role = f"{side}_{part}"
            if role in names:
                x = named(role)
            else:
                x = next((g for r in rules if (g := group(tuple(lab.format(side=side, s=side[0].upper())
                                                                  for lab in r))) is not None), None)
            if x is None:
                if part in ("shoulder", "elbow", "wrist"):
                    tried = " or ".join("+".join(lab.format(side=side, s=side[0].upper()) for lab in r) for r in rules)
                    raise UserError(f"{source}: no marker for {role} (tried {tried}); pass a name map "
                                    f"(--joint-names {role}=LABEL), labels are: {', '.join(map(str, labels))}")
                continue
            out_names.append(role)
            out.append(x)
    if "hips" in names:
        x = named("hips")
    else:
        x = next((g for r in PELVIS_RULES if (g := group(r)) is not None), None)
    if x is not None:
        out_names.append("hips")
        out.append(x)
    return np.stack(out, axis=1), out_names
