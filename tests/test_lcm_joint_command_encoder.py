"""JointCommandEncoder: joint vectors into one lcmt_robot_state, by name; NaN never sent."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder

from akc_drake.systems.lcm_joint_command_encoder import JointCommandEncoder


def test_message_by_name_and_time():
    enc = JointCommandEncoder({"q_left": ["a1", "a2"], "q_right": ["b1", "b2", "b3"]})
    ctx = enc.CreateDefaultContext()
    ctx.SetTime(1.234567)
    enc.GetInputPort("q_left").FixValue(ctx, [0.5, -0.25])
    enc.GetInputPort("q_right").FixValue(ctx, [1.0, 2.0, 3.0])
    msg = enc.get_output_port().Eval(ctx)
    assert msg.utime == 1234567 and msg.num_joints == 5
    assert list(msg.joint_name) == ["a1", "a2", "b1", "b2", "b3"] == enc.joint_names
    np.testing.assert_allclose(msg.joint_position, [0.5, -0.25, 1.0, 2.0, 3.0])
    # lcm round trip (joint_position is float32 on the wire)
    back = type(msg).decode(msg.encode())
    np.testing.assert_allclose(back.joint_position, msg.joint_position, rtol=1e-7)


def test_nan_raises_naming_the_port():
    enc = JointCommandEncoder({"q_left": ["a1"], "q_right": ["b1"]})
    ctx = enc.CreateDefaultContext()
    enc.GetInputPort("q_left").FixValue(ctx, [0.0])
    enc.GetInputPort("q_right").FixValue(ctx, [np.nan])
    with pytest.raises(ValueError, match="q_right"):
        enc.get_output_port().Eval(ctx)


def test_bad_groups():
    with pytest.raises(ValueError, match="at least one"):
        JointCommandEncoder({})
    with pytest.raises(ValueError, match="repeated"):
        JointCommandEncoder({"a": ["j"], "b": ["j"]})
    with pytest.raises(ValueError, match="no joints"):
        JointCommandEncoder({"a": []})
    DiagramBuilder().AddSystem(JointCommandEncoder({"a": ["j"]}))
