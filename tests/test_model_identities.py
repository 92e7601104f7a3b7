"""Layer 1: the SymPy model itself, evaluated at 30 digits, before any C is involved."""
import mpmath as mp
import numpy as np
import sympy as sp

from uavarm.model import kinematics


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
