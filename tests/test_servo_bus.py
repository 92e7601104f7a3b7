"""The servo-bus driver (firmware_stm32/App/Src/servo_bus.c), seen on the bus of a simulated
board: power switching, boot wait, configuration, the per-tick traffic, and faults.

Everything is observed as the hardware would: the instruction packets the board sends
(checked against the AX-12A e-manual's framing and rebuilt with the official DynamixelSDK), the
simulated AX-12A servos' registers, and the heartbeat frames on the link. Counters the
heartbeat does not carry are read from the driver's state for the per-servo detail.
"""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from simboard_tools import (
    FAULT, IDS, INST_READ, INST_SYNC_WRITE, INST_WRITE, MODEL, PARK_SPEED, PARK_UNITS, TICK,
    UNIT_RANGE, BusLog, heartbeat_showing, make_board, run_until, run_to_next_heartbeat, ready, running, sdk_rebuild,
    servo_c, sync_goal_speed,
)
from test_fault_injection import ReplyTap, with_error
from uavarm.sim.board import baud_register

# AX-12A e-manual control table
ADDR = {"return_delay_time": 5, "cw_angle_limit": 6, "temperature_limit": 11, "status_return_level": 16,
        "shutdown": 18, "torque_enable": 24, "goal_position": 30, "moving_speed": 32, "torque_limit": 34, "present_position": 36,
        "present_temperature": 43}
OVERLOAD = 0x20
OVERHEATING_BIT = 2                       # AX-12A status error byte
RETURN_DELAY = MODEL.servo_return_delay_us // 2


def le16(v: int) -> bytes:
    return int(v).to_bytes(2, "little")


def wanted_registers(j: int) -> set[tuple[int, bytes]]:
    """(address, data) of what the servo of joint j must hold once configured: Status Return
    Level 1, Return Delay Time, angle limits = the joint limits, Torque Enable, Torque Limit one
    below Max Torque (1022: a servo whose RAM reset has it back at Max Torque, told apart by
    the running reads), and the AX-12A's factory safety values (e-manual: Highest Limit
    Temperature 70 deg C, voltage 6.0-14.0 V, Max Torque 1023, Alarm Shutdown 0x24)."""
    cw, ccw = UNIT_RANGE[j]
    return {
        (ADDR["status_return_level"], bytes([1])),
        (ADDR["return_delay_time"], bytes([RETURN_DELAY])),
        (ADDR["cw_angle_limit"], le16(cw) + le16(ccw)),
        (ADDR["temperature_limit"], bytes([70, 60, 140]) + le16(1023)),
        (ADDR["shutdown"], bytes([0x24])),
        (ADDR["torque_limit"], le16(1022)),
        (ADDR["torque_enable"], bytes([1])),
    }


def expected_config_writes(j: int, table: bytes) -> set[tuple[int, bytes]]:
    """The wanted registers that the servo's table (as it was before enable) does not hold:
    nothing else is written (the EEPROM wears)."""
    return {(a, d) for a, d in wanted_registers(j) if table[a:a + len(d)] != d}


def enabled_board(**kw):
    board = make_board(**kw)
    log = BusLog(board)
    board.send("enable", on=1)
    assert run_until(board, lambda: ready(board), 1.0) is not None
    return board, log


# ---------------------------------------------------------------- enable and configuration

def test_power_on_boot_wait_and_configuration():
    board = make_board(at=[512, 512, 512])   # factory-fresh RAM: SRL 2, return delay 500 us
    log = BusLog(board)
    before = [bytes(board.bus.servo(i).table) for i in IDS]
    board.run(0.05)
    assert not board.servo_power and not log.tx, "nothing before enable"
    t_enable = board.time
    board.send("enable", on=1)
    board.run(0.25)

    (t_on, on), = board.power_log
    assert on and t_on - t_enable <= 2 * board.poll_us / 1e6
    assert log.tx, "nothing sent"
    first = log.tx[0].start
    print(f"\npower on at {t_on * 1e3:.1f} ms, first byte {(first - t_on) * 1e3:.2f} ms later "
          f"(boot time {MODEL.servo_boot_time * 1e3:.0f} ms)")
    assert first - t_on >= MODEL.servo_boot_time - 1e-9

    # configuration: every packet before the first SYNC_WRITE, servo by servo in joint order
    n_cfg = next(k for k, p in enumerate(log.tx) if p.inst == INST_SYNC_WRITE)
    cfg = log.tx[:n_cfg]
    per_servo = [[p for p in cfg if p.id == id_] for id_ in IDS]
    assert [p.id for p in cfg] == [p.id for group in per_servo for p in group], "servos interleaved"
    for j, group in enumerate(per_servo):
        writes = [p for p in group if p.inst == INST_WRITE]
        assert {(p.params[0], p.params[1:]) for p in writes} == expected_config_writes(j, before[j])
        assert len(writes) == len(expected_config_writes(j, before[j]))
        first, read = group[0], group[-1]
        assert first.inst == INST_READ and read.inst == INST_READ and len(group) == len(writes) + 2, \
            "what the servo holds read first, the writes, one read-back"
        for pkt in (first, read):
            addr, n = pkt.params
            assert addr <= 5 and addr + n >= 44, "the reads cover every register written and the status"
    print(f"configuration: {len(cfg)} packets, {sum(len(p.raw) for p in cfg)} bytes, "
          f"{(cfg[-1].end - cfg[0].start) * 1e3:.2f} ms")

    for j, id_ in enumerate(IDS):
        table = board.bus.servo(id_).table
        assert all(table[a:a + len(d)] == d for a, d in wanted_registers(j))
    # the servos' own verdict: no instruction since the configuration gave an error
    assert all(p.raw[4] == 0 for p in log.replies), [p.raw.hex(" ") for p in log.replies if p.raw[4]]
    # factory-fresh (Status Return Level 2) they answered every WRITE too, with no parameter:
    # each reply taken as the answer to its request (none stray), none counted as bad or missing
    assert any(r.raw[3] == 2 for r in log.replies), "the writes were answered"
    assert board.app.bus.stray_packets == 0
    for j in range(3):
        s = servo_c(board, j)
        assert (s.timeouts, s.retries, s.bad_packets, s.error_packets) == (0, 0, 0, 0), j


def test_every_packet_is_what_the_official_sdk_builds():
    board = make_board(at=[512, 512, 512])
    log = BusLog(board)
    board.send("enable", on=1)
    board.run(0.3)
    board.send("engage", on=1)
    board.run(0.2)
    assert {p.inst for p in log.tx} == {INST_WRITE, INST_READ, INST_SYNC_WRITE}
    for p in log.tx:
        assert p.raw == sdk_rebuild(p.raw), p.raw.hex(" ")
    # the whole byte stream is these packets and nothing else
    assert bytes(board.servo_tx) == b"".join(p.raw for p in log.tx)


def test_a_command_beyond_the_registers_ranges_is_held_back():
    """Goal Position takes 0..1023 and Moving Speed 0..2047 (the e-manual's control table):
    the driver sends no SYNC_WRITE with a value beyond, and the next command replaces it."""
    board, log = enabled_board()
    ffi, lib, bus = board.ffi, board.lib, board.app.bus
    # between ticks, with the bus idle: the driver's own polls, no tick to queue a command
    assert run_until(board, lambda: bus.phase == 0 and not bus.command_pending and not bus.read_due,
                     0.1) is not None
    p = ffi.addressof(board.app, "bus")
    u16 = lambda v: ffi.new("uint16_t[3]", v)
    sends = board.hp.servo_sends
    for goal, speed in [([1024, 0, 0], [0, 0, 0]), ([0, 0, 0], [0, 2048, 0]), ([0, 0, 0xFFFF], [0, 0, 0])]:
        lib.sbus_command(p, u16(goal), u16(speed))
        lib.sbus_poll(p)
        assert board.hp.servo_sends == sends and bus.command_pending
    lib.sbus_command(p, u16([1023, 0, 512]), u16([2047, 0, 1]))
    lib.sbus_poll(p)
    assert board.hp.servo_sends == sends + 1 and not bus.command_pending
    board.run(0.001)   # the packet onto the simulated bus
    sync = next(s for s in log.syncs() if sync_goal_speed(s.raw)[0] == [1023, 0, 512])
    assert sync_goal_speed(sync.raw)[1] == [2047, 0, 1] and sync.raw == sdk_rebuild(sync.raw)


def test_disable_stops_all_traffic_and_reenable_configures_again():
    board, log = enabled_board()
    board.run(0.1)
    board.send("enable", on=0)
    t_off = board.time
    board.run(0.3)
    assert board.power_log[-1][1] is False and board.power_log[-1][0] - t_off <= TICK
    # bytes may still be on the wire from before the cut, none start after it
    assert not [p for p in log.tx if p.start > board.power_log[-1][0]]
    n = len(log.tx)
    eeprom_before = [servo_c(board, j).eeprom_writes for j in range(3)]
    assert all(eeprom_before), "the first enable wrote the EEPROM (factory values differ)"
    board.send("enable", on=1)
    board.run(0.2)
    t_on = board.power_log[-1][0]
    again = log.tx[n:]
    assert again[0].start - t_on >= MODEL.servo_boot_time - 1e-9
    # the EEPROM holds the configuration already: read, the RAM's Torque Limit and Torque
    # Enable again (power-up reset them), read back
    assert [(p.inst, p.params[0]) for p in again[:4]] == [(INST_READ, 5), (INST_WRITE, ADDR["torque_limit"]),
                                                          (INST_WRITE, ADDR["torque_enable"]), (INST_READ, 5)]
    assert [servo_c(board, j).eeprom_writes for j in range(3)] == eeprom_before, "no EEPROM written again"


# ---------------------------------------------------------------- running traffic

def test_each_tick_one_sync_write_and_one_round_robin_read():
    board, log = enabled_board()
    t0 = board.time + TICK
    board.run(0.33)
    ticks: dict[int, list] = {}
    for p in log.tx:
        if p.start >= t0 and p.start < board.time - TICK:
            ticks.setdefault(int(p.start / TICK + 1e-6), []).append(p)
    assert len(ticks) >= 30
    read_ids = []
    stats = []
    for k, pkts in sorted(ticks.items()):
        assert [p.inst for p in pkts] == [INST_SYNC_WRITE, INST_READ], [p.raw.hex(" ") for p in pkts]
        sync, read = pkts
        assert sync.id == 0xFE
        goal, speed = sync_goal_speed(sync.raw)
        assert goal == [round(u) for u in PARK_UNITS] and speed == [PARK_SPEED] * 3
        # Moving Speed .. Present Temperature: a servo reset by a supply dip shows Torque
        # Limit back at Max Torque
        assert read.params == bytes([ADDR["moving_speed"], ADDR["present_temperature"] + 1 - ADDR["moving_speed"]])
        read_ids.append(read.id)
        replies = [r for r in log.replies if sync.start <= r.start < (k + 1) * TICK]
        assert len(replies) == 1 and replies[0].raw[2] == read.id and replies[0].raw[3] == 12 + 2
        reply = replies[0]
        stats.append((len(sync.raw) + len(read.raw), len(reply.raw), (reply.end - sync.start) * 1e6))
    first = IDS.index(read_ids[0])
    assert read_ids == [IDS[(first + k) % 3] for k in range(len(read_ids))]
    tx_b, rx_b, bus_us = stats[0]
    worst = max(s[2] for s in stats)
    # the driver's own worst case (a read that times out) bounds what the bus saw, and fits a tick
    bound = board.lib.sbus_tick_bus_time_us(board.ffi.addressof(board.app, "bus"))
    print(f"\nper tick: {tx_b} bytes out + {rx_b} bytes back = {tx_b + rx_b} bytes at "
          f"{MODEL.servo_baud} baud, {bus_us:.0f} us of bus time (worst {worst:.0f} us, "
          f"driver's bound {bound} us) of a {TICK * 1e6:.0f} us tick")
    assert worst <= bound < TICK * 1e6
    # the driver's count of SYNC_WRITEs (what `make bench` divides by) is the wire's
    assert board.app.bus.sync_writes == len(log.syncs())
    # every read answered: the driver counts nothing wrong
    for j in range(3):
        s = servo_c(board, j)
        assert (s.timeouts, s.retries, s.bad_packets, s.error_packets) == (0, 0, 0, 0)
        assert s.status_valid and not s.failed


# ---------------------------------------------------------------- faults

def silence(board, id_, how):
    """Make a servo stop answering: unplugged, or its Baud Rate register wrong."""
    s = board.bus.servo(id_)
    if how == "unplugged":
        board.bus.servos.remove(s)
    else:
        s.set_register("baud_rate", baud_register(MODEL.servo_baud) + 10)
    return s


def restore(board, s, how):
    if how == "unplugged":
        board.bus.add(s)
    else:
        s.set_register("baud_rate", baud_register(MODEL.servo_baud))


@pytest.mark.parametrize("how", ["unplugged", "wrong_baud"])
def test_silent_servo_times_out_is_retried_and_recovers(how):
    board, log = enabled_board()
    board.run(0.05)
    j, id_ = 1, IDS[1]
    before = (servo_c(board, j).timeouts, servo_c(board, j).retries)
    t_fault = board.time
    s = silence(board, id_, how)
    hb = heartbeat_showing(board, lambda hb: hb["faults"] & FAULT["servo_timeout"], 0.5)
    assert hb["servo_timeouts"] > 0
    c = servo_c(board, j)
    assert c.timeouts > before[0] and c.retries > before[1] and c.failed
    reads = [p.id for p in log.reads(t_fault)]
    # the silent servo is asked again (a retry) before the round robin moves on
    assert any(a == b == id_ for a, b in zip(reads, reads[1:])), reads
    # the others keep being read and answering
    for other in (IDS[0], IDS[2]):
        assert [r for r in log.replies if r.start > t_fault and r.raw[2] == other]
        assert not servo_c(board, IDS.index(other)).failed
    assert not [r for r in log.replies if r.start > t_fault + 0.002 and r.raw[2] == id_]

    restore(board, s, how)
    t_back = board.time
    hb = heartbeat_showing(board, lambda hb: not hb["faults"] & FAULT["servo_timeout"], 0.5)
    assert not servo_c(board, j).failed
    assert [r for r in log.replies if r.start > t_back and r.raw[2] == id_]
    # the total only grows
    assert hb["servo_timeouts"] >= board.heartbeats[-2]["servo_timeouts"]


@pytest.mark.parametrize("how", ["unplugged", "overheating"])
@pytest.mark.parametrize("j", [0, 2])
def test_what_a_servo_reported_is_forgotten_with_the_power(j, how):
    """What the driver knew of a servo's live state goes with the servos' supply: a servo
    that stopped answering shows servo_timeout, one that reports overheating shows
    servo_error and its error byte; after disable (power off) the heartbeat no longer
    claims either, and no servo's reading counts as current."""
    board, log = enabled_board()
    board.run(0.05)
    if how == "unplugged":
        silence(board, IDS[j], how)
    else:
        ReplyTap(board).faults[IDS[j]] = with_error(OVERHEATING_BIT)
    fault = FAULT["servo_timeout"] if how == "unplugged" else FAULT["servo_error"]
    hb = run_to_next_heartbeat(board)
    assert hb["faults"] & fault, hb
    board.send("enable", on=0)
    hb = run_to_next_heartbeat(board)
    assert hb["enabled"] == 0 and not hb["faults"] & fault and hb[f"servo{j + 1}_error"] == 0, hb
    assert not any(servo_c(board, k).status_valid or servo_c(board, k).failed for k in range(3))


def test_a_command_queued_when_the_power_is_cut_is_not_sent_when_it_returns():
    """The driver holds a command (goals and speeds) at the moment the servos' supply is
    cut: after the power comes back and the servos are set up again, those stale goals are
    never sent (the arm may have been moved by hand meanwhile); the first goals come from
    where it now stands."""
    board, log = enabled_board()
    board.run(0.1)
    bus = board.ffi.addressof(board.app, "bus")
    stale = [round(PARK_UNITS[0]) + 100, round(PARK_UNITS[1]), round(PARK_UNITS[2])]
    board.lib.sbus_command(bus, stale, [PARK_SPEED] * 3)
    board.lib.sbus_power(bus, False)
    board.send("enable", on=0)
    board.run(0.1)
    t_on = board.time
    board.send("enable", on=1)
    assert run_until(board, lambda: log.syncs(t_on), 1.0) is not None
    board.run(0.1)
    goals = [sync_goal_speed(p.raw)[0] for p in log.syncs(t_on)]
    assert stale not in goals and goals[0] == [round(u) for u in PARK_UNITS]


def test_servo_silent_during_configuration_cuts_power_and_latches():
    board = make_board()
    log = BusLog(board)
    s = silence(board, IDS[2], "wrong_baud")
    board.send("enable", on=1)
    board.run(0.3)
    assert [on for _, on in board.power_log] == [True, False]
    t_off = board.power_log[-1][0]
    verify_reads = [p for p in log.reads() if p.id == IDS[2]]
    assert len(verify_reads) == 6, "three configuration attempts, each a read before and a read back"
    assert not log.syncs(), "no command to an unconfigured bus"
    assert not [p for p in log.tx if p.start > t_off]
    print(f"\nconfiguration given up {(t_off - board.power_log[0][0]) * 1e3:.1f} ms after power on")
    hb = run_to_next_heartbeat(board)
    assert hb["enabled"] == 0 and hb["engaged"] == 0
    assert hb["faults"] & FAULT["servo_config"], hb
    board.send("engage", on=1)            # refused: not enabled
    hb = run_to_next_heartbeat(board)
    assert hb["engaged"] == 0 and hb["faults"] & FAULT["servo_config"]

    # a new enable retries: still silent -> fails again
    board.send("enable", on=1)
    board.run(0.3)
    assert [on for _, on in board.power_log] == [True, False, True, False]
    # answering again -> configured
    restore(board, s, "wrong_baud")
    board.send("enable", on=1)
    assert run_until(board, lambda: running(board), 0.3) is not None
    hb = run_to_next_heartbeat(board)
    assert hb["enabled"] == 1 and not hb["faults"] & FAULT["servo_config"], hb
    assert s.register("torque_enable") == 1


def test_overload_is_reported_in_the_heartbeat():
    board, log = enabled_board()
    board.run(0.05)
    j = 1
    board.bus.servo(IDS[j]).overload = True
    hb = run_to_next_heartbeat(board)
    assert hb["servo2_error"] == OVERLOAD and hb["servo1_error"] == hb["servo3_error"] == 0
    assert hb["faults"] & FAULT["servo_error"], hb
    assert not hb["faults"] & FAULT["servo_timeout"]
    c = servo_c(board, j)
    assert c.error_packets > 0 and c.error_bits[5] == c.error_packets
    # the servo's own Shutdown cut its torque (e-manual: Shutdown 0x24 includes overload)
    assert board.bus.servo(IDS[j]).register("torque_limit") == 0

    board.bus.servo(IDS[j]).overload = False
    hb = run_to_next_heartbeat(board)
    assert hb["servo2_error"] == 0 and not hb["faults"] & FAULT["servo_error"], hb
    # a new enable writes Torque Limit back
    board.send("enable", on=0)
    board.run(0.02)
    board.send("enable", on=1)
    assert run_until(board, lambda: running(board), 0.3) is not None
    assert board.bus.servo(IDS[j]).register("torque_limit") == 1023


def test_bus_echo_is_ignored():
    board, log = enabled_board(bus_echo=True)
    board.send("set_position", x=70.0, y=-20.0, z=-95.0)
    board.send("engage", on=1)
    board.run(0.6)
    hb = board.heartbeats[-1]
    assert hb["enabled"] == 1 and hb["engaged"] == 1 and hb["faults"] == 0, hb
    for j in range(3):
        c = servo_c(board, j)
        assert (c.timeouts, c.bad_packets, c.error_packets, c.last_error) == (0, 0, 0, 0)
        assert c.status_valid
    assert board.app.bus.stray_packets > 0, "the echo was there to be ignored"
    goal, _ = sync_goal_speed(log.syncs()[-1].raw)
    # there, within the compliance margin (a unit) at which a lagging shaft stops
    assert all(abs(board.bus.servo(i).position - g) <= 1.0 for i, g in zip(IDS, goal))


# A parameter byte changed (the checksum no longer fits), or the checksum byte itself off by
# one either way or by its top bit: Protocol 1.0's checksum, ~(ID + LEN + ERR + params), no
# longer matches in any of them.
CORRUPTIONS = {"parameter": (5, lambda b: b ^ 0x40), "checksum + 1": (-1, lambda b: (b + 1) & 0xFF),
               "checksum - 1": (-1, lambda b: (b - 1) & 0xFF), "checksum top bit": (-1, lambda b: b ^ 0x80)}


@pytest.mark.parametrize("how", CORRUPTIONS)
def test_corrupted_replies_are_counted_and_survived(how):
    board, log = enabled_board()
    bus = board.bus
    send_reply = bus._send_reply
    corrupted = []
    where, change = CORRUPTIONS[how]

    def corrupt(start, data):
        if data[2] == IDS[0] and len(corrupted) < 4:
            data = bytearray(data)
            data[where] = change(data[where])
            corrupted.append(bytes(data))
        return send_reply(start, bytes(data))

    bus._send_reply = corrupt
    board.run(0.3)
    c = servo_c(board, 0)
    assert len(corrupted) == 4 and c.bad_packets == 4
    assert c.error_packets == 0, "a corrupted packet is not a servo error"
    assert c.status_valid and not c.failed, "read again and answered"
    assert servo_c(board, 1).bad_packets == servo_c(board, 2).bad_packets == 0


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.randoms(use_true_random=False),
       st.lists(st.binary(min_size=1, max_size=40), min_size=1, max_size=12))
def test_garbage_on_the_bus_is_survived(rnd, chunks):
    board, log = enabled_board()
    lib = board.lib
    for chunk in chunks:
        board.run(rnd.uniform(0.0, 0.02))
        if rnd.random() < 0.5:
            chunk = b"\xff\xff" + chunk      # a plausible header
        lib.host_port_servo_push(board.hp, chunk, len(chunk))
    n = len(log.syncs())
    board.run(0.1)
    assert len(log.syncs()) >= n + 9, "still one SYNC_WRITE per tick"
    assert board.servo_power
    # after the garbage, every servo is read and answers
    t = board.time
    board.run(0.05)
    for j in range(3):
        assert servo_c(board, j).status_valid and not servo_c(board, j).failed
    assert {r.raw[2] for r in log.replies if r.start > t} == set(IDS)


def test_garbage_reply_counts_a_bad_packet():
    board, log = enabled_board()
    total = lambda: sum(servo_c(board, j).bad_packets for j in range(3))
    before = total()
    n = len(log.reads())
    while len(log.reads()) == n:
        board.step(10)
    read = log.reads()[-1]
    while board.time < read.end:
        board.step(10)
    # a status-shaped packet from the servo being read, with a wrong checksum, just before
    # the servo's own answer
    bad = bytes([0xFF, 0xFF, read.id, 10, 0]) + bytes(8) + b"\x00"
    board.lib.host_port_servo_push(board.hp, bad, len(bad))
    board.run(0.05)
    assert total() == before + 1
    j = IDS.index(read.id)
    assert servo_c(board, j).bad_packets == 1 and servo_c(board, j).timeouts == 0, \
        "the real answer behind it still counts"
