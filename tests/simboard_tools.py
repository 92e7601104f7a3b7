"""Shared tools of the end-to-end tests of the firmware application (test_servo_bus.py,
test_app.py), which reach it only through uavarm.sim.board.SimBoard: LLCP bytes in, servo-bus
bytes out, simulated servos, heartbeat frames back.

Every oracle here is independent of the C under test:
- what goes on the servo bus: Protocol 1.0 framing as the AX-12A e-manual states it
  (`split_packets`), Protocol 2.0's for the X-series (`split_packets2`, its CRC the one
  test_dxl_protocol2 computes bit by bit), and the official DynamixelSDK's packet builders
  (`sdk_rebuild`);
- units <-> joint angles and speeds: the servos' written facts (the AX-12A's e-manual: 1023
  position units over 300 deg, 0.111 rpm per Moving Speed unit; the X-series': 4096 a turn,
  0.229 rpm per Profile Velocity unit) with the model file's zero and direction of each
  servo (`Servos`; the module-level names are the committed model file's AX-12As);
- joint limits and collisions: tests/oracles.py's plain geometry (`pose_ok`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import dynamixel_sdk as sdk
import numpy as np

import oracles
from test_dxl_protocol2 import crc16
from uavarm.build import variants
from uavarm.link import messages
from uavarm.model import config
from uavarm.sim import ax12_sim
from uavarm.sim.board import SimBoard, baud_register, make_servo, specific_force_up
from uavarm.sim.xseries_sim import unstuffed

MODEL = config.load()
US = 1_000_000

# Protocol 1.0 (the e-manual's "Instructions")
INST_READ = 0x02
INST_WRITE = 0x03
INST_SYNC_WRITE = 0x83
BROADCAST_ID = 0xFE

# heartbeat.faults bit of each FAULTS name (model/messages.py, lowest bit first)
FAULT = {name: 1 << i for i, (name, _) in enumerate(messages.FAULTS)}

IDS = [s.id for s in MODEL.servos]
FK_TOL_MM = oracles.FK_TOL_MM
TICK = 1.0 / MODEL.sample_rate
UNIT_RAD = math.radians(300.0) / 1023          # one position unit (AX-12A e-manual)
RPM_PER_SPEED_UNIT = 0.111                     # Moving Speed, joint mode (AX-12A e-manual)

# Each servo model's written facts: (position unit in rad, speed unit in rpm, protocol,
# Torque Enable's address), from its e-manual
SERVO_FACTS = {"AX-12A": (UNIT_RAD, RPM_PER_SPEED_UNIT, 1, 24),
               "XL430-W250": (2 * math.pi / 4096, 0.229, 2, 64),
               "XM430-W350": (2 * math.pi / 4096, 0.229, 2, 64)}


# ---------------------------------------------------------------- bus packets

@dataclass(frozen=True)
class Packet:
    """One instruction packet as it left the board: start of its first byte and end of its
    last stop bit (bus seconds), in Dynamixel Protocol 1.0 or 2.0."""
    start: float
    end: float
    raw: bytes
    protocol: int = 1

    @property
    def id(self) -> int:
        return self.raw[2] if self.protocol == 1 else self.raw[4]

    @property
    def inst(self) -> int:
        return self.raw[4] if self.protocol == 1 else self.raw[7]

    @property
    def params(self) -> bytes:
        return self.raw[5:-1] if self.protocol == 1 else unstuffed(self.raw[8:-2])


def split_packets(data: bytes) -> list[bytes]:
    """Cuts a stream of instruction packets into packets, the e-manual's "Protocol 1.0
    packets": FF FF ID LEN INST P1..PN CHK with LEN = N + 2 and CHK = ~(ID + LEN + INST +
    P1 + ... + PN) & 0xFF. Every byte must belong to a well-formed packet."""
    out, i = [], 0
    data = bytes(data)
    while i < len(data):
        assert data[i:i + 2] == b"\xff\xff", f"no packet header at byte {i}: {data[i:].hex(' ')}"
        assert i + 4 <= len(data), f"truncated packet: {data[i:].hex(' ')}"
        n = data[i + 3] + 4
        pkt = data[i:i + n]
        assert len(pkt) == n, f"truncated packet: {pkt.hex(' ')}"
        assert pkt[3] >= 2
        assert (~sum(pkt[2:-1])) & 0xFF == pkt[-1], f"bad checksum: {pkt.hex(' ')}"
        out.append(pkt)
        i += n
    return out


def split_packets2(data: bytes) -> list[bytes]:
    """The same for Protocol 2.0 (its e-manual): FF FF FD 00 ID LEN_L LEN_H INST P1..PN CRC_L
    CRC_H, LEN the bytes after it, the CRC-16 over all before it."""
    out, i = [], 0
    data = bytes(data)
    while i < len(data):
        assert data[i:i + 4] == b"\xff\xff\xfd\x00", f"no packet header at byte {i}: {data[i:].hex(' ')}"
        n = 7 + int.from_bytes(data[i + 5:i + 7], "little")
        pkt = data[i:i + n]
        assert len(pkt) == n >= 10, f"truncated packet: {pkt.hex(' ')}"
        assert crc16(pkt[:-2]) == int.from_bytes(pkt[-2:], "little"), f"bad CRC: {pkt.hex(' ')}"
        out.append(pkt)
        i += n
    return out


class _MemPort:
    """The little of a PortHandler that the SDK's transmit-only calls need."""

    def __init__(self):
        self.is_using = False
        self.out = bytearray()

    def clearPort(self):
        pass

    def writePort(self, packet):
        self.out += bytes(packet)
        return len(packet)

    def setPacketTimeout(self, packet_length):
        pass


_PH = sdk.Protocol1PacketHandler()


def sdk_rebuild(pkt: bytes) -> bytes:
    """The same instruction built by the official DynamixelSDK (Protocol1PacketHandler)."""
    port = _MemPort()
    id_, inst, params = pkt[2], pkt[4], list(pkt[5:-1])
    if inst == INST_WRITE:
        assert _PH.writeTxOnly(port, id_, params[0], len(params) - 1, params[1:]) == sdk.COMM_SUCCESS
    elif inst == INST_READ:
        assert len(params) == 2
        assert _PH.readTx(port, id_, params[0], params[1]) == sdk.COMM_SUCCESS
    elif inst == INST_SYNC_WRITE:
        assert id_ == BROADCAST_ID
        assert _PH.syncWriteTxOnly(port, params[0], params[1], params[2:], len(params) - 2) == sdk.COMM_SUCCESS
    else:
        raise AssertionError(f"unexpected instruction 0x{inst:02X} in {pkt.hex(' ')}")
    return bytes(port.out)


def sync_entries(pkt: bytes) -> tuple[int, int, dict[int, bytes]]:
    """(start address, data length, {id: data}) of a SYNC_WRITE (AX-12A e-manual)."""
    p = pkt[5:-1]
    addr, size, entries = p[0], p[1], p[2:]
    assert size > 0 and len(entries) % (size + 1) == 0
    return addr, size, {entries[k]: bytes(entries[k + 1:k + 1 + size])
                        for k in range(0, len(entries), size + 1)}


def sync_goal_speed(pkt: bytes) -> tuple[list[int], list[int]]:
    """Goal position and moving speed per joint (model order) of a SYNC_WRITE at 30."""
    return AX.sync_goal_speed(pkt)


class BusLog:
    """Records, in bus time, every instruction packet the board sends and every status
    packet a simulated servo sends back, by wrapping the bus simulator's entry points."""

    def __init__(self, board: SimBoard):
        self.board = board
        protocol = Servos(board.model).protocol
        split = split_packets if protocol == 1 else split_packets2
        self.tx: list[Packet] = []
        self.replies: list[Packet] = []        # (start, end, bytes) of status packets
        self.tx_power: list[bool] = []          # the supply switch as each packet left
        bus = board.bus
        write, send_reply = bus.write, bus._send_reply

        def logged_write(data):
            start = max(bus.time, bus._tx_end)
            end = write(data)
            t = start
            for pkt in split(data):
                t_end = t + len(pkt) * bus.byte_time
                self.tx.append(Packet(t, t_end, pkt, protocol))
                self.tx_power.append(board.servo_power)
                t = t_end
            assert math.isclose(t, end)
            return end

        def logged_reply(start, data):
            self.replies.append(Packet(start, start + len(data) * bus.byte_time, bytes(data), protocol))
            return send_reply(start, data)

        bus.write = logged_write
        bus._send_reply = logged_reply

    def syncs(self, since: float = -1.0) -> list[Packet]:
        return [p for p in self.tx if p.inst == INST_SYNC_WRITE and p.start >= since]

    def reads(self, since: float = -1.0) -> list[Packet]:
        return [p for p in self.tx if p.inst == INST_READ and p.start >= since]


# ---------------------------------------------------------------- units and geometry

def relaxed_model(m, unit_rad: float):
    """The model with every collision boundary moved out by what rounding a joint angle to
    the nearest servo unit (half of unit_rad per joint; the AX-12A's: 0.147 deg) can move the arm."""
    half = 0.5 * unit_rad
    reach = m.L2 + m.L3
    mm = half * (reach + reach + m.L3) + 1e-3   # joint 1 swings <= reach, 2 and 3 too
    deg = math.degrees(half) + 1e-4
    limits = tuple(dataclasses.replace(l, min_deg=l.min_deg - deg, max_deg=l.max_deg + deg) for l in m.limits)
    return dataclasses.replace(m, limits=limits, body_z=m.body_z + mm, leg_distance=m.leg_distance + mm,
                               leg_half_width=m.leg_half_width - deg)


class Servos:
    """A model file's servos as the oracles see them: their written facts (SERVO_FACTS) with
    the model file's ids, zeros, directions, joint limits and speeds."""

    def __init__(self, model: config.Model):
        self.model = model
        self.unit_rad, self.rpm_per_speed_unit, self.protocol, self.torque_enable = \
            SERVO_FACTS[model.servo_model.name]
        self.ids = [s.id for s in model.servos]
        self.zero = np.array([s.zero for s in model.servos], dtype=float)
        self.direction = np.array([s.direction for s in model.servos], dtype=float)
        self.park_speed, self.transit_speed, self.working_speed = (
            self.speed_register(rpm) for rpm in (model.park_speed_rpm, model.transit_speed_rpm, model.working_speed_rpm))
        self.unit_range = [self._unit_range(j) for j in range(3)]
        self.relaxed = relaxed_model(model, self.unit_rad)

    def joint_units(self, j: int, rad: float) -> float:
        return float(self.zero[j] + self.direction[j] * rad / self.unit_rad)

    def units_to_joints(self, units) -> np.ndarray:
        """Joint angles (rad) of servo positions, shape (..., 3)."""
        return self.direction * (np.asarray(units, dtype=float) - self.zero) * self.unit_rad

    def speed_register(self, rpm: float) -> int:
        """The speed register's value nearest a speed in rpm (1..1023; 0 would mean no limit)."""
        return min(1023, max(1, round(rpm / self.rpm_per_speed_unit)))

    def speed_units_per_s(self, speed: int) -> float:
        """Position units per second of a speed register's value."""
        return speed * self.rpm_per_speed_unit * 360 / 60 / math.degrees(self.unit_rad)

    def _unit_range(self, j: int) -> tuple[int, int]:
        m = self.model
        ends = sorted(self.joint_units(j, math.radians(d)) for d in (m.limits[j].min_deg, m.limits[j].max_deg))
        return math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9)

    def poses_ok(self, units) -> np.ndarray:
        """Servo positions (N, 3) inside the servos' unit ranges of the joint limits, in poses
        the plain-geometry check accepts up to the servo rounding."""
        u = np.atleast_2d(np.asarray(units, dtype=float))
        lo, hi = np.array(self.unit_range, dtype=float).T
        status, _ = oracles.check_pose(self.relaxed, self.units_to_joints(u))
        return np.all((u >= lo) & (u <= hi), axis=1) & (status == 0)

    def sync_goal_speed(self, pkt: bytes) -> tuple[list[int], list[int]]:
        """Goal position and speed per joint (model order) of a SYNC_WRITE: the AX-12A's of Goal
        Position(30) and Moving Speed, 2 bytes each; the X-series' of Profile Velocity(112) and
        Goal Position(116), 4 bytes each."""
        if self.protocol == 1:
            addr, size, entries = sync_entries(pkt)
            assert (addr, size) == (30, 4), f"SYNC_WRITE of {size} bytes at {addr}"
            goal_at, speed_at, n = 0, 2, 2
        else:
            p = unstuffed(pkt[8:-2])
            addr, size, raw = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little"), p[4:]
            assert (addr, size) == (112, 8) and len(raw) % 9 == 0, f"SYNC_WRITE of {size} bytes at {addr}"
            entries = {raw[k]: raw[k + 1:k + 9] for k in range(0, len(raw), 9)}
            goal_at, speed_at, n = 4, 0, 4
        assert sorted(entries) == sorted(self.ids)
        goal = [int.from_bytes(entries[i][goal_at:goal_at + n], "little") for i in self.ids]
        speed = [int.from_bytes(entries[i][speed_at:speed_at + n], "little") for i in self.ids]
        return goal, speed

    def is_torque_off_to_all(self, p: Packet) -> bool:
        """A broadcast WRITE of Torque Enable 0 (the arm limp on purpose)."""
        address = bytes([self.torque_enable]) if self.protocol == 1 else self.torque_enable.to_bytes(2, "little")
        return p.inst == INST_WRITE and p.id == BROADCAST_ID and p.params == address + b"\0"


AX = Servos(MODEL)


def joint_units(j: int, rad: float) -> float:
    return AX.joint_units(j, rad)


def units_to_joints(units) -> np.ndarray:
    """Joint angles (rad) of servo positions, shape (..., 3)."""
    return AX.units_to_joints(units)


PARK_Q = [math.radians(d) for d in MODEL.park_deg]
PARK_UNITS = [joint_units(j, q) for j, q in enumerate(PARK_Q)]


def speed_register(rpm: float) -> int:
    """The Moving Speed value nearest a speed in rpm (1..1023; 0 would mean no limit)."""
    return AX.speed_register(rpm)


PARK_SPEED, TRANSIT_SPEED, WORKING_SPEED = AX.park_speed, AX.transit_speed, AX.working_speed
UNIT_RANGE = AX.unit_range


def speed_units_per_s(speed: int) -> float:
    """Position units per second of a Moving Speed value."""
    return AX.speed_units_per_s(speed)


def max_unit_step(goals) -> int:
    """The largest change of any joint's goal (units) between consecutive goals."""
    g = np.asarray(goals, dtype=int)
    return int(np.abs(np.diff(g, axis=0)).max()) if len(g) > 1 else 0


def ee_of_units(units) -> np.ndarray:
    """End effector (base frame, mm) of servo positions, by plain geometry."""
    return oracles.arm_points(MODEL, units_to_joints(units))[2]


def shaft_units(board: SimBoard) -> list[float]:
    return [board.bus.servo(i).position for i in Servos(board.model).ids]


RELAXED = AX.relaxed


def poses_ok(units) -> np.ndarray:
    """Servo positions (N, 3) inside the servos' unit ranges of the joint limits, in poses
    the plain-geometry check accepts up to the servo rounding."""
    return AX.poses_ok(units)


def pose_ok(goal_units) -> bool:
    return bool(poses_ok(goal_units)[0])


def level_ik_ok(p) -> bool:
    """A point the arm can reach from a level base by the plain-geometry oracles."""
    q, exists = oracles.textbook_ik(MODEL, np.asarray(p, dtype=float))
    if not exists[0].any():
        return False
    status, _ = oracles.check_pose(MODEL, q[0][exists[0]])
    return bool((status == 0).any())


def level_ik_clear(p, mm: float = 0.5, deg: float = 0.5):
    """Points (N, 3) the arm reaches from a level base in a pose `mm` clear of the body plane
    and the leg distance, `deg` clear of the leg sectors and the joint limits (plain geometry):
    well inside the workspace, whatever margin the firmware keeps from its edges. A mask, or
    a bool for one point."""
    q, exists = oracles.textbook_ik(MODEL, np.asarray(p, dtype=float))
    ok = np.zeros_like(exists)
    ok[exists] = oracles.clear_by(MODEL, q[exists], mm, math.radians(deg))
    return bool(ok[0].any()) if np.ndim(p) == 1 else ok.any(axis=1)


# ---------------------------------------------------------------- boards

def make_board(at=None, lag: float | None = None, **kw) -> SimBoard:
    """A SimBoard whose servos (one per joint, at the bus's baud) rest at `at` (units per
    joint; default the park pose, so tests not about parking need not wait for it), their
    shafts lagging `lag` s (default the model file's servo.response_lag) behind their
    speed-limited profile; the supply is SimBoard's (kw `supply`: default a 3S battery at
    11.1 V, sagging as they move)."""
    at = PARK_UNITS if at is None else at
    lag = MODEL.servo_response_lag if lag is None else lag
    servos = [ax12_sim.AX12(s.id, position=float(round(u)), time_constant=lag, deadband=lag > 0,
                            table={"baud_rate": baud_register(MODEL.servo_baud)})
              for s, u in zip(MODEL.servos, at)]
    return SimBoard(MODEL, servos=servos, **kw)


# The servo families the end-to-end tests run on: the committed model file's AX-12As, and the
# same arm made of XM430-W350s (uavarm/build/variants.py's XM430_EDITS), its firmware built
# from that model file.
FAMILIES = ["AX-12A", "XM430-W350"]
_X = {}


def family_servos(family: str) -> Servos:
    """The servos of the committed model file (AX-12A), or of it made an XM430-W350 arm."""
    if family == "AX-12A":
        return AX
    if not _X:
        variant = variants.build(variants.XM430_EDITS)
        _X.update(servos=Servos(variant.model), lib=(variant.ffi, variant.lib))
    return _X["servos"]


def family_board(family, at=None, lag: float | None = None, **kw) -> SimBoard:
    """A SimBoard of `family`'s servos resting at joint angles `at` (rad; default the park
    pose), their shafts lagging `lag` s (default the model file's) behind their profile."""
    sv = family_servos(family)
    m = sv.model
    q = [math.radians(d) for d in m.park_deg] if at is None else at
    lag = m.servo_response_lag if lag is None else lag
    servos = [make_servo(m, j, position=round(sv.joint_units(j, q[j])), lag=lag, deadband=lag > 0) for j in range(3)]
    return SimBoard(m, servos=servos, lib=family_lib(family), **kw)


def family_lib(family: str):
    """(ffi, lib) of `family`'s firmware build, for SimBoard (None: the committed one's)."""
    family_servos(family)
    return None if family == "AX-12A" else _X["lib"]


def run_until(board: SimBoard, cond, timeout: float, step: float = 0.005) -> float | None:
    """Runs until cond() holds (checked every `step`); the time it first held, or None."""
    end = board.time + timeout
    while board.time < end - 1e-9:
        if cond():
            return board.time
        board.run(min(step, end - board.time))
    return board.time if cond() else None


def running(board: SimBoard) -> bool:
    """The servo driver has configured every servo (the first SYNC_WRITE is out)."""
    return len(board.commands) > 0 and board.servo_power


# Engage waits for the estimator to settle on the IMU's samples since power-up: one time
# constant of its alignment gain, at most 1 s (the model's align_accel_gain).
IMU_SETTLE_S = 1.0 / max(MODEL.estimator.align_accel_gain, 1.0)


def ready(board: SimBoard) -> bool:
    """Running, and the IMU sampled long enough since power-up for engage to be taken."""
    return running(board) and board.time >= IMU_SETTLE_S + 2 * TICK


def last_hb(board: SimBoard) -> dict:
    assert board.heartbeats, "no heartbeat yet"
    return board.heartbeats[-1]


def heartbeat_showing(board: SimBoard, shows, within: float) -> dict:
    """The first heartbeat from now on for which shows(hb) holds, within `within` s."""
    n = len(board.heartbeats)
    found = run_until(board, lambda: any(shows(hb) for hb in board.heartbeats[n:]), within, step=0.001)
    assert found is not None, f"no heartbeat showed it within {within} s"
    return next(hb for hb in board.heartbeats[n:] if shows(hb))


def run_to_next_heartbeat(board: SimBoard) -> dict:
    n = len(board.heartbeats)
    period = MODEL.heartbeat_period
    assert run_until(board, lambda: len(board.heartbeats) > n, period + 0.01, step=0.001) is not None
    return board.heartbeats[-1]


def servo_c(board: SimBoard, j: int):
    """The driver's record of joint j's servo (counters), from the application's state."""
    return board.app.bus.servo[j]


@dataclass
class Tilt:
    """The board turned smoothly (raised cosine, `duration` s from t0) from one roll/pitch
    (rad) to another, with the gyro rates of that turn: a physical tilt, which a gated
    estimator follows (an instant jump of Gravity has no rate and only the accelerometer
    sees it)."""
    start: tuple
    end: tuple
    t0: float
    duration: float = 0.5

    def _s(self, t):
        x = min(max((t - self.t0) / self.duration, 0.0), 1.0)
        return 0.5 - 0.5 * math.cos(math.pi * x), (0.5 * math.pi * math.sin(math.pi * x) / self.duration
                                                    if 0.0 < x < 1.0 else 0.0)

    def attitude(self, t):
        s, _ = self._s(t)
        return tuple(a + s * (b - a) for a, b in zip(self.start, self.end))

    def imu(self, t):
        _, ds = self._s(t)
        roll, pitch = self.attitude(t)
        roll_rate, pitch_rate = ((b - a) * ds for a, b in zip(self.start, self.end))
        # body rates of Z-Y-X Euler rates with no yaw (as uavarm.sim.board.Rocking)
        gyro = (roll_rate, math.cos(roll) * pitch_rate, -math.sin(roll) * pitch_rate)
        return specific_force_up(roll, pitch), gyro
