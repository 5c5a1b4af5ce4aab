"""``AddLcmPublishers``: the teleop diagram's robot commands and control frames on LCM, with Drake's own systems.

Channels (the defaults; a prefix can be given):

====================== ===================== =========== ===================================================
channel                type                  rate        content
====================== ===================== =========== ===================================================
``AKC_ROBOT_COMMAND``  ``lcmt_robot_state``  IK rate     commanded arm joint positions (14, by joint name)
``AKC_ROBOT_STATE``    ``lcmt_robot_state``  IK rate     measured arm joint positions of the simulated robot
``AKC_CONTROL_FRAMES`` ``lcmt_viewer_draw``  camera rate wrist targets in the robot torso frame
``AKC_TRACKING``       ``lcmt_drake_signal`` camera rate ``left_tracking_lost``, ``right_tracking_lost`` (0/1)
====================== ===================== =========== ===================================================

The types are Drake's (``from drake import lcmt_drake_signal, lcmt_robot_state, lcmt_viewer_draw``), so a driver
needs only the ``drake`` (or ``lcm``) Python package. Publishing uses
:class:`pydrake.systems.lcm.LcmPublisherSystem` on a :class:`pydrake.lcm.DrakeLcm` (``memq://`` in process,
``udpm://239.255.76.67:7667?ttl=0`` on this host only).
"""

from __future__ import annotations

from dataclasses import dataclass

from drake import lcmt_drake_signal, lcmt_robot_state, lcmt_viewer_draw
from pydrake.systems.lcm import LcmPublisherSystem

from akc_drake.robot.model import arm_joint_names
from akc_drake.systems.lcm_control_frame_encoder import ControlFrameEncoder
from akc_drake.systems.lcm_joint_command_encoder import JointCommandEncoder

SIDES = ("left", "right")
COMMAND, STATE, FRAMES, TRACKING = "AKC_ROBOT_COMMAND", "AKC_ROBOT_STATE", "AKC_CONTROL_FRAMES", "AKC_TRACKING"


@dataclass
class LcmPublishers:
    """What :func:`AddLcmPublishers` added: channel name -> publisher, and the encoders."""

    channels: dict
    command_encoder: JointCommandEncoder
    state_encoder: JointCommandEncoder | None
    frame_encoder: ControlFrameEncoder | None


def open_lcm(url: str = "memq://"):
    """A ``DrakeLcm`` on ``url``; a ``udpm://`` URL without ``ttl`` gets ``ttl=0`` (multicast that never leaves
    this host). Give ``ttl=1`` explicitly to reach a robot on the local network. ``file://LOG?mode=w`` writes an
    LCM log (replay it with ``lcm-logplayer``)."""
    from pydrake.lcm import DrakeLcm

    url = str(url).strip()
    scheme = url.split("://", 1)[0] if "://" in url else ""
    if scheme not in ("memq", "udpm", "file"):
        raise ValueError(f"--lcm {url}: expected memq://, udpm://GROUP:PORT[?ttl=N] or file://LOG?mode=w")
    if scheme == "udpm" and "ttl=" not in url:
        url += ("&" if "?" in url else "?") + "ttl=0"
    try:
        return DrakeLcm(url)
    except RuntimeError as e:
        raise ValueError(f"--lcm {url}: {e}") from None


def AddLcmPublishers(builder, lcm, *, q_commanded: dict, q_measured: dict | None = None,
                     X_TE_desired: dict | None = None, tracking_lost=None, command_period_s: float = 0.01,
                     frame_period_s: float = 0.1, frame_offset_s: float = 0.0, prefix: str = "") -> LcmPublishers:
    """Add the encoders and ``LcmPublisherSystem``\\ s to ``builder`` and wire them.

    Args:
        builder: the teleop diagram's DiagramBuilder.
        lcm: a ``pydrake.lcm.DrakeLcm`` (its URL decides the transport).
        q_commanded: ``{side: OutputPort}`` commanded arm joint positions (7 each).
        q_measured: ``{side: OutputPort}`` measured arm joint positions, or None.
        X_TE_desired: ``{side: OutputPort}`` the FrameMapper's wrist targets (RigidTransform), or None.
        tracking_lost: the FrameMapper's ``tracking_lost`` output (2,), required with ``X_TE_desired``.
        command_period_s: the command and state publishing period (the IK's).
        frame_period_s: the control-frame publishing period (the camera's).
        frame_offset_s: the control frames' publishing offset (the mapper's stage offset: Drake runs the
            mapper's update before a publish at the same instant, so each message carries that frame's targets).
        prefix: prepended to every channel name.

    Returns:
        :class:`LcmPublishers`.
    """
    channels = {}

    def publisher(channel, lcm_type, period, port, offset=0.0):
        pub = builder.AddSystem(LcmPublisherSystem.Make(channel=prefix + channel, lcm_type=lcm_type, lcm=lcm,
                                                        publish_period=period, publish_offset=offset))
        pub.set_name(f"LcmPublisher_{prefix + channel}")
        builder.Connect(port, pub.get_input_port())
        channels[prefix + channel] = pub

    groups = {f"q_{s}": [f"{n}" for n in arm_joint_names(s)] for s in SIDES}

    def encoder(name, ports):
        enc = builder.AddSystem(JointCommandEncoder(groups))
        enc.set_name(name)
        for s in SIDES:
            builder.Connect(ports[s], enc.GetInputPort(f"q_{s}"))
        return enc

    cmd = encoder("JointCommandEncoder", q_commanded)
    publisher(COMMAND, lcmt_robot_state, command_period_s, cmd.get_output_port())
    state = None
    if q_measured is not None:
        state = encoder("JointStateEncoder", q_measured)
        publisher(STATE, lcmt_robot_state, command_period_s, state.get_output_port())
    frames = None
    if X_TE_desired is not None:
        if tracking_lost is None:
            raise ValueError("AddLcmPublishers: X_TE_desired needs the tracking_lost port too")
        frames = builder.AddSystem(ControlFrameEncoder())
        frames.set_name("ControlFrameEncoder")
        for s in SIDES:
            builder.Connect(X_TE_desired[s], frames.GetInputPort(f"X_TE_desired_{s}"))
        builder.Connect(tracking_lost, frames.GetInputPort("tracking_lost"))
        publisher(FRAMES, lcmt_viewer_draw, frame_period_s, frames.GetOutputPort("lcmt_viewer_draw"), frame_offset_s)
        publisher(TRACKING, lcmt_drake_signal, frame_period_s, frames.GetOutputPort("lcmt_drake_signal"),
                  frame_offset_s)
    return LcmPublishers(channels, cmd, state, frames)
