"""Collision predicates (SPEC.md), written once for joint-space checks and for the IK.

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


def near_leg(m: Model, g: Geometry) -> sp.Boolean:
    """The arm's plane is within leg_half_width of a leg: |cos(theta1 - a)| >= cos(hw)."""
    cos_hw = sp.cos(sp.pi * sp.nsimplify(m.leg_half_width, rational=True) / 180).evalf(30)
    near = []
    for a in leg_planes(m):
        c, s = sp.cos(a).evalf(30), sp.sin(a).evalf(30)
        near.append(sp.Abs(g.cos_q1 * c + g.sin_q1 * s) >= cos_hw * g.angle_scale)
    return sp.Or(*near)


def inside_leg_distance(m: Model, g: Geometry) -> sp.Boolean:
    """End effector and joint 3 inside the leg distance: clear of the legs whichever way
    joint 1 turns."""
    d = sp.Float(m.leg_distance, 30)
    return sp.And(g.ee_rho < d, g.j3_rho < d * g.j3_scale)


def legs_clear(m: Model, g: Geometry) -> sp.Boolean:
    """Near a leg, both end effector and joint 3 must stay inside the leg distance."""
    return sp.Or(sp.Not(near_leg(m, g)), inside_leg_distance(m, g))
