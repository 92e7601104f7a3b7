"""Dynamixel AX-12A servos on a Protocol 1.0 bus: a deterministic simulator.

Written from the servo's documentation (the ROBOTIS AX-12A e-manual, the
legacy AX-12 manual, DynamixelSDK). Time only moves when `step()` is called.

    bus = AX12Bus(baud=1_000_000)
    bus.add(AX12(id=1))
    bus.write(instruction_bytes)   # the master starts transmitting now
    bus.step(0.002)                # bytes travel, servos answer and move
    bus.read()                     # status bytes that have arrived by now

Every byte takes 10 bit times on the wire (start, 8 data, stop). A servo acts on an
instruction when its last byte has arrived, and its status packet starts Return Delay
Time (2 us per unit) later. `SdkPort` lets DynamixelSDK code talk to the bus.

Where the documentation is silent this simulator chooses, and says so:
- Bad checksum (open point 1): answered with the Checksum error bit when
  `AX12(reply_to_bad_checksum=True)` (the default), ignored when False.
- Broadcast PING (open point 2): not answered, like every broadcast.
- Writing Goal Position does not turn the torque on (open point 3): firmware must write
  Torque Enable.
- A WRITE / REG_WRITE / SYNC_WRITE entry is all or nothing. Any refused byte (missing or
  read-only address, half of a 2-byte register, value out of its write range, locked
  address) gives the Range error; a Goal Position outside CW..CCW Angle Limit gives the
  Angle Limit error; either way nothing of it is written.
- READ past the end of the table or of length 0 gives the Range error and no data; the
  addresses missing from the AX-12A table (10, 19-23, 45) read as 0.
- A wrong parameter count, an unknown instruction (REBOOT and BULK_READ included) and a
  SYNC_WRITE not sent to the broadcast ID give the Instruction error.
- RESET while Lock = 1 gives the Range error and resets nothing (Lock lasts until
  power-off).
- Motion is no-load: the position follows a speed-limited profile toward the goal,
  optionally through a first-order lag; with `deadband` the lagging shaft stops once it is
  within the Compliance Margin of the profile (no torque there), so it rests up to that many
  units short of the goal. Compliance and punch are not modelled (the shaft does not sag
  under its load); Overload can be injected with `AX12.overload`. In wheel mode the shaft
  turns at (Moving Speed bits 0-9) / 1023 of the no-load speed and the position wraps at 1024.
- Present Load (40-41) is the torque the servo's motor applies, as a share of its stall
  torque at the supply it has (1.5 N m at 12 V, in proportion to the voltage, as its speed),
  0..1023 in bits 0-9, capped at Torque Limit, with bit 10 its sense: 0 = CCW (the sense in
  which the position grows), 1 = CW. The e-manual calls it an inferred value, from the
  motor's output, not a torque sensor's: so it is the torque the motor drives with, which
  holds a shaft still against the outside torque (`AX12.outside_torque`, e.g. the arm's
  weight: a joint pulled CW reads CCW). It is worked out when a READ covers it; a limp
  servo (torque off) reads 0.
- The LED blinks (`alarm_led_blinking`) while the last instruction's error bits or a
  lasting condition (voltage, temperature, overload) meet Alarm LED; Shutdown zeroes
  Torque Limit on the same bits, and again at every step while a condition lasts.
- An extra FF before the ID is skipped as part of the header, as the SDK does for status.
- Servos do not hear each other's replies. Replies that overlap in time (duplicate IDs)
  reach the master interleaved byte by byte, i.e. as garbage.
"""
from __future__ import annotations

import heapq
import itertools
import math
from collections import deque
from dataclasses import dataclass

BROADCAST_ID = 0xFE

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REG_WRITE = 0x04
INST_ACTION = 0x05
INST_RESET = 0x06
INST_SYNC_WRITE = 0x83

ERR_VOLTAGE = 0x01
ERR_ANGLE_LIMIT = 0x02
ERR_OVERHEATING = 0x04
ERR_RANGE = 0x08
ERR_CHECKSUM = 0x10
ERR_OVERLOAD = 0x20
ERR_INSTRUCTION = 0x40

MODEL_NUMBER = 12
TABLE_SIZE = 50                 # addresses 0..49
BYTE_GAP_TIMEOUT = 0.100        # s: a longer gap inside an instruction discards it
BITS_PER_BYTE = 10              # start + 8 data + stop
RETURN_DELAY_UNIT = 2e-6        # s per Return Delay Time unit
NO_LOAD_RPM = 59.0              # at 12 V
STALL_TORQUE_NM = 1.5           # at 12 V (e-manual: 1.5 N m at 12 V, 1.5 A)
NOMINAL_VOLTAGE = 12.0
RPM_PER_SPEED_UNIT = 0.111      # Moving Speed / Present Speed unit, joint mode
UNITS_PER_DEGREE = 1023 / 300
UNITS_PER_S_PER_RPM = 6.0 * UNITS_PER_DEGREE   # 1 rpm = 6 deg/s
LOCKABLE_FREE = range(0x18, 0x24)  # with Lock = 1 only Torque Enable .. Torque Limit are writable
MAX_SUBSTEP = 1e-3              # s, integration step of the motion


@dataclass(frozen=True)
class Register:
    addr: int
    size: int
    name: str
    write_range: tuple[int, int] | None   # None: read-only

    @property
    def eeprom(self) -> bool:
        return self.addr < 24


REGISTERS = (
    Register(0, 2, "model_number", None),
    Register(2, 1, "firmware_version", None),
    Register(3, 1, "id", (0, 253)),
    Register(4, 1, "baud_rate", (0, 254)),
    Register(5, 1, "return_delay_time", (0, 254)),
    Register(6, 2, "cw_angle_limit", (0, 1023)),
    Register(8, 2, "ccw_angle_limit", (0, 1023)),
    Register(11, 1, "temperature_limit", (0, 150)),
    Register(12, 1, "min_voltage_limit", (50, 250)),
    Register(13, 1, "max_voltage_limit", (50, 250)),
    Register(14, 2, "max_torque", (0, 1023)),
    Register(16, 1, "status_return_level", (0, 2)),
    Register(17, 1, "alarm_led", (0, 127)),
    Register(18, 1, "shutdown", (0, 127)),
    Register(24, 1, "torque_enable", (0, 1)),
    Register(25, 1, "led", (0, 1)),
    Register(26, 1, "cw_compliance_margin", (0, 254)),
    Register(27, 1, "ccw_compliance_margin", (0, 254)),
    Register(28, 1, "cw_compliance_slope", (1, 254)),
    Register(29, 1, "ccw_compliance_slope", (1, 254)),
    Register(30, 2, "goal_position", (0, 1023)),
    Register(32, 2, "moving_speed", (0, 2047)),   # 0..1023 in joint mode, checked apart
    Register(34, 2, "torque_limit", (0, 1023)),
    Register(36, 2, "present_position", None),
    Register(38, 2, "present_speed", None),
    Register(40, 2, "present_load", None),
    Register(42, 1, "present_voltage", None),
    Register(43, 1, "present_temperature", None),
    Register(44, 1, "registered", None),
    Register(46, 1, "moving", None),
    Register(47, 1, "lock", (1, 1)),
    Register(48, 2, "punch", (0, 1023)),
)
REG = {r.name: r for r in REGISTERS}
_REG_AT = [None] * TABLE_SIZE
for _r in REGISTERS:
    for _a in range(_r.addr, _r.addr + _r.size):
        _REG_AT[_a] = _r

# Factory values of the EEPROM area (AX-12A, not the legacy AX-12).
EEPROM_DEFAULTS = {
    "model_number": MODEL_NUMBER, "id": 1, "baud_rate": 1, "return_delay_time": 250,
    "cw_angle_limit": 0, "ccw_angle_limit": 1023, "temperature_limit": 70,
    "min_voltage_limit": 60, "max_voltage_limit": 140, "max_torque": 1023,
    "status_return_level": 2, "alarm_led": 0x24, "shutdown": 0x24,
}
# RAM values at power-on; Goal Position and Torque Limit are derived (see AX12.power_on).
RAM_DEFAULTS = {
    "torque_enable": 0, "led": 0, "cw_compliance_margin": 1, "ccw_compliance_margin": 1,
    "cw_compliance_slope": 32, "ccw_compliance_slope": 32, "moving_speed": 0,
    "registered": 0, "moving": 0, "lock": 0, "punch": 32,
}


def checksum(body: bytes) -> int:
    """~(ID + LEN + INST/ERR + params) & 0xFF."""
    return ~sum(body) & 0xFF


def packet(id_: int, inst_or_error: int, params: bytes = b"") -> bytes:
    """A Protocol 1.0 packet (instruction or status, same framing)."""
    body = bytes([id_, len(params) + 2, inst_or_error]) + bytes(params)
    return b"\xff\xff" + body + bytes([checksum(body)])


def baud_of(baud_rate_register: int) -> float:
    return 2_000_000 / (baud_rate_register + 1)


@dataclass(frozen=True)
class Reply:
    """A status packet a servo sends `delay` seconds after the instruction's last byte."""
    delay: float
    data: bytes


class AX12:
    """One AX-12A: control table, instruction handling and no-load motion.

    position     initial shaft position in units (0..1023, 512 = centre)
    voltage      supply voltage in V; scales the no-load speed and sets Present Voltage
    temperature  degrees C (set the attribute later to inject overheating)
    time_constant  s, first-order lag of the shaft behind the speed-limited profile (0 = none)
    deadband     with a lag: the shaft stops within the CW/CCW Compliance Margin of the profile
    reply_to_bad_checksum  answer a corrupted instruction with the Checksum error, or stay silent
    table        register values to start from instead of the factory ones, e.g.
                 {"baud_rate": 9, "return_delay_time": 0}
    """

    # step() moves the shaft itself unless a subclass changes _advance or max_speed (a
    # faulty servo in the tests): then it goes through them, substep by substep
    _plain_motion = True

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls._plain_motion = cls._advance is AX12._advance and cls.max_speed is AX12.max_speed

    def __init__(self, id: int = 1, *, position: float = 512.0, voltage: float = 12.0,
                 temperature: float = 30.0, time_constant: float = 0.0, deadband: bool = False,
                 reply_to_bad_checksum: bool = True, firmware_version: int = 0,
                 table: dict[str, int] | None = None):
        self.voltage = voltage
        self.temperature = temperature
        self.time_constant = time_constant
        self.deadband = deadband
        self.reply_to_bad_checksum = reply_to_bad_checksum
        self.firmware_version = firmware_version   # not documented for the AX-12A
        self.overload = False       # fault injection: the load cannot be controlled
        # What turns the shaft from outside, when Present Load is read: a function giving N m,
        # CCW (position growing) positive, e.g. gravity on the arm (SimBoard); None: nothing.
        self.outside_torque = None
        # Called just before a whole packet is acted on: the bus brings the motion up to then.
        self.before_packet = None
        self.powered = True
        self.table = bytearray(TABLE_SIZE)
        self._pos = float(position)         # shaft, in units
        self._profile = float(position)     # speed-limited set point the shaft follows
        self._pending: tuple[int, bytes] | None = None   # REG_WRITE waiting for ACTION
        self._last_error = 0
        self._rx = bytearray()
        self._rx_time = -math.inf
        settings = {"id": id, **(table or {})}
        unknown = set(settings) - set(REG)
        if unknown:
            raise KeyError(f"not AX-12A registers: {sorted(unknown)}")
        self._reset_eeprom()
        for name, value in settings.items():
            if REG[name].eeprom:
                self.set_register(name, value)
        self.power_on()
        for name, value in settings.items():
            if not REG[name].eeprom:
                self.set_register(name, value)

    # ------------------------------------------------------------ registers

    def register(self, name: str) -> int:
        r = REG[name]
        return int.from_bytes(self.table[r.addr:r.addr + r.size], "little")

    def set_register(self, name: str, value: int) -> None:
        """Set a register directly, without the checks of a WRITE (test setup, faults)."""
        r = REG[name]
        self.table[r.addr:r.addr + r.size] = int(value).to_bytes(r.size, "little")

    @property
    def id(self) -> int:
        return self.table[REG["id"].addr]

    @property
    def position(self) -> float:
        """The shaft position in units, unquantised."""
        return self._pos

    @property
    def locked(self) -> bool:
        return self.register("lock") == 1

    @property
    def wheel_mode(self) -> bool:
        return self.register("cw_angle_limit") == 0 and self.register("ccw_angle_limit") == 0

    @property
    def torque_on(self) -> bool:
        """Powered, Torque Enable set and Torque Limit above 0: the motor holds the shaft."""
        t = self.table
        return self.powered and bool(t[24]) and bool(t[34] or t[35])

    @property
    def return_delay(self) -> float:
        return RETURN_DELAY_UNIT * self.register("return_delay_time")

    def hears(self, bus_baud: float) -> bool:
        """Powered and within the 3 % baud tolerance of the bus. (Asked for every byte: Baud
        Rate read by its address, 4.)"""
        return self.powered and abs(baud_of(self.table[4]) - bus_baud) <= 0.03 * bus_baud

    def condition_bits(self) -> int:
        """Error bits of lasting conditions: voltage, temperature, overload. (By address, as
        step(): it runs at every step.)"""
        t = self.table
        bits = 0
        volts10 = round(self.voltage * 10)
        if not t[12] <= volts10 <= t[13]:                          # Min / Max Voltage Limit
            bits |= ERR_VOLTAGE
        if self.temperature > t[11]:                               # Temperature Limit
            bits |= ERR_OVERHEATING
        if self.overload:
            bits |= ERR_OVERLOAD
        return bits

    @property
    def alarm_led_blinking(self) -> bool:
        return bool((self._last_error | self.condition_bits()) & self.register("alarm_led"))

    # --------------------------------------------------------- power, reset

    def _reset_eeprom(self) -> None:
        self.table[:24] = bytes(24)
        for name, value in EEPROM_DEFAULTS.items():
            self.set_register(name, value)
        self.set_register("firmware_version", self.firmware_version)

    def power_on(self) -> None:
        """Power applied: the RAM area takes its initial values, the EEPROM area stays."""
        self.powered = True
        self.table[24:] = bytes(TABLE_SIZE - 24)
        for name, value in RAM_DEFAULTS.items():
            self.set_register(name, value)
        self.set_register("goal_position", self._quantised())
        self.set_register("torque_limit", self.register("max_torque"))
        self._profile = self._pos
        self._pending = None
        self._last_error = 0
        self._rx.clear()
        self._update_present(0.0, 0.0)

    def power_off(self) -> None:
        self.powered = False

    def turn_by_hand(self, position: float) -> None:
        """Someone turns the shaft to `position` (units), as on the bench with the torque off."""
        self._pos = self._profile = float(position)
        self._update_present(0.0, 0.0)

    def factory_reset(self) -> None:
        """The whole table back to factory values: ID 1, 1 Mbps."""
        self._reset_eeprom()
        self.power_on()

    # ------------------------------------------------------------- receiving

    @staticmethod
    def one_packet(data: bytes) -> bool:
        """data is one whole packet as receive() parses it: from an empty buffer, a packet
        is complete only at its last byte."""
        return (len(data) >= 6 and data[0] == data[1] == 0xFF and data[2] != 0xFF and data[3] >= 2
                and len(data) == data[3] + 4)

    def receive(self, byte: int, t: float) -> Reply | None:
        """One byte from the wire, whose stop bit ended at time t (s)."""
        rx = self._rx
        if rx and t - self._rx_time > BYTE_GAP_TIMEOUT:
            rx.clear()
        self._rx_time = t
        rx.append(byte)
        n = len(rx)
        if n <= 2:
            if byte != 0xFF:
                rx.clear()
            return None
        if n == 3 and byte == 0xFF:      # FF FF FF: still the header
            rx.pop()
            return None
        if n == 4 and byte < 2:          # LEN counts at least INST and CHK
            rx.clear()
            return None
        if n < 4 or n < rx[3] + 4:
            return None
        pkt = bytes(rx)
        rx.clear()
        if self.before_packet is not None:
            self.before_packet()
        return self._on_packet(pkt)

    def _answers(self, inst: int) -> bool:
        level = self.register("status_return_level")
        if inst == INST_PING:
            return True
        if inst == INST_READ:
            return level >= 1
        return level >= 2

    def _on_packet(self, pkt: bytes) -> Reply | None:
        pid, inst, params = pkt[2], pkt[4], pkt[5:-1]
        if pid not in (self.id, BROADCAST_ID):
            return None
        # Decided before the instruction runs: a WRITE changing SRL, ID or the return delay
        # (or a RESET) is answered the old way, from the old ID.
        answer = pid != BROADCAST_ID and self._answers(inst)
        reply_id, delay = self.id, self.return_delay
        if checksum(pkt[2:-1]) != pkt[-1]:
            error, data = ERR_CHECKSUM, b""
            answer = answer and self.reply_to_bad_checksum
        else:
            error, data = self._execute(inst, params, pid == BROADCAST_ID)
        self._raise(error)
        if not answer:
            return None
        return Reply(delay, packet(reply_id, error | self.condition_bits(), data))

    def _raise(self, error: int) -> None:
        """Alarm LED and Shutdown semantics for the error bits of one instruction."""
        self._last_error = error
        if (error | self.condition_bits()) & self.register("shutdown"):
            self.set_register("torque_limit", 0)

    # ------------------------------------------------------------ executing

    def _execute(self, inst: int, params: bytes, broadcast: bool) -> tuple[int, bytes]:
        """Run one instruction; returns (error bits, status parameters)."""
        if inst == INST_PING:
            return 0, b""
        if inst == INST_READ:
            if len(params) != 2:
                return ERR_INSTRUCTION, b""
            addr, n = params
            if n == 0 or addr + n > TABLE_SIZE:
                return ERR_RANGE, b""
            if addr < 42 and addr + n > 40:
                self._latch_load()
            return 0, bytes(self.table[addr:addr + n])
        if inst in (INST_WRITE, INST_REG_WRITE):
            if len(params) < 2:
                return ERR_INSTRUCTION, b""
            addr, data = params[0], bytes(params[1:])
            new, error = self._checked_write(addr, data)
            if not error:
                if inst == INST_WRITE:
                    self.table = new
                else:
                    self._pending = (addr, data)
                    self.set_register("registered", 1)
            return error, b""
        if inst == INST_ACTION:
            if self._pending is None:
                return ERR_INSTRUCTION, b""
            addr, data = self._pending
            self._pending = None
            self.set_register("registered", 0)
            new, error = self._checked_write(addr, data)   # limits may have changed since
            if not error:
                self.table = new
            return error, b""
        if inst == INST_RESET:
            if broadcast:
                return 0, b""           # not allowed: ignored
            if self.locked:
                return ERR_RANGE, b""
            self.factory_reset()
            return 0, b""
        if inst == INST_SYNC_WRITE:
            return self._sync_write(params, broadcast), b""
        return ERR_INSTRUCTION, b""

    def _sync_write(self, params: bytes, broadcast: bool) -> int:
        if not broadcast or len(params) < 2:
            return ERR_INSTRUCTION
        addr, size, entries = params[0], params[1], params[2:]
        if size == 0 or len(entries) % (size + 1):
            return ERR_INSTRUCTION
        for i in range(0, len(entries), size + 1):
            if entries[i] == self.id:
                new, error = self._checked_write(addr, bytes(entries[i + 1:i + 1 + size]))
                if not error:
                    self.table = new
                return error
        return 0

    def _checked_write(self, addr: int, data: bytes) -> tuple[bytearray | None, int]:
        """The table after writing data at addr, or (None, error bits) if refused."""
        end = addr + len(data)
        if end > TABLE_SIZE:
            return None, ERR_RANGE
        touched = {_REG_AT[a] for a in range(addr, end)}
        if None in touched:
            return None, ERR_RANGE
        new = bytearray(self.table)
        new[addr:end] = data

        def value(r: Register) -> int:
            return int.from_bytes(new[r.addr:r.addr + r.size], "little")

        wheel = value(REG["cw_angle_limit"]) == 0 and value(REG["ccw_angle_limit"]) == 0
        for r in touched:
            if r.write_range is None or r.addr < addr or r.addr + r.size > end:
                return None, ERR_RANGE      # read-only, or half of a 2-byte register
            if self.locked and r.addr not in LOCKABLE_FREE:
                return None, ERR_RANGE
            lo, hi = r.write_range
            if r.name == "moving_speed" and not wheel:
                hi = 1023
            if not lo <= value(r) <= hi:
                return None, ERR_RANGE
        if REG["goal_position"] in touched and not wheel:
            if not value(REG["cw_angle_limit"]) <= value(REG["goal_position"]) <= value(REG["ccw_angle_limit"]):
                return None, ERR_ANGLE_LIMIT
        return new, 0

    # --------------------------------------------------------------- motion

    def max_speed(self) -> float:
        """No-load speed cap in units/s: 59 rpm at 12 V, proportional to the supply."""
        return NO_LOAD_RPM * max(self.voltage, 0.0) / NOMINAL_VOLTAGE * UNITS_PER_S_PER_RPM

    def stall_torque(self) -> float:
        """The motor's full output in N m: 1.5 N m at 12 V, proportional to the supply."""
        return STALL_TORQUE_NM * max(self.voltage, 0.0) / NOMINAL_VOLTAGE

    def present_load(self) -> int:
        """Present Load now: the torque the motor applies to hold the shaft against the outside
        torque, 0..1023 of its stall torque (capped at Torque Limit), bit 10 set when it is CW;
        0 with the torque off."""
        stall = self.stall_torque()
        if not self.torque_on or self.outside_torque is None or stall <= 0:
            return 0
        limit = self.register("torque_limit")
        applied = -self.outside_torque()               # N m, CCW positive
        magnitude = min(round(abs(applied) / stall * 1023), limit, 1023)
        return magnitude | (0x400 if applied < 0 and magnitude else 0)

    def _latch_load(self) -> None:
        load = self.present_load()
        self.table[40], self.table[41] = load & 0xFF, load >> 8

    def commanded_speed(self) -> float:
        """Joint-mode speed toward the goal in units/s: Moving Speed, capped; 0 = the cap."""
        units = self.register("moving_speed") & 0x3FF
        cap = self.max_speed()
        return cap if units == 0 else min(units * RPM_PER_SPEED_UNIT * UNITS_PER_S_PER_RPM, cap)

    def step(self, dt: float, present: bool = True) -> None:
        """Advance the servo by dt seconds; present=False leaves the Present registers to a
        later step (nothing reads them in between). (Reads the table by address: this runs
        at every step of the bus, so it avoids the by-name register helpers.)"""
        if not self.powered or dt <= 0:
            return
        t = self.table
        if t[18] and self.condition_bits() & t[18]:               # Shutdown
            t[34] = t[35] = 0                                      # Torque Limit
        start = self._pos
        if t[24] and (t[34] or t[35]):                             # Torque Enable, Torque Limit
            n = 1 if dt <= MAX_SUBSTEP else math.ceil(dt / MAX_SUBSTEP)
            if self._plain_motion and (t[6] or t[7] or t[8] or t[9]):   # joint mode
                self._follow(dt / n, n)
            else:
                for _ in range(n):
                    self._advance(dt / n)
        else:
            self._profile = self._pos   # limp: no load is modelled, the shaft stays put
        if present:
            self._update_present(start, dt)

    def resting(self) -> bool:
        """A step now would leave the shaft and its profile where they are: at the same
        supply, the same Present registers too."""
        if not self.powered:
            return True
        t = self.table
        if not self._plain_motion or not (t[6] or t[7] or t[8] or t[9]):
            return False                                   # wheel mode, or a subclass's own motion
        if not (t[24] and (t[34] or t[35])):
            return self._profile == self._pos              # limp
        if self._profile != (t[30] | t[31] << 8):
            return False
        err = self._profile - self._pos
        return err == 0 or (self.deadband and self.time_constant > 0 and abs(err) <= t[27 if err > 0 else 26])

    def _advance(self, h: float) -> None:
        t = self.table
        if not (t[6] or t[7] or t[8] or t[9]):                    # wheel mode: both angle limits 0
            speed = t[32] | t[33] << 8
            direction = -1.0 if speed & 0x400 else 1.0     # bit 10 set = CW = decreasing
            rate = (speed & 0x3FF) / 1023 * self.max_speed()
            self._pos = self._profile = (self._pos + direction * rate * h) % 1024
            return
        self._follow(h, 1)

    def _follow(self, h: float, n: int) -> None:
        """Joint mode: n substeps of h seconds toward Goal Position at Moving Speed. (The
        table and the voltage do not change within a step: read once.)"""
        t = self.table
        goal = t[30] | t[31] << 8
        pos, profile = self._pos, self._profile
        if profile == goal:                     # at rest: each substep would leave it so
            err = profile - pos
            if err == 0 or (self.deadband and self.time_constant > 0 and abs(err) <= t[27 if err > 0 else 26]):
                return
        units = (t[32] | t[33] << 8) & 0x3FF
        cap = self.max_speed()
        speed = cap if units == 0 else min(units * RPM_PER_SPEED_UNIT * UNITS_PER_S_PER_RPM, cap)
        travel = speed * h
        lag = self.time_constant > 0
        pull = -math.expm1(-h / self.time_constant) if lag else 0.0
        for _ in range(n):
            if abs(goal - profile) <= travel:
                profile = float(goal)
            else:
                profile += math.copysign(travel, goal - profile)
            if lag:
                err = profile - pos
                if self.deadband and abs(err) <= t[27 if err > 0 else 26]:   # CCW / CW Compliance Margin
                    continue
                pos += err * pull
            else:
                pos = profile
        self._pos, self._profile = pos, profile

    def _quantised(self) -> int:
        q = round(self._pos)
        return 0 if q < 0 else 1023 if q > 1023 else q

    def _update_present(self, start: float, dt: float) -> None:
        t = self.table
        q = round(self._pos)
        q = 0 if q < 0 else 1023 if q > 1023 else q                 # (as _quantised)
        t[36], t[37] = q & 0xFF, q >> 8                              # Present Position
        rate = (self._pos - start) / dt if dt > 0 else 0.0      # units/s, + = CCW
        if rate:                                                # (a shaft at rest: 0, and quicker)
            magnitude = min(round(abs(rate) / UNITS_PER_S_PER_RPM / RPM_PER_SPEED_UNIT), 1023)
            speed = magnitude | (0x400 if rate < 0 else 0)
            t[38], t[39] = speed & 0xFF, speed >> 8                  # Present Speed
        else:
            t[38] = t[39] = 0
        volts10 = round(self.voltage * 10)
        t[42] = 0 if volts10 < 0 else 255 if volts10 > 255 else volts10      # Present Voltage
        degrees = round(self.temperature)
        t[43] = 0 if degrees < 0 else 255 if degrees > 255 else degrees      # Present Temperature
        driven = t[24] and (t[34] or t[35])
        if not (t[6] or t[7] or t[8] or t[9]):
            moving = driven and ((t[32] | t[33] << 8) & 0x3FF) > 0
        else:
            goal = t[30] | t[31] << 8
            moving = driven and (self._profile != goal or q != goal)
        t[46] = int(bool(moving))                                    # Moving


@dataclass
class Supply:
    """The servos' supply as it reaches them: a battery of `volts` (open circuit) behind
    `resistance` ohms (its cells, the wiring and the board's supply switch), each powered
    servo drawing `idle_amps` at rest and up to `moving_amps` more in proportion to its
    speed as a share of its no-load speed at that supply. The voltage sags as the servos
    move (their speed cap with it) and Present Voltage reads it.

    The AX-12A's figures: 50 mA on standby and 1.5 A at stall (12 V) in the e-manual;
    `moving_amps` is the current of a joint turning at full speed under the arm's own
    weight and inertia, a third of stall (an assumption, not a measured figure). A 3S
    lithium battery spends a flight between 12.6 V (full) and about 10 V under load.
    """
    volts: float = 11.1
    resistance: float = 0.25
    idle_amps: float = 0.05
    moving_amps: float = 0.5

    def sagged(self, speeds: list[float]) -> float:
        """The voltage at the servos when they turn at these shares of their no-load speed."""
        amps = sum(self.idle_amps + self.moving_amps * min(abs(s), 1.0) for s in speeds)
        return self.volts - self.resistance * amps


def supply_of(supply: Supply | float | None) -> Supply:
    """A Supply from itself, its open-circuit volts, or None (the default battery)."""
    if isinstance(supply, Supply):
        return supply
    return Supply() if supply is None else Supply(volts=float(supply))


class AX12Bus:
    """A half-duplex Protocol 1.0 bus: the master's bytes, servos, and their replies in time.

    baud  bus speed in bit/s; a servo listens only if its Baud Rate register is within 3 %
    echo  the master also receives its own bytes (a single-wire UART without an echo
          filter), at the times they leave the wire
    lazy  step the servos only when a byte reaches them, on power switching and on `sync()`
          (long simulations: far fewer steps; the motion is integrated over longer
          intervals, in substeps of at most MAX_SUBSTEP). Call sync() before reading a
          servo's state.
    """

    def __init__(self, servos=(), *, baud: float = 1_000_000, echo: bool = False, lazy: bool = False,
                 supply: Supply | None = None):
        self.baud = baud
        self.echo = echo
        self.lazy = lazy
        self.supply = supply
        self.time = 0.0
        self._servo_time = 0.0
        self.servos: list[AX12] = []
        self._tx: deque[tuple[float, int]] = deque()   # master bytes: (end of stop bit, byte)
        self._due: deque[float] = deque()   # times of the master's bytes that may complete a packet
        self._tx_end = 0.0
        self._rx: list[tuple[float, int, int]] = []     # heap of (arrival, order, byte)
        self._order = itertools.count()
        for servo in servos:
            self.add(servo)

    def add(self, servo: AX12) -> AX12:
        self.servos.append(servo)
        servo.before_packet = self.sync
        return servo

    def servo(self, id_: int) -> AX12:
        for s in self.servos:
            if s.id == id_:
                return s
        raise KeyError(id_)

    @property
    def byte_time(self) -> float:
        return BITS_PER_BYTE / self.baud

    def write(self, data: bytes) -> float:
        """The master transmits data, starting now or when its previous bytes have left.
        Returns the time the last stop bit ends."""
        data = bytes(data)
        # One whole packet onto a quiet bus can make a servo act only at its last byte.
        whole = not self._tx and all(not s._rx and s.one_packet(data) for s in self.servos)
        t = max(self.time, self._tx_end)
        for k, byte in enumerate(data, 1):
            t += self.byte_time
            self._tx.append((t, byte))
            if k == len(data) or not whole:
                self._due.append(t)
            if self.echo:
                heapq.heappush(self._rx, (t, next(self._order), byte))
        self._tx_end = t
        return t

    def read(self, n: int | None = None) -> bytes:
        """Up to n (default all) received bytes that have arrived by now."""
        out = bytearray()
        while self._rx and self._rx[0][0] <= self.time and (n is None or len(out) < n):
            out.append(heapq.heappop(self._rx)[2])
        return bytes(out)

    def available(self) -> int:
        """How many received bytes have arrived by now."""
        return sum(1 for t, _, _ in self._rx if t <= self.time)

    def next_due(self) -> float:
        """When a byte of the master's in flight next may make a servo act (s; inf: none).
        No new reply can arrive before then."""
        return self._due[0] if self._due else math.inf

    def take_arrivals(self, until: float) -> list[tuple[float, int]]:
        """The received bytes that arrive by `until`, whenever that is: (arrival, byte), in
        order. (For a master that holds them until their time.)"""
        out = []
        while self._rx and self._rx[0][0] <= until:
            t, _, byte = heapq.heappop(self._rx)
            out.append((t, byte))
        return out

    @property
    def busy(self) -> bool:
        """Bytes still on their way (the master's, or replies not yet arrived)."""
        return bool(self._tx) or any(t > self.time for t, _, _ in self._rx)

    def step(self, dt: float) -> None:
        self.run_until(self.time + dt)

    def run_until(self, end: float, present: bool = True) -> None:
        """Advance to time `end`, delivering the master's bytes to the servos on the way
        (present: as AX12.step's, for the motion up to `end`)."""
        while self._tx and self._tx[0][0] <= end:
            t, byte = self._tx.popleft()
            self.time = max(self.time, t)      # the motion is brought up to t once a packet is whole
            while self._due and self._due[0] <= t:
                self._due.popleft()
            for servo in self.servos:
                if servo.hears(self.baud):
                    reply = servo.receive(byte, t)
                    if reply is not None:
                        self._send_reply(t + reply.delay, reply.data)
        self._move_to(end, present)

    def settle(self) -> float:
        """Advance until nothing is in flight; returns the time that took."""
        start = self.time
        while self.busy:
            pending = [t for t, _ in self._tx] + [t for t, _, _ in self._rx]
            self.run_until(max(pending))
        return self.time - start

    def power(self, on: bool) -> None:
        """Switch the servos' supply (the board's MOSFET)."""
        self.sync()
        for servo in self.servos:
            if on and not servo.powered:
                servo.power_on()
            elif not on:
                servo.power_off()

    def set_supply_voltage(self, volts: float) -> None:
        """The supply's voltage from now on (with a Supply: its open-circuit voltage, sagging
        as the servos move)."""
        self.sync()
        if self.supply is not None:
            self.supply.volts = volts
        for servo in self.servos:
            servo.voltage = volts

    def _move_to(self, t: float, present: bool = True) -> None:
        if t > self.time:
            self.time = t
            if not self.lazy:
                self.sync(present)

    def sync(self, present: bool = True) -> None:
        """Bring the servos' motion up to the bus time."""
        if self.time > self._servo_time:
            dt = self.time - self._servo_time
            before = [servo._pos for servo in self.servos]
            for servo in self.servos:
                servo.step(dt, present)
            self._servo_time = self.time
            if self.supply is not None:
                self._sag(before, dt)

    def _sag(self, before: list[float], dt: float) -> None:
        """The supply's voltage after an interval of dt in which the shafts moved from `before`."""
        shares = []
        for s, p in zip(self.servos, before):
            if s.powered and s._pos == p:
                shares.append(0.0)                      # (a shaft at rest, at any cap)
            elif s.powered:
                cap = s.max_speed()
                shares.append(abs(s._pos - p) / dt / cap if cap > 0 else 0.0)
        volts = self.supply.sagged(shares)
        for servo in self.servos:
            servo.voltage = volts

    def _send_reply(self, start: float, data: bytes) -> None:
        for k, byte in enumerate(data):
            heapq.heappush(self._rx, (start + (k + 1) * self.byte_time, next(self._order), byte))


class SdkPort:
    """What DynamixelSDK's packet handlers need of a PortHandler, wired to an AX12Bus.

    Reading lets simulated time run until every reply has arrived, so the SDK sees its
    answer (or a timeout, when none comes) without waiting in real time.
    """

    def __init__(self, bus: AX12Bus):
        self.bus = bus
        self.is_open = True
        self.is_using = False
        self.baudrate = bus.baud
        self.tx_time_per_byte = 1000.0 * BITS_PER_BYTE / bus.baud   # ms, as the SDK computes it

    def openPort(self):
        return True

    def closePort(self):
        self.is_open = False

    def clearPort(self):
        self.bus.read()

    def writePort(self, packet_bytes):
        self.bus.write(bytes(packet_bytes))
        return len(packet_bytes)

    def readPort(self, length):
        self.bus.settle()
        return self.bus.read(length)

    def getBytesAvailable(self):
        return self.bus.available()

    def setPacketTimeout(self, packet_length):
        pass

    def setPacketTimeoutMillis(self, msec):
        pass

    def isPacketTimeout(self):
        return not self.bus.busy     # nothing more can arrive
