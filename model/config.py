"""Load and validate the manipulator model file.

Every error names the file and the dotted key, so a user who mistypes a number in
manipulator.toml is told exactly where. The loader returns plain frozen dataclasses;
the symbolic modules read nothing else.
"""
from __future__ import annotations

import difflib
import hashlib
import math
from fractions import Fraction
import tomllib
from dataclasses import dataclass
from pathlib import Path

from . import pose_tolerance, servo_models

DEFAULT_MODEL = Path(__file__).with_name("manipulator.toml")
JOINTS = ("theta1", "theta2", "theta3")
# MPU-6050 choices (register value of each setting, PS-MPU-6000A rev 3.4 section 4)
ACCEL_RANGES_G = {2: 0, 4: 1, 8: 2, 16: 3}             # AFS_SEL
GYRO_RANGES_DPS = {250: 0, 500: 1, 1000: 2, 2000: 3}   # FS_SEL


def accel_lsb_per_g(range_g: int) -> int:
    """MPU-6050 accelerometer counts per g at a full-scale range (16384 at +-2 g, halved per step)."""
    return 16384 >> ACCEL_RANGES_G[range_g]


def gyro_dps_per_lsb(range_dps: int) -> float:
    """MPU-6050 gyro deg/s per count: full scale over 32768 (the datasheet's 131, 65.5, 32.8,
    16.4 LSB/(deg/s) round it)."""
    return range_dps / 32768
DLPF_BANDWIDTHS = {260: 0, 184: 1, 94: 2, 44: 3, 21: 4, 10: 5, 5: 6}   # DLPF_CFG, accel Hz
# Every length of the model (mm) is at most 10 m: the generated code is float32, and the
# code generator's exact SymPy checks take minutes on lengths like 1e300. A link is 0 or at
# least 1 um long, for the same reason at the other end (1e-300).
LENGTH_MAX_MM = 10_000.0
LENGTH_MIN_MM = 0.001
# A link shorter than 1 mm is a length in metres by mistake (L2 = 0.065 for 65 mm).
LINK_PLAUSIBLE_MM = 1.0
# A UART hears another baud within 3 % (the e-manuals' Baud Rate tables).
BAUD_TOLERANCE = 0.03
# The slowest heartbeat (s): the drone side counts a link silent after 1.5 s without one
# and waits 1 s for one to confirm a command, so three and two must fit in those.
HEARTBEAT_SLOWEST_S = 0.5

# Every key of the model file, by table; the imu.accel_bias, imu.accel_scale,
# imu.gyro_bias_dps, imu.gyro_scale, imu.gyro_cross_axis and servo.response_lag calibration and
# servo.model (then an AX-12A) may be absent. Any other key is refused (a typo would
# otherwise be ignored, or reported as the key it was meant to be missing).
_KEYS_BY_TABLE = {
    "geometry": "L1 L2 L3",
    "joints.theta1": "min max", "joints.theta2": "min max", "joints.theta3": "min max",
    "collision": "body_z leg_angles leg_half_width leg_distance",
    "servo": "model baud units_max range_deg return_delay_us park_speed_rpm transit_speed_rpm "
             "working_speed_rpm speed_margin boot_time response_lag zero_tolerance_deg bench_torque_limit",
    "servo.theta1": "id zero direction", "servo.theta2": "id zero direction",
    "servo.theta3": "id zero direction",
    "park": "q",
    "motion": "axis_hold_radius axis_release_radius follow_window_deg stretch_margin",
    "link": "silence_timeout heartbeat_period frame_gap",
    "imu": "sample_rate i2c_address accel_range_g gyro_range_dps dlpf_bandwidth mounting_rpy "
           "accel_bias accel_scale gyro_bias_dps gyro_scale gyro_cross_axis",
    "mount": "offset",
    "masses": "servo upper_arm upper_arm_com forearm forearm_com end_effector end_effector_com",
    "filters.accel": "cutoff order", "filters.gyro": "cutoff order",
    "estimator": "kind complementary_gyro_weight accel_gain bias_gain align_accel_gain align_bias_gain "
                 "accel_reject_g accel_reject_deg gyro_bias_max_dps drone_attitude link_gain "
                 "link_bias_gain link_delay_min link_delay_max link_timeout lead_time drone_velocity "
                 "velocity_bandwidth link_gain_with_velocity link_bias_gain_with_velocity fc_error_gain "
                 "fc_error_max_deg fc_error_tau fc_error_deg drone_attitude_white_deg accel_bias_prior_g "
                 "accel_bias_walk_g accel_bias_attitude_gain accel_bias_bandwidth accel_bias_max_g gate_sigmas "
                 "drone_attitude_noise_deg drone_velocity_noise drift_dps drift_max_deg reject_after retake_after "
                 "correction_max_deg",
}
UNKNOWN_KEYS_NAMED = 5
GATE_WIDEST_DEG = 45.0        # the drone-attitude gate at its widest (deg)
KNOWN_KEYS = tuple(f"{table}.{name}" for table, names in _KEYS_BY_TABLE.items() for name in names.split())


class ModelError(ValueError):
    """The model file is missing, unreadable or inconsistent."""


@dataclass(frozen=True)
class JointLimit:
    min_deg: float
    max_deg: float

    @property
    def min_rad(self) -> float:
        return math.radians(self.min_deg)

    @property
    def max_rad(self) -> float:
        return math.radians(self.max_deg)


@dataclass(frozen=True)
class Servo:
    id: int
    zero: int
    direction: int


@dataclass(frozen=True)
class Filter:
    cutoff: float
    order: int


@dataclass(frozen=True)
class Model:
    path: Path
    sha256: str
    L1: float
    L2: float
    L3: float
    limits: tuple[JointLimit, JointLimit, JointLimit]
    body_z: float
    leg_angles: tuple[float, ...]
    leg_half_width: float
    leg_distance: float
    servo_model: servo_models.ServoModel   # servo.model's facts (model/servo_models.py)
    servo_baud: int
    servo_units_max: int
    servo_range_deg: float
    servos: tuple[Servo, Servo, Servo]
    servo_return_delay_us: int
    park_speed_rpm: float
    transit_speed_rpm: float
    working_speed_rpm: float
    servo_speed_margin: float      # the share of the no-load speed at the reported supply goals may take
    servo_boot_time: float
    servo_response_lag: float      # s: how far the shaft lags its goal (the lead time covers it)
    servo_zero_tolerance_deg: float  # deg: how far a joint may be off after a careful calibration
    servo_bench_torque_limit: float  # share of the maximum torque the servos get on the bench (enable 2)
    park_deg: tuple[float, float, float]
    link_silence_timeout: float
    heartbeat_period: float
    link_frame_gap: float
    sample_rate: float
    imu_address: int
    accel_range_g: int
    gyro_range_dps: int
    dlpf_bandwidth: int
    imu_mounting_rpy_deg: tuple[float, float, float]
    imu_calibration: "ImuCalibration"
    mount_offset: tuple[float, float, float]
    accel_filter: Filter
    gyro_filter: Filter
    complementary_gyro_weight: float
    estimator: "Estimator"
    motion: "Motion"
    masses: "Masses"


# Plausible calibration results (MPU-6050 datasheet: zero-g offset +-80 mg on X and Y,
# +-150 mg on Z; sensitivity within 3 %, the gyro's +-2 % more over temperature): beyond
# these the chip or the procedure is broken.
ACCEL_BIAS_MAX_G = 0.25
ACCEL_SCALE_RANGE = (0.9, 1.1)
GYRO_SCALE_RANGE = (0.9, 1.1)
# The gyro's cross-axis sensitivity: the datasheet's +-2 %, twice that taken for the chip's.
GYRO_CROSS_AXIS_MAX = 0.04
# An AX-12A's lag behind its goal until measured: inside the factory compliance slope (32
# units) its duty, and at no load its speed, is proportional to the error, so the error
# decays with 32 units / (59 rpm = 1207 units/s) = 26.5 ms (an assumption from the servo's
# control law, not a measured figure: `uavarm calibrate lag` measures it). A servo lagging more than
# SERVO_LAG_MAX_S is too slow to stabilise anything (or is not following at all).
SERVO_LAG_ASSUMED_S = 0.0265
SERVO_LAG_MAX_S = 0.15
# A servo zero off by more than this is not a calibration (at the zero pose, by eye, a joint
# 10 deg off is plain to see).
ZERO_TOLERANCE_MAX_DEG = 10.0
# Below this share of its maximum torque a servo on the bench may not hold the arm up (the
# simulated arm held straight out level takes 7 %).
BENCH_TORQUE_MIN = 0.1


@dataclass(frozen=True)
class ImuCalibration:
    """[imu] calibration, IMU axes: each accelerometer axis reads scale x (true) + bias (g);
    gyro axis i reads gyro_scale[i] x (rate_i + sum over j of gyro_cross_axis[i][j] x rate_j)
    + its zero-rate offset, the offset (deg/s) the estimator starts from. Identity when absent."""
    accel_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    gyro_bias_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    gyro_cross_axis: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 3


@dataclass(frozen=True)
class Motion:
    """[motion]: how the arm moves from one pose to the next."""
    axis_hold_radius: float        # mm: joint 1 holds while the target is this close to its axis ...
    axis_release_radius: float     # mm: ... and follows it again beyond this
    follow_window_deg: float       # deg: following a tilt turns joint 1 at most this far from its goal
    stretch_margin: float          # mm: the arm stops this short of full stretch


@dataclass(frozen=True)
class Masses:
    """[masses]: the arm's moving parts (g) and where each one's centre of mass sits (mm from
    its link's joint, along the link): the URDF's inertials, the simulator's gravity torques."""
    servo: float                   # each AX-12A
    upper_arm: float               # the upper arm's brackets and screws ...
    upper_arm_com: float           # ... their centre, from the shoulder
    forearm: float                 # the forearm's, from the elbow
    forearm_com: float
    end_effector: float            # the tool, from the elbow
    end_effector_com: float


MASS_MIN_G = 1.0         # a part lighter than a gram is a mass in kilograms by mistake
MASS_MAX_G = 2000.0      # four times what an AX-12A holds out at the arm's reach


ESTIMATOR_KINDS = ("complementary", "quaternion")
HISTORY_MAX = 32    # samples of attitude history the firmware keeps (stabiliser.h STAB_HISTORY)


@dataclass(frozen=True)
class Estimator:
    """[estimator]: which attitude estimator, its gains, the drone-attitude fusion and the lead."""
    kind: str                      # "complementary" | "quaternion"
    accel_gain: float              # 1/s, quaternion: accelerometer correction in flight (engaged)
    bias_gain: float               # 1/s^2, quaternion: gyro-bias integral gain in flight
    align_accel_gain: float        # 1/s, while the arm is not engaged (at rest, before flight)
    align_bias_gain: float         # 1/s^2, idem
    accel_reject_g: float          # g: accelerometer weight falls to 0 at this |norm - 1 g|
    accel_reject_deg: float        # deg: ... and at this angle from the gyro-propagated up (in flight)
    gyro_bias_max_dps: float       # deg/s: the bias estimate's clamp
    drone_attitude: bool           # fuse the drone's attitude from the link
    link_gain: float               # 0..1: fraction of the measured tilt error removed per message
    link_bias_gain: float          # 1/s: gyro-bias correction from the link's error
    link_delay_min: float          # s: the link's smallest delay (measurement to arrival)
    link_delay_max: float          # s: older measurements are refused (history length)
    link_timeout: float            # s: without a fresh message, the IMU alone again
    lead_time: float               # s: command ahead along the measured rate (0: off)
    drone_velocity: bool           # fuse the drone's velocity from the link (model/velocity.py)
    velocity_bandwidth: float      # rad/s: of its correction
    link_gain_with_velocity: float      # link_gain while the velocity is fresh too
    link_bias_gain_with_velocity: float  # link_bias_gain while the velocity is fresh too
    fc_error_gain: float           # 1/s: the flight controller's error learnt from its disagreement
    fc_error_max_deg: float        # deg: the clamp of the flight controller's estimated error
    fc_error_tau: float            # s: its correlation time, over which the learnt error fades (0: never)
    fc_error_deg: float            # deg: its size, 1 sigma (the split's Kalman filter)
    drone_attitude_white_deg: float  # deg: the drone attitude's white error per message, 1 sigma (the same)
    accel_bias_prior_g: float      # g: the accelerometer's bias the split expects, 1 sigma (0: fixed gains)
    accel_bias_walk_g: float       # g: how far that bias wanders in a minute, 1 sigma (the same)
    accel_bias_attitude_gain: float  # 1/s: the tilt and the accelerometer's bias moved towards the drone's attitude
    accel_bias_bandwidth: float    # rad/s: the accelerometer's bias learnt along up (0: not learnt)
    accel_bias_max_g: float        # g: the clamp of its estimate
    gate_sigmas: float             # a drone message is refused beyond this many expected spreads
    drone_attitude_noise_deg: float  # deg, 1 sigma: the flight controller's attitude error
    drone_velocity_noise: float    # m/s per axis, 1 sigma: the odometry's velocity error
    drift_dps: float               # deg/s: how fast the estimate may drift without the drone's messages
    drift_max_deg: float           # deg: ... and how far at most
    reject_after: float            # s: a stream refused this long is dropped (and flagged)
    retake_after: float            # s: a dropped stream agreeing this long is taken back
    correction_max_deg: float      # deg: the most one attitude message turns the estimate by


class _Reader:
    """Typed access to the parsed TOML with errors that name file and key."""

    def __init__(self, path: Path, data: dict):
        self.path = path
        self.data = data
        self.read: set[str] = set()      # every key asked for


    def fail(self, key: str, message: str) -> ModelError:
        return ModelError(f"{self.path}: {key}: {message}")

    def get(self, key: str):
        self.read.add(key)
        node = self.data
        for part in key.split("."):
            if not isinstance(node, dict) or part not in node:
                raise self.fail(key, "missing")
            node = node[part]
        return node

    def has(self, key: str) -> bool:
        try:
            self.get(key)
        except ModelError:
            return False
        return True

    def number(self, key: str, *, positive=False, nonnegative=False, lo=None, hi=None) -> float:
        value = self.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected a number, got {type(value).__name__} {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(key, f"must be finite, got {value}")
        if positive and value <= 0:
            raise self.fail(key, f"must be positive, got {value}")
        if nonnegative and value < 0:
            raise self.fail(key, f"must not be negative, got {value}")
        if lo is not None and value < lo:
            raise self.fail(key, f"must be >= {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.fail(key, f"must be <= {hi}, got {value}")
        return value

    def integer(self, key: str, *, lo=None, hi=None, choices=None) -> int:
        value = self.get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"expected an integer, got {type(value).__name__} {value!r}")
        if lo is not None and value < lo:
            raise self.fail(key, f"must be >= {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.fail(key, f"must be <= {hi}, got {value}")
        if choices is not None and value not in choices:
            raise self.fail(key, f"must be one of {sorted(choices)}, got {value}")
        return value

    def boolean(self, key: str) -> bool:
        value = self.get(key)
        if not isinstance(value, bool):
            raise self.fail(key, f"expected true or false, got {type(value).__name__} {value!r}")
        return value

    def choice(self, key: str, choices) -> str:
        value = self.get(key)
        if not isinstance(value, str) or value not in choices:
            raise self.fail(key, f"must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
        return value

    def number_list(self, key: str, *, lo=None, hi=None) -> tuple[float, ...]:
        value = self.get(key)
        if not isinstance(value, list):
            raise self.fail(key, f"expected a list of numbers, got {type(value).__name__}")
        out = []
        for i, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
                raise self.fail(f"{key}[{i}]", f"expected a finite number, got {item!r}")
            if (lo is not None and item < lo) or (hi is not None and item > hi):
                raise self.fail(f"{key}[{i}]", f"must be within [{lo}, {hi}], got {item}")
            out.append(float(item))
        return tuple(out)


def load(path: str | Path = DEFAULT_MODEL) -> Model:
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"{path}: cannot read the model file: {exc.strerror}") from None
    return parse(raw, path)


def parse(raw: bytes, path: Path) -> Model:
    """The model in raw (the bytes of a model file); path names it in errors and in the model."""
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except RecursionError:
        raise ModelError(f"{path}: not valid TOML: arrays or tables nested too deeply") from None
    except ValueError as exc:   # bad UTF-8 or TOML, or an integer of more than 4300 digits
        raise ModelError(f"{path}: not valid TOML: {exc}") from None
    _check_integers(path, data)
    _check_known_keys(path, data)
    r = _Reader(path, data)

    limits = []
    for name in JOINTS:
        lo = r.number(f"joints.{name}.min", lo=-180.0, hi=180.0)
        hi = r.number(f"joints.{name}.max", lo=-180.0, hi=180.0)
        if lo >= hi:
            raise r.fail(f"joints.{name}", f"min ({lo}) must be less than max ({hi})")
        limits.append(JointLimit(lo, hi))

    servo_model = _servo_model(r)
    units_max = r.integer("servo.units_max", lo=1, hi=65535)
    range_deg = r.number("servo.range_deg", lo=1.0, hi=360.0)   # (1e-300 degrees divides by zero)
    _check_servo_resolution(r, servo_model, units_max, range_deg)
    servos = []
    for name in JOINTS:
        servos.append(Servo(
            id=r.integer(f"servo.{name}.id", lo=0, hi=253),
            zero=r.integer(f"servo.{name}.zero", lo=0, hi=units_max),
            direction=r.integer(f"servo.{name}.direction", choices={-1, 1}),
        ))
    if len({s.id for s in servos}) != len(servos):
        raise r.fail("servo", f"servo ids must differ, got {[s.id for s in servos]}")

    sample_rate = r.number("imu.sample_rate", positive=True)
    divider = 1000.0 / sample_rate
    if not 1 <= divider <= 256 or divider != round(divider):   # (a subnormal rate: divider inf)
        raise r.fail("imu.sample_rate", f"must be 1000 Hz / n for n in 1..256 (MPU-6050 SMPLRT_DIV), "
                                        f"got {sample_rate}")
    return_delay = r.integer("servo.return_delay_us", lo=0, hi=508)
    if return_delay % 2:
        raise r.fail("servo.return_delay_us", f"must be even (2 us steps), got {return_delay}")
    park = _three(r, "park.q")
    heartbeat = r.number("link.heartbeat_period", positive=True, hi=HEARTBEAT_SLOWEST_S)
    if heartbeat < 1.0 / sample_rate or heartbeat * 1000.0 != round(heartbeat * 1000.0):
        raise r.fail("link.heartbeat_period", f"must be whole milliseconds, at least one tick "
                                              f"({1000.0 / sample_rate:g} ms), got {heartbeat}")
    filters = []
    for sensor in ("accel", "gyro"):
        cutoff = r.number(f"filters.{sensor}.cutoff", positive=True)
        if cutoff >= sample_rate / 2:
            raise r.fail(f"filters.{sensor}.cutoff",
                         f"must be below the Nyquist frequency {sample_rate / 2} Hz, got {cutoff}")
        filters.append(Filter(cutoff, r.integer(f"filters.{sensor}.order", lo=1, hi=8)))

    model = Model(
        path=path,
        sha256=hashlib.sha256(raw).hexdigest(),
        L1=_link(r, "geometry.L1", zero_allowed=True),
        L2=_link(r, "geometry.L2"),
        L3=_link(r, "geometry.L3"),
        limits=tuple(limits),
        body_z=r.number("collision.body_z", lo=-LENGTH_MAX_MM, hi=LENGTH_MAX_MM),
        leg_angles=r.number_list("collision.leg_angles", lo=-180.0, hi=180.0),
        leg_half_width=r.number("collision.leg_half_width", nonnegative=True, hi=90.0),
        leg_distance=r.number("collision.leg_distance", positive=True, hi=LENGTH_MAX_MM),
        servo_model=servo_model,
        servo_baud=_servo_baud(r, servo_model),
        servo_units_max=units_max,
        servo_range_deg=range_deg,
        servos=tuple(servos),
        servo_return_delay_us=return_delay,
        park_speed_rpm=_speed_rpm(r, "servo.park_speed_rpm", servo_model),
        transit_speed_rpm=_speed_rpm(r, "servo.transit_speed_rpm", servo_model),
        working_speed_rpm=_speed_rpm(r, "servo.working_speed_rpm", servo_model),
        servo_speed_margin=r.number("servo.speed_margin", positive=True, hi=1.0),
        servo_boot_time=r.number("servo.boot_time", nonnegative=True, hi=10.0),
        servo_response_lag=(r.number("servo.response_lag", nonnegative=True, hi=SERVO_LAG_MAX_S)
                            if r.has("servo.response_lag") else SERVO_LAG_ASSUMED_S),
        servo_zero_tolerance_deg=r.number("servo.zero_tolerance_deg", nonnegative=True,
                                          hi=ZERO_TOLERANCE_MAX_DEG),
        servo_bench_torque_limit=r.number("servo.bench_torque_limit", lo=BENCH_TORQUE_MIN, hi=1.0),
        park_deg=park,
        link_silence_timeout=r.number("link.silence_timeout", lo=2 / sample_rate, hi=3600.0),
        heartbeat_period=heartbeat,
        link_frame_gap=r.number("link.frame_gap", positive=True, hi=10.0),
        sample_rate=sample_rate,
        imu_address=r.integer("imu.i2c_address", choices={0x68, 0x69}),
        accel_range_g=r.integer("imu.accel_range_g", choices=set(ACCEL_RANGES_G)),
        gyro_range_dps=r.integer("imu.gyro_range_dps", choices=set(GYRO_RANGES_DPS)),
        dlpf_bandwidth=r.integer("imu.dlpf_bandwidth", choices=set(DLPF_BANDWIDTHS)),
        imu_mounting_rpy_deg=_three(r, "imu.mounting_rpy"),
        imu_calibration=_imu_calibration(r),
        mount_offset=_offset(r, "mount.offset"),
        accel_filter=filters[0],
        gyro_filter=filters[1],
        complementary_gyro_weight=r.number("estimator.complementary_gyro_weight", lo=0.0, hi=1.0),
        estimator=_estimator(r, sample_rate),
        motion=_motion(r),
        masses=_masses(r, _link(r, "geometry.L2"), _link(r, "geometry.L3")),
    )
    _check_servo_travel(r, model)
    _check_poses_within_tolerance(r, model)
    return model


def _check_integers(path: Path, data: dict) -> None:
    """TOML integers are 64-bit; tomllib takes any size, which float() and even str() can
    refuse later. Rejected here, with the key."""
    stack = [("", data)]
    while stack:
        key, node = stack.pop()
        if isinstance(node, dict):
            stack.extend((f"{key}.{k}" if key else k, v) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((f"{key}[{i}]", v) for i, v in enumerate(node))
        elif isinstance(node, int) and not -2**63 <= node < 2**63:
            raise ModelError(f"{path}: {key}: integer outside TOML's 64-bit range "
                             f"({node.bit_length()} bits)")


def _leaf_keys(data: dict) -> list[str]:
    """The dotted keys of every value that is not a table, in the file's order."""
    out, stack = [], [("", data)]
    while stack:
        key, node = stack.pop()
        if isinstance(node, dict):
            stack.extend(reversed([(f"{key}.{k}" if key else k, v) for k, v in node.items()]))
        else:
            out.append(key)
    return out


def _check_known_keys(path: Path, data: dict) -> None:
    """Refuse keys the loader does not read, each with the nearest known key (the first
    UNKNOWN_KEYS_NAMED of them; then how many more)."""
    unknown = [key for key in _leaf_keys(data)
               if key not in KNOWN_KEYS and not any(k.startswith(key + ".") for k in KNOWN_KEYS)]
    # (a table given as a value is not unknown: the typed reader says what it expects)
    if not unknown:
        return
    problems = []
    for key in unknown[:UNKNOWN_KEYS_NAMED]:
        near = difflib.get_close_matches(key, KNOWN_KEYS, n=1)
        problems.append(f"{key}: unknown key" + (f" (did you mean {near[0]}?)" if near else ""))
    more = len(unknown) - UNKNOWN_KEYS_NAMED
    raise ModelError(f"{path}: " + "; ".join(problems) + (f"; and {more} more unknown keys" if more > 0 else ""))


def _link(r: _Reader, key: str, zero_allowed: bool = False) -> float:
    value = r.number(key, nonnegative=zero_allowed, positive=not zero_allowed, hi=LENGTH_MAX_MM)
    if value < LENGTH_MIN_MM and not (zero_allowed and value == 0):
        raise r.fail(key, f"must be {'0 or ' if zero_allowed else ''}at least {LENGTH_MIN_MM} mm, got {value}")
    if value < LINK_PLAUSIBLE_MM and value != 0:
        raise r.fail(key, f"{value} mm is not a link length: lengths are in millimetres "
                          f"({value} m = {value * 1000:g} mm?)")
    return value


def _servo_model(r: _Reader) -> servo_models.ServoModel:
    """servo.model's facts; an AX-12A when the key is absent (model files before the key)."""
    key = "servo.model"
    if not r.has(key):
        return servo_models.MODELS[servo_models.DEFAULT]
    return servo_models.MODELS[r.choice(key, tuple(servo_models.MODELS))]


def _check_servo_resolution(r: _Reader, servo: servo_models.ServoModel, units_max: int, range_deg: float) -> None:
    """servo.units_max and servo.range_deg stay in the file (the servo map is computed from
    them) but must be the chosen servo's travel: positions 0..units_max over range_deg."""
    if units_max != servo.units_max:
        raise r.fail("servo.units_max", f"the {servo.name}'s positions run 0..{servo.units_max} "
                                        f"(servo.model = \"{servo.name}\"), got {units_max}")
    if Fraction(range_deg) != servo.units_max * servo.deg_per_unit:
        raise r.fail("servo.range_deg", f"the {servo.name}'s {servo.units_max} units span {servo.range_deg!r} deg "
                                        f"({float(servo.deg_per_unit):.6g} deg per unit; servo.model = "
                                        f"\"{servo.name}\"), got {range_deg!r}")


def _speed_rpm(r: _Reader, key: str, servo: servo_models.ServoModel) -> float:
    """A goal speed the servo's speed register holds: one unit up to its upper bound."""
    return r.number(key, lo=servo.rpm_per_speed_unit, hi=servo.speed_units_max * servo.rpm_per_speed_unit)


def _servo_baud(r: _Reader, servo: servo_models.ServoModel) -> int:
    """The bus baud: one the servo runs at (its Baud Rate register's rates), within the UART's tolerance."""
    key = "servo.baud"
    rates = servo.bauds
    baud = r.integer(key, lo=round(min(rates.values())), hi=round(max(rates.values())))
    n = servo_models.baud_register(servo, baud)
    if abs(rates[n] / baud - 1) > BAUD_TOLERANCE:
        raise r.fail(key, f"an {servo.name} runs at {servo.baud_rule}; the nearest to {baud}, {rates[n]:.0f} "
                          f"(n = {n}), is {rates[n] / baud - 1:+.1%} off, beyond the UART's "
                          f"{BAUD_TOLERANCE:.0%} tolerance")
    return baud


def _three(r: _Reader, key: str) -> tuple[float, float, float]:
    values = r.number_list(key, lo=-180.0, hi=180.0)
    if len(values) != 3:
        raise r.fail(key, f"expected 3 angles in degrees, got {len(values)}")
    return values


def _imu_calibration(r: _Reader) -> ImuCalibration:
    def vector(key, default, lo, hi, what):
        if not r.has(key):
            return default
        values = r.number_list(key, lo=lo, hi=hi)
        if len(values) != 3:
            raise r.fail(key, f"expected 3 {what} (x, y, z in the IMU's axes), got {len(values)}")
        return values
    def cross_axis():
        key = "imu.gyro_cross_axis"
        if not r.has(key):
            return ((0.0, 0.0, 0.0),) * 3
        rows = r.get(key)
        if not isinstance(rows, list) or len(rows) != 3 or not all(isinstance(row, list) for row in rows):
            raise r.fail(key, "expected 3 rows [x, y, z]: each gyro axis's reading per unit of rate about "
                              "the IMU's x, y and z")
        for i, row in enumerate(rows):
            if len(row) != 3:
                raise r.fail(f"{key}[{i}]", f"expected 3 sensitivities (x, y, z), got {len(row)}")
            for j, c in enumerate(row):
                where = f"{key}[{i}][{j}]"
                if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c):
                    raise r.fail(where, f"expected a finite number, got {c!r}")
                if i == j and c != 0:
                    raise r.fail(where, f"must be 0 (an axis's own sensitivity is imu.gyro_scale), got {c}")
                if abs(c) > GYRO_CROSS_AXIS_MAX:
                    raise r.fail(where, f"must be within [{-GYRO_CROSS_AXIS_MAX}, {GYRO_CROSS_AXIS_MAX}] "
                                        f"(the datasheet's +-2 % twice over), got {c}")
        return tuple(tuple(float(c) for c in row) for row in rows)
    gyro_max = r.number("estimator.gyro_bias_max_dps", nonnegative=True, hi=100.0)
    return ImuCalibration(
        accel_bias=vector("imu.accel_bias", (0.0, 0.0, 0.0), -ACCEL_BIAS_MAX_G, ACCEL_BIAS_MAX_G, "offsets in g"),
        accel_scale=vector("imu.accel_scale", (1.0, 1.0, 1.0), *ACCEL_SCALE_RANGE, "scale factors"),
        gyro_bias_dps=vector("imu.gyro_bias_dps", (0.0, 0.0, 0.0), -gyro_max, gyro_max,
                             "rates in deg/s (within estimator.gyro_bias_max_dps)"),
        gyro_scale=vector("imu.gyro_scale", (1.0, 1.0, 1.0), *GYRO_SCALE_RANGE, "scale factors"),
        gyro_cross_axis=cross_axis(),
    )


def _masses(r: _Reader, L2: float, L3: float) -> Masses:
    def grams(name):
        key = f"masses.{name}"
        value = r.number(key, positive=True, hi=MASS_MAX_G)
        if value < MASS_MIN_G:
            raise r.fail(key, f"{value} g is below {MASS_MIN_G:g} g: masses are in grams (kilograms by mistake?)")
        return value

    def centre(name, length, link, joint):
        key = f"masses.{name}"
        value = r.number(key)
        if not 0.0 <= value <= length:
            raise r.fail(key, f"must lie on the {link}: 0 to {length} mm from the {joint}, got {value}")
        return value
    return Masses(servo=grams("servo"),
                  upper_arm=grams("upper_arm"), upper_arm_com=centre("upper_arm_com", L2, "upper arm (L2)", "shoulder"),
                  forearm=grams("forearm"), forearm_com=centre("forearm_com", L3, "forearm (L3)", "elbow"),
                  end_effector=grams("end_effector"),
                  end_effector_com=centre("end_effector_com", L3, "forearm (L3)", "elbow"))


def _offset(r: _Reader, key: str) -> tuple[float, float, float]:
    values = r.number_list(key, lo=-LENGTH_MAX_MM, hi=LENGTH_MAX_MM)
    if len(values) != 3:
        raise r.fail(key, f"expected 3 lengths in mm (x, y, z), got {len(values)}")
    return values


def _estimator(r: _Reader, sample_rate: float) -> Estimator:
    dt = 1.0 / sample_rate
    k = "estimator."
    # Gains above half the sample rate would overshoot in one step.
    gain = lambda key: r.number(k + key, nonnegative=True, hi=sample_rate / 2)
    bias_gain = lambda key: r.number(k + key, nonnegative=True, hi=(sample_rate / 2) ** 2 / 4)
    est = Estimator(
        kind=r.choice(k + "kind", ESTIMATOR_KINDS),
        accel_gain=gain("accel_gain"),
        bias_gain=bias_gain("bias_gain"),
        align_accel_gain=gain("align_accel_gain"),
        align_bias_gain=bias_gain("align_bias_gain"),
        accel_reject_g=r.number(k + "accel_reject_g", lo=0.001, hi=1.0),
        accel_reject_deg=r.number(k + "accel_reject_deg", lo=0.1, hi=90.0),
        gyro_bias_max_dps=r.number(k + "gyro_bias_max_dps", nonnegative=True, hi=100.0),
        drone_attitude=r.boolean(k + "drone_attitude"),
        link_gain=r.number(k + "link_gain", lo=0.0, hi=1.0),
        link_bias_gain=r.number(k + "link_bias_gain", nonnegative=True, hi=sample_rate / 2),
        link_delay_min=r.number(k + "link_delay_min", nonnegative=True, hi=1.0),
        link_delay_max=r.number(k + "link_delay_max", lo=dt, hi=0.5),
        link_timeout=r.number(k + "link_timeout", lo=2 * dt, hi=10.0),
        lead_time=r.number(k + "lead_time", nonnegative=True, hi=0.2),
        drone_velocity=r.boolean(k + "drone_velocity"),
        # slower than the drone's messages (>= 50 Hz) by far: one message moves little
        velocity_bandwidth=r.number(k + "velocity_bandwidth", lo=0.01, hi=5.0),
        link_gain_with_velocity=r.number(k + "link_gain_with_velocity", lo=0.0, hi=1.0),
        link_bias_gain_with_velocity=r.number(k + "link_bias_gain_with_velocity", nonnegative=True,
                                              hi=sample_rate / 2),
        fc_error_gain=r.number(k + "fc_error_gain", nonnegative=True, hi=10.0),
        fc_error_max_deg=r.number(k + "fc_error_max_deg", nonnegative=True, hi=10.0),
        fc_error_tau=r.number(k + "fc_error_tau", nonnegative=True, hi=3600.0),
        fc_error_deg=r.number(k + "fc_error_deg", positive=True, hi=10.0),
        drone_attitude_white_deg=r.number(k + "drone_attitude_white_deg", positive=True, hi=10.0),
        accel_bias_prior_g=r.number(k + "accel_bias_prior_g", nonnegative=True, hi=0.5),
        accel_bias_walk_g=r.number(k + "accel_bias_walk_g", nonnegative=True, hi=0.5),
        accel_bias_attitude_gain=r.number(k + "accel_bias_attitude_gain", nonnegative=True, hi=10.0),
        accel_bias_bandwidth=r.number(k + "accel_bias_bandwidth", nonnegative=True, hi=5.0),
        accel_bias_max_g=r.number(k + "accel_bias_max_g", positive=True, hi=0.5),
        # the gate: under 1 sigma refuses honest data, over 20 takes 20 deg lies
        gate_sigmas=r.number(k + "gate_sigmas", lo=1.0, hi=20.0),
        drone_attitude_noise_deg=r.number(k + "drone_attitude_noise_deg", positive=True, hi=10.0),
        drone_velocity_noise=r.number(k + "drone_velocity_noise", positive=True, hi=5.0),
        drift_dps=r.number(k + "drift_dps", nonnegative=True, hi=90.0),
        drift_max_deg=r.number(k + "drift_max_deg", nonnegative=True, hi=45.0),
        reject_after=r.number(k + "reject_after", lo=dt, hi=60.0),
        retake_after=r.number(k + "retake_after", nonnegative=True, hi=60.0),
        correction_max_deg=r.number(k + "correction_max_deg", lo=0.01, hi=45.0),
    )
    if est.accel_bias_prior_g > 0 and est.fc_error_tau == 0:
        raise r.fail(k + "fc_error_tau", "the split's Kalman filter (accel_bias_prior_g > 0) needs the flight "
                                         "controller's error to come and go: set its correlation time (s)")
    if 0.0 < est.fc_error_tau < 10 * est.link_timeout:
        # one message fades fc_error by h / tau, h up to the link's timeout: at most a tenth
        raise r.fail(k + "fc_error_tau", f"must be 0 (never fades) or at least 10 x link_timeout "
                                         f"({10 * est.link_timeout:g} s), got {est.fc_error_tau}")
    if est.link_delay_min >= est.link_delay_max:
        raise r.fail(k + "link_delay_min", f"must be less than link_delay_max ({est.link_delay_max}), "
                                           f"got {est.link_delay_min}")
    if math.ceil(est.link_delay_max * sample_rate) + 2 > HISTORY_MAX:
        raise r.fail(k + "link_delay_max", f"the attitude history holds {HISTORY_MAX - 2} samples: at most "
                                           f"{(HISTORY_MAX - 2) / sample_rate} s at {sample_rate} Hz, got {est.link_delay_max}")
    widest = est.gate_sigmas * math.hypot(est.drone_attitude_noise_deg, est.drift_max_deg)
    if widest > GATE_WIDEST_DEG:
        raise r.fail(k + "gate_sigmas", f"the attitude gate opens to gate_sigmas x hypot(drone_attitude_noise_deg, "
                                        f"drift_max_deg) = {widest:.1f} deg: at most {GATE_WIDEST_DEG} (wider lets a "
                                        f"flight controller's lie of that size in)")
    if est.drone_attitude and est.kind != "quaternion":
        raise r.fail(k + "drone_attitude", "the drone's attitude is fused by the quaternion estimator only: "
                                           "set kind = \"quaternion\" or drone_attitude = false")
    if est.drone_velocity and est.kind != "quaternion":
        raise r.fail(k + "drone_velocity", "the drone's velocity is fused by the quaternion estimator only: "
                                           "set kind = \"quaternion\" or drone_velocity = false")
    return est


def _motion(r: _Reader) -> Motion:
    k = "motion."
    reach = r.number("geometry.L2") + r.number("geometry.L3")
    hold = r.number(k + "axis_hold_radius", nonnegative=True, hi=LENGTH_MAX_MM)
    release = r.number(k + "axis_release_radius", nonnegative=True, hi=LENGTH_MAX_MM)
    if release < hold:
        raise r.fail(k + "axis_release_radius", f"must be at least axis_hold_radius ({hold}), got {release}")
    if release >= reach:
        raise r.fail(k + "axis_release_radius", f"must be less than the arm's reach L2 + L3 ({reach} mm), "
                                                f"got {release}")
    margin = r.number(k + "stretch_margin", nonnegative=True, hi=0.1 * reach)
    window = r.number(k + "follow_window_deg", nonnegative=True, hi=180.0)
    return Motion(axis_hold_radius=hold, axis_release_radius=release, follow_window_deg=window,
                  stretch_margin=margin)


def _check_servo_travel(r: _Reader, model: Model) -> None:
    """Every joint limit must map inside the servo's 0..units_max range (exact rationals: a
    limit that maps exactly onto 0 or units_max is accepted; servo.joint_to_units is the same
    map in SymPy, which costs milliseconds per call)."""
    units_per_deg = Fraction(model.servo_units_max) / Fraction(model.servo_range_deg)
    for s, name, limit in zip(model.servos, JOINTS, model.limits):
        for deg in (limit.min_deg, limit.max_deg):
            units = s.zero + s.direction * Fraction(deg) * units_per_deg
            if not 0 <= units <= model.servo_units_max:
                raise r.fail(f"joints.{name}",
                             f"limit {deg} deg maps to servo position {float(units):.1f}, outside "
                             f"0..{model.servo_units_max}, the {model.servo_model.name}'s travel "
                             f"(check servo.{name}.zero)")


def _off_by(offsets_deg) -> str:
    """'joint 2 +3.0 deg and joint 3 -3.0 deg' (the joints that are off)."""
    off = [f"joint {j} {d:+.1f} deg" for j, d in enumerate(offsets_deg, 1) if round(d, 1) != 0]
    return " and ".join(off) if off else "no joint"


def _how_close(c: pose_tolerance.Clearance) -> str:
    if c.mm > 0:
        return f"{c.part} comes within {c.mm:.1f} mm of the {c.boundary}"
    return f"{c.part} is {-c.mm:.1f} mm past the {c.boundary}"


def _check_poses_within_tolerance(r: _Reader, model: Model) -> None:
    """The park pose, and the pose joint 1 turns past a leg in (the tuck), must stay clear of
    the body and the legs with every joint off by up to servo.zero_tolerance_deg: a
    calibration that careful is what the arm is flown with."""
    tol = model.servo_zero_tolerance_deg
    shown = "[" + ", ".join(f"{d:g}" for d in model.park_deg) + "]"
    c = pose_tolerance.least(model, model.park_deg, tol)
    if not c.clear:
        exact = pose_tolerance.least(model, model.park_deg, 0.0)
        if not exact.clear:
            what = "not below the body" if exact.boundary == "body plane" else "in a landing leg"
            raise r.fail("park.q", f"the park pose q={shown} deg is {what}: {_how_close(exact)}")
        raise r.fail("park.q", f"the park pose q={shown} deg is only safe with a perfect calibration: with "
                               f"{_off_by(c.offsets_deg)} off (servo.zero_tolerance_deg = {tol:g}) "
                               f"{_how_close(c)}")
    if pose_tolerance.tuck_deg(model, tol) is None:
        raise r.fail("park.q", "neither the park pose's joints 2-3 nor hanging straight down keep joint 3 and "
                               "the end effector inside collision.leg_distance and below the body with every "
                               f"joint within servo.zero_tolerance_deg ({tol:g} deg): the arm could not turn "
                               "joint 1 past a leg")
