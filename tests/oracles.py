"""Independent references for the tests: plain geometry, not the SymPy model or its C.

The arm as a person would describe it: joint 1 turns a vertical plane about the base
axis (its horizontal direction is (cos q1, -sin q1), as in the arm's DH table); in
that plane the upper arm hangs from the shoulder, L1 below the base origin, at angle q2
from straight down, and the forearm at q2 + q3.
"""
from __future__ import annotations

import math

import numpy as np

# How far (mm) an end effector the firmware holds at a point may be from it: 1.5 units
# (0.44 deg) per joint at ~140 mm reach, the goal rounded to a unit and a lagging shaft
# stopped within its compliance margin (a unit) of the goal.
FK_TOL_MM = 2.0


def _arm_xyz(m, q):
    """The elbow's and the end effector's x, y, z (each of shape q.shape[:-1]): the arm's
    plane direction h = (cos q1, -sin q1, 0) and straight down, one component at a time
    (the same arithmetic as whole vectors, without their temporaries)."""
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    hx, hy = np.cos(q1), -np.sin(q1)
    s2, c2 = np.sin(q2), np.cos(q2)
    s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
    elbow = (m.L2 * (s2 * hx), m.L2 * (s2 * hy), -m.L1 + m.L2 * -c2)
    ee = (elbow[0] + m.L3 * (s23 * hx), elbow[1] + m.L3 * (s23 * hy), elbow[2] + m.L3 * -c23)
    return elbow, ee


def arm_points(m, q):
    """(shoulder, elbow, end effector) as numpy arrays, for q of shape (..., 3)."""
    q = np.asarray(q, dtype=np.float64)
    elbow, ee = _arm_xyz(m, q)
    shoulder = np.broadcast_to(m.L1 * np.array([0.0, 0.0, -1.0]), q.shape)
    return shoulder, np.stack(elbow, axis=-1), np.stack(ee, axis=-1)


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
    elbow, ee = _arm_xyz(m, q)
    status = np.zeros(len(q), dtype=int)

    in_limits = np.ones(len(q), dtype=bool)
    clear = np.ones(len(q), dtype=bool)
    for j, lim in enumerate(m.limits):         # (a joint at a time: contiguous columns)
        qj, lo, hi = np.ascontiguousarray(q[:, j]), math.radians(lim.min_deg), math.radians(lim.max_deg)
        in_limits &= (qj >= lo) & (qj <= hi)
        clear &= np.minimum(np.abs(qj - lo), np.abs(qj - hi)) > margin

    below = (ee[2] < m.body_z) & (elbow[2] < m.body_z)
    # (each quantity is judged only where it decides: elsewhere it leaves `clear` as it is)
    out_of_limits = ~in_limits
    for zz in (ee[2], elbow[2]):
        clear &= out_of_limits | (np.abs(zz - m.body_z) > margin)

    # the arm's vertical plane near a leg (legs 180 deg apart block the same plane)
    hw = math.radians(m.leg_half_width)
    near = np.zeros(len(q), dtype=bool)
    not_below = out_of_limits | ~below
    q1 = np.ascontiguousarray(q[:, 0])
    for a in np.radians(m.leg_angles):
        d = np.mod(q1 - a, math.pi)
        dist = np.minimum(d, math.pi - d)
        near |= dist <= hw
        clear &= not_below | (np.abs(dist - hw) > margin)
    ee_rho, el_rho = np.hypot(ee[0], ee[1]), np.hypot(elbow[0], elbow[1])
    hits_leg = near & ((ee_rho >= m.leg_distance) | (el_rho >= m.leg_distance))
    not_near = not_below | ~near
    for rr in (ee_rho, el_rho):
        clear &= not_near | (np.abs(rr - m.leg_distance) > margin)

    status[~in_limits] = 2
    status[in_limits & ~below] = 3
    status[in_limits & below & hits_leg] = 4
    return status, clear


def reach_limits(m, elbow):
    """(smallest, largest) shoulder distance of the elbow sign `elbow` on a followed branch:
    the law of cosines at joint 3's limit, and full stretch less the model's margin."""
    lim = m.limits[2]
    far = math.radians(min(lim.max_deg, 180.0) if elbow > 0 else min(-lim.min_deg, 180.0))
    r_min = math.sqrt(m.L2**2 + m.L3**2 + 2 * m.L2 * m.L3 * math.cos(far))
    return r_min, m.L2 + m.L3 - m.motion.stretch_margin


def branch_ik(m, p, ref, elbow, hold):
    """The followed-branch IK as its contract states it (kinematics.h kin_ik_branch), by the
    law of cosines in float64: joint 1 in the plane toward or away from the target, whichever
    is nearer ref[0] (or at ref[0] with hold), stopped at its limits; the target projected
    onto that plane; its shoulder distance clamped into the elbow's reach; joint 2 continued
    from ref[1] (never more than half a turn from it) and stopped at its limits. Returns (q, reach_clamped, q1_clamped, q2_clamped)."""
    x, y, z = p
    lo = [math.radians(l.min_deg) for l in m.limits]
    hi = [math.radians(l.max_deg) for l in m.limits]
    q1, q1_clamped = ref[0], False
    if not hold:
        toward = math.atan2(-y, x)
        turn = float(wrap(toward - ref[0]))
        if abs(turn) > math.pi / 2:
            turn -= math.copysign(math.pi, turn)
        q1 = ref[0] + turn
        if not lo[0] <= q1 <= hi[0]:
            q1, q1_clamped = min(max(q1, lo[0]), hi[0]), True
    u = x * math.cos(q1) - y * math.sin(q1)
    v = -(z + m.L1)
    r = math.hypot(u, v)
    r_min, r_max = reach_limits(m, elbow)
    rc = min(max(r, r_min), r_max)
    beta = math.acos(min(1.0, max(-1.0, (m.L2**2 + m.L3**2 - rc**2) / (2 * m.L2 * m.L3))))
    gamma = math.acos(min(1.0, max(-1.0, (rc**2 + m.L2**2 - m.L3**2) / (2 * rc * m.L2))))
    q3 = elbow * (math.pi - beta)
    q2 = float(wrap(math.atan2(u, v) - elbow * gamma))
    q2 = ref[1] + float(wrap(q2 - ref[1]))     # continued from ref[1]
    q2_clamped = not lo[1] <= q2 <= hi[1]
    q2 = min(max(q2, lo[1]), hi[1])
    q3 = min(max(q3, lo[2]), hi[2])
    return np.array([q1, q2, q3]), not r_min <= r <= r_max, q1_clamped, q2_clamped


def servo_path(a, b, samples=9):
    """Poses a servo set passes through from joint vector a to b when every joint turns at
    the same speed and stops on arrival (each at its own time): the joint with the longest
    way sets the duration, the others stop early. `samples` evenly spaced instants, shape
    (samples, 3), or (N, samples, 3) for a and b of shape (N, 3)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = b - a
    way = np.abs(d).max(axis=-1, keepdims=True)[..., None, :]        # (..., 1, 1)
    t = np.linspace(0.0, 1.0, samples)[:, None] * way                  # (..., samples, 1)
    return a[..., None, :] + np.sign(d)[..., None, :] * np.minimum(t, np.abs(d)[..., None, :])


def clear_by(m, q, mm, rad):
    """Poses q (N, 3) at least `mm` below the body plane and inside the leg distance wherever
    joint 1 is within leg_half_width + `rad` of a leg, and `rad` inside every limit."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    elbow, ee = _arm_xyz(m, q)
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    ok = np.all((q > lo + rad) & (q < hi - rad), axis=1)
    ok &= (ee[2] < m.body_z - mm) & (elbow[2] < m.body_z - mm)
    near = np.zeros(len(q), dtype=bool)
    for leg in np.radians(m.leg_angles):
        d = np.mod(q[:, 0] - leg, math.pi)
        near |= np.minimum(d, math.pi - d) <= math.radians(m.leg_half_width) + rad
    reach = np.maximum(np.hypot(ee[0], ee[1]), np.hypot(elbow[0], elbow[1]))
    return ok & (~near | (reach < m.leg_distance - mm))


def clearance_mm(m, q):
    """How far (mm) poses q (N, 3) stand clear of the body plane and, where joint 1 is within a
    leg's half width, of the leg distance: the least of the elbow's and the end effector's
    distances to those boundaries (negative: inside)."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    elbow, ee = _arm_xyz(m, q)
    clear = np.minimum(m.body_z - elbow[2], m.body_z - ee[2])
    near = np.zeros(len(q), dtype=bool)
    q1 = np.ascontiguousarray(q[:, 0])
    for a in np.radians(m.leg_angles):
        d = np.mod(q1 - a, math.pi)
        near |= np.minimum(d, math.pi - d) <= math.radians(m.leg_half_width)
    reach = np.maximum(np.hypot(ee[0], ee[1]), np.hypot(elbow[0], elbow[1]))
    return np.where(near, np.minimum(clear, m.leg_distance - reach), clear)
