"""The simulator's errors as ranges: each seed draws its own flight controller, odometry and
IMU from them, and `make sim-report` states its figures across the draws (median, 95th
percentile and worst), so that a figure is not a claim about one tuned-for set of errors.

Each quantity is drawn uniformly from its range, once per seed (the same seed draws the same
errors for every estimator, so the estimators are compared on the same hardware):

- the flight controller's attitude (drone_attitude): white 0.2-0.5 deg and slowly varying
  (first-order Markov) 0.2-0.5 deg RMS per axis, correlation time 10-60 s, at 30-100 Hz,
  15-25 ms late with +-0-5 ms jitter (EKF-class estimators on common flight controllers);
- the odometry's velocity (drone_velocity): white 0.03-0.1 m/s and slowly varying
  0.03-0.1 m/s per axis, 10-60 s, at 30-100 Hz, 15-25 ms late with +-0-5 ms jitter;
- the IMU: imu_model's `ranges` profile (accelerometer bias up to +-15 mg per axis drifting
  up to +-1 mg/min, gyro offset up to +-3 deg/s drifting up to +-0.1 deg/s/min, scales and
  the gyro's cross-axis sensitivity as a calibration leaves them), drawn by the sensor's seed.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import imu_model, scenarios

IMU_PROFILE = "ranges"
LINK = {"rate_hz": (30.0, 100.0), "delay_ms": (15.0, 25.0), "jitter_ms": (0.0, 5.0),
        "noise_deg": (0.2, 0.5), "slow_deg": (0.2, 0.5), "slow_tau_s": (10.0, 60.0)}
VELOCITY = {"rate_hz": (30.0, 100.0), "delay_ms": (15.0, 25.0), "jitter_ms": (0.0, 5.0),
            "noise_mps": (0.03, 0.1), "slow_mps": (0.03, 0.1), "slow_tau_s": (10.0, 60.0)}


# Errors a draw can leave out (`python -m uavarm.sim.report --without`), to find which one
# sets a figure: their sizes set to 0, everything else drawn as before.
LEFT_OUT = {"attitude-slow": ("link", ("slow_deg",)), "attitude-white": ("link", ("noise_deg",)),
            "velocity-slow": ("velocity", ("slow_mps",)), "velocity-white": ("velocity", ("noise_mps",))}


def drawn(scenario: scenarios.Scenario, seed: int, imu_profile: str | None = None,
          without: tuple[str, ...] = ()) -> scenarios.Scenario:
    """The scenario with this seed's draw of the drone's errors, and the IMU's profile of ranges
    (or the one given); the errors named in `without` (LEFT_OUT) zero."""
    rng = np.random.default_rng([seed, 5])

    def params(cls, ranges):
        return cls(**{name: float(rng.uniform(lo, hi)) for name, (lo, hi) in ranges.items()})
    streams = {"link": dataclasses.replace(params(scenarios.LinkParams, LINK), bias_deg=0.0,
                                           outages=scenario.link.outages),
               "velocity": dataclasses.replace(params(scenarios.VelocityParams, VELOCITY),
                                               outages=scenario.velocity.outages)}
    for name in without:
        stream, fields = LEFT_OUT[name]
        streams[stream] = dataclasses.replace(streams[stream], **{f: 0.0 for f in fields})
    return dataclasses.replace(scenario, imu_profile=imu_profile or IMU_PROFILE, **streams)


# The smallest size stated_sizes gives: the model file needs the split's sizes positive.
SIZE_FLOOR = {"fc_error_deg": 0.01, "drone_attitude_white_deg": 0.01, "accel_bias_prior_g": 0.0005}


def stated_sizes(scenario: scenarios.Scenario) -> list[str]:
    """KEY=VALUE edits that state this draw's own error sizes to the split's Kalman filter: the
    flight controller's slow error and its correlation time, its white error, and the spread of
    the IMU profile's horizontal accelerometer bias (uniform, so half-width / sqrt 3). A filter
    that knows each drone's sizes, though not its errors; sizes under SIZE_FLOOR are floored."""
    imu = imu_model.PROFILES[scenario.imu_profile]
    sizes = {"fc_error_deg": scenario.link.slow_deg, "drone_attitude_white_deg": scenario.link.noise_deg,
             "accel_bias_prior_g": max(imu.accel_bias_g[:2]) / math.sqrt(3.0)}
    edits = [f"estimator.{key}={max(value, SIZE_FLOOR[key]):.6g}" for key, value in sizes.items()]
    return edits + [f"estimator.fc_error_tau={scenario.link.slow_tau_s:.6g}"]


def describe(scenario: scenarios.Scenario, imu: imu_model.ImuDraw | None) -> str:
    """One draw in words: what a reader needs to judge the worst case."""
    a, v = scenario.link, scenario.velocity
    parts = [f"drone attitude {a.noise_deg:.2f} deg white + {a.slow_deg:.2f} deg slow ({a.slow_tau_s:.0f} s) at "
             f"{a.rate_hz:.0f} Hz, {a.delay_ms:.0f} +- {a.jitter_ms:.1f} ms",
             f"velocity {v.noise_mps:.3f} m/s white + {v.slow_mps:.3f} m/s slow ({v.slow_tau_s:.0f} s) at "
             f"{v.rate_hz:.0f} Hz, {v.delay_ms:.0f} +- {v.jitter_ms:.1f} ms"]
    if imu is not None:
        mg = ", ".join(f"{1e3 * b:+.1f}" for b in imu.accel_bias)
        drift = ", ".join(f"{6e4 * d:+.2f}" for d in imu.accel_drift)
        dps = ", ".join(f"{math.degrees(b):+.2f}" for b in imu.gyro_bias)
        parts.append(f"accelerometer bias ({mg}) mg drifting ({drift}) mg/min, gyro offset ({dps}) deg/s")
    return "; ".join(parts)


def ranges_text() -> str:
    """The ranges as the report states them."""
    p = imu_model.PROFILES[IMU_PROFILE]
    return (f"drone attitude {LINK['noise_deg'][0]}-{LINK['noise_deg'][1]} deg white + "
            f"{LINK['slow_deg'][0]}-{LINK['slow_deg'][1]} deg slowly varying "
            f"({LINK['slow_tau_s'][0]:.0f}-{LINK['slow_tau_s'][1]:.0f} s) at "
            f"{LINK['rate_hz'][0]:.0f}-{LINK['rate_hz'][1]:.0f} Hz, {LINK['delay_ms'][0]:.0f}-"
            f"{LINK['delay_ms'][1]:.0f} ms late +- 0-{LINK['jitter_ms'][1]:.0f} ms; velocity "
            f"{VELOCITY['noise_mps'][0]}-{VELOCITY['noise_mps'][1]} m/s white + {VELOCITY['slow_mps'][0]}-"
            f"{VELOCITY['slow_mps'][1]} m/s slowly varying at {VELOCITY['rate_hz'][0]:.0f}-"
            f"{VELOCITY['rate_hz'][1]:.0f} Hz, equally late; IMU accelerometer bias 0-"
            f"{1e3 * p.accel_bias_g[0]:.0f} mg per axis drifting 0-{1e3 * p.accel_drift_g_per_min:.0f} mg/min, "
            f"gyro offset 0-{p.gyro_bias_dps:g} deg/s drifting 0-{p.gyro_drift_dps_per_min:g} deg/s/min, "
            f"gyro scale 0-{100 * p.gyro_scale:g} %, cross-axis 0-{100 * p.gyro_cross:g} %, "
            f"accelerometer scale 0-{100 * p.accel_scale:g} %, propeller vibration in flight")
