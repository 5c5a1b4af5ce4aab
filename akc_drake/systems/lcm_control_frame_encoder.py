"""ControlFrameEncoder: the mapper's wrist targets as Drake's ``lcmt_viewer_draw`` and its tracking status as
``lcmt_drake_signal``.

``lcmt_viewer_draw`` is Drake's list of named poses (``link_name``, ``position`` xyz in metres, ``quaternion``
wxyz); it is what Drake's own tools (``drake-visualizer``, ``meldis``) read. Here each entry is a control frame
in the robot's torso frame: ``left_wrist_target`` / ``right_wrist_target`` (``X_TE_desired_*`` of the
FrameMapper, eq. 17 mapped to the robot). ``lcmt_drake_signal`` (Drake's named vector) carries
``left_tracking_lost`` and ``right_tracking_lost`` (0 or 1), so a driver can hold the arm whose operator wrist is
not tracked (the mapper already holds its target).
"""

from __future__ import annotations

import numpy as np
from drake import lcmt_drake_signal, lcmt_viewer_draw
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

SIDES = ("left", "right")


class ControlFrameEncoder(LeafSystem):
    """Encodes ``X_TE_desired_left/right`` into one ``lcmt_viewer_draw``, ``tracking_lost`` into an
    ``lcmt_drake_signal``.

    .. pydrake_system::

        name: ControlFrameEncoder
        input_ports:
        - X_TE_desired_left
        - X_TE_desired_right
        - tracking_lost
        output_ports:
        - lcmt_viewer_draw
        - lcmt_drake_signal
    """

    def __init__(self):
        super().__init__()
        self._X = {
            s: self.DeclareAbstractInputPort(f"X_TE_desired_{s}", AbstractValue.Make(RigidTransform())) for s in SIDES
        }
        self._lost = self.DeclareVectorInputPort("tracking_lost", 2)
        self.DeclareAbstractOutputPort("lcmt_viewer_draw", lambda: AbstractValue.Make(lcmt_viewer_draw()),
                                       self._calc_frames, {self.all_input_ports_ticket()})
        self.DeclareAbstractOutputPort("lcmt_drake_signal", lambda: AbstractValue.Make(lcmt_drake_signal()),
                                       self._calc_status, {self._lost.ticket(), self.time_ticket()})

    def _calc_frames(self, context, output) -> None:
        msg = lcmt_viewer_draw()
        msg.timestamp = int(round(context.get_time() * 1e3))  # lcmt_viewer_draw's timestamp is in milliseconds
        msg.num_links = len(SIDES)
        msg.link_name = [f"{s}_wrist_target" for s in SIDES]
        msg.robot_num = [0] * len(SIDES)
        msg.position, msg.quaternion = [], []
        for s in SIDES:
            X = self._X[s].Eval(context)
            q = X.rotation().ToQuaternion()
            msg.position.append([float(v) for v in X.translation()])
            msg.quaternion.append([float(q.w()), float(q.x()), float(q.y()), float(q.z())])
        output.set_value(msg)

    def _calc_status(self, context, output) -> None:
        lost = np.asarray(self._lost.Eval(context), dtype=float)
        msg = lcmt_drake_signal()
        msg.timestamp = int(round(context.get_time() * 1e6))  # microseconds, as lcmt_robot_state's utime
        msg.dim = len(SIDES)
        msg.coord = [f"{s}_tracking_lost" for s in SIDES]
        msg.val = [float(v > 0.5) for v in lost]
        output.set_value(msg)
