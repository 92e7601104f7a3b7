"""Drone physics of the closed-loop simulator (uavarm/sim/drone.py): invariants of a rigid body
and of a thrust-along-body-z multirotor, checked by independent means (numerical
differentiation of positions and rotation matrices built here from elementary rotations)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from uavarm.sim import drone

G = 9.80665


def R_of(roll, pitch):
    """Base -> world: pitch about y after roll about x (scipy, intrinsic Y then X)."""
    return Rotation.from_euler("YX", [pitch, roll]).as_matrix()


def test_rotation_matches_scipy():
    rng = np.random.default_rng(0)
    for roll, pitch in rng.uniform(-0.6, 0.6, (50, 2)):
        assert np.allclose(drone.rotation(roll, pitch), R_of(roll, pitch), atol=1e-12)


def test_hovering_level_in_still_air_reads_one_g_up():
    t = drone.grid(5.0)
    zero = np.zeros((len(t), 3))
    f = drone.fly(t, zero, zero, zero, zero)
    motion = drone.FlightMotion(f, (0.0, 0.0, -80.0))
    for ti in (0.5, 2.0, 4.9):
        acc, gyro = motion.imu(ti)
        assert np.allclose(acc, [0, 0, 1], atol=1e-9)
        assert np.allclose(gyro, 0, atol=1e-12)
        assert motion.attitude(ti) == pytest.approx((0.0, 0.0), abs=1e-12)


def test_coordinated_flight_without_drag_reads_only_body_z_thrust():
    """The accelerometer of a multirotor whose only force is thrust sees no horizontal
    specific force, however it tilts: why an accelerometer tilt estimate fails in flight."""
    params = drone.DroneParams(drag=0.0)
    f = drone.manoeuvre(20.0, np.random.default_rng(3), gust_mps=0.0, params=params)
    assert f.tilt_deg.max() > 8.0
    motion = drone.FlightMotion(f)               # IMU at the centre of rotation
    thrust = []
    for ti in np.arange(0.5, 19.5, 0.01):
        acc, _ = motion.imu(ti)
        assert abs(acc[0]) < 1e-9 and abs(acc[1]) < 1e-9
        thrust.append(acc[2])
    assert min(thrust) > 0.8 and max(thrust) > 1.01      # it pulls more than 1 g while turning


def test_with_drag_the_horizontal_specific_force_is_the_drag():
    f = drone.hover(10.0, np.random.default_rng(4))
    v = np.gradient(f.pos, f.t, axis=0)
    motion = drone.FlightMotion(f)
    # thrust is along body z, so the specific force's body-x/y part is the aerodynamic force
    # alone; check it as the residual of Newton's law, a - thrust - g, from positions
    a = np.gradient(v, f.t, axis=0)
    for i in range(1000, 9000, 250):
        R = R_of(f.roll[i], f.pitch[i])
        force_body = R.T @ (a[i] + [0, 0, G]) / G
        acc, _ = motion.imu(f.t[i])
        assert np.allclose(acc[:2], force_body[:2], atol=2e-3)


def test_imu_off_the_centre_of_rotation_reads_the_points_acceleration():
    """Specific force at r from the centre of rotation against the second derivative of that
    point's position, p(t) = R(t) r, on the bench (centre still)."""
    f = drone.bench(20.0, np.random.default_rng(5))
    r_mm = np.array([30.0, -20.0, -80.0])
    motion = drone.FlightMotion(f, r_mm)
    R = np.array([R_of(a, b) for a, b in zip(f.roll, f.pitch)])
    p = R @ (r_mm / 1000)
    a = np.gradient(np.gradient(p, f.t, axis=0), f.t, axis=0)
    for i in range(500, 19500, 400):
        want = R[i].T @ (a[i] + [0, 0, G]) / G
        acc, gyro = motion.imu(f.t[i])
        assert np.allclose(acc, want, atol=2e-5)


def test_body_rates_are_those_of_the_rotation_matrix():
    f = drone.hover(5.0, np.random.default_rng(6))
    R = np.array([R_of(a, b) for a, b in zip(f.roll, f.pitch)])
    dR = np.gradient(R, f.t, axis=0)
    for i in range(100, 4900, 200):
        W = R[i].T @ dR[i]                       # skew(omega_body)
        assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], f.omega[i], atol=2e-4)


def test_bench_tilts_up_to_twenty_degrees_with_no_linear_acceleration():
    for seed in range(3):
        f = drone.bench(60.0, np.random.default_rng(seed))
        assert f.tilt_deg.max() == pytest.approx(20.0, abs=0.01)
        assert np.all(f.acc == 0)


def test_hover_tilts_five_to_ten_degrees_at_gust_frequencies():
    for seed in range(3):
        f = drone.hover(40.0, np.random.default_rng(seed))
        dev = np.degrees(np.hypot(f.roll - f.roll.mean(), f.pitch - f.pitch.mean()))
        assert 5.0 <= np.percentile(dev, 95) <= 10.0
        assert np.abs(f.pos[:, :2]).max() < 1.0                  # holds position
        horizontal = np.linalg.norm(f.acc[:, :2], axis=1)
        assert horizontal.std() > 0.2                             # ... but not without accelerating
        # most of the tilt's variance lies in 0.15-2.5 Hz
        x = f.roll - f.roll.mean()
        spec = np.abs(np.fft.rfft(x)) ** 2
        freqs = np.fft.rfftfreq(len(x), 1 / drone.RATE)
        band = (freqs > 0.15) & (freqs < 2.5)
        assert spec[band].sum() > 0.8 * spec[1:].sum()


def test_manoeuvre_flies_two_to_three_metres_per_second_tilting_ten_to_fifteen_degrees():
    for seed in range(3):
        f = drone.manoeuvre(40.0, np.random.default_rng(seed))
        speed = np.linalg.norm(np.gradient(f.pos, f.t, axis=0)[:, :2], axis=1)
        assert 2.0 <= speed.max() <= 3.0
        accelerating = np.linalg.norm(f.acc[:, :2], axis=1) > 0.9 * G * math.tan(math.radians(10))
        assert accelerating.mean() > 0.1
        assert 10.0 <= np.percentile(f.tilt_deg[accelerating], 50) <= 15.0
        assert f.tilt_deg.max() <= 17.0


def test_resampled_log_reproduces_the_flight():
    f = drone.hover(10.0, np.random.default_rng(7))
    idx = np.arange(0, len(f.t), 10)                 # a 100 Hz log
    g = drone.resample(f.t[idx], f.roll[idx], f.pitch[idx], f.acc[idx])
    assert len(g.t) == len(f.t)
    assert np.degrees(np.abs(g.roll - f.roll)).max() < 0.01
    assert np.abs(g.omega - f.omega)[100:-100].max() < math.radians(0.5)
    assert np.abs(g.acc - f.acc).max() < 0.05


def test_preflight_is_still_and_level_then_enters_the_flight_smoothly():
    f = drone.hover(10.0, np.random.default_rng(8))
    g = drone.with_preflight(f, 3.0, ramp_s=2.0)
    n = round(3.0 * drone.RATE)
    assert len(g.t) == n + len(f.t) and g.t[n] == pytest.approx(3.0)
    motion = drone.FlightMotion(g, (0.0, 0.0, -80.0))
    for t in (0.1, 1.5, 2.9):
        acc, gyro = motion.imu(t)
        assert np.allclose(acc, [0, 0, 1], atol=1e-9) and np.allclose(gyro, 0, atol=1e-9)
    assert np.abs(np.diff(g.roll)).max() < math.radians(0.1)           # no jump at take-off
    assert np.allclose(g.roll[n + 2000:], f.roll[2000:]) and np.allclose(g.acc[n + 2000:], f.acc[2000:])
