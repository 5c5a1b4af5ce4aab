"""AddLcmPublishers: Drake's LcmPublisherSystem on memq:// (in process) and udpm with ttl=0 (two processes)."""

import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from drake import lcmt_drake_signal, lcmt_robot_state, lcmt_viewer_draw
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource

from akc_drake.robot.model import arm_joint_names
from akc_drake.systems.lcm_publishers import COMMAND, FRAMES, STATE, TRACKING, AddLcmPublishers, open_lcm


def _diagram(lcm, prefix=""):
    b = DiagramBuilder()
    q = {s: b.AddSystem(ConstantVectorSource(np.arange(7) * (0.1 if s == "left" else -0.1))).get_output_port()
         for s in ("left", "right")}
    qm = {s: b.AddSystem(ConstantVectorSource(np.full(7, 0.5))).get_output_port() for s in ("left", "right")}
    X = {s: b.AddSystem(ConstantValueSource(AbstractValue.Make(RigidTransform([0.3, 0.2 if s == "left" else -0.2,
                                                                              0.0])))).get_output_port()
         for s in ("left", "right")}
    lost = b.AddSystem(ConstantVectorSource([0.0, 0.0])).get_output_port()
    pubs = AddLcmPublishers(b, lcm, q_commanded=q, q_measured=qm, X_TE_desired=X, tracking_lost=lost,
                            command_period_s=0.01, frame_period_s=0.1, prefix=prefix)
    return b.Build(), pubs


def test_in_process_memq():
    lcm = open_lcm("memq://")
    got = {COMMAND: [], STATE: [], FRAMES: [], TRACKING: []}
    lcm.Subscribe(COMMAND, lambda m: got[COMMAND].append(lcmt_robot_state.decode(m)))
    lcm.Subscribe(STATE, lambda m: got[STATE].append(lcmt_robot_state.decode(m)))
    lcm.Subscribe(FRAMES, lambda m: got[FRAMES].append(lcmt_viewer_draw.decode(m)))
    lcm.Subscribe(TRACKING, lambda m: got[TRACKING].append(lcmt_drake_signal.decode(m)))
    diagram, pubs = _diagram(lcm)
    assert set(pubs.channels) == {COMMAND, STATE, FRAMES, TRACKING}
    Simulator(diagram).AdvanceTo(0.295)
    while lcm.HandleSubscriptions(0) > 0:
        pass
    assert len(got[COMMAND]) == len(got[STATE]) == 30  # t = 0, 0.01, ..., 0.29
    assert len(got[FRAMES]) == len(got[TRACKING]) == 3  # t = 0, 0.1, 0.2
    assert list(got[TRACKING][2].val) == [0.0, 0.0] and got[TRACKING][2].timestamp == 200000
    cmd = got[COMMAND][-1]
    assert cmd.utime == 290000
    assert list(cmd.joint_name) == arm_joint_names("left") + arm_joint_names("right")
    np.testing.assert_allclose(cmd.joint_position, np.r_[np.arange(7) * 0.1, -np.arange(7) * 0.1], rtol=1e-6)
    np.testing.assert_allclose(got[STATE][0].joint_position, 0.5)
    fr = got[FRAMES][1]
    assert fr.timestamp == 100 and list(fr.link_name) == ["left_wrist_target", "right_wrist_target"]
    np.testing.assert_allclose(fr.position, [[0.3, 0.2, 0.0], [0.3, -0.2, 0.0]], atol=1e-7)


def test_udpm_url_gets_ttl_zero():
    assert open_lcm("udpm://239.255.76.67:7671").get_lcm_url().endswith("?ttl=0")
    assert open_lcm("udpm://239.255.76.67:7671?ttl=0").get_lcm_url().count("ttl=") == 1
    with pytest.raises(ValueError, match="--lcm"):
        open_lcm("nonsense://x")


CHILD = textwrap.dedent(
    """
    import sys
    from drake import lcmt_robot_state
    from pydrake.lcm import DrakeLcm
    lcm = DrakeLcm(sys.argv[1])
    got = []
    lcm.Subscribe(sys.argv[2], lambda m: got.append(lcmt_robot_state.decode(m)))
    print("ready", flush=True)
    for _ in range(1200):  # up to 60 s: the parent may take seconds to build its diagram on a loaded machine
        lcm.HandleSubscriptions(50)
        if len(got) >= 5:
            break
    print(len(got), " ".join(f"{v:.6f}" for v in (got[-1].joint_position if got else [])), flush=True)
    """
)


def test_two_processes_over_multicast_that_stays_on_this_host():
    # ttl=0: the kernel never sends these multicast datagrams beyond this host (ip(7), IP_MULTICAST_TTL).
    url = "udpm://239.255.76.67:7681?ttl=0"
    channel = f"AKC_TEST_{os.getpid()}_"  # another test run on this host publishes on other channels
    try:
        lcm = open_lcm(url)
    except ValueError as e:
        pytest.skip(f"no multicast here: {e}")
    child = subprocess.Popen([sys.executable, "-c", CHILD, url, channel + COMMAND], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        diagram, _ = _diagram(lcm, prefix=channel)
        sim = Simulator(diagram)
        # Publish until the child has its five messages (it then exits), for at most 45 s: a burst of 1 s of
        # simulated time (about 100 datagrams in a few ms) once reached the child short of five under load, and
        # the parent stopped publishing while the child waited.
        deadline = time.monotonic() + 45.0
        k = 0
        while child.poll() is None and time.monotonic() < deadline:
            k += 1
            sim.AdvanceTo(0.01 * k)
            time.sleep(0.002)
        out, _ = child.communicate(timeout=90)
    finally:
        child.kill()
    n, *vals = out.split()
    if int(n) == 0:
        pytest.skip("multicast on this host delivered nothing (no multicast route)")
    assert int(n) >= 5
    np.testing.assert_allclose([float(v) for v in vals], np.r_[np.arange(7) * 0.1, -np.arange(7) * 0.1], atol=1e-6)
