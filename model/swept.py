"""Is every pose between two goals safe? The swept check.

Between two consecutive goals each servo turns its joint from the old angle to the new one
at its own speed, arriving at its own time. Whatever the timing, every pose on the way lies
in the box of joint vectors the two goals span, and so in the box about the new goal b that
reaches back to the old one: centre c = b, half-widths h = |b - a| (the firmware's check
shares its sines and cosines with the goal it is about to command). The box is safe when:

  * both goals are inside the joint limits (the limits are a box too);
  * every collision quantity of fk_in_plane stays on its safe side over the whole box.
    Each is bounded by Taylor's theorem about the centre:
        f(c + d) <= f(c) + sum_i |df/dq_i(c)| h_i + 1/2 sum_ij M_ij h_i h_j,
    with M_ij a bound of |d2f/dq_i dq_j| over all angles: every term of those derivatives
    is a length times a product of sines and cosines, so the sum of the lengths bounds it;
  * near a leg (joint 1's interval within leg_half_width of a leg), both reaches' bounds
    stay inside the leg distance.

For a box of zero width this is exactly the pose check of model/collision.py; the bound's
slack grows with the square of the box's size (0.7 mm for a 3.5 deg step of every joint).
"""
from __future__ import annotations

import sympy as sp

from . import collision, kinematics
from .config import Model

CENTRE = sp.symbols("c1:4", real=True)
HALF = sp.symbols("h1:4", nonnegative=True)


def amplitude(expr: sp.Expr) -> sp.Expr:
    """A bound of |expr| over all angles: the sum of its terms' |coefficients|, each term a
    constant times sines and cosines."""
    total = sp.Integer(0)
    for term in sp.Add.make_args(sp.expand(expr)):
        coeff, rest = term.as_coeff_Mul()
        for factor in sp.Mul.make_args(rest):
            base = factor.as_base_exp()[0]
            if not isinstance(base, (sp.sin, sp.cos)) and factor != 1:
                raise ValueError(f"not a sum of trigonometric products: {expr}")
        total += abs(coeff)
    return total


def upper_bound(expr: sp.Expr, q=kinematics.JOINT_SYMBOLS, abs_value: bool = False) -> sp.Expr:
    """An upper bound of expr (of |expr| with abs_value) over the box CENTRE +- HALF."""
    at_centre = dict(zip(q, CENTRE))
    value = expr.subs(at_centre)
    bound = sp.Abs(value) if abs_value else value
    for qi, hi in zip(q, HALF):
        bound += sp.Abs(sp.diff(expr, qi).subs(at_centre)) * hi
    for i, (qi, hi) in enumerate(zip(q, HALF)):
        for j, (qj, hj) in enumerate(zip(q, HALF)):
            m_ij = amplitude(sp.diff(expr, qi, qj))
            if m_ij != 0:
                bound += sp.Rational(1, 2) * m_ij * hi * hj
    return bound


def box_geometry(m: Model) -> collision.Geometry:
    """The collision quantities' worst values over the box: the heights' and the reaches'
    upper bounds (scale 1), joint 1 at the box's centre (its half-width widens the legs)."""
    # the heights with sums of angles kept whole: expanded, each product counts apart
    j3_u, j3_z, ee_u, ee_z = (sp.trigsimp(e) for e in kinematics.fk_in_plane(m))
    c1 = CENTRE[0]
    return collision.Geometry(
        cos_q1=sp.cos(c1), sin_q1=sp.sin(c1), angle_scale=sp.Integer(1),
        ee_rho=upper_bound(ee_u, abs_value=True), ee_z=upper_bound(ee_z),
        j3_rho=upper_bound(j3_u, abs_value=True), j3_z=upper_bound(j3_z), j3_scale=sp.Integer(1), q1=c1,
    )


def box_clear(m: Model) -> tuple[sp.Boolean, sp.Boolean]:
    """(below the body, clear of the legs) for every pose in the box; the joint limits are
    checked on the two goals themselves."""
    g = box_geometry(m)
    return collision.body_clear(m, g), collision.legs_clear(m, g, widen=HALF[0])
