"""Layer 1: the SymPy model itself, evaluated at 30 digits, before any C is involved."""
import mpmath as mp
import numpy as np
import sympy as sp

from uavarm.model import kinematics, velocity


def test_fk_of_model_ik_is_identity(model):
    ikm = kinematics.ik(model)
    _, ee = kinematics.fk_points(model)
    fk = sp.lambdify(kinematics.JOINT_SYMBOLS, list(ee), modules="mpmath")
    iks = [sp.lambdify(kinematics.TARGET_SYMBOLS, list(c.q), modules="mpmath") for c in ikm.candidates]
    rng = np.random.default_rng(14)
    worst = mp.mpf(0)
    with mp.workdps(30):
        for _ in range(200):
            d = rng.normal(size=3)
            r = rng.uniform(abs(model.L2 - model.L3) + 1, model.L2 + model.L3 - 1)
            p = [mp.mpf(float(v)) for v in d / np.linalg.norm(d) * r + [0, 0, -model.L1]]
            for ik in iks:
                got = fk(*ik(*p))
                worst = max(worst, max(abs(g - w) for g, w in zip(got, p)))
    assert worst < mp.mpf("1e-20")


def test_four_candidates_are_distinct_solutions(model):
    """Away from singular sets the four candidates are four different joint vectors."""
    ikm = kinematics.ik(model)
    p = {kinematics.x: 60, kinematics.y: -25, kinematics.z: -120}
    qs = [[float(sp.N(e.subs(p), 30)) for e in c.q] for c in ikm.candidates]
    for i in range(4):
        for j in range(i + 1, 4):
            assert np.max(np.abs(np.subtract(qs[i], qs[j]))) > 0.1


def test_the_splits_joseph_update_is_the_kalman_filters(model):
    """velocity.split_update's covariance (Joseph form, as emitted) at split_gain's gain is
    the textbook P - K S K^T, and that gain minimises the updated variances: at any other
    gain their sum P00 + P11 is larger (the filter is optimal, not merely consistent)."""
    m00, m01, m11 = velocity.SPLIT_PRED
    white = velocity.split_noises(model)["white_var"]
    p = sp.Matrix([[m00, m01], [m01, m11]])
    hv = sp.Matrix([[-1, 1]])
    s = (hv * p * hv.T)[0] + white
    k = p * hv.T / s
    textbook = p - k * s * k.T
    gain = dict(zip(velocity.SPLIT_K, velocity.split_gain(model)))
    _, _, p00, p01, p11 = (sp.sympify(e).xreplace(gain) for e in velocity.split_update(model))
    for got, want in ((p00, textbook[0, 0]), (p01, textbook[0, 1]), (p11, textbook[1, 1])):
        assert sp.simplify(got - want) == 0
    at = {m00: sp.Rational(3, 10 ** 5), m01: sp.Rational(-1, 10 ** 6), m11: sp.Rational(4, 10 ** 5)}
    best = [float(e.xreplace(at)) for e in (p00, p11)]
    kd, kf = velocity.SPLIT_K
    for dk in ((0.05, 0), (-0.05, 0), (0, 0.05), (0, -0.05)):
        other = {kd: gain[kd].xreplace(at) + dk[0], kf: gain[kf].xreplace(at) + dk[1]}
        _, _, q00, _, q11 = (sp.sympify(e).xreplace(at).xreplace(other) for e in velocity.split_update(model))
        assert float(q00) + float(q11) > best[0] + best[1]


def test_the_splits_prediction_is_first_order_markov(model):
    """Over h much shorter than fc_error_tau the predicted P11 relaxes towards fc_error_deg^2
    as exp(-2 h / tau) does (to first order in h), P01 decays as exp(-h / tau), and P00 grows
    by the bias's walk, accel_bias_walk_g^2 per minute."""
    e = model.estimator
    h, tau = sp.Rational(1, 100), sp.nsimplify(e.fc_error_tau, rational=True)
    at = {velocity.SPLIT_H: h, velocity.SPLIT_P[0]: 0, velocity.SPLIT_P[1]: sp.Rational(1, 10 ** 5),
          velocity.SPLIT_P[2]: 0}
    p00, p01, p11 = (float(sp.sympify(v).xreplace(at)) for v in velocity.split_predict(model))
    fc2 = np.radians(e.fc_error_deg) ** 2
    assert np.isclose(p11, fc2 * (1 - np.exp(-2 * float(h / tau))), rtol=float(h / tau))
    assert np.isclose(p01, 1e-5 * np.exp(-float(h / tau)), rtol=float(h / tau) ** 2 * 2)
    assert np.isclose(p00, e.accel_bias_walk_g ** 2 / 60 * float(h), rtol=1e-12)


def test_the_split_waits_until_the_velocity_loop_has_taken_back_all_but_a_seventieth(model):
    """The velocity loop's gains place a triple pole at the bandwidth (its characteristic
    polynomial s^3 + k_v s^2 + g k_t s + g k_b is (s + w)^3), whose slowest response to an
    initial error is (1 + w t + (w t)^2 / 2) e^(-w t); settle_s is where that is under 1.5 %."""
    s, t = sp.symbols("s t", positive=True)
    w = sp.nsimplify(model.estimator.velocity_bandwidth, rational=True)
    k = velocity.gains(model.estimator.velocity_bandwidth)
    gap = sp.Poly(s ** 3 + k["k_v"] * s ** 2 + velocity.G * k["k_t"] * s + velocity.G * k["k_b"] - (s + w) ** 3, s)
    assert all(abs(c) < 1e-30 for c in gap.all_coeffs())       # (G is a float: exact to its digits)
    left = (1 + w * t + (w * t) ** 2 / 2) * sp.exp(-w * t)
    settle = velocity.settle_s(model.estimator.velocity_bandwidth)
    assert 0.013 < float(left.subs(t, settle)) < 0.015
    assert float(left.subs(t, settle / 2)) > 0.2          # half as long would leave a fifth
