"""The generated attitude estimator (estimator.c) against independent oracles.

Oracles: scipy's rotations for the frames (R_WB = Ry(pitch) Rx(roll), IMU mounting
R_mount = Rz(yaw) Ry(pitch) Rx(roll), v_base = R_mount v_imu; model/attitude.py),
body rates taken from scipy by differencing rotations (not from the Euler kinematics under
test), a float64 complementary filter written from the corrected formula (erratum 1)
(angle_k = w (angle_{k-1} + rate dt) + (1 - w) angle_acc), the filter's closed-form behaviour,
and the SymPy model evaluated at 30 digits.

Besides the committed build, two models with the IMU rotated on the board are generated into
a temporary folder: a seeded random mounting (with 200 Hz and gyro weight 0.9, so dt and w
are seen to follow the model file) and a quarter-turn one (the IMU upside down, turned 90 deg).
"""
import math
import re

import mpmath as mp
import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, example, given, settings, strategies as st
from scipy.spatial.transform import Rotation

from conftest import ROOT
from uavarm.build import generated, variants
from uavarm.model import attitude

EPS32 = float(np.finfo(np.float32).eps)   # 1.19e-7: one float32 step at 1.0
TILT_TOL_URAD = 1.0       # ~8 float32 steps at 1 rad: atan2 (~1-2 ulp), input rounding, mounting sums
TO_BASE_TOL_UM = 0.1      # points up to 200 mm: 200 mm * a few float32 eps = ~0.05 um
STEP_TOL_EPS = 8          # one filter step: 8 eps times the sum of the magnitudes of its terms
COS_PITCH_MIN = 0.01      # model/attitude.py: the Euler kinematics divide by max(cos pitch, 0.01)

_RANDOM_RPY = np.random.default_rng(2024).uniform(-180, 180, 3).round(1)
VARIANTS = {
    "committed": {},
    "random_mount": {"imu.mounting_rpy": [float(a) for a in _RANDOM_RPY], "imu.sample_rate": 200.0,
                     "estimator.complementary_gyro_weight": 0.9},
    "upside_down": {"imu.mounting_rpy": [180.0, 0.0, 90.0]},
}


class Build:
    """A generated estimator with the model it came from and its parameters as scipy sees them."""

    def __init__(self, model, ffi, lib):
        self.m, self.ffi, self.lib = model, ffi, lib
        self.w = model.complementary_gyro_weight
        self.dt = 1.0 / model.sample_rate
        r, p, y = np.radians(model.imu_mounting_rpy_deg)
        self.mount = rot_z(y) * rot_y(p) * rot_x(r)           # v_base = R_mount v_imu
        self.R = self.mount.as_matrix()
        self.e = ffi.new("est_attitude_t *")
        self.acc, self.gyro = ffi.new("float[3]"), ffi.new("float[3]")
        self.out = [ffi.new("float *"), ffi.new("float *")]

    def imu(self, v_base):
        """A base-frame vector in the IMU's axes (v_imu = R_mount^T v_base)."""
        return self.mount.inv().apply(v_base)

    def tilt(self, acc):
        self.acc[0:3] = [float(v) for v in acc]
        self.lib.est_tilt_from_accel(self.acc, *self.out)
        return self.out[0][0], self.out[1][0]

    def step(self, state, acc, gyro):
        """One C step from `state` (roll, pitch); returns the new (roll, pitch)."""
        self.lib.est_set(self.e, *state)
        self.acc[0:3] = [float(v) for v in acc]
        self.gyro[0:3] = [float(v) for v in gyro]
        self.lib.est_complementary_step(self.e, self.acc, self.gyro, self.dt)
        return self.e.roll, self.e.pitch


def rot_x(a):
    return Rotation.from_rotvec([a, 0.0, 0.0])


def rot_y(a):
    return Rotation.from_rotvec([0.0, a, 0.0])


def rot_z(a):
    return Rotation.from_rotvec([0.0, 0.0, a])


def r_wb(roll, pitch):
    """Level frame -> base frame of the drone tilted by (roll, pitch): Ry(pitch) Rx(roll)."""
    return rot_y(pitch) * rot_x(roll)


def specific_force_base(roll, pitch):
    """What an accelerometer at rest reads, in the base frame: "up" (0, 0, 1) seen from B."""
    return r_wb(roll, pitch).inv().apply([0.0, 0.0, 1.0])


def f32(v):
    return np.asarray(v, dtype=np.float32).astype(np.float64)


@pytest.fixture(scope="module", params=list(VARIANTS))
def build(request):
    """The generated code of the model with the variant's keys edited (generated once per test
    run for all workers: uavarm.build.variants)."""
    model, gen_dir = variants.generate(VARIANTS[request.param])
    ffi, lib = generated.default() if gen_dir == generated.GENERATED else generated.load(gen_dir)
    return Build(model, ffi, lib)


def test_scipy_conventions_are_the_textbook_ones():
    """The oracle's own building blocks: active rotations, p * q applies q first."""
    a = 0.3
    c, s = math.cos(a), math.sin(a)
    assert np.allclose(rot_x(a).as_matrix(), [[1, 0, 0], [0, c, -s], [0, s, c]])
    assert np.allclose(rot_y(a).as_matrix(), [[c, 0, s], [0, 1, 0], [-s, 0, c]])
    assert np.allclose(rot_z(a).as_matrix(), [[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert np.allclose(r_wb(0.2, 0.5).as_matrix(), rot_y(0.5).as_matrix() @ rot_x(0.2).as_matrix())


def test_mounting_is_the_model_files(build):
    """The generated code's R_mount (printed in estimator.c's header) is scipy's Rz Ry Rx."""
    assert np.allclose(np.array(attitude.mounting(build.m).tolist(), dtype=float), build.R, atol=1e-15)


# --- tilt from the accelerometer ----------------------------------------------------------

def test_tilt_from_accel_matches_scipy(build):
    rng = np.random.default_rng(21)
    n = 3000
    rp = rng.uniform(-math.radians(60), math.radians(60), size=(n, 2))
    scale = 10 ** rng.uniform(-3, 4.5, size=n)            # any positive unit: g, m/s^2, LSB
    worst = 0.0
    for (roll, pitch), k in zip(rp, scale):
        acc = f32(build.imu(specific_force_base(roll, pitch)) * k)
        got = build.tilt(acc)
        worst = max(worst, abs(got[0] - roll), abs(got[1] - pitch))
        build.lib.est_reset(build.e, build.acc)
        assert (build.e.roll, build.e.pitch) == got
    print(f"tilt from accel ({build.m.imu_mounting_rpy_deg}): max error {worst * 1e6:.3f} urad")
    assert worst <= TILT_TOL_URAD * 1e-6


def test_tilt_sign_conventions(build):
    """Nose down (positive pitch about y) puts "up" toward base -x; right side down
    (positive roll about x) puts it toward +y."""
    roll, pitch = build.tilt(build.imu([-math.sin(0.3), 0.0, math.cos(0.3)]))
    assert abs(pitch - 0.3) < 1e-6 and abs(roll) < 1e-6
    roll, pitch = build.tilt(build.imu([0.0, math.sin(0.3), math.cos(0.3)]))
    assert abs(roll - 0.3) < 1e-6 and abs(pitch) < 1e-6


# --- level frame -> base frame -----------------------------------------------------------

def test_level_to_base_matches_scipy(gen):
    ffi, lib = gen
    rng = np.random.default_rng(22)
    n = 5000
    rp = f32(rng.uniform(-math.pi, math.pi, size=(n, 2)))
    pts = rng.normal(size=(n, 3))
    pts = f32(pts / np.linalg.norm(pts, axis=1)[:, None] * 200.0 * rng.uniform(0, 1, size=(n, 1)) ** (1 / 3))
    e, p_in, p_out = ffi.new("est_attitude_t *"), ffi.new("float[3]"), ffi.new("float[3]")
    worst = 0.0
    for (roll, pitch), p in zip(rp, pts):
        lib.est_set(e, roll, pitch)
        p_in[0:3] = p.tolist()
        lib.est_level_to_base(e, p_in, p_out)
        want = r_wb(roll, pitch).inv().apply(p)
        worst = max(worst, float(np.max(np.abs(np.array(list(p_out)) - want))))
    print(f"level to base, points within 200 mm: max error {worst * 1e3:.4f} um")
    assert worst <= TO_BASE_TOL_UM * 1e-3


# --- complementary filter ------------------------------------------------------------------

def reference_step(b, state, acc, gyro):
    """The corrected complementary filter (erratum 1) in float64: angle_k = w (angle + rate dt) + (1 - w) angle_acc, with
    roll/pitch of the measured "up" and the Z-Y-X Euler rates of the body rates; also returns
    the tolerance of one float32 step (STEP_TOL_EPS times the magnitudes of the terms)."""
    roll, pitch = state
    u = b.R @ np.asarray(acc, dtype=float)
    p, q, r = b.R @ np.asarray(gyro, dtype=float)
    acc_roll = math.atan2(u[1], u[2])
    acc_pitch = math.atan2(-u[0], math.hypot(u[1], u[2]))
    tan_pitch = math.sin(pitch) / max(math.cos(pitch), COS_PITCH_MIN)
    rate_roll = p + (q * math.sin(roll) + r * math.cos(roll)) * tan_pitch
    rate_pitch = q * math.cos(roll) - r * math.sin(roll)
    w, dt = b.w, b.dt
    nxt = (w * (roll + rate_roll * dt) + (1 - w) * acc_roll,
           w * (pitch + rate_pitch * dt) + (1 - w) * acc_pitch)
    nxt = tuple(math.remainder(a, 2 * math.pi) for a in nxt)    # angles live in [-pi, pi]
    ga = np.abs(b.R) @ np.abs(np.asarray(gyro, dtype=float))
    scale = (w * abs(roll) + w * dt * (ga[0] + (ga[1] + ga[2]) * abs(tan_pitch)) + (1 - w) * math.pi,
             w * abs(pitch) + w * dt * (ga[1] + ga[2]) + (1 - w) * math.pi / 2)
    return nxt, tuple(STEP_TOL_EPS * EPS32 * s for s in scale)


def test_at_rest_converges_geometrically(build):
    """Static gravity, zero gyro, wrong start: the error shrinks by exactly w per step."""
    rng = np.random.default_rng(23)
    n = 60
    for true in [(0.0, 0.0)] + [tuple(rng.uniform(-1.0, 1.0, 2)) for _ in range(5)]:
        acc = f32(build.imu(specific_force_base(*true)))
        want = build.tilt(acc)                          # the accelerometer's angle, float32
        assert max(abs(want[0] - true[0]), abs(want[1] - true[1])) <= TILT_TOL_URAD * 1e-6
        err0 = rng.uniform(-0.5, 0.5, 2)
        state = (float(np.float32(want[0] + err0[0])), float(np.float32(want[1] + err0[1])))
        err0 = np.array(state) - want
        _, tol = reference_step(build, want, acc, (0, 0, 0))
        for k in range(1, n + 1):
            state = build.step(state, acc, (0.0, 0.0, 0.0))
            predicted = build.w ** k * err0
            # rounding per step, accumulated through the contraction w: <= tol / (1 - w)
            assert np.all(np.abs(np.array(state) - want - predicted) <= np.array(tol) / (1 - build.w)), k
        assert np.all(np.abs(np.array(state) - true) <= build.w ** n * np.abs(err0) + 1e-5)


def random_imu_sequence(b, rng, n):
    """A wandering attitude (|pitch| <= 75 deg) with accelerometer noise and gyro rates up to a
    few rad/s, in the IMU's axes."""
    rp = np.cumsum(rng.normal(0, 0.05, size=(n, 2)), axis=0)
    rp[:, 0] = np.clip(rp[:, 0], -1.2, 1.2)
    rp[:, 1] = np.clip(rp[:, 1], -1.3, 1.3)
    acc = [f32(b.imu(specific_force_base(*a)) * 9.81 + rng.normal(0, 0.5, 3)) for a in rp]
    gyro = f32(rng.normal(0, 1.5, size=(n, 3)) * rng.choice([0.1, 1.0, 5.0], size=(n, 1)))
    return acc, gyro


def test_step_matches_float64_formula(build):
    rng = np.random.default_rng(24)
    worst_rel = worst_abs = 0.0
    for _ in range(6):
        acc, gyro = random_imu_sequence(build, rng, 300)
        state = build.tilt(acc[0])
        for a, g in zip(acc, gyro):
            want, tol = reference_step(build, state, a, g)
            state = build.step(state, a, g)
            for i in range(2):
                err = abs(math.remainder(state[i] - want[i], 2 * math.pi))
                worst_abs = max(worst_abs, err)
                worst_rel = max(worst_rel, err / tol[i] * STEP_TOL_EPS)
                assert err <= tol[i], (i, state, want)
            assert abs(state[1]) < 1.45            # the clamp on cos(pitch) is not involved
    print(f"complementary step vs float64 formula: max error {worst_abs * 1e6:.3f} urad, "
          f"{worst_rel:.2f} eps of the terms' magnitude")


def trajectory_gyro_acc(b, roll_fn, pitch_fn, t):
    """Accelerometer (at rest: "up") and gyro (body rates from scipy: the rotation from
    t - h to t + h as a rotation vector over 2h) in IMU axes, float32."""
    h = 1e-5
    R0 = r_wb(roll_fn(t - h), pitch_fn(t - h))
    R1 = r_wb(roll_fn(t + h), pitch_fn(t + h))
    body_rate = (R0.inv() * R1).as_rotvec() / (2 * h)
    return f32(b.imu(specific_force_base(roll_fn(t), pitch_fn(t)))), f32(b.imu(body_rate))


@pytest.mark.parametrize("motion", ["constant_roll_rate", "roll_swing", "pitch_swing"])
def test_tracks_motion_with_the_predicted_lag(build, motion):
    """Accelerometer and gyro agree with a true motion. The formula's error obeys
    e_k = w e_{k-1} + w tau_k, tau_k = angle'(t_k) dt - (angle(t_k) - angle(t_{k-1})):
    zero for a constant rate (the gyro step is then exact), a lag of about w/(1 - w) times
    angle'' dt^2 / 2 for a swing. In these motions only one Euler angle moves, so the
    estimated attitude feeding the kinematics changes the rates by O(eps) only; the C must
    follow the predicted error within the rounding bound."""
    dt, w = build.dt, build.w
    fns = {
        "constant_roll_rate": (lambda t: -0.9 + 1.0 * t, lambda t: 0.35 + 0 * t,
                               lambda t: 1.0 + 0 * t, lambda t: 0 * t),
        "roll_swing": (lambda t: 0.6 * np.sin(np.pi * t), lambda t: -0.3 + 0 * t,
                       lambda t: 0.6 * np.pi * np.cos(np.pi * t), lambda t: 0 * t),
        "pitch_swing": (lambda t: 0.4 + 0 * t, lambda t: 0.7 * np.sin(1.5 * np.pi * t),
                        lambda t: 0 * t, lambda t: 0.7 * 1.5 * np.pi * np.cos(1.5 * np.pi * t)),
    }
    roll_fn, pitch_fn, droll, dpitch = fns[motion]
    n = round(1.8 / dt)
    acc0, _ = trajectory_gyro_acc(build, roll_fn, pitch_fn, 0.0)
    state = build.tilt(acc0)
    e_pred = np.array(state) - [roll_fn(0.0), pitch_fn(0.0)]
    worst_dev = worst_err = 0.0
    bound = 0.0
    for k in range(1, n + 1):
        t, t0 = k * dt, (k - 1) * dt
        acc, gyro = trajectory_gyro_acc(build, roll_fn, pitch_fn, t)
        _, tol = reference_step(build, state, acc, gyro)
        bound = max(bound, max(tol) / (1 - w) + 2 * TILT_TOL_URAD * 1e-6)
        state = build.step(state, acc, gyro)
        tau = np.array([droll(t) * dt - (roll_fn(t) - roll_fn(t0)),
                        dpitch(t) * dt - (pitch_fn(t) - pitch_fn(t0))])
        e_pred = w * e_pred + w * tau
        err = np.array(state) - [roll_fn(t), pitch_fn(t)]
        worst_err = max(worst_err, float(np.max(np.abs(err))))
        worst_dev = max(worst_dev, float(np.max(np.abs(err - e_pred))))
    print(f"{motion} at {1 / dt:g} Hz, w {w}: max tracking error {worst_err * 1e3:.4f} mrad, "
          f"deviation from the predicted lag {worst_dev * 1e6:.3f} urad (bound {bound * 1e6:.2f})")
    assert worst_dev <= bound
    if motion != "constant_roll_rate":
        assert worst_err > 10 * bound          # the lag is real and of the predicted size


def test_one_gyro_step_integrates_rate_times_dt(build):
    """The rate is integrated over the sample period: level and at rest with a gyro rate, one step moves the angle by
    w * rate * dt with dt = 1 / sample_rate of the model file (not w * rate)."""
    w, dt = build.m.complementary_gyro_weight, 1.0 / build.m.sample_rate
    up = f32(build.imu([0.0, 0.0, 1.0]))
    for rate in (0.5, -2.0, 7.0):
        roll, pitch = build.step((0.0, 0.0), up, f32(build.imu([rate, 0.0, 0.0])))
        assert roll == pytest.approx(w * rate * dt, rel=1e-6, abs=1e-9) and abs(pitch) < 1e-9
        roll, pitch = build.step((0.0, 0.0), up, f32(build.imu([0.0, rate, 0.0])))
        assert pitch == pytest.approx(w * rate * dt, rel=1e-6, abs=1e-9) and abs(roll) < 1e-9


def test_step_matches_sympy_at_30_digits(build):
    syms = (attitude.roll, attitude.pitch) + attitude.ACC + attitude.GYRO + (attitude.DT,)
    f = sp.lambdify(syms, list(attitude.complementary_step(build.m)), modules="mpmath")
    rng = np.random.default_rng(25)
    worst = worst_rel = 0.0
    with mp.workdps(30):
        for _ in range(400):
            state = (float(f32(rng.uniform(-math.pi, math.pi))), float(f32(rng.uniform(-1.5, 1.5))))
            acc = f32(rng.normal(size=3) * 10 ** rng.uniform(-2, 4))
            gyro = f32(rng.normal(size=3) * rng.choice([0.1, 1.0, 10.0]))
            got = build.step(state, acc, gyro)
            exact = f(*(mp.mpf(float(v)) for v in (*state, *acc, *gyro, f32(build.dt))))
            _, tol = reference_step(build, state, acc, gyro)
            for i in range(2):
                err = abs(math.remainder(float(exact[i] - mp.mpf(got[i])), 2 * math.pi))   # C wraps
                worst = max(worst, err)
                worst_rel = max(worst_rel, err / tol[i] * STEP_TOL_EPS)
                assert err <= tol[i]
    print(f"complementary step vs SymPy at 30 digits: max error {worst * 1e6:.3f} urad, "
          f"{worst_rel:.2f} eps of the terms' magnitude")


# --- never a non-finite attitude -----------------------------------------------------------

def _define(name):
    text = (ROOT / "generated" / "model_params.h").read_text()
    return re.search(rf"^#define {name}\s+(\S+)", text, re.M).group(1)


ACCEL_LSB = float(_define("MODEL_ACCEL_G_PER_LSB").rstrip("f"))
GYRO_LSB_2000 = math.radians(2000.0) / 32768        # the MPU's largest range: the worst rates
int16 = st.integers(-32768, 32767)
vec16 = st.tuples(int16, int16, int16)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(roll=st.floats(-math.pi, math.pi), pitch=st.floats(-math.pi, math.pi),
       samples=st.lists(st.tuples(vec16, vec16), min_size=1, max_size=20))
@example(roll=0.0, pitch=0.0, samples=[((0, 0, 0), (0, 0, 0))])
@example(roll=math.pi, pitch=-math.pi, samples=[((0, 0, 0), (32767, 32767, 32767))])
@example(roll=-math.pi, pitch=math.pi / 2, samples=[((-32768, -32768, -32768), (-32768, -32768, -32768))] * 5)
@example(roll=0.0, pitch=math.pi / 2, samples=[((0, 0, -32768), (0, 32767, 32767))] * 20)
def test_attitude_always_finite(gen, roll, pitch, samples):
    ffi, lib = gen
    e, acc, gyro = ffi.new("est_attitude_t *"), ffi.new("float[3]"), ffi.new("float[3]")
    out = [ffi.new("float *"), ffi.new("float *")]
    p, q = ffi.new("float[3]", [120.0, -80.0, -150.0]), ffi.new("float[3]")
    lib.est_set(e, roll, pitch)
    for a, g in samples:
        acc[0:3] = [v * ACCEL_LSB for v in a]
        gyro[0:3] = [v * GYRO_LSB_2000 for v in g]
        lib.est_tilt_from_accel(acc, *out)
        assert all(math.isfinite(o[0]) and abs(o[0]) <= math.pi + 1e-6 for o in out)
        lib.est_complementary_step(e, acc, gyro, 0.01)   # (a 100 Hz period: finiteness is the point)
        assert math.isfinite(e.roll) and math.isfinite(e.pitch)
        lib.est_level_to_base(e, p, q)
        assert all(math.isfinite(v) for v in q)


def test_sustained_full_scale_gyro_stays_finite(gen):
    """Full-scale rates held for 20 s (a tumbling drone): the angles stay wrapped into
    [-pi, pi], well inside fm_sincosf's domain (it returns NaN beyond |x| = 2048)."""
    ffi, lib = gen
    e, acc, gyro = ffi.new("est_attitude_t *"), ffi.new("float[3]"), ffi.new("float[3]")
    g = 32767 * GYRO_LSB_2000
    worst = 0.0
    for signs in [(1, 1, 1), (1, -1, 1), (0, 1, 1), (1, 0, -1), (-1, 1, 0), (0, 0, 1)]:
        for a in ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]):
            lib.est_set(e, 0.0, 1.5)
            acc[0:3] = a
            gyro[0:3] = [s * g for s in signs]
            for _ in range(2000):
                lib.est_complementary_step(e, acc, gyro, 0.01)   # (a 100 Hz period: finiteness is the point)
                worst = max(worst, abs(e.roll), abs(e.pitch))
            assert math.isfinite(e.roll) and math.isfinite(e.pitch)
    print(f"full-scale gyro for 20 s: largest |angle| {worst:.6f} rad")
    assert worst <= math.pi * (1 + 1e-6)


def test_the_firmwares_complementary_estimate_holds_a_tilt_while_yawing():
    """The complementary configuration's stab_sample on a board held at 20 deg of roll that
    turns about the vertical at 90 deg/s (the body rates from scipy by differencing; most of
    the turn is on the gyro's z axis): the Euler kinematics need all three axes, and over 3 s
    roll and pitch stay within 0.3 deg of the truth."""
    from uavarm.build import variants
    v = variants.build({"estimator.kind": "complementary", "estimator.drone_attitude": False,
                        "estimator.drone_velocity": False})
    ffi, lib, dt = v.ffi, v.lib, 1.0 / v.model.sample_rate
    roll0, yaw_rate = math.radians(20.0), math.radians(90.0)
    truth = lambda t: rot_z(yaw_rate * t) * rot_x(roll0)
    s = ffi.new("stab_t *")
    lib.stab_reset(s)
    acc, gyro = ffi.new("float[3]"), ffi.new("float[3]")
    roll, pitch = ffi.new("float *"), ffi.new("float *")
    worst = 0.0
    for k in range(round(3.0 / dt)):
        t = k * dt
        acc[0:3] = [float(x) for x in truth(t).inv().apply([0.0, 0.0, 1.0])]
        gyro[0:3] = [float(x) for x in (truth(t - dt / 2).inv() * truth(t + dt / 2)).as_rotvec() / dt]
        lib.stab_sample(s, acc, gyro, 1_000_000 + round(t * 1e6), True)
        lib.stab_attitude(s, roll, pitch)
        worst = max(worst, abs(roll[0] - roll0), abs(pitch[0]))
    assert math.degrees(worst) < 0.3, math.degrees(worst)
