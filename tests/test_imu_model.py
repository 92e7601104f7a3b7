"""The MPU-6050 sensor model (uavarm/sim/imu_model.py) against its datasheet figures.

Oracles: the numbers of PS-MPU-6000A rev 3.4 and RM-MPU-6000A rev 4.2 (typed here, not
imported from the module under test), scipy.signal.welch for noise densities, scipy's
Butterworth design for the filter's response, and sampling theory for where a tone aliases.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import signal

from uavarm.sim import imu_model
from uavarm.sim.imu_model import PROFILES, ImuDraw, ImuErrors, Mpu6050Sensor, Tone

# Datasheet figures (PS-MPU-6000A rev 3.4, 6.1 / 6.2)
GYRO_DENSITY_DPS = 0.005
ACCEL_DENSITY_G = 400e-6
# RM-MPU-6000A rev 4.2, register 26: DLPF_CFG -> accel bandwidth (Hz), delay (ms)
ACCEL_DLPF = {1: (184, 2.0), 2: (94, 3.0), 3: (44, 4.9), 4: (21, 8.5), 5: (10, 13.8), 6: (5, 19.0)}
GYRO_DLPF = {1: (188, 1.9), 2: (98, 2.8), 3: (42, 4.8), 4: (20, 8.3), 5: (10, 13.4), 6: (5, 18.6)}


def still(t):
    return np.array([0.0, 0.0, 1.0]), np.zeros(3)


def record(sensor, truth, seconds, cfg, div, rate=1000.0):
    """The output registers read at `rate` Hz for `seconds`: (n, 3) accel, (n, 3) gyro."""
    acc, gyro = [], []
    for k in range(1, round(seconds * rate) + 1):
        a, g = sensor.read(k / rate, truth, cfg, div)
        acc.append(a)
        gyro.append(g)
    return np.array(acc), np.array(gyro)


def test_white_noise_density_matches_the_datasheet():
    """In the pass band of the widest filter, at the 1 kHz output rate, the one-sided PSD is
    the datasheet's density squared, on every axis."""
    sensor = Mpu6050Sensor("white", seed=1)
    acc, gyro = record(sensor, still, 30.0, cfg=1, div=0)
    for data, density in ((acc, ACCEL_DENSITY_G), (np.degrees(gyro), GYRO_DENSITY_DPS)):
        f, pxx = signal.welch(data - data.mean(axis=0), fs=1000.0, nperseg=1024, axis=0)
        band = (f > 5) & (f < 60)
        measured = np.sqrt(pxx[band].mean(axis=0))
        assert np.allclose(measured, density, rtol=0.1), (measured, density)


def test_white_profile_has_no_bias_and_noise_through_the_firmwares_filter():
    """The SimBoard's default: zero mean; RMS at the 44 Hz setting is density * sqrt(noise
    bandwidth of a 2nd-order Butterworth = pi/(2 sqrt 2) f_c), e.g. the datasheet's own
    0.05 deg/s at ~100 Hz scales to ~0.035 deg/s."""
    sensor = Mpu6050Sensor("white", seed=2)
    acc, gyro = record(sensor, still, 20.0, cfg=3, div=9, rate=100.0)
    assert np.allclose(acc.mean(axis=0), [0, 0, 1], atol=1e-3)
    assert np.allclose(np.degrees(gyro).mean(axis=0), 0, atol=0.01)
    enbw = math.pi / (2 * math.sqrt(2))
    assert np.allclose(acc.std(axis=0), ACCEL_DENSITY_G * math.sqrt(enbw * 44), rtol=0.15)
    assert np.allclose(np.degrees(gyro).std(axis=0), GYRO_DENSITY_DPS * math.sqrt(enbw * 42), rtol=0.15)


@pytest.mark.parametrize("profile, gyro_dps, accel_g, scale", [
    ("datasheet", 20.0, (0.050, 0.050, 0.080), 0.03),
    ("calibrated", 3.0, (0.005, 0.005, 0.009), 0.004),
    ("ranges", 3.0, (0.015, 0.015, 0.015), 0.004),
])
def test_biases_and_scale_errors_stay_in_their_ranges_and_fill_them(profile, gyro_dps, accel_g, scale):
    draws = [Mpu6050Sensor(profile, seed=s).draw for s in range(300)]
    gyro = np.degrees([d.gyro_bias for d in draws])
    accel = np.array([d.accel_bias for d in draws])
    gscale = np.array([d.gyro_scale for d in draws]) - 1
    assert np.all(np.abs(gyro) <= gyro_dps) and np.all(np.abs(gyro).max(axis=0) > 0.9 * gyro_dps)
    assert np.all(np.abs(accel) <= accel_g) and np.all(np.abs(accel).max(axis=0) > 0.9 * np.array(accel_g))
    assert np.all(np.abs(gscale) <= scale) and np.all(np.abs(gscale).max(axis=0) > 0.9 * scale)


def test_the_datasheet_gyro_reads_a_share_of_the_other_axes_rates():
    """A turn about X only, at 1 rad/s: Y and Z read up to 2 % of it (the datasheet's
    cross-axis sensitivity), the draws filling that range; the profile's other draws are
    those of a sensor without it."""
    draws = [Mpu6050Sensor("datasheet", seed=s).draw for s in range(300)]
    cross = np.array([d.gyro_cross for d in draws])
    assert np.all(np.diagonal(cross, axis1=1, axis2=2) == 0.0)
    off_diagonal = ~np.eye(3, dtype=bool)
    assert np.abs(cross).max() <= 0.02 and np.all(np.abs(cross).max(axis=0)[off_diagonal] > 0.9 * 0.02)
    plain = Mpu6050Sensor(replace(PROFILES["datasheet"], gyro_cross=0.0), seed=7).draw
    assert np.array_equal(plain.gyro_scale, draws[7].gyro_scale) and np.array_equal(plain.gyro_bias, draws[7].gyro_bias)
    sensor = Mpu6050Sensor("datasheet", seed=7)
    d = sensor.draw
    sensor.draw = replace(d, gyro_bias=np.zeros(3), tones=())
    _, gyro = record(sensor, lambda t: (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])), 2.0, cfg=3, div=9,
                     rate=100.0)
    want = d.gyro_scale * np.array([1.0, d.gyro_cross[1, 0], d.gyro_cross[2, 0]])
    assert np.allclose(gyro[-50:].mean(axis=0), want, atol=2e-4)


def test_a_biased_sensor_reads_its_bias():
    sensor = Mpu6050Sensor("datasheet", seed=5)
    sensor.draw = ImuDraw(sensor.draw.gyro_bias, sensor.draw.accel_bias, sensor.draw.gyro_scale,
                          sensor.draw.accel_scale, ())          # no vibration: means only
    acc, gyro = record(sensor, still, 5.0, cfg=3, div=9, rate=100.0)
    d = sensor.draw
    assert np.allclose(acc.mean(axis=0), d.accel_bias + [0, 0, d.accel_scale[2]], atol=1e-3)
    assert np.allclose(gyro.mean(axis=0), d.gyro_bias, atol=math.radians(0.01))


def _sine_gain(cfg, freq, axis):
    """Steady-state amplitude of a unit sine at freq through DLPF_CFG cfg (1 kHz output)."""
    sensor = Mpu6050Sensor("ideal", seed=0)
    w = 2 * math.pi * freq

    def truth(t):
        s = math.sin(w * t)
        return np.array([s, 0.0, 0.0]), np.array([s, 0.0, 0.0])
    acc, gyro = record(sensor, truth, 2.0 + 5.0 / freq, cfg=cfg, div=0)
    out = (acc if axis == "accel" else gyro)[-1000 - round(1000 / freq):, 0]
    return (out.max() - out.min()) / 2


@pytest.mark.parametrize("cfg", [2, 3, 4, 5])
@pytest.mark.parametrize("axis, table", [("accel", ACCEL_DLPF), ("gyro", GYRO_DLPF)])
def test_dlpf_bandwidth_is_the_register_maps(cfg, axis, table):
    """-3 dB at the table's bandwidth; the pass band passes, the stop band stops."""
    bw = table[cfg][0]
    assert _sine_gain(cfg, bw, axis) == pytest.approx(1 / math.sqrt(2), abs=0.03)
    assert _sine_gain(cfg, bw / 10, axis) == pytest.approx(1.0, abs=0.01)


def test_dlpf_delay_at_the_projects_setting():
    """A ramp comes out late by the filter's delay: at DLPF_CFG 3 the table says 4.9 ms
    (accel) and 4.8 ms (gyro); the 2nd-order model has 5.1 / 5.4 ms."""
    sensor = Mpu6050Sensor("ideal", seed=0)

    def ramp(t):
        return np.array([t, 0.0, 0.0]), np.array([t, 0.0, 0.0])
    acc, gyro = record(sensor, ramp, 1.0, cfg=3, div=0)
    t_end = 1.0
    assert (t_end - acc[-1, 0]) * 1e3 == pytest.approx(ACCEL_DLPF[3][1], abs=0.5)
    assert (t_end - gyro[-1, 0]) * 1e3 == pytest.approx(GYRO_DLPF[3][1], abs=0.8)


def test_propeller_tone_aliases_to_the_folded_frequency_with_the_filters_gain():
    """An 83 Hz tone, filtered at DLPF_CFG 3 and sampled at 100 Hz, reads as a 17 Hz tone of
    amplitude |H(83 Hz)| (scipy's 2nd-order Butterworth at 44 Hz, 1 kHz)."""
    sensor = Mpu6050Sensor("ideal", seed=0)
    amp = 0.2
    sensor.draw = ImuDraw(np.zeros(3), np.zeros(3), np.ones(3), np.ones(3),
                          (Tone(83.0, 0.3, np.array([0.0, 0.0, amp]), np.zeros(3)),))
    acc, _ = record(sensor, still, 20.48, cfg=3, div=9, rate=100.0)
    z = acc[:, 2] - acc[:, 2].mean()
    f, pxx = signal.periodogram(z, fs=100.0, window="hann", scaling="spectrum")
    assert f[np.argmax(pxx)] == pytest.approx(17.0, abs=0.1)
    b, a = signal.butter(2, 44.0, fs=1000.0)
    _, h = signal.freqz(b, a, worN=[83.0], fs=1000.0)
    t = np.arange(1, len(z) + 1) / 100.0
    basis = np.c_[np.sin(2 * math.pi * 17.0 * t), np.cos(2 * math.pi * 17.0 * t)]
    coef, *_ = np.linalg.lstsq(basis, z, rcond=None)
    assert np.hypot(*coef) == pytest.approx(amp * abs(h[0]), rel=0.03)


def test_vibration_tones_are_in_the_propeller_band():
    for seed in range(50):
        tones = Mpu6050Sensor("calibrated", seed=seed).draw.tones
        assert len(tones) == 4
        assert all(57.0 <= t.freq <= 97.0 for t in tones)
        assert max(t.freq for t in tones) - min(t.freq for t in tones) <= 6.0


def test_vibration_starts_with_the_motors():
    sensor = Mpu6050Sensor("calibrated", seed=4, vibration_from=1.0)
    t = np.arange(0, 2.0, 0.001)
    v = sensor.sample_errors(t)
    assert np.all(v[t < 1.0] == 0) and np.abs(v[t >= 1.0]).max() > 0.05


def test_output_updates_every_smplrt_div_plus_one_internal_samples():
    sensor = Mpu6050Sensor("white", seed=3)
    acc, _ = record(sensor, still, 0.2, cfg=3, div=9)
    changes = np.flatnonzero(np.any(np.diff(acc, axis=0) != 0, axis=1)) + 2   # ms of each update
    assert np.all(changes % 10 == 0)
    assert len(changes) == 20          # at 10, 20, ..., 200 ms


def test_seeded_and_deterministic():
    a = record(Mpu6050Sensor("datasheet", seed=7), still, 0.5, cfg=3, div=9, rate=100.0)
    b = record(Mpu6050Sensor("datasheet", seed=7), still, 0.5, cfg=3, div=9, rate=100.0)
    c = record(Mpu6050Sensor("datasheet", seed=8), still, 0.5, cfg=3, div=9, rate=100.0)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


def test_profiles_are_named_and_the_vibration_can_be_turned_off():
    assert set(imu_model.PROFILES) == {"ideal", "white", "calibrated", "datasheet", "ranges"}
    e = imu_model.PROFILES["calibrated"].without_vibration()
    assert isinstance(e, ImuErrors) and not e.vibration
    assert Mpu6050Sensor(e, seed=0).draw.tones == ()


def test_the_ranges_profile_drifts_within_its_rates_and_leaves_the_other_draws_alone():
    """Drift rates drawn within +-1 mg/min (accelerometer) and +-0.1 deg/s/min (gyro) per axis,
    filling the range; a sensor without drift draws the same biases and scales."""
    draws = [Mpu6050Sensor("ranges", seed=s).draw for s in range(300)]
    accel = np.array([d.accel_drift for d in draws]) * 60.0          # g/min
    gyro = np.degrees([d.gyro_drift for d in draws]) * 60.0          # deg/s per min
    assert np.all(np.abs(accel) <= 0.001) and np.all(np.abs(accel).max(axis=0) > 0.9 * 0.001)
    assert np.all(np.abs(gyro) <= 0.1) and np.all(np.abs(gyro).max(axis=0) > 0.9 * 0.1)
    still_profile = replace(PROFILES["ranges"], accel_drift_g_per_min=0.0, gyro_drift_dps_per_min=0.0)
    plain = Mpu6050Sensor(still_profile, seed=7).draw
    assert np.array_equal(plain.accel_bias, draws[7].accel_bias) and np.array_equal(plain.gyro_cross, draws[7].gyro_cross)
    assert not plain.accel_drift.any() and not plain.gyro_drift.any()


def test_a_drifting_sensor_reads_its_bias_moving_in_time():
    """Held still, the reading moves by the drift rate times the time since power-up."""
    sensor = Mpu6050Sensor("ideal", seed=3)                           # no noise: the drift alone
    rate_acc, rate_gyro = np.array([0.002, -0.001, 0.0005]), np.radians([0.05, -0.02, 0.01])   # per s
    sensor.draw = replace(sensor.draw, accel_drift=rate_acc, gyro_drift=rate_gyro)
    acc, gyro = record(sensor, still, 6.0, cfg=3, div=9, rate=100.0)
    moved_acc = acc[-100:].mean(axis=0) - acc[:100].mean(axis=0)      # 5 s apart
    moved_gyro = gyro[-100:].mean(axis=0) - gyro[:100].mean(axis=0)
    assert np.allclose(moved_acc, 5.0 * rate_acc, rtol=1e-3)
    assert np.allclose(moved_gyro, 5.0 * rate_gyro, rtol=1e-3)
