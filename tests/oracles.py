"""Independent references for the tests: plain geometry, not the SymPy model or its C.

The arm as a person would describe it: joint 1 turns a vertical plane about the base
axis (its horizontal direction is (cos q1, -sin q1), as in the DH table of SPEC.md); in
that plane the upper arm hangs from the shoulder, L1 below the base origin, at angle q2
from straight down, and the forearm at q2 + q3.
"""
from __future__ import annotations

import math

import numpy as np


def arm_points(m, q):
    """(shoulder, elbow, end effector) as numpy arrays, for q of shape (..., 3)."""
    q = np.asarray(q, dtype=np.float64)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    h = np.stack([np.cos(q1), -np.sin(q1), np.zeros_like(q1)], axis=-1)
    down = np.array([0.0, 0.0, -1.0])
    shoulder = np.broadcast_to(m.L1 * down, h.shape)
    elbow = shoulder + m.L2 * (np.sin(q2)[..., None] * h + np.cos(q2)[..., None] * down)
    ee = elbow + m.L3 * (np.sin(q2 + q3)[..., None] * h + np.cos(q2 + q3)[..., None] * down)
    return shoulder, elbow, ee


def wrap(a):
    """Angle wrapped to (-pi, pi]."""
    a = np.mod(np.asarray(a) + np.pi, 2 * np.pi) - np.pi
    return np.where(a <= -np.pi, a + 2 * np.pi, a)


def textbook_ik(m, p):
    """The thesis's IK (eqs. 3.8-3.11, errata 4-5 applied), float64, all four solutions.

    Returns q of shape (N, 4, 3) in the order (toward, elbow +), (toward, -), (away, +),
    (away, -), and a mask of which exist (NaN where acos is out of its domain).
    """
    p = np.atleast_2d(np.asarray(p, dtype=np.float64))
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    out = np.empty((len(p), 4, 3))
    rho = np.hypot(x, y)
    t1 = np.arctan2(-y, x)
    with np.errstate(invalid="ignore"):
        for i, (toward, elbow) in enumerate([(True, 1), (True, -1), (False, 1), (False, -1)]):
            u = rho if toward else -rho               # signed in-plane distance
            v = -(z + m.L1)                           # depth below the shoulder
            r = np.hypot(u, v)
            gamma = np.arccos((r**2 + m.L2**2 - m.L3**2) / (2 * r * m.L2))   # at the shoulder
            beta = np.arccos((m.L2**2 + m.L3**2 - r**2) / (2 * m.L2 * m.L3))  # at the elbow
            q3 = elbow * (math.pi - beta)
            q2 = np.arctan2(u, v) - elbow * gamma
            out[:, i, 0] = t1 if toward else wrap(t1 + math.pi)
            out[:, i, 1] = wrap(q2)
            out[:, i, 2] = q3
    exists = ~np.isnan(out).any(axis=2)
    return out, exists


def check_pose(m, q, margin=0.0):
    """Status of joint vectors by plain geometry: 0 ok, 2 joint limit, 3 body, 4 leg.

    Also returns `clear`: False where any quantity lies within `margin` (mm or rad) of a
    decision boundary, so a float32 implementation may legitimately decide either way.
    """
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    _, elbow, ee = arm_points(m, q)
    status = np.zeros(len(q), dtype=int)
    clear = np.ones(len(q), dtype=bool)

    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    in_limits = np.all((q >= lo) & (q <= hi), axis=1)
    clear &= np.all(np.minimum(np.abs(q - lo), np.abs(q - hi)) > margin, axis=1)

    below = (ee[:, 2] < m.body_z) & (elbow[:, 2] < m.body_z)
    for zz in (ee[:, 2], elbow[:, 2]):
        clear &= np.where(in_limits, np.abs(zz - m.body_z) > margin, True)

    # the arm's vertical plane near a leg (legs 180 deg apart block the same plane)
    hw = math.radians(m.leg_half_width)
    near = np.zeros(len(q), dtype=bool)
    for a in np.radians(m.leg_angles):
        d = np.mod(q[:, 0] - a, math.pi)
        dist = np.minimum(d, math.pi - d)
        near |= dist <= hw
        clear &= np.where(in_limits & below, np.abs(dist - hw) > margin, True)
    ee_rho, el_rho = np.hypot(ee[:, 0], ee[:, 1]), np.hypot(elbow[:, 0], elbow[:, 1])
    hits_leg = near & ((ee_rho >= m.leg_distance) | (el_rho >= m.leg_distance))
    for rr in (ee_rho, el_rho):
        clear &= np.where(in_limits & below & near, np.abs(rr - m.leg_distance) > margin, True)

    status[~in_limits] = 2
    status[in_limits & ~below] = 3
    status[in_limits & below & hits_leg] = 4
    return status, clear
