"""Joint vectors concentrated near every boundary of the safe set, by plain geometry: the
joint limits, the body plane (end effector and joint 3), the edges of the legs' sectors and
the leg distance. Each family puts one quantity a random distance from its boundary, on
either side: log-uniformly distributed between 3e-4 and 2 (rad or mm, as the quantity's
unit), so most points sit closer than any grid spacing and none on a grid; the other
joints are uniform over (and a little past) their travel. Seeded: the same seed gives the
same points.
"""
from __future__ import annotations

import math

import numpy as np

OFFSET_DECADES = (-3.5, 0.3)


def offsets(rng: np.random.Generator, n: int) -> np.ndarray:
    """Signed distances from a boundary, log-uniform in magnitude."""
    mag = 10.0 ** rng.uniform(*OFFSET_DECADES, n)
    return mag * rng.choice([-1.0, 1.0], n)


def _uniform_joints(rng, m, n, past=0.1):
    lo = np.radians([l.min_deg for l in m.limits]) - past
    hi = np.radians([l.max_deg for l in m.limits]) + past
    return rng.uniform(lo, hi, (n, 3))


def near_limits(rng, m, n):
    """One joint at one of its limits, plus an offset."""
    q = _uniform_joints(rng, m, n)
    joint = rng.integers(0, 3, n)
    ends = np.array([[math.radians(l.min_deg), math.radians(l.max_deg)] for l in m.limits])
    q[np.arange(n), joint] = ends[joint, rng.integers(0, 2, n)] + offsets(rng, n)
    return q


def _solve_forearm(rng, m, q, target, fn):
    """q3 such that fn(q2 + q3) = target for each row (the forearm's angle from straight
    down), where reachable: either solution; NaN rows where not."""
    with np.errstate(invalid="ignore"):
        a = np.arcsin(target) if fn == "sin" else np.arccos(target)
    other = (math.pi - a) if fn == "sin" else -a
    a = np.where(rng.integers(0, 2, len(q)) == 1, a, other)
    q3 = np.mod(a - q[:, 1] + math.pi, 2 * math.pi) - math.pi
    return q3


def _mostly_inside_limits(m, q):
    """The rows inside the travel limits, and one in ten of the others (the limits have
    their own family)."""
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    inside = np.all((q >= lo) & (q <= hi), axis=1)
    return q[inside | (np.arange(len(q)) % 10 == 0)]


def near_body(rng, m, n):
    """The end effector's or joint 3's height at the body plane, plus an offset (mm)."""
    q = _uniform_joints(rng, m, n)
    dz = offsets(rng, n)
    elbow = rng.integers(0, 2, n) == 1
    # joint 3: z = -L1 - L2 cos q2
    with np.errstate(invalid="ignore"):
        q2 = np.arccos(-(m.body_z + dz + m.L1) / m.L2) * rng.choice([-1.0, 1.0], n)
    q[elbow, 1] = q2[elbow]
    # end effector: z = -L1 - L2 cos q2 - L3 cos(q2 + q3)
    c = -(m.body_z + dz + m.L1 + m.L2 * np.cos(q[:, 1])) / m.L3
    q3 = _solve_forearm(rng, m, q, c, "cos")
    q[~elbow, 2] = q3[~elbow]
    return _mostly_inside_limits(m, q[np.isfinite(q).all(axis=1)])


def near_leg_sectors(rng, m, n):
    """Joint 1 at an edge of a leg's sector (either way round, the plane's both faces), plus
    an offset (rad); the arm reaching beyond the leg distance half of the time."""
    q = _uniform_joints(rng, m, n)
    legs = np.radians(m.leg_angles)
    hw = math.radians(m.leg_half_width)
    centre = legs[rng.integers(0, len(legs), n)] + rng.choice([0.0, math.pi, -math.pi], n)
    q[:, 0] = centre + rng.choice([-hw, hw], n) + offsets(rng, n)
    q[:, 0] = np.mod(q[:, 0] + math.pi, 2 * math.pi) - math.pi
    return q


def near_leg_distance(rng, m, n):
    """The end effector's horizontal distance from the base axis at the leg distance, plus
    an offset (mm); joint 1 inside a leg's sector half of the time."""
    q = near_leg_sectors(rng, m, n)
    inside = rng.integers(0, 2, n) == 1
    legs = np.radians(m.leg_angles)
    q[inside, 0] = legs[rng.integers(0, len(legs), inside.sum())] + rng.uniform(-1, 1, inside.sum()) * math.radians(
        m.leg_half_width)
    # signed horizontal reach in the arm's plane: L2 sin q2 + L3 sin(q2 + q3)
    r = (m.leg_distance + offsets(rng, n)) * rng.choice([-1.0, 1.0], n)
    s = (r - m.L2 * np.sin(q[:, 1])) / m.L3
    q[:, 2] = _solve_forearm(rng, m, q, s, "sin")
    return _mostly_inside_limits(m, q[np.isfinite(q).all(axis=1)])


FAMILIES = {"limits": near_limits, "body": near_body, "leg sectors": near_leg_sectors,
            "leg distance": near_leg_distance}
