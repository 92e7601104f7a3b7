"""The drone side: the link client and the command line against the simulated board behind a
pseudo-terminal (SITL), as they would talk to the real board's USB serial port. The client
keeps the SITL's clock (simulated time), so a busy machine that slows the board slows the
client's timeouts alike; the command line, a process of its own, keeps the wall clock and is
given only what waits for heartbeats, not for a time."""
import math
import os
import re
import subprocess
import sys
import time
import tty

import numpy as np
import pytest

from oracles import FK_TOL_MM, arm_points
from uavarm.link import llcp
from uavarm.link import ArmLink, CommandRefused, LinkGarbled, LinkSilent, PortNotFound
from uavarm.model import config
from uavarm.sim.sitl import Sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)

SPEED = 2.0          # simulated seconds per real second
TARGET = (60.0, 20.0, -120.0)


@pytest.fixture
def sitl():
    s = Sitl(speed=SPEED).start()
    yield s
    s.stop()


def link(sitl):
    """A link client on the SITL's port, keeping its clock."""
    return ArmLink(sitl.device, clock=sitl.clock)


def wait_for(sitl, arm, cond, sim_seconds):
    """Heartbeats until cond(hb): that heartbeat, or None once the board's simulated clock
    has run sim_seconds (real time may run slower on a busy machine)."""
    end = sitl.board.time + sim_seconds
    while sitl.board.time < end:
        hb = arm.next_heartbeat()
        if cond(hb):
            return hb
    return None


def joints_deg(hb):
    return np.degrees([hb["q1"], hb["q2"], hb["q3"]])


def test_missing_port_is_a_clear_error():
    with pytest.raises(PortNotFound, match="/dev/no-such-arm"):
        ArmLink("/dev/no-such-arm")


def pty_pair():
    master, slave = os.openpty()
    tty.setraw(slave)
    return master, os.ttyname(slave), slave


def test_silent_and_garbled_links_are_told_apart():
    master, path, slave = pty_pair()
    try:
        with ArmLink(path, silence=0.3) as arm:
            with pytest.raises(LinkSilent, match="no heartbeat"):
                arm.next_heartbeat()
            os.write(master, b"hello, this is not LLCP " * 4 + b"b05ZZ")
            with pytest.raises(LinkGarbled, match="no valid heartbeat.*wrong baud or device"):
                arm.next_heartbeat()
    finally:
        os.close(master)
        os.close(slave)


def test_commands_through_the_pseudo_terminal(sitl):
    m = config.load()
    park = np.array(m.park_deg)
    with link(sitl) as arm:
        hb = arm.status()
        assert hb["enabled"] == 0 and hb["engaged"] == 0 and hb["fault_names"] == []

        with pytest.raises(CommandRefused, match="not enabled"):
            arm.engage()

        assert arm.enable()["enabled"] == 1
        hb = wait_for(sitl, arm, lambda hb: np.abs(joints_deg(hb) - park).max() < 1.0, 4.0)
        assert hb is not None, "the parked pose was not reached"

        with pytest.raises(CommandRefused, match="unreachable"):
            arm.set_position(500.0, 0.0, 0.0)
        with pytest.raises(ValueError, match="finite"):
            arm.set_position(math.nan, 0.0, 0.0)
        arm.set_position(*TARGET)
        assert arm.engage()["engaged"] == 1
        arm.keep_alive()                   # the link lives while the arm moves

        def at_target(hb):
            arm.keep_alive()
            ee = arm_points(m, [hb["q1"], hb["q2"], hb["q3"]])[2]
            return np.linalg.norm(ee - TARGET) <= FK_TOL_MM
        assert wait_for(sitl, arm, at_target, 3.0) is not None, "the set position was not reached"

        hb = arm.disable()
        assert hb["enabled"] == 0 and hb["engaged"] == 0
        assert not sitl.board.servo_power


def test_link_cut_parks_the_arm_and_is_reported(sitl):
    m = config.load()
    with link(sitl) as arm:
        arm.enable()
        arm.engage()
        # the drone stops sending: after link.silence_timeout the board parks and says why
        hb = wait_for(sitl, arm, lambda hb: not hb["engaged"], 3 * m.link_silence_timeout)
        assert hb is not None and "link_lost" in arm.status()["fault_names"]
        assert arm.status()["enabled"] == 1


def test_command_line_against_the_sitl(sitl):
    run = lambda *a: subprocess.run([sys.executable, "-m", "uavarm.cli", "link", sitl.device, *a],
                                    capture_output=True, text=True, timeout=30)
    out = run("status")
    assert out.returncode == 0 and "enabled 0" in out.stdout and "(reset: power_on)" in out.stdout
    out = run("enable")
    assert out.returncode == 0 and "enabled 1" in out.stdout
    out = run("goto", "500", "0", "0")
    assert out.returncode == 1 and "unreachable" in out.stderr


def test_sitl_speaks_llcp_only(sitl):
    """What comes out of the pseudo-terminal is exactly the LLCP frames the board sent."""
    fd = os.open(sitl.device, os.O_RDWR | os.O_NOCTTY)
    data = b""
    end = sitl.clock() + 1.2
    while sitl.clock() < end:
        data += os.read(fd, 4096)
    os.close(fd)
    frames = llcp.Decoder().feed(data, 0.0)
    assert len(frames) >= 2 and data.startswith(b"b") and len(data) == sum(llcp.frame_size(len(f)) for f in frames)


def test_attitude_feed_keeps_an_engaged_arm_engaged(sitl):
    m = config.load()
    with link(sitl) as arm:
        arm.enable()
        arm.engage()
        end, sent = sitl.clock() + 2 * m.link_silence_timeout, 0
        while sitl.clock() < end:
            arm.send_attitude(0.01, -0.02)
            sent += 1
            due = sitl.clock() + 0.02                 # 50 Hz of simulated time
            while sitl.clock() < due:
                time.sleep(0.001)                     # (a poll's interval: the SITL's clock paces)
        hb = arm.status()
        assert hb["engaged"] == 1 and "link_lost" not in hb["fault_names"]
        assert sitl.board.app.drone_attitudes == sent     # every frame arrived whole


def test_a_sitl_behind_real_time_says_so_and_a_client_on_its_clock_does_not_mind(monkeypatch):
    """Asked for 50 times real time, more than any machine runs it: the SITL reports how far
    behind real time it is; a client keeping its clock gets its fresh heartbeats and its
    commands confirmed all the same. Asked for a speed it can keep, it says it caught up."""
    from uavarm.sim import sitl as sitl_module
    monkeypatch.setattr(sitl_module, "LAG_REPORT_S", 0.2)
    told = []
    s = Sitl(speed=50.0, warn=told.append).start()
    try:
        with link(s) as arm:
            assert arm.enable()["enabled"] == 1
            assert arm.status()["enabled"] == 1 and arm.age.stale == 0
        assert re.fullmatch(r"sitl: the simulated board is \d+\.\d\d s behind real time \(speed 50x asked\): "
                            r"the machine is too busy; its heartbeats come late", told[0]), told
        assert s.max_lag > sitl_module.LAG_WARN_S
        s.speed = 1e-3
        end = time.monotonic() + 30
        while not told[-1].startswith("sitl: the simulated board has caught up"):
            assert time.monotonic() < end, told       # (a hang guard: it takes 0.2 s)
            time.sleep(0.05)                          # (until the report comes)
    finally:
        s.stop()


@pytest.mark.parametrize("text, kind", [("level", "Gravity"), ("tilt:10,-5", "Gravity"), ("rock:10,5,0.5", "Rocking")])
def test_scenarios_parse(text, kind):
    from uavarm.sim.sitl import motion_of
    assert type(motion_of(text)).__name__ == kind


@pytest.mark.parametrize("text", ["tilt:10", "rock:1,2", "spin:3", "tilt:a,b", "rock:10,10,0", "tilt:nan,0"])
def test_bad_scenarios_are_refused(text):
    from uavarm.sim.sitl import motion_of
    with pytest.raises(ValueError, match="scenario"):
        motion_of(text)
