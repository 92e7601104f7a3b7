"""The drone the arm hangs under: how its centre of rotation moves and how it tilts.

A point-mass multirotor (world frame W: z up, heading fixed, so W is the gravity-aligned,
heading-following frame; SI units):

    a = R(roll, pitch) (0, 0, T/m) + (0, 0, -g) - k_drag (v - wind)

Thrust along body z; `k_drag` lumps rotor and body drag per unit mass (linear in airspeed,
the rotor-drag regime of a multirotor at a few m/s). The attitude follows the position
controller's commanded tilt through a second-order response (the inner attitude loop);
thrust keeps the altitude. The position controller is a PID with acceleration
feed-forward, so it tilts to hold position against the wind and tilts to accelerate along a
reference. Yaw stays 0: the heading-following frame is W itself.

The result is a `Flight`: 1 kHz arrays of attitude, body rates, body angular acceleration
and the centre of rotation's acceleration. `FlightMotion` turns it into what an IMU fixed
to the arm's base reads (specific force in g and body rates, base axes), with the lever
arm r from the centre of rotation to the IMU:

    f_B = R^T (a - g_W) + alpha x r + omega x (omega x r)

The IMU is assumed to sit at the base frame's origin, so r is the model's mount offset.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G = 9.80665
RATE = 1000.0          # Hz: the flight is tabulated at the IMU's internal rate


@dataclass(frozen=True)
class DroneParams:
    """A 650-class quadrotor under a typical position controller (assumed figures)."""
    attitude_wn: float = 18.0        # rad/s: attitude loop natural frequency
    attitude_zeta: float = 0.8
    drag: float = 0.35               # 1/s: drag force per unit mass per m/s of airspeed
    pos_kp: float = 2.0              # 1/s^2
    pos_kd: float = 2.6              # 1/s
    pos_ki: float = 0.4              # 1/s^3
    max_tilt_deg: float = 35.0


@dataclass
class Flight:
    """The drone's motion on a uniform time grid (RATE Hz), W frame, SI units."""
    t: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray
    acc: np.ndarray                  # (n, 3) acceleration of the centre of rotation, m/s^2
    pos: np.ndarray | None = None    # (n, 3) m, for plots
    omega: np.ndarray | None = None  # (n, 3) body rates, rad/s (derived when None)
    alpha: np.ndarray | None = None  # (n, 3) body angular acceleration, rad/s^2
    vel: np.ndarray | None = None    # (n, 3) velocity of the centre of rotation, m/s (derived when None)

    def __post_init__(self):
        if self.omega is None:
            self.omega = body_rates(self.roll, self.pitch, np.gradient(self.roll, self.t),
                                    np.gradient(self.pitch, self.t))
        if self.alpha is None:
            self.alpha = np.gradient(self.omega, self.t, axis=0)
        if self.pos is None:
            self.pos = np.zeros((len(self.t), 3))
        if self.vel is None:   # the acceleration integrated from rest: what the IMU's force implies
            dt = np.diff(self.t)[:, None]
            steps = 0.5 * (self.acc[1:] + self.acc[:-1]) * dt
            self.vel = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])

    @property
    def seconds(self) -> float:
        return float(self.t[-1])

    @property
    def tilt_deg(self) -> np.ndarray:
        """Angle between body z and world z."""
        return np.degrees(np.arccos(np.clip(np.cos(self.roll) * np.cos(self.pitch), -1, 1)))


def body_rates(roll, pitch, roll_rate, pitch_rate):
    """Body rates of Z-Y-X Euler rates with no yaw: p = roll', q = cos(roll) pitch',
    r = -sin(roll) pitch'."""
    return np.stack([roll_rate, np.cos(roll) * pitch_rate, -np.sin(roll) * pitch_rate], axis=-1)


def rotation(roll, pitch) -> np.ndarray:
    """R_WB = Ry(pitch) Rx(roll) (base to world), for arrays: shape (..., 3, 3)."""
    roll, pitch = np.asarray(roll, dtype=float), np.asarray(pitch, dtype=float)
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    zero = np.zeros_like(cr)
    return np.stack([
        np.stack([cp, sp * sr, sp * cr], axis=-1),
        np.stack([zero, cr, -sr], axis=-1),
        np.stack([-sp, cp * sr, cp * cr], axis=-1),
    ], axis=-2)


class FlightMotion:
    """A Flight as SimBoard's motion: attitude(t) and imu(t) (specific force in g, body
    rates in rad/s, base axes) of an IMU at r_mm from the centre of rotation (base axes)."""

    def __init__(self, flight: Flight, r_mm=(0.0, 0.0, 0.0)):
        self.flight = flight
        r = np.asarray(r_mm, dtype=float) / 1000.0
        R = rotation(flight.roll, flight.pitch)
        g_w = np.array([0.0, 0.0, -G])
        f = np.einsum("nji,nj->ni", R, flight.acc - g_w)          # R^T (a - g)
        w, al = flight.omega, flight.alpha
        f += np.cross(al, r) + np.cross(w, np.cross(w, r))
        self._force_g = f / G
        self._n = len(flight.t)

    def index(self, t: float) -> int:
        return min(max(round(t * RATE), 0), self._n - 1)

    def attitude(self, t: float):
        i = self.index(t)
        return float(self.flight.roll[i]), float(self.flight.pitch[i])

    def imu(self, t: float):
        i = self.index(t)
        return self._force_g[i], self.flight.omega[i]


# ---------------------------------------------------------------- scenarios

def grid(seconds: float) -> np.ndarray:
    return np.arange(round(seconds * RATE) + 1) / RATE


def sines(t, freqs, amps, phases) -> np.ndarray:
    return sum(a * np.sin(2 * math.pi * f * t + p) for f, a, p in zip(freqs, amps, phases))


def bench(seconds: float, rng: np.random.Generator, max_tilt_deg: float = 20.0) -> Flight:
    """Tilting by hand on the bench about the centre of rotation, which stays still: roll and
    pitch each a sum of two sines (0.17-0.61 Hz), scaled so the tilt peaks at max_tilt_deg."""
    t = grid(seconds)
    roll, pitch = (sines(t, freqs, (0.7, 0.3), rng.uniform(0, 2 * math.pi, 2))
                   for freqs in ((0.23, 0.61), (0.17, 0.47)))
    tilt = np.arccos(np.cos(roll) * np.cos(pitch))
    scale = math.radians(max_tilt_deg) / tilt.max()
    for _ in range(20):          # tilt is not linear in the scale: a few fixed-point steps
        tilt = np.arccos(np.cos(scale * roll) * np.cos(scale * pitch)).max()
        scale *= math.radians(max_tilt_deg) / tilt
    return Flight(t, scale * roll, scale * pitch, np.zeros((len(t), 3)))


def gusts(t, rng, mean, sigma, band=(0.2, 2.0), components=12) -> np.ndarray:
    """Horizontal wind, m/s, (n, 3): per axis a mean plus a sum of sines log-spaced over band
    with random phases, scaled to standard deviation sigma."""
    out = np.zeros((len(t), 3))
    freqs = np.geomspace(*band, components)
    for axis in range(2):
        f = freqs * rng.uniform(0.9, 1.1, components)
        s = sines(t, f, np.ones(components), rng.uniform(0, 2 * math.pi, components))
        out[:, axis] = mean[axis] + sigma * s / s.std()
    return out


def fly(t, wind, p_ref, v_ref, a_ref, params: DroneParams = DroneParams()) -> Flight:
    """Integrate the multirotor under its position controller (semi-implicit Euler at RATE)."""
    n = len(t)
    dt = 1.0 / RATE
    P = params
    roll = np.zeros(n)
    pitch = np.zeros(n)
    acc = np.zeros((n, 3))
    pos = np.zeros((n, 3))
    # per axis in plain floats: a step is some thirty operations on 3-vectors, which numpy
    # makes ten times dearer than the arithmetic
    px, py, pz = (float(x) for x in p_ref[0])
    vx, vy, vz = (float(x) for x in v_ref[0])
    p_ref, v_ref, a_ref, wind = (np.asarray(x, dtype=float).tolist() for x in (p_ref, v_ref, a_ref, wind))
    # start trimmed against the initial wind (integrator holding it), so no start-up transient
    ix = -P.drag * (wind[0][0] - vx) / P.pos_ki
    iy = -P.drag * (wind[0][1] - vy) / P.pos_ki
    iz = 0.0
    wn2, c = P.attitude_wn ** 2, 2 * P.attitude_zeta * P.attitude_wn
    kp, kd, ki, drag = P.pos_kp, P.pos_kd, P.pos_ki, P.drag
    max_tilt = math.radians(P.max_tilt_deg)
    r = q = rate_r = rate_q = 0.0     # attitude and its rate, rad and rad/s
    for k in range(n):
        (rx, ry, rz), (wx, wy, wz) = p_ref[k], v_ref[k]
        ix += (rx - px) * dt
        iy += (ry - py) * dt
        iz += (rz - pz) * dt
        ax_ref, ay_ref, az_ref = a_ref[k]
        # a_des - g_w + own drag fed forward; the wind is the I term's
        tx = kp * (rx - px) + kd * (wx - vx) + ki * ix + ax_ref + drag * vx
        ty = kp * (ry - py) + kd * (wy - vy) + ki * iy + ay_ref + drag * vy
        tz = kp * (rz - pz) + kd * (wz - vz) + ki * iz + az_ref + G + drag * vz
        norm = math.sqrt(tx * tx + ty * ty + tz * tz)
        nx, ny, nz = tx / norm, ty / norm, tz / norm
        roll_cmd = math.atan2(-ny, math.hypot(nx, nz))
        pitch_cmd = math.atan2(nx, nz)
        tilt = math.acos(min(1.0, math.cos(roll_cmd) * math.cos(pitch_cmd)))
        if tilt > max_tilt:
            roll_cmd *= max_tilt / tilt
            pitch_cmd *= max_tilt / tilt
        if k == 0:
            r, q = roll_cmd, pitch_cmd    # the attitude starts where it is commanded
        rate_r += (wn2 * (roll_cmd - r) - c * rate_r) * dt
        rate_q += (wn2 * (pitch_cmd - q) - c * rate_q) * dt
        r += rate_r * dt
        q += rate_q * dt
        bx, by, bz = math.sin(q) * math.cos(r), -math.sin(r), math.cos(q) * math.cos(r)
        thrust = tx * bx + ty * by + tz * bz
        wind_x, wind_y, wind_z = wind[k]
        a_x = bx * thrust - drag * (vx - wind_x)
        a_y = by * thrust - drag * (vy - wind_y)
        a_z = bz * thrust - G - drag * (vz - wind_z)
        vx, vy, vz = vx + a_x * dt, vy + a_y * dt, vz + a_z * dt
        px, py, pz = px + vx * dt, py + vy * dt, pz + vz * dt
        roll[k], pitch[k] = r, q
        acc[k] = a_x, a_y, a_z
        pos[k] = px, py, pz
    return Flight(t, roll, pitch, acc, pos)


def hover(seconds: float, rng: np.random.Generator, gust_mps: float = 2.0, mean_wind_mps: float = 2.0,
          params: DroneParams = DroneParams()) -> Flight:
    """Position hold in gusty wind: a mean wind from a random direction plus gusts of
    standard deviation gust_mps per horizontal axis over 0.2-2 Hz."""
    t = grid(seconds)
    heading = rng.uniform(0, 2 * math.pi)
    mean = mean_wind_mps * np.array([math.cos(heading), math.sin(heading), 0.0])
    wind = gusts(t, rng, mean, gust_mps)
    zero = np.zeros((len(t), 3))
    return fly(t, wind, zero, zero, zero, params)


def trapezoid(distance: float, speed: float, accel: float):
    """(duration, s(t), v(t), a(t)) of a rest-to-rest move: constant accel to speed, cruise,
    constant decel."""
    t_acc = speed / accel
    d_acc = 0.5 * accel * t_acc ** 2
    if 2 * d_acc > distance:
        t_acc = math.sqrt(distance / accel)
        speed = accel * t_acc
        d_acc = distance / 2
    t_cruise = (distance - 2 * d_acc) / speed
    total = 2 * t_acc + t_cruise

    def at(t):
        t = np.clip(t, 0, total)
        s = np.where(t < t_acc, 0.5 * accel * t ** 2,
                     np.where(t < t_acc + t_cruise, d_acc + speed * (t - t_acc),
                              distance - 0.5 * accel * (total - t) ** 2))
        v = np.where(t < t_acc, accel * t, np.where(t < t_acc + t_cruise, speed, accel * (total - t)))
        a = np.where(t < t_acc, accel, np.where(t < t_acc + t_cruise, 0.0, -accel))
        return s, v, a
    return total, at


def manoeuvre(seconds: float, rng: np.random.Generator, speed: float = 2.5, tilt_deg: float = 10.0,
              leg_m: float = 8.0, pause_s: float = 2.0, jerk_s: float = 0.4, gust_mps: float = 0.5,
              params: DroneParams = DroneParams()) -> Flight:
    """Lateral moves between waypoints: legs of leg_m at `speed`, accelerating at
    g tan(tilt_deg) (that tilt, plus the drag's: 10-15 deg while accelerating), each ramped in and out over jerk_s,
    in directions drawn at random (staying near home), a pause after each; light gusts."""
    t = grid(seconds)
    n = len(t)
    a_ref = np.zeros((n, 3))
    accel = G * math.tan(math.radians(tilt_deg))
    start, here = 1.0, np.zeros(3)
    while start < t[-1]:
        heading = rng.uniform(0, 2 * math.pi)
        d = np.array([math.cos(heading), math.sin(heading), 0.0])
        if np.linalg.norm(here + leg_m * d) > 1.2 * leg_m:
            d = -d
        total, at = trapezoid(leg_m, speed, accel)
        sel = (t >= start) & (t <= start + total)
        a_ref[sel] = at(t[sel] - start)[2][:, None] * d
        here = here + leg_m * d
        start += total + pause_s + jerk_s
    box = np.ones(round(jerk_s * RATE))
    box /= box.size
    a_ref = np.stack([np.convolve(a_ref[:, i], box)[:n] for i in range(3)], axis=-1)
    v_ref = np.cumsum(a_ref, axis=0) / RATE
    p_ref = np.cumsum(v_ref, axis=0) / RATE
    wind = gusts(t, rng, np.zeros(3), gust_mps)
    return fly(t, wind, p_ref, v_ref, a_ref, params)


def with_preflight(flight: Flight, preflight_s: float, ramp_s: float = 2.0) -> Flight:
    """The flight preceded by preflight_s on the ground (still, level) and entered through a
    smooth ramp of ramp_s (attitude and acceleration scaled from 0 to 1 by a smoothstep): the
    board is powered before take-off, as on a real drone."""
    if preflight_s <= 0:
        return flight
    n_pre = round(preflight_s * RATE)
    t = np.arange(n_pre + len(flight.t)) / RATE
    x = np.clip(flight.t / ramp_s, 0.0, 1.0) if ramp_s > 0 else np.ones(len(flight.t))
    w = x * x * (3 - 2 * x)
    pad = lambda a: np.concatenate([np.zeros((n_pre,) + a.shape[1:]), a])
    return Flight(t, pad(w * flight.roll), pad(w * flight.pitch), pad(w[:, None] * flight.acc),
                  pad(flight.pos - flight.pos[0]))


def resample(t_log, roll, pitch, acc, seconds: float | None = None) -> Flight:
    """A flight log (any sample times, strictly increasing, from 0) on the RATE grid: roll and
    pitch by cubic Hermite interpolation (smooth rates), acceleration linearly."""
    t_log = np.asarray(t_log, dtype=float)
    end = t_log[-1] if seconds is None else min(seconds, t_log[-1])
    t = grid(end)
    return Flight(t, hermite(t_log, roll, t), hermite(t_log, pitch, t),
                  np.stack([np.interp(t, t_log, np.asarray(acc)[:, i]) for i in range(3)], axis=-1))


def hermite(x, y, xi) -> np.ndarray:
    """Catmull-Rom style cubic Hermite interpolation (slopes by finite differences)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    m = np.gradient(y, x)
    i = np.clip(np.searchsorted(x, xi, side="right") - 1, 0, len(x) - 2)
    h = x[i + 1] - x[i]
    s = (xi - x[i]) / h
    h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
    h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    return h00 * y[i] + h10 * h * m[i] + h01 * y[i + 1] + h11 * h * m[i + 1]
