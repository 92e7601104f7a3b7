"""Calibration results that are possible but unusual: a value the loader accepts yet a careful
run on sound hardware does not give, or one far from what the model file already holds for the
same part. Such a result is shown and not written unless the user asks for it (`--allow-unusual`)
and confirms it once more: a lab calibrates once and flies what it wrote."""
from __future__ import annotations

from dataclasses import dataclass

import tomlkit

from .fit import CalibrationError

# The IMU's roll or pitch on the base, deg: a board bolted flat on the arm's base sits within a
# few degrees of level; beyond this it is mounted askew, or the drone was not standing level.
MOUNTING_TILT_MAX_DEG = 10.0
# A calibrated accelerometer's bias (g) and scale (fraction) move less than this when the same
# chip is calibrated again (the MPU-6050 drifts about 5 mg, 9 on Z, and 0.2 % over 10 degC); more is a
# different chip or a botched run.
ACCEL_BIAS_CHANGE_MAX_G = 0.05
ACCEL_SCALE_CHANGE_MAX = 0.02
# An AX-12A's lag behind its goal, s: its control law gives 26.5 ms at no load (config's
# SERVO_LAG_ASSUMED_S), the simulator's slowest servos 45 ms on a 9 V supply; outside this a
# servo is blocked, loaded, under-powered, or the jogs were disturbed.
SERVO_LAG_RANGE_S = (0.005, 0.080)
# The lead time moved by more than this (s) means the servos changed beyond a re-fit's noise.
LEAD_TIME_CHANGE_MAX_S = 0.030


@dataclass(frozen=True)
class Departure:
    key: str        # the model file key, e.g. "imu.mounting_rpy"
    was: str        # the model file's current value, as printed
    now: str        # the calibrated value, as printed
    why: str        # the window it is beyond, in plain words, e.g. "a mounting more than 10 deg from level"


def shown(value) -> str:
    """A value as the model file prints it."""
    return tomlkit.item(list(value) if isinstance(value, tuple) else value).as_string()


def settle(departures: list[Departure], allow: bool, confirm) -> None:
    """Nothing beyond its window: returns. Otherwise prints each departure; without `allow` raises CalibrationError saying
    what is suspicious and that `--allow-unusual` writes it after a second confirmation; with it, asks confirm(...) again
    and raises CalibrationError if the answer is no."""
    if not departures:
        return
    print("unusual result:")
    for d in departures:
        print(f"  {d.key} = {d.now} (was {d.was}): {d.why}")
    what = "; ".join(f"{d.key} = {d.now} ({d.why})" for d in departures)
    if not allow:
        raise CalibrationError(f"unusual result, not written: {what}. Check the hardware and the procedure and "
                               "calibrate again; if it is right, `--allow-unusual` writes it after a second "
                               "confirmation")
    if not confirm("these values are beyond what a calibration usually gives: write them all the same?"):
        raise CalibrationError(f"unusual result declined, not written: {what}")


def mounting(was: tuple[float, float, float], roll: float, pitch: float, yaw: float) -> list[Departure]:
    """The IMU's mounting (deg) beyond MOUNTING_TILT_MAX_DEG of level in roll or pitch."""
    if max(abs(roll), abs(pitch)) <= MOUNTING_TILT_MAX_DEG:
        return []
    return [Departure("imu.mounting_rpy", shown(was), shown([roll, pitch, yaw]),
                      f"a mounting more than {MOUNTING_TILT_MAX_DEG:g} deg from level (roll {roll:+.1f}, "
                      f"pitch {pitch:+.1f} deg): is the board askew, or was the drone not standing level?")]


def accelerometer(was_bias, was_scale, bias, scale) -> list[Departure]:
    """A new accelerometer bias (g) or scale far from the model file's calibrated one (a
    default, uncalibrated value is not compared)."""
    out = []
    if tuple(was_bias) != (0.0, 0.0, 0.0):
        moved = max(abs(n - w) for n, w in zip(bias, was_bias))
        if moved > ACCEL_BIAS_CHANGE_MAX_G:
            out.append(Departure("imu.accel_bias", shown(was_bias), shown(bias),
                                 f"{moved * 1000:.0f} mg from the last calibration, more than "
                                 f"{ACCEL_BIAS_CHANGE_MAX_G * 1000:.0f} mg: the same chip does not move that far "
                                 "(a different chip, or a botched run?)"))
    if tuple(was_scale) != (1.0, 1.0, 1.0):
        moved = max(abs(n / w - 1) for n, w in zip(scale, was_scale))
        if moved > ACCEL_SCALE_CHANGE_MAX:
            out.append(Departure("imu.accel_scale", shown(was_scale), shown(scale),
                                 f"{moved:.1%} from the last calibration, more than {ACCEL_SCALE_CHANGE_MAX:.0%}: "
                                 "the same chip does not move that far (a different chip, or a botched run?)"))
    return out


def servo_lag(was_lag: float, lag: float, was_lead: float, lead: float) -> list[Departure]:
    """A servo lag (s) outside an AX-12A's SERVO_LAG_RANGE_S, or a lead time moved more than
    LEAD_TIME_CHANGE_MAX_S."""
    out = []
    lo, hi = SERVO_LAG_RANGE_S
    if not lo <= lag <= hi:
        out.append(Departure("servo.response_lag", shown(was_lag), shown(lag),
                             f"{lag * 1000:.1f} ms, outside an AX-12A's {lo * 1000:.0f}-{hi * 1000:.0f} ms "
                             "(a servo blocked, loaded or under-powered, or the jogs disturbed?)"))
    if abs(lead - was_lead) > LEAD_TIME_CHANGE_MAX_S:
        out.append(Departure("estimator.lead_time", shown(was_lead), shown(lead),
                             f"moved {(lead - was_lead) * 1000:+.1f} ms, more than "
                             f"{LEAD_TIME_CHANGE_MAX_S * 1000:.0f} ms"))
    return out
