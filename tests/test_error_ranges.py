"""The simulator's error ranges: every seed draws within them, the draws fill them, a seed
always draws the same errors, and a drawn scenario is one the scenario files could state."""
from __future__ import annotations

import dataclasses

import numpy as np

from uavarm.sim import error_ranges, scenarios


def test_draws_stay_within_the_ranges_and_fill_them():
    base = scenarios.load("hover")
    drawn = [error_ranges.drawn(base, seed) for seed in range(200)]
    for attr, ranges in (("link", error_ranges.LINK), ("velocity", error_ranges.VELOCITY)):
        for name, (lo, hi) in ranges.items():
            values = np.array([getattr(getattr(s, attr), name) for s in drawn])
            assert values.min() >= lo and values.max() <= hi, (attr, name)
            assert values.min() < lo + 0.1 * (hi - lo) and values.max() > hi - 0.1 * (hi - lo), (attr, name)
    assert {s.imu_profile for s in drawn} == {error_ranges.IMU_PROFILE}
    assert all(s.motion == base.motion and s.target == base.target and s.kind == base.kind for s in drawn)


def test_a_seed_draws_the_same_errors_and_the_imu_profile_can_be_chosen():
    base = scenarios.load("bench")
    assert error_ranges.drawn(base, 4) == error_ranges.drawn(base, 4)
    lossy = dataclasses.replace(base, link=dataclasses.replace(base.link, outages=((20.0, 50.0),)),
                                velocity=dataclasses.replace(base.velocity, outages=((5.0, 6.0),)))
    assert error_ranges.drawn(lossy, 4).link.outages == ((20.0, 50.0),)      # the draw keeps the outages
    assert error_ranges.drawn(lossy, 4).velocity.outages == ((5.0, 6.0),)
    assert error_ranges.drawn(base, 4).link != error_ranges.drawn(base, 5).link
    assert error_ranges.drawn(base, 4, "datasheet").imu_profile == "datasheet"


def test_a_drawn_scenario_is_one_a_scenario_file_can_state():
    for seed in range(20):
        s = error_ranges.drawn(scenarios.load("manoeuvre"), seed)
        assert scenarios.parse(scenarios.dump(s)) == s


def test_an_error_left_out_is_zero_and_the_rest_drawn_as_before():
    """Leaving the flight controller's slow error out zeroes it alone: the same seed's other
    errors (its white error, rate, delays; the velocity's) are drawn unchanged."""
    base = scenarios.load("hover")
    full = error_ranges.drawn(base, 7)
    for name, (stream, fields) in error_ranges.LEFT_OUT.items():
        cut = error_ranges.drawn(base, 7, without=(name,))
        before, after = getattr(full, stream), getattr(cut, stream)
        for f in dataclasses.fields(before):
            assert getattr(after, f.name) == (0.0 if f.name in fields else getattr(before, f.name)), (name, f.name)
        assert getattr(before, fields[0]) > 0.0
        other = "velocity" if stream == "link" else "link"
        assert getattr(cut, other) == getattr(full, other)
