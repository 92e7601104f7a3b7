"""The split's scalar model (uavarm.sim.split_bound): its Kalman filter is the textbook one
(the variance it predicts is the one its errors show over the draws), and no linear estimate
beats it on its own model, the firmware's split included.

Oracles: the draws themselves (Monte Carlo against the filter's Riccati recursion), and the
Kalman filter's optimality among linear estimates when its model is the truth."""
from __future__ import annotations

import numpy as np
import pytest

from uavarm.model import config
from uavarm.sim import split_bound

MODEL = config.load()


@pytest.mark.parametrize("sigma, tau", [(0.5, 10.0), (0.35, 30.0), (0.2, 60.0)])
def test_the_filters_predicted_variance_is_what_its_errors_show(sigma, tau):
    b, f, w = split_bound.draws(sigma, tau, seed=3)
    errors, variance = split_bound.kalman(b, f, w, sigma, tau)
    for k in (0, 250, 1000, len(f) - 1):   # the first message, 5 s, 20 s, the end
        assert np.mean(errors[k] ** 2) == pytest.approx(variance[k], rel=0.08), k


@pytest.mark.parametrize("sigma, tau", split_bound.CORNERS)
def test_no_linear_estimate_beats_the_filter_that_knows_the_errors(sigma, tau):
    """The same draws through the fixed gains, fading and not, and the Kalman filter with the
    model file's sizes (the firmware's): none has a lower tilt error than the filter given the
    corner's own sigma and tau (1 % for the draws' spread)."""
    b, f, w = split_bound.draws(sigma, tau)
    e = MODEL.estimator
    best = split_bound.scored_rms_deg(split_bound.kalman(b, f, w, sigma, tau)[0])
    others = {"fading": split_bound.split(b, f, w, e.accel_bias_attitude_gain, e.fc_error_gain, e.fc_error_tau),
              "not fading": split_bound.split(b, f, w, e.accel_bias_attitude_gain, e.fc_error_gain, 0.0),
              "model file": split_bound.kalman(b, f, w, e.fc_error_deg, e.fc_error_tau, e.accel_bias_prior_g,
                                               e.accel_bias_walk_g)[0]}
    for name, errors in others.items():
        assert split_bound.scored_rms_deg(errors) >= 0.99 * best, name
