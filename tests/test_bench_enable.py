"""The bench enable (enable 2) on the simulated board: the servos powered and configured with
the torque off, for calibrating their zeros and directions, and never driven by the model's
(untrusted) calibration on the firmware's own initiative. The servos here rest where the
model's zero 512 and direction +1 do not put the park pose: joint 1 at 300 units, joint 2 at
700, joint 3 at 512, as a servo mounted offset or reversed would.

Oracles: the simulated servos' own shafts (their positions at every physics step) and
registers, the SYNC_WRITEs and WRITEs on the bus (Protocol 1.0 framing, each WRITE rebuilt by
the official DynamixelSDK), the AX-12A control table (Torque Enable at 24, Torque Limit at
34..35, whose 1023 is the maximum torque), a board enabled the ordinary way for the registers
configured, and the message table's states, refusals and fault bits.
"""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from simboard_tools import (FAULT, MODEL, PARK_UNITS, BusLog, make_board, run_until, sdk_rebuild, shaft_units,
                            sync_goal_speed)
from uavarm.link import ArmLink, CommandRefused, messages, shell
from uavarm.link.client import RestartWatch
from uavarm.sim.sitl import Sitl

TRUTH = [300, 700, 512]          # where the shafts rest (units)
TORQUE_ENABLE = 24
HB_S = MODEL.heartbeat_period
BENCH = 2                        # enable's value, and the heartbeat's enabled, for the bench
TORQUE_LIMIT = 34
FULL_LIMIT = 1022                # configured outside the bench: one below Max Torque (1023)
BENCH_LIMIT = round(MODEL.servo_bench_torque_limit * 1023)   # the model's share of the maximum


def state(board) -> str:
    return messages.STATES[board.heartbeats[-1]["state"]][0]


def refusal(board) -> str:
    return messages.REFUSALS[board.heartbeats[-1]["refusal"]][0]


def after_heartbeats(board, n=2) -> dict:
    """Runs until n more heartbeats came (the first may predate a command); the last."""
    start = len(board.heartbeats)
    assert run_until(board, lambda: len(board.heartbeats) >= start + n, n * HB_S + 0.05) is not None
    return board.heartbeats[-1]


def keep_alive(board, seconds):
    """Runs `seconds` repeating the set position every 0.2 s, as the link client does."""
    end = board.time + seconds
    while board.time < end - 1e-9:
        if board.heartbeats:
            hb = board.heartbeats[-1]
            board.send("set_position", x=hb["set_x"], y=hb["set_y"], z=hb["set_z"])
        board.run(min(0.2, end - board.time))


def bench(at=TRUTH):
    """A board whose shafts rest at `at`, bench-enabled and configured; its bus log."""
    board = make_board(at=at)
    log = BusLog(board)
    board.shaft_trace = []
    board.send("enable", on=BENCH)
    assert run_until(board, lambda: board.heartbeats and state(board) == "limp", 2.0) is not None
    return board, log


def torque_writes(log, since=-1.0):
    """(servo id, value) of every WRITE to Torque Enable after `since` (bus time)."""
    return [(p.id, p.params[1]) for p in log.tx if p.start >= since and p.inst == 0x03 and p.params[0] == TORQUE_ENABLE]


def torque_limit_writes(log, since=-1.0):
    """(bus time, servo id, value) of every WRITE that covers Torque Limit (34..35) after
    `since`, each checked against the same WRITE built by the DynamixelSDK."""
    out = []
    for p in log.tx:
        if p.start < since or p.inst != 0x03:
            continue
        addr, data = p.params[0], p.params[1:]
        if addr <= TORQUE_LIMIT and TORQUE_LIMIT + 1 < addr + len(data):
            assert p.raw == sdk_rebuild(p.raw), p.raw.hex(" ")
            k = TORQUE_LIMIT - addr
            out.append((p.start, p.id, data[k] | data[k + 1] << 8))
    return out


def torque_limits(board) -> list[int]:
    return [s.register("torque_limit") for s in board.bus.servos]


def shaft_span(board, since_us=0) -> np.ndarray:
    """How far each shaft moved (units, max - min) at the physics steps since `since_us`."""
    rows = np.array([r[2:] for r in board.shaft_trace if r[0] >= since_us], dtype=float)
    return rows.max(axis=0) - rows.min(axis=0)


def hold_then(board, log, jog_units=None):
    """Torque back on (holding where the arm stands), or a jog of joint 1 by jog_units from
    limp; kept alive until it holds there. The shafts then (units)."""
    if jog_units is None:
        board.send("torque", on=1)
    else:
        board.send("jog", joint=1, mode=1, value=float(jog_units))
    keep_alive(board, 1.5)
    assert state(board) == "jogged" and torque_enabled(board)
    return shaft_units(board)


def torque_enabled(board) -> bool:
    return all(s.register("torque_enable") == 1 for s in board.bus.servos)


def limp_from(board, log, since):
    """Limp since `since` (bus time): a broadcast Torque Enable 0, every servo's torque off,
    no SYNC_WRITE after it, the shafts still within a unit of where they were."""
    assert (0xFE, 0) in torque_writes(log, since)
    assert not any(s.register("torque_enable") for s in board.bus.servos)
    off_at = max(p.start for p in log.tx if p.inst == 0x03 and p.params[:2] == bytes([TORQUE_ENABLE, 0]))
    assert not log.syncs(off_at), "a goal sent after the torque went off"


# ---------------------------------------------------------------- the bench enable itself

def test_bench_enable_configures_the_servos_with_the_torque_off_and_moves_nothing():
    board, log = bench()
    keep_alive(board, 2.0)
    hb = after_heartbeats(board)
    assert board.servo_power and hb["enabled"] == BENCH and state(board) == "limp"
    assert not hb["faults"] & (FAULT["servo_config"] | FAULT["servo_timeout"] | FAULT["servo_error"])
    assert not log.syncs() and not board.commands, "no goal sent"
    assert all(v == 0 for _, v in torque_writes(log)), "the torque never switched on"
    assert not torque_enabled(board) and not any(s.register("torque_enable") for s in board.bus.servos)
    assert shaft_span(board).max() <= 1.0 and shaft_units(board) == pytest.approx(TRUTH, abs=1.0)
    # the registers configured as an ordinary enable configures them, Torque Enable aside
    plain = make_board(at=TRUTH)
    plain.send("enable", on=1)
    plain.run(1.0)
    for s_bench, s_plain in zip(board.bus.servos, plain.bus.servos):
        for name in ("return_delay_time", "cw_angle_limit", "ccw_angle_limit", "temperature_limit",
                     "min_voltage_limit", "max_voltage_limit", "max_torque", "status_return_level", "shutdown"):
            assert s_bench.register(name) == s_plain.register(name), name
        assert s_bench.register("status_return_level") == 1, "written (the factory's is 2)"
    # Torque Limit: the bench's share of the maximum torque, the ordinary enable's full one
    assert torque_limits(board) == [BENCH_LIMIT] * 3 and torque_limits(plain) == [FULL_LIMIT] * 3
    assert [s.register("cw_angle_limit") for s in board.bus.servos] != [0, 0, 0], "the joint limits written"
    # the reading where the shafts are (the service stream works)
    board.send("stream", imu_every=0, servos=1)
    keep_alive(board, 0.3)
    seen = {f["servo"]: f["position"] for f in board.streamed["servo_status"]}
    assert [seen[i] for i in range(3)] == [round(u) for u in TRUTH]


def test_engage_is_refused_on_the_bench_and_nothing_moves():
    board, log = bench()
    board.send("engage", on=1)
    hb = after_heartbeats(board)
    assert refusal(board) == "bench" and not hb["engaged"] and hb["faults"] & FAULT["command_refused"]
    keep_alive(board, 1.0)
    assert not log.syncs() and not torque_enabled(board) and shaft_span(board).max() <= 1.0


def test_silence_leaves_a_bench_arm_limp_and_flags_link_lost():
    board, log = bench()
    t0 = board.bus.time
    board.run(MODEL.link_silence_timeout + 2 * HB_S)       # nothing sent
    hb = after_heartbeats(board)
    assert hb["faults"] & FAULT["link_lost"] and hb["enabled"] == BENCH and state(board) == "limp"
    assert not log.syncs() and torque_writes(log, t0) == [] and shaft_span(board).max() <= 1.0
    # held where it stands, then silence again: limp, no goal toward the park pose
    held = hold_then(board, log)
    t1 = board.bus.time
    start_us = board.now_us
    board.run(MODEL.link_silence_timeout + 2 * HB_S)
    hb = after_heartbeats(board)
    assert hb["faults"] & FAULT["link_lost"] and state(board) == "limp"
    limp_from(board, log, t1)
    assert shaft_span(board, start_us).max() <= 1.0 and shaft_units(board) == pytest.approx(held, abs=1.0)


def test_a_drone_message_leaves_a_held_bench_arm_limp():
    board, log = bench()
    held = hold_then(board, log)
    assert held == pytest.approx(TRUTH, abs=1.0), "torque 1 holds where the arm stands"
    t0, start_us = board.bus.time, board.now_us
    board.send("drone_attitude", seq=0, stamp_us=0, roll=0.0, pitch=0.0)
    keep_alive(board, 1.0)
    assert state(board) == "limp" and board.heartbeats[-1]["enabled"] == BENCH
    limp_from(board, log, t0)
    assert shaft_span(board, start_us).max() <= 1.0


def test_disengage_from_a_jog_on_the_bench_goes_limp_where_the_arm_stands():
    board, log = bench()
    jogged = hold_then(board, log, jog_units=20)
    assert jogged == pytest.approx([TRUTH[0] + 20, TRUTH[1], TRUTH[2]], abs=1.0)
    # the jog's goals: from where the arm stood to the jogged pose, never toward the park pose
    goals = np.array([sync_goal_speed(p.raw)[0] for p in log.syncs()], dtype=float)
    assert (goals[:, 0] >= TRUTH[0] - 1).all() and (goals[:, 0] <= TRUTH[0] + 21).all()
    assert (np.abs(goals[:, 1:] - TRUTH[1:]) <= 1).all()
    t0, start_us = board.bus.time, board.now_us
    board.send("engage", on=0)
    keep_alive(board, 1.0)
    assert state(board) == "limp"
    limp_from(board, log, t0)
    assert shaft_span(board, start_us).max() <= 1.0


def test_a_servo_reset_on_the_bench_leaves_the_arm_limp():
    """A held bench arm whose joint-3 servo browns out (RAM reset, torque off): the whole arm
    goes limp, flagged servo_reset, no goal toward the park pose."""
    board, log = bench()
    held = hold_then(board, log)
    servo = board.bus.servos[2]
    servo.power_off()
    servo.power_on()                                  # RAM back to its power-on values
    t0, start_us = board.bus.time, board.now_us
    keep_alive(board, 1.0)
    hb = after_heartbeats(board)
    assert hb["faults"] & FAULT["servo_reset"] and state(board) == "limp" and hb["enabled"] == BENCH
    limp_from(board, log, t0)
    assert shaft_span(board, start_us).max() <= 1.0 and shaft_units(board) == pytest.approx(held, abs=1.0)


# ---------------------------------------------------------------- the bench's Torque Limit

def test_the_bench_writes_its_torque_limit_to_every_servo_and_moves_with_it():
    """enable 2 writes Torque Limit = servo.bench_torque_limit x 1023 to each servo, and
    nothing else there; torque 1 and a jog set the servos up with it again."""
    assert 0.1 <= MODEL.servo_bench_torque_limit < 1.0 and BENCH_LIMIT < 1023
    board, log = bench()
    writes = torque_limit_writes(log)
    assert {i for _, i, _ in writes} == {s.id for s in MODEL.servos}
    assert {v for _, _, v in writes} == {BENCH_LIMIT} and torque_limits(board) == [BENCH_LIMIT] * 3
    t0 = board.bus.time
    hold_then(board, log)
    held = torque_limit_writes(log, t0)
    assert {i for _, i, _ in held} == {s.id for s in MODEL.servos} and {v for _, _, v in held} == {BENCH_LIMIT}
    assert torque_limits(board) == [BENCH_LIMIT] * 3
    t1 = board.bus.time
    board.send("jog", joint=1, mode=1, value=10.0)
    keep_alive(board, 1.0)
    assert state(board) == "jogged" and torque_limits(board) == [BENCH_LIMIT] * 3
    assert log.syncs(t1) and all(v == BENCH_LIMIT for _, _, v in torque_limit_writes(log, t1))


@pytest.mark.parametrize("held", [False, True], ids=["limp", "held"])
def test_enable_1_from_the_bench_writes_the_full_torque_limit_before_the_first_goal(held):
    board, log = bench()
    if held:
        hold_then(board, log)
    assert torque_limits(board) == [BENCH_LIMIT] * 3
    t0 = board.bus.time
    held_goal = sync_goal_speed(log.syncs()[-1].raw)[0] if held else None
    board.send("enable", on=1)
    keep_alive(board, 6.0)
    assert state(board) == "parked" and board.heartbeats[-1]["enabled"] == 1
    assert shaft_units(board) == pytest.approx(PARK_UNITS, abs=2.0)
    assert torque_limits(board) == [FULL_LIMIT] * 3
    writes = torque_limit_writes(log, t0)
    assert all(v == FULL_LIMIT for _, _, v in writes), "no bench limit written after enable 1"
    assert {i for _, i, _ in writes} == {s.id for s in MODEL.servos}
    full_at = max(t for t, _, _ in writes)            # every servo has its full Torque Limit
    # before that only the held pose's goals (a held arm's ticks until the frame is taken),
    # then the goals toward the park pose
    before = [sync_goal_speed(p.raw)[0] for p in log.syncs(t0) if p.start < full_at]
    assert all(g == held_goal for g in before), "a goal sent before the full Torque Limit"
    after = [sync_goal_speed(p.raw)[0] for p in log.syncs(full_at)]
    assert after and after[-1] == pytest.approx(PARK_UNITS, abs=1.0), "parked by goals after it"


@pytest.mark.parametrize("held", [False, True], ids=["limp", "held"])
def test_a_servo_reset_on_the_bench_is_set_up_again_with_the_bench_limit(held):
    """Joint 3's servo browns out on the bench (its Torque Limit back at Max Torque, 1023).
    Held, it is found (servo_reset, servo_resets counted) and the arm goes limp; limp, its
    torque is off anyway. Either way, torque 1 sets it up with the bench's limit, not more."""
    board, log = bench()
    if held:
        hold_then(board, log)
    resets = board.heartbeats[-1]["servo_resets"]
    servo = board.bus.servos[2]
    servo.power_off()
    servo.power_on()
    assert servo.register("torque_limit") == 1023
    keep_alive(board, 1.0)
    hb = after_heartbeats(board)
    assert state(board) == "limp"
    if held:
        assert hb["faults"] & FAULT["servo_reset"] and hb["servo_resets"] == resets + 1
    t0 = board.bus.time
    hold_then(board, log)
    assert torque_limits(board) == [BENCH_LIMIT] * 3
    assert servo.id in {i for _, i, v in torque_limit_writes(log, t0) if v == BENCH_LIMIT}
    assert all(v == BENCH_LIMIT for _, _, v in torque_limit_writes(log, t0))


@pytest.mark.parametrize("enabled", [BENCH, 1], ids=["bench", "enable 1"])
def test_torque_1_while_a_reset_servo_is_being_read_holds_without_a_reset_found(enabled):
    """A servo that browned out while limp comes back set up by torque 1, whose refit writes
    every servo: the status READ of it that was on the wire as torque 1 came (asked for while
    limp, answering Torque Limit 1023) is no reset found, and the arm holds."""
    if enabled == BENCH:
        board, log = bench()
    else:
        board = make_board(at=TRUTH)
        log = BusLog(board)
        board.send("enable", on=1)
        keep_alive(board, 6.0)
        board.send("torque", on=0)
        keep_alive(board, 2 * HB_S)
    assert state(board) == "limp"
    servo = board.bus.servos[2]
    servo.power_off()
    servo.power_on()
    keep_alive(board, 0.5)
    resets = board.heartbeats[-1]["servo_resets"]
    n = len(log.tx)
    while not (len(log.tx) > n and log.tx[-1].inst == 0x02 and log.tx[-1].id == servo.id):
        board.step(board.poll_us)                    # until the READ of the reset servo is sent
    assert board.bus.time < log.tx[-1].end + 0.0005, "its reply still to come"
    board.send("torque", on=1)
    keep_alive(board, 1.0)
    hb = after_heartbeats(board, 1)
    assert state(board) == "jogged" and torque_enabled(board)
    assert not hb["faults"] & FAULT["servo_reset"] and hb["servo_resets"] == resets
    assert torque_limits(board) == [BENCH_LIMIT if enabled == BENCH else FULL_LIMIT] * 3


def test_enable_1_while_the_bench_still_starts_configures_the_servos_again_and_parks():
    board = make_board(at=TRUTH)
    board.send("enable", on=BENCH)
    board.run(0.05)                                   # the servos still booting
    board.send("enable", on=1)
    keep_alive(board, 6.0)
    assert state(board) == "parked" and board.heartbeats[-1]["enabled"] == 1 and torque_enabled(board)
    assert shaft_units(board) == pytest.approx(PARK_UNITS, abs=2.0)


def test_the_bench_is_refused_while_the_drone_flies():
    board = make_board(at=TRUTH)
    board.send("drone_attitude", seq=0, stamp_us=0, roll=0.0, pitch=0.0)
    board.run(0.1)
    board.send("enable", on=BENCH)
    hb = after_heartbeats(board)
    assert refusal(board) == "flying" and hb["enabled"] == 0 and not board.servo_power


def test_enable_1_ends_the_bench_and_parks_and_enable_0_cuts_the_supply():
    board, log = bench()
    keep_alive(board, 0.5)
    board.send("enable", on=1)
    keep_alive(board, 6.0)
    hb = after_heartbeats(board)
    assert hb["enabled"] == 1 and state(board) == "parked"
    assert shaft_units(board) == pytest.approx(PARK_UNITS, abs=2.0)
    board.send("engage", on=1)
    keep_alive(board, 0.5)
    assert board.heartbeats[-1]["engaged"]
    board.send("enable", on=0)
    board.run(0.1)
    assert not board.servo_power and after_heartbeats(board)["enabled"] == 0


def test_enable_1_parks_a_held_bench_arm_too():
    board, log = bench()
    hold_then(board, log)
    board.send("enable", on=1)
    keep_alive(board, 6.0)
    assert state(board) == "parked" and board.heartbeats[-1]["enabled"] == 1
    assert shaft_units(board) == pytest.approx(PARK_UNITS, abs=2.0)


def test_the_bench_is_refused_while_engaged():
    board = make_board()
    board.send("enable", on=1)
    keep_alive(board, 1.5)
    board.send("engage", on=1)
    keep_alive(board, 0.5)
    board.send("enable", on=BENCH)
    hb = after_heartbeats(board)
    assert refusal(board) == "engaged" and hb["engaged"] and hb["enabled"] == 1


# ---------------------------------------------------------------- the drone side

def test_the_shell_reads_enable_limp():
    assert shell.parse("enable limp") == ("enable limp", [])
    assert shell.parse("enable") == ("enable", [])
    with pytest.raises(shell.ShellError):
        shell.parse("enable stiff")


def test_a_bench_board_that_restarted_is_enabled_limp_again():
    watchdog = [name for name, _ in messages.RESET_CAUSES].index("watchdog")
    hb = lambda uptime, enabled: {"uptime_ms": uptime, "enabled": enabled, "engaged": 0, "reset_cause": watchdog,
                                  "last_fault": 0}
    for enabled, again in ((BENCH, BENCH), (1, 1)):
        watch = RestartWatch()
        assert watch.check(hb(5000, enabled)) is None
        assert "restarted while enabled" in watch.check(hb(100, 0))
        assert watch.enabled_as == again
        assert ("limp again" in watch.reenabled()) == (again == BENCH)


@pytest.mark.realtime
def test_the_command_line_bench_enables_a_sitl_limp_and_it_stays_limp_once_silent():
    s = Sitl(speed=2.0)
    for servo, units in zip(s.board.bus.servos, TRUTH):
        servo.turn_by_hand(units)
    s.board.shaft_trace = []
    s.start()
    run = lambda *a: subprocess.run([sys.executable, "-m", "uavarm.cli", "link", s.device, *a],
                                    capture_output=True, text=True, timeout=60)
    try:
        out = run("enable", "--limp")
        assert out.returncode == 0, out.stderr
        assert " limp (bench: enabled limp)" in out.stdout and "enabled 2 " in out.stdout
        with ArmLink(s.device, clock=s.clock) as arm:
            end = s.clock() + MODEL.link_silence_timeout + 1.0      # the link silent since the command
            while s.clock() < end:
                hb = arm.next_heartbeat()
            assert hb["enabled"] == BENCH and messages.STATES[hb["state"]][0] == "limp"
            assert hb["faults"] & FAULT["link_lost"]
            with pytest.raises(CommandRefused, match="enabled limp for calibration"):
                arm.engage()
        assert s.board.servo_power and not any(sv.register("torque_enable") for sv in s.board.bus.servos)
        assert shaft_span(s.board).max() <= 1.0 and shaft_units(s.board) == pytest.approx(TRUTH, abs=1.0)
        out = run("disable")
        assert out.returncode == 0 and "enabled 0 " in out.stdout and not s.board.servo_power
    finally:
        s.stop()
