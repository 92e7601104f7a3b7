"""Velocity aiding: the drone's velocity from its odometry makes the tilt observable in
accelerated flight, and with it the slowly varying error of the flight controller's attitude.

The estimator integrates the IMU's specific force into the IMU's velocity in base axes,

    v <- v + dt (G (a - b_a - u) - w x v)    a = R_mount acc (g), u the estimate's up, w its rate,
                                             b_a the estimate of the accelerometer's bias (g)

so a tilt error d (rad, the estimate's up off by d) makes v drift from the true velocity at
G d per second. Each drone_velocity message (level, heading-following frame, the centre of
rotation's; measured `delay` ago) is turned into the same axes with the estimate's tilt at
that time, plus the lever arm to the base origin, where the IMU sits:

    e = T(u_h)^T v_level + w x offset - v_h          (m/s, base axes: measured - predicted)
    turn = u_h x e                                    (rad per m/s: the tilt error's direction)

and corrects, over the time h since the previous message (gains per second):

    v <- v + k_v h e                 (v and its history)
    q <- normalise(q (x) (1, k_t h turn / 2))         (a small body-axes rotation)
    bias <- bias - k_b h turn
    with the drone's attitude fused, not split (below): fc_error <- fc_error - k_t h turn

With the drone's attitude fused each of its messages compares the estimate with the flight
controller's up corrected by the estimate of its error, u_fc + fc_error x u_fc (quaternion.py
link_error). While the velocity is fresh that comparison corrects with gains of its own
(link_gain_with_velocity, 0 in the committed model: the gyro between velocity corrections
does better, docs/simulator.md) and moves fc_error by what is left (fc_error_gain per
second); not split, the turn above moves fc_error too, so the two stay agreed. When the
velocity stops, the flight controller's attitude corrects at link_gain, its learnt error
removed.

Gains from one bandwidth w_n (rad/s): pole placement on the small-angle error dynamics per
axis (e_v' = G d - k_v e_v, d' = -k_t e_v - b, b' = k_b e_v, with d the tilt error and b the
gyro bias error): a triple pole at -w_n, k_v = 3 w_n, k_t = 3 w_n^2 / G, k_b = w_n^3 / G.

The accelerometer's bias: at one attitude its part across the up direction is a tilt error
like any other (the loop above takes it as one: up to 0.3 deg for 5 mg), and only its part
along up shows, as a vertical velocity drift. The up direction sweeps the body's axes as the
drone tilts, so that drift, fed back along up, teaches every axis of the bias the tilts
reach; the tilt error it left is then taken back by the loop above:

    r = (u_h . e) u_h                         (the innovation along up, base axes)
    v <- v + (k_u - k_v) h r                  (along up the velocity corrects at k_u instead)
    b_a <- clamp(b_a - k_a h r, +-accel_bias_max)

Gains from the bandwidth w_a along up (e_u' = -G b_u - k_u e_u, b_u' = k_a e_u): a double
pole at -w_a, k_u = 2 w_a, k_a = w_a^2 / G (g per m/s per s); w_a = 0 leaves the bias at 0.

Across up, the bias is learnt from the drone's attitude. With the velocity fused, the loop
above holds the estimate's up where the specific force less the bias estimate points,
u = a - b_a: any error of b_a across up is a tilt error the velocity cannot see. The drone's
attitude sees it, beside its own slowly varying error, and the two cannot be told apart at
one attitude: each of its messages in flight (err = u_fc x u_h, quaternion.link_error, over
the time h since the previous one) moves fc_error towards the estimate at fc_error_gain (k_f)
and the estimate towards the flight controller's up at accel_bias_attitude_gain (k_d), the
bias with it so that a - b_a - u, all the velocity loop sees, is unchanged (fc_error is then
the flight controller's error alone: the velocity's turns leave it; not engaged, nothing is
learnt, as the arm at rest is levelled on the accelerometer as it reads, bias and all):

    q <- normalise(q (x) (1, k_d h err / 2))     u moves by k_d h (u_fc - u_h)
    b_a <- b_a - k_d h (u_h x err)               b_a moves by -k_d h (u_fc - u_h)

With the flight controller's error e_f and the bias's tilt e_b (the velocity's alone) the
disagreement closes at k_f + k_d per second, leaving the tilt error (k_f e_b + k_d e_f) /
(k_f + k_d): the two errors weighed by the gains (equal gains: their mean).

But the flight controller's error comes and goes (a correlation time of tens of seconds) and
the bias stays. With fixed gains, fc_error therefore also fades at 1 / fc_error_tau (tau)
while it learns, fc_error <- fc_error + h (k_f err - fc_error / tau), so that a disagreement
that outlasts tau ends as the bias (at k_d / ((k_f + k_d) tau) per second).

The committed model weighs the two by their stated sizes instead: per base axis a Kalman
filter of x = (x0, x1), x0 the estimate's tilt error from the bias (prior accel_bias_prior_g,
a random walk of accel_bias_walk_g a minute), x1 fc_error's error (first-order Markov of
fc_error_deg over tau), measured by each message as

    err = x1 - x0 + white (drone_attitude_white_deg),     H = (-1, 1)

Its gain K = (-k_d, k_f) per message moves the estimate and its bias by k_d err and fc_error
by k_f err (fc_error fading by the prediction's h / tau); P is updated in Joseph form
(split_predict, split_gain, split_update below: est_split_step in C). Early
on the disagreement is shared by the priors; then the part that outlasts tau goes to the
bias, and the gain for it falls as it is learnt (tests/test_velocity_aiding.py checks P
against the textbook step; uavarm/sim/split_bound.py compares the estimates on a scalar
model of the two errors).
"""
from __future__ import annotations

import sympy as sp

from .attitude import ACC, DT, mounting
from .config import Model
from .quaternion import ERR, FC_ERROR, Q, QH, RATE, UP, _clamp, _normalised, qmul, tilt_transpose, up_of

G = sp.Float("9.80665", 40)                         # standard gravity, m/s^2 (the accelerometer's g)
VEL = sp.symbols("vx vy vz", real=True)             # the estimate, base axes, m/s
VEL_H = sp.symbols("hvx hvy hvz", real=True)        # the estimate at the message's measurement time
V_LEVEL = sp.symbols("lx ly lz", real=True)         # the message: level, heading-following frame, m/s
TURN = sp.symbols("tx ty tz", real=True)            # a small body-axes rotation, rad
ACC_BIAS = sp.symbols("abx aby abz", real=True)     # the accelerometer's bias estimate, base axes, g
INNOV = sp.symbols("ex ey ez", real=True)           # an innovation e, base axes, m/s
ALONG = sp.symbols("rx ry rz", real=True)           # its part along up, base axes, m/s
K_A = sp.Symbol("k_a", real=True)
SPLIT_P = sp.symbols("p00 p01 p11", real=True)     # the split's covariance, rad^2
SPLIT_PRED = sp.symbols("m00 m01 m11", real=True)  # the same, predicted to the message
SPLIT_K = sp.symbols("kd kf", real=True)           # its gain, K = (-kd, kf)
SPLIT_H = sp.Symbol("h", positive=True)            # s since the previous message
SPLIT_ERR = sp.Symbol("err", real=True)            # the message's disagreement on one axis, rad
SPLIT_FC = sp.Symbol("fc", real=True)              # fc_error on that axis, rad


def predict(m: Model):
    """v after one sample of ACC (IMU axes, g) over DT, with UP and RATE the estimate's."""
    a = mounting(m) * sp.Matrix(ACC) - sp.Matrix(ACC_BIAS)
    u, w, v = sp.Matrix(UP), sp.Matrix(RATE), sp.Matrix(VEL)
    return list(v + G * DT * (a - u) - DT * w.cross(v))   # (G dt) (a - b_a - u): one product per axis


def innovation(m: Model):
    """(e (3), turn (3)): the message's V_LEVEL against VEL_H, the estimate's velocity when
    its attitude was QH (unit), with RATE the current rate (for the lever arm)."""
    u_h = up_of(QH)
    offset = sp.Matrix([sp.nsimplify(c, rational=True) / 1000 for c in m.mount_offset])
    measured = tilt_transpose(u_h) * sp.Matrix(V_LEVEL) + sp.Matrix(RATE).cross(offset)
    e = measured - sp.Matrix(VEL_H)
    return list(e), list(u_h.cross(e))


def along_up():
    """r (3): INNOV's part along the up direction of QH (unit)."""
    u_h = up_of(QH)
    along = u_h.dot(sp.Matrix(INNOV))
    return [along * c for c in u_h]


def tilt_as_bias():
    """r (3) = u_h x ERR, u_h the up direction of QH (unit): for a small ERR
    (quaternion.link_error's), u_fc - u_h, the move of up that the drone's attitude asks for."""
    return list(up_of(QH).cross(sp.Matrix(ERR)))


def accel_bias_update(m: Model):
    """ACC_BIAS moved by -K_A * ALONG, clamped to the model's accel_bias_max_g."""
    lim = sp.nsimplify(m.estimator.accel_bias_max_g, rational=True)
    return [_clamp(ACC_BIAS[i] - K_A * ALONG[i], lim) for i in range(3)]


def turned():
    """normalise(Q (x) (1, TURN / 2)): Q after a small rotation TURN in its own (body) axes."""
    return _normalised(qmul(Q, (sp.Integer(1),) + tuple(t / 2 for t in TURN)))


def gains(bandwidth: float) -> dict[str, sp.Expr]:
    """k_v (1/s), k_t (rad/s per m/s), k_b (rad/s^2 per m/s) of the bandwidth w_n (rad/s)."""
    w = sp.nsimplify(bandwidth, rational=True)
    return {"k_v": 3 * w, "k_t": 3 * w ** 2 / G, "k_b": w ** 3 / G}


def settle_s(bandwidth: float) -> sp.Expr:
    """s for the velocity loop (gains: a triple pole at w_n) to take back a turn it did not
    make: (1 + w t + (w t)^2 / 2) e^(-w t) is 1.4 % at w t = 8. Not engaged, the split waits
    this long after the velocity became fresh (the drone's attitude heard before it turned
    the estimate without the bias)."""
    return 8 / sp.nsimplify(bandwidth, rational=True)


def accel_bias_gains(bandwidth: float) -> dict[str, sp.Expr]:
    """k_u (1/s), k_a (g per m/s per s) of the bandwidth w_a (rad/s) along up."""
    w = sp.nsimplify(bandwidth, rational=True)
    return {"k_u": 2 * w, "k_a": w ** 2 / G}


def split_noises(m: Model) -> dict[str, sp.Expr]:
    """The split's Kalman filter, in rad^2 (a bias of b g tilts the estimate by b rad): prior
    variances of x0 (bias) and x1 (fc_error's error), of the white error per message, the bias's
    random walk per second, and fc_error's fading rate 1 / fc_error_tau (1/s, 0: never)."""
    e = m.estimator
    exact = lambda v: sp.nsimplify(v, rational=True)
    return {"bias_var": exact(e.accel_bias_prior_g) ** 2,
            "fc_var": sp.rad(exact(e.fc_error_deg)) ** 2,
            "white_var": sp.rad(exact(e.drone_attitude_white_deg)) ** 2,
            "bias_walk": exact(e.accel_bias_walk_g) ** 2 / 60,
            "fade": sp.Integer(0) if e.fc_error_tau == 0 else 1 / exact(e.fc_error_tau)}


def split_predict(m: Model):
    """SPLIT_P predicted over SPLIT_H: x0 wanders by the bias's walk, x1 fades by
    a = 1 - h / tau and its variance returns towards fc_error_deg^2 (first-order Markov)."""
    n = split_noises(m)
    p00, p01, p11 = SPLIT_P
    a = 1 - SPLIT_H * n["fade"]
    return [p00 + SPLIT_H * n["bias_walk"], a * p01, a ** 2 * p11 + (1 - a ** 2) * n["fc_var"]]


def split_gain(m: Model):
    """(kd, kf): K = P H^T / (H P H^T + R) for the predicted SPLIT_PRED, H = (-1, 1)."""
    m00, m01, m11 = SPLIT_PRED
    inv = 1 / (m00 + m11 - 2 * m01 + split_noises(m)["white_var"])
    return [(m00 - m01) * inv, (m11 - m01) * inv]


def split_update(m: Model):
    """(turn, learn, p00, p01, p11) from SPLIT_PRED and SPLIT_K: the estimate turns by kd err,
    fc_error moves by kf err less its fading over SPLIT_H, and P = (I - K H) P (I - K H)^T +
    K R K^T (Joseph form: symmetric and positive in float32 too; kept in this form, not
    simplified to (I - K H) P, which loses both)."""
    n = split_noises(m)
    kd, kf = SPLIT_K
    m00, m01, m11 = SPLIT_PRED
    i_kh = sp.Matrix([[1 - kd, kd], [kf, 1 - kf]])          # I - K H, K = (-kd, kf), H = (-1, 1)
    k = sp.Matrix([-kd, kf])
    p = i_kh * sp.Matrix([[m00, m01], [m01, m11]]) * i_kh.T + k * n["white_var"] * k.T
    return [kd * SPLIT_ERR, kf * SPLIT_ERR - SPLIT_H * n["fade"] * SPLIT_FC, p[0, 0], p[0, 1], p[1, 1]]
