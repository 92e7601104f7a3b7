"""How close a pose comes to the body plane and the legs when the joints are off by up to the
servos' zero tolerance: the clearance the arm really has if its calibration is as good as a
careful user leaves it, not only if it is exact.

The box of joint vectors (each joint within +-tolerance of the pose) is cut into CELLS x CELLS
cells over joints 2 and 3; in each, joint 3's and the end effector's height and distance from
the base axis are bounded by interval arithmetic on sin and cos (exact extremes of each over an
angle interval). Every joint vector of the box lies in a cell, so the least clearance found is a
lower bound of the true one (provably conservative), and a cell's width keeps it within about
a millimetre of it. Joint 1 only decides whether the arm's plane may meet a leg, which is
decided exactly for the whole interval. Plain float64 trigonometry: its rounding (1e-13 mm) is
far below ROUNDING_MM, the margin the verdict keeps. (model/swept.py bounds boxes too, in
SymPy for the generated C; the loader wants its verdict in a millisecond, on every load.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CELLS = 48              # per joint: 0.125 deg cells at 3 deg, bound within ~0.5 mm of the truth
ROUNDING_MM = 1e-9      # a clearance must exceed this to count (float64 rounding)
PARTS = ("joint 3", "the end effector")


@dataclass(frozen=True)
class Clearance:
    mm: float                                   # least clearance over the box (negative: inside)
    part: str                                   # "joint 3" or "the end effector"
    boundary: str                               # "body plane" or "leg distance"
    offsets_deg: tuple[float, float, float]     # where in the box (joint errors, deg)

    @property
    def clear(self) -> bool:
        return self.mm > ROUNDING_MM


def _contains(a, b, c):
    """Whether [a, b] contains c + 2 pi k for some integer k."""
    return np.ceil((a - c) / (2 * math.pi)) * (2 * math.pi) + c <= b


def _cos_lo(a, b):
    return np.where(_contains(a, b, math.pi), -1.0, np.minimum(np.cos(a), np.cos(b)))


def _sin_range(a, b):
    lo = np.where(_contains(a, b, -math.pi / 2), -1.0, np.minimum(np.sin(a), np.sin(b)))
    hi = np.where(_contains(a, b, math.pi / 2), 1.0, np.maximum(np.sin(a), np.sin(b)))
    return lo, hi


def _leg_offset(m, q1_deg: float, tol_deg: float) -> float | None:
    """An error of joint 1 within the tolerance that puts the arm's plane within
    leg_half_width of a leg (legs 180 deg apart block the same plane), or None."""
    best = None
    for a in m.leg_angles:
        for k in range(-3, 4):
            centre = a + 180.0 * k
            # the offset nearest 0 within [-tol, tol] that lands within hw of centre
            lo, hi = centre - m.leg_half_width - q1_deg, centre + m.leg_half_width - q1_deg
            lo, hi = max(lo, -tol_deg), min(hi, tol_deg)
            if lo <= hi:
                offset = min(max(0.0, lo), hi)
                best = offset if best is None or abs(offset) < abs(best) else best
    return best


def least(m, q_deg, tol_deg: float, any_q1: bool = False) -> Clearance:
    """The least clearance of joint 3 and the end effector from the body plane (and, where
    the arm's plane may meet a leg, or at any joint 1 angle if any_q1, from the leg distance)
    over every joint vector within tol_deg of q_deg: a lower bound (see the module's note)."""
    q1, q2, q3 = (float(v) for v in q_deg)
    edges = np.linspace(-tol_deg, tol_deg, CELLS + 1) if tol_deg > 0 else np.zeros(2)
    e2, e3 = np.meshgrid(edges, edges, indexing="ij")
    lo2, hi2 = np.radians(q2 + e2[:-1, :-1]), np.radians(q2 + e2[1:, 1:])
    lo3, hi3 = np.radians(q3 + e3[:-1, :-1]), np.radians(q3 + e3[1:, 1:])
    lo23, hi23 = lo2 + lo3, hi2 + hi3                 # the forearm's angle from straight down
    L1, L2, L3 = m.L1, m.L2, m.L3
    j3_z = -L1 - L2 * _cos_lo(lo2, hi2)
    ee_z = j3_z - L3 * _cos_lo(lo23, hi23)
    s2_lo, s2_hi = _sin_range(lo2, hi2)
    s23_lo, s23_hi = _sin_range(lo23, hi23)
    j3_rho = L2 * np.maximum(np.abs(s2_lo), np.abs(s2_hi))
    ee_rho = np.maximum(np.abs(L2 * s2_lo + L3 * s23_lo), np.abs(L2 * s2_hi + L3 * s23_hi))
    # a cell is named by its corner farther from the pose (the worst is on the box's edge)
    outer = np.where(np.abs(edges[:-1]) > np.abs(edges[1:]), edges[:-1], edges[1:])
    leg_q1 = 0.0 if any_q1 else _leg_offset(m, q1, tol_deg)
    worst = None
    for part, z, rho in zip(PARTS, (j3_z, ee_z), (j3_rho, ee_rho)):
        checks = [(m.body_z - z, "body plane", 0.0)]
        if leg_q1 is not None:
            checks.append((m.leg_distance - rho, "leg distance", leg_q1))
        for grid, boundary, off1 in checks:
            i, j = np.unravel_index(np.argmin(grid), grid.shape)
            if worst is None or grid[i, j] < worst.mm:
                off3 = float(outer[j]) if part == PARTS[1] else 0.0     # (joint 3 does not move itself)
                worst = Clearance(float(grid[i, j]), part, boundary, (off1, float(outer[i]), off3))
    return worst


def tuck_deg(m, tol_deg: float) -> tuple[float, float] | None:
    """Joints 2 and 3 (deg) of the pose in which the arm turns joint 1 to go round a leg: the
    park pose's if, within the tolerance, they keep the end effector and joint 3 inside the
    leg distance and below the body at every joint 1 angle, else hanging straight down if
    that does; None if neither."""
    for q23 in (tuple(m.park_deg[1:]), (0.0, 0.0)):
        inside = all(m.limits[j + 1].min_deg <= d <= m.limits[j + 1].max_deg for j, d in enumerate(q23))
        if inside and least(m, (0.0, *q23), tol_deg, any_q1=True).clear:
            return q23
    return None
