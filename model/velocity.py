"""Velocity aiding: the drone's velocity from its odometry makes the tilt observable in
accelerated flight, and with it the slowly varying error of the flight controller's attitude.

The estimator integrates the IMU's specific force into the IMU's velocity in base axes,

    v <- v + dt (G (a - u) - w x v)          a = R_mount acc (g), u the estimate's up, w its rate

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
    with the drone's attitude fused: fc_error <- fc_error - k_t h turn

With the drone's attitude fused each of its messages compares the estimate with the flight
controller's up corrected by the estimate of its error, u_fc + fc_error x u_fc (quaternion.py
link_error). While the velocity is fresh that comparison corrects with gains of its own
(link_gain_with_velocity, 0 in the committed model: the gyro between velocity corrections
does better, docs/simulator.md) and moves fc_error by what is left (fc_error_gain per
second); the turn above moves fc_error too, so the two stay agreed. When the velocity stops,
the flight controller's attitude corrects at link_gain, its learnt error removed.

Gains from one bandwidth w_n (rad/s): pole placement on the small-angle error dynamics per
axis (e_v' = G d - k_v e_v, d' = -k_t e_v - b, b' = k_b e_v, with d the tilt error and b the
gyro bias error): a triple pole at -w_n, k_v = 3 w_n, k_t = 3 w_n^2 / G, k_b = w_n^3 / G.
"""
from __future__ import annotations

import sympy as sp

from .attitude import ACC, DT, mounting
from .config import Model
from .quaternion import FC_ERROR, Q, QH, RATE, UP, _normalised, qmul, tilt_transpose, up_of

G = sp.Float("9.80665", 40)                         # standard gravity, m/s^2 (the accelerometer's g)
VEL = sp.symbols("vx vy vz", real=True)             # the estimate, base axes, m/s
VEL_H = sp.symbols("hvx hvy hvz", real=True)        # the estimate at the message's measurement time
V_LEVEL = sp.symbols("lx ly lz", real=True)         # the message: level, heading-following frame, m/s
TURN = sp.symbols("tx ty tz", real=True)            # a small body-axes rotation, rad


def predict(m: Model):
    """v after one sample of ACC (IMU axes, g) over DT, with UP and RATE the estimate's."""
    a = mounting(m) * sp.Matrix(ACC)
    u, w, v = sp.Matrix(UP), sp.Matrix(RATE), sp.Matrix(VEL)
    return list(v + DT * (G * (a - u) - w.cross(v)))


def innovation(m: Model):
    """(e (3), turn (3)): the message's V_LEVEL against VEL_H, the estimate's velocity when
    its attitude was QH (unit), with RATE the current rate (for the lever arm)."""
    u_h = up_of(QH)
    offset = sp.Matrix([sp.nsimplify(c, rational=True) / 1000 for c in m.mount_offset])
    measured = tilt_transpose(u_h) * sp.Matrix(V_LEVEL) + sp.Matrix(RATE).cross(offset)
    e = measured - sp.Matrix(VEL_H)
    return list(e), list(u_h.cross(e))


def turned():
    """normalise(Q (x) (1, TURN / 2)): Q after a small rotation TURN in its own (body) axes."""
    return _normalised(qmul(Q, (sp.Integer(1),) + tuple(t / 2 for t in TURN)))


def gains(bandwidth: float) -> dict[str, sp.Expr]:
    """k_v (1/s), k_t (rad/s per m/s), k_b (rad/s^2 per m/s) of the bandwidth w_n (rad/s)."""
    w = sp.nsimplify(bandwidth, rational=True)
    return {"k_v": 3 * w, "k_t": 3 * w ** 2 / G, "k_b": w ** 3 / G}
