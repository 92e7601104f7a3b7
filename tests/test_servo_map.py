"""Joint angle <-> AX-12A units against the servo's documented scale: 1023 units over
300 degrees (AX-12A e-manual), the model's zero and direction."""
import math

import numpy as np
import pytest

UNITS_PER_DEG = 1023 / 300.0


def expected_units(model, j, angle_rad):
    s = model.servos[j]
    return s.zero + s.direction * math.degrees(angle_rad) * UNITS_PER_DEG


def test_round_trip_and_rounding(model, gen):
    ffi, lib = gen
    rng = np.random.default_rng(10)
    units = ffi.new("uint16_t[3]")
    back = ffi.new("float[3]")
    for _ in range(5000):
        q = [rng.uniform(l.min_rad, l.max_rad) for l in model.limits]
        q32 = [float(np.float32(v)) for v in q]
        assert lib.servo_joints_to_units(ffi.new("float[3]", q32), units)
        for j in range(3):
            assert abs(units[j] - expected_units(model, j, q32[j])) <= 0.5 + 1e-3
        lib.servo_units_to_joints(units, back)
        for j in range(3):
            # one unit is 0.293 deg: the round trip loses at most half of it
            assert abs(back[j] - q32[j]) <= math.radians(0.5 / UNITS_PER_DEG) + 1e-6


def test_units_to_joints_centre_and_scale(model, gen):
    ffi, lib = gen
    q = ffi.new("float[3]")
    s = model.servos
    lib.servo_units_to_joints(ffi.new("uint16_t[3]", [s[0].zero, s[1].zero, s[2].zero]), q)
    assert list(q) == [0.0, 0.0, 0.0]
    lib.servo_units_to_joints(ffi.new("uint16_t[3]", [s[0].zero + 1023 // 3] * 3), q)
    assert q[0] == pytest.approx(s[0].direction * math.radians((1023 // 3) / UNITS_PER_DEG), rel=1e-6)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, 3.0, -3.0])
def test_refuses_non_finite_or_out_of_limit_angles(gen, bad):
    ffi, lib = gen
    units = ffi.new("uint16_t[3]", [111, 222, 333])
    for j in range(3):
        q = [0.0, 0.0, 0.0]
        q[j] = bad
        assert not lib.servo_joints_to_units(ffi.new("float[3]", q), units)
        assert list(units) == [111, 222, 333]          # nothing written


def test_limits_map_inside_the_unit_range(model, gen):
    """Angles exactly at the travel limits are accepted and stay inside the limits' units."""
    ffi, lib = gen
    units = ffi.new("uint16_t[3]")
    for end in ("min_rad", "max_rad"):
        q = []
        for l in model.limits:
            v = np.float32(getattr(l, end))
            inward = np.float32(l.max_rad if end == "min_rad" else l.min_rad)
            while not l.min_rad <= v <= l.max_rad:      # float32 rounding may step outside
                v = np.nextafter(v, inward)
            q.append(float(v))
        assert lib.servo_joints_to_units(ffi.new("float[3]", q), units)
        for j in range(3):
            lo = expected_units(model, j, model.limits[j].min_rad)
            hi = expected_units(model, j, model.limits[j].max_rad)
            assert min(lo, hi) <= units[j] <= max(lo, hi)


def test_refuses_the_first_angle_past_each_limit(model, gen):
    """The nearest float32 beyond each end of each joint's travel (from the model's limits in
    float64) is refused, the other joints at zero."""
    ffi, lib = gen
    units = ffi.new("uint16_t[3]")
    for j, l in enumerate(model.limits):
        for end, outward in ((l.min_rad, -np.inf), (l.max_rad, np.inf)):
            v = np.float32(end)
            while l.min_rad <= v <= l.max_rad:
                v = np.nextafter(v, np.float32(outward))
            q = [0.0, 0.0, 0.0]
            q[j] = float(v)
            assert not lib.servo_joints_to_units(ffi.new("float[3]", q), units), (j, end, v)
