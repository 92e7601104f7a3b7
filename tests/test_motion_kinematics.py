"""The generated motion kinematics: kin_ik_branch (the IK of a followed target on one
branch, projected onto what it reaches) and kin_check_swept (is the whole box between two
goals safe).

Oracles: tests/oracles.py's plain geometry (the branch IK by the law of cosines, forward
kinematics, the pose check on densely sampled boxes), and the SymPy model evaluated at 40
digits (model/kinematics.py BranchIk, model/swept.py).
"""
from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
import sympy as sp

import oracles
from uavarm.model import kinematics, swept

RNG_SEED = 20261124
DEG = math.pi / 180


def _f3(ffi, v):
    return ffi.new("float[3]", [float(a) for a in v])


def branch(gen, p, ref, elbow, hold, with_next=False):
    ffi, lib = gen
    q, nxt = ffi.new("float[3]"), ffi.new("float[3]")
    flags = lib.kin_ik_branch(_f3(ffi, p), _f3(ffi, ref), float(elbow), bool(hold), q, nxt)
    if with_next:
        return np.array(list(q)), flags, np.array(list(nxt))
    return np.array(list(q)), flags


def limits(model):
    return np.radians([l.min_deg for l in model.limits]), np.radians([l.max_deg for l in model.limits])


def random_refs(model, rng, n):
    lo, hi = limits(model)
    return rng.uniform(lo, hi, (n, 3))


# ---------------------------------------------------------------- kin_ik_branch

def test_branch_ik_is_its_contract_by_the_law_of_cosines(model, gen):
    """Random targets (inside and far outside the reach, near and on the axis), random
    joints to continue from, both elbows, joint 1 free or held: the C agrees with the plain
    geometry oracle within float32 accuracy wherever no decision is within a hair of its
    boundary, and its flags say what was given up."""
    lib = gen[1]
    rng = np.random.default_rng(RNG_SEED)
    n, checked, flags_seen = 6000, 0, 0
    refs = random_refs(model, rng, n)
    targets = rng.uniform([-180, -180, -220], [180, 180, 60], (n, 3))
    targets[::7, :2] *= 0.02                       # near and on joint 1's axis
    for k in range(n):
        p, ref = targets[k], refs[k]
        elbow, hold = (1, -1)[k % 2], k % 3 == 0
        want, reach, q1c, q2c = oracles.branch_ik(model, p, ref, elbow, hold)
        got, flags = branch(gen, p, ref, elbow, hold)
        assert np.all(np.isfinite(got))
        lo, hi = limits(model)
        assert np.all(got >= lo.astype(np.float32)) and np.all(got <= hi.astype(np.float32)), (p, ref, got)
        # decisions within a hair of their boundary may go either way in float32
        r = math.hypot(p[0] * math.cos(want[0]) - p[1] * math.sin(want[0]), p[2] + model.L1)
        r_min, r_max = oracles.reach_limits(model, elbow)
        turn = abs(float(oracles.wrap(math.atan2(-p[1], p[0]) - ref[0])))
        edge = (min(abs(r - r_min), abs(r - r_max)) < 1e-3 or abs(turn - math.pi / 2) < 1e-4
                or np.any((0 < np.abs(np.concatenate([want - lo, want - hi])))
                          & (np.abs(np.concatenate([want - lo, want - hi])) < 1e-4))
                or math.hypot(p[0], p[1]) < 1e-3)
        if edge:
            continue
        checked += 1
        flags_seen |= flags
        assert bool(flags & lib.KIN_BRANCH_REACH) == reach, (p, ref, elbow, hold, flags)
        assert bool(flags & lib.KIN_BRANCH_Q1) == q1c, (p, ref, elbow, hold, flags)
        assert bool(flags & lib.KIN_BRANCH_Q2) == q2c, (p, ref, elbow, hold, flags)
        assert np.abs(got - want).max() < 2e-4, (p, ref, elbow, hold, got, want)
    print(f"\n{checked} of {n} compared away from decision boundaries")
    assert checked > 0.9 * n
    assert flags_seen == lib.KIN_BRANCH_REACH | lib.KIN_BRANCH_Q1 | lib.KIN_BRANCH_Q2   # every outcome exercised


def test_branch_ik_reaches_a_reachable_target_exactly(model, gen):
    """Within the reach, joint 1 free: forward kinematics (plain geometry) of the result is the
    target to float32 accuracy, on the elbow asked for."""
    rng = np.random.default_rng(RNG_SEED + 1)
    r_min, r_max = oracles.reach_limits(model, 1)
    done = 0
    while done < 3000:
        p = rng.uniform([-140, -140, -190], [140, 140, 20])
        v = -(p[2] + model.L1)
        if not r_min + 0.1 < math.hypot(math.hypot(p[0], p[1]), v) < r_max - 0.1 or math.hypot(p[0], p[1]) < 1:
            continue
        ref = random_refs(model, rng, 1)[0]
        elbow = (1, -1)[done % 2]
        q, flags = branch(gen, p, ref, elbow, False)
        if flags:   # joint 1 or 2 stopped at a limit: not reachable on this branch
            continue
        ee = oracles.arm_points(model, q)[2]
        assert np.linalg.norm(ee - p) < 2e-3, (p, ref, q)
        assert math.copysign(1, q[2]) == elbow
        done += 1


def test_branch_ik_out_of_reach_gives_the_nearest_point_of_the_shell(model, gen):
    """Beyond the reach (or inside the inner sphere) the end effector lands on the elbow's
    reach shell, on the line from the shoulder to the target (the nearest point of the
    shell in joint 1's plane)."""
    rng = np.random.default_rng(RNG_SEED + 2)
    shoulder = np.array([0.0, 0.0, -model.L1])
    done = 0
    while done < 1500:
        p = rng.uniform([-300, -300, -320], [300, 300, 200])
        elbow = (1, -1)[done % 2]
        r_min, r_max = oracles.reach_limits(model, elbow)
        r = np.linalg.norm(p - shoulder)
        if r_min - 1 < r < r_max + 1 or math.hypot(p[0], p[1]) < 1:
            continue
        ref = random_refs(model, rng, 1)[0]
        q, flags = branch(gen, p, ref, elbow, False)
        if flags != gen[1].KIN_BRANCH_REACH:   # (a joint also stopped: a different point)
            continue
        ee = oracles.arm_points(model, q)[2]
        want = shoulder + (p - shoulder) / r * (r_max if r > r_max else r_min)
        assert np.linalg.norm(ee - want) < 2e-3, (p, q, ee, want)
        done += 1


def test_branch_ik_holds_joint_1_and_reaches_in_its_plane(model, gen):
    """With joint 1 held: it stays exactly, and the end effector reaches the target's
    projection onto the held plane (the target moved along the plane's normal)."""
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(1000):
        ref = random_refs(model, rng, 1)[0]
        normal = np.array([math.sin(ref[0]), math.cos(ref[0]), 0.0])   # (cos q1, -sin q1, 0) is the plane
        u, z = rng.uniform(-60, 60), rng.uniform(-170, -90)
        in_plane = np.array([u * math.cos(ref[0]), -u * math.sin(ref[0]), z])
        p = in_plane + normal * rng.uniform(-20, 20)
        q, flags = branch(gen, p, ref, 1 if ref[2] >= 0 else -1, True)
        assert q[0] == np.float32(ref[0])
        if flags == 0:
            assert np.linalg.norm(oracles.arm_points(model, q)[2] - in_plane) < 2e-3


def test_branch_ik_keeps_its_branch_and_is_continuous(model, gen):
    """A target moved in small steps along random paths, in and out of the reach and past
    joint 1's axis, each result continued from the last (joint 1 held within 10 mm of the
    axis): the elbow sign is kept, and every step is small, but where joint 1 is let go
    again (it then turns to the target; the firmware moves there at the servos' speed)."""
    rng = np.random.default_rng(RNG_SEED + 4)
    for trial in range(40):
        a, b = rng.uniform([-150, -150, -200], [150, 150, 0], (2, 3))
        elbow = (1, -1)[trial % 2]
        q, _, nxt = branch(gen, a, [0.0, 0.0, 0.5 * elbow], elbow, False, with_next=True)
        held = False
        for s in np.linspace(0, 1, 400)[1:]:
            p = a + s * (b - a)
            was_held, held = held, math.hypot(p[0], p[1]) < 10
            q_next, _, nxt = branch(gen, p, nxt, elbow, held, with_next=True)
            assert q_next[2] * elbow >= 0, "elbow sign kept"
            # a target step of |b - a| / 400 (<= 1.3 mm) turns joint 1 at most 0.13 rad at
            # 10 mm from the axis; joints 2-3 as the inverse Jacobian allows at the margins
            if not (was_held and not held):
                assert abs(q_next[0] - q[0]) < 0.15, (trial, s, q, q_next)
            assert np.abs(q_next[1:] - q[1:]).max() < 0.4, (trial, s, q, q_next)
            q = q_next


def test_branch_ik_stops_at_joint_1s_limit_while_the_target_circles_past(model, gen):
    """A target carried round the axis (as a drone rocking 27 deg in both axes carries a set
    position 60 mm out): joint 1 follows it to its limit and stays there while the target
    goes on round, never jumping to the far side; when the target comes back the same way,
    joint 1 follows it back."""
    lo, hi = limits(model)
    angles = np.radians(np.concatenate([np.arange(0, 400, 2), np.arange(400, -1, -2)]))
    nxt, q1 = np.array([0.0, 0.5, 0.5]), []
    for a in angles:
        p = np.array([80 * math.cos(a), -80 * math.sin(a), -120.0])   # azimuth a: joint 1 at a faces it
        q, flags, nxt = branch(gen, p, nxt, 1, False, with_next=True)
        q1.append(q[0])
        assert bool(flags & gen[1].KIN_BRANCH_Q1) == (a > hi[0] + 1e-3) or abs(a - hi[0]) < 1e-3
    q1 = np.array(q1)
    assert np.abs(np.diff(q1)).max() < math.radians(2.1), "no jump"
    assert q1.max() == np.float32(hi[0]) and abs(q1[-1]) < 1e-4


def test_branch_ik_expressions_against_the_model_at_40_digits(model, gen):
    """Inside the reach with joint 1 facing the target, q2 and q3 of the generated C equal
    the model's BranchIk expressions evaluated at 40 digits (mpmath)."""
    b = kinematics.branch_ik(model)
    x, y, z = kinematics.TARGET_SYMBOLS
    f = sp.lambdify((kinematics.U, z, kinematics.ELBOW, kinematics.R2), [b.q2, b.q3], modules="mpmath")
    rng = np.random.default_rng(RNG_SEED + 5)
    mp.mp.dps = 40
    worst = 0.0
    for k in range(500):
        p = rng.uniform([-140, -140, -190], [140, 140, 20])
        elbow = (1, -1)[k % 2]
        q, flags = branch(gen, p, [math.atan2(-p[1], p[0]), 0.0, 0.0], elbow, False)
        if flags:
            continue
        u = math.hypot(p[0], p[1])
        r2 = u * u + (p[2] + model.L1) ** 2
        want = [float(v) for v in f(mp.mpf(u), mp.mpf(p[2]), elbow, mp.mpf(r2))]
        worst = max(worst, abs(q[1] - want[0]), abs(q[2] - want[1]))
    print(f"\nworst |C - model| {worst:.2e} rad")
    assert worst < 1e-4


# ---------------------------------------------------------------- kin_check_swept

def check_swept(gen, a, b):
    ffi, lib = gen
    return lib.kin_check_swept(_f3(ffi, a), _f3(ffi, b))


def box_samples(a, b, rng, n=300, about_b=False):
    """Corners, edge midpoints and random points of the box a..b, or (about_b) of the box
    about b that reaches back to a, which kin_check_swept checks (float64)."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    if about_b:
        lo, hi = b - np.abs(b - a), b + np.abs(b - a)
    corners = np.array([[(lo, hi)[(k >> j) & 1][j] for j in range(3)] for k in range(8)])
    return np.vstack([corners, (corners[:, None] + corners[None]).reshape(-1, 3) / 2,
                      lo + rng.uniform(0, 1, (n, 3)) * (hi - lo)])


def near_boundary_boxes(model, rng, n):
    """Boxes whose centres are drawn near every boundary: the joint limits, the leg zones'
    edges, the body plane and the leg distance (by bisection along random directions), with
    half-widths up to 4 deg."""
    lo, hi = limits(model)
    hw = math.radians(model.leg_half_width)
    legs = np.radians(model.leg_angles)
    out = []
    while len(out) < n:
        c = rng.uniform(lo, hi)
        kind = rng.integers(4)
        if kind == 0:                              # a joint limit
            j = rng.integers(3)
            c[j] = (lo, hi)[rng.integers(2)][j] + rng.normal(0, 0.02)
        elif kind == 1:                            # a leg zone's edge
            c[0] = rng.choice(legs) + rng.choice([-1, 1]) * hw + rng.normal(0, 0.02)
        else:                                      # the body plane or the leg distance
            d = rng.normal(0, 1, 3)
            s0, s1 = 0.0, 1.0
            st0 = oracles.check_pose(model, c)[0][0]
            if oracles.check_pose(model, c + d)[0][0] == st0:
                continue
            for _ in range(30):
                mid = (s0 + s1) / 2
                s0, s1 = (mid, s1) if oracles.check_pose(model, c + mid * d)[0][0] == st0 else (s0, mid)
            c = c + s0 * d + rng.normal(0, 0.01, 3)
        h = rng.uniform(0, math.radians(4), 3) * (rng.uniform(0, 1, 3) < 0.8)
        out.append((c - h, c + h))
    return out


def test_swept_check_accepts_only_boxes_that_are_safe_everywhere(model, gen):
    """Boxes drawn near every boundary (not on any grid): whenever the C accepts one, every
    sampled pose in it is safe by plain geometry."""
    rng = np.random.default_rng(RNG_SEED + 6)
    accepted = 0
    for a, b in near_boundary_boxes(model, rng, 4000):
        if check_swept(gen, a, b) != 0:
            continue
        accepted += 1
        status, _ = oracles.check_pose(model, box_samples(a, b, rng))
        assert (status == 0).all(), (a, b, status[status != 0][:4])
    print(f"\n{accepted} of 4000 near-boundary boxes accepted, all safe")
    assert accepted > 500


def test_swept_check_of_one_pose_is_the_pose_check(model, gen):
    """For a box of zero width, kin_check_swept decides as the plain-geometry pose check
    (away from the boundaries by 1e-4 mm or rad), and as kin_check_joints."""
    ffi, lib = gen
    rng = np.random.default_rng(RNG_SEED + 7)
    lo, hi = limits(model)
    q = np.vstack([rng.uniform(lo - 0.2, hi + 0.2, (3000, 3)),
                   np.array([c for c, _ in near_boundary_boxes(model, rng, 1000)])])
    want, clear = oracles.check_pose(model, q, margin=1e-4)
    for v, w, c in zip(q, want, clear):
        got = check_swept(gen, v, v)
        assert got == lib.kin_check_joints(_f3(ffi, v)) or not c
        if c:
            assert got == w, (v, got, w)


def test_swept_check_is_not_vacuous(model, gen):
    """Steps up to the working speed's per-tick travel (3.5 deg of every joint at once) whose
    box about the new goal (the one kin_check_swept bounds) keeps 1 mm from the body plane and
    the leg distance and 0.5 deg from the leg zones and the limits are accepted: the bound's
    slack is below that."""
    rng = np.random.default_rng(RNG_SEED + 8)
    lo, hi = limits(model)
    step = 3.54 * DEG
    tried = 0
    for _ in range(4000):
        a = rng.uniform(lo, hi)
        b = a + rng.uniform(-step, step, 3)
        if not (oracles.clear_by(model, box_samples(a, b, rng, 200, about_b=True), 1.0, 0.5 * DEG).all()
                and oracles.clear_by(model, np.array([a, b]), 0.0, 0.5 * DEG).all()):
            continue
        tried += 1
        assert check_swept(gen, a, b) == 0, (a, b)
    print(f"\n{tried} clear steps, all accepted")
    assert tried > 300


def clear_of_body_and_legs(model, q):
    """Plain geometry's body and leg verdicts for any joint angles (the promised box may
    reach past a joint limit: its bound holds there too, and the limits are checked on the
    goals)."""
    from dataclasses import replace
    free = replace(model, limits=[replace(l, min_deg=-720.0, max_deg=720.0) for l in model.limits])
    return oracles.check_pose(free, q)[0] == 0


GRID = 9                       # poses per joint across each promised box: 9 x 9 x 9 = 729


def near_the_body_plane(model, rng, n):
    """Poses inside the limits whose elbow or end effector is 0 to 6 mm below the body plane."""
    lo, hi = limits(model)
    out = []
    while len(out) < n:
        q = rng.uniform(lo, hi, (4000, 3))
        _, elbow, tip = oracles.arm_points(model, q)
        gap = model.body_z - np.maximum(elbow[:, 2], tip[:, 2])
        out += list(q[(gap > 0) & (gap < 6.0)])
    return out[:n]


@pytest.mark.parametrize("check", ["kin_check_swept", "kin_check_move"])
def test_the_swept_bound_is_never_below_the_moves_true_extent(model, gen, check):
    """The bound's promise, against dense sampling: moves from poses drawn near every
    boundary (the leg sectors' edges and the leg distance, the joint limits, the body plane;
    half of them with the elbow or the end effector 0 to 6 mm below the body plane),
    one, two or all three joints turning at once, by 0.05 to 15 deg each (a tick's step and
    a route's pieces); kin_check_move with no margin and with the planner's 0.0035 rad.
    Whenever the check says KIN_OK, every pose of a 9 x 9 x 9 grid over the box it promises
    clear (about b, half-widths max(|b - a|, margin)), and 40 random poses in it, are clear
    of body and legs by plain geometry."""
    ffi, lib = gen
    rng = np.random.default_rng(RNG_SEED + 10 + (check == "kin_check_move"))
    lo, hi = limits(model)
    n_moves, accepted, sampled = 6000, {1: 0, 2: 0, 3: 0}, 0
    near = {"body": 0, "legs": 0}
    u = np.linspace(-1.0, 1.0, GRID)
    grid = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
    starts = [(a_lo + a_hi) / 2 for a_lo, a_hi in near_boundary_boxes(model, rng, n_moves // 2)]
    for a in starts + near_the_body_plane(model, rng, n_moves - len(starts)):
        a = np.clip(a, lo, hi)
        turning = rng.choice(3, size=rng.integers(1, 4), replace=False)
        d = np.zeros(3)
        d[turning] = rng.choice([-1, 1], len(turning)) * np.exp(rng.uniform(math.log(0.05), math.log(15.0), len(turning))) * DEG
        b = a + d
        margin = 0.0 if check == "kin_check_swept" or rng.integers(2) else 0.0035
        if check == "kin_check_swept":
            status = lib.kin_check_swept(_f3(ffi, a), _f3(ffi, b))
        else:
            status = lib.kin_check_move(_f3(ffi, a), _f3(ffi, b), margin)
        if status != lib.KIN_OK:
            continue
        # the goals as the C saw them (float32), and the box about b it promises
        a32, b32 = np.float32(a).astype(float), np.float32(b).astype(float)
        h = np.maximum(np.abs(b32 - a32), margin)
        poses = np.vstack([b32 + grid * h, b32 + rng.uniform(-1, 1, (40, 3)) * h])
        ok = clear_of_body_and_legs(model, poses)
        assert ok.all(), (check, a, b, margin, poses[~ok][:3])
        accepted[len(turning)] += 1
        sampled += len(poses)
        _, elbow, tip = oracles.arm_points(model, b32)
        if min(abs(elbow[2] - model.body_z), abs(tip[2] - model.body_z)) < 5.0:
            near["body"] += 1
        legs = np.radians(model.leg_angles)
        if min(min(abs(oracles.wrap(b32[0] - leg)), math.pi - abs(oracles.wrap(b32[0] - leg))) for leg in legs) \
                < math.radians(model.leg_half_width) + 5 * DEG:
            near["legs"] += 1
    print(f"\n{check}: {sum(accepted.values())} of {n_moves} moves accepted (by joints turning: {accepted}; "
          f"ending within 5 mm of the body plane: {near['body']}, within 5 deg of a leg sector: {near['legs']}), "
          f"{sampled:,} poses sampled in their boxes, all clear")
    assert min(accepted.values()) > 300 and min(near.values()) > 100


@pytest.mark.parametrize("what", ["body", "legs"])
def test_swept_bound_against_the_model_at_40_digits(model, gen, what):
    """The C's verdicts on random boxes equal the model's bound (model/swept.py) evaluated at
    40 digits, where that bound is not within 1e-3 of its threshold."""
    ffi, lib = gen
    body, legs = swept.box_clear(model)
    cond = body if what == "body" else legs
    f = sp.lambdify(swept.CENTRE + swept.HALF, cond, modules="mpmath")
    margin_expr = [rel.lhs - rel.rhs for rel in cond.atoms(sp.StrictLessThan)]
    margins = sp.lambdify(swept.CENTRE + swept.HALF, margin_expr, modules="mpmath")
    mp.mp.dps = 40
    rng = np.random.default_rng(RNG_SEED + 9)
    lo, hi = limits(model)
    compared = 0
    for a, b in near_boundary_boxes(model, rng, 1500):
        if not (np.all(np.minimum(a, b) >= lo) and np.all(np.maximum(a, b) <= hi)):
            continue
        c = b                                               # the box about the new goal
        h = np.abs(b - a) + 1e-6                            # the C's slack
        args = [mp.mpf(v) for v in np.concatenate([c, h])]
        if min(abs(float(v)) for v in margins(*args)) < 1e-3:
            continue
        near_zone = min(abs(abs(c[0] - leg) - math.radians(model.leg_half_width) - h[0])
                        for leg in np.radians(model.leg_angles) for leg in (leg, leg - 2 * math.pi, leg + 2 * math.pi))
        if what == "legs" and near_zone < 1e-5:
            continue
        got = check_swept(gen, a, b)
        want_ok = bool(f(*args))
        if what == "body":
            assert (got != lib.KIN_BODY) == want_ok, (a, b, got)
        elif got != lib.KIN_BODY:
            assert (got != lib.KIN_LEG) == want_ok, (a, b, got)
        compared += 1
    assert compared > 500
