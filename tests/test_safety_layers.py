"""Each safety layer of the generated code on its own, against oracles that are not the code
under test: kin_check_joints against plain geometry (tests/oracles.py) with the model file's
numbers read by tests/arm_spec.py, and servo_joints_to_units / servo_units_to_joints against
the AX-12A's written facts (1023 units over 300 degrees, 512 the centre, the model file's
zero and direction). The points are random, seeded, and concentrated near every boundary
(tests/boundary_points.py): limits, body plane, leg sectors, leg distance."""
import math
import os

import numpy as np
import pytest

import arm_spec
import boundary_points
import oracles

SEED = int(os.environ.get("SAFETY_SEED", "24031"))
POINTS = 40_000          # per family (before the limits filter)
MARGIN = 2e-4            # rad / mm: closer to a boundary than this, float32 may decide either way
NAMES = {0: "ok", 2: "limit", 3: "body", 4: "leg"}


@pytest.fixture(scope="module")
def rng():
    print(f"\nboundary points seed {SEED} (SAFETY_SEED=... to change)")
    return np.random.default_rng(SEED)


def check_all(ffi, lib, q32):
    out = np.empty(len(q32), dtype=int)
    buf = ffi.new("float[3]")
    for i, v in enumerate(q32):
        buf[0], buf[1], buf[2] = float(v[0]), float(v[1]), float(v[2])
        out[i] = lib.kin_check_joints(buf)
    return out


@pytest.mark.parametrize("family", list(boundary_points.FAMILIES))
def test_kin_check_joints_near_every_boundary(gen, rng, family):
    """kin_check_joints gives the plain-geometry status at every point not within MARGIN of
    a boundary; most points lie within 1 (rad or mm) of the family's boundary, on both
    sides, so a limit, half-width or distance off by a fraction of a degree or millimetre
    shows."""
    ffi, lib = gen
    m = arm_spec.spec()
    q = boundary_points.FAMILIES[family](rng, m, POINTS).astype(np.float32)
    got = check_all(ffi, lib, q)
    want, clear = oracles.check_pose(m, q.astype(np.float64), margin=MARGIN)
    bad = (got != want) & clear
    counts = {NAMES[k]: int((want == k).sum()) for k in NAMES}
    print(f"{family}: {len(q)} points, oracle {counts}, {(~clear).sum()} within {MARGIN} of a boundary")
    assert not bad.any(), [(np.degrees(v).tolist(), int(g), int(w)) for v, g, w in
                           zip(q[bad][:5], got[bad][:5], want[bad][:5])]
    assert (~clear).mean() < 0.1
    assert counts["ok"] > len(q) // 20 and len(q) - counts["ok"] > len(q) // 20   # both sides exercised


def test_non_finite_joints_are_refused(gen):
    ffi, lib = gen
    for bad in (float("nan"), float("inf"), -float("inf")):
        for j in range(3):
            q = [0.0, 1.0, -1.9]
            q[j] = bad
            assert lib.kin_check_joints(ffi.new("float[3]", q)) == 2     # KIN_JOINT_LIMIT


def test_target_on_the_body_plane_is_refused(gen):
    """The end effector must stay strictly below the body plane: a target exactly on it
    (a float equal to body_z) is refused by every IK candidate, a target a millimetre below
    is reached."""
    ffi, lib = gen
    m = arm_spec.spec()
    out = ffi.new("kin_ik_t *")
    now = ffi.new("float[3]", [math.radians(v) for v in m.park_deg])
    reached = 0
    for x, y in [(90.0, 20.0), (60.0, -30.0), (-80.0, 5.0), (0.0, 95.0), (110.0, 0.0)]:
        lib.kin_ik(ffi.new("float[3]", [x, y, m.body_z]), now, out)
        assert out.selected == -1 and all(out.status[i] != 0 for i in range(4)), (x, y, list(out.status))
        lib.kin_ik(ffi.new("float[3]", [x, y, m.body_z - 1.0]), now, out)
        reached += out.selected >= 0
    assert reached >= 3


def servo_points(rng, m, n):
    """Joint angles near each joint's limits (and past them) and all over the travel."""
    q = boundary_points.near_limits(rng, m, n)
    q[: n // 4] = rng.uniform(-math.pi, math.pi, (n // 4, 3))
    return q.astype(np.float32)


def test_servo_joints_to_units_by_the_servos_written_facts(gen, rng):
    """Inside the limits: the nearest whole unit of zero + direction x angle x 1023 / 300 deg
    (one either way only where the exact value is within 1e-3 of a half unit), inside the
    joint's unit range; outside the limits (beyond float32 rounding of the limit): refused."""
    ffi, lib = gen
    m = arm_spec.spec()
    q = servo_points(rng, m, POINTS)
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    buf, units = ffi.new("float[3]"), ffi.new("uint16_t[3]")
    taken = refused = 0
    for v in q:
        buf[0], buf[1], buf[2] = float(v[0]), float(v[1]), float(v[2])
        ok = lib.servo_joints_to_units(buf, units)
        v64 = v.astype(np.float64)
        inside, outside = np.all((v64 >= lo) & (v64 <= hi)), np.any((v64 < lo - 1e-6) | (v64 > hi + 1e-6))
        if inside and np.all((v64 >= lo + 1e-6) & (v64 <= hi - 1e-6)):
            assert ok, np.degrees(v64)
        if outside:
            assert not ok, np.degrees(v64)
        if not ok:
            refused += 1
            continue
        taken += 1
        for j in range(3):
            exact = arm_spec.units_exact(j, v64[j])
            u_lo, u_hi = arm_spec.unit_range(j)
            want = min(max(math.floor(exact + 0.5), u_lo), u_hi)
            tol = 1 if abs(exact - math.floor(exact) - 0.5) < 1e-3 else 0
            assert abs(units[j] - want) <= tol, (j, math.degrees(v64[j]), units[j], exact)
    print(f"servo map: {taken} taken, {refused} refused")
    assert taken > POINTS // 5 and refused > POINTS // 5


def test_servo_units_to_joints_by_the_servos_written_facts(gen):
    """Every position 0..1023 of each servo: (units - zero) / direction x 300 deg / 1023."""
    ffi, lib = gen
    m = arm_spec.spec()
    units, q = ffi.new("uint16_t[3]"), ffi.new("float[3]")
    for u in range(arm_spec.AX12_UNITS_MAX + 1):
        units[0] = units[1] = units[2] = u
        lib.servo_units_to_joints(units, q)
        for j, s in enumerate(m.servos):
            want = math.radians((u - s.zero) * s.direction * arm_spec.AX12_RANGE_DEG / arm_spec.AX12_UNITS_MAX)
            assert q[j] == pytest.approx(want, abs=2e-6), (j, u)


def test_centre_is_512_and_the_joint_limits_are_the_servos_angle_limits(gen):
    """The servo's centre (joint angle 0 with the model's zero 512) and the unit range at the
    limits: the end units are inside the limits, one more unit is outside."""
    ffi, lib = gen
    m = arm_spec.spec()
    units = ffi.new("uint16_t[3]")
    assert lib.servo_joints_to_units(ffi.new("float[3]", [0.0, 0.0, 0.0]), units)
    assert [units[j] for j in range(3)] == [s.zero for s in m.servos]
    assert all(s.zero == arm_spec.AX12_CENTRE for s in m.servos)    # the model file's servos sit centred
    for j in range(3):
        u_lo, u_hi = arm_spec.unit_range(j)
        for u, inside in ((u_lo, True), (u_hi, True), (u_lo - 1, False), (u_hi + 1, False)):
            ang = (u - m.servos[j].zero) * m.servos[j].direction * math.radians(300.0) / 1023
            q = [0.0, 0.0, 0.0]
            q[j] = ang
            assert lib.servo_joints_to_units(ffi.new("float[3]", q), units) == inside, (j, u)
