"""The arithmetic of the IMU calibrations, apart from how the samples are taken.

Accelerometer (six or more still positions, as PX4 and ArduPilot do it): each axis reads
scale x (true) + bias, and at rest the true specific force is 1 g in some direction, so the
corrected readings of every position lie on the unit sphere. Bias and scale per axis are the
least-squares fit of |(reading - bias) / scale| = 1 over the positions (Gauss-Newton from the
per-axis mid-points); the positions need not be exactly aligned with the axes.

Mounting: with the drone standing level the IMU's corrected reading is the base frame's up
in IMU axes; for v_base = Rz(yaw) Ry(pitch) Rx(roll) v_imu that is (-sin p, sin r cos p,
cos r cos p), which gives roll and pitch (yaw is not seen by gravity).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.config import ACCEL_BIAS_MAX_G, ACCEL_SCALE_RANGE, accel_lsb_per_g, gyro_dps_per_lsb

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


def mounting_from_gravity(up_imu: np.ndarray) -> tuple[float, float]:
    """(roll, pitch) in degrees of the IMU on the base, from the corrected reading with the
    base level (the base's up in IMU axes)."""
    ax, ay, az = (float(v) for v in up_imu)
    return math.degrees(math.atan2(ay, az)), math.degrees(math.atan2(-ax, math.hypot(ay, az)))
