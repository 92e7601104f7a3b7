"""The arithmetic of the calibrations, apart from how the samples are taken.

Accelerometer (six or more still positions, as PX4 and ArduPilot do it): each axis reads
scale x (true) + bias, and at rest the true specific force is 1 g in some direction, so the
corrected readings of every position lie on the unit sphere. Bias and scale per axis are the
least-squares fit of |(reading - bias) / scale| = 1 over the positions (Gauss-Newton from the
per-axis mid-points); the positions need not be exactly aligned with the axes.

Gyro scale (the same calibration run: the rates streamed while the board is turned from
one position to the next): the gyro reads G (true) + offset, the offset known from the still
positions; G's diagonal is each axis's scale, its other entries the cross-axis sensitivity
(each axis also reads up to 2 % of the rates about the other two, which alone would misfit
the turns by about a degree). The rates with the offset removed, mapped through G's inverse
and integrated over a turn, must carry the up direction seen before it (the accelerometer's,
corrected) onto the one seen after it; G is the least-squares fit of that over the turns
(Gauss-Newton from the identity). A turn about the vertical is not seen, so each axis must
have turned about a horizontal direction, which turning the board from face to face does.

Mounting: with the drone standing level the IMU's corrected reading is the base frame's up
in IMU axes; for v_base = Rz(yaw) Ry(pitch) Rx(roll) v_imu that is (-sin p, sin r cos p,
cos r cos p), which gives roll and pitch (yaw is not seen by gravity).

Servo lag: the shaft as a first-order lag with dead time behind its goal, x' = (g(t - dead)
- x) / tau, fitted to the present positions streamed while the firmware ramps the goal (a
jog); the goal between readings taken as linear (the firmware moves it a step per tick).
Following a ramp the shaft lags by dead + tau, which the lead time must cover (how that
splits into the two, only the ramp's end shows, and with readings 30 ms apart poorly).

Link delay: pings sent from this computer and answered at once by the board; the quickest
round trip is the link's fixed delay there and back, half of it each way if the two ways
are alike (the error is half their difference: USB full speed polls every millisecond both
ways). The board's arrival times, against the send times, give the one-way delay's spread
above that minimum (the clocks' offset cancels in the differences).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import rotation
from ..model.config import (ACCEL_BIAS_MAX_G, ACCEL_SCALE_RANGE, GYRO_CROSS_AXIS_MAX, GYRO_SCALE_RANGE,
                            accel_lsb_per_g, gyro_dps_per_lsb)

# A still window: the spread of the readings no more than the sensor's noise allows
# (400 ug/sqrt(Hz) through the 21 Hz DLPF is about 2 mg rms; 0.005 deg/s/sqrt(Hz) 0.02 deg/s).
STILL_ACCEL_STD_G = 0.01
STILL_GYRO_STD_DPS = 0.5
FIT_RESIDUAL_MAX_G = 0.01          # rms of |corrected| - 1 over the positions
AXIS_COVERAGE_G = 0.7              # every axis must have pointed up and down at least this much


class CalibrationError(ValueError):
    """Samples a calibration cannot use: moving, too few, an axis never up or down, or a
    result outside what the chip can be."""


@dataclass(frozen=True)
class Window:
    """One still position: mean specific force (g) and rate (deg/s), IMU axes, raw (as read)."""
    accel_g: np.ndarray
    gyro_dps: np.ndarray
    samples: int


@dataclass(frozen=True)
class AccelFit:
    bias: np.ndarray               # g
    scale: np.ndarray
    residual_g: float              # rms of |corrected| - 1


def window(frames: list[dict], range_g: int, range_dps: int) -> Window:
    """The mean of streamed imu_raw frames, checked still; CalibrationError if it moved."""
    if len(frames) < 20:
        raise CalibrationError(f"only {len(frames)} IMU samples came: is the IMU stream running?")
    counts = np.array([[f["ax"], f["ay"], f["az"], f["gx"], f["gy"], f["gz"]] for f in frames], dtype=float)
    accel = counts[:, :3] / accel_lsb_per_g(range_g)
    gyro = counts[:, 3:] * gyro_dps_per_lsb(range_dps)
    a_std, g_std = accel.std(axis=0).max(), gyro.std(axis=0).max()
    if a_std > STILL_ACCEL_STD_G or g_std > STILL_GYRO_STD_DPS:
        raise CalibrationError(f"the board moved (spread {a_std * 1000:.1f} mg, {g_std:.2f} deg/s; still is "
                               f"<= {STILL_ACCEL_STD_G * 1000:.0f} mg and {STILL_GYRO_STD_DPS} deg/s): "
                               "hold it still and take this position again")
    return Window(accel.mean(axis=0), gyro.mean(axis=0), len(frames))


def fit_accel(windows: list[Window]) -> AccelFit:
    """Bias and scale per axis from still positions; CalibrationError if they cannot be trusted."""
    if len(windows) < 6:
        raise CalibrationError(f"{len(windows)} positions: at least 6 are needed (each axis up and down)")
    m = np.array([w.accel_g for w in windows])
    for axis, name in enumerate("XYZ"):
        if m[:, axis].max() < AXIS_COVERAGE_G or m[:, axis].min() > -AXIS_COVERAGE_G:
            raise CalibrationError(f"the IMU's {name} axis was never pointed straight up and straight down "
                                   f"(readings {m[:, axis].min():+.2f} .. {m[:, axis].max():+.2f} g)")
    bias = (m.max(axis=0) + m.min(axis=0)) / 2
    scale = (m.max(axis=0) - m.min(axis=0)) / 2
    for _ in range(50):
        c = (m - bias) / scale
        norm = np.linalg.norm(c, axis=1)
        r = norm - 1.0
        # d|c|/d bias_i = -c_i / (scale_i |c|); d|c|/d scale_i = -c_i^2 / (scale_i |c|)
        jac = np.hstack([-c / (scale * norm[:, None]), -c * c / (scale * norm[:, None])])
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)
        bias, scale = bias + step[:3], scale + step[3:]
        if np.abs(step).max() < 1e-12:
            break
    residual = float(np.sqrt(np.mean((np.linalg.norm((m - bias) / scale, axis=1) - 1.0) ** 2)))
    if residual > FIT_RESIDUAL_MAX_G:
        raise CalibrationError(f"the positions do not fit one bias and scale (rms {residual * 1000:.1f} mg, "
                               f"at most {FIT_RESIDUAL_MAX_G * 1000:.0f}): was the board moved during a position?")
    if np.abs(bias).max() > ACCEL_BIAS_MAX_G or not (
            ACCEL_SCALE_RANGE[0] <= scale.min() and scale.max() <= ACCEL_SCALE_RANGE[1]):
        raise CalibrationError(f"bias {np.round(bias, 3)} g, scale {np.round(scale, 4)}: outside what an "
                               f"MPU-6050 can be (|bias| <= {ACCEL_BIAS_MAX_G} g, scale {ACCEL_SCALE_RANGE}); "
                               "check the IMU and its range setting")
    return AccelFit(bias, scale, residual)


def gyro_bias(windows: list[Window]) -> np.ndarray:
    """deg/s: the mean rate over every still position (the board turned between them, not during)."""
    weights = np.array([w.samples for w in windows], dtype=float)
    return (np.array([w.gyro_dps for w in windows]) * weights[:, None]).sum(axis=0) / weights.sum()


# Gyro scale fit: how much each axis must have turned (how far the up directions after the
# turns move per unit of its scale: 0.5 rad is 0.3 deg per percent, several times the error
# of an up direction) and how well the turns must agree. A cross-axis sensitivity beyond the
# model file's GYRO_CROSS_AXIS_MAX (twice the datasheet's) means the turns, not the chip, are wrong.
GYRO_SCALE_SEEN_RAD = 0.5
GYRO_TURN_RESIDUAL_MAX_DEG = 0.25  # rms over the turns of the up direction's misfit
_TURN_HINT = "was a turn faster than the gyro's range, or the board knocked while held?"


@dataclass(frozen=True)
class Turn:
    """The board turned by hand between two still positions: the raw rates (deg/s, IMU
    axes) streamed during it, the seconds between consecutive ones, and the up direction
    (unit vector, IMU axes) of the positions before and after."""
    gyro_dps: np.ndarray           # (n, 3)
    dt: np.ndarray                 # (n - 1,)
    up_before: np.ndarray
    up_after: np.ndarray


@dataclass(frozen=True)
class GyroScaleFit:
    scale: np.ndarray              # each axis's reading per unit of rate about it
    cross_axis: np.ndarray         # (3, 3): axis i's reading per unit of rate about axis j, over its scale
    residual_deg: float            # rms misfit of the up direction after each turn
    turns: int


def turned(turn: Turn, unmix: np.ndarray, offset_dps: np.ndarray) -> np.ndarray:
    """The board's turn as a rotation matrix R (after-axes to before-axes: v_before = R
    v_after): the rates are unmix (reading - offset), each held until the next sample (a
    turn starts and ends still)."""
    rate = np.radians(turn.gyro_dps - offset_dps) @ unmix.T
    return rotation.product(rotation.from_vectors(rate[:len(turn.dt)] * turn.dt[:, None]))


def _up_misfit(turns: list[Turn], unmix: np.ndarray, offset_dps: np.ndarray) -> np.ndarray:
    """Per turn, the up direction carried through the turn minus the one seen after it."""
    return np.concatenate([turned(t, unmix, offset_dps).T @ t.up_before - t.up_after for t in turns])


def fit_gyro_scale(turns: list[Turn], offset_dps: np.ndarray) -> GyroScaleFit:
    """Each gyro axis's scale and cross-axis sensitivity from turns between still positions;
    CalibrationError if an axis did not turn enough to tell, or the turns do not agree."""
    if not turns:
        raise CalibrationError("no turn between positions was streamed whole: is the link dropping frames?")
    unmix = np.eye(3)                  # G's inverse: the rates from the readings
    step_size = 1e-6
    for _ in range(20):
        r = _up_misfit(turns, unmix, offset_dps)
        jac = np.stack([(_up_misfit(turns, unmix + step_size * np.eye(9)[i].reshape(3, 3), offset_dps) - r)
                        / step_size for i in range(9)], axis=1)
        for axis, name in enumerate("XYZ"):
            if np.linalg.norm(jac[:, 4 * axis]) < GYRO_SCALE_SEEN_RAD:
                raise CalibrationError(f"the board hardly turned about the IMU's {name} axis (other than about the "
                                       "vertical), so its gyro scale cannot be told: turn it over that axis")
        step, *_ = np.linalg.lstsq(jac, -r, rcond=None)   # (entries no turn shows stay as they are)
        unmix = unmix + step.reshape(3, 3)
        if np.abs(step).max() < 1e-9:
            break
    misfit = _up_misfit(turns, unmix, offset_dps).reshape(-1, 3)
    residual = float(np.degrees(np.sqrt(np.mean(np.sum(misfit ** 2, axis=1)))))
    if residual > GYRO_TURN_RESIDUAL_MAX_DEG:
        raise CalibrationError(f"the turns do not fit one gyro (rms {residual:.2f} deg, at most "
                               f"{GYRO_TURN_RESIDUAL_MAX_DEG}): {_TURN_HINT}")
    try:
        gain = np.linalg.inv(unmix)
    except np.linalg.LinAlgError:
        raise CalibrationError("the turns give no gyro at all: check the IMU and its range setting") from None
    scale = np.diag(gain).copy()
    if not (GYRO_SCALE_RANGE[0] <= scale.min() and scale.max() <= GYRO_SCALE_RANGE[1]):
        raise CalibrationError(f"gyro scale {np.round(scale, 4)}: outside what an MPU-6050 can be "
                               f"({GYRO_SCALE_RANGE}); check the IMU and its range setting")
    cross = gain / scale[:, None] - np.eye(3)
    if np.abs(cross).max() > GYRO_CROSS_AXIS_MAX:
        raise CalibrationError(f"the turns give a gyro cross-axis sensitivity of {np.abs(cross).max() * 100:.1f} % "
                               f"(an MPU-6050 has at most 2 %): {_TURN_HINT}")
    return GyroScaleFit(scale, cross, residual, len(turns))


def mounting_from_gravity(up_imu: np.ndarray) -> tuple[float, float]:
    """(roll, pitch) in degrees of the IMU on the base, from the corrected reading with the
    base level (the base's up in IMU axes)."""
    ax, ay, az = (float(v) for v in up_imu)
    return math.degrees(math.atan2(ay, az)), math.degrees(math.atan2(-ax, math.hypot(ay, az)))


# Servo lag fit: the grid of dead times and time constants searched (s), and what a usable
# record must show. The bounds on the shaft's motion are angles, each servo's readings held to
# them in its own units: a shaft that follows reads within about an AX-12A's unit (0.29 deg)
# of the model, and the same motion read in an XM430-W350's finer units (0.088 deg) misfits by
# 3.4 times as many of them (most of it the ramp's corners, cut by readings 30 ms apart).
LAG_GRID_S = np.arange(0.0, 0.1205, 0.0005)
LAG_FIT_RMS_MAX_DEG = 0.44         # 1.5 AX-12A units
LAG_TRAVEL_MIN_DEG = 2.9           # under 10 AX-12A units: the goal hardly moved
LAG_FOLLOWED_SHARE = 0.7           # of the goal's travel the shaft must have followed
LAG_TAIL_S = 0.15                  # readings used after the goal stops


@dataclass(frozen=True)
class ServoLag:
    dead: float                    # s
    tau: float                     # s
    rms_units: float               # of the fit

    @property
    def lag(self) -> float:
        """s: how far the shaft lags a ramp of its goal."""
        return self.dead + self.tau


def _first_order(goal: np.ndarray, x0: float, dt: float, taus: np.ndarray) -> np.ndarray:
    """Responses (len(taus), len(goal)) of x' = (goal - x) / tau on a grid of step dt, from
    x0; tau 0 follows the goal."""
    keep = np.exp(-dt / np.maximum(taus, 1e-12)) * (taus > 0)
    x = np.empty((len(taus), len(goal)))
    x[:, 0] = x0
    for k in range(1, len(goal)):
        x[:, k] = keep * x[:, k - 1] + (1.0 - keep) * goal[k]
    return x


def _moving_part(t, goal, pos, joint: int):
    """The readings from the last one at rest before the goal moved to LAG_TAIL_S after it
    stopped (at rest the shaft may stand anywhere within the compliance margin: no lag to see)."""
    if len(t) < 6:
        raise CalibrationError(f"only {len(t)} readings of joint {joint}'s servo during a jog: is it "
                               "connected (heartbeat servo_timeout)?")
    changes = np.flatnonzero(np.diff(goal)) + 1          # readings with a new goal
    if len(changes) == 0:
        raise CalibrationError(f"joint {joint}'s goal did not move during the record (jog refused?)")
    end = np.searchsorted(t, t[changes[-1]] + LAG_TAIL_S, side="right")
    part = slice(changes[0] - 1, end)
    return t[part], goal[part], pos[part]


def fit_servo_lag(records: list[tuple[np.ndarray, np.ndarray, np.ndarray]], joint: int,
                  deg_per_unit: float) -> ServoLag:
    """Dead time and time constant of one servo from records of (time s, goal, position)
    (units of deg_per_unit, the servo's own), each a jog from rest with readings from before
    it; CalibrationError if the shaft did not follow or the fit is poor."""
    rms_max = LAG_FIT_RMS_MAX_DEG / deg_per_unit
    dt = 0.0005
    sse = np.zeros((len(LAG_GRID_S), len(LAG_GRID_S)))     # [dead, tau]
    count = 0
    for record in records:
        t, goal, pos = _moving_part(*record, joint)
        travel, followed = np.ptp(goal), np.ptp(pos)
        if travel < LAG_TRAVEL_MIN_DEG / deg_per_unit or followed < LAG_FOLLOWED_SHARE * travel:
            raise CalibrationError(f"joint {joint}'s servo moved {followed:.0f} of the {travel:.0f} units its goal "
                                   "did: is it blocked, limp or unpowered?")
        grid = np.arange(t[0] - LAG_GRID_S[-1], t[-1] + dt, dt)
        g = np.interp(grid, t, goal)             # held at the first goal before the record
        x = _first_order(g, pos[0], dt, LAG_GRID_S)
        for i, dead in enumerate(LAG_GRID_S):
            at = np.clip(np.round((t[1:] - dead - grid[0]) / dt).astype(int), 0, len(grid) - 1)
            sse[i] += ((x[:, at] - pos[1:]) ** 2).sum(axis=1)
        count += len(t) - 1
    i, j = np.unravel_index(np.argmin(sse), sse.shape)
    rms = float(np.sqrt(sse[i, j] / count))
    fit = ServoLag(float(LAG_GRID_S[i]), float(LAG_GRID_S[j]), rms)
    if rms > rms_max:
        raise CalibrationError(f"joint {joint}'s servo does not follow its goal like a lag (fit rms {rms:.1f} units, "
                               f"at most {rms_max:.1f}): was the arm touched or loaded during the jogs?")
    if LAG_GRID_S[-1] in (fit.dead, fit.tau):
        raise CalibrationError(f"joint {joint}'s servo lags more than {LAG_GRID_S[-1] * 1000:.0f} ms: too slow to "
                               "stabilise anything (supply voltage? compliance settings?)")
    return fit


PING_ANSWERED_MIN = 0.9            # share of pings answered for a usable measurement


@dataclass(frozen=True)
class LinkDelay:
    one_way: float                 # s: half the quickest round trip
    round_trip_min: float          # s
    spread_p50: float              # s: the one-way delay's excess over its quickest, median
    spread_p95: float              # s: and 95th percentile
    answered: int
    sent: int


def fit_link_delay(exchanges: list[tuple[float, float, int]], sent: int) -> LinkDelay:
    """exchanges: (sent s, received s) on this computer's clock and the board's arrival time
    (us, its 32-bit clock) of each answered ping, in the order sent; `sent` pings in all."""
    if sent == 0 or len(exchanges) < PING_ANSWERED_MIN * sent:
        raise CalibrationError(f"{sent - len(exchanges)} of {sent} pings unanswered: the link drops frames, or "
                               "the board's firmware is older than the ping message (flash this one)")
    t_sent = np.array([e[0] for e in exchanges])
    t_back = np.array([e[1] for e in exchanges])
    arrived = np.array([e[2] for e in exchanges], dtype=np.int64)
    board = np.concatenate([[0], np.cumsum(np.diff(arrived) % 2**32)]) * 1e-6   # unwrapped, s
    trip = t_back - t_sent
    one_way = board - (t_sent - t_sent[0])        # the one-way delay plus an unknown constant
    excess = one_way - one_way.min()
    return LinkDelay(one_way=float(trip.min()) / 2, round_trip_min=float(trip.min()),
                     spread_p50=float(np.percentile(excess, 50)), spread_p95=float(np.percentile(excess, 95)),
                     answered=len(exchanges), sent=sent)

