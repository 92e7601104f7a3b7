"""Closed-loop simulator: the firmware (host build) on a simulated board under a flying drone.

Everything reaches the firmware as on the hardware: IMU register bytes (uavarm.sim.imu_model
through uavarm.sim.mpu6050_sim), servo-bus bytes (uavarm.sim.ax12_sim with a small-signal lag and
the compliance dead band), link bytes (LLCP: set_position kept alive every 0.25 s and, when
the firmware fuses them, the drone's attitude and velocity at the scenario's rates, delays
and errors) and time. The drone (uavarm.sim.drone) rotates the arm's base about its centre of rotation, at the
model's mount offset from it.

Figure of merit: the end effector's error in the gravity-aligned, heading-following frame
centred on the drone's centre of rotation,

    e = R (offset + FK(q_shafts)) - (offset + p)

with R the true attitude (yaw removed), q_shafts the simulated servo shafts' joint angles and
p the set position (level frame at the base's level position). Scored from `settle` seconds
after engage, every IMU tick; plus the firmware's attitude estimate (stab_attitude) against
the true base attitude.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from . import drone, imu_model, scenarios
from .board import SimBoard, make_servo
from ..model import kinematics
from ..build.variants import Variant

US = 1_000_000
KEEP_ALIVE_S = 0.25


def servo_lag_of(settings: "Settings", model) -> float:
    """s: how far the simulated shafts lag: the hardware's if the settings say, else as the
    model file believes (servo.response_lag)."""
    return model.servo_response_lag if settings.servo_lag is None else settings.servo_lag


@dataclass
class Settings:
    seconds: float = 60.0            # scored time
    settle: float = 5.0              # after engage, not scored: the arm gets there, filters settle
    preflight: float = 10.0          # s on the ground after power-up (still, level, motors off)
    engage_at: float = 1.5           # s after the flight starts (enable at power-up)
    poll_us: int = 250               # main-loop period of the simulated board
    servo_lag: float | None = None   # s; None: the model file's servo.response_lag
    supply: float | None = None      # V, the servos' battery (sagging as they move); None: ax12_sim.Supply's
    servo_deadband: bool = True      # the compliance margin: no torque within 1 unit of the goal
    drone_attitude: bool | None = None   # send the link attitude; None: when the firmware fuses it
    drone_velocity: bool | None = None   # send the link velocity; None: when the firmware fuses it


@dataclass
class Run:
    scenario: str
    seed: int
    label: str
    t: np.ndarray                    # s since engage, every tick
    error_mm: np.ndarray             # (n, 3)
    true_att: np.ndarray             # (n, 2) roll, pitch rad
    est_att: np.ndarray              # (n, 2)
    scored: np.ndarray               # bool (n,)
    flight: drone.Flight
    out_of_reach_ticks: int = 0
    unreachable_ticks: int = 0       # the set position refused as unreachable (from a level base)
    link_messages: int = 0
    faults: list = field(default_factory=list)
    last_heartbeat: dict = field(default_factory=dict)
    gate_refusals: dict = field(default_factory=dict)   # stream -> messages the gate refused, drops
    imu: imu_model.ImuDraw | None = None                 # the sensor's drawn errors

    def metrics(self) -> dict:
        e = np.linalg.norm(self.error_mm[self.scored], axis=1)
        a = np.degrees(np.abs(self.est_att[self.scored] - self.true_att[self.scored]))
        a = np.linalg.norm(a, axis=1)
        return {"rms": float(np.sqrt(np.mean(e ** 2))), "p95": float(np.percentile(e, 95)),
                "max": float(e.max()), "att_rms": float(np.sqrt(np.mean(a ** 2))), "att_max": float(a.max()),
                "seconds": float(self.t[self.scored][-1] - self.t[self.scored][0] + self.t[1] - self.t[0])}


def ee_error(model, q, roll, pitch, target) -> np.ndarray:
    """e = R (offset + FK(q)) - (offset + p), mm; q (n, 3), roll/pitch (n,)."""
    fk = fk_function(model)
    off = np.asarray(model.mount_offset, dtype=float)
    ee = np.stack(fk(q[:, 0], q[:, 1], q[:, 2]), axis=-1).reshape(len(q), 3)
    R = drone.rotation(roll, pitch)
    return np.einsum("nij,nj->ni", R, off + ee) - (off + np.asarray(target, dtype=float))


_FK = {}


def fk_function(model):
    key = (model.L1, model.L2, model.L3)
    if key not in _FK:
        f = sp.lambdify(kinematics.JOINT_SYMBOLS, list(kinematics.fk_points(model)[1]), modules="numpy")
        _FK[key] = lambda a, b, c: [np.broadcast_to(v, np.shape(a)) for v in f(a, b, c)]
    return _FK[key]


def fuses(model, key: str) -> bool:
    """Does the model's firmware fuse estimator.<key> (drone_attitude, drone_velocity)?"""
    return bool(getattr(model.estimator, key))


class SlowError:
    """A first-order Gauss-Markov error per axis: RMS sigma, correlation time tau (s), started
    from its stationary distribution."""

    def __init__(self, sigma: float, tau: float, axes: int, rng: np.random.Generator):
        self.sigma, self.tau, self.rng = sigma, tau, rng
        self.value = rng.standard_normal(axes) * sigma

    def step(self, dt: float) -> np.ndarray:
        a = math.exp(-dt / self.tau)
        self.value = a * self.value + math.sqrt(1 - a * a) * self.sigma * self.rng.standard_normal(len(self.value))
        return self.value


class DroneStream:
    """Messages of the drone's computer: measured at rate_hz, stamped in the drone's clock,
    delivered after a jittered delay, in order (a serial link does not reorder), except
    those measured within one of the stream's outages (s after engage at engage_s of the
    flight), lost on the way: their sequence numbers are skipped, and the slow error goes
    on changing meanwhile. Subclasses say what is measured (`measure(i)`, the flight's
    sample index) and hold the slow error (`slow`)."""

    def __init__(self, p, flight: drone.Flight, rng: np.random.Generator, engage_s: float = 0.0):
        self.p = p
        self.flight = flight
        self.rng = rng
        self.engage_s = engage_s
        self.clock_offset_us = int(rng.integers(0, 2 ** 32))
        self.seq = int(rng.integers(0, 2 ** 16))
        self.k = 1
        self.last_arrival = 0.0
        self._next = self._schedule()

    def measure(self, i: int) -> dict:
        raise NotImplementedError

    def _skip_outages(self):
        while True:
            t = self.k / self.p.rate_hz - self.engage_s
            end = next((b for a, b in self.p.outages if a <= t < b), None)
            if end is None:
                return
            lost = max(math.ceil((end + self.engage_s) * self.p.rate_hz) - self.k, 1)
            self.slow.step(lost / self.p.rate_hz)
            self.k += lost
            self.seq = (self.seq + lost) & 0xFFFF

    def _schedule(self):
        self._skip_outages()
        t_meas = self.k / self.p.rate_hz
        delay = (self.p.delay_ms + self.rng.uniform(-1, 1) * self.p.jitter_ms) / 1000.0
        arrival = max(t_meas + delay, self.last_arrival)
        values = self.measure(min(round(t_meas * drone.RATE), len(self.flight.t) - 1))
        stamp = (self.clock_offset_us + round(t_meas * US)) & 0xFFFFFFFF
        return arrival, dict(seq=self.seq, stamp_us=stamp, **values)

    @property
    def next_time(self) -> float:
        return self._next[0]

    def pop(self) -> dict:
        arrival, msg = self._next
        self.last_arrival = arrival
        self.k += 1
        self.seq = (self.seq + 1) & 0xFFFF
        self._next = self._schedule()
        return msg


class LinkAttitude(DroneStream):
    """The flight controller's roll and pitch: truth plus a constant, a slowly varying and a
    white error per axis."""

    def __init__(self, p: scenarios.LinkParams, flight: drone.Flight, rng: np.random.Generator,
                 engage_s: float = 0.0):
        self.bias = np.radians(rng.uniform(-1, 1, 2) * p.bias_deg)
        self.slow = SlowError(math.radians(p.slow_deg), p.slow_tau_s, 2, rng)
        super().__init__(p, flight, rng, engage_s)

    def measure(self, i):
        att = np.array([self.flight.roll[i], self.flight.pitch[i]]) + self.bias \
            + self.slow.step(1.0 / self.p.rate_hz) + self.rng.standard_normal(2) * math.radians(self.p.noise_deg)
        return dict(roll=float(att[0]), pitch=float(att[1]))


class LinkVelocity(DroneStream):
    """The odometry's velocity of the centre of rotation (level, heading-following frame):
    truth plus a slowly varying and a white error per axis."""

    def __init__(self, p: scenarios.VelocityParams, flight: drone.Flight, rng: np.random.Generator,
                 engage_s: float = 0.0):
        self.slow = SlowError(p.slow_mps, p.slow_tau_s, 3, rng)
        super().__init__(p, flight, rng, engage_s)

    def measure(self, i):
        v = self.flight.vel[i] + self.slow.step(1.0 / self.p.rate_hz) + self.rng.standard_normal(3) * self.p.noise_mps
        return dict(vx=float(v[0]), vy=float(v[1]), vz=float(v[2]))


def make_servos(model, lag: float, deadband: bool):
    from ..model import servo as servo_map
    out = []
    for j, s in enumerate(model.servos):
        park = float(servo_map.joint_to_units(model, j, math.radians(model.park_deg[j])))
        out.append(make_servo(model, j, position=round(park), lag=lag, deadband=deadband))
    return out


def scenario_flight(scenario: scenarios.Scenario, seed: int, settings: Settings) -> drone.Flight:
    """The scenario's motion for a run (without the preflight), seeded as simulate() does."""
    st = settings
    return scenario.flight(st.engage_at + st.settle + st.seconds + 0.1, np.random.default_rng([seed, 2]))


def simulate(scenario: scenarios.Scenario, variant: Variant, seed: int = 0, settings: Settings = Settings(),
             label: str = "") -> Run:
    model = variant.model
    st = settings
    rng = np.random.default_rng([seed, 1])
    flight = drone.with_preflight(scenario_flight(scenario, seed, st), st.preflight)
    total = st.preflight + st.engage_at + st.settle + st.seconds
    motion = drone.FlightMotion(flight, model.mount_offset)
    sensor = imu_model.Mpu6050Sensor(scenario.imu_errors(), seed=int(np.random.default_rng([seed, 3]).integers(2 ** 31)),
                                     vibration_from=st.preflight)
    lag = servo_lag_of(st, model)
    board = SimBoard(model, servos=make_servos(model, lag, st.servo_deadband), motion=motion,
                     poll_us=st.poll_us, lib=(variant.ffi, variant.lib), record=False, sensor=sensor,
                     supply=st.supply)
    board.bus.lazy = True                   # servos stepped at bus traffic; sync() before reading them
    send_attitude = fuses(model, "drone_attitude") if st.drone_attitude is None else st.drone_attitude
    send_velocity = fuses(model, "drone_velocity") if st.drone_velocity is None else st.drone_velocity
    streams = []   # (message name, stream)
    engage_s = st.preflight + st.engage_at
    if send_attitude:
        streams.append(("drone_attitude", LinkAttitude(scenario.link, flight, rng, engage_s)))
    if send_velocity:
        streams.append(("drone_velocity", LinkVelocity(scenario.velocity, flight, np.random.default_rng([seed, 4]),
                                                       engage_s)))
    ffi, lib = variant.ffi, variant.lib
    stab = ffi.addressof(board.app, "stab")
    roll_p, pitch_p = ffi.new("float *"), ffi.new("float *")
    target = dict(zip("xyz", scenario.target))
    units_per_rad = model.servo_units_max / math.radians(model.servo_range_deg)
    zero = np.array([s.zero for s in model.servos], dtype=float)
    direction = np.array([s.direction for s in model.servos], dtype=float)
    servos = [board.bus.servo(s.id) for s in model.servos]

    tick_us = board.tick_us
    end_us = round(total * US)
    engage_us = round((st.preflight + st.engage_at) * US)
    next_alive = engage_us
    rec_t, rec_q, rec_true, rec_est = [], [], [], []
    out_of_reach = unreachable = n_link = 0
    faults = set()
    board.send("enable", on=1)
    engaged = False
    next_rec = engage_us + tick_us // 2        # mid-tick: after the tick's servo command
    while board.now_us < end_us:
        events = [end_us, next_rec]
        if engaged or board.now_us < engage_us:
            events.append(next_alive if engaged else engage_us)
        events += [round(stream.next_time * US) for _, stream in streams]
        t_next = max(min(events), board.now_us + 1)
        board.run_until_us(t_next)
        now = board.now_us
        if not engaged and now >= engage_us:
            board.send("set_position", **target)
            board.send("engage", on=1)
            engaged = True
            next_alive = now + round(KEEP_ALIVE_S * US)
        elif engaged and now >= next_alive:
            board.send("set_position", **target)
            next_alive += round(KEEP_ALIVE_S * US)
        for name, stream in streams:
            while stream.next_time * US <= now:
                board.send(name, **stream.pop())
                n_link += 1
        if now >= next_rec:
            next_rec += tick_us
            lib.stab_attitude(stab, roll_p, pitch_p)
            board.bus.sync()
            rec_t.append(board.time)
            rec_q.append([s.position for s in servos])
            rec_true.append(motion.attitude(board.time))
            rec_est.append((roll_p[0], pitch_p[0]))
            out_of_reach += bool(board.app.out_of_reach)
            unreachable += bool(board.app.unreachable)
            for hb in board.heartbeats[-1:]:
                if hb["faults"]:
                    faults.add(hb["faults"])
    q = direction * (np.array(rec_q) - zero) / units_per_rad
    true_att = np.array(rec_true)
    err = ee_error(model, q, true_att[:, 0], true_att[:, 1], scenario.target)
    t = np.array(rec_t) - st.preflight - st.engage_at
    refusals = {name: (st_.disagreed, st_.rejections) for name, st_ in (("drone_attitude", stab.link), ("drone_velocity", stab.vel))}
    return Run(scenario.name, seed, label, t, err, true_att, np.array(rec_est), t >= st.settle,
               flight, out_of_reach, unreachable, n_link, sorted(faults), dict(board.heartbeats[-1]) if board.heartbeats else {},
               refusals, sensor.draw)
