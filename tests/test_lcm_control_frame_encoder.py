"""ControlFrameEncoder: wrist targets and the lost mask into one lcmt_viewer_draw."""

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RollPitchYaw

from akc_drake.systems.lcm_control_frame_encoder import ControlFrameEncoder


def test_poses_quaternions_and_lost_mask():
    enc = ControlFrameEncoder()
    ctx = enc.CreateDefaultContext()
    ctx.SetTime(2.5)
    X_l = RigidTransform(RollPitchYaw(0.1, -0.2, 0.3), [0.4, 0.2, -0.1])
    X_r = RigidTransform(RollPitchYaw(-0.5, 0.0, 1.0), [0.3, -0.25, 0.05])
    enc.GetInputPort("X_TE_desired_left").FixValue(ctx, X_l)
    enc.GetInputPort("X_TE_desired_right").FixValue(ctx, X_r)
    enc.GetInputPort("tracking_lost").FixValue(ctx, [0.0, 1.0])
    msg = enc.GetOutputPort("lcmt_viewer_draw").Eval(ctx)
    assert msg.timestamp == 2500 and msg.num_links == 2
    assert list(msg.link_name) == ["left_wrist_target", "right_wrist_target"]
    for i, X in enumerate((X_l, X_r)):
        np.testing.assert_allclose(msg.position[i], X.translation(), atol=1e-12)
        w, x, y, z = msg.quaternion[i]
        R = RigidTransform(Quaternion(w, x, y, z), [0, 0, 0]).rotation().matrix()
        np.testing.assert_allclose(R, X.rotation().matrix(), atol=1e-12)
    back = type(msg).decode(msg.encode())
    np.testing.assert_allclose(back.position, msg.position, rtol=1e-6)
    status = enc.GetOutputPort("lcmt_drake_signal").Eval(ctx)
    assert status.timestamp == 2_500_000 and status.dim == 2
    assert list(status.coord) == ["left_tracking_lost", "right_tracking_lost"] and list(status.val) == [0.0, 1.0]
    enc.GetInputPort("tracking_lost").FixValue(ctx, [1.0, 0.0])
    assert list(enc.GetOutputPort("lcmt_drake_signal").Eval(ctx).val) == [1.0, 0.0]
    assert type(status).decode(status.encode()).coord == status.coord
