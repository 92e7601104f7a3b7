"""Attitude of the arm's base from the IMU, and the target turned into the tilted base frame.

Frames: the base frame B has z up and turns with the drone; the level frame W is
gravity-aligned and follows the drone's heading, so B = W rotated by pitch about y after
roll about x (the Z-Y-X Euler convention without yaw):

    R_WB = Ry(pitch) Rx(roll),     p_B = R_WB^T p_W

The IMU reads the specific force, which at rest is "up": u_B = R_WB^T (0, 0, 1) =
(-sin pitch, sin roll cos pitch, cos roll cos pitch), so

    roll = atan2(u_y, u_z),   pitch = atan2(-u_x, sqrt(u_y^2 + u_z^2))

(the thesis's equation 3.1 is garbled in print; this is the standard form). The IMU's own axes are rotated on
the board: v_B = R_mount v_IMU, R_mount from the model file's mounting roll/pitch/yaw.

The complementary filter (thesis eq. 3.3, with the rate integrated over the
sample period) blends the gyro-propagated angle with the accelerometer's:

    angle_k = w (angle_{k-1} + rate dt) + (1 - w) angle_acc

where the Euler-angle rates come from the body rates (p, q, r) through the Z-Y-X
kinematics: roll' = p + (q sin roll + r cos roll) tan pitch, pitch' = q cos roll - r sin roll.
"""
from __future__ import annotations

import sympy as sp

from .config import Model

roll, pitch = sp.symbols("roll pitch", real=True)
ACC = sp.symbols("ax ay az", real=True)       # accelerometer, IMU axes (any unit)
GYRO = sp.symbols("gx gy gz", real=True)      # gyro, IMU axes, rad/s
P_LEVEL = sp.symbols("px py pz", real=True)   # a point in the level frame
# Smallest |cos pitch| the Euler kinematics divide by: keeps the rates finite at +-90 deg,
# an attitude the drone never flies.
COS_PITCH_MIN = sp.Rational(1, 100)


def rx(a):
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def ry(a):
    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def rz(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def mounting(m: Model) -> sp.Matrix:
    """R_mount: IMU axes to base axes.

    Rational entries (quarter-turn mountings: 0, +-1) stay exact, so their zeros fold away in
    the generated code; every other entry becomes a 40-digit number, since the float32 printer
    folds numbers but cannot print a constant such as sin(17 pi/180).
    """
    r, p, y = (sp.pi * sp.nsimplify(a, rational=True) / 180 for a in m.imu_mounting_rpy_deg)
    return (rz(y) * ry(p) * rx(r)).applyfunc(_constant)


def _constant(v: sp.Expr) -> sp.Expr:
    if v.is_Rational:
        return v
    f = sp.Float(sp.N(v, 50), 40)
    return sp.Integer(0) if abs(f) < sp.Float("1e-40") else f


def level_to_base(roll_, pitch_) -> sp.Matrix:
    """R_WB^T: multiplies a level-frame vector to give it in the tilted base frame."""
    return (ry(pitch_) * rx(roll_)).T


def tilt_from_accel(m: Model) -> tuple[sp.Expr, sp.Expr]:
    """(roll, pitch) of the gravity direction the accelerometer (IMU axes) measures."""
    u = mounting(m) * sp.Matrix(ACC)
    return sp.atan2(u[1], u[2]), sp.atan2(-u[0], sp.sqrt(u[1] ** 2 + u[2] ** 2))


def euler_rates(m: Model) -> tuple[sp.Expr, sp.Expr]:
    """(roll', pitch') of the body rates the gyro (IMU axes) measures, at attitude (roll, pitch)."""
    w = mounting(m) * sp.Matrix(GYRO)
    tan_pitch = sp.sin(pitch) / sp.Max(sp.cos(pitch), COS_PITCH_MIN)
    return (w[0] + (w[1] * sp.sin(roll) + w[2] * sp.cos(roll)) * tan_pitch,
            w[1] * sp.cos(roll) - w[2] * sp.sin(roll))


DT = sp.Symbol("dt", positive=True)   # s since the previous sample (the stabiliser measures it)


def complementary_step(m: Model) -> tuple[sp.Expr, sp.Expr]:
    """The next (roll, pitch) from the previous (roll, pitch) and one IMU sample taken DT
    after the previous one."""
    w = sp.nsimplify(m.complementary_gyro_weight, rational=True)
    dt = DT
    acc_roll, acc_pitch = tilt_from_accel(m)
    rate_roll, rate_pitch = euler_rates(m)
    return (w * (roll + rate_roll * dt) + (1 - w) * acc_roll,
            w * (pitch + rate_pitch * dt) + (1 - w) * acc_pitch)
