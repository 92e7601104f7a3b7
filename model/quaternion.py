"""Quaternion attitude with gyro-bias estimation and acceleration rejection, the fusion of
the drone's own (delayed) attitude, and the commanded point with lead and mount offset.

Frames as in attitude.py: q is the unit quaternion (w, x, y, z) of R_WB, body (base) axes to
the level frame. Its yaw is the integrated gyro's and means nothing: only the tilt is used,
through the "up" direction in body axes

    u = R_WB^T e_z = (2(xz - wy), 2(yz + wx), w^2 - x^2 - y^2 + z^2) = (-sin p, sin r cos p, cos r cos p)

Step (one sample period dt, a Mahony-style PI observer):

    a = R_mount acc,  w_m = R_mount gyro               (base axes)
    e = a x u                                           the rotation that turns u toward a
    g = max(0, 1 - |a.a - 1| / (2 accel_tol)) / (1 + innovation_scale e.e)
    w = w_m - b + k_p g e
    q <- normalise(q (x) dq(w dt)),  dq(t) = (1 - |t|^2/8, t (1/2 - |t|^2/48))   (exp to 4th order)
    b <- clamp(b - k_i g e dt, +-bias_max)

The gate g refuses the accelerometer when its magnitude is not 1 g (any acceleration that
changes the thrust) and damps it when its direction disagrees with the gyro-propagated
estimate by more than the innovation angle (weight 1/2 there): in coordinated flight a multirotor's accelerometer reads body-z
thrust whatever the tilt, so only the second test sees that. k_p, k_i and the innovation scale
are run-time arguments: the firmware aligns fast while the arm is not engaged (rest) and
slowly, gated, in flight.

Drone attitude (delayed): the flight controller's roll/pitch at measurement time give the up
direction u_fc (less the estimate of its slowly varying error when the drone's velocity is
fused, velocity.py); with q_h this estimator's attitude at that time (from its history), the
measured up in the level frame is v = R(q_h) u_fc, and the level-frame rotation taking v to
e_z corrects the attitude at that time. Applied on the left to the current estimate, it
corrects the current attitude exactly, gyro increments since then included:

    q <- normalise(c (x) q),  c = (1 + v_z, k v_y, -k v_x, 0)        (k = 1: the shortest arc)
    b <- clamp(b - k_b (u_fc x u_h), +-bias_max)                      (the same error, body axes)

Command point: the set position p (level frame whose origin is where the base origin sits when
the drone is level) seen from the base, whose origin is offset o from the centre of rotation:
p_base = R^T (o + p) - o, with R the tilt (Ry(pitch) Rx(roll)) of the up direction predicted
lead_time ahead along the measured rate: u_lead = u + lead (u x w).
"""
from __future__ import annotations

import sympy as sp

from .attitude import ACC, DT, GYRO, P_LEVEL, mounting
from .config import Model

Q = sp.symbols("qw qx qy qz", real=True)          # current estimate
QH = sp.symbols("hw hx hy hz", real=True)         # the estimate at the link's measurement time
BIAS = sp.symbols("bx by bz", real=True)          # gyro bias, base axes, rad/s
UP = sp.symbols("ux uy uz", real=True)            # up direction in base axes (any length > 0)
RATE = sp.symbols("wx wy wz", real=True)          # bias-corrected body rate, base axes, rad/s
K_P, K_I, INNOVATION = sp.symbols("k_p k_i innovation_scale", real=True)
GATE = sp.Symbol("gate", real=True)
LINK_SR, LINK_CR, LINK_SP, LINK_CP = sp.symbols("sr cr sp cp", real=True)
LINK_K, LINK_KB = sp.symbols("k_link k_bias", real=True)
FC_ERROR = sp.symbols("fx fy fz", real=True)      # the flight controller's tilt error, base axes, rad
# |horizontal part of up| is kept above this fraction of |up| (pitch within +-89.9 deg), so
# the tilt rotation stays finite for any attitude.
H_MIN = sp.Rational(1, 1000)


def qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def up_of(q) -> sp.Matrix:
    """R(q)^T e_z: the level frame's up in body axes (times |q|^2)."""
    w, x, y, z = q
    return sp.Matrix([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z])


def rotate(q, v) -> sp.Matrix:
    """R(q) v for a unit quaternion q (body to level)."""
    w, x, y, z = q
    r = sp.Matrix([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                   [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                   [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return r * sp.Matrix(v)


def _normalised(q):
    inv = 1 / sp.sqrt(sum(c * c for c in q))
    return tuple(c * inv for c in q)


def _clamp(v, lim):
    return sp.Max(-lim, sp.Min(lim, v))


def delta(theta):
    """exp of the rotation vector theta as a quaternion, to 4th order in |theta|."""
    t2 = sum(t * t for t in theta)
    return (1 - t2 / 8,) + tuple(t * (sp.Rational(1, 2) - t2 / 48) for t in theta)


def _rat(x) -> sp.Expr:
    return sp.nsimplify(x, rational=True)


def gate(m: Model, a, e):
    tol = _rat(m.estimator.accel_reject_g)
    n2 = sum(c * c for c in a)
    mag = sp.Max(0, 1 - sp.Abs(n2 - 1) / (2 * tol))
    # a soft gate: large innovations are damped, never cut off, so an estimate that has drifted
    # past the innovation angle still comes back (slowly) instead of locking out
    return mag / (1 + INNOVATION * sum(c * c for c in e))


def accel_gate(m: Model):
    """The accelerometer's weight g of the step, from ACC, Q and INNOVATION."""
    a = mounting(m) * sp.Matrix(ACC)
    return gate(m, a, a.cross(up_of(Q)))


def step(m: Model):
    """(q_next (4), bias_next (3), rate (3), up_next (3)): one sample of accelerometer and gyro."""
    q_raw, b_next, rate = step_unnormalised(m)
    q_next, up_next = normalised_step(q_raw, 1 / sum(c * c for c in q_raw))
    return q_next, b_next, rate, up_next


def normalised_step(q_raw, inv2):
    """(q_next (4), up_next (3)) of the step's q_raw, given inv2 = 1 / |q_raw|^2 (a symbol for
    the generated code: one division and one square root, not two divisions)."""
    q_next = tuple(c * sp.sqrt(inv2) for c in q_raw)
    up_next = list(up_of(q_raw) * inv2)      # = up_of(q_next), without normalising first
    return q_next, up_next


def step_unnormalised(m: Model):
    """(q_raw (4), bias_next (3), rate (3)): the step before its normalisation."""
    M = mounting(m)
    a = M * sp.Matrix(ACC)
    w_m = M * sp.Matrix(GYRO)
    u = up_of(Q)
    e = a.cross(u)
    g = GATE                      # accel_gate(m), computed first (keeps the expressions small)
    dt = DT                       # s since the previous sample (the stabiliser measures it)
    b = sp.Matrix(BIAS)
    w = w_m - b + K_P * g * e
    q_raw = qmul(Q, delta(tuple(c * dt for c in w)))
    b_next = [_clamp(b[i] - K_I * g * e[i] * dt, _bias_max(m)) for i in range(3)]
    rate = [w_m[i] - b_next[i] for i in range(3)]
    return q_raw, b_next, rate


def propagate_unnormalised(m: Model):
    """(q_raw (4), rate (3)): the step with the accelerometer's gains 0, the gyro alone (in
    flight while the drone's messages correct the attitude); the bias is left as it is."""
    w = sp.Matrix(rate_of(m))
    return qmul(Q, delta(tuple(c * DT for c in w))), list(w)


def from_up(u):
    """The quaternion of zero yaw whose up direction is u (the shortest arc from u to e_z);
    u = -e_z (upside down) has no unique one: roll pi then."""
    ux, uy, uz = u
    n = sp.sqrt(ux * ux + uy * uy + uz * uz)
    return (n + uz, uy, -ux, sp.Integer(0))   # normalised by the caller


def link_error():
    """(c (4, not normalised), err (3)): the level-frame correction and the body-axes error
    (u_fc x u_h) of the drone's roll/pitch (as sines and cosines) measured when this
    estimator's attitude was QH, the estimate of the flight controller's own error (FC_ERROR,
    a small rotation; velocity.py) removed: u_fc + FC_ERROR x u_fc."""
    u_raw = sp.Matrix([-LINK_SP, LINK_SR * LINK_CP, LINK_CR * LINK_CP])
    u_fc = u_raw + sp.Matrix(FC_ERROR).cross(u_raw)
    v = rotate(QH, u_fc)
    c = (1 + v[2], LINK_K * v[1], -LINK_K * v[0], sp.Integer(0))
    return c, list(u_fc.cross(up_of(QH)))


CORR = sp.symbols("cw cx cy cz", real=True)
ERR = sp.symbols("ex ey ez", real=True)


def rotate_left():
    """normalise(CORR (x) Q): a level-frame correction applied to an attitude."""
    return _normalised(qmul(CORR, Q))


def bias_update(m: Model):
    """BIAS moved by -LINK_KB * ERR, clamped."""
    return [_clamp(BIAS[i] - LINK_KB * ERR[i], _bias_max(m)) for i in range(3)]


def _bias_max(m: Model):
    return sp.Float(sp.N(_rat(m.estimator.gyro_bias_max_dps) * sp.pi / 180, 40), 40)


def rate_of(m: Model, gyro=GYRO, bias=BIAS):
    """Bias-corrected body rate in base axes from a gyro sample in IMU axes."""
    w = mounting(m) * sp.Matrix(gyro)
    return [w[i] - bias[i] for i in range(3)]


def tilt_transpose(u) -> sp.Matrix:
    """(Ry(pitch) Rx(roll))^T of the up direction u (any length): no trig, one square root
    each for |u| and its horizontal part."""
    ux, uy, uz = u
    n = sp.sqrt(ux * ux + uy * uy + uz * uz)
    h = sp.Max(sp.sqrt(uy * uy + uz * uz), H_MIN * n)
    sp_, cp = -ux / n, h / n
    sr, cr = uy / h, uz / h
    r_wb = sp.Matrix([[cp, sp_ * sr, sp_ * cr], [0, cr, -sr], [-sp_, cp * sr, cp * cr]])
    return r_wb.T


def command_point(m: Model):
    """p_base (3) from UP, RATE and P_LEVEL, with the model's lead time and mount offset."""
    u = sp.Matrix(UP)
    lead = _rat(m.estimator.lead_time)
    u_lead = u + lead * u.cross(sp.Matrix(RATE))
    o = sp.Matrix([_rat(v) for v in m.mount_offset])
    return tilt_transpose(u_lead) * (o + sp.Matrix(P_LEVEL)) - o
