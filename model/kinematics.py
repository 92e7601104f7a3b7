"""Kinematics of the RRR arm, written once in SymPy.

Forward kinematics is the arm's Denavit-Hartenberg chain. The closed-form inverse
kinematics uses the same geometry seen in the arm's vertical plane:

  * joint 1 turns that plane; in it, a point sits at signed horizontal distance `u`
    from the base axis and at depth `v` below the shoulder (joint 2);
  * joint 2 and joint 3 are a planar two-link chain: u = L2 s2 + L3 s23,
    v = L2 c2 + L3 c23 (angles measured from straight down).

Four candidates: the plane turned toward the target (u = +rho) or away from it, reaching
back over (u = -rho), each with the elbow on either side (theta3 >= 0 or <= 0).

The IK avoids acos/asin entirely: sin and cos of theta2 and theta3 come straight from the
triangle as polynomials of the target, so no angle needs a second trig call and an
unreachable target can be clamped (disc < 0) and flagged instead of producing NaN.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from . import collision
from .config import Model

q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
x, y, z = sp.symbols("x y z", real=True)
JOINT_SYMBOLS = (q1, q2, q3)
TARGET_SYMBOLS = (x, y, z)

# Candidate order: (plane toward target?, elbow sign of theta3)
CANDIDATES = ((True, +1), (True, -1), (False, +1), (False, -1))


def dh_transform(theta, alpha, r, d) -> sp.Matrix:
    """Standard DH transform Rz(theta) Tz(d) Tx(r) Rx(alpha)."""
    ct, st, ca, sa = sp.cos(theta), sp.sin(theta), sp.cos(alpha), sp.sin(alpha)
    return sp.Matrix([
        [ct, -st * ca, st * sa, r * ct],
        [st, ct * ca, -ct * sa, r * st],
        [0, sa, ca, d],
        [0, 0, 0, 1],
    ])


def dh_rows(m: Model):
    L1, L2, L3 = (sp.nsimplify(v, rational=True) for v in (m.L1, m.L2, m.L3))
    return (
        (-q1, sp.pi / 2, 0, -L1),
        (-sp.pi / 2 + q2, 0, L2, 0),
        (q3, 0, L3, 0),
    )


def fk_points(m: Model, at=None) -> tuple[sp.Matrix, sp.Matrix]:
    """(joint 3 position, end-effector position) in the base frame, from the DH chain: as
    expressions of (q1, q2, q3), or at the joint values `at` (numbers, substituted first, so
    nothing is left to simplify)."""
    rows = dh_rows(m)
    if at is not None:
        values = dict(zip(JOINT_SYMBOLS, at))
        rows = [[sp.sympify(e).subs(values) for e in row] for row in rows]
    t1, t2, t3 = (dh_transform(*row) for row in rows)
    origin = sp.Matrix([0, 0, 0, 1])
    j3 = (t1 * t2 * origin)[:3, 0]
    ee = (t1 * t2 * t3 * origin)[:3, 0]
    if at is not None:
        return j3, ee
    simplify = lambda v: sp.Matrix([sp.expand_trig(sp.trigsimp(e)) for e in v])
    return simplify(j3), simplify(ee)


@dataclass(frozen=True)
class IkCandidate:
    toward: bool          # plane turned toward the target (u = +rho) or away from it
    elbow: int            # +1: theta3 >= 0, -1: theta3 <= 0
    q: tuple              # (theta1, theta2, theta3) as expressions of x, y, z
    geometry: collision.Geometry


@dataclass(frozen=True)
class IkModel:
    rho: sp.Expr          # horizontal distance of the target from the base axis
    disc: sp.Expr         # >= 0 exactly when the target is within the two-link reach
    candidates: tuple[IkCandidate, ...]


def ik(m: Model) -> IkModel:
    L1, L2, L3 = (sp.nsimplify(v, rational=True) for v in (m.L1, m.L2, m.L3))
    rho = sp.sqrt(x**2 + y**2)
    v = -(z + L1)                                  # depth of the target below the shoulder
    r2 = rho**2 + (z + L1)**2
    # cos and sin of theta3, both times 2 L2 L3; the sine's square is factored so it stays
    # accurate near full stretch, and clamped at 0 when the target is out of reach.
    disc = ((L2 + L3)**2 - r2) * (r2 - (L2 - L3)**2)
    c3 = r2 - L2**2 - L3**2
    s3 = sp.sqrt(sp.Max(disc, 0))
    theta1 = sp.atan2(-y, x)                       # plane turned toward the target: u = +rho
    # turned away, reaching back over: theta1 + pi, wrapped to (-pi, pi]
    theta1_away = sp.Piecewise((theta1 + sp.pi, theta1 <= 0), (theta1 - sp.pi, True))
    toward = {}
    for elbow in (+1, -1):
        # u = A s2 + B c2 and v = A c2 - B s2 with A = L2 + L3 cos(theta3), B = L3 sin(theta3),
        # so r^2 s2 = A u - B v and r^2 c2 = A v + B u. Both sides below are times 2 L2.
        a, b = 2 * L2**2 + c3, elbow * s3
        s2 = a * rho - b * v                       # sin(theta2) times 2 L2 r^2
        c2 = a * v + b * rho                       # cos(theta2) times 2 L2 r^2
        # joint 3 sits at in-plane distance L2 sin(theta2) and height -L1 - L2 cos(theta2)
        j3_rho, j3_z, scale = L2 * sp.Abs(s2), -L1 * 2 * L2 * r2 - L2 * c2, 2 * L2 * r2
        toward[elbow] = ((sp.atan2(s2, c2), elbow * sp.atan2(s3, c3)), (j3_rho, j3_z, scale))
    candidates = []
    for is_toward, elbow in CANDIDATES:
        if is_toward:
            (q2, q3), j3 = toward[elbow]
            q = (theta1, q2, q3)
        else:
            # the mirror image through the base axis of the other elbow's toward-solution
            (q2, q3), j3 = toward[-elbow]
            q = (theta1_away, -q2, -q3)
        sign = 1 if is_toward else -1
        geometry = collision.Geometry(
            cos_q1=sign * x, sin_q1=-sign * y, angle_scale=rho,   # cos, sin of theta1 times rho
            ee_rho=rho, ee_z=z, j3_rho=j3[0], j3_z=j3[1], j3_scale=j3[2])
        candidates.append(IkCandidate(is_toward, elbow, q, geometry))
    return IkModel(rho=rho, disc=disc, candidates=tuple(candidates))


def joint_limits_ok(m: Model, q) -> sp.Boolean:
    conds = []
    for qi, lim in zip(q, m.limits):
        # one comparison instead of two in the generated C; not for an atan2, as SymPy
        # rewrites |-atan2(a, b)| into a new atan2 that CSE would not share with the angle
        if lim.min_deg == -lim.max_deg and not sp.sympify(qi).has(sp.atan2):
            conds.append(sp.Abs(qi) <= sp.Float(lim.max_rad, 30))
        else:
            conds += [qi >= sp.Float(lim.min_rad, 30), qi <= sp.Float(lim.max_rad, 30)]
    return sp.And(*conds)


def fk_in_plane(m: Model, at=None) -> tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr]:
    """(joint 3's signed in-plane distance from the base axis, its height, the end effector's
    likewise): the arm's vertical plane seen from the side, u along (cos q1, -sin q1)."""
    j3, ee = fk_points(m, at)
    a1 = q1 if at is None else at[0]
    tidy = sp.trigsimp if at is None else (lambda e: e)
    in_plane = lambda p: tidy(p[0] * sp.cos(a1) - p[1] * sp.sin(a1))
    return in_plane(j3), j3[2], in_plane(ee), ee[2]


def fk_geometry(m: Model, at=None) -> collision.Geometry:
    """Collision quantities of the joint vector (q1, q2, q3), for the joint-space check; at
    the joint values `at` if given (what check_park needs: the same quantities without
    the symbolic simplification, a hundred times faster)."""
    j3_u, j3_z, ee_u, ee_z = fk_in_plane(m, at)
    a1 = q1 if at is None else at[0]
    return collision.Geometry(
        cos_q1=sp.cos(a1), sin_q1=sp.sin(a1), angle_scale=sp.Integer(1),
        ee_rho=sp.Abs(ee_u), ee_z=ee_z,
        j3_rho=sp.Abs(j3_u), j3_z=j3_z, j3_scale=sp.Integer(1), q1=a1,
    )


# ---------------------------------------------------------------- one branch, followed

U = sp.Symbol("u", real=True)          # signed distance of the target from joint 1's axis, in its plane
ELBOW = sp.Symbol("elbow", real=True)  # +1 or -1: the sign of theta3 on the branch followed
R2 = sp.Symbol("r2c", positive=True)   # squared shoulder distance the elbow is set for


@dataclass(frozen=True)
class BranchIk:
    """The IK on one branch, for a target that moves (model/motion keys).

    In the plane of joint 1 at angle q1 a point sits at signed distance u from the base
    axis (u = +rho in the plane turned toward it, -rho in the plane turned away, anything
    in between in a plane held still) and at depth v below the shoulder. The elbow sign is
    kept, so one formula covers both planes: the away candidates of ik() are this with
    u = -rho. The elbow angle is set for r2c, the squared shoulder distance clamped into
    what the elbow reaches (r2_min..r2_max of that elbow sign), while theta2 still points
    along (u, v): a target out of reach gives the nearest point of the reachable shell,
    radially about the shoulder.
    """
    azimuth: sp.Expr        # theta1 of the plane turned toward the target
    rho: sp.Expr            # the target's distance from the base axis
    in_plane: sp.Expr       # u of the target in the plane of joint 1 at angle q1
    r2: sp.Expr             # u^2 + v^2 (a function of U and z)
    q2: sp.Expr             # of U, z, ELBOW, R2
    q3: sp.Expr             # of ELBOW, R2
    r2_min: dict            # elbow sign -> squared shoulder distance at joint 3's limit
    r2_max: dict            # elbow sign -> ... at the straightest elbow allowed


def reach_r2(m: Model) -> tuple[dict, dict]:
    """Per elbow sign, the smallest and largest squared shoulder distance joint 3 allows:
    r^2 = L2^2 + L3^2 + 2 L2 L3 cos(theta3) falls as |theta3| grows, and the arm stops
    motion.stretch_margin short of full stretch, where the elbow angle would swing a lot for
    a tiny change of reach."""
    L2, L3 = (sp.nsimplify(v, rational=True) for v in (m.L2, m.L3))
    lim = m.limits[2]
    r2_of = lambda deg: L2**2 + L3**2 + 2 * L2 * L3 * sp.cos(sp.rad(sp.nsimplify(deg, rational=True)))
    stretch = (L2 + L3 - sp.nsimplify(m.motion.stretch_margin, rational=True))**2
    lo, hi = {}, {}
    for elbow, (near, far) in ((1, (max(lim.min_deg, 0.0), lim.max_deg)), (-1, (max(-lim.max_deg, 0.0), -lim.min_deg))):
        far = max(min(far, 180.0), near)
        lo[elbow] = r2_of(far)
        hi[elbow] = sp.Max(sp.Min(r2_of(near), stretch), lo[elbow])
    return lo, hi


def branch_ik(m: Model) -> BranchIk:
    L1, L2, L3 = (sp.nsimplify(v, rational=True) for v in (m.L1, m.L2, m.L3))
    v = -(z + L1)
    c3 = R2 - L2**2 - L3**2                        # cos(theta3) times 2 L2 L3
    s3 = sp.sqrt(sp.Max(((L2 + L3)**2 - R2) * (R2 - (L2 - L3)**2), 0))
    a, b = 2 * L2**2 + c3, ELBOW * s3              # as in ik(): (u, v) turned by theta3's triangle
    lo, hi = reach_r2(m)
    return BranchIk(
        azimuth=sp.atan2(-y, x),
        rho=sp.sqrt(x**2 + y**2),
        in_plane=x * sp.cos(q1) - y * sp.sin(q1),
        r2=U**2 + v**2,
        q2=sp.atan2(a * U - b * v, a * v + b * U),
        q3=ELBOW * sp.atan2(s3, c3),
        r2_min=lo, r2_max=hi,
    )
