"""The simulator's error ranges: every seed draws within them, the draws fill them, a seed
always draws the same errors, and a drawn scenario is one the scenario files could state."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from uavarm.build import variants
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


def test_stated_sizes_tell_the_split_each_draws_own_errors():
    """`--sizes-as-drawn`: the model file's split sizes become the draw's own (the flight
    controller's slow error, its correlation time and white error), the bias prior the spread
    of a uniform draw over the profile's horizontal range; a size left out is floored, not 0."""
    base = scenarios.load("hover")
    for seed, profile, half_width_g in ((3, None, 0.015), (8, "calibrated", 0.005)):
        d = error_ranges.drawn(base, seed, profile)
        est = variants.model_of(variants.edits(None, error_ranges.stated_sizes(d))).estimator
        assert est.fc_error_deg == pytest.approx(d.link.slow_deg, rel=1e-5)
        assert est.fc_error_tau == pytest.approx(d.link.slow_tau_s, rel=1e-5)
        assert est.drone_attitude_white_deg == pytest.approx(d.link.noise_deg, rel=1e-5)
        assert est.accel_bias_prior_g == pytest.approx(half_width_g / 3 ** 0.5, rel=1e-5)
    quiet = error_ranges.drawn(base, 3, without=("attitude-slow",))
    est = variants.model_of(variants.edits(None, error_ranges.stated_sizes(quiet))).estimator
    assert est.fc_error_deg == error_ranges.SIZE_FLOOR["fc_error_deg"] > 0.0
