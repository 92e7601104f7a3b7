"""Collision predicates of the arm, written once for joint-space checks and for the IK.

A pose is described by a `Geometry`: cos/sin of joint 1, and the horizontal distance from
the base axis (rho) and height (z) of joint 3 and of the end effector. Some quantities may
carry a positive scale factor, so the IK can state them without a division: a predicate
compares `a < b * scale` instead of `a / scale < b`.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .config import Model


@dataclass(frozen=True)
class Geometry:
    cos_q1: sp.Expr          # times angle_scale
    sin_q1: sp.Expr          # times angle_scale
    angle_scale: sp.Expr
    ee_rho: sp.Expr
    ee_z: sp.Expr
    j3_rho: sp.Expr          # times j3_scale
    j3_z: sp.Expr            # times j3_scale
    j3_scale: sp.Expr
    q1: sp.Expr | None = None  # joint 1's angle where known (joint space): no trigonometry for the legs


def body_clear(m: Model, g: Geometry) -> sp.Boolean:
    """End effector and joint 3 strictly below the drone's body plane."""
    body_z = sp.Float(m.body_z, 30)
    return sp.And(g.ee_z < body_z, g.j3_z < body_z * g.j3_scale)


def leg_planes(m: Model) -> tuple[sp.Expr, ...]:
    """Leg angles folded onto [0, 180) degrees, as exact angles in radians: the arm's
    vertical plane meets a leg whichever way it faces, so legs 180 deg apart block the
    same plane and are checked once."""
    folded = sorted({sp.nsimplify(a, rational=True) % 180 for a in m.leg_angles})
    return tuple(sp.pi * a / 180 for a in folded)


def near_leg(m: Model, g: Geometry, widen: sp.Expr = sp.Integer(0)) -> sp.Boolean:
    """The arm's plane is within leg_half_width of a leg: |cos(theta1 - a)| >= cos(hw).
    widen (rad, joint space only): for any joint 1 within that much of g.q1."""
    hw = sp.pi * sp.nsimplify(m.leg_half_width, rational=True) / 180
    if g.q1 is not None:
        return _near_leg_angle(m, g.q1, hw, widen)
    assert widen == 0, "a widened test needs joint 1's angle"
    cos_hw = sp.cos(hw).evalf(30)
    near = []
    for a in leg_planes(m):
        c, s = sp.cos(a).evalf(30), sp.sin(a).evalf(30)
        near.append(sp.Abs(g.cos_q1 * c + g.sin_q1 * s) >= cos_hw * g.angle_scale)
    return sp.Or(*near)


def _near_leg_angle(m: Model, q1: sp.Expr, hw: sp.Expr, widen: sp.Expr) -> sp.Boolean:
    """near_leg from the angle: for hw <= 90 deg, |cos(q1 - a)| >= cos(hw) exactly when q1 is
    within hw of a + k pi. For |q1| <= 180 deg (the joint limits' range) the k with a + k pi
    within hw of [-pi, pi] are enough (a widened test may reach one more: kept if within
    hw + pi of the range, as widen is at most pi there). Legs in mirror pairs (+-a) are tested
    on |q1|, half as many comparisons."""
    reach = hw + (sp.pi if widen != 0 else 0)
    centres = {a + k * sp.pi for a in leg_planes(m) for k in (-2, -1, 0, 1, 2)}
    centres = {c for c in centres if -sp.pi - reach <= c <= sp.pi + reach}
    angle = q1
    if all(-c in centres for c in centres):   # legs in mirror pairs: half the tests on |q1|
        angle, centres = sp.Abs(q1), {c for c in centres if c >= 0}
    return sp.Or(*(sp.Abs(angle - c.evalf(30)) <= hw.evalf(30) + widen for c in sorted(centres, key=float)))


def legs_clear(m: Model, g: Geometry, widen: sp.Expr = sp.Integer(0)) -> sp.Boolean:
    """Near a leg, both end effector and joint 3 must stay inside the leg distance."""
    d = sp.Float(m.leg_distance, 30)
    return sp.Or(sp.Not(near_leg(m, g, widen)), sp.And(g.ee_rho < d, g.j3_rho < d * g.j3_scale))
