"""The service commands for bring-up and calibration, on the simulated board: torque off and
on (limp for positioning by hand), jog, and the raw IMU and servo status streams. Each is
driven through the link bytes, with tests/invariants.py watching every step (every move
checked against the limits, the body and the legs by plain geometry).

Oracles: the AX-12A control table (Torque Enable at 24, Torque Limit at 34; 1023 units over
300 degrees), the MPU-6050 register map (ACCEL_XOUT_H at 0x3B, big-endian counts, 8192
counts/g at +-4 g), the message layouts as written, and the simulated servos' own shafts.
"""
from __future__ import annotations

import math
import re
import time

import numpy as np
import pytest

from invariants import Invariants
from simboard_tools import (
    FAULT, IDS, MODEL, PARK_SPEED, PARK_UNITS, BusLog, make_board, ready, shaft_units, sync_goal_speed,
)
from uavarm.link import messages

REFUSAL = {name: k for k, (name, _) in enumerate(messages.REFUSALS)}
STATE = {name: k for k, (name, _) in enumerate(messages.STATES)}
TORQUE_ENABLE, TORQUE_LIMIT = 24, 34
UNIT_DEG = 300.0 / 1023
COUNTS_PER_G = 32768 / 4                 # MPU-6050 at +-4 g (the model's range)
HB_S = MODEL.heartbeat_period


@pytest.fixture(scope="module", autouse=True)
def four_g_range():
    assert MODEL.accel_range_g == 4, "the counts-per-g oracle below is for +-4 g"


def parked(**kw):
    board = make_board(**kw)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.5) is not None
    assert inv.run_until(lambda: state(board) == "parked", 2.0) is not None
    return board, inv


def state(board) -> str:
    return messages.STATES[board.heartbeats[-1]["state"]][0] if board.heartbeats else "none"


def refusal(board) -> str:
    return messages.REFUSALS[board.heartbeats[-1]["refusal"]][0]


def after_heartbeat(inv):
    inv.next_heartbeat()
    return inv.board.heartbeats[-1]


def limp_and_turn(inv, j, units):
    """Torque off, then joint j's shaft turned by hand to `units`."""
    inv.board.send("torque", on=0)
    inv.run(0.2)
    inv.board.bus.servos[j].turn_by_hand(units)
    inv.run(0.1)


def torque_writes(inv, since):
    """(servo id, value) of every WRITE to Torque Enable sent after `since`."""
    return [(p.id, p.params[1]) for p in inv.log.tx
            if p.start >= since and p.inst == 0x03 and p.params[0] == TORQUE_ENABLE]


# ---------------------------------------------------------------- torque off and on

def test_torque_off_makes_the_arm_limp_without_a_brown_out_and_still_reads_it():
    board, inv = parked()
    t0 = board.time
    board.send("torque", on=0)
    inv.run(0.3)
    assert torque_writes(inv, t0) == [(0xFE, 0)], "one broadcast WRITE of Torque Enable 0"
    # e-manual framing, written out: broadcast id, length 4, WRITE, address 24, one byte 0,
    # checksum ~(FE+04+03+18+00) & FF
    assert [p.raw for p in inv.log.tx if p.start >= t0 and p.inst == 0x03] == [bytes.fromhex("ff ff fe 04 03 18 00 e2")]
    assert all(s.register("torque_enable") == 0 for s in board.bus.servos) and board.servo_power
    assert not inv.log.syncs(t0 + 0.02), "nothing commanded while limp"
    # turned by hand: 40 units on joint 2 (clear of everything), read back in the heartbeat
    target = PARK_UNITS[1] + 40
    board.bus.servos[1].turn_by_hand(target)
    hb = after_heartbeat(inv)
    hb = after_heartbeat(inv)
    assert state(board) == "limp"
    assert math.degrees(hb["p2"]) == pytest.approx(MODEL.park_deg[1] + 40 * UNIT_DEG, abs=UNIT_DEG)   # the shaft
    assert math.degrees(hb["q2"]) == pytest.approx(MODEL.park_deg[1], abs=1e-4)    # the goal: none sent limp
    assert not hb["faults"] & (FAULT["servo_reset"] | FAULT["servo_tracking"] | FAULT["command_refused"])
    assert hb["servo_resets"] == 0
    # torque on: each servo set up again, holding where it stands (nothing moves)
    t1 = board.time
    board.send("torque", on=1)
    assert inv.run_until(lambda: state(board) == "jogged", 1.0) is not None
    assert sorted(torque_writes(inv, t1)) == [(1, 1), (2, 1), (3, 1)]
    inv.run(0.5)
    assert shaft_units(board)[1] == pytest.approx(target, abs=1.0)
    assert all(s.register("torque_enable") == 1 for s in board.bus.servos)
    assert board.heartbeats[-1]["servo_resets"] == 0


def test_service_commands_are_refused_while_engaged_or_disabled():
    board = make_board()
    inv = Invariants(board, BusLog(board))
    inv.run(0.6)
    for name, fields in (("torque", {"on": 0}), ("jog", {"joint": 1, "mode": 0, "value": 0.1})):
        board.send(name, **fields)
        after_heartbeat(inv)
        assert refusal(board) == "not_enabled", name
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.5) is not None
    board.send("engage", on=1)
    assert inv.run_until(lambda: board.heartbeats[-1]["engaged"], 1.0) is not None
    for name, fields in (("torque", {"on": 0}), ("jog", {"joint": 1, "mode": 0, "value": 0.1}),
                         ("stream", {"imu_every": 1, "servos": 1})):
        board.send(name, **fields)
        after_heartbeat(inv)
        assert refusal(board) == "engaged" and board.heartbeats[-1]["engaged"], name
    assert all(s.register("torque_enable") == 1 for s in board.bus.servos)


def test_service_commands_are_refused_while_the_servos_start():
    """Right after enable the servos boot and are configured: torque and jog wait for that."""
    for name, fields in (("torque", {"on": 0}), ("jog", {"joint": 1, "mode": 0, "value": 0.1})):
        board = make_board()
        inv = Invariants(board, BusLog(board))
        inv.run(0.6)
        board.send("enable", on=1)
        inv.run(0.01)
        board.send(name, **fields)
        after_heartbeat(inv)
        assert refusal(board) == "servos_starting", name


def test_a_disable_ends_limp_enabled_again_the_arm_parks():
    """Torque off, then the servos' supply cut: limp ends with the power, so the next enable
    sets the servos up with torque on and parks the arm, as any enable does."""
    board, inv = parked()
    board.send("torque", on=0)
    assert inv.run_until(lambda: state(board) == "limp", 1.0) is not None
    board.send("enable", on=0)
    inv.run(0.2)
    t0 = board.time
    board.send("enable", on=1)
    assert inv.run_until(lambda: state(board) == "parked", 3.0) is not None
    assert inv.log.syncs(t0) and all(s.register("torque_enable") == 1 for s in board.bus.servos)


def test_engage_while_limp_turns_the_torque_on_and_parks_first():
    board, inv = parked()
    limp_and_turn(inv, 0, PARK_UNITS[0] + 60)
    board.send("engage", on=1)
    after_heartbeat(inv)
    assert refusal(board) == "servos_starting" and not board.heartbeats[-1]["engaged"]
    assert inv.run_until(lambda: state(board) == "parked", 3.0) is not None
    inv.run(0.1)            # the shafts' lag behind the goals
    assert shaft_units(board)[0] == pytest.approx(PARK_UNITS[0], abs=1.5)
    board.send("engage", on=1)
    assert inv.run_until(lambda: board.heartbeats[-1]["engaged"], 1.0) is not None


# ---------------------------------------------------------------- jog

def test_jog_to_an_angle_and_by_units_at_park_speed():
    board, inv = parked()
    t0 = board.time
    target = math.radians(MODEL.park_deg[0] + 20.0)
    board.send("jog", joint=1, mode=0, value=target)
    assert inv.run_until(lambda: state(board) in ("jogging", "jogged"), 0.6) is not None
    assert inv.run_until(lambda: state(board) == "jogged", 3.0) is not None
    speeds = {tuple(sync_goal_speed(p.raw)[1]) for p in inv.log.syncs(t0)}
    assert speeds == {(PARK_SPEED,) * 3}
    target = PARK_UNITS[0] + 20.0 / UNIT_DEG
    # the shaft there a lag after the goals, within its compliance margin of the rounded goal
    assert inv.run_until(lambda: abs(shaft_units(board)[0] - round(target)) <= 1.0, 0.5) is not None
    goal_before = sync_goal_speed(inv.log.syncs()[-1].raw)[0]
    board.send("jog", joint=2, mode=1, value=-25.0)
    assert inv.run_until(lambda: sync_goal_speed(inv.log.syncs()[-1].raw)[0][1] == goal_before[1] - 25, 2.0)
    last = sync_goal_speed(inv.log.syncs()[-1].raw)[0]
    assert (last[0], last[2]) == (goal_before[0], goal_before[2])
    assert not board.heartbeats[-1]["faults"] & FAULT["command_refused"]


@pytest.mark.parametrize("joint, mode, value", [
    (0, 0, 0.0), (4, 0, 0.0), (1, 2, 0.0),                 # no such joint or mode
    (2, 0, float("nan")), (1, 1, float("inf")),            # not finite
    (2, 0, math.radians(125.0)),                           # beyond joint 2's 120 deg limit
    (1, 0, math.radians(150.0)),                           # beyond joint 1's 145 deg limit
    (1, 1, 2000.0),                                        # beyond the servo's 0..1023 units
])
def test_a_bad_jog_is_refused_and_nothing_moves(joint, mode, value):
    board, inv = parked()
    before = shaft_units(board)
    n = len(inv.log.syncs())
    board.send("jog", joint=joint, mode=mode, value=value)
    after_heartbeat(inv)
    assert refusal(board) == "bad_jog" and state(board) == "parked"
    inv.run(0.3)
    assert {tuple(sync_goal_speed(p.raw)[0]) for p in inv.log.syncs()[n:]} <= {tuple(round(u) for u in PARK_UNITS)}
    assert np.allclose(shaft_units(board), before, atol=1.0)


def test_jog_while_limp_turns_the_torque_on_and_goes_there():
    board, inv = parked()
    limp_and_turn(inv, 2, PARK_UNITS[2] + 30)
    board.send("jog", joint=3, mode=1, value=-30.0)
    assert inv.run_until(lambda: state(board) == "jogged", 3.0) is not None   # the goals there
    # the shaft there a lag later, within its compliance margin of the rounded goal
    assert inv.run_until(lambda: abs(shaft_units(board)[2] - round(PARK_UNITS[2])) <= 1.0, 0.5) is not None
    assert all(s.register("torque_enable") == 1 for s in board.bus.servos)


def test_a_jog_taken_while_limp_clears_the_last_refusal():
    board, inv = parked()
    limp_and_turn(inv, 2, PARK_UNITS[2] + 30)
    board.send("jog", joint=4, mode=0, value=0.1)
    after_heartbeat(inv)
    assert refusal(board) == "bad_jog"
    board.send("jog", joint=3, mode=1, value=-30.0)
    after_heartbeat(inv)
    assert refusal(board) == "none"


def test_engage_from_a_jogged_pose_parks_first():
    board, inv = parked()
    board.send("jog", joint=1, mode=0, value=math.radians(MODEL.park_deg[0] + 30.0))
    assert inv.run_until(lambda: state(board) == "jogged", 3.0) is not None
    t0 = board.time
    board.send("engage", on=1)
    park = tuple(round(u) for u in PARK_UNITS)
    assert inv.run_until(lambda: any(tuple(sync_goal_speed(p.raw)[0]) == park for p in inv.log.syncs(t0)), 3.0)
    assert inv.run_until(lambda: state(board) == "holding", 3.0) is not None


# ---------------------------------------------------------------- streams

def test_the_raw_imu_stream_carries_the_chips_counts():
    board = make_board()
    inv = Invariants(board, BusLog(board))
    board.send("stream", imu_every=2, servos=0)
    inv.run(1.0)
    frames = board.streamed["imu_raw"]
    assert 45 <= len(frames) <= 51                       # every second tick of 100 Hz
    assert [f["seq"] for f in frames] == list(range(frames[0]["seq"], frames[0]["seq"] + len(frames)))
    gaps = np.diff([f["stamp_us"] for f in frames])
    assert np.all(np.abs(gaps - 20_000) <= 200)
    a = np.array([[f["ax"], f["ay"], f["az"]] for f in frames], dtype=float) / COUNTS_PER_G
    assert np.linalg.norm(a, axis=1) == pytest.approx(1.0, abs=0.03)   # still: gravity alone
    assert all(f["fresh"] for f in frames[1:])
    board.send("stream", imu_every=0, servos=0)
    inv.run(0.1)
    n = len(board.streamed["imu_raw"])
    inv.run(0.3)
    assert len(board.streamed["imu_raw"]) == n


def test_the_servo_stream_reports_each_status_read():
    board, inv = parked()
    board.send("stream", imu_every=0, servos=1)
    t0 = board.time
    inv.run(0.9)
    frames = board.streamed["servo_status"]
    reads = len(inv.log.reads(t0 + 0.02))
    assert abs(len(frames) - reads) <= 2 and len(frames) >= 80
    assert {f["servo"] for f in frames} == {0, 1, 2}
    park = [round(u) for u in PARK_UNITS]
    for f in frames:
        assert f["goal"] == park[f["servo"]]
        assert abs(f["position"] - board.bus.servos[f["servo"]].register("present_position")) <= 1
    board.send("engage", on=1)                                         # engage stops the streams
    assert inv.run_until(lambda: board.heartbeats[-1]["engaged"], 1.0) is not None
    n = len(board.streamed["servo_status"])
    inv.run(0.3)
    assert len(board.streamed["servo_status"]) == n


def test_the_servo_stream_carries_each_reply_while_the_arm_moves():
    """Streaming through a jog of joint 3 by 40 units at the park speed and back: every
    frame's position, speed and load are those of a status reply its servo sent (the reply's
    bytes, Present Position at 36, Present Speed at 38, Present Load at 40, little-endian),
    and the moving joint's frames show its speed, either way (bit 10: the direction)."""
    board, inv = parked()
    board.send("stream", imu_every=0, servos=1)
    t0 = board.time
    board.send("jog", joint=3, mode=1, value=40.0)
    inv.run(1.0)
    board.send("jog", joint=3, mode=1, value=-40.0)
    inv.run(1.0)
    replies = set()
    for r in inv.log.replies:
        if r.start >= t0 and r.raw[3] == 12 + 2:           # a status reply of registers 32..43
            p = r.raw[5:-1]
            replies.add((IDS.index(r.raw[2]), *(int.from_bytes(p[k:k + 2], "little") for k in (4, 6, 8))))
    frames = board.streamed["servo_status"]
    assert frames and all((f["servo"], f["position"], f["speed"], f["load"]) in replies for f in frames)
    moving = [f["speed"] for f in frames if f["servo"] == 2 and f["speed"] != 0]
    assert sum(s < 1024 for s in moving) >= 5 and sum(s >= 1024 for s in moving) >= 5


# ---------------------------------------------------------------- from the command line

@pytest.mark.realtime
def test_the_command_line_limps_stiffens_and_jogs_a_sitl():
    """In the shell, which keeps the arm limp or jogged between its commands; alone, a limp
    arm parks with the torque on once the link has been silent for its timeout."""
    import subprocess
    import sys
    from uavarm.sim.sitl import Sitl
    s = Sitl(speed=2.0).start()
    run = lambda *a, text="": subprocess.run([sys.executable, "-m", "uavarm.cli", "link", s.device, *a],
                                             input=text, capture_output=True, text=True, timeout=60)
    try:
        out = run("shell", text="enable\nlimp\nwait 2\nstatus\nstiff\njog 1 25\nwait 2\nstatus\n")
        assert out.returncode == 0, out
        lines = [line for line in out.stdout.splitlines() if re.match(r"\w+: ok ", line)]
        assert [line.split(":")[0] for line in lines] == ["enable", "limp", "status", "stiff", "jog", "status"], out
        assert " limp," in lines[2] and " jogged," in lines[5] and "link_lost" not in out.stdout, out.stdout
        assert "the arm is jogged and parks once the link has been silent" in out.stdout
        out = run("jog", "2", "130")                       # beyond joint 2's 120 deg
        assert out.returncode == 1 and "jog refused" in out.stderr and "Traceback" not in out.stderr
        out = run("jog", "4", "0")
        assert out.returncode == 2 and "joint must be 1, 2 or 3" in out.stderr
        out = run("limp")
        assert out.returncode == 0 and " limp " in out.stdout, out
        end = s.clock() + 5 * MODEL.link_silence_timeout
        while not (s.board.heartbeats and state(s.board) == "parked"):
            assert s.clock() < end, "the limp arm did not park once the link fell silent"
            time.sleep(0.05)                               # (until a heartbeat says so, in simulated time)
        assert s.board.heartbeats[-1]["faults"] & FAULT["link_lost"] and torque_on_everywhere(s.board)
    finally:
        s.stop()


# ---------------------------------------------------------------- bench and flight

class Drone:
    """The drone's flight controller on the link: drone_attitude (level: the board is) every
    `every` s, seq and stamp counting up, while run() runs the board under the invariants."""

    def __init__(self, inv, every=0.02):
        self.inv, self.every, self.seq = inv, every, 0

    def send(self):
        board = self.inv.board
        board.send("drone_attitude", seq=self.seq, stamp_us=board.now_us & 0xFFFFFFFF, roll=0.0, pitch=0.0)
        self.seq = (self.seq + 1) & 0xFFFF

    def run(self, seconds):
        end = self.inv.board.time + seconds
        while self.inv.board.time < end - 1e-9:
            self.send()
            self.inv.run(min(self.every, end - self.inv.board.time), step=self.every / 2)

    def run_until(self, cond, timeout):
        end = self.inv.board.time + timeout
        while self.inv.board.time < end - 1e-9:
            if cond():
                return True
            self.run(self.every)
        return bool(cond())


def keep_alive(inv, seconds, every=0.2) -> float:
    """Runs `seconds`, repeating the set position in force every `every` s (what the shell and
    the calibrations send to keep a limp or jogged arm so); the time of the last one sent."""
    board = inv.board
    end = board.time + seconds
    sent = board.time
    while board.time < end - 1e-9:
        hb = board.heartbeats[-1]
        board.send("set_position", x=hb["set_x"], y=hb["set_y"], z=hb["set_z"])
        sent = board.time
        inv.run(min(every, end - board.time))
    return sent


def torque_on_everywhere(board) -> bool:
    return all(s.register("torque_enable") == 1 for s in board.bus.servos)


def at_park(board) -> bool:
    """The shafts stopped on the park goal (within the compliance margin, a unit)."""
    return all(abs(s - round(p)) <= 1.0 for s, p in zip(shaft_units(board), PARK_UNITS))


def test_while_the_drone_streams_torque_off_jog_and_streams_are_refused_as_flying():
    """The drone's attitude at 50 Hz, the arm parked: torque 0, jog (joint 2 to 119 deg, a
    pose it may rest at) and a stream on are refused with `flying`; nothing moves, the torque
    stays on. A stream off is taken. A second after the drone's last message the bench is
    back: the same jog is taken."""
    board, inv = parked()
    drone = Drone(inv)
    drone.run(0.3)
    t0, n = board.time, len(inv.log.syncs())
    for k, (name, fields) in enumerate((("torque", {"on": 0}), ("jog", {"joint": 2, "mode": 0, "value": math.radians(119.0)}),
                                        ("torque", {"on": 1}), ("stream", {"imu_every": 1, "servos": 0}),
                                        ("stream", {"imu_every": 0, "servos": 1}))):
        board.send("set_position", **dict(zip("xyz", (60.0, 20.0 + k, -120.0))))   # a command taken
        drone.run(2 * HB_S)
        assert refusal(board) == "none"
        board.send(name, **fields)
        drone.run(2 * HB_S)
        assert refusal(board) == "flying", (name, fields)
        assert state(board) == "parked" and torque_on_everywhere(board)
    board.send("stream", imu_every=0, servos=0)
    drone.run(2 * HB_S)
    assert refusal(board) == "none"
    assert {tuple(sync_goal_speed(p.raw)[0]) for p in inv.log.syncs()[n:]} == {tuple(round(u) for u in PARK_UNITS)}
    assert not board.streamed["imu_raw"] and not board.streamed["servo_status"]
    assert torque_writes(inv, t0) == []
    # the drone falls silent: a link silence timeout later the bench is back
    inv.run(MODEL.link_silence_timeout + 0.05)
    board.send("jog", joint=2, mode=0, value=math.radians(119.0))
    after_heartbeat(inv)
    assert refusal(board) == "none" and state(board) in ("jogging", "jogged")


def test_a_drone_velocity_marks_flight_too():
    board, inv = parked()
    board.send("drone_velocity", seq=0, stamp_us=board.now_us, vx=0.0, vy=0.0, vz=0.0)
    inv.run(0.01)
    board.send("torque", on=0)
    after_heartbeat(inv)
    assert refusal(board) == "flying" and state(board) == "parked"


def test_the_drone_heard_ends_limp_with_the_torque_on_and_parks():
    """Limp on the bench, joint 1 turned by hand 60 units, the servo stream on: the drone's
    first attitude message turns the torque back on, stops the stream and parks the arm by a
    checked route (tests/invariants.py judges the shafts from the first goal on)."""
    board, inv = parked()
    board.send("stream", imu_every=0, servos=1)
    limp_and_turn(inv, 0, PARK_UNITS[0] + 60)
    assert inv.run_until(lambda: state(board) == "limp", HB_S + 0.05) is not None
    t0 = board.time
    drone = Drone(inv)
    drone.run(0.05)
    assert sorted(torque_writes(inv, t0)) == [(1, 1), (2, 1), (3, 1)]
    n = len(board.streamed["servo_status"])
    assert drone.run_until(lambda: state(board) == "parked" and at_park(board), 4.0), shaft_units(board)
    assert len(board.streamed["servo_status"]) <= n + 1, "the stream stopped"
    assert torque_on_everywhere(board)
    assert not board.heartbeats[-1]["faults"] & FAULT["link_lost"]
    assert {tuple(sync_goal_speed(p.raw)[1]) for p in inv.log.syncs(t0)} == {(PARK_SPEED,) * 3}


def test_the_drone_heard_ends_a_jog_and_parks():
    board, inv = parked()
    board.send("jog", joint=1, mode=0, value=math.radians(MODEL.park_deg[0] + 30.0))
    assert inv.run_until(lambda: state(board) == "jogging", HB_S + 0.05) is not None
    Drone(inv).run_until(lambda: state(board) == "parked" and at_park(board), 4.0)
    assert state(board) == "parked" and at_park(board) and torque_on_everywhere(board)


# The servos these parks from a held pose run on: the model file's lag on the default 3S
# supply (11.1 V, sagging), and the slowest, 45 ms on 9.0 V; Invariants judges the shafts.
SERVOS = [pytest.param({}, id="model lag, 11.1 V"), pytest.param({"lag": 0.045, "supply": 9.0}, id="45 ms, 9.0 V")]


@pytest.mark.parametrize("servos", SERVOS)
def test_a_limp_arm_kept_alive_stays_limp_and_ten_seconds_of_silence_park_it_with_the_torque_on(servos):
    """The set position repeated every 0.2 s (a shell or a calibration on the bench) keeps a
    limp arm limp past the link's silence timeout; then 10 s without a frame: a silence
    timeout after the last one the torque comes back on and the arm parks, flagging
    link_lost."""
    board, inv = parked(**servos)
    limp_and_turn(inv, 1, PARK_UNITS[1] + 40)
    t_limp = board.time
    t_last = keep_alive(inv, 3 * MODEL.link_silence_timeout)
    assert state(board) == "limp" and not torque_writes(inv, t_limp)
    inv.run(10.0)
    on = [p.start for p in inv.log.tx if p.start > t_last and p.inst == 0x03 and p.params[:2] == bytes([TORQUE_ENABLE, 1])]
    assert on, "the torque never came back on"
    delay = on[0] - t_last
    print(f"\nlimp and silent: torque on {delay * 1e3:.1f} ms after the last frame")
    assert MODEL.link_silence_timeout <= delay <= MODEL.link_silence_timeout + 0.05
    hb = board.heartbeats[-1]
    assert state(board) == "parked" and at_park(board) and torque_on_everywhere(board)
    assert hb["faults"] & FAULT["link_lost"] and hb["enabled"] and not hb["engaged"]
    assert inv.shaft_steps > 0


@pytest.mark.parametrize("servos", SERVOS)
def test_a_jogged_arm_parks_after_ten_seconds_of_silence(servos):
    """Joint 2 jogged to 119 deg (kept alive until it is there), then 10 s without a frame:
    parked with the torque on and link_lost."""
    board, inv = parked(**servos)
    board.send("jog", joint=2, mode=0, value=math.radians(119.0))
    end = board.time + 5.0
    while state(board) != "jogged" and board.time < end:
        keep_alive(inv, 0.2)
    assert state(board) == "jogged"
    assert math.degrees(board.heartbeats[-1]["q2"]) == pytest.approx(119.0, abs=0.5)
    t_last = keep_alive(inv, 0.2)     # the last frame: sent once the goals are there
    held = inv.goals(t_last)[-1]
    inv.run(10.0)
    hb = board.heartbeats[-1]
    assert state(board) == "parked" and at_park(board) and torque_on_everywhere(board)
    assert hb["faults"] & FAULT["link_lost"]
    parking = [p for p in inv.log.syncs(t_last) if sync_goal_speed(p.raw)[0] != list(held)]
    assert parking and MODEL.link_silence_timeout <= parking[0].start - t_last <= MODEL.link_silence_timeout + 0.03


@pytest.mark.parametrize("servos", SERVOS)
def test_an_arm_held_where_the_hands_left_it_parks_once_the_link_is_silent(servos):
    """Limp, joint 1 turned by hand, then the torque back on (held there: jogged), then no
    frame: the hold ends a silence timeout after the torque command, parked with link_lost."""
    board, inv = parked(**servos)
    limp_and_turn(inv, 0, PARK_UNITS[0] + 60)
    board.send("torque", on=1)
    t_last = board.time
    assert inv.run_until(lambda: state(board) == "jogged", MODEL.link_silence_timeout) is not None
    assert shaft_units(board)[0] == pytest.approx(PARK_UNITS[0] + 60, abs=1.5)
    assert inv.run_until(lambda: state(board) == "parked" and at_park(board), 10.0) is not None
    hb = board.heartbeats[-1]
    assert hb["faults"] & FAULT["link_lost"] and torque_on_everywhere(board)
    parking = [p for p in inv.log.syncs(t_last) if sync_goal_speed(p.raw)[1] == [PARK_SPEED] * 3
               and sync_goal_speed(p.raw)[0][0] != round(PARK_UNITS[0] + 60)]
    assert parking and MODEL.link_silence_timeout <= parking[0].start - t_last <= MODEL.link_silence_timeout + 0.03


def test_pings_alone_keep_nothing_alive():
    """An engaged arm whose controller has gone, a latency tool pinging at 50 Hz: every ping is
    answered, and the arm parks a silence timeout after the last frame that was not a ping."""
    board, inv = parked()
    board.send("engage", on=1)
    assert inv.run_until(lambda: board.heartbeats[-1]["engaged"], 1.0) is not None
    board.send("set_position", x=60.0, y=20.0, z=-120.0)
    t_last = board.time
    for k in range(300):                                   # 6 s
        board.send("ping", seq=k, stamp_us=k * 20_000)
        inv.run(0.02)
    assert len(board.streamed["pong"]) >= 299
    assert [p["seq"] for p in board.streamed["pong"]][:5] == [0, 1, 2, 3, 4]
    hb = board.heartbeats[-1]
    assert not hb["engaged"] and hb["faults"] & FAULT["link_lost"] and state(board) == "parked"
    parking = [p for p in inv.log.syncs(t_last) if sync_goal_speed(p.raw)[1] == [PARK_SPEED] * 3]
    assert parking and MODEL.link_silence_timeout <= parking[0].start - t_last <= MODEL.link_silence_timeout + 0.03


def test_a_repeated_set_position_leaves_the_last_refusal_standing():
    """A keep-alive (the set position in force again) is no new command: the heartbeat still
    says why the last one was refused; a new set position is a command taken."""
    board, inv = parked()
    board.send("jog", joint=4, mode=0, value=0.0)
    keep_alive(inv, 1.2)
    assert refusal(board) == "bad_jog"
    board.send("set_position", x=60.0, y=20.0, z=-120.0)
    after_heartbeat(inv)
    assert refusal(board) == "none"
