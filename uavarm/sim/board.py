"""A simulated board: the firmware application (host build) wired to simulated servos (the
AX-12A or the X-series servo the model file names), an MPU-6050 register file and the drone's
link, in deterministic simulated time.

The application is reached only through what the hardware has: link bytes, servo-bus bytes
and the supply switch (to and from uavarm.sim.ax12_sim), IMU registers (uavarm.sim.mpu6050_sim),
the tick interrupt and the clock. Everything the board says comes back as link bytes.

    board = SimBoard()
    board.send("enable", on=1)
    board.run(1.0)                      # seconds of simulated time
    board.heartbeats[-1]                # decoded heartbeat fields
    board.streamed["imu_raw"]           # decoded service stream frames (stream command)
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np

from .. import rotation
from ..build import firmware
from ..link import llcp, messages
from . import ax12_sim, xseries_sim
from .arm_load import ArmMasses, gravity_torques
from ..model import attitude, config, servo as servo_map
from .imu_model import Mpu6050Sensor
from .mpu6050_sim import Mpu6050

US = 1_000_000
# heartbeats a board that does not record keeps (40 s at 25 Hz): the SITL's tests look back
HEARTBEATS_KEPT = 1000


@dataclass
class SyncCommand:
    """One SYNC_WRITE of goal position and moving speed, as it left the board."""
    time: float
    goal: dict[int, int]       # servo id -> units
    speed: dict[int, int]


def baud_register(baud: float) -> int:
    """The AX-12A Baud Rate register value for a bus speed: bps = 2e6 / (value + 1)."""
    return round(2_000_000 / baud) - 1


def make_servo(model, joint: int, *, position: float | None = None, lag: float = 0.0, deadband: bool = True):
    """The simulated servo of a joint as the model file names it (servo.model): an AX-12A,
    or an X-series servo, at the model's bus speed, its shaft lagging by `lag` s; an AX-12A
    with its compliance margin if deadband (an X-series servo holds by its PID)."""
    s = model.servos[joint]
    kw = {} if position is None else {"position": float(position)}
    if model.servo_model.protocol == 2:
        register = next(v for v, bps in model.servo_model.bauds.items() if bps == model.servo_baud)
        return xseries_sim.XServo(xseries_sim.MODELS[model.servo_model.name], s.id, time_constant=lag,
                                  table={"baud_rate": register}, **kw)
    return ax12_sim.AX12(s.id, time_constant=lag, deadband=deadband,
                         table={"baud_rate": baud_register(model.servo_baud)}, **kw)


def parse_instructions(data: bytes) -> list[tuple[int, int, bytes]]:
    """(id, instruction, params) of every well-formed instruction packet in data."""
    out, i = [], 0
    while i + 6 <= len(data):
        if data[i] != 0xFF or data[i + 1] != 0xFF:
            i += 1
            continue
        n = data[i + 3] + 4
        pkt = data[i:i + n]
        if len(pkt) == n and ax12_sim.checksum(pkt[2:-1]) == pkt[-1]:
            out.append((pkt[2], pkt[4], bytes(pkt[5:-1])))
            i += n
        else:
            i += 1
    return out


def specific_force_up(roll: float, pitch: float):
    """What an ideal accelerometer at rest reads in the base frame (g): "up" seen tilted."""
    return (-math.sin(pitch), math.sin(roll) * math.cos(pitch), math.cos(roll) * math.cos(pitch))


@dataclass
class Gravity:
    """A static board tilted by roll/pitch (rad): the IMU sees 1 g "up", no rotation."""
    roll: float = 0.0
    pitch: float = 0.0

    def attitude(self, t: float):
        return self.roll, self.pitch

    def imu(self, t: float):
        """(specific force in g, body rates in rad/s), in the base frame."""
        return specific_force_up(self.roll, self.pitch), (0.0, 0.0, 0.0)


@dataclass
class Rocking:
    """Bench tilting: roll and pitch swing sinusoidally (amplitudes in rad, frequency in Hz,
    pitch a quarter period behind roll), about the arm's base, with no linear acceleration."""
    roll_amp: float
    pitch_amp: float = 0.0
    freq: float = 0.5

    def attitude(self, t: float):
        w = 2 * math.pi * self.freq
        return self.roll_amp * math.sin(w * t), self.pitch_amp * math.sin(w * t - math.pi / 2)

    def imu(self, t: float):
        w = 2 * math.pi * self.freq
        roll, pitch = self.attitude(t)
        roll_rate = self.roll_amp * w * math.cos(w * t)
        pitch_rate = self.pitch_amp * w * math.cos(w * t - math.pi / 2)
        # body rates of Z-Y-X Euler rates with no yaw: p = roll', q = cos(roll) pitch', r = -sin(roll) pitch'
        gyro = (roll_rate, math.cos(roll) * pitch_rate, -math.sin(roll) * pitch_rate)
        return specific_force_up(roll, pitch), gyro


@dataclass
class Turning:
    """The board turned by hand about its own centre: from orientation `start` (rotation
    matrix, base axes to the world's) about an axis fixed in the board (`turn`: rotation
    vector, rad, base axes), smoothly (smoothstep) over `seconds` from board time `t0`, then
    held still there."""
    start: np.ndarray
    turn: np.ndarray
    t0: float
    seconds: float

    def _progress(self, t: float) -> tuple[float, float]:
        x = min(max((t - self.t0) / self.seconds, 0.0), 1.0)
        return x * x * (3 - 2 * x), 6 * x * (1 - x) / self.seconds

    def orientation(self, t: float) -> np.ndarray:
        return self.start @ rotation.from_vector(self._progress(t)[0] * np.asarray(self.turn, dtype=float))

    def end(self) -> np.ndarray:
        return self.orientation(self.t0 + self.seconds)

    def attitude(self, t: float):
        R = self.orientation(t)
        return math.atan2(R[2, 1], R[2, 2]), -math.asin(max(-1.0, min(1.0, R[2, 0])))

    def imu(self, t: float):
        """(specific force in g, body rates in rad/s), base axes: up seen from the board (its
        centre does not move), the rate along the turn's axis."""
        return tuple(self.orientation(t)[2]), tuple(self._progress(t)[1] * np.asarray(self.turn, dtype=float))


def servo_truth_of(model, truth) -> tuple[tuple[float, ...], tuple[int, ...]]:
    """(zeros, directions) of the servos as mounted: `truth` checked, or the model file's."""
    if truth is None:
        return tuple(float(s.zero) for s in model.servos), tuple(int(s.direction) for s in model.servos)
    try:
        zeros, directions = truth
        zeros = tuple(float(z) for z in zeros)
        directions = tuple(int(d) for d in directions)
    except (TypeError, ValueError):
        raise ValueError(f"servo truth {truth!r}: use ((ZERO, ZERO, ZERO), (DIR, DIR, DIR))") from None
    n = len(model.servos)
    if len(zeros) != n or len(directions) != n or not all(d in (1, -1) for d in directions) \
            or not all(0 <= z <= model.servo_units_max for z in zeros):
        raise ValueError(f"servo truth {truth!r}: {n} zeros in servo units (0 to {model.servo_units_max}) and {n} "
                         "directions (1 or -1)")
    return zeros, directions


def reset_cause_value(cause: str) -> int:
    """The heartbeat's reset_cause of a RESET_CAUSES name."""
    causes = [name for name, _ in messages.RESET_CAUSES]
    if cause not in causes:
        raise ValueError(f"reset cause {cause!r}: one of {causes}")
    return causes.index(cause)


class SimBoard:
    """model: the model the firmware was generated from; servos: AX12 objects (default: one
    per joint, at the bus's baud, resting at their centre); motion: Gravity (default: level
    and still), Rocking, Turning, or any object with attitude(t) and imu(t); start_us: the firmware clock's value at t = 0 (to exercise its wrap-around);
    poll_us: main-loop period; record: keep every servo byte and command (tests) or only
    the last HEARTBEATS_KEPT heartbeats (long runs such as the SITL); servo_lag: the default servos' shaft
    lag behind their speed-limited profile (s, first order, stopping within the compliance
    margin; 0: none; None: the model file's servo.response_lag); supply: the servos' supply
    (ax12_sim.Supply, or its open-circuit volts; default a 3S battery at 11.1 V that sags as
    the servos move, their speed cap with it); sensor: the MPU-6050's sensor model
    (uavarm.sim.imu_model.Mpu6050Sensor; default: datasheet white noise only, seed 0). A motion
    gives the base frame's attitude(t) and imu(t) in base axes; the board turns the latter
    into the IMU's axes with the model's mounting rotation (or imu_mounting_rpy_deg, the
    hardware as it is, for calibration) and the sensor model samples it at the chip's
    internal rate.

    The servos are mounted as the model file's servo zeros and directions say, unless
    servo_truth = ((zero units per joint), (direction per joint)) says otherwise (the
    hardware as it is, for calibration: a servo offset or mounted the other way round).
    That and arm_masses (arm_load.ArmMasses) are the physical arm: gravity's torque about
    each joint, at the shafts' true angles and the base's attitude(t), is what each servo
    holding its joint reads as Present Load.

    Faults of the board itself, for the tests: imu_clock_error, how far the IMU's own clock
    runs from the tick's (0.02: 2 % fast; 0: a sample just before every tick); and the
    attributes tick_interrupt (False: the tick timer's interrupt stops), clock_frozen (True:
    the firmware's microsecond clock stops) and link_echo (True: every byte the board sends
    on the link comes back to it, as through a terminal that echoes)."""

    def __init__(self, model=None, *, servos=None, motion=None, start_us: int = 0,
                 poll_us: int = 100, lib=None, bus_echo: bool = False, record: bool = True,
                 sensor: Mpu6050Sensor | None = None, imu_clock_error: float = 0.0,
                 imu_mounting_rpy_deg: tuple[float, float, float] | None = None, servo_lag: float | None = None,
                 supply: ax12_sim.Supply | float | None = None,
                 servo_truth: tuple[tuple[float, float, float], tuple[int, int, int]] | None = None,
                 arm_masses: ArmMasses | None = None):
        self.model = model or config.load()
        self.ffi, self.lib = lib or firmware.default()
        m = self.model
        self.hp = self.ffi.new("host_port_t *")
        self.lib.host_port_init(self.hp, m.servo_baud, m.imu_address)
        self.imu = Mpu6050(memoryview(self.ffi.buffer(self.hp.imu_regs)))
        if servos is None:
            lag = m.servo_response_lag if servo_lag is None else servo_lag
            servos = [make_servo(m, j, lag=lag, deadband=lag > 0) for j in range(len(m.servos))]
        self.bus = ax12_sim.AX12Bus(servos, baud=m.servo_baud, echo=bus_echo, supply=ax12_sim.supply_of(supply))
        self.bus.power(False)
        self._truth_zero, self._truth_direction = servo_truth_of(m, servo_truth)
        self._units_per_rad = float(servo_map.units_per_rad(m))     # the servo's, as the model names it
        self.arm_masses = arm_masses or ArmMasses.of(m)
        # the arm's shafts, joint by joint (still there if a cable is pulled off the bus)
        self.joint_servos = [next((sv for sv in self.bus.servos if sv.id == s.id), None) for s in m.servos]
        for j, servo in enumerate(self.joint_servos):
            if servo is not None:
                servo.outside_torque = functools.partial(self._gravity_on_shaft, j)
        self.motion = motion or Gravity()
        self.sensor = sensor or Mpu6050Sensor("white", seed=0)
        # the IMU as it really sits (the model file's mounting unless told otherwise: calibration)
        truth = m if imu_mounting_rpy_deg is None else replace(m, imu_mounting_rpy_deg=tuple(imu_mounting_rpy_deg))
        self._base_to_imu = np.array(attitude.mounting(truth).T.tolist(), dtype=float)
        self.start_us = start_us
        self.poll_us = poll_us
        self.tick_us = round(US / m.sample_rate)
        self.now_us = 0                       # simulated time since start
        self._next_tick = self.tick_us
        self.imu_period_us = self.tick_us / (1.0 + imu_clock_error)
        self._next_sample = self.tick_us - (self.imu_period_us if imu_clock_error else 0.0)
        self.tick_interrupt = True
        self.clock_frozen = False
        self.link_echo = False
        self._frozen_at = 0
        self._power = False
        self._link = llcp.Decoder(expected_len=lambda i: messages.BY_ID[i].size if i in messages.BY_ID else -1)
        self.heartbeats: list[dict] = []
        self.heartbeat_times: list[float] = []
        self.streamed: dict[str, list[dict]] = {"imu_raw": [], "servo_status": [], "pong": []}   # service streams, pongs
        self.servo_tx = bytearray()           # every byte the board put on the servo bus
        self.servo_rx_bytes = 0               # bytes the servos sent back
        self.commands: list[SyncCommand] = []
        self.power_log: list[tuple[float, bool]] = []
        self.link_out = bytearray()           # bytes the board sent to the drone, not yet taken
        self.shaft_trace: list | None = None  # set to [] to record (us, supply on, shaft units...) every step
        self.record = record
        self._buf = self.ffi.new("uint8_t[]", 512)
        self.app = self.ffi.new("app_t *")
        self._loop = self.ffi.new("host_loop_t *")
        self._clock()
        self.lib.app_init(self.app, self.ffi.addressof(self.hp, "port"))
        self.app.reset_cause = reset_cause_value("power_on")   # as after power-up

    def reset(self, cause: str = "watchdog", last_fault: int = 0) -> None:
        """The chip resets (its watchdog, or a fault that halted it: `last_fault`, the exception
        number): the firmware starts again from app_init, the servo supply off (its switch's pin
        is low from reset), the bytes in the link's and the servo bus's queues lost; the board
        then reports `cause` (a RESET_CAUSES name) and `last_fault`. The IMU and the servos are
        chips of their own: they run on (the servos lose their supply)."""
        value = reset_cause_value(cause)
        hp = self.hp
        for fifo in (hp.link_in, hp.link_out, hp.servo_in, hp.servo_out):
            fifo.head = fifo.len = 0
        hp.servo_tx_active = False
        self.lib.app_init(self.app, self.ffi.addressof(self.hp, "port"))
        self.app.reset_cause = value
        self.app.last_fault = last_fault
        self._collect()

    # ------------------------------------------------------------------ inputs

    @property
    def time(self) -> float:
        return self.now_us / US

    def send(self, name: str, **fields) -> None:
        self.send_bytes(llcp.encode(messages.encode(name, **fields)))

    def send_bytes(self, data: bytes) -> None:
        pushed = self.lib.host_port_link_push(self.hp, bytes(data), len(data))
        if pushed != len(data):
            raise OverflowError(f"link input full: {pushed} of {len(data)} bytes taken")

    # ------------------------------------------------------------------ time

    def run(self, seconds: float) -> None:
        self.run_until_us(self.now_us + round(seconds * US))

    def run_until_us(self, end_us: int) -> None:
        while self.now_us < end_us:
            self._run_quiet_passes(end_us)
            if self.now_us < end_us:
                self.step(min(self.poll_us, end_us - self.now_us))
        self.bus.run_until(self.time)

    def _run_quiet_passes(self, end_us: int) -> None:
        """The main-loop passes before end_us in which nothing reaches this side (no packet
        on the servo bus whole, no IMU sample due), run in C (host_loop.h) up to the first
        that leaves something to take. The servos' replies known by then wait in C for their
        passes. A shaft trace gets its row for every pass."""
        due = self.bus.next_due()
        self._arrive(self.bus.take_arrivals(due))
        stop = min(end_us, math.floor(self._next_sample), end_us if due == math.inf else math.floor(due * US) - 1)
        if self.now_us + self.poll_us >= stop:
            return
        loop = self._loop
        loop.now_us, loop.stop_us, loop.poll_us = self.now_us, stop, self.poll_us
        loop.next_tick_us, loop.tick_us, loop.frozen_at_us = self._next_tick, self.tick_us, self._frozen_at
        loop.start_us = self.start_us & 0xFFFFFFFF
        loop.tick_interrupt, loop.clock_frozen, loop.servo_power = self.tick_interrupt, self.clock_frozen, self._power
        start_us = self.now_us
        passes = self.lib.host_loop_run(loop, self.hp, self.app)
        if passes:
            self.now_us, self._next_tick, self._frozen_at = loop.now_us, loop.next_tick_us, loop.frozen_at_us
            if self.shaft_trace is not None:
                self._trace_passes(start_us, passes)
            self.bus.run_until(self.time)
            self._collect()

    def _trace_passes(self, start_us: int, passes: int) -> None:
        """The shafts at each of the passes after start_us, as step() records them. Once a
        pass finds every servo resting (and so the supply settled on them), they stay so
        until the next packet: the passes up to the last are not stepped one by one."""
        power, servos = self._power, self.bus.servos
        settled = False
        for k in range(1, passes + 1):
            t_us = start_us + k * self.poll_us
            if settled and k < passes:
                self.shaft_trace.append((t_us, power, *shafts))
                continue
            resting = all(getattr(s, "resting", lambda: False)() for s in servos)
            self.bus.run_until(t_us / US, present=k == passes)
            shafts = tuple(s.position for s in servos)
            self.shaft_trace.append((t_us, power, *shafts))
            settled = resting

    def _arrive(self, arrivals: list[tuple[float, int]]) -> None:
        """Queue the servos' bytes for the passes at which step() would hand them over: the
        first whose time is at or after theirs."""
        if not arrivals:
            return
        passes = []
        for t, _ in arrivals:
            p = math.ceil(t * US)
            p += 1 if not t <= p / US else -1 if t <= (p - 1) / US else 0
            passes.append(p)
        data = bytes(b for _, b in arrivals)
        if self.lib.host_loop_arrive(self._loop, data, passes, len(data)) != len(data):
            raise OverflowError("the servos' bytes on their way overflow the board's queue")
        self.servo_rx_bytes += len(data)

    def step(self, dt_us: int) -> None:
        """Advance dt_us, then run one pass of the firmware's main loop."""
        self.now_us += dt_us
        self.bus.run_until(self.time)
        if self.shaft_trace is not None:
            self.shaft_trace.append((self.now_us, self._power, *(s.position for s in self.bus.servos)))
        self._loop.now_us = self.now_us
        self.lib.host_loop_deliver(self._loop, self.hp)          # (bytes queued by the quiet passes)
        rx = self.bus.read()
        if rx:
            self.servo_rx_bytes += len(rx)
            self.lib.host_port_servo_push(self.hp, rx, len(rx))
        if self.now_us >= self._next_sample:       # the chip latches a sample on its own clock
            self._next_sample += self.imu_period_us
            accel, gyro = self.sensor.read(self.time, self._imu_truth, self.imu.dlpf_cfg, self.imu.smplrt_div)
            self.imu.sample(accel, gyro)
        if self.now_us >= self._next_tick:
            self._next_tick += self.tick_us
            if self.tick_interrupt:
                self.lib.app_request_tick(self.app)
        self._clock()
        self.lib.app_poll(self.app)
        self.lib.app_watch(self.app)
        self._collect()

    def _imu_truth(self, t: float):
        """The true specific force (g) and rates (rad/s) at time t, IMU axes."""
        accel, gyro = self.motion.imu(t)
        return self._base_to_imu @ np.asarray(accel, dtype=float), self._base_to_imu @ np.asarray(gyro, dtype=float)

    def _clock(self) -> None:
        if not self.clock_frozen:
            self._frozen_at = self.now_us
        self.hp.now_us = (self.start_us + self._frozen_at) & 0xFFFFFFFF

    def _collect(self) -> None:
        if self.hp.servo_power != self._power:
            self._power = bool(self.hp.servo_power)
            self.bus.power(self._power)
            self.power_log.append((self.time, self._power))
        buf = self._buf
        n = self.lib.host_port_servo_take(self.hp, buf, len(buf))
        if n:
            data = bytes(self.ffi.buffer(buf, n))
            self.bus.write(data)
            if self.record:
                self.servo_tx += data
                packets = xseries_sim.instruction_packets(data) if self.model.servo_model.protocol == 2 \
                    else parse_instructions(data)
                self.commands += [self._sync_command(params) for _, inst, params in packets
                                  if inst == ax12_sim.INST_SYNC_WRITE]
        n = self.lib.host_port_link_take(self.hp, buf, len(buf))
        if n:
            data = bytes(self.ffi.buffer(buf, n))
            self.link_out += data
            if self.link_echo:
                self.send_bytes(data)
            for payload in self._link.feed(data, self.time):
                name, fields = messages.decode(payload)
                if name == "heartbeat":
                    self.heartbeats.append(fields)
                    self.heartbeat_times.append(self.time)
                elif name in self.streamed:
                    self.streamed[name].append(fields)
            if not self.record:
                del self.heartbeats[:-HEARTBEATS_KEPT], self.heartbeat_times[:-HEARTBEATS_KEPT]
                for frames in self.streamed.values():
                    del frames[:-1000]

    def take_link_output(self) -> bytes:
        """The bytes the board has sent to the drone since the last call."""
        data = bytes(self.link_out)
        self.link_out.clear()
        return data

    def _sync_command(self, params: bytes) -> SyncCommand:
        """A SYNC_WRITE of goal position and goal speed (Moving Speed; Profile Velocity), at
        the addresses and sizes of the model's servo (Protocol 1.0: address and length a byte
        each; 2.0: two bytes each)."""
        regs = self.model.servo_model.registers
        goal_reg, speed_reg = regs["GOAL_POSITION"], regs["GOAL_SPEED"]
        first = min(goal_reg.address, speed_reg.address)
        field = 2 if self.model.servo_model.protocol == 2 else 1
        addr = int.from_bytes(params[:field], "little")
        size = int.from_bytes(params[field:2 * field], "little")
        goal, speed = {}, {}
        if addr == first and size == goal_reg.size + speed_reg.size:
            for k in range(2 * field, len(params) - size, size + 1):
                entry = params[k + 1:k + 1 + size]
                goal[params[k]], speed[params[k]] = (
                    int.from_bytes(entry[r.address - first:r.address - first + r.size], "little")
                    for r in (goal_reg, speed_reg))
        return SyncCommand(self.time, goal, speed)

    # ------------------------------------------------------------------ views

    @property
    def servo_power(self) -> bool:
        return self._power

    def joint_angles(self, command: SyncCommand) -> list[float]:
        """The joint angles (rad) a SYNC_WRITE commands, through the model's servo map."""
        return [float(servo_map.units_to_joint(self.model, j, command.goal[s.id]))
                for j, s in enumerate(self.model.servos)]

    def imu_axis(self, k: int) -> np.ndarray:
        """The IMU's axis k (0: X, 1: Y, 2: Z, as printed on it) in the base's axes, as it really sits."""
        return self._base_to_imu[k].copy()

    def true_joints(self) -> list[float]:
        """The joints' physical angles (rad), from the shafts as the servos are really mounted
        (servo_truth); a joint without its servo: 0."""
        return [0.0 if sv is None else d * (sv.position - z) / self._units_per_rad
                for sv, z, d in zip(self.joint_servos, self._truth_zero, self._truth_direction)]

    @property
    def servo_truth(self) -> tuple[tuple[float, ...], tuple[int, ...]]:
        """(zeros, directions) of the servos as really mounted."""
        return self._truth_zero, self._truth_direction

    def truth_units(self, joint: int, angle: float) -> float:
        """The servo position (units) at which a joint really is at `angle` (rad)."""
        return self._truth_zero[joint] + self._truth_direction[joint] * angle * self._units_per_rad

    def _gravity_on_shaft(self, joint: int) -> float:
        """The torque (N m) gravity exerts on a joint's servo shaft now, CCW positive."""
        up = specific_force_up(*self.motion.attitude(self.bus.time))
        torque = gravity_torques(self.model, self.true_joints(), up, self.arm_masses)[joint]
        return self._truth_direction[joint] * torque

    def servo_joints(self) -> list[float]:
        """The simulated shafts' joint angles (rad) as the model file maps them."""
        return [float(servo_map.units_to_joint(self.model, j, self.bus.servo(s.id).position))
                for j, s in enumerate(self.model.servos)]
