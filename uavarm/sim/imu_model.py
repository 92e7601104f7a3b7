"""The MPU-6050 as a sensor: what its output registers hold for a given true motion.

Uavarm.mpu6050_sim is the register file (what I2C sees); this module decides the numbers
that go into it. The chip samples its sensors at an internal 1 kHz, passes them through the
digital low-pass filter that CONFIG.DLPF_CFG selects, and updates the output registers with
every (SMPLRT_DIV + 1)-th filtered sample: plain decimation, so whatever the DLPF leaves
above half the output rate folds down (a 80 Hz propeller tone sampled at 100 Hz reads as
20 Hz). The simulator reads DLPF_CFG and SMPLRT_DIV from the register file, i.e. the
setting the firmware wrote.

Figures (InvenSense PS-MPU-6000A rev 3.4, sections 6.1 and 6.2; RM-MPU-6000A rev 4.2,
register 26):

- gyro rate noise spectral density 0.005 deg/s/sqrt(Hz); initial zero-rate output (ZRO)
  tolerance +-20 deg/s; sensitivity scale factor tolerance +-3 %; cross-axis sensitivity
  +-2 %;
- accelerometer noise power spectral density 400 ug/sqrt(Hz); zero-g initial calibration
  tolerance +-50 mg (X, Y), +-80 mg (Z); zero-g change over 0..70 C +-35 mg (X, Y),
  +-60 mg (Z); sensitivity initial tolerance +-3 %, change over temperature +-0.02 %/C;
- DLPF_TABLE below: bandwidth and delay of each DLPF_CFG.

Modelling choices, stated:

- The noise is white at the densities above over the 0..500 Hz band of the 1 kHz internal
  rate, before the DLPF (the datasheet's "total RMS noise 0.05 deg/s at DLPF_CFG = 2" is
  what 0.005 deg/s/sqrt(Hz) gives through a ~100 Hz filter, so the densities are pre-filter).
- The DLPF is a 2nd-order Butterworth low-pass at the table's bandwidth (bilinear transform
  with pre-warping at 1 kHz). Its delay at DC (sqrt(2) / (2 pi f_c)) is 5.1 ms at the
  project's 44 Hz setting against the table's 4.9 ms, and 2.4 ms at 94 Hz against 3.0 ms; at
  21 Hz and below the table's delays are shorter than any non-resonant filter of that
  bandwidth can have (they cannot be group delays at DC), so only the bandwidth is matched.
  DLPF_CFG 0 (260 Hz, gyro at 8 kHz) is approximated at the 1 kHz rate.
- Biases and scale errors are drawn uniformly within +-range per axis, once per seeded
  sensor. Profiles (PROFILES): `ideal` (none of it), `white` (noise only: the SimBoard's
  default, so its data are never frozen), `calibrated` (the closed-loop simulator's
  default: what `uavarm calibrate imu` leaves, i.e. the datasheet's temperature drift for a
  +-10 C change since then: accelerometer +-5 mg X/Y, +-9 mg Z and +-0.2 % scale; gyro
  scale +-0.4 % (its +-2 % over temperature taken as spread linearly over the specified
  -40..85 C, +-0.32 %, plus the calibration's own error, 0.08 % on the simulated board);
  the gyro's cross-axis sensitivity that the calibration leaves, +-0.75 % (it measures the
  datasheet's +-2 % to within that on the simulated board, but for the Y rate seen on X and
  Z, told to +-1.25 % only, which the profile does not single out: the chip's whole +-2 % not
  undone moved the simulator's figures by at most 0.05 mm; the firmware undoes what it
  measured); the gyro's ZRO +-3 deg/s, the few deg/s real parts show well inside the +-20 deg/s
  tolerance, as it drifts (the estimator learns it); propeller vibration on), `datasheet`
  (the full initial tolerances, +-20 deg/s, +-50/+-80 mg, +-3 %, the gyro's +-2 % cross-axis
  sensitivity, vibration on: a worst case, uncalibrated), `ranges` (what `make sim-report`
  draws across: `calibrated` with the accelerometer's bias widened to +-15 mg on every axis,
  a bench calibration followed by a temperature change of up to 30 C, and both biases
  drifting during the run as the board warms: +-1 mg/min per accelerometer axis (0.5 mg/C,
  2 C/min) and +-0.1 deg/s/min per gyro axis).
- A drift is linear in time from power-up, drawn uniformly within +-range per axis from a
  generator of its own (the profile's other draws and noise stay as without it).
- The gyro's cross-axis sensitivity: axis i reads scale_i (rate_i + sum_j c_ij rate_j), each
  c_ij drawn uniformly within +-range from a generator of its own (the profile's other draws
  and noise stay as without it).
- Propeller vibration: one tone per motor (4) at a hover rotor frequency drawn in
  57..97 Hz, each motor within +-3 Hz of it, random phases; amplitudes per motor
  (VIBRATION_ACCEL_G, VIBRATION_GYRO_DPS) are an assumption for an arm base bolted to the
  frame of a balanced 650-class quad (a few tenths of a g in all; flight controllers call
  raw vibration of several g too much). Constant rotor speed: the tones do not follow
  thrust.
- No cross-axis sensitivity of the accelerometer, nonlinearity or g-sensitivity of the gyro; quantisation is the register file's (int16 of the
  full-scale range).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

INTERNAL_RATE = 1000.0        # Hz: the sample rate SMPLRT_DIV divides (DLPF_CFG 1..6)

# DLPF_CFG -> (accel bandwidth Hz, accel delay ms, gyro bandwidth Hz, gyro delay ms)
DLPF_TABLE = {
    0: (260.0, 0.0, 256.0, 0.98),
    1: (184.0, 2.0, 188.0, 1.9),
    2: (94.0, 3.0, 98.0, 2.8),
    3: (44.0, 4.9, 42.0, 4.8),
    4: (21.0, 8.5, 20.0, 8.3),
    5: (10.0, 13.8, 10.0, 13.4),
    6: (5.0, 19.0, 5.0, 18.6),
}

GYRO_NOISE_DPS_RTHZ = 0.005
ACCEL_NOISE_G_RTHZ = 400e-6
ACCEL_ZERO_G_TOLERANCE_G = (0.050, 0.050, 0.080)
ACCEL_BIAS_RANGE_G = 0.015       # per axis, after a bench calibration and a temperature change
GYRO_ZRO_TOLERANCE_DPS = 20.0
SCALE_TOLERANCE = 0.03
CROSS_AXIS_TOLERANCE = 0.02      # the gyro's
CROSS_AXIS_CALIBRATED = 0.0075   # ... what `uavarm calibrate imu` leaves of it (tests/test_calibrate.py) ...
CROSS_AXIS_CALIBRATED_Y_FED = 0.0125   # ... but of the Y rate seen on X and Z: its six positions turn Y once
VIBRATION_BAND_HZ = (57.0, 97.0)
VIBRATION_MOTORS = 4
VIBRATION_MOTOR_SPREAD_HZ = 3.0
VIBRATION_ACCEL_G = (0.05, 0.05, 0.10)      # per motor, amplitude, IMU axes
VIBRATION_GYRO_DPS = (0.4, 0.4, 0.2)         # per motor, amplitude


@dataclass(frozen=True)
class ImuErrors:
    """What a sensor of this kind gets wrong; ranges are +-half-widths of uniform draws."""
    name: str
    gyro_noise_dps_rthz: float = GYRO_NOISE_DPS_RTHZ
    accel_noise_g_rthz: float = ACCEL_NOISE_G_RTHZ
    gyro_bias_dps: float = 0.0
    accel_bias_g: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_scale: float = 0.0
    accel_scale: float = 0.0
    gyro_cross: float = 0.0
    accel_drift_g_per_min: float = 0.0     # per axis, during the run
    gyro_drift_dps_per_min: float = 0.0
    vibration: bool = False
    vibration_accel_g: tuple[float, float, float] = VIBRATION_ACCEL_G
    vibration_gyro_dps: tuple[float, float, float] = VIBRATION_GYRO_DPS

    def without_vibration(self) -> ImuErrors:
        return replace(self, vibration=False)


PROFILES = {
    "ideal": ImuErrors("ideal", gyro_noise_dps_rthz=0.0, accel_noise_g_rthz=0.0),
    "white": ImuErrors("white"),
    "calibrated": ImuErrors("calibrated", gyro_bias_dps=3.0, accel_bias_g=(0.005, 0.005, 0.009),
                            gyro_scale=0.004, accel_scale=0.002, gyro_cross=CROSS_AXIS_CALIBRATED, vibration=True),
    "datasheet": ImuErrors("datasheet", gyro_bias_dps=GYRO_ZRO_TOLERANCE_DPS,
                           accel_bias_g=ACCEL_ZERO_G_TOLERANCE_G, gyro_scale=SCALE_TOLERANCE,
                           accel_scale=SCALE_TOLERANCE, gyro_cross=CROSS_AXIS_TOLERANCE, vibration=True),
    "ranges": ImuErrors("ranges", gyro_bias_dps=3.0, accel_bias_g=(ACCEL_BIAS_RANGE_G,) * 3,
                        gyro_scale=0.004, accel_scale=0.002, gyro_cross=CROSS_AXIS_CALIBRATED,
                        accel_drift_g_per_min=0.001, gyro_drift_dps_per_min=0.1, vibration=True),
}


@dataclass(frozen=True)
class Tone:
    freq: float                      # Hz
    phase: float                     # rad
    accel_g: np.ndarray              # amplitude per IMU axis
    gyro_rad_s: np.ndarray


@dataclass(frozen=True)
class ImuDraw:
    """One sensor's realised errors (IMU axes; g and rad/s)."""
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gyro_scale: np.ndarray           # multiplicative: 1 + error
    accel_scale: np.ndarray
    tones: tuple[Tone, ...] = field(default_factory=tuple)
    gyro_cross: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))   # c_ij, zero diagonal
    accel_drift: np.ndarray = field(default_factory=lambda: np.zeros(3))        # g/s
    gyro_drift: np.ndarray = field(default_factory=lambda: np.zeros(3))         # rad/s per s

    @property
    def drifts(self) -> bool:
        return bool(self.accel_drift.any() or self.gyro_drift.any())


def draw(errors: ImuErrors, rng: np.random.Generator) -> ImuDraw:
    def sym(half):
        return rng.uniform(-1.0, 1.0, 3) * np.asarray(half, dtype=float)
    gyro_bias = np.radians(sym(errors.gyro_bias_dps))
    accel_bias = sym(errors.accel_bias_g)
    gyro_scale = 1.0 + sym(errors.gyro_scale)
    accel_scale = 1.0 + sym(errors.accel_scale)
    tones = ()
    if errors.vibration:
        hover = rng.uniform(*VIBRATION_BAND_HZ)
        tones = tuple(Tone(float(np.clip(hover + rng.uniform(-1, 1) * VIBRATION_MOTOR_SPREAD_HZ, *VIBRATION_BAND_HZ)),
                           float(rng.uniform(0, 2 * math.pi)),
                           np.asarray(errors.vibration_accel_g, dtype=float),
                           np.radians(np.asarray(errors.vibration_gyro_dps, dtype=float)))
                      for _ in range(VIBRATION_MOTORS))
    cross = np.zeros((3, 3))
    if errors.gyro_cross:
        cross = (1.0 - np.eye(3)) * rng.spawn(1)[0].uniform(-errors.gyro_cross, errors.gyro_cross, (3, 3))
    accel_drift, gyro_drift = np.zeros(3), np.zeros(3)
    if errors.accel_drift_g_per_min or errors.gyro_drift_dps_per_min:
        own = rng.spawn(1)[0]
        accel_drift = own.uniform(-1.0, 1.0, 3) * errors.accel_drift_g_per_min / 60.0
        gyro_drift = np.radians(own.uniform(-1.0, 1.0, 3) * errors.gyro_drift_dps_per_min / 60.0)
    return ImuDraw(gyro_bias, accel_bias, gyro_scale, accel_scale, tones, cross, accel_drift, gyro_drift)


def butterworth2(cutoff: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of a 2nd-order Butterworth low-pass, bilinear transform pre-warped at cutoff."""
    k = math.tan(math.pi * min(cutoff, 0.499 * fs) / fs)
    norm = 1.0 + math.sqrt(2.0) * k + k * k
    b = np.array([k * k, 2 * k * k, k * k]) / norm
    a = np.array([1.0, 2.0 * (k * k - 1.0) / norm, (1.0 - math.sqrt(2.0) * k + k * k) / norm])
    return b, a


class Mpu6050Sensor:
    """A seeded MPU-6050 sensor. `read(t, truth, dlpf_cfg, smplrt_div)` runs the chip's
    internal 1 kHz pipeline up to time t (s) and returns what its output registers hold:
    (specific force in g, angular rate in rad/s), IMU axes. truth(t) gives the true
    (specific force g, rate rad/s) in IMU axes at an internal sample time."""

    def __init__(self, errors: ImuErrors | str = "white", seed: int = 0, vibration_from: float = 0.0):
        self.errors = PROFILES[errors] if isinstance(errors, str) else errors
        self.vibration_from = vibration_from      # s: the motors start (before: on the ground, off)
        self.rng = np.random.default_rng(seed)
        self.draw = draw(self.errors, self.rng)
        fs = INTERNAL_RATE
        self.noise_std = np.array([self.errors.accel_noise_g_rthz] * 3
                                  + [math.radians(self.errors.gyro_noise_dps_rthz)] * 3) * math.sqrt(fs / 2)
        self._k = 0                  # next internal sample index (time k / fs)
        self._cfg = None
        self._z = np.zeros((2, 6))   # DLPF state (transposed direct form II), per axis
        self.output = (np.zeros(3), np.zeros(3))

    def _coefficients(self, cfg: int):
        accel_bw, _, gyro_bw, _ = DLPF_TABLE[cfg]
        ba, aa = butterworth2(accel_bw, INTERNAL_RATE)
        bg, ag = butterworth2(gyro_bw, INTERNAL_RATE)
        self._b = np.array([np.r_[[ba[i]] * 3, [bg[i]] * 3] for i in range(3)])
        self._a = np.array([np.r_[[aa[i]] * 3, [ag[i]] * 3] for i in range(3)])
        self._blocks = {}

    def _block(self, n: int):
        """(P, W) for n samples: the filter's state after them is P z + sum_i W[i] x_i, from
        state z (per axis: (6, 2), z0 and z1 of the transposed direct form II) and inputs x_i.
        The same recursion as a loop over the samples, in a few array operations."""
        if n not in self._blocks:
            b, a = self._b, self._a
            step = np.zeros((6, 2, 2))
            step[:, 0, 0], step[:, 0, 1], step[:, 1, 0] = -a[1], 1.0, -a[2]
            gain = np.stack([b[1] - a[1] * b[0], b[2] - a[2] * b[0]], axis=1)[..., None]
            powers = [np.broadcast_to(np.eye(2), (6, 2, 2))]
            for _ in range(n):
                powers.append(step @ powers[-1])
            weights = np.array([(powers[n - 1 - i] @ gain)[..., 0] for i in range(n)]).reshape(n, 6, 2)
            self._blocks[n] = (powers[n], weights)
        return self._blocks[n]

    def _state_after(self, z: np.ndarray, x: np.ndarray) -> np.ndarray:
        P, W = self._block(len(x))
        return (P @ z[..., None])[..., 0] + np.einsum("iak,ia->ak", W, x)

    def _start(self, x: np.ndarray) -> None:
        """Filter state at rest on x (the chip has been on long before the firmware asks)."""
        b, a = self._b, self._a
        self._z[1] = (b[2] - a[2]) * x
        self._z[0] = (b[1] - a[1]) * x + self._z[1]

    def sample_errors(self, t: np.ndarray) -> np.ndarray:
        """(n, 6) additive vibration at the internal sample times t."""
        out = np.zeros((len(t), 6))
        for tone in self.draw.tones:
            s = np.sin(2 * math.pi * tone.freq * t + tone.phase)[:, None]
            out += s * np.r_[tone.accel_g, tone.gyro_rad_s]
        out[t < self.vibration_from] = 0.0
        return out

    def read(self, t: float, truth, dlpf_cfg: int, smplrt_div: int):
        dlpf_cfg = int(dlpf_cfg) & 7
        dlpf_cfg = dlpf_cfg if dlpf_cfg in DLPF_TABLE else 0     # 7 is reserved
        if dlpf_cfg != self._cfg:
            self._coefficients(dlpf_cfg)
        end = math.floor(t * INTERNAL_RATE + 1e-6)
        if end < self._k:
            return self.output
        ks = np.arange(self._k, end + 1)
        times = ks / INTERNAL_RATE
        d = self.draw
        x = np.empty((len(ks), 6))
        for i, ti in enumerate(times):
            acc, gyro = truth(float(ti))
            x[i, :3] = acc
            x[i, 3:] = gyro
        x[:, :3] = x[:, :3] * d.accel_scale + d.accel_bias
        x[:, 3:] = (x[:, 3:] @ (np.eye(3) + d.gyro_cross).T) * d.gyro_scale + d.gyro_bias
        if d.drifts:
            x += times[:, None] * np.r_[d.accel_drift, d.gyro_drift]
        x += self.sample_errors(times)
        if self._cfg is None:
            self._start(x[0])   # at rest on the noise-free signal: a noise sample is no rest state
        x += self.rng.standard_normal(x.shape) * self.noise_std
        self._cfg = dlpf_cfg
        z = self._z.T                                    # (6, 2)
        period = int(smplrt_div) + 1
        latched = end - end % period - self._k           # the last sample the registers take
        if latched >= 0:
            y = self._b[0] * x[latched] + self._state_after(z, x[:latched])[:, 0]
            self.output = (y[:3].copy(), y[3:].copy())
        self._z = self._state_after(z, x).T.copy()
        self._k = end + 1
        return self.output
