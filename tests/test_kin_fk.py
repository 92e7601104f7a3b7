"""Generated forward kinematics against the SymPy model at 30 digits, and the DH chain
against the plain geometric description of the arm."""
import mpmath as mp
import numpy as np
import sympy as sp

import oracles
from uavarm.model import kinematics

N = 10_000
TOL_MM = 1e-3     # 1 micrometre


def _fk_mp(model):
    j3, ee = kinematics.fk_points(model)
    return sp.lambdify(kinematics.JOINT_SYMBOLS, list(ee) + list(j3), modules="mpmath")


def test_fk_matches_sympy_at_30_digits(model, gen):
    ffi, lib = gen
    rng = np.random.default_rng(1)
    qs = rng.uniform(-np.pi, np.pi, size=(N, 3)).astype(np.float32)
    f = _fk_mp(model)
    qc, ee, j3 = ffi.new("float[3]"), ffi.new("float[3]"), ffi.new("float[3]")
    worst = 0.0
    with mp.workdps(30):
        for q in qs:
            qc[0:3] = q.tolist()
            lib.kin_fk_ee(qc, ee)
            lib.kin_fk_joint3(qc, j3)
            exact = f(*(mp.mpf(float(v)) for v in q))        # the float32 input, exactly
            got = list(ee) + list(j3)
            worst = max(worst, max(abs(float(e - g)) for e, g in zip(exact, got)))
    print(f"FK max error over {N} joint vectors: {worst * 1e3:.4f} um")
    assert worst <= TOL_MM


def test_dh_chain_is_the_described_arm(model):
    """The arm's DH table and the plain geometry of oracles.py describe one arm."""
    f = sp.lambdify(kinematics.JOINT_SYMBOLS, list(kinematics.fk_points(model)[1]) +
                    list(kinematics.fk_points(model)[0]), modules="numpy")
    rng = np.random.default_rng(2)
    qs = rng.uniform(-np.pi, np.pi, size=(2000, 3))
    _, elbow, ee = oracles.arm_points(model, qs)
    got = np.array(f(qs[:, 0], qs[:, 1], qs[:, 2])).T
    assert np.max(np.abs(got[:, :3] - ee)) < 1e-9
    assert np.max(np.abs(got[:, 3:] - elbow)) < 1e-9


def test_arm_hangs_straight_down_at_zero(model, gen):
    ffi, lib = gen
    ee = ffi.new("float[3]")
    lib.kin_fk_ee(ffi.new("float[3]", [0, 0, 0]), ee)
    assert np.allclose(list(ee), [0, 0, -(model.L1 + model.L2 + model.L3)], atol=1e-4)
