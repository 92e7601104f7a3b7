"""How close the firmware's split comes to the best linear estimate of the two errors it
separates: the flight controller's slowly varying error and the accelerometer's bias
(model/velocity.py, docs/simulator.md).

A scalar model of one tilt axis in flight, from engage. The velocity holds the estimate
where the accelerometer's bias puts it: off by b, constant, uniform within the error
ranges' bias (+-15 mg: +-0.86 deg). The drone's attitude is off by the flight controller's
slowly varying error f (first-order Markov: sigma, correlation time tau) and by white noise
w. Each of its messages (50 Hz) gives the disagreement

    z = (f - f_hat) - (b - b_hat) + w

which moves b_hat (the estimate, with the bias behind it) and f_hat (fc_error): by the fixed
gains (the model file's accel_bias_attitude_gain, fc_error_gain, fading over fc_error_tau or
not), or by the Kalman filter of [b - b_hat, f - f_hat], as the firmware does with the model
file's stated sizes (accel_bias_prior_g and _walk_g, fc_error_deg and _tau,
drone_attitude_white_deg), and with each corner's true sigma and tau: the best linear
estimate for this model.

Figure: the tilt error b - b_hat, RMS over the report's scored window (5-35 s after engage),
over 4,000 draws per corner of the ranges; every estimate sees the same draws.

    python -m uavarm.sim.split_bound
"""
from __future__ import annotations

import math
import sys

import numpy as np

from ..model import config
from . import error_ranges, imu_model

RATE_HZ = 50.0
WINDOW_S = (5.0, 35.0)
DRAWS = 4000
WHITE_DEG = sum(error_ranges.LINK["noise_deg"]) / 2          # the range's middle, per message
# (sigma deg, tau s): the four corners of the flight controller's slow error and the middle
_SIGMA, _TAU = error_ranges.LINK["slow_deg"], error_ranges.LINK["slow_tau_s"]
CORNERS = ((_SIGMA[0], _TAU[0]), (_SIGMA[1], _TAU[0]), (sum(_SIGMA) / 2, sum(_TAU) / 2),
           (_SIGMA[0], _TAU[1]), (_SIGMA[1], _TAU[1]))


def draws(sigma_deg: float, tau_s: float, seed: int = 0):
    """(b, f over time, w over time), rad: DRAWS flights of the corner."""
    rng = np.random.default_rng(seed)
    h, n = 1.0 / RATE_HZ, round(WINDOW_S[1] * RATE_HZ)
    bias_deg = math.degrees(math.atan(imu_model.ACCEL_BIAS_RANGE_G))
    b = np.radians(rng.uniform(-bias_deg, bias_deg, DRAWS))
    a = math.exp(-h / tau_s)
    f = np.empty((n, DRAWS))
    f[0] = rng.normal(0.0, math.radians(sigma_deg), DRAWS)
    for k in range(1, n):
        f[k] = a * f[k - 1] + rng.normal(0.0, math.radians(sigma_deg) * math.sqrt(1 - a * a), DRAWS)
    return b, f, rng.normal(0.0, math.radians(WHITE_DEG), (n, DRAWS))


def split(b, f, w, k_d: float, k_f: float, tau: float) -> np.ndarray:
    """The tilt error after each message, corrected as stab_drone_attitude does."""
    h = 1.0 / RATE_HZ
    b_hat, f_hat, out = np.zeros_like(b), np.zeros_like(b), np.empty_like(f)
    for k in range(len(f)):
        z = (f[k] - f_hat) - (b - b_hat) + w[k]
        b_hat -= h * k_d * z                            # the estimate towards the flight controller
        f_hat += h * (k_f * z - (f_hat / tau if tau else 0.0))
        out[k] = b - b_hat
    return out


def kalman(b, f, w, sigma_deg: float, tau_s: float, bias_g: float | None = None,
           walk_g: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(the tilt error after each message, its variance as the filter predicts it), corrected
    by the Kalman filter of x = [b - b_hat, f - f_hat] (z = -x0 + x1 + w) with these priors:
    f's sigma and tau, the bias's sigma (g; None: the draws' own, uniform within the ranges)
    and its random walk (g a minute)."""
    h = 1.0 / RATE_HZ
    a, s2 = math.exp(-h / tau_s), math.radians(sigma_deg) ** 2
    bias_var = math.atan(imu_model.ACCEL_BIAS_RANGE_G) ** 2 / 3.0 if bias_g is None else bias_g ** 2
    p = np.array([[bias_var, 0.0], [0.0, s2]])
    q = walk_g ** 2 / 60.0 * h
    r = math.radians(WHITE_DEG) ** 2
    b_hat, f_hat, out, variance = np.zeros_like(b), np.zeros_like(b), np.empty_like(f), np.empty(len(f))
    for k in range(len(f)):
        f_hat *= a
        p = np.array([[p[0, 0] + q, a * p[0, 1]], [a * p[0, 1], a * a * p[1, 1] + (1 - a * a) * s2]])
        hv = np.array([-1.0, 1.0])
        s = hv @ p @ hv + r
        gain = p @ hv / s
        z = (f[k] - f_hat) - (b - b_hat) + w[k]
        b_hat += gain[0] * z
        f_hat += gain[1] * z
        p = p - np.outer(gain, gain) * s
        out[k] = b - b_hat
        variance[k] = p[0, 0]
    return out, variance


def scored_rms_deg(errors: np.ndarray) -> float:
    first = round(WINDOW_S[0] * RATE_HZ)
    return math.degrees(math.sqrt(float(np.mean(errors[first:] ** 2))))


def table(model: config.Model) -> dict[tuple[float, float], dict[str, float]]:
    """Per corner, each estimate's tilt error RMS (deg)."""
    e = model.estimator
    out = {}
    for sigma, tau in CORNERS:
        b, f, w = draws(sigma, tau)
        out[(sigma, tau)] = {
            "fixed gains, not fading": scored_rms_deg(split(b, f, w, e.accel_bias_attitude_gain, e.fc_error_gain, 0.0)),
            "fixed gains, fading": scored_rms_deg(split(b, f, w, e.accel_bias_attitude_gain, e.fc_error_gain,
                                                        e.fc_error_tau)),
            "Kalman, the model file's sizes (committed)": scored_rms_deg(
                kalman(b, f, w, e.fc_error_deg, e.fc_error_tau, e.accel_bias_prior_g, e.accel_bias_walk_g)[0]),
            "Kalman, the corner's own": scored_rms_deg(kalman(b, f, w, sigma, tau)[0]),
        }
    return out


def main() -> int:
    rows = table(config.load())
    names = list(next(iter(rows.values())))
    print("| flight controller's slow error | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    for (sigma, tau), r in rows.items():
        print(f"| {sigma} deg, {tau:.0f} s | " + " | ".join(f"{r[n]:.3f}" for n in names) + " |")
    print(f"\nTilt error RMS (deg), {WINDOW_S[0]:.0f}-{WINDOW_S[1]:.0f} s after engage, {DRAWS} draws per row; the "
          f"accelerometer's bias uniform within +-{1e3 * imu_model.ACCEL_BIAS_RANGE_G:.0f} mg, white {WHITE_DEG} deg "
          f"at {RATE_HZ:.0f} Hz.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
