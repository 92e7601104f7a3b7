"""Exhaustive safety over pairs of poses: from start poses on a grid, to targets on a grid,
at drone tilts up to +-30 deg, every goal the firmware's command path sends (engage, follow,
disengage: app.c's own command_servos, tests/csrc/safety_grid.c) is a safe pose, the path the
servos take to it from the previous goal is safe and, with the goals sent through the servo
driver to servos that lag 0-45 ms and slow with a 9.0-12.6 V supply, the shafts themselves
stand in safe poses, by plain geometry; and the SymPy model's own IK selection never picks
an unsafe pose."""
import hashlib
import math

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

import arm_spec
import oracles
from conftest import ROOT
from oracles import check_pose, servo_path
from uavarm.build import cbuild, firmware, generated, variants
from uavarm.model import collision, config, kinematics

HARNESS = ROOT / "tests" / "csrc"
TILTS_DEG = np.arange(-30.0, 30.1, 10.0)
MARGIN = 1e-4            # mm / rad: closer to a boundary, float32 may decide either way


def grid(m):
    reach = m.L2 + m.L3 + m.L1
    xs = np.arange(-reach - 20.0, reach + 20.1, 8.0)
    zs = np.arange(-reach - 60.0, m.body_z + 40.1, 8.0)
    x, y, z = np.meshgrid(xs, xs, zs, indexing="ij")
    targets = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    r, p = np.meshgrid(np.radians(TILTS_DEG), np.radians(TILTS_DEG), indexing="ij")
    tilts = np.stack([r.ravel(), p.ravel()], axis=1)
    return targets, tilts


def harness_lib(gen_dir=generated.GENERATED):
    """safety_grid.c includes app.c (its static command path): app.c's hash joins the flags,
    so an edited app.c rebuilds. gen_dir: the generated code of the model file to build for."""
    app_c = firmware.APP / "Src" / "app.c"
    sources = [s for s in firmware.app_sources(gen_dir) if s != app_c] + [HARNESS / "safety_grid.c"]
    tag = hashlib.sha256(app_c.read_bytes()).hexdigest()[:16]
    return cbuild.load("safety_grid", sources, [HARNESS / "safety_grid.h"],
                       include_dirs=[gen_dir, firmware.APP / "Inc", HARNESS, firmware.APP / "Src"],
                       extra_flags=[f"-DAPP_C_SHA=0x{tag}"])


@pytest.fixture(scope="module")
def harness():
    return harness_lib()


@pytest.fixture(scope="module")
def xm430_harness():
    """(the oracle's numbers of the model file made an XM430-W350 arm, the harness built from it)."""
    _, gen_dir = variants.generate(variants.XM430_EDITS)
    return arm_spec.spec(gen_dir.parent / "manipulator.toml"), harness_lib(gen_dir)


def assert_safe(m, q, what):
    status, clear = check_pose(m, q, margin=MARGIN)
    bad = (status != 0) & clear
    assert not bad.any(), f"{what}: {bad.sum()} unsafe, e.g. {np.degrees(q[bad][:3])} deg"
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    assert np.all((q >= lo - 1e-6) & (q <= hi + 1e-6)), f"{what}: a joint past its limit"
    return int((~clear).sum())


def start_poses(m):
    """The park pose and safe poses spread over the joint space (a 4 x 3 x 3 grid, offset
    from every boundary), each as the arm may stand when engaged."""
    q1 = np.radians([-120.0, -60.0, 15.0, 100.0])
    q2 = np.radians([-70.0, 10.0, 80.0])
    q3 = np.radians([-90.0, -20.0, 60.0])
    poses = np.stack(np.meshgrid(q1, q2, q3, indexing="ij"), axis=-1).reshape(-1, 3)
    status, clear = check_pose(m, poses, margin=0.05)
    return np.vstack([np.radians(m.park_deg), poses[(status == 0) & clear]])


# The servos' physics the grid runs on: no lag at a full battery, the model file's lag at a
# nominal one, 45 ms at a flat one (each servo reports the supply, sag included), each on a
# 48 mm grid of targets. `make test` runs the two ends, the slowest servos and the quickest
# (whose shafts come nearest the body and the legs); `make test-long` the model file's lag
# between them, and the slowest on the full 24 mm grid, eight times the runs
PHYSICS = [(0.0, 12.6), (config.load().servo_response_lag, 11.1), (0.045, 9.0)]
GRIDS = [(PHYSICS[0], 48.0), pytest.param((PHYSICS[1], 48.0), marks=pytest.mark.long), (PHYSICS[2], 48.0),
         pytest.param((PHYSICS[2], 24.0), marks=pytest.mark.long)]


class Out:
    """A grid_out_t with its arrays (numpy, so Python reads them without copying)."""

    def __init__(self, ffi, goals: int, shafts: int):
        self.goals, self.goal_run = np.empty((goals, 3), np.float32), np.empty(goals, np.uint32)
        self.shafts, self.shaft_run = np.empty((shafts, 3), np.float32), np.empty(shafts, np.uint32)
        self.c = ffi.new("grid_out_t *")
        self.c.goals, self.c.goal_run = ffi.from_buffer("float[]", self.goals), ffi.from_buffer("uint32_t[]", self.goal_run)
        self.c.shafts = ffi.from_buffer("float[]", self.shafts)
        self.c.shaft_run = ffi.from_buffer("uint32_t[]", self.shaft_run)
        self.c.cap_goals, self.c.cap_shafts = goals, shafts


def run_grid(harness, start, targets, tilts, ticks, physics, out):
    ffi, lib = harness
    targets = np.ascontiguousarray(targets, dtype=np.float32)
    tilts = np.ascontiguousarray(tilts, dtype=np.float32)
    lib.safety_grid(ffi.new("float[3]", [float(v) for v in start]), ffi.from_buffer("float[]", targets), len(targets),
                    ffi.from_buffer("float[]", tilts), len(tilts), ticks, physics[0], physics[1], out.c)
    assert out.c.n_goals < out.c.cap_goals and out.c.n_shafts < out.c.cap_shafts
    n, k = out.c.n_goals, out.c.n_shafts
    assert out.c.readings >= n, ("each goal is followed by a status reading the driver takes", out.c.readings, n)
    return out.goals[:n].astype(np.float64), out.goal_run[:n], out.shafts[:k].astype(np.float64), out.c.refused


@pytest.mark.parametrize("grid", GRIDS, ids=lambda g: f"{g[0][0] * 1e3:.1f} ms {g[0][1]} V, {g[1]:.0f} mm")
def test_every_commanded_move_is_safe_from_any_start(harness, grid):
    """Pairs: start poses x targets on a 24 mm or 48 mm grid (inside and beyond the reach) x
    tilts of 0 and +-30 deg about each axis; 60 ticks following, 60 ticks disengaging, the goals sent
    through the servo driver to servos that lag and slow with their supply. Each goal and the
    servos' path from the one before (every joint at the same speed, each arriving at its own
    time, sampled) pass the plain-geometry check, and so do the shafts themselves after every 1 ms
    step of the servos (in which one moved)."""
    physics, spacing = grid
    every_move_is_safe(harness, arm_spec.spec(), physics, spacing, AX12_UNIT_RAD)


def test_every_commanded_move_of_an_xm430_arm_is_safe_from_any_start(xm430_harness):
    """The same pairs for the model file made an XM430-W350 arm (its Protocol 2.0 driver, its
    units and zeros), on the slowest servos: 45 ms of lag on 9.0 V, the 48 mm grid."""
    m, harness = xm430_harness
    every_move_is_safe(harness, m, PHYSICS[2], 48.0, XM430_UNIT_RAD)


def every_move_is_safe(harness, m, physics, spacing, unit_rad):
    """m: the oracle's numbers (arm_spec) of the model file the harness was built from;
    unit_rad: its servos' unit (their e-manual's)."""
    ffi, lib = harness
    reach = m.L1 + m.L2 + m.L3
    xs = np.arange(-reach, reach + 0.1, spacing)
    zs = np.arange(-reach - 20.0, 20.1, spacing)
    x, y, z = np.meshgrid(xs, xs, zs, indexing="ij")
    targets = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    tilts = np.radians([[0, 0], [30, 0], [-30, 0], [0, 30], [0, -30]])
    out = Out(ffi, 2_000_000, 6_000_000)
    moves = near = samples = total_refused = 0
    clearance = math.inf
    starts = start_poses(m)
    for start in starts:
        g, run, shafts, refused = run_grid(harness, start, targets, tilts, 60, physics, out)
        near += assert_safe(m, g, f"goals from {np.degrees(start).round(1)}")
        same_run = run[1:] == run[:-1]
        a = np.vstack([start, g[:-1]])[1:][same_run]            # previous goal of the same run
        b = g[1:][same_run]
        paths = servo_path(a, b, 5)[:, 1:-1].reshape(-1, 3)
        near += assert_safe(m, paths, f"paths from {np.degrees(start).round(1)}")
        q = units_to_joints(m, shafts, unit_rad)
        near += assert_safe(m, q, f"shafts from {np.degrees(start).round(1)}")
        clearance = min(clearance, float(oracles.clearance_mm(m, q).min()))
        moves += len(a)
        samples += len(q)
        total_refused += refused
    runs = len(starts) * len(targets) * len(tilts)
    print(f"\nlag {physics[0] * 1e3:.1f} ms, {physics[1]} V: {len(starts)} start poses x {len(targets)} targets x "
          f"{len(tilts)} tilts = {runs} engage/follow/disengage runs, {moves} moves checked along the servos' path, "
          f"{samples} shaft samples (every 1 ms step with one moving), 0 unsafe ({near} within {MARGIN} of a boundary), the shafts "
          f"{clearance:.2f} mm clear of the body and the legs at least; {total_refused} routes refused")
    assert samples > 0


def test_the_harness_servo_moves_as_the_simulator_s():
    """The harness's servo (C, for speed) against uavarm.sim.ax12_sim's AX-12A fed the same
    goals and speeds through the bus: the same shaft, 1 ms by 1 ms, at every lag and supply."""
    from uavarm.sim import ax12_sim

    def simulator(lag, volts):
        servo = ax12_sim.AX12(1, position=500.0, voltage=volts, time_constant=lag, deadband=lag > 0)
        servo.set_register("torque_enable", 1)
        return servo
    servo_moves_as_the_simulator_s(harness_lib(), simulator, "moving_speed", (200, 800), [0, 90, 270, 532, 1023])


def test_the_xm430_harness_servo_moves_as_the_simulator_s(xm430_harness):
    """The same for the XM430-W350 build against uavarm.sim.xseries_sim's XServo (Profile
    Velocity; Profile Acceleration 0, as the driver sets it up)."""
    from uavarm.sim import xseries_sim

    def simulator(lag, volts):
        servo = xseries_sim.XServo(xseries_sim.XM430_W350, 1, position=500.0, voltage=volts, time_constant=lag)
        servo.set_register("torque_enable", 1)
        return servo
    servo_moves_as_the_simulator_s(xm430_harness[1], simulator, "profile_velocity", (200, 3800), [0, 44, 131, 258, 1023])


def servo_moves_as_the_simulator_s(harness, simulator, speed_register, goal_range, speed_choices):
    ffi, lib = harness
    rng = np.random.default_rng(5)
    for lag, volts in PHYSICS:
        n = 600
        goals = np.repeat(rng.integers(*goal_range, n // 50), 50).astype(np.float32)
        speeds = np.repeat(rng.choice(speed_choices, n // 50), 50).astype(np.float32)
        shafts = np.empty(n, np.float32)
        lib.servo_model(lag, volts, ffi.from_buffer("float[]", goals), ffi.from_buffer("float[]", speeds), n, 500.0,
                        ffi.from_buffer("float[]", shafts))
        servo = simulator(lag, volts)
        ref = []
        for g, v in zip(goals, speeds):
            servo.set_register("goal_position", int(g))
            servo.set_register(speed_register, int(v))
            servo.step(0.001)
            ref.append(servo.position)
        np.testing.assert_allclose(shafts, ref, atol=0.02, err_msg=f"lag {lag}, {volts} V")


AX12_UNIT_RAD = math.radians(arm_spec.AX12_RANGE_DEG) / arm_spec.AX12_UNITS_MAX   # AX-12A e-manual
XM430_UNIT_RAD = 2 * math.pi / 4096   # XM430-W350 e-manual: 4096 units a turn


def units_to_joints(m, units, unit_rad):
    """Joint angles (rad) of servo positions, from the model's zero and direction of each servo and
    the servos' unit."""
    zero = np.array([s.zero for s in m.servos], dtype=float)
    direction = np.array([s.direction for s in m.servos], dtype=float)
    return direction * (np.asarray(units, dtype=float) - zero) * unit_rad


def test_from_park_every_reachable_target_gets_a_route(harness):
    """From the park pose and from every other start pose, on a level board, every target of
    the grid that the plain-geometry IK reaches in a pose well clear of every boundary
    (0.5 mm, 0.5 deg) gets a clear route: none refused."""
    import simboard_tools
    ffi, lib = harness
    m = arm_spec.spec()
    targets, _ = grid(m)
    targets = targets[::7]
    reachable = targets[simboard_tools.level_ik_clear(targets)]
    level = np.zeros((1, 2))
    out = Out(ffi, len(reachable) * 120 + 1, len(reachable) * 1200 + 1)
    counts = [run_grid(harness, start, reachable, level, 60, PHYSICS[1], out)[3] for start in start_poses(m)]
    print(f"\n{len(reachable)} reachable targets x {len(counts)} start poses, level: {sum(counts)} refused")
    assert sum(counts) == 0


def model_ik(m):
    """The SymPy model's IK (lambdified once, float64) with its checks and nearest-valid
    selection: a function of (targets in the base frame, the current joints)."""
    ikm = kinematics.ik(m)
    xyz = kinematics.TARGET_SYMBOLS
    exprs = [ikm.disc >= 0]
    for cand in ikm.candidates:
        exprs += list(cand.q) + [kinematics.joint_limits_ok(m, cand.q), collision.body_clear(m, cand.geometry),
                                 collision.legs_clear(m, cand.geometry)]
    f = sp.lambdify(xyz, exprs, modules="numpy")

    def solutions(p_base, q_now):
        out = f(p_base[:, 0], p_base[:, 1], p_base[:, 2])
        reach = np.broadcast_to(out[0], len(p_base))
        best = np.full((len(p_base), 3), np.nan)
        best_d = np.full(len(p_base), np.inf)
        for k in range(4):
            q = np.stack([np.broadcast_to(v, len(p_base)) for v in out[1 + 6 * k:4 + 6 * k]], axis=1).astype(float)
            ok = reach & np.all([np.broadcast_to(v, len(p_base)) for v in out[4 + 6 * k:7 + 6 * k]], axis=0)
            d = np.sum((q - q_now) ** 2, axis=1)
            take = ok & (d < best_d)
            best[take], best_d[take] = q[take], d[take]
        return best
    return solutions


def test_model_never_selects_an_unsafe_pose():
    m = config.load()
    targets, tilts = grid(m)
    targets = targets[::3]          # the lambdified model is slower; every third target
    park = np.radians(m.park_deg)
    chosen, near = 0, 0
    model_solutions = model_ik(m)
    for roll, pitch in tilts:
        # p_base = (Ry(pitch) Rx(roll))^T (o + p_level) - o, from scipy (o: the mount offset)
        r_wb = Rotation.from_euler("YX", [pitch, roll]).as_matrix()
        o = np.array(m.mount_offset)
        q = model_solutions((targets + o) @ r_wb - o, park)
        valid = ~np.isnan(q[:, 0])
        chosen += int(valid.sum())
        near += assert_safe(arm_spec.spec(), q[valid], f"model at roll {math.degrees(roll):.0f}, pitch {math.degrees(pitch):.0f}")
    print(f"\nmodel: {len(targets)} targets x {len(tilts)} tilts, {chosen} selected, 0 unsafe "
          f"({near} within {MARGIN} of a boundary)")
