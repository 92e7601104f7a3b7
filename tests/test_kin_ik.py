"""Generated IK: every candidate that exists is found and correct, nothing else escapes.

Oracles: the DH forward kinematics in float64 (FK(IK(p)) == p), the thesis's textbook IK
in float64 (the four exact solutions), and plain geometry for the statuses.
"""
import numpy as np
import pytest
import sympy as sp

import oracles
from uavarm.model import kinematics

N = 100_000
FK_TOL = 2e-3           # mm: 2 micrometres
ANGLE_TOL = 2e-5        # rad, between the C candidate and the exact one, outside the band
BAND = 1e-2             # mm: the singular band (base axis; full stretch; innermost reach)
OK, UNREACHABLE, JOINT_LIMIT, BODY, LEG = range(5)


def run_ik(gen, targets, q_now=(0.0, 0.0, 0.0)):
    ffi, lib = gen
    out = ffi.new("kin_ik_t *")
    p, qn = ffi.new("float[3]"), ffi.new("float[3]", list(q_now))
    qs = np.empty((len(targets), 4, 3), dtype=np.float32)
    st = np.empty((len(targets), 4), dtype=int)
    sel = np.empty(len(targets), dtype=int)
    buf = ffi.buffer(out.q)
    for i, t in enumerate(targets):
        p[0:3] = [float(v) for v in t]
        sel[i] = lib.kin_ik(p, qn, out)
        qs[i] = np.frombuffer(buf, dtype=np.float32).reshape(4, 3)
        st[i] = list(out.status)
    return qs, st, sel


def fk64(model):
    f = sp.lambdify(kinematics.JOINT_SYMBOLS, list(kinematics.fk_points(model)[1]), modules="numpy")
    return lambda q: np.stack(np.broadcast_arrays(*f(q[..., 0], q[..., 1], q[..., 2])), axis=-1)


def shell_targets(model, n, rng, lo=None, hi=None):
    """Targets uniform in the two-link reach shell about the shoulder."""
    lo = abs(model.L2 - model.L3) if lo is None else lo
    hi = model.L2 + model.L3 if hi is None else hi
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = np.cbrt(rng.uniform(lo**3, hi**3, size=n))
    p = d * r[:, None] + [0, 0, -model.L1]
    return p.astype(np.float32)


def test_fk_of_ik_and_completeness(model, gen):
    rng = np.random.default_rng(3)
    p = shell_targets(model, N, rng)
    qs, st, _ = run_ik(gen, p)
    p64 = p.astype(np.float64)
    exact, exists = oracles.textbook_ik(model, p64)
    fk = fk64(model)

    rho = np.hypot(p64[:, 0], p64[:, 1])
    r = np.hypot(rho, p64[:, 2] + model.L1)
    band = (rho < BAND) | (r > model.L2 + model.L3 - BAND) | (r < abs(model.L2 - model.L3) + BAND)

    found = st != UNREACHABLE
    missing = exists & ~found
    err = np.linalg.norm(fk(qs.astype(np.float64)) - p64[:, None, :], axis=2)
    dq = np.abs(oracles.wrap(qs.astype(np.float64) - exact))
    wrong = found & exists & ((err > FK_TOL) | (~band[:, None] & (dq.max(axis=2) > ANGLE_TOL)))
    print(f"\n{N} targets, {exists.sum()} exact candidates; band holds {band.sum()} targets")
    print(f"max |FK(IK(p)) - p| = {err[found].max() * 1e3:.4f} um; "
          f"max angle error outside band = {dq[found & ~band[:, None]].max():.2e} rad")
    print(f"missing: {missing[~band].sum()} outside band, {missing[band].sum()} inside; "
          f"wrong: {wrong[~band].sum()} outside band, {wrong[band].sum()} inside")
    assert exists[~band].all()
    assert missing[~band].sum() == 0 and wrong[~band].sum() == 0
    assert err[found].max() <= FK_TOL
    assert np.all(np.isfinite(qs))
    assert np.all(np.abs(qs) <= np.float32(np.pi))


def test_statuses_match_plain_geometry(model, gen):
    rng = np.random.default_rng(4)
    p = shell_targets(model, 20_000, rng)
    qs, st, sel = run_ik(gen, p)
    expect, clear = oracles.check_pose(model, qs.reshape(-1, 3).astype(np.float64), margin=1e-4)
    expect, clear = expect.reshape(-1, 4), clear.reshape(-1, 4)
    mismatch = (st != expect) & clear
    print(f"\nstatus counts: {np.bincount(st.ravel(), minlength=5)}; near a boundary: {(~clear).sum()}")
    assert mismatch.sum() == 0, f"{mismatch.sum()} statuses differ, e.g. {qs[mismatch][:3]}"
    assert (~clear).mean() < 0.01
    # the selection is a valid candidate whenever one exists, and the one nearest q_now
    has_valid = (st == OK).any(axis=1)
    assert np.array_equal(sel >= 0, has_valid)
    d = np.where(st == OK, np.sum(qs.astype(np.float64) ** 2, axis=2), np.inf)
    idx = np.flatnonzero(has_valid)
    picked = d[idx, sel[idx]]
    assert np.all(picked <= d[idx].min(axis=1) + 1e-5)


def test_selection_prefers_the_nearest_valid_solution(model, gen):
    """Holding a target while starting from each valid candidate must keep that candidate."""
    rng = np.random.default_rng(5)
    p = shell_targets(model, 3000, rng)
    qs, st, _ = run_ik(gen, p)
    ffi, lib = gen
    out = ffi.new("kin_ik_t *")
    checked = 0
    for target, cands, stats in zip(p, qs, st):
        for i in np.flatnonzero(stats == OK):
            assert lib.kin_ik(ffi.new("float[3]", target.tolist()), ffi.new("float[3]", cands[i].tolist()), out) == i
            checked += 1
    assert checked > 1000


@pytest.mark.parametrize("target", [
    (0.0, 0.0, -40.0),                 # at the shoulder: inside the inner sphere
    (0.0, 0.0, -45.0),
    (300.0, 0.0, -40.0),               # far beyond reach
    (0.0, 0.0, -40.0 - 138.5 - 1.0),   # just beyond full stretch, straight down
    (1e30, -1e30, 1e30),
])
def test_unreachable_targets_are_flagged_never_nan(gen, target):
    qs, st, sel = run_ik(gen, [target])
    assert np.all(st == UNREACHABLE) and sel[0] == -1
    assert np.all(np.isfinite(qs))


def test_inside_the_inner_sphere_is_refused_by_the_joint_limits(gen):
    """(0, 0, 0) is 40 mm from the shoulder: two links of 65 and 73.5 mm can fold that
    short, but only past joint 3's limit (which keeps the 75 mm inner radius)."""
    qs, st, sel = run_ik(gen, [(0.0, 0.0, 0.0)])
    assert np.all(st == JOINT_LIMIT) and sel[0] == -1


@pytest.mark.parametrize("target", [
    (float("nan"), 0.0, -100.0), (0.0, float("inf"), -100.0), (0.0, 0.0, float("-inf"))])
def test_non_finite_targets_are_refused(gen, target):
    qs, st, sel = run_ik(gen, [target])
    assert np.all(st == UNREACHABLE) and sel[0] == -1
    assert np.all(np.isfinite(qs))


def test_targets_on_the_base_axis(model, gen):
    """On the axis theta1 is free; the IK must still give a finite, correct answer."""
    fk = fk64(model)
    for depth in (-130.0, -150.0, -170.0, -178.0):
        qs, st, sel = run_ik(gen, [(0.0, 0.0, depth)])
        assert sel[0] >= 0, st
        got = fk(qs[0, sel[0]].astype(np.float64))
        assert np.linalg.norm(got - [0, 0, depth]) < FK_TOL


def test_full_stretch_straight_down(model, gen):
    z = -(model.L1 + model.L2 + model.L3)
    qs, st, sel = run_ik(gen, [(0.0, 0.0, z)])
    assert sel[0] >= 0
    assert np.allclose(qs[0, sel[0], 1:], 0.0, atol=1e-3)


def test_nan_current_joints_still_select(model, gen):
    p = shell_targets(model, 200, np.random.default_rng(6))
    _, st, sel = run_ik(gen, p, q_now=(float("nan"), 0.0, 0.0))
    assert np.array_equal(sel >= 0, (st == OK).any(axis=1))


def test_nearest_first_solver_selects_as_kin_ik(model, gen):
    """kin_ik_nearest (what the firmware runs each tick: candidates checked nearest first,
    stopping at the first valid one) gives bit for bit kin_ik's selection, or kin_ik's
    first refusal reason when no candidate is valid."""
    ffi, lib = gen
    rng = np.random.default_rng(11)
    reach = model.L1 + model.L2 + model.L3
    targets = np.concatenate([
        shell_targets(model, 6000, rng),
        rng.uniform(-reach - 20.0, reach + 20.0, size=(6000, 3)).astype(np.float32),   # many refused
        [(0.0, 0.0, -130.0), (0.0, 0.0, 0.0), (float("nan"), 0.0, -100.0), (1e30, 0.0, 0.0)],
    ])
    lo = np.array([l.min_rad for l in model.limits])
    hi = np.array([l.max_rad for l in model.limits])
    q_nows = np.concatenate([rng.uniform(lo, hi, size=(len(targets) - 4, 3)),
                             [(float("nan"), 0.0, 0.0), (float("inf"), 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)]])
    out, p, qn, q_out = ffi.new("kin_ik_t *"), ffi.new("float[3]"), ffi.new("float[3]"), ffi.new("float[3]")
    selected = ties = 0

    def distance(q, q_now):   # as kin_ik computes it, in float32
        d = [np.float32(q[j]) - np.float32(q_now[j]) for j in range(3)]
        return d[0] * d[0] + d[1] * d[1] + d[2] * d[2]

    for target, q_now in zip(targets, q_nows):
        # and again from each valid candidate, and from a point between the first two
        p[0:3] = [float(v) for v in target]
        qn[0:3] = [float(v) for v in q_now]
        lib.kin_ik(p, qn, out)
        valid = [i for i in range(4) if out.status[i] == OK]
        starts = [q_now] + [list(out.q[i]) for i in valid]
        starts.append([(out.q[0][j] + out.q[1][j]) / 2 for j in range(3)])
        # halfway between two valid candidates: often an exact tie, which goes to the lower index
        starts += [[float(np.float32((out.q[i][j] + out.q[k][j]) / 2)) for j in range(3)]
                   for i in valid for k in valid if i < k]
        for start in starts:
            qn[0:3] = [float(v) for v in start]
            sel = lib.kin_ik(p, qn, out)
            ties += sel >= 0 and sum(distance(out.q[i], start) == distance(out.q[sel], start)
                                     for i in range(4) if out.status[i] == OK) > 1
            q_out[0:3] = [-7.0, -7.0, -7.0]
            status = lib.kin_ik_nearest(p, qn, q_out)
            if sel >= 0:
                assert status == OK
                assert np.array_equal(np.array(list(q_out), np.float32), np.array(list(out.q[sel]), np.float32))
                selected += 1
            else:
                refused = [s for s in out.status if s != UNREACHABLE]
                assert status == (refused[0] if refused else UNREACHABLE), (target, list(out.status))
                assert list(q_out) == [-7.0, -7.0, -7.0]
    assert selected > 5000
    print(f"\n{selected} selections compared, {ties} of them with an exact tie")
    assert ties > 1000, ties      # exact ties were exercised
