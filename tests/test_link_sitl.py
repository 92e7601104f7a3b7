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
from uavarm.link import llcp, messages
from uavarm.link.messages import fault_names
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
    return np.degrees([hb["p1"], hb["p2"], hb["p3"]])


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
            ee = arm_points(m, [hb["p1"], hb["p2"], hb["p3"]])[2]
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



# ---------------------------------------------------------------- bench and flight

class DroneLink(ArmLink):
    """A link that is also the drone's flight controller: while `flying`, each poll (every wait
    for a heartbeat polls) sends drone_attitude once 0.02 s of the SITL's clock has passed
    since the last, 50 Hz."""
    flying = False
    _fed = -math.inf

    def poll(self):
        if self.flying and self.clock() - self._fed >= 0.02:
            self._fed = self.clock()
            self.send_attitude(0.0, 0.0)
        return super().poll()


def state_of(hb) -> str:
    return messages.STATES[hb["state"]][0]


def torque_on_everywhere(sitl) -> bool:
    return all(s.register("torque_enable") == 1 for s in sitl.board.bus.servos)


def test_while_the_drone_flies_the_bench_is_refused_and_its_attitude_parks_a_limp_arm(sitl):
    """The drone's attitude at 50 Hz: torque off and a jog are refused as `flying` and the arm
    stays parked with the torque on; a silence timeout after the drone's last message the
    bench is back (the arm goes limp); the drone's next attitude turns the torque back on and
    parks it, no link_lost (the link never fell silent)."""
    m = config.load()
    with DroneLink(sitl.device, clock=sitl.clock) as arm:
        arm.enable()
        assert wait_for(sitl, arm, lambda hb: state_of(hb) == "parked", 10.0) is not None
        arm.flying = True
        arm.collect("imu_raw", 0.1)                   # (the drone's attitude comes)
        for command in (lambda: arm.torque(False), lambda: arm.jog(2, angle=math.radians(119.0))):
            with pytest.raises(CommandRefused, match="refused: .*the drone may be flying"):
                command()
            hb = arm.next_heartbeat()
            assert state_of(hb) == "parked" and torque_on_everywhere(sitl)
        arm.flying = False                            # it lands
        arm.collect("imu_raw", m.link_silence_timeout + 0.1)
        with arm.kept_alive():
            assert state_of(arm.torque(False)) == "limp"
            assert not torque_on_everywhere(sitl)
            arm.flying = True                         # and takes off again
            hb = wait_for(sitl, arm, lambda hb: state_of(hb) == "parked", 5.0)
        assert hb is not None, "the limp arm did not park when the drone's attitude came"
        assert torque_on_everywhere(sitl) and not hb["engaged"] and hb["enabled"]
        assert "link_lost" not in fault_names(hb["faults"])


def test_pings_keep_nothing_alive_and_a_jogged_arm_parks_once_the_link_is_silent(sitl):
    """A latency tool pinging at 50 Hz for 6 s, every ping answered: the engaged arm parks
    (link_lost). Then jogged (kept alive until there) and left: 10 s later it is parked with
    the torque on and link_lost."""
    m = config.load()
    with link(sitl) as arm:
        arm.enable()
        arm.engage()
        pings, end = 0, sitl.clock() + 6.0
        while sitl.clock() < end:
            arm.ping(pings)
            pings += 1
            due = sitl.clock() + 0.02
            while sitl.clock() < due:
                arm.poll()
                time.sleep(0.001)                     # (a poll's interval: the SITL's clock paces)
        arm.poll()
        hb = arm.status()
        assert hb["engaged"] == 0 and "link_lost" in hb["fault_names"] and state_of(hb) in ("parking", "parked")
        assert len(arm.pongs) >= pings - 5, (len(arm.pongs), pings)      # the last few still on their way
        assert wait_for(sitl, arm, lambda hb: state_of(hb) == "parked", 5.0) is not None
        with arm.kept_alive():                        # (until there)
            arm.jog(2, angle=math.radians(119.0))
            assert wait_for(sitl, arm, lambda hb: state_of(hb) == "jogged", 5.0) is not None
        end = sitl.clock() + 10.0
        hbs = []
        while sitl.clock() < end:
            hbs.append(arm.next_heartbeat())
        assert state_of(hbs[0]) == "jogged"
        assert state_of(hbs[-1]) == "parked" and "link_lost" in fault_names(hbs[-1]["faults"])
        assert torque_on_everywhere(sitl) and hbs[-1]["enabled"] and not hbs[-1]["engaged"]


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
        end = time.monotonic() + 30
        while not told:                               # the report, once it is 0.1 s behind
            assert time.monotonic() < end, "no report of the lag"
            time.sleep(0.05)
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


def test_a_sitl_behind_real_time_catches_up_no_faster_than_its_catch_up_rate():
    """The board's thread held up 2 s (as a busy machine does): then, however busy the machine,
    the board runs at most CATCH_UP times the speed asked until it has caught up, so a program
    pacing itself on the wall clock looks at most that much slower to it than to a real board.
    (A bound only: load slows the board, never speeds it; flat out it ran 1.46 s in 0.2 s.)"""
    from uavarm.sim import sitl as sitl_module
    s = Sitl(speed=1.0, warn=lambda text: None).start()
    try:
        s.handle = lambda text: time.sleep(2.0) or "held up"
        assert s.submit("hold").result(timeout=30) == "held up"
        # the board's clock, read from here, trails its run by up to a slice (run in C before the
        # clock is set); the slice under way at the start, and the next one's credit, were earned
        # before it; each slice's credit rounded to a microsecond (a few hundred slices)
        slack_us = 3 * sitl_module.SLICE_S * 1e6 + 1000
        for _ in range(5):
            wall, board_us = time.monotonic(), s.board.now_us
            time.sleep(0.2)
            ran_us = s.board.now_us - board_us
            assert ran_us <= sitl_module.CATCH_UP * (time.monotonic() - wall) * 1e6 + slack_us
        assert s.lag > 1.0, "still catching up: the spans above were all behind real time"
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
