"""Tests for akc_drake.operator.asf_amc: ASF/AMC parsing, forward kinematics, units, writing, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from akc_drake.errors import UserError
from akc_drake.operator.asf_amc import (
    AMCMotion,
    format_amc,
    format_asf,
    parse_amc,
    parse_asf,
    read_amc,
    read_asf,
    write_amc,
    write_asf,
)

DATA = Path(__file__).parent / "data" / "mocap"
IN = 0.0254 / 0.45  # metres per CMU length unit


def _one_bone(axis: str, dof: str, direction: str = "1 0 0", units: str = "length 1.0") -> str:
    """A root and one bone of length 2 (file units)."""
    return (
        f":version 1.10\n:name one\n:units\n  mass 1.0\n  {units}\n  angle deg\n"
        ":root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n  position 0 0 0\n  orientation 0 0 0\n"
        f":bonedata\n  begin\n    id 1\n    name b\n    direction {direction}\n    length 2\n"
        f"    axis {axis}\n    dof {dof}\n  end\n:hierarchy\n  begin\n    root b\n  end\n"
    )


def _end(asf: str, amc_values: str, angle: str = ":DEGREES") -> np.ndarray:
    skel = parse_asf(asf, length_unit="m")
    m = parse_amc(f"{angle}\n1\nroot 0 0 0 0 0 0\nb {amc_values}\n", skel)
    return m.global_positions()[0, 1]


def test_bone_axis_conjugates_the_motion_rotation():
    # C = Rz(90): rx acts about C x = +y. Ry(90) takes the bone (x) to -z.
    np.testing.assert_allclose(_end(_one_bone("0 0 90 XYZ", "rx"), "90"), [0, 0, -2], atol=1e-12)
    # Without the axis rotation, rx about x leaves a bone along x where it is.
    np.testing.assert_allclose(_end(_one_bone("0 0 0 XYZ", "rx"), "90"), [2, 0, 0], atol=1e-12)
    # rz with C = I: x -> +y.
    np.testing.assert_allclose(_end(_one_bone("0 0 0 XYZ", "rz"), "90"), [0, 2, 0], atol=1e-12)


def test_dof_order_is_the_rotation_order():
    # dof "rz rx": z first, then x: x -> y -> z.
    np.testing.assert_allclose(_end(_one_bone("0 0 0 XYZ", "rz rx"), "90 90"), [0, 0, 2], atol=1e-12)
    # dof "rx rz": x first (no effect on x), then z: x -> y.
    np.testing.assert_allclose(_end(_one_bone("0 0 0 XYZ", "rx rz"), "90 90"), [0, 2, 0], atol=1e-12)


def test_axis_order_matters():
    # Axis angles 90 about x and 90 about z; with dof ry = 90 the bone (along x) turns about C y.
    # XYZ: C = Rz(90) Rx(90), C y = Rz(90) z = z: a turn about z takes x to +y.
    np.testing.assert_allclose(_end(_one_bone("90 0 90 XYZ", "ry"), "90"), [0, 2, 0], atol=1e-12)
    # C y for ZYX = Rx(90) Rz(90) y = Rx(90)(-x) = -x: rotation about -x leaves the bone along x.
    np.testing.assert_allclose(_end(_one_bone("90 0 90 ZYX", "ry"), "90"), [2, 0, 0], atol=1e-12)


def test_radians_and_translation_dofs():
    np.testing.assert_allclose(
        _end(_one_bone("0 0 0 XYZ", "rz"), repr(np.pi / 2), angle=":RADIANS"), [0, 2, 0], atol=1e-12
    )
    # l lengthens the bone; tx moves its end along C x.
    np.testing.assert_allclose(_end(_one_bone("0 0 0 XYZ", "l"), "1.5"), [3.5, 0, 0], atol=1e-12)
    np.testing.assert_allclose(_end(_one_bone("0 0 90 XYZ", "tx"), "0.5"), [2, 0.5, 0], atol=1e-12)


def test_length_units():
    # CMU: length 0.45 and inches; a bone of 2 units is 2 / 0.45 in.
    skel = parse_asf(_one_bone("0 0 0 XYZ", "rx", units="length 0.45"))
    assert skel.metres_per_unit == pytest.approx(0.0254 / 0.45)
    m = parse_amc("1\nroot 0 0 0 0 0 0\nb 0\n", skel)
    np.testing.assert_allclose(m.global_positions()[0, 1], [2 * IN, 0, 0], atol=1e-15)
    cm = parse_asf(_one_bone("0 0 0 XYZ", "rx"), length_unit="cm")
    np.testing.assert_allclose(
        parse_amc("1\nroot 0 0 0 0 0 0\nb 0\n", cm).global_positions()[0, 1], [0.02, 0, 0]
    )
    with pytest.raises(UserError, match="parsec"):
        parse_asf(_one_bone("0 0 0 XYZ", "rx"), length_unit="parsec")


def test_tiny_skeleton_file():
    s = read_asf(DATA / "tiny.asf")
    assert s.name == "tiny" and s.length_scale == 0.45 and s.angle_unit == "deg"
    assert len(s.bones) == 14
    assert s.joint_names[0] == "root" and s.joint_names[1] == "lhipjoint"
    assert s.parents["lhumerus"] == "lclavicle" and s.parents["lowerback"] == "root"
    b = s.bone("lfemur")
    assert b.dof == ("rx", "ry", "rz")
    assert b.limits == ((-160.0, 20.0), (-70.0, 70.0), (-60.0, 70.0))
    np.testing.assert_array_equal(s.bone("lhumerus").axis, [0, 0, 90])
    assert s.root_order == ("TX", "TY", "TZ", "RX", "RY", "RZ")
    assert "CMU bone names" in " ".join(s.documentation)
    with pytest.raises(KeyError, match="nosuchbone"):
        s.bone("nosuchbone")


def test_tiny_motion_forward_kinematics_hand_computed():
    s = read_asf(DATA / "tiny.asf")
    m = read_amc(DATA / "tiny.amc", s)
    assert m.num_frames == 4 and m.fully_specified and m.angle_unit == "deg"
    np.testing.assert_array_equal(m.frame_numbers, [1, 2, 3, 4])
    assert m.frame_time == pytest.approx(1 / 120)
    start = m.bone_start_positions()
    end = m.global_positions()
    names = m.joint_names
    sh, el, wr = (start[:, names.index(n)] for n in ("lhumerus", "lradius", "lwrist"))
    root_y = 17 * IN
    shoulder = np.array([(2.7) * IN, root_y + (4.5 + 9.0) * IN, 0.0])
    # Frame 1 (T-pose): the left arm straight along +x.
    np.testing.assert_allclose(sh[0], shoulder, atol=1e-12)
    np.testing.assert_allclose(el[0], shoulder + [5.1 * IN, 0, 0], atol=1e-12)
    np.testing.assert_allclose(wr[0], shoulder + [(5.1 + 4.95) * IN, 0, 0], atol=1e-12)
    # Frame 2: humerus rx = -90 with axis (0 0 90) is a -90 rotation about y: the arm points +z.
    np.testing.assert_allclose(el[1] - sh[1], [0, 0, 5.1 * IN], atol=1e-12)
    np.testing.assert_allclose(wr[1] - el[1], [0, 0, 4.95 * IN], atol=1e-12)
    # Frame 3: radius rz = 90 lifts the forearm to +y.
    np.testing.assert_allclose(wr[2] - el[2], [0, 4.95 * IN, 0], atol=1e-12)
    # Right side mirrors it.
    rsh, rel, rwr = (start[:, names.index(n)] for n in ("rhumerus", "rradius", "rwrist"))
    np.testing.assert_allclose(rel[1] - rsh[1], [0, 0, 5.1 * IN], atol=1e-12)
    np.testing.assert_allclose(rwr[2] - rel[2], [0, 4.95 * IN, 0], atol=1e-12)
    # Frame 4: the root turned 90 deg about y and moved by (10, 17, -5).
    np.testing.assert_allclose(start[3, 0], [10 * IN, root_y, -5 * IN], atol=1e-12)
    np.testing.assert_allclose(el[3] - sh[3], [0, 0, -5.1 * IN], atol=1e-12)
    # A bone's end is its child's start.
    np.testing.assert_allclose(end[:, names.index("lhumerus")], el, atol=1e-15)


def test_round_trip_files(tmp_path):
    s = read_asf(DATA / "tiny.asf")
    m = read_amc(DATA / "tiny.amc", s)
    write_asf(tmp_path / "t.asf", s)
    write_amc(tmp_path / "t.amc", m, asf_name="t.asf")
    s2 = read_asf(tmp_path / "t.asf")
    m2 = read_amc(tmp_path / "t.amc", tmp_path / "t.asf")
    assert s2.joint_names == s.joint_names and s2.parents == s.parents
    assert s2.children_order == s.children_order
    assert s2.documentation == s.documentation
    for a, b in zip(s2.bones, s.bones, strict=True):
        assert (a.id, a.name, a.length, a.axis_order, a.dof, a.limits) == (
            b.id,
            b.name,
            b.length,
            b.axis_order,
            b.dof,
            b.limits,
        )
        np.testing.assert_array_equal(a.direction, b.direction)
        np.testing.assert_array_equal(a.axis, b.axis)
    assert (s2.length_scale, s2.mass_scale, s2.angle_unit, s2.root_order, s2.root_axis) == (
        s.length_scale,
        s.mass_scale,
        s.angle_unit,
        s.root_order,
        s.root_axis,
    )
    np.testing.assert_array_equal(m2.frame_numbers, m.frame_numbers)
    assert m2.bone_order == m.bone_order and set(m2.values) == set(m.values)
    for k in m.values:
        np.testing.assert_array_equal(m2.values[k], m.values[k])
    np.testing.assert_array_equal(m2.global_positions(), m.global_positions())
    # Writing again gives the same text.
    assert format_asf(s2) == format_asf(s) and format_amc(m2) == format_amc(m)


@settings(max_examples=20, deadline=None)
@given(
    root=arrays(np.float64, (3, 6), elements=st.floats(-1e3, 1e3, allow_nan=False, width=64)),
    humerus=arrays(np.float64, (3, 3), elements=st.floats(-360, 360, allow_nan=False, width=64)),
)
def test_amc_round_trip_is_exact_and_fk_keeps_bone_lengths(root, humerus):
    s = read_asf(DATA / "tiny.asf")
    m = read_amc(DATA / "tiny.amc", s)
    values = {k: np.repeat(v[:1], 3, axis=0) for k, v in m.values.items()}
    values["root"] = root
    values["lhumerus"] = humerus
    m3 = AMCMotion(skeleton=s, frame_numbers=[1, 2, 3], values=values)
    r = parse_amc(format_amc(m3), s)
    for k in values:
        np.testing.assert_array_equal(r.values[k], values[k])
    start, end = r.global_transforms()[1:]
    i = s.joint_names.index("lhumerus")
    np.testing.assert_allclose(np.linalg.norm(end[:, i] - start[:, i], axis=1), 5.1 * IN, atol=1e-12)


def test_limits_with_infinity_and_commas():
    text = _one_bone("0 0 0 XYZ", "rx ry").replace(
        "dof rx ry", "dof rx ry\n    limits (-inf, inf)\n  (-10, 10)"
    )
    s = parse_asf(text)
    assert s.bone("b").limits == ((-np.inf, np.inf), (-10.0, 10.0))
    assert parse_asf(format_asf(s)).bone("b").limits == s.bone("b").limits


# ------------------------------------------------------------------------------------------------ errors


def _amc_error(tmp_path, text: str, name: str = "bad.amc") -> tuple[Path, str]:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(UserError) as e:
        read_amc(p, read_asf(DATA / "tiny.asf"))
    return p, str(e.value)


def _asf_error(tmp_path, text: str, name: str = "bad.asf") -> tuple[Path, str]:
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(UserError) as e:
        read_asf(p)
    return p, str(e.value)


AMC_TEXT = (DATA / "tiny.amc").read_text()
ASF_TEXT = (DATA / "tiny.asf").read_text()


def _line_of(text: str, needle: str, occurrence: int = 1) -> int:
    seen = 0
    for k, line in enumerate(text.splitlines(), start=1):
        if line.strip() == needle:
            seen += 1
            if seen == occurrence:
                return k
    raise AssertionError(needle)


def test_amc_truncated_last_frame(tmp_path):
    lines = AMC_TEXT.splitlines()
    text = "\n".join(lines[:-5]) + "\n"  # frame 4 loses its last five bones
    p, msg = _amc_error(tmp_path, text)
    assert msg.startswith(f"{p}:{_line_of(AMC_TEXT, '4')}:")
    assert "frame 4 lacks" in msg and "rwrist" in msg


def test_amc_wrong_value_count(tmp_path):
    text = AMC_TEXT.replace("lradius 90", "lradius 90 0")
    p, msg = _amc_error(tmp_path, text)
    assert msg.startswith(f"{p}:{_line_of(text, 'lradius 90 0')}:")
    assert "'lradius' has 2 value(s)" in msg and "needs 1" in msg


def test_amc_garbage_number(tmp_path):
    text = AMC_TEXT.replace("rradius -90", "rradius -9o")
    p, msg = _amc_error(tmp_path, text)
    assert msg.startswith(f"{p}:{_line_of(text, 'rradius -9o')}:") and "'-9o'" in msg


def test_amc_other_errors(tmp_path):
    p, msg = _amc_error(tmp_path, "", "e.amc")
    assert msg.startswith(f"{p}:1:") and "empty" in msg
    p, msg = _amc_error(tmp_path, "# nothing but a comment\n:DEGREES\n", "nf.amc")
    assert msg.startswith(f"{p}:2:") and "no frames" in msg
    text = AMC_TEXT.replace("lwrist 0\n", "lwristt 0\n", 1)
    p, msg = _amc_error(tmp_path, text, "ub.amc")
    assert msg.startswith(f"{p}:{_line_of(text, 'lwristt 0')}:") and "unknown bone 'lwristt'" in msg
    text = AMC_TEXT.replace(":DEGREES", ":DEGREEZ")
    p, msg = _amc_error(tmp_path, text, "kw.amc")
    assert msg.startswith(f"{p}:{_line_of(text, ':DEGREEZ')}:") and "unknown keyword" in msg
    text = AMC_TEXT.replace("lowerback 0 0 0\nthorax", "lowerback 0 0 0\nlowerback 0 0 0\nthorax", 1)
    p, msg = _amc_error(tmp_path, text, "twice.amc")
    assert "appears twice" in msg
    text = AMC_TEXT.replace(":DEGREES\n1\n", ":DEGREES\n")
    p, msg = _amc_error(tmp_path, text, "noframe.amc")
    assert msg.startswith(f"{p}:{_line_of(text, 'root 0 17 0 0 0 0')}:") and "frame number" in msg


def test_asf_errors(tmp_path):
    cases = {
        "kw.asf": (ASF_TEXT.replace(":hierarchy", ":hierarchie"), ":hierarchie", "unknown keyword"),
        "num.asf": (ASF_TEXT.replace("length 5.1", "length 5.l"), "length 5.l", "'5.l'"),
        "bonekw.asf": (
            ASF_TEXT.replace("length 4.95", "lenght 4.95"),
            "lenght 4.95",
            "unknown keyword 'lenght'",
        ),
        "dof.asf": (ASF_TEXT.replace("dof rz\n", "dof rw\n", 1), "dof rw", "unknown dof 'rw'"),
        "axis.asf": (ASF_TEXT.replace("axis 0 0 90  XYZ", "axis 0 0 90"), "axis 0 0 90", "axis needs"),
        "parent.asf": (
            ASF_TEXT.replace("lhumerus lradius", "lhumerus lradius lradius"),
            "lhumerus lradius lradius",
            "already has parent",
        ),
        "unk.asf": (
            ASF_TEXT.replace("lradius lwrist", "lradius lwrist lhand"),
            "lradius lwrist lhand",
            "unknown bone 'lhand'",
        ),
    }
    for name, (text, line_text, needle) in cases.items():
        p, msg = _asf_error(tmp_path, text, name)
        assert msg.startswith(f"{p}:{_line_of(text, line_text)}:"), (name, msg)
        assert needle in msg, (name, msg)
    # A bone left out of the hierarchy is reported at the end of the file.
    text = ASF_TEXT.replace("    rradius rwrist\n", "")
    p, msg = _asf_error(tmp_path, text, "orphan.asf")
    assert msg.startswith(f"{p}:{len(text.splitlines())}:") and "'rwrist' does not appear" in msg
    # A bone block cut short.
    text = ASF_TEXT.split(":hierarchy")[0].rsplit("  end", 1)[0]
    p, msg = _asf_error(tmp_path, text, "cut.asf")
    assert "file ends inside the bone block" in msg
    p, msg = _asf_error(tmp_path, "\n# nothing\n", "empty.asf")
    assert msg.startswith(f"{p}:1:") and "empty file" in msg
    p, msg = _asf_error(
        tmp_path, ASF_TEXT.replace("    limits (-10.0 170.0)\n", "    limits (-10.0)\n"), "lim.asf"
    )
    assert "pairs" in msg


def test_load_errors(tmp_path):
    with pytest.raises(UserError, match="no such ASF file"):
        read_asf(tmp_path / "none.asf")
    with pytest.raises(UserError, match="no such AMC file"):
        read_amc(tmp_path / "none.amc", DATA / "tiny.asf")
    with pytest.raises(UserError, match="frame_rate"):
        parse_amc(AMC_TEXT, read_asf(DATA / "tiny.asf"), frame_rate=0)


def test_optional_sections_round_trip():
    text = ASF_TEXT.replace(":name tiny\n", ":name tiny\n:namespace tiny_ns\n").replace(
        ":hierarchy", ":skin\n  body.obj\n  hands.obj\n:hierarchy"
    )
    s = parse_asf(text)
    assert s.namespace == "tiny_ns" and s.skin == ("body.obj", "hands.obj")
    s2 = parse_asf(format_asf(s))
    assert (s2.namespace, s2.skin, s2.documentation) == (s.namespace, s.skin, s.documentation)
    inline = parse_asf(ASF_TEXT.replace(":documentation\n", ":documentation one line of notes\n"))
    assert inline.documentation[0].strip() == "one line of notes" and len(inline.documentation) == 3
