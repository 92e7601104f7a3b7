"""The node's core without ROS (uavarm.link.arm_core: what a ROS 2 adapter would wrap): a
SITL's board driven through it, its loop in a thread as the node runs it, its log and
statuses collected. The core and the drone's messages keep the SITL's clock (simulated
time), so their timeouts and the board's agree however busy the machine.

Oracles: the heartbeat's written fields and units (mm and ms on the wire, m and s out), the
board's own counters (the SITL's app state), the documented refusal and fault names."""
from __future__ import annotations

import math
import threading
import time

import pytest

from conftest import wait_simulated
from uavarm.link import messages
from uavarm.link.arm_core import ArmCore, status_of
from uavarm.model import config
from uavarm.sim.sitl import Sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)

# the SITL's speed: real time, so that the core's loop, a thread beside the board's, keeps
# the arm alive on a busy machine as it would beside a real board
SPEED = 1.0


class Log:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(("info", text))

    def warn(self, text):
        self.lines.append(("warn", text))

    def error(self, text):
        self.lines.append(("error", text))

    def warn_every(self, seconds, text):
        self.warn(text)


@pytest.fixture
def core():
    """An ArmCore on a SITL's port and clock, its loop stepping every 10 ms in a thread."""
    sitl = Sitl(speed=SPEED).start()
    log, statuses = Log(), []
    c = ArmCore(sitl.device, 115200, log, statuses.append, clock=sitl.clock)
    c.open(sitl.clock())
    stop = threading.Event()

    def loop():
        while not stop.is_set():
            c.step(sitl.clock())
            time.sleep(0.01)     # (the loop's pace, as the node's timer)
    threading.Thread(target=loop, daemon=True).start()
    yield c, sitl, log, statuses
    stop.set()
    c.close()
    sitl.stop()


def heartbeat(**changes):
    names = [name for name, _ in messages.BY_NAME["heartbeat"].fields]
    hb = dict.fromkeys(names, 0)
    hb.update(changes)
    return hb


def test_a_status_is_the_heartbeat_in_si_units_and_names():
    refusal = [name for name, _ in messages.REFUSALS].index("no_route")
    hb = heartbeat(set_x=60.0, set_y=-20.0, set_z=-120.0, uptime_ms=1500, refusal=refusal, faults=0b101,
                   q1=0.1, q2=0.2, q3=-0.3, p1=0.15, p2=float("nan"), p3=-0.25, enabled=1, last_fault=3,
                   state=[name for name, _ in messages.STATES].index("limp"),
                   servo1_voltage=111, servo2_temperature=41, servo1_load=512, servo2_load=1024 + 1023)
    s = status_of(hb, "imu")
    assert s["set_position"] == pytest.approx([0.060, -0.020, -0.120]) and s["uptime"] == 1.5
    assert s["refusal"] == "no_route" and s["fault_names"] == ["servo_timeout", "servo_config"]
    # the shafts as read (NaN: not read), the goals beside them
    assert s["joints"][0] == 0.15 and math.isnan(s["joints"][1]) and s["joints"][2] == -0.25
    assert s["goal_joints"] == [0.1, 0.2, -0.3] and s["enabled"] is True and s["last_fault"] == "HardFault"
    assert s["state_name"] == "limp" and s["refusal_code"] == refusal
    # AX-12A e-manual: Present Voltage in 0.1 V; Present Load 0..1023 of the maximum torque, +1024 clockwise
    assert s["servo_voltage"] == [11.1, 0.0, 0.0] and s["servo_temperature"] == [0.0, 41.0, 0.0]
    assert s["servo_load"] == pytest.approx([512 / 1023, -1.0, 0.0])
    assert status_of(heartbeat(), "drone")["refusal"] == "" and status_of(heartbeat(), "drone")["last_fault"] == ""
    assert s["velocity_source"] == "none" and status_of(hb, "drone", "drone")["velocity_source"] == "drone"
    # model/messages.py SOURCES: bit 0 the accelerometer, 1 the drone's attitude, 2 its velocity
    assert s["estimate_sources"] == [] and status_of(heartbeat(estimate_sources=0b110), "drone")["estimate_sources"] \
        == ["drone_attitude", "drone_velocity"]


def test_the_core_drives_the_board_and_forwards_the_attitude(core):
    c, sitl, log, statuses = core
    assert c.enable(True)[0]
    ok, text = c.set_position(0.060, 0.020, -0.120)
    assert ok, text
    assert c.engage(True)[0]
    assert statuses and statuses[-1]["set_position"] == pytest.approx([0.060, 0.020, -0.120], abs=1e-6)
    before = sitl.board.app.drone_attitudes
    c.attitude(0.01, -0.02, None, sitl.clock())
    assert wait_simulated(sitl, 1.0, lambda: sitl.board.app.drone_attitudes > before)
    wait_simulated(sitl, 0.15)                                          # loop steps while it is fresh
    assert sitl.board.app.drone_attitudes == before + 1                 # one stampless measurement: one frame
    unstamped = [text for _, text in log.lines if "carry no stamp" in text]
    assert len(unstamped) == 1 and "stamped on arrival" in unstamped[0]
    assert ("info", f"arm: forwarding the drone's attitude from {c.attitude_topic} to the board") in log.lines
    mark = len(log.lines)
    for _ in range(10):                                                 # kept fresh, no velocity
        c.attitude(0.01, -0.02, None, sitl.clock())
        wait_simulated(sitl, 0.04)
    assert not [text for _, text in log.lines[mark:] if "no attitude" in text]
    assert len([text for _, text in log.lines if "carry no stamp" in text]) == 1     # said once
    before = sitl.board.app.drone_velocities
    c.velocity((0.5, -0.25, 0.0), None, sitl.clock())
    assert wait_simulated(sitl, 1.0, lambda: sitl.board.app.drone_velocities > before)
    wait_simulated(sitl, 0.1)                                           # several loop steps more
    assert sitl.board.app.drone_velocities == before + 1                # each measurement once
    assert ("info", f"arm: forwarding the drone's velocity from {c.attitude_topic} to the board") in log.lines
    assert c.velocity_source == "drone"                                 # (what the next status says)
    c.velocity((0.5, -0.25, 0.0), None, sitl.clock() - 1.0)             # stale when it came
    wait_simulated(sitl, 0.3)
    assert sitl.board.app.drone_velocities == before + 1
    assert c.velocity_source == "none"
    assert ("warn", f"arm: no velocity on {c.attitude_topic} for 0.20 s: the board goes on without it") in log.lines
    # none fresh: the core keeps the engaged arm alive past the board's silence timeout
    wait_simulated(sitl, 2 * config.load().link_silence_timeout + 1.0)
    last = statuses[-1]
    assert last["engaged"] and last["attitude_source"] == "imu", (last["fault_names"], last["state_name"], log.lines)
    ok, text = c.set_position(5.0, 0.0, 0.0)
    assert not ok and "unreachable" in text and "(board figures in mm)" in text


def test_a_port_that_is_not_there_is_retried_with_one_error():
    log = Log()
    c = ArmCore("/dev/no-such-arm", 115200, log, lambda s: None)
    for k in range(3):
        c.step(100.0 + 1.5 * k)                       # past the reopen period each time
    assert c.link is None and [level for level, _ in log.lines] == ["error"]
    assert c.enable(True) == (False, f"no link to the board: {c.link_error}")


class StubLink:
    """What a step uses of SharedLink, recording what it sends."""
    silence, engaged, last_sent = 1.5, False, 0.0

    def __init__(self):
        self.sent = []

    def poll(self):
        return []

    def send(self, name, **fields):
        self.sent.append((name, fields))

    def send_attitude(self, roll, pitch, stamp_us):
        self.sent.append(("drone_attitude", {"roll": roll, "pitch": pitch, "stamp_us": stamp_us}))

    def send_velocity(self, vx, vy, vz, stamp_us):
        self.sent.append(("drone_velocity", {"stamp_us": stamp_us}))


def stub_core(**kw):
    log = Log()
    c = ArmCore("/dev/stub", 115200, log, lambda s: None, **kw)
    c.link = StubLink()
    return c, log


def test_a_target_stream_sends_the_latest_point_at_most_target_rate_times_a_second():
    c, log = stub_core(target_rate=50.0)
    c.target(0.060, 0.020, -0.120)
    c.step(10.000)
    c.target(0.061, 0.020, -0.120)
    c.step(10.010)                                    # 10 ms after: held back
    c.target(0.062, 0.020, -0.120)                   # the latest replaces it
    c.step(10.020)
    c.step(10.030)                                    # nothing new
    sent = [f for name, f in c.link.sent if name == "set_position"]
    assert sent == [{"x": 60.0, "y": 20.0, "z": -120.0}, {"x": 62.0, "y": 20.0, "z": -120.0}]
    c.target(math.nan, 0.0, -0.1)                     # never sent
    c.target(60.0, 20.0, -120.0)                      # millimetres by mistake: sent, refused by the board, hinted
    c.step(10.100)
    assert [f for name, f in c.link.sent if name == "set_position"][-1] == {"x": 60000.0, "y": 20000.0, "z": -120000.0}
    assert any("not finite" in text for _, text in log.lines)
    assert any("millimetres? the services and ~target take metres" in text for _, text in log.lines)
    # engaged, no attitude, the stream stopped: the keep-alive repeats the last point streamed
    # (the last heartbeat may predate it)
    c.link.engaged, c.link.last_sent = True, 0.0
    c.step(11.0)
    assert c.link.sent[-1] == ("set_position", {"x": 60000.0, "y": 20000.0, "z": -120000.0})
    with pytest.raises(ValueError, match="tick rate"):
        stub_core(target_rate=150.0)


def test_each_drone_measurement_is_sent_once_and_a_stampless_one_stamped_on_arrival():
    c, log = stub_core()
    c.attitude(0.01, -0.02, None, 20.0)
    for k in range(5):
        c.step(20.0 + 0.01 * k)                       # five steps while it is fresh
    c.attitude(0.01, -0.02, 123456, 20.05)            # stamped: its own stamp
    c.step(20.06)
    attitudes = [f for name, f in c.link.sent if name == "drone_attitude"]
    assert [f["stamp_us"] for f in attitudes] == [20_000_000, 123456]
    assert [level for level, text in log.lines if "carry no stamp" in text] == ["warn"]
