"""ControlFrameEncoder: the mapper's wrist targets (and tracking status) as Drake's ``lcmt_viewer_draw`` message.

``lcmt_viewer_draw`` is Drake's list of named poses (``link_name``, ``position`` xyz in metres, ``quaternion``
wxyz); it is what Drake's own tools (``drake-visualizer``, ``meldis``) read. Here each entry is a control frame
in the robot's torso frame: ``left_wrist_target`` / ``right_wrist_target`` (``X_TE_desired_*`` of the
FrameMapper, eq. 17 mapped to the robot). ``robot_num`` carries the tracking status as a bit mask (bit 0: left
lost, bit 1: right lost), so a driver can hold the arm whose operator wrist is not tracked.
"""

from __future__ import annotations

import numpy as np
from drake import lcmt_viewer_draw
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

SIDES = ("left", "right")


class ControlFrameEncoder(LeafSystem):
    """Encodes ``X_TE_desired_left/right`` and ``tracking_lost`` into one ``lcmt_viewer_draw``.

    .. pydrake_system::

        name: ControlFrameEncoder
        input_ports:
        - X_TE_desired_left
        - X_TE_desired_right
        - tracking_lost
        output_ports:
        - lcmt_viewer_draw
    """

    def __init__(self):
        super().__init__()
        self._X = {
            s: self.DeclareAbstractInputPort(f"X_TE_desired_{s}", AbstractValue.Make(RigidTransform())) for s in SIDES
        }
        self._lost = self.DeclareVectorInputPort("tracking_lost", 2)
        self.DeclareAbstractOutputPort("lcmt_viewer_draw", lambda: AbstractValue.Make(lcmt_viewer_draw()), self._calc)

    def _calc(self, context, output) -> None:
        msg = lcmt_viewer_draw()
        msg.timestamp = int(round(context.get_time() * 1e3))  # lcmt_viewer_draw's timestamp is in milliseconds
        msg.num_links = len(SIDES)
        msg.link_name = [f"{s}_wrist_target" for s in SIDES]
        lost = np.asarray(self._lost.Eval(context), dtype=float)
        mask = sum(1 << i for i, v in enumerate(lost) if v > 0.5)
        msg.robot_num = [mask] * len(SIDES)
        msg.position, msg.quaternion = [], []
        for s in SIDES:
            X = self._X[s].Eval(context)
            q = X.rotation().ToQuaternion()
            msg.position.append([float(v) for v in X.translation()])
            msg.quaternion.append([float(q.w()), float(q.x()), float(q.y()), float(q.z())])
        output.set_value(msg)
