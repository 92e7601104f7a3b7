"""Dynamixel X-series servos (XM430-W350, XL430-W250) on a Protocol 2.0 bus: a simulator.

Written from the ROBOTIS e-manual: the servos' pages (emanual.robotis.com/docs/en/dxl/x/xm430-w350/,
.../xl430-w250/: specifications, control table, Profile Velocity(112) and Profile
Acceleration(108), Hardware Error Status(70), Shutdown(63)) and the Protocol 2.0 page
(emanual.robotis.com/docs/en/dxl/protocol2/: packet format, byte stuffing, CRC, error codes).
Time only moves when `step()` is called. An `XServo` speaks the same byte interface as
`ax12_sim.AX12` (`hears`, `receive`, `step`), so an `AX12Bus` carries its bytes with their
wire timing and `SdkPort` lets DynamixelSDK's Protocol2PacketHandler talk to it:

    bus = AX12Bus([XServo(XM430_W350, id=1, table={"baud_rate": 3})], baud=1_000_000)

Where the e-manual is silent this simulator chooses, and says so:
- A corrupted instruction (bad CRC) gets no answer (the servo cannot trust its ID).
- A WRITE or SYNC_WRITE entry is all or nothing. A missing or read-only address, or an EEPROM
  address while Torque Enable is 1, gives the Access error; part of a multi-byte register the
  Data Length error; a value outside the register's range the Data Range error; a Goal
  Position outside Min/Max Position Limit the Data Limit error.
- READ of addresses the table does not hold (reserved ones inside it) reads 0; past its end
  (address 252) gives the Access error.
- Hardware Error Status collects the lasting conditions (input voltage outside its limits,
  temperature above Temperature Limit, a load beyond the stall torque at the supply) whose bit
  is set in Shutdown (default 52: overheating, electrical shock, overload; not the voltage).
  It then clears Torque Enable; writing Torque Enable = 1 gives the Result Fail error until
  REBOOT, which clears the status (a condition that lasts is found again at the next step).
- Goal PWM(100) starts at PWM Limit(36) and takes -885..885 (the e-manual bounds it by PWM
  Limit); it is kept, but its cap on the motor's output is not modelled.
- Only Position Control Mode (3) with a velocity-based profile moves the shaft; in the other
  modes the shaft holds. A new goal ahead keeps the profile's speed (velocity override); one
  behind it starts the profile again from rest. The shaft follows the profile through the
  first-order lag in substeps of at most 1 ms.
- Indirect Address 1..28 (168..223) and Indirect Data 1..28 (224..251) are modelled for reading:
  Indirect Data k reads the byte at the address Indirect Address k holds (its initial value
  224 + k - 1 is Indirect Data k itself, which holds 0). Writing through Indirect Data is not
  modelled (the Access error); Indirect Address takes any RAM address (64..661), and an address
  this table does not hold reads 0.
- In a SYNC_READ the k-th listed servo answers after the k servos before it, each taking its
  Return Delay Time and a status packet with the data asked for (no stuffing assumed in theirs).
- Broadcast PING is answered after Return Delay Time: the e-manual's order among several
  servos is not modelled (their answers would overlap on the bus).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from uavarm.sim.ax12_sim import (BITS_PER_BYTE, BROADCAST_ID, BYTE_GAP_TIMEOUT, MAX_SUBSTEP,
                                 NOMINAL_VOLTAGE, RETURN_DELAY_UNIT, Reply)

HEADER = b"\xff\xff\xfd\x00"

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83

# Status error byte: an error number in bits 0-6, the alert bit 7 (Hardware Error Status != 0)
ERR_RESULT_FAIL = 0x01
ERR_INSTRUCTION = 0x02
ERR_DATA_RANGE = 0x04
ERR_DATA_LENGTH = 0x05
ERR_DATA_LIMIT = 0x06
ERR_ACCESS = 0x07
ALERT = 0x80

# Hardware Error Status / Shutdown bits
HW_INPUT_VOLTAGE = 0x01
HW_OVERHEATING = 0x04
HW_ELECTRICAL_SHOCK = 0x10
HW_OVERLOAD = 0x20

TABLE_SIZE = 252                       # addresses 0..251 (Indirect Data 28 is the last)
EEPROM_END = 64                        # Torque Enable(64) opens the RAM area
INDIRECT_ADDRESS = 168                 # Indirect Address 1..28, 2 bytes each
INDIRECT_DATA = 224                    # Indirect Data 1..28
INDIRECTS = 28
UNITS_PER_TURN = 4096
RPM_PER_VELOCITY_UNIT = 0.229          # Profile Velocity, Velocity Limit, Present Velocity
RPM2_PER_ACCELERATION_UNIT = 214.577   # Profile Acceleration, rev/min^2
AMPS_PER_CURRENT_UNIT = 0.00269        # Present Current (XM430)
BAUD_RATES = (9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
POSITION_CONTROL = 3
PWM_MAX = 885                          # PWM Limit's range and factory value (100 %)


def units_per_s(rpm: float) -> float:
    return rpm * UNITS_PER_TURN / 60.0


@dataclass(frozen=True)
class Model:
    """One servo type's facts from its e-manual page (at 12 V)."""
    name: str
    number: int
    no_load_rpm: float
    stall_torque_nm: float
    stall_amps: float
    temperature_limit: int
    max_voltage_limit: int          # 0.1 V; also the top of both voltage limits' range
    min_voltage_limit: int          # and the bottom of it
    velocity_limit: int
    current_sensing: bool           # Present Current (XM430) or Present Load (XL430) at 126


XM430_W350 = Model("XM430-W350", 1020, 46.0, 4.1, 2.3, 80, 160, 95, 350, True)
XL430_W250 = Model("XL430-W250", 1060, 61.0, 1.5, 1.4, 72, 140, 60, 265, False)
MODELS = {m.name: m for m in (XM430_W350, XL430_W250)}


@dataclass(frozen=True)
class Register:
    addr: int
    size: int
    name: str
    write_range: tuple[int, int] | None   # None: read-only
    signed: bool = False


def registers(model: Model) -> tuple[Register, ...]:
    volts = (model.min_voltage_limit, model.max_voltage_limit)
    return (
        Register(0, 2, "model_number", None),
        Register(6, 1, "firmware_version", None),
        Register(7, 1, "id", (0, 252)),
        Register(8, 1, "baud_rate", (0, 7)),
        Register(9, 1, "return_delay_time", (0, 254)),
        Register(10, 1, "drive_mode", (0, 13)),
        Register(11, 1, "operating_mode", (0, 16)),
        Register(24, 4, "moving_threshold", (0, 1023)),
        Register(31, 1, "temperature_limit", (0, 100)),
        Register(32, 2, "max_voltage_limit", volts),
        Register(34, 2, "min_voltage_limit", volts),
        Register(36, 2, "pwm_limit", (0, PWM_MAX)),
        Register(44, 4, "velocity_limit", (0, 1023)),
        Register(48, 4, "max_position_limit", (0, 4095)),
        Register(52, 4, "min_position_limit", (0, 4095)),
        Register(63, 1, "shutdown", (0, 255)),
        Register(64, 1, "torque_enable", (0, 1)),
        Register(65, 1, "led", (0, 1)),
        Register(68, 1, "status_return_level", (0, 2)),
        Register(69, 1, "registered_instruction", None),
        Register(70, 1, "hardware_error_status", None),
        Register(100, 2, "goal_pwm", (-PWM_MAX, PWM_MAX), True),
        Register(108, 4, "profile_acceleration", (0, 32767)),
        Register(112, 4, "profile_velocity", (0, 32767)),
        Register(116, 4, "goal_position", (0, 4095)),
        Register(122, 1, "moving", None),
        Register(126, 2, "present_current" if model.current_sensing else "present_load", None, True),
        Register(128, 4, "present_velocity", None, True),
        Register(132, 4, "present_position", None, True),
        Register(144, 2, "present_input_voltage", None),
        Register(146, 1, "present_temperature", None),
        *(Register(INDIRECT_ADDRESS + 2 * k, 2, f"indirect_address_{k + 1}", (EEPROM_END, 661))
          for k in range(INDIRECTS)),
        *(Register(INDIRECT_DATA + k, 1, f"indirect_data_{k + 1}", None) for k in range(INDIRECTS)),
    )


def defaults(model: Model) -> dict[str, int]:
    """Initial values (Goal Position and the Present ones are set from the shaft)."""
    return {
        "model_number": model.number, "id": 1, "baud_rate": 1, "return_delay_time": 250,
        "drive_mode": 0, "operating_mode": POSITION_CONTROL, "moving_threshold": 10,
        "temperature_limit": model.temperature_limit,
        "max_voltage_limit": model.max_voltage_limit, "min_voltage_limit": model.min_voltage_limit,
        "pwm_limit": PWM_MAX, "velocity_limit": model.velocity_limit, "max_position_limit": 4095,
        "min_position_limit": 0, "shutdown": HW_OVERHEATING | HW_ELECTRICAL_SHOCK | HW_OVERLOAD,
        "status_return_level": 2,
    }


def _crc_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = (crc << 1) ^ 0x8005 if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes, crc: int = 0) -> int:
    """The Protocol 2.0 CRC-16 (polynomial 0x8005, MSB first, initial 0), table-driven."""
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuffed(body: bytes) -> bytes:
    """Byte stuffing: an FD after every FF FF FD."""
    out = bytearray()
    for b in body:
        out.append(b)
        if b == 0xFD and out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def unstuffed(body: bytes) -> bytes:
    """Byte stuffing undone: the FD that follows each FF FF FD dropped."""
    out = bytearray()
    stuffing = False
    for b in body:
        if stuffing and b == 0xFD:
            stuffing = False
            continue
        out.append(b)
        stuffing = out[-3:] == b"\xff\xff\xfd"
    return bytes(out)


def instruction_packets(data: bytes) -> list[tuple[int, int, bytes]]:
    """(id, instruction, params unstuffed) of every instruction packet with a good CRC in data."""
    out, i = [], data.find(HEADER)
    while 0 <= i and i + 10 <= len(data):
        end = i + 7 + int.from_bytes(data[i + 5:i + 7], "little")
        pkt = data[i:end]
        if len(pkt) == end - i and crc16(pkt[:-2]) == int.from_bytes(pkt[-2:], "little") and pkt[7] != INST_STATUS:
            out.append((pkt[4], pkt[7], unstuffed(pkt[8:-2])))
            i = data.find(HEADER, end)
        else:
            i = data.find(HEADER, i + 1)
    return out


def status_packet(id_: int, error: int, params: bytes = b"") -> bytes:
    body = stuffed(bytes([INST_STATUS, error]) + bytes(params))
    head = HEADER + bytes([id_]) + (len(body) + 2).to_bytes(2, "little")
    return head + body + crc16(head + body).to_bytes(2, "little")


def along_profile(d: float, u: float, vmax: float, accel: float, t: float) -> tuple[float, float]:
    """The trapezoidal profile toward a goal d units away, starting at speed u toward it:
    (distance covered, speed) after t seconds. Accelerates at `accel` (inf: at once) up to
    `vmax`, or less where the distance is too short (a triangle), cruises, and brakes to stop
    on the goal. Evaluated exactly, so stepping it in any steps gives the same motion."""
    if math.isinf(accel):
        covered = min(d, vmax * t)
        return covered, vmax if covered < d else 0.0
    u = min(u, vmax)
    peak = max(u, min(vmax, math.sqrt(accel * d + u * u / 2)))   # (peak^2 - u^2 + peak^2) / 2a = d
    if peak <= 0:
        return 0.0, 0.0
    t_up = (peak - u) / accel
    d_up = (u + peak) / 2 * t_up
    t_down = peak / accel
    t_cruise = max(0.0, (d - d_up - peak * t_down / 2) / peak)
    if t <= t_up:
        return min(d, u * t + accel * t * t / 2), u + accel * t
    t -= t_up
    if t <= t_cruise:
        return min(d, d_up + peak * t), peak
    t -= t_cruise
    if t < t_down:
        return min(d, d_up + peak * t_cruise + peak * t - accel * t * t / 2), peak - accel * t
    return d, 0.0


class XServo:
    """One X-series servo: control table, Protocol 2.0 instructions, profiled motion.

    model        XM430_W350 or XL430_W250
    position     initial shaft position in units (0..4095, 2048 = centre)
    voltage      supply in V: the no-load speed and stall torque are in proportion to it
    temperature  degrees C (set the attribute later to overheat it)
    time_constant  s, first-order lag of the shaft behind the profile (0 = none)
    load_torque  N m from outside on the shaft, CCW (position growing) positive (attribute;
                 or outside_torque, a function giving it)
    table        register values to start from, e.g. {"baud_rate": 3, "return_delay_time": 0}
    """

    def __init__(self, model: Model = XM430_W350, id: int = 1, *, position: float = 2048.0,
                 voltage: float = 12.0, temperature: float = 30.0, time_constant: float = 0.0,
                 firmware_version: int = 45, table: dict[str, int] | None = None):
        self.model = model
        self.regs = {r.name: r for r in registers(model)}
        self._at = [None] * TABLE_SIZE
        for r in self.regs.values():
            for a in range(r.addr, r.addr + r.size):
                self._at[a] = r
        self.voltage = voltage
        self.temperature = temperature
        self.time_constant = time_constant
        self.firmware_version = firmware_version   # not given by the e-manual: a choice
        self.load_torque = 0.0
        # or, as AX12's, a function giving it at the moment (gravity on the arm: SimBoard)
        self.outside_torque = None
        self.before_packet = None   # as AX12's: the bus brings the motion up to the packet
        self.powered = True
        self.table = bytearray(TABLE_SIZE)
        self._pos = float(position)
        self._profile = float(position)          # the profile's position, units
        self._profile_speed = 0.0                # the profile's velocity, units/s
        self._rx = bytearray()
        self._rx_time = -math.inf
        settings = {"id": id, **(table or {})}
        unknown = set(settings) - set(self.regs)
        if unknown:
            raise KeyError(f"not {model.name} registers: {sorted(unknown)}")
        for name, value in defaults(model).items():
            self.set_register(name, value)
        self.set_register("firmware_version", firmware_version)
        for name, value in settings.items():
            if self.regs[name].addr < EEPROM_END:
                self.set_register(name, value)
        self.power_on()
        for name, value in settings.items():
            if self.regs[name].addr >= EEPROM_END:
                self.set_register(name, value)

    # ------------------------------------------------------------ registers

    def register(self, name: str) -> int:
        r = self.regs[name]
        return int.from_bytes(self.table[r.addr:r.addr + r.size], "little", signed=r.signed)

    def set_register(self, name: str, value: int) -> None:
        """Set a register directly, without the checks of a WRITE (test setup, faults)."""
        r = self.regs[name]
        self.table[r.addr:r.addr + r.size] = int(value).to_bytes(r.size, "little", signed=r.signed)

    @property
    def id(self) -> int:
        return self.table[7]

    @property
    def position(self) -> float:
        """The shaft position in units, unquantised."""
        return self._pos

    @property
    def torque_on(self) -> bool:
        return self.powered and self.table[64] == 1

    @property
    def byte_time(self) -> float:
        return BITS_PER_BYTE / BAUD_RATES[self.table[8]]

    def hears(self, bus_baud: float) -> bool:
        """Powered and within 3 % of the bus's baud (as the AX-12A model)."""
        return self.powered and abs(BAUD_RATES[self.table[8]] - bus_baud) <= 0.03 * bus_baud

    # --------------------------------------------------------- power, reboot

    def power_on(self) -> None:
        """Power applied (or REBOOT): the RAM area takes its initial values."""
        self.powered = True
        self.table[EEPROM_END:] = bytes(TABLE_SIZE - EEPROM_END)
        self.set_register("status_return_level", 2)
        self.set_register("goal_pwm", self.register("pwm_limit"))
        for k in range(INDIRECTS):
            self.set_register(f"indirect_address_{k + 1}", INDIRECT_DATA + k)
        self._profile, self._profile_speed = self._pos, 0.0
        self.set_register("goal_position", self._quantised())
        self._rx.clear()
        self._update_present(0.0)

    def power_off(self) -> None:
        self.powered = False

    def turn_by_hand(self, position: float) -> None:
        """Someone turns the shaft to `position` (units), as on the bench with the torque off."""
        self._pos = self._profile = float(position)
        self._profile_speed = 0.0
        self._update_present(0.0)

    # ------------------------------------------------------------ hardware

    def max_speed(self) -> float:
        """No-load speed in units/s at the supply: the e-manual's at 12 V, in proportion."""
        return units_per_s(self.model.no_load_rpm) * max(self.voltage, 0.0) / NOMINAL_VOLTAGE

    def stall_torque(self) -> float:
        return self.model.stall_torque_nm * max(self.voltage, 0.0) / NOMINAL_VOLTAGE

    def conditions(self) -> int:
        """Hardware error bits of the lasting conditions, whether Shutdown selects them or not."""
        bits = 0
        volts10 = round(self.voltage * 10)
        if not self.register("min_voltage_limit") <= volts10 <= self.register("max_voltage_limit"):
            bits |= HW_INPUT_VOLTAGE
        if self.temperature > self.table[31]:
            bits |= HW_OVERHEATING
        if self.torque_on and abs(self.load_torque) > self.stall_torque():
            bits |= HW_OVERLOAD
        return bits

    def _check_hardware(self) -> None:
        found = self.conditions() & self.table[63]
        if found:
            self.table[70] |= found
        if self.table[70]:
            self.table[64] = 0                     # Torque Enable off until REBOOT

    # ------------------------------------------------------------- receiving

    @staticmethod
    def one_packet(data: bytes) -> bool:
        """data is one whole packet as receive() parses it: from an empty buffer, a packet
        is complete only at its last byte."""
        return len(data) >= 10 and data[:4] == HEADER and len(data) == 7 + (data[5] | data[6] << 8)

    def receive(self, byte: int, t: float) -> Reply | None:
        """One byte from the wire, whose stop bit ended at time t (s)."""
        rx = self._rx
        if rx and t - self._rx_time > BYTE_GAP_TIMEOUT:
            rx.clear()
        self._rx_time = t
        rx.append(byte)
        n = len(rx)
        if n <= 4:
            while rx and rx != HEADER[:len(rx)]:
                del rx[0]                          # not (yet) a header: slide on
            return None
        if n < 7:
            return None
        length = rx[5] | rx[6] << 8
        if length < 3:                             # LEN counts at least INST and the CRC
            rx.clear()
            return None
        if n < 7 + length:
            return None
        pkt = bytes(rx)
        rx.clear()
        if crc16(pkt[:-2]) != int.from_bytes(pkt[-2:], "little"):
            return None                            # corrupted: no answer
        if self.before_packet is not None:
            self.before_packet()
        return self._on_packet(pkt[4], pkt[7], unstuffed(pkt[8:-2]))

    def _on_packet(self, pid: int, inst: int, params: bytes) -> Reply | None:
        me = self.id
        if inst == INST_SYNC_READ:
            return self._sync_read(params) if pid == BROADCAST_ID else None
        if pid not in (me, BROADCAST_ID):
            return None
        level = self.table[68]                     # decided before the instruction runs
        answer = inst == INST_PING or (level >= 1 and inst == INST_READ) or level >= 2
        answer = answer and (pid != BROADCAST_ID or inst == INST_PING)
        delay = RETURN_DELAY_UNIT * self.table[9]
        error, data = self._execute(inst, params)
        if not answer:
            return None
        return Reply(delay, status_packet(me, self._alert(error), data))

    def _alert(self, error: int) -> int:
        return error | (ALERT if self.table[70] else 0)

    # ------------------------------------------------------------ executing

    def _execute(self, inst: int, params: bytes) -> tuple[int, bytes]:
        if inst == INST_PING:
            return 0, bytes([self.table[0], self.table[1], self.table[6]])
        if inst == INST_READ:
            if len(params) != 4:
                return ERR_INSTRUCTION, b""
            return self._read(params[0] | params[1] << 8, params[2] | params[3] << 8)
        if inst == INST_WRITE:
            if len(params) < 3:
                return ERR_INSTRUCTION, b""
            return self._write(params[0] | params[1] << 8, bytes(params[2:])), b""
        if inst == INST_REBOOT:
            answer = self._alert(0)                # answered as it was, then rebooted
            self.power_on()
            return answer, b""
        if inst == INST_SYNC_WRITE:
            return self._sync_write(params), b""
        return ERR_INSTRUCTION, b""

    def _read(self, addr: int, n: int) -> tuple[int, bytes]:
        if n == 0 or addr + n > TABLE_SIZE:
            return ERR_ACCESS, b""
        where = [self._indirect(a) for a in range(addr, addr + n)]
        if any(126 <= a < 128 for a in where):
            self._latch_current()
        return 0, bytes(self.table[a] if a < TABLE_SIZE else 0 for a in where)

    def _indirect(self, addr: int) -> int:
        """The address a read of addr reads: Indirect Data k's is Indirect Address k's value
        (its own address while at the initial value)."""
        if not INDIRECT_DATA <= addr < INDIRECT_DATA + INDIRECTS:
            return addr
        return self.register(f"indirect_address_{addr - INDIRECT_DATA + 1}")

    def _sync_read(self, params: bytes) -> Reply | None:
        if len(params) < 5:
            return None
        ids = list(params[4:])
        if self.id not in ids:
            return None
        n = params[2] | params[3] << 8
        error, data = self._read(params[0] | params[1] << 8, n)
        if self.table[68] < 1:
            return None
        slot = RETURN_DELAY_UNIT * self.table[9] + (11 + n) * self.byte_time
        delay = ids.index(self.id) * slot + RETURN_DELAY_UNIT * self.table[9]
        return Reply(delay, status_packet(self.id, self._alert(error), data))

    def _sync_write(self, params: bytes) -> int:
        if len(params) < 5:
            return ERR_INSTRUCTION
        addr, size, entries = params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]
        if size == 0 or len(entries) % (size + 1):
            return ERR_INSTRUCTION
        for i in range(0, len(entries), size + 1):
            if entries[i] == self.id:
                return self._write(addr, bytes(entries[i + 1:i + 1 + size]))
        return 0

    def _write(self, addr: int, data: bytes) -> int:
        """Write data at addr, all or nothing; returns the error number (0: written)."""
        end = addr + len(data)
        if end > TABLE_SIZE:
            return ERR_ACCESS
        touched = {self._at[a] for a in range(addr, end)}
        if None in touched or any(r.write_range is None for r in touched):
            return ERR_ACCESS
        if addr < EEPROM_END and self.table[64]:
            return ERR_ACCESS                      # EEPROM locked while the torque is on
        if any(r.addr < addr or r.addr + r.size > end for r in touched):
            return ERR_DATA_LENGTH
        new = bytearray(self.table)
        new[addr:end] = data

        def value(r: Register) -> int:
            return int.from_bytes(new[r.addr:r.addr + r.size], "little", signed=r.signed)

        for r in touched:
            lo, hi = r.write_range
            if not lo <= value(r) <= hi:
                return ERR_DATA_RANGE
        goal = self.regs["goal_position"]
        if goal in touched and not (value(self.regs["min_position_limit"]) <= value(goal)
                                    <= value(self.regs["max_position_limit"])):
            return ERR_DATA_LIMIT
        if self.regs["torque_enable"] in touched and new[64] and self.table[70]:
            return ERR_RESULT_FAIL                 # shut down: only REBOOT brings it back
        self.table = new
        return 0

    # ------------------------------------------------------- current, load

    def motor_torque(self) -> float:
        """The torque the motor applies to hold the shaft against the load, N m (CCW +)."""
        load = self.load_torque if self.outside_torque is None else self.outside_torque()
        return -load if self.torque_on else 0.0

    def _latch_current(self) -> None:
        """Present Current (XM430: 2.69 mA units, through the torque constant at stall) or
        Present Load (XL430: 0.1 % of the stall torque at the supply)."""
        torque = self.motor_torque()
        m = self.model
        if m.current_sensing:
            amps = torque * m.stall_amps / m.stall_torque_nm
            value = round(amps / AMPS_PER_CURRENT_UNIT)
        else:
            stall = self.stall_torque()
            value = round(1000 * torque / stall) if stall > 0 else 0
            value = max(-1000, min(1000, value))
        self.set_register("present_current" if m.current_sensing else "present_load", value)

    # --------------------------------------------------------------- motion

    def step(self, dt: float, present: bool = True) -> None:
        """Advance the servo by dt seconds (present: as AX12.step's)."""
        if not self.powered or dt <= 0:
            return
        self._check_hardware()
        start = self._pos
        if self.torque_on and self.table[11] == POSITION_CONTROL:
            n = max(1, math.ceil(dt / MAX_SUBSTEP))
            for _ in range(n):
                self._advance(dt / n)
        else:
            self._profile, self._profile_speed = self._pos, 0.0    # limp or not modelled
        if present:
            self._update_present((self._pos - start) / dt)

    def profile_limits(self) -> tuple[float, float]:
        """(speed units/s, acceleration units/s^2) of the profile: Profile Velocity capped by
        the no-load speed (0 = that speed), Profile Acceleration (0 = infinite)."""
        cap = self.max_speed()
        v = self.register("profile_velocity")
        speed = cap if v == 0 else min(units_per_s(v * RPM_PER_VELOCITY_UNIT), cap)
        a = self.register("profile_acceleration")
        accel = math.inf if a == 0 else a * RPM2_PER_ACCELERATION_UNIT * UNITS_PER_TURN / 3600.0
        return speed, accel

    def _advance(self, h: float) -> None:
        goal = self.register("goal_position")
        p, v = self._profile, self._profile_speed
        if p != goal or v:
            speed, accel = self.profile_limits()
            d = goal - p
            toward = max(0.0, math.copysign(v, d)) if d else abs(v)
            moved, new_speed = along_profile(abs(d), toward, speed, accel, h)
            self._profile = float(goal) if moved >= abs(d) else p + math.copysign(moved, d)
            self._profile_speed = math.copysign(new_speed, d)
        tau = self.time_constant
        if tau > 0:
            # the lag's exact answer to a profile moving linearly within the substep, so that
            # the shaft trails a steady speed v by v * tau whatever the steps are
            slope = (self._profile - p) / h
            decay = math.exp(-h / tau)
            self._pos = self._profile - slope * tau + (self._pos - p + slope * tau) * decay
        else:
            self._pos = self._profile

    def _quantised(self) -> int:
        return min(max(round(self._pos), 0), UNITS_PER_TURN - 1)

    def _update_present(self, rate: float) -> None:
        self.set_register("present_position", self._quantised())
        velocity = round(rate * 60.0 / UNITS_PER_TURN / RPM_PER_VELOCITY_UNIT)
        self.set_register("present_velocity", velocity)
        self.set_register("present_input_voltage", min(max(round(self.voltage * 10), 0), 65535))
        self.set_register("present_temperature", min(max(round(self.temperature), 0), 255))
        moving = self._profile != self.register("goal_position") or \
            abs(velocity) > self.register("moving_threshold")
        self.table[122] = int(self.torque_on and moving)
