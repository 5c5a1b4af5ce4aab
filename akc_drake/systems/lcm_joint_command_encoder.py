"""JointCommandEncoder: the robot's joint vectors as Drake's ``lcmt_robot_state`` LCM message.

A robot driver subscribes to the channel (see README, "Using the output") and reads ``joint_name`` /
``joint_position`` by name, so the message does not depend on the order of our ports. ``utime`` is the
diagram's time in microseconds. A non-finite value raises ``ValueError`` naming the port, as the robot station's
command assembler does: the pipeline never commands NaN, and a message must not carry one to a real robot.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from drake import lcmt_robot_state
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem


class JointCommandEncoder(LeafSystem):
    """Concatenates vector input ports into one ``lcmt_robot_state`` message.

    .. pydrake_system::

        name: JointCommandEncoder
        input_ports:
        - <group 0> (e.g. q_commanded_left)
        - <group 1> (e.g. q_commanded_right)
        output_ports:
        - lcmt_robot_state

    Args:
        groups: ``{port name: joint names}``; one vector input port per entry, sized by its joint names.
    """

    def __init__(self, groups: dict[str, Sequence[str]]):
        super().__init__()
        if not groups:
            raise ValueError("JointCommandEncoder needs at least one group of joints")
        self._names: list[str] = []
        self._ports = []
        for port, names in groups.items():
            names = [str(n) for n in names]
            if not names:
                raise ValueError(f"JointCommandEncoder: group {port!r} has no joints")
            self._ports.append(self.DeclareVectorInputPort(port, len(names)))
            self._names += names
        if len(set(self._names)) != len(self._names):
            raise ValueError("JointCommandEncoder: repeated joint names")
        self.DeclareAbstractOutputPort(
            "lcmt_robot_state", lambda: AbstractValue.Make(lcmt_robot_state()), self._calc
        )

    @property
    def joint_names(self) -> list[str]:
        return list(self._names)

    def _calc(self, context, output) -> None:
        parts = [np.asarray(p.Eval(context), dtype=float) for p in self._ports]
        for port, q in zip(self._ports, parts, strict=True):
            if not np.all(np.isfinite(q)):
                raise ValueError(f"JointCommandEncoder: input '{port.get_name()}' is not finite: {q}")
        q = np.concatenate(parts)
        msg = lcmt_robot_state()
        msg.utime = int(round(context.get_time() * 1e6))
        msg.num_joints = len(self._names)
        msg.joint_name = list(self._names)
        msg.joint_position = [float(v) for v in q]
        output.set_value(msg)
