"""Tests for akc_drake.operator.bvh: parsing, forward kinematics, units, writing, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from akc_drake.errors import UserError
from akc_drake.operator.bvh import (
    BVHJoint,
    BVHMotion,
    axis_rotation,
    format_bvh,
    parse_bvh,
    read_bvh,
    write_bvh,
)

DATA = Path(__file__).parent / "data" / "mocap"

# A two-link planar arm: base joint at the origin, elbow 10 cm along x, end 10 cm further.
ARM2 = """\
HIERARCHY
ROOT Base
{
  OFFSET 0 0 0
  CHANNELS 3 Zrotation Xrotation Yrotation
  JOINT Elbow
  {
    OFFSET 10 0 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 10 0 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.1
0 0 0 0 0 0
90 0 0 0 0 0
90 0 0 90 0 0
"""


def _one_joint(order: str, values: str) -> str:
    """A root with a rotation-only joint in channel order ``order`` and a 1 m End Site along x."""
    chans = " ".join(f"{a}rotation" for a in order)
    return (
        "HIERARCHY\nROOT R\n{\n OFFSET 0 0 0\n CHANNELS 3 "
        + chans
        + "\n End Site\n {\n  OFFSET 1 0 0\n }\n}\n"
        "MOTION\nFrames: 1\nFrame Time: 0.01\n" + values + "\n"
    )


def test_two_link_arm_forward_kinematics_hand_computed():
    m = parse_bvh(ARM2)
    assert m.joint_names == ("Base", "Elbow", "Elbow_end")
    assert m.joints[2].end_site and m.joints[2].parent == 1
    P = m.global_positions()
    assert P.shape == (3, 3, 3)
    # Frame 0: straight along x. Frame 1: the base turned 90 deg about z: the arm along +y.
    # Frame 2: the elbow turned another 90 deg: the forearm along -x from (0, 0.1, 0).
    np.testing.assert_allclose(P[0], [[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(P[1], [[0, 0, 0], [0, 0.1, 0], [0, 0.2, 0]], atol=1e-12)
    np.testing.assert_allclose(P[2], [[0, 0, 0], [0, 0.1, 0], [-0.1, 0.1, 0]], atol=1e-12)
    assert m.frame_time == pytest.approx(0.1)
    np.testing.assert_allclose(m.times(), [0.0, 0.1, 0.2])


def test_rotation_order_follows_channel_order():
    # Z then X (R = Rz Rx): x -> Rz(90)(Rx(90) x) = Rz(90) x = +y.
    zx = parse_bvh(_one_joint("ZXY", "90 90 0"), units="m").global_positions()[0, 1]
    # X then Z (R = Rx Rz): x -> Rx(90)(Rz(90) x) = Rx(90) y = +z.
    xz = parse_bvh(_one_joint("XZY", "90 90 0"), units="m").global_positions()[0, 1]
    np.testing.assert_allclose(zx, [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(xz, [0, 0, 1], atol=1e-12)


def test_zxy_and_xyz_with_three_angles_hand_checked():
    # ZXY, 90 each: Ry x = -z; Rx(-z) = +y; Rz(+y) = -x.
    zxy = parse_bvh(_one_joint("ZXY", "90 90 90"), units="m").global_positions()[0, 1]
    # XYZ, 90 each: Rz x = +y; Ry(+y) = +y; Rx(+y) = +z.
    xyz = parse_bvh(_one_joint("XYZ", "90 90 90"), units="m").global_positions()[0, 1]
    np.testing.assert_allclose(zxy, [-1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(xyz, [0, 0, 1], atol=1e-12)


def test_axis_rotation_is_right_handed_and_vectorised():
    np.testing.assert_allclose(axis_rotation("z", np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(axis_rotation("x", np.pi / 2) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(axis_rotation("y", np.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    R = axis_rotation("Y", np.array([0.0, 0.3, -2.0]))
    assert R.shape == (3, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-15)


def test_units_convert_to_metres():
    cm = parse_bvh(ARM2).global_positions()
    m = parse_bvh(ARM2, units="m").global_positions()
    inch = parse_bvh(ARM2, units="in").global_positions()
    mm = parse_bvh(ARM2, units="mm").global_positions()
    np.testing.assert_allclose(m, cm * 100.0, atol=1e-12)
    np.testing.assert_allclose(inch, cm * 2.54, atol=1e-12)
    np.testing.assert_allclose(mm, cm * 0.1, atol=1e-12)
    assert m[0, 2, 0] == pytest.approx(20.0)
    with pytest.raises(UserError, match="furlong"):
        parse_bvh(ARM2, units="furlong")


def test_position_channels_replace_the_offset():
    text = (
        "HIERARCHY\nROOT Hips\n{\n OFFSET 5 7 9\n CHANNELS 4 Xposition Zposition Yrotation Xrotation\n"
        " JOINT A\n {\n  OFFSET 0 0 10\n  CHANNELS 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.5\n"
        "1 2 0 0\n1 2 90 0\n"
    )
    P = parse_bvh(text).global_positions()
    # x and z come from the channels (1, 2), y keeps the offset (7); in metres.
    np.testing.assert_allclose(P[0, 0], [0.01, 0.07, 0.02], atol=1e-12)
    np.testing.assert_allclose(P[0, 1], [0.01, 0.07, 0.12], atol=1e-12)
    # Ry(90) turns the child's +z offset into +x.
    np.testing.assert_allclose(P[1, 1], [0.11, 0.07, 0.02], atol=1e-12)


def test_upper_body_file():
    m = read_bvh(DATA / "upper_body.bvh")
    assert m.name == "upper_body"
    assert m.num_frames == 5 and m.channels.shape == (5, 42)
    assert m.frame_time == pytest.approx(0.025) and m.frame_rate == pytest.approx(40.0)
    assert "LeftHand_end" in m.joint_names and "Neck_end" in m.joint_names
    assert m.joints[m.joint_index("LeftArm")].channels == ("Zrotation", "Xrotation", "Yrotation")
    P = m.global_positions()
    ls = P[:, m.joint_index("LeftArm")]
    le = P[:, m.joint_index("LeftForeArm")]
    lw = P[:, m.joint_index("LeftHand")]
    # T-pose: shoulder at (3 + 13.6, 90 + 10 + 38, 0) cm, arm along +x.
    np.testing.assert_allclose(ls[0], [0.166, 1.38, 0.0], atol=1e-12)
    np.testing.assert_allclose(le[0], [0.454, 1.38, 0.0], atol=1e-12)
    # Frame 1: LeftArm Yrotation -90 points the arm along +z (forward).
    np.testing.assert_allclose(le[1] - ls[1], [0, 0, 0.288], atol=1e-12)
    # Frame 2: forearm Zrotation 90 lifts the forearm to +y.
    np.testing.assert_allclose(lw[2] - le[2], [0, 0.28, 0], atol=1e-12)
    # Frame 3: the hips turned 90 deg about y: the left arm now points along -z.
    np.testing.assert_allclose(le[3] - ls[3], [0, 0, -0.288], atol=1e-12)
    # Frame 4: the whole body translated by the root position channels.
    np.testing.assert_allclose(ls[4] - ls[0], [0.5, 0.0, -0.2], atol=1e-12)
    np.testing.assert_allclose(m.joint_channels("LeftArm")[1], [0, 0, -90])
    assert m.channels[1, m.column("LeftArm", "Yrotation")] == -90
    with pytest.raises(KeyError, match="Xposition"):
        m.column("LeftArm", "Xposition")


def test_round_trip_file(tmp_path):
    m = read_bvh(DATA / "upper_body.bvh")
    out = tmp_path / "copy.bvh"
    write_bvh(out, m)
    r = read_bvh(out)
    assert r.joint_names == m.joint_names
    assert [j.channels for j in r.joints] == [j.channels for j in m.joints]
    assert [j.parent for j in r.joints] == [j.parent for j in m.joints]
    assert [j.end_site for j in r.joints] == [j.end_site for j in m.joints]
    for a, b in zip(r.joints, m.joints, strict=True):
        np.testing.assert_array_equal(a.offset, b.offset)
    np.testing.assert_array_equal(r.channels, m.channels)
    assert r.frame_time == m.frame_time
    np.testing.assert_array_equal(r.global_positions(), m.global_positions())


@settings(max_examples=25, deadline=None)
@given(
    values=arrays(np.float64, (4, 6), elements=st.floats(-720, 720, allow_nan=False, width=64)),
    frame_time=st.floats(1e-4, 1.0),
)
def test_round_trip_is_exact_for_any_values(values, frame_time):
    m = parse_bvh(ARM2)
    m2 = BVHMotion(joints=m.joints, frame_time=frame_time, channels=values, units="cm")
    r = parse_bvh(format_bvh(m2))
    np.testing.assert_array_equal(r.channels, values)
    assert r.frame_time == m2.frame_time
    # With a fixed number of decimals the values round-trip to that precision.
    r6 = parse_bvh(format_bvh(m2, precision=6))
    np.testing.assert_allclose(r6.channels, values, atol=5e-7)


@settings(max_examples=25, deadline=None)
@given(values=arrays(np.float64, (3, 6), elements=st.floats(-360, 360, allow_nan=False, width=64)))
def test_forward_kinematics_preserves_segment_lengths(values):
    m = parse_bvh(ARM2)
    P = BVHMotion(joints=m.joints, frame_time=0.1, channels=values).global_positions()
    np.testing.assert_allclose(np.linalg.norm(P[:, 1] - P[:, 0], axis=1), 0.1, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(P[:, 2] - P[:, 1], axis=1), 0.1, atol=1e-12)


def test_comments_and_blank_lines_are_tolerated():
    commented = (
        "# exported by hand\n\nHIERARCHY   # the skeleton\nROOT Base\n{\n  OFFSET 0 0 0  # origin\n\n"
        "  CHANNELS 3 Zrotation Xrotation Yrotation\n  JOINT Elbow\n  {\n    OFFSET 10 0 0\n"
        "    CHANNELS 3 Zrotation Yrotation Xrotation\n    End Site\n    {\n      OFFSET 10 0 0\n    }\n"
        "  }\n}\nMOTION\n# motion follows\nFrames: 3\n\nFrame Time: 0.1\n0 0 0 0 0 0\n\n"
        "90 0 0 0 0 0   # a comment after a row\n# a comment line between rows\n90 0 0 90 0 0\n\n\n"
    )
    a, b = parse_bvh(commented), parse_bvh(ARM2)
    np.testing.assert_array_equal(a.channels, b.channels)
    np.testing.assert_array_equal(a.global_positions(), b.global_positions())


def test_braces_on_the_keyword_line_and_lower_case_channels():
    text = (
        "HIERARCHY\nROOT Base {\n OFFSET 0 0 0\n CHANNELS 3 zrotation xrotation yrotation\n"
        " JOINT Elbow { OFFSET 10 0 0\n CHANNELS 3 Zrotation Yrotation Xrotation\n"
        " End Site { OFFSET 10 0 0 } } }\nMOTION\nFrames: 3\nFrame Time: 0.1\n"
        "0 0 0 0 0 0\n90 0 0 0 0 0\n90 0 0 90 0 0\n"
    )
    np.testing.assert_allclose(parse_bvh(text).global_positions(), parse_bvh(ARM2).global_positions())


def _write(tmp_path, text: str, name: str = "bad.bvh") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _error(path: Path) -> str:
    with pytest.raises(UserError) as e:
        read_bvh(path)
    return str(e.value)


def test_truncated_frames_name_file_and_line(tmp_path):
    text = ARM2.rsplit("\n", 2)[0] + "\n"  # drop the last frame row
    p = _write(tmp_path, text)
    msg = _error(p)
    n_lines = len(text.splitlines())
    assert msg.startswith(f"{p}:{n_lines}:")
    assert "truncated" in msg and "Frames: 3" in msg and "2 frame row" in msg


def test_wrong_number_of_values_names_the_row(tmp_path):
    lines = ARM2.splitlines()
    lines[-2] = "90 0 0 0 0"  # frame 1 has 5 values instead of 6
    p = _write(tmp_path, "\n".join(lines) + "\n")
    msg = _error(p)
    assert msg.startswith(f"{p}:{len(lines) - 1}:")
    assert "5 values" in msg and "6 channels" in msg


def test_too_many_rows(tmp_path):
    p = _write(tmp_path, ARM2 + "0 0 0 0 0 0\n")
    msg = _error(p)
    assert msg.startswith(f"{p}:{len(ARM2.splitlines()) + 1}:") and "more frame rows" in msg


def test_missing_channels_names_the_joint(tmp_path):
    text = ARM2.replace("    CHANNELS 3 Zrotation Yrotation Xrotation\n", "")
    p = _write(tmp_path, text)
    msg = _error(p)
    # Reported on the JOINT Elbow line (line 6).
    assert msg.startswith(f"{p}:6:") and "'Elbow'" in msg and "no CHANNELS" in msg


def test_garbage_number_names_line_and_value(tmp_path):
    lines = ARM2.splitlines()
    lines[-1] = "90 0 0 9O 0 0"
    p = _write(tmp_path, "\n".join(lines) + "\n")
    msg = _error(p)
    assert msg.startswith(f"{p}:{len(lines)}:") and "'9O'" in msg and "not a number" in msg
    p2 = _write(
        tmp_path, ARM2.replace("OFFSET 10 0 0\n    CHANNELS", "OFFSET 10 abc 0\n    CHANNELS"), "b2.bvh"
    )
    msg2 = _error(p2)
    assert msg2.startswith(f"{p2}:8:") and "'abc'" in msg2
    p3 = _write(tmp_path, ARM2.replace("Frame Time: 0.1", "Frame Time: fast"), "b3.bvh")
    assert _error(p3).startswith(f"{p3}:18:")
    p4 = _write(tmp_path, ARM2.replace("90 0 0 90 0 0", "90 0 0 nan 0 0"), "b4.bvh")
    assert "not a finite number" in _error(p4)


def test_empty_file(tmp_path):
    for k, text in enumerate(("", "\n\n   \n", "# only a comment\n")):
        p = _write(tmp_path, text, f"empty{k}.bvh")
        msg = _error(p)
        assert msg.startswith(f"{p}:1:") and "empty file" in msg


def test_unknown_keywords_and_other_mistakes(tmp_path):
    cases = {
        "kw.bvh": (
            ARM2.replace("    OFFSET 10 0 0\n    CHANNELS", "    OFSET 10 0 0\n    CHANNELS"),
            8,
            "OFSET",
        ),
        "hier.bvh": (ARM2.replace("HIERARCHY", "SKELETON"), 1, "HIERARCHY"),
        "chan.bvh": (
            ARM2.replace("Zrotation Yrotation Xrotation", "Zrotation Yrotation Wrotation"),
            9,
            "Wrotation",
        ),
        "nmotion.bvh": (ARM2.split("MOTION")[0], 15, "MOTION"),
        "frames.bvh": (ARM2.replace("Frames: 3", "Frames: three"), 17, "three"),
        "count.bvh": (
            ARM2.replace("CHANNELS 3 Zrotation Xrotation", "CHANNELS 2 Zrotation Xrotation"),
            5,
            "Yrotation",
        ),
        "dup.bvh": (ARM2.replace("JOINT Elbow", "JOINT Base"), 16, "repeated joint name"),
        "time.bvh": (ARM2.replace("Frame Time: 0.1", "Frame Time: 0"), 18, "positive"),
        "brace.bvh": (ARM2.replace("  }\n}\nMOTION", "  }\nMOTION"), 15, "'}'"),
    }
    for name, (text, line, needle) in cases.items():
        p = _write(tmp_path, text, name)
        msg = _error(p)
        assert msg.startswith(f"{p}:{line}:"), (name, msg)
        assert needle in msg, (name, msg)


def test_unreadable_files(tmp_path):
    with pytest.raises(UserError, match="no such BVH file"):
        read_bvh(tmp_path / "missing.bvh")
    p = tmp_path / "binary.bvh"
    p.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(UserError, match="not a text file"):
        read_bvh(p)


def test_motion_validation():
    m = parse_bvh(ARM2)
    with pytest.raises(ValueError, match=r"shape \(F, 6\)"):
        BVHMotion(joints=m.joints, frame_time=0.1, channels=np.zeros((2, 5)))
    with pytest.raises(ValueError, match="frame_time"):
        BVHMotion(joints=m.joints, frame_time=-1.0, channels=np.zeros((2, 6)))
    with pytest.raises(ValueError, match="depth-first"):
        joints = [
            BVHJoint("A", -1, [0, 0, 0], ("Xrotation",)),
            BVHJoint("B", 0, [1, 0, 0], ("Xrotation",)),
            BVHJoint("C", 0, [1, 0, 0], ("Xrotation",)),
            BVHJoint("D", 1, [1, 0, 0], ("Xrotation",)),
        ]
        BVHMotion(joints=joints, frame_time=0.1, channels=np.zeros((1, 4)))
    with pytest.raises(ValueError, match="unknown channel"):
        BVHJoint("A", -1, [0, 0, 0], ("Xrot",))
    empty = BVHMotion(joints=m.joints, frame_time=0.1, channels=np.zeros((0, 6)))
    assert empty.global_positions().shape == (0, 3, 3)
    assert parse_bvh(format_bvh(empty)).num_frames == 0


def test_joint_names_with_spaces_round_trip():
    text = (
        ARM2.replace("ROOT Base", "ROOT Bip01 Pelvis")
        .replace("JOINT Elbow", "JOINT Bip01 L Forearm {")
        .replace("JOINT Bip01 L Forearm {\n  {", "JOINT Bip01 L Forearm {")
    )
    m = parse_bvh(text)
    assert m.joint_names == ("Bip01 Pelvis", "Bip01 L Forearm", "Bip01 L Forearm_end")
    r = parse_bvh(format_bvh(m))
    assert r.joint_names == m.joint_names
    np.testing.assert_array_equal(r.global_positions(), parse_bvh(ARM2).global_positions())
