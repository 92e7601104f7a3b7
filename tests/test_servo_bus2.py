"""The X-series servo-bus driver (firmware_stm32/App/Src/servo_bus2.c: Dynamixel Protocol 2.0),
built into a host variant of the firmware from a model file with servo.model = "XM430-W350",
driven through the host port (uavarm/build/csrc/host_port.c) against three simulated
XM430-W350s (uavarm/sim/xseries_sim.py) on a simulated bus with its wire timing.

Oracles, none taken from the C under test:
- the instruction packets: Protocol 2.0's written format (header FF FF FD 00, LEN, CRC-16 of
  test_dxl_protocol2, computed bit by bit from the polynomial), and the official
  DynamixelSDK's GroupSyncWrite for the SYNC_WRITE;
- what the servos must hold: the XM430-W350 e-manual's control table and factory values
  (typed below), the model file's joint limits and speeds turned into units here;
- what happened: the simulated servos' registers and shafts.
"""
from __future__ import annotations

import math
import re
import subprocess
from pathlib import Path

import pytest

from conftest import once_per_run, require_arm_toolchain
from sdk_capture import packet_handler, sdk_sync_write
from simboard_tools import family_lib, family_servos
from test_dxl_protocol2 import crc16
from test_servo_models import xm430_text
from uavarm.build import cbuild, firmware
from uavarm.codegen import generate
from uavarm.model import config
from uavarm.sim.ax12_sim import AX12Bus
from uavarm.sim.xseries_sim import XL430_W250, XM430_W350, XServo, unstuffed

US = 1_000_000
BAUD = 1_000_000
BAUD_REGISTER = 3                 # 1 Mbit/s (e-manual, Baud Rate(8))
INST_READ, INST_WRITE, INST_SYNC_WRITE = 0x02, 0x03, 0x83
BROADCAST = 0xFE
STATE = {"off": 0, "booting": 1, "configuring": 2, "running": 3, "failed": 4}
EEPROM_END = 64                   # Torque Enable(64) opens the RAM area

# XM430-W350 e-manual control table: name -> (address, size)
TABLE = {"return_delay_time": (9, 1), "drive_mode": (10, 1), "operating_mode": (11, 1),
         "temperature_limit": (31, 1), "max_voltage_limit": (32, 2), "min_voltage_limit": (34, 2),
         "velocity_limit": (44, 4), "max_position_limit": (48, 4), "min_position_limit": (52, 4),
         "pwm_limit": (36, 2), "shutdown": (63, 1), "torque_enable": (64, 1), "status_return_level": (68, 1),
         "hardware_error_status": (70, 1), "goal_pwm": (100, 2), "profile_acceleration": (108, 4), "profile_velocity": (112, 4),
         "goal_position": (116, 4), "present_current": (126, 2), "present_velocity": (128, 4),
         "present_position": (132, 4), "present_input_voltage": (144, 2), "present_temperature": (146, 1)}
INDIRECT_ADDRESS, INDIRECT_DATA = 168, 224   # Indirect Address 1 (2 bytes each), Indirect Data 1


def table_bytes(*names):
    """Each byte's address of the named registers (the e-manual's table), in order."""
    return [a for n in names for a in range(TABLE[n][0], TABLE[n][0] + TABLE[n][1])]


# What the status map must point at: Torque Enable, Status Return Level, Hardware Error Status,
# Present Current, the low two bytes of Present Velocity (it stays within +-Velocity Limit, at
# most 1023), Present Position, the low byte of Present Input Voltage (at most 160, the
# servos' 16 V) and Present Temperature; a status READ asks for as many Indirect Data bytes.
STATUS_MAP = (table_bytes("torque_enable", "status_return_level", "hardware_error_status", "present_current")
              + table_bytes("present_velocity")[:2] + table_bytes("present_position")
              + table_bytes("present_input_voltage")[:1] + table_bytes("present_temperature"))
STATUS_READ = bytes([INDIRECT_DATA, 0, len(STATUS_MAP), 0])   # a READ's address and length
OVERHEATING = 0x04                # Hardware Error Status bit 2
ALERT = 0x80                      # status error byte bit 7


@pytest.fixture(scope="module")
def rig_parts():
    """(model, ffi, lib): the whole firmware application built for the host from the model
    file made an XM430-W350 arm (1 Mbit/s, zeros at 2048: uavarm/build/variants.py's
    XM430_EDITS)."""
    return (family_servos("XM430-W350").model, *family_lib("XM430-W350"))


# ---------------------------------------------------------------- units from the model file

def unit_range(model, j: int) -> tuple[int, int]:
    """Joint j's limits in XM430 position units (4096 per turn) around the model's zero."""
    s = model.servos[j]
    ends = sorted(s.zero + s.direction * d * 4096 / 360 for d in (model.limits[j].min_deg, model.limits[j].max_deg))
    return math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9)


def profile_velocity(rpm: float) -> int:
    """Profile Velocity units (0.229 rpm, e-manual) nearest a speed."""
    return round(rpm / 0.229)


def wanted(model, j: int) -> dict[str, int]:
    """What servo j must hold once configured: Return Delay Time as the model file says (2 us
    units), normal direction with a velocity-based profile (Drive Mode 0), Position Control
    Mode (3), the e-manual's factory safety values (Temperature Limit 80 deg C, voltage
    9.5-16.0 V, PWM Limit 885 = 100 %, Shutdown 52: overheating, electrical shock, overload),
    Velocity Limit at the top of its range (1023: the model's speeds are checked against it),
    the joint limits as Position Limits, Status Return Level 1 (reads only), Goal PWM at PWM
    Limit (the full torque), no acceleration ramp, torque on."""
    lo, hi = unit_range(model, j)
    return {"return_delay_time": model.servo_return_delay_us // 2, "drive_mode": 0, "operating_mode": 3,
            "temperature_limit": 80, "max_voltage_limit": 160, "min_voltage_limit": 95, "pwm_limit": 885,
            "goal_pwm": 885, "velocity_limit": 1023,
            "max_position_limit": hi, "min_position_limit": lo, "shutdown": 52, "status_return_level": 1,
            "profile_acceleration": 0, "torque_enable": 1}


# ---------------------------------------------------------------- packets on the wire

def split_packets(data: bytes) -> list[tuple[int, int, bytes]]:
    """(id, instruction, unstuffed parameters) of a stream of Protocol 2.0 instruction
    packets: FF FF FD 00 ID LEN_L LEN_H INST P1..PN CRC_L CRC_H, LEN = bytes after it, CRC-16
    over all before it. Every byte must belong to a well-formed packet."""
    out, i = [], 0
    while i < len(data):
        assert data[i:i + 4] == b"\xff\xff\xfd\x00", f"no header at byte {i}: {data[i:].hex(' ')}"
        length = data[i + 5] | data[i + 6] << 8
        pkt = data[i:i + 7 + length]
        assert len(pkt) == 7 + length, f"truncated: {pkt.hex(' ')}"
        assert crc16(pkt[:-2]) == int.from_bytes(pkt[-2:], "little"), pkt.hex(" ")
        out.append((pkt[4], pkt[7], unstuffed(pkt[8:-2]), pkt))
        i += len(pkt)
    return out


class Rig:
    """The driver (sbus_t) on the host port, the servos on a simulated bus; time moves in
    steps of `poll_us`, each ending with one sbus_poll()."""

    def __init__(self, parts, servos, poll_us: int = 50, echo: bool = False):
        self.model, self.ffi, self.lib = parts
        self.poll_us = poll_us
        self.hp = self.ffi.new("host_port_t *")
        self.lib.host_port_init(self.hp, BAUD, self.model.imu_address)
        self.bus = AX12Bus(servos, baud=BAUD, echo=echo)
        self.bus.power(False)
        self.ids = [s.id for s in self.model.servos]
        self.sbus = self.ffi.new("sbus_t *")
        self.now_us = 0
        self.power = False
        self.sent: list[tuple[float, bytes]] = []      # (time, packet) of every instruction
        self._pending = b""
        self._buf = self.ffi.new("uint8_t[]", 512)
        self.lib.sbus_init(self.sbus, self.ffi.addressof(self.hp, "port"), self.ids, BAUD)
        self.on_tick = None
        self._next_tick = 0

    def servo(self, j: int) -> XServo:
        return self.bus.servo(self.ids[j])

    @property
    def state(self) -> int:
        return self.sbus.state

    def step(self) -> None:
        self.now_us += self.poll_us
        self.bus.run_until(self.now_us / US)
        rx = self.bus.read()
        if rx:
            self.lib.host_port_servo_push(self.hp, rx, len(rx))
        self.hp.now_us = self.now_us
        if self.on_tick and self.now_us >= self._next_tick:
            self._next_tick = self.now_us + round(US / self.model.sample_rate)
            self.on_tick(self)
        self.lib.sbus_poll(self.sbus)
        if self.hp.servo_power != self.power:
            self.power = bool(self.hp.servo_power)
            self.bus.power(self.power)
        n = self.lib.host_port_servo_take(self.hp, self._buf, len(self._buf))
        if n:
            data = bytes(self.ffi.buffer(self._buf, n))
            self.bus.write(data)
            for pkt in split_packets(data):
                self.sent.append((self.now_us / US, pkt))

    def run(self, seconds: float) -> None:
        end = self.now_us + round(seconds * US)
        while self.now_us < end:
            self.step()

    def run_until(self, cond, seconds: float) -> bool:
        end = self.now_us + round(seconds * US)
        while self.now_us < end:
            self.step()
            if cond():
                return True
        return False

    def power_on(self, limp: bool = False) -> None:
        (self.lib.sbus_power_limp(self.sbus) if limp else self.lib.sbus_power(self.sbus, True))

    def packets(self, since: float = -1.0, inst: int | None = None):
        return [p for t, p in self.sent if t >= since and (inst is None or p[1] == inst)]

    def command(self, goal, speed) -> None:
        self.lib.sbus_command(self.sbus, list(goal), list(speed))

    def counters(self, j: int):
        return self.sbus.servo[j]


def factory_servos(model, positions=(2048, 2048, 2048), kind=XM430_W350, **table):
    """X-series servos as they leave the factory (return delay 500 us, Status Return Level 2),
    but at the bus's baud and with the model file's ids."""
    return [XServo(kind, s.id, position=p, table={"baud_rate": BAUD_REGISTER, **table})
            for s, p in zip(model.servos, positions)]


def running_rig(parts, echo=False, **kw):
    model = parts[0]
    rig = Rig(parts, factory_servos(model, **kw), echo=echo)
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0), rig.state
    return rig


# ---------------------------------------------------------------- power-up and configuration

def test_power_up_configures_every_servo_and_runs(rig_parts):
    model = rig_parts[0]
    rig = Rig(rig_parts, factory_servos(model))
    before = [bytes(rig.servo(j).table) for j in range(3)]
    rig.run(0.05)
    assert rig.state == STATE["off"] and not rig.sent
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0), rig.state
    first = rig.sent[0][0]
    assert first >= model.servo_boot_time - 1e-9, "nothing before the servos' boot time"
    cfg = rig.packets()
    # servo by servo: a READ of what it holds, the WRITEs, a READ back, a READ of the status
    per_servo = [[p for p in cfg if p[0] == id_] for id_ in rig.ids]
    assert [p[0] for p in cfg] == [p[0] for g in per_servo for p in g], "servos interleaved"
    for j, group in enumerate(per_servo):
        assert [p[1] for p in group[:1] + group[-2:]] == [INST_READ] * 3
        assert all(p[1] == INST_WRITE for p in group[1:-2])
        for read in (group[0], group[-2]):
            addr, n = int.from_bytes(read[2][:2], "little"), int.from_bytes(read[2][2:4], "little")
            assert addr <= 9 and addr + n >= 147, "the reads cover every register written and the status"
        assert group[-1][2] == STATUS_READ, "the status through its map"
        s = rig.servo(j)
        want = wanted(model, j)
        assert {k: s.register(k) for k in want} == want
        # an EEPROM write only where the servo held something else
        for _, _, params, _ in group[1:-2]:
            addr, data = int.from_bytes(params[:2], "little"), params[2:]
            if addr < EEPROM_END:
                assert before[j][addr:addr + len(data)] != data, (addr, data.hex(" "))
        c = rig.counters(j)
        assert (c.timeouts, c.retries, c.bad_packets, c.error_packets) == (0, 0, 0, 0)
        assert c.eeprom_writes > 0 and c.status_valid and c.present_position == 2048
    print(f"\nconfiguration: {len(cfg)} packets, {sum(len(p[3]) for p in cfg)} bytes, "
          f"{(rig.now_us / US - first) * 1e3:.2f} ms")


def test_a_second_power_up_writes_no_eeprom(rig_parts):
    rig = running_rig(rig_parts)
    eeprom = [bytes(rig.servo(j).table[:EEPROM_END]) for j in range(3)]
    written = [rig.counters(j).eeprom_writes for j in range(3)]
    rig.lib.sbus_power(rig.sbus, False)
    rig.run(0.05)
    assert not rig.servo(0).powered
    t = rig.now_us / US
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0)
    writes = rig.packets(t, INST_WRITE)
    assert writes, "the RAM is set up again"
    assert all(int.from_bytes(p[2][:2], "little") >= EEPROM_END for p in writes), \
        [p[3].hex(" ") for p in writes]
    assert [rig.counters(j).eeprom_writes for j in range(3)] == written
    assert [bytes(rig.servo(j).table[:EEPROM_END]) for j in range(3)] == eeprom
    for j in range(3):
        want = wanted(rig.model, j)
        assert {k: rig.servo(j).register(k) for k in want} == want


def test_only_the_eeprom_register_that_differs_is_written(rig_parts):
    """A servo configured before whose Temperature Limit was changed since: the EEPROM write
    at the next power-up is that register's alone (after the torque is turned off: the
    EEPROM is locked while it is on)."""
    rig = running_rig(rig_parts)
    rig.lib.sbus_power(rig.sbus, False)
    rig.run(0.02)
    rig.servo(1).set_register("temperature_limit", 70)
    t = rig.now_us / US
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0)
    eeprom = [p for p in rig.packets(t, INST_WRITE) if int.from_bytes(p[2][:2], "little") < EEPROM_END]
    assert len(eeprom) == 1 and eeprom[0][0] == rig.ids[1]
    assert rig.servo(1).register("temperature_limit") == 80


def test_eeprom_is_written_with_the_torque_off(rig_parts):
    """A servo whose torque is on when it is configured (its supply never went off) and whose
    EEPROM differs is told to turn the torque off first: the servo refuses EEPROM writes
    while it is on (e-manual). It ends configured, torque on."""
    model = rig_parts[0]
    servos = factory_servos(model)
    rig = Rig(rig_parts, servos)
    rig.power_on()
    rig.run(model.servo_boot_time * 0.5)
    servos[2].set_register("torque_enable", 1)
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0), rig.state
    writes = [p for p in rig.packets(inst=INST_WRITE) if p[0] == rig.ids[2]]
    assert writes[0][2] == bytes([64, 0, 0]), writes[0][3].hex(" ")
    want = wanted(model, 2)
    assert {k: servos[2].register(k) for k in want} == want


# ---------------------------------------------------------------- running

def goals_in_range(model, fractions):
    out = []
    for j, f in enumerate(fractions):
        lo, hi = unit_range(model, j)
        out.append(round(lo + f * (hi - lo)))
    return out


def test_each_command_one_sync_write_and_one_status_read_and_the_goals_are_reached(rig_parts):
    rig = running_rig(rig_parts)
    model = rig.model
    goal = goals_in_range(model, (0.3, 0.55, 0.7))
    speed = [profile_velocity(model.transit_speed_rpm)] * 3
    rig.on_tick = lambda r: r.command(goal, speed)
    t0 = rig.now_us / US
    rig.run(1.5)
    tick = 1.0 / model.sample_rate
    by_tick: dict[int, list] = {}
    for t, p in rig.sent:
        if t0 + tick <= t < rig.now_us / US - tick:
            by_tick.setdefault(int((t - t0) / tick), []).append(p)
    assert len(by_tick) > 100
    read_ids = []
    for pkts in by_tick.values():
        assert [p[1] for p in pkts] == [INST_SYNC_WRITE, INST_READ], [p[3].hex(" ") for p in pkts]
        sync, read = pkts
        assert sync[0] == BROADCAST and read[2] == STATUS_READ, "the status map's bytes"
        read_ids.append(read[0])
    k = rig.ids.index(read_ids[0])
    assert read_ids == [rig.ids[(k + n) % 3] for n in range(len(read_ids))], "round robin"
    for j in range(3):
        s = rig.servo(j)
        assert s.register("profile_velocity") == speed[j]
        assert abs(s.position - goal[j]) <= 1.0, (j, s.position, goal[j])
        c = rig.counters(j)
        assert abs(c.present_position - goal[j]) <= 1
        assert (c.timeouts, c.retries, c.bad_packets, c.error_packets, c.resets) == (0, 0, 0, 0, 0)
        assert c.present_voltage == 120 and c.hardware_error == 0
    assert rig.sbus.sync_writes == len(rig.packets(inst=INST_SYNC_WRITE))


@pytest.mark.parametrize("goal, speed", [([1000, 2048, 3000], [44, 131, 258]), ([2100, 2000, 2047], [0, 1, 1023])])
def test_the_sync_write_is_the_sdks(rig_parts, goal, speed):
    """The SYNC_WRITE of Profile Velocity(112) and Goal Position(116), 8 bytes per servo,
    byte for byte what DynamixelSDK's GroupSyncWrite sends for the same values."""
    rig = running_rig(rig_parts)
    goal = [min(max(g, unit_range(rig.model, j)[0]), unit_range(rig.model, j)[1]) for j, g in enumerate(goal)]
    t = rig.now_us / US
    rig.command(goal, speed)
    rig.run(0.005)
    (sync,) = rig.packets(t, INST_SYNC_WRITE)
    data = b"".join(v.to_bytes(4, "little") + g.to_bytes(4, "little") for g, v in zip(goal, speed))
    assert sync[3] == sdk_sync_write(packet_handler(2.0), 112, 8, rig.ids, data)
    assert [rig.servo(j).register("goal_position") for j in range(3)] == goal


def test_a_command_beyond_the_registers_ranges_is_held_back(rig_parts):
    """Goal Position 0..4095 and Profile Velocity up to Velocity Limit 1023: a command
    beyond is never sent; the next one replaces it."""
    rig = running_rig(rig_parts)
    rig.run(0.01)
    sends = rig.hp.servo_sends
    for goal, speed in [([4096, 2048, 2048], [1, 1, 1]), ([2048, 2048, 2048], [1, 1024, 1])]:
        rig.command(goal, speed)
        rig.lib.sbus_poll(rig.sbus)
        assert rig.hp.servo_sends == sends and rig.sbus.command_pending
    rig.command([2048, 2048, 2048], [1, 1023, 1])
    rig.lib.sbus_poll(rig.sbus)
    assert rig.hp.servo_sends == sends + 1


def test_bus_time_per_command_is_bounded(rig_parts):
    rig = running_rig(rig_parts)
    model = rig.model
    goal = goals_in_range(model, (0.5, 0.5, 0.5))
    rig.on_tick = lambda r: r.command(goal, [44] * 3)
    replies = []
    send_reply = rig.bus._send_reply

    def keep(start, data):
        replies.append((start, len(data)))
        return send_reply(start, data)

    rig.bus._send_reply = keep
    t0 = rig.now_us / US
    rig.run(0.2)
    syncs = [(t, p) for t, p in rig.sent if p[1] == INST_SYNC_WRITE and t > t0]
    byte = 10 / BAUD
    worst = 0.0
    for t, p in syncs[:-1]:
        after = [(s, n) for s, n in replies if t <= s < t + 1.0 / model.sample_rate]
        assert len(after) == 1
        start, n = after[0]
        worst = max(worst, start + n * byte - t)
    bound = rig.lib.sbus_tick_bus_time_us(rig.sbus)
    print(f"\nper command: SYNC_WRITE {len(syncs[0][1][3])} bytes + READ 14 bytes + status {replies[-1][1]} bytes "
          f"at {BAUD} bit/s: worst {worst * 1e6:.0f} us on the wire (return delay "
          f"{model.servo_return_delay_us} us), driver's bound {bound} us, tick {US / model.sample_rate:.0f} us")
    assert worst * 1e6 <= bound < US / model.sample_rate


def test_the_status_map_points_at_the_registers_read_and_reads_them(rig_parts):
    """Indirect Address 1..13 hold the addresses of STATUS_MAP; what the driver makes of a
    reading through them is what those registers hold (the servos at different supplies,
    temperatures, loads and speeds)."""
    rig = running_rig(rig_parts)
    model = rig.model
    for j in range(3):
        assert [rig.servo(j).register(f"indirect_address_{k + 1}") for k in range(len(STATUS_MAP))] == STATUS_MAP
        rig.servo(j).voltage = 11.3 + 0.2 * j
        rig.servo(j).temperature = 41 + j
        rig.servo(j).load_torque = (-0.4, 0.25, 1.1)[j]
    held = {}   # each servo's registers as its latest READ found them

    def snapshot(j, read):
        def read_and_keep(addr, n):
            answer = read(addr, n)
            s = rig.servo(j)
            held[j] = {k: s.register(k) for k in ("present_position", "present_velocity", "present_current",
                                                   "present_input_voltage", "present_temperature")}
            return answer
        return read_and_keep
    for j in range(3):
        rig.servo(j)._read = snapshot(j, rig.servo(j)._read)
    goal = goals_in_range(model, (0.2, 0.8, 0.35))
    rig.on_tick = lambda r: r.command(goal, [131] * 3)
    for _ in range(30):   # while moving: each reading against the registers it was read from
        reads = rig.sbus.status_reads
        assert rig.run_until(lambda: rig.sbus.status_reads != reads, 0.02)
        j = rig.sbus.last_read
        c, want = rig.counters(j), held[j]
        assert c.present_position == want["present_position"]
        velocity = want["present_velocity"]
        assert c.present_speed == min(abs(velocity), 1023) | (0x400 if velocity < 0 else 0)
        assert c.present_current == want["present_current"] != 0
        assert c.present_voltage == want["present_input_voltage"] == round(rig.servo(j).voltage * 10)
        assert c.present_temperature == want["present_temperature"] == 41 + j
        assert c.hardware_error == 0 and c.last_error == 0
    assert rig.sbus.remaps == 0


# ---------------------------------------------------------------- faults

def test_a_brown_out_is_seen_and_the_servo_refit_holding_where_it_stands(rig_parts):
    """A supply dip resets a servo's RAM (torque off, Status Return Level 2, profile 0) and
    the arm sags where it hangs: the driver sees Torque Enable 0 at its next reading of that
    servo, counts a reset and sets it up again with the torque on, its goal where it stands
    (not where it was told before the dip)."""
    rig = running_rig(rig_parts)
    model = rig.model
    goal = goals_in_range(model, (0.5, 0.5, 0.5))
    rig.on_tick = lambda r: r.command(goal, [131] * 3)
    rig.run(0.5)
    assert abs(rig.servo(1).position - goal[1]) <= 1
    # from now on commanded only while no refit is due (as the application does)
    rig.on_tick = lambda r: (None if r.sbus.refit or r.sbus.refitting else r.command(goal, [131] * 3))
    s = rig.servo(1)
    s.power_on()                        # the dip: RAM at its power-on values
    sagged = goal[1] - 40
    s.turn_by_hand(sagged)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)     # nothing commanded: read only
    taken = []
    reads = rig.counters(1).reads

    def watch():
        if rig.counters(1).reads != reads + len(taken):
            taken.append(rig.counters(1).present_position)
        return rig.sbus.resets == 1
    assert rig.run_until(watch, 0.2)
    assert rig.counters(1).resets == 1
    # its status map was lost with the RAM: that reading (every byte 0) was not taken, the map
    # was written again and the servo read again, so the position it holds by is where it sags
    assert taken == [sagged] and rig.sbus.remaps == 1
    assert rig.run_until(lambda: not rig.sbus.refit and not rig.sbus.refitting, 0.05)
    rig.run(0.1)
    assert s.register("torque_enable") == 1 and s.register("status_return_level") == 1
    assert s.register("goal_position") == sagged and abs(s.position - sagged) <= 1
    assert rig.sbus.refits == 1 and rig.sbus.resets == 1 and rig.sbus.remaps == 1
    assert [rig.counters(j).resets for j in range(3)] == [0, 1, 0]


def test_a_servo_whose_status_map_will_not_hold_is_failed_not_read(rig_parts):
    """A servo whose READs through the map keep answering with its initial values (the map's
    WRITEs lost): none of those readings is taken (its position would be 0), it is read
    again once, then marked failed for the round as a silent servo is, and the other servos
    are read as before."""
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    rig.run(0.05)
    s = rig.servo(0)
    position = rig.counters(0).present_position
    execute = s._execute
    s._execute = lambda inst, params: (0, b"") if inst == INST_WRITE else execute(inst, params)
    s.power_on()
    reads = [rig.counters(j).reads for j in range(3)]
    rig.run(0.2)
    c = rig.counters(0)
    assert c.reads == reads[0] and c.present_position == position and c.failed
    assert rig.sbus.remaps >= 2 and c.retries >= 1 and c.timeouts == 0
    assert all(rig.counters(j).reads > reads[j] + 3 for j in (1, 2))


def test_a_hardware_error_is_counted_and_is_not_a_brown_out(rig_parts):
    """Overheating (above Temperature Limit 80 deg C): the servo's Shutdown turns its torque
    off and raises Hardware Error Status bit 2 and the alert bit of its status packets. The
    driver counts the bit, keeps the alert as the servo's error, and does not take the
    torque off for a lost RAM."""
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    rig.run(0.05)
    rig.servo(2).temperature = 81
    rig.run(0.1)
    c = rig.counters(2)
    assert c.hardware_error == OVERHEATING and c.hardware_error_bits[2] > 0
    assert sum(c.hardware_error_bits) == c.hardware_error_bits[2]
    assert c.last_error == ALERT and c.error_packets > 0 and c.present_temperature == 81
    assert rig.sbus.resets == 0 and rig.sbus.refits == 0
    assert rig.servo(2).register("torque_enable") == 0
    assert rig.counters(0).hardware_error == 0 and rig.counters(0).last_error == 0


def test_a_silent_servo_is_retried_then_failed_and_recovers(rig_parts):
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    rig.run(0.05)
    s = rig.servo(1)
    rig.bus.servos.remove(s)
    t = rig.now_us / US
    rig.run(0.2)
    c = rig.counters(1)
    assert c.timeouts >= 2 and c.retries >= 1 and c.failed
    reads = [p[0] for p in rig.packets(t, INST_READ)]
    assert any(a == b == rig.ids[1] for a, b in zip(reads, reads[1:])), "asked again before moving on"
    assert not rig.counters(0).failed and not rig.counters(2).failed
    rig.bus.add(s)
    rig.run(0.1)
    assert not rig.counters(1).failed


def test_a_servo_silent_at_power_up_fails_the_configuration(rig_parts):
    model = rig_parts[0]
    servos = factory_servos(model)
    servos[2].set_register("baud_rate", 1)          # 57600: deaf to the bus
    rig = Rig(rig_parts, servos)
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["failed"], 1.0), rig.state
    reads = [p for p in rig.packets(inst=INST_READ) if p[0] == rig.ids[2]]
    assert len(reads) == 6, "three attempts, each a read before and a read back"
    c = rig.counters(2)
    assert c.failed and c.timeouts == 3 and c.retries == 2
    assert not rig.packets(inst=INST_SYNC_WRITE)


def test_a_corrupted_reply_is_counted_and_survived(rig_parts):
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    send_reply = rig.bus._send_reply
    corrupted = []

    def corrupt(start, data):
        if data[4] == rig.ids[0] and len(corrupted) < 2:
            data = bytearray(data)
            data[9] ^= 0x01                 # the first parameter: the CRC no longer fits
            corrupted.append(bytes(data))
        return send_reply(start, bytes(data))

    rig.bus._send_reply = corrupt
    rig.run(0.2)
    c = rig.counters(0)
    assert len(corrupted) == 2 and c.bad_packets == 2 and c.error_packets == 0
    assert c.status_valid and not c.failed


def test_a_reply_with_an_fd_is_taken_but_not_one_with_an_unstuffed_ff_ff_fd(rig_parts):
    """FD bytes alone (Present Position and Velocity 253) need no stuffing: the reading is taken.
    The same reply with FF FF FD written into its parameters and its CRC made right again, but
    not stuffed (LEN as expected), breaks Protocol 2.0's rule: at every place it is refused."""
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    s = rig.servo(0)
    s.turn_by_hand(253)
    s.set_register("goal_position", 253)
    step = s._update_present

    def at_253(rate):
        step(rate)
        s.set_register("present_velocity", 253)

    s._update_present = at_253
    rig.run(0.05)
    c = rig.counters(0)
    assert c.present_position == 253 and c.present_speed == 253 and c.bad_packets == 0
    send_reply = rig.bus._send_reply
    planted = []
    places = len(STATUS_MAP) - 2    # FF FF FD wholly within the parameters, after the error byte

    def plant(start, data):
        k = len(planted)
        if data[4] == rig.ids[0] and data[7] == 0x55 and k < places:
            body = bytearray(data[:-2])
            body[9 + k:12 + k] = b"\xff\xff\xfd"
            assert len(body) == 9 + len(STATUS_MAP)
            data = bytes(body) + crc16(bytes(body)).to_bytes(2, "little")
            planted.append(data)
        return send_reply(start, data)

    rig.bus._send_reply = plant
    reads = c.reads
    assert rig.run_until(lambda: len(planted) == places, 1.0)
    rig.run(0.01)
    assert c.reads == reads and c.present_position == 253, "no planted reply taken"
    rig.run(0.1)
    assert c.reads > reads and c.present_position == 253


def test_the_bus_echo_and_a_stuffed_reply_go_through_the_parser(rig_parts):
    """On a bus that echoes the master's bytes every reply follows an instruction packet (not
    a status): the driver's straight read gives way to the resynchronising parser, which skips
    the echo. A reply the servo had to stuff (Present Position 0xFDFFFF.. cannot be, so an FF
    FF FD put into Present Velocity's bytes) is longer than expected and is taken by the parser
    too, unstuffed. Nothing is counted wrong and the goals are reached."""
    rig = running_rig(rig_parts, echo=True)
    goal = goals_in_range(rig.model, (0.4, 0.6, 0.5))
    rig.on_tick = lambda r: r.command(goal, [131] * 3)
    rig.run(0.6)
    for j in range(3):
        c = rig.counters(j)
        assert (c.timeouts, c.bad_packets, c.error_packets, c.last_error) == (0, 0, 0, 0)
        assert abs(c.present_position - goal[j]) <= 1 and abs(rig.servo(j).position - goal[j]) <= 1
    # a stuffed reply: Present Velocity(128) reads -3 (FD FF FF FF) after Present Current(126)
    # 0xFFFF (-1, the shaft held against 4.8 mN m): FF FF FD on the wire, stuffed to FF FF FD FD
    s = rig.servo(1)
    s.load_torque = 0.0048
    step = s._update_present

    def moving_backward(rate):
        step(rate)
        s.set_register("present_velocity", -3)

    s._update_present = moving_backward
    reads = rig.counters(1).reads
    rig.run(0.1)
    c = rig.counters(1)
    assert c.reads > reads and c.present_current == -1 and c.present_speed == 0x400 | 3
    assert (c.timeouts, c.bad_packets, c.error_packets) == (0, 0, 0)
    assert c.present_load == 0x400 | 1 and rig.servo(1).register("present_current") == -1


# ---------------------------------------------------------------- service

def test_limp_and_back(rig_parts):
    rig = running_rig(rig_parts)
    model = rig.model
    goal = goals_in_range(model, (0.5, 0.5, 0.5))
    rig.on_tick = lambda r: r.command(goal, [131] * 3)
    rig.run(0.4)
    t = rig.now_us / US
    rig.lib.sbus_limp(rig.sbus, True)
    rig.on_tick = lambda r: (r.command(goal, [131] * 3), r.lib.sbus_read(r.sbus))
    rig.run(0.1)
    writes = rig.packets(t, INST_WRITE)
    assert writes[0][0] == BROADCAST and writes[0][2] == bytes([64, 0, 0])
    assert not rig.packets(t, INST_SYNC_WRITE), "no goal while limp"
    assert all(rig.servo(j).register("torque_enable") == 0 for j in range(3))
    moved = [g + 25 for g in goal]
    for j in range(3):
        rig.servo(j).turn_by_hand(moved[j])
    rig.run(0.05)                       # read where the hands put it
    assert [rig.counters(j).present_position for j in range(3)] == moved
    rig.on_tick = None
    rig.lib.sbus_limp(rig.sbus, False)
    assert rig.run_until(lambda: not rig.sbus.refit and not rig.sbus.refitting, 0.05)
    rig.run(0.02)
    for j in range(3):
        s = rig.servo(j)
        assert s.register("torque_enable") == 1 and s.register("goal_position") == moved[j]
    assert rig.sbus.resets == 0


def test_limp_during_a_refit_stops_it(rig_parts):
    """sbus_limp(true) while a refit's writes are still going out: the refit stops there, so
    no servo gets its torque back on after the broadcast torque off."""
    rig = running_rig(rig_parts)
    rig.on_tick = lambda r: r.lib.sbus_read(r.sbus)
    rig.run(0.05)
    rig.lib.sbus_limp(rig.sbus, True)
    rig.run(0.03)
    rig.on_tick = None
    rig.lib.sbus_limp(rig.sbus, False)          # all three to be refit, one write at a time
    assert rig.run_until(lambda: rig.sbus.refit_steps and rig.sbus.refit_servo == 1, 0.05)
    rig.lib.sbus_limp(rig.sbus, True)
    rig.run(0.05)
    assert not rig.sbus.refitting and not rig.sbus.refit
    assert [rig.servo(j).register("torque_enable") for j in range(3)] == [0, 0, 0]


def test_power_limp_configures_with_the_torque_off_and_the_bench_torque(rig_parts):
    """The bench: configured with Torque Enable 0 and Goal PWM at servo.bench_torque_limit of
    PWM Limit 885 (Goal PWM caps the motor's output in Position Control Mode, e-manual); no
    goal sent while limp; the torque back on with that cap, and sbus_full_torque() sets each
    servo up again with the full Goal PWM, holding where it stands."""
    model = rig_parts[0]
    bench = round(885 * model.servo_bench_torque_limit)
    rig = Rig(rig_parts, factory_servos(model))
    rig.power_on(limp=True)
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0)
    rig.on_tick = lambda r: (r.command([2048] * 3, [44] * 3), r.lib.sbus_read(r.sbus))
    rig.run(0.1)
    for j in range(3):
        want = {**wanted(model, j), "torque_enable": 0}
        got = {k: rig.servo(j).register(k) for k in want}
        assert abs(got.pop("goal_pwm") - bench) <= 1 and want.pop("goal_pwm") == 885
        assert got == want
        assert rig.counters(j).status_valid
    assert rig.sbus.limp and not rig.packets(inst=INST_SYNC_WRITE) and rig.sbus.resets == 0
    rig.servo(0).turn_by_hand(2100)
    rig.run(0.05)
    rig.on_tick = None
    rig.lib.sbus_limp(rig.sbus, False)
    assert rig.run_until(lambda: not rig.sbus.refit and not rig.sbus.refitting, 0.05)
    rig.run(0.001)
    assert all(rig.servo(j).register("torque_enable") == 1 for j in range(3))
    assert all(abs(rig.servo(j).register("goal_pwm") - bench) <= 1 for j in range(3))
    assert rig.servo(0).register("goal_position") == 2100
    rig.lib.sbus_full_torque(rig.sbus)
    assert rig.run_until(lambda: not rig.sbus.refit and not rig.sbus.refitting, 0.05)
    rig.run(0.01)
    for j in range(3):
        s = rig.servo(j)
        assert (s.register("goal_pwm"), s.register("torque_enable")) == (885, 1)
    assert rig.servo(0).register("goal_position") == 2100 and abs(rig.servo(0).position - 2100) <= 1
    assert rig.sbus.resets == 0


def test_an_xl430_build_sets_up_xl430s_with_their_own_safety_values(tmp_path_factory):
    """From a model file naming the XL430-W250, the driver configures XL430-W250s with that
    servo's factory safety values (e-manual: Temperature Limit 72 deg C, voltage 6.0-14.0 V),
    the rest as for the XM430-W350, and runs."""
    def make(folder):
        (folder / "arm.toml").write_text(xm430_text("XL430-W250"))
        assert generate.main(["--model", str(folder / "arm.toml"), "--out", str(folder / "generated")]) == 0
        return str(folder)
    folder = Path(once_per_run(tmp_path_factory, "xl430_firmware", make))
    model = config.load(folder / "arm.toml")
    parts = (model, *firmware.load(folder / "generated"))
    rig = Rig(parts, factory_servos(model, kind=XL430_W250))
    rig.power_on()
    assert rig.run_until(lambda: rig.state == STATE["running"], 1.0), rig.state
    for j in range(3):
        want = {**wanted(model, j), "temperature_limit": 72, "max_voltage_limit": 140, "min_voltage_limit": 60}
        assert {k: rig.servo(j).register(k) for k in want} == want


# ---------------------------------------------------------------- the target

def test_the_xm430_application_builds_for_the_cortex_m4(rig_parts, tmp_path):
    """Every application source (servo_bus2.c the bus driver) and the XM430-W350 model's
    generated code compile with the target's flags and warnings, with no double-precision
    arithmetic; the sbus_* functions come from servo_bus2.c."""
    require_arm_toolchain()
    gen_dir = Path(rig_parts[0].path).parent / "generated"
    objs = []
    for src in firmware.app_sources(gen_dir):
        obj = tmp_path / (src.stem + ".o")
        proc = subprocess.run(["arm-none-eabi-gcc", *cbuild.TARGET_FLAGS, f"-I{gen_dir}", f"-I{firmware.APP / 'Inc'}",
                               "-c", str(src), "-o", str(obj)], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr
        objs.append(obj)
    undefined = subprocess.run(["arm-none-eabi-nm", "-u", *map(str, objs)], capture_output=True, text=True,
                               check=True).stdout
    assert not re.search(r"\b__aeabi_d\w+", undefined), "double-precision arithmetic on the target"
    defined = subprocess.run(["arm-none-eabi-nm", "--defined-only", str(tmp_path / "servo_bus2.o")],
                             capture_output=True, text=True, check=True).stdout
    assert " T sbus_poll" in defined
