"""Joint angle <-> servo position units, from the model file's zero and direction; goal speeds
in the servo model's speed register units."""
from __future__ import annotations

import math

import sympy as sp

from .config import Model
from .servo_models import ServoModel


def units_per_rad(m: Model) -> sp.Expr:
    units, degrees = (sp.nsimplify(v, rational=True) for v in (m.servo_units_max, m.servo_range_deg))
    return units / (sp.pi * degrees / 180)


def joint_to_units(m: Model, joint: int, angle) -> sp.Expr:
    s = m.servos[joint]
    return s.zero + s.direction * angle * units_per_rad(m)


def units_to_joint(m: Model, joint: int, units) -> sp.Expr:
    s = m.servos[joint]
    return s.direction * (units - s.zero) / units_per_rad(m)


def speed_units(rpm: float, servo: ServoModel) -> int:
    """The goal-speed register value (AX-12A Moving Speed, X-series Profile Velocity) of a speed
    in rpm: 1..its upper bound (0 would mean "no limit")."""
    return min(servo.speed_units_max, max(1, round(rpm / servo.rpm_per_speed_unit)))


# Torque Limit's full scale (AX-12A e-manual: 1023 = the maximum torque), and what the firmware
# configures outside the bench: one below, so that a servo whose RAM reset (its Torque Limit
# back at the EEPROM's Max Torque, 1023) is told apart at its next status reading.
TORQUE_LIMIT_MAX = 1023
TORQUE_LIMIT_SET = TORQUE_LIMIT_MAX - 1


def bench_torque_limit(m: Model) -> int:
    """The Torque Limit register value on the bench: servo.bench_torque_limit of the maximum,
    at most TORQUE_LIMIT_SET (a reset servo must still read differently)."""
    return min(TORQUE_LIMIT_SET, round(m.servo_bench_torque_limit * TORQUE_LIMIT_MAX))


def rad_per_s(speed: int, servo: ServoModel) -> sp.Expr:
    """The joint speed (rad/s) a goal-speed register value allows: speed x its unit (AX-12A 0.111 rpm)."""
    return speed * sp.nsimplify(servo.rpm_per_speed_unit, rational=True) * 2 * sp.pi / 60


def units_per_s_per_speed_unit(m: Model) -> sp.Expr:
    """Position units per second that one goal-speed unit allows: rpm x 6 deg/s per rpm x
    the model's units per degree."""
    units, degrees = (sp.nsimplify(v, rational=True) for v in (m.servo_units_max, m.servo_range_deg))
    return sp.nsimplify(m.servo_model.rpm_per_speed_unit, rational=True) * 6 * units / degrees


def unit_range(m: Model, joint: int) -> tuple[int, int]:
    """The servo positions that lie inside the joint's travel limits (whole units)."""
    lim = m.limits[joint]
    ends = sorted(float(joint_to_units(m, joint, sp.rad(sp.nsimplify(d, rational=True))))
                  for d in (lim.min_deg, lim.max_deg))
    return math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9)


def supply_step_per_decivolt(m: Model) -> sp.Expr:
    """The most a goal may move per tick (rad) per 0.1 V the servos report: the share
    servo.speed_margin of the servo model's no-load speed, which falls in proportion to the supply."""
    facts = m.servo_model
    rpm_per_decivolt = sp.nsimplify(facts.no_load_rpm, rational=True) / sp.nsimplify(facts.no_load_volts, rational=True) / 10
    margin = sp.nsimplify(m.servo_speed_margin, rational=True)
    return margin * rpm_per_decivolt * 2 * sp.pi / 60 / sp.nsimplify(m.sample_rate, rational=True)


# How far (deg) a shaft may stand from its goal and still follow it: an AX-12A's compliance and
# sag under the arm's weight (8 of its units); the same angle on any servo.
TRACK_TOLERANCE_DEG = 2.35


def track_tolerance_units(m: Model) -> int:
    """TRACK_TOLERANCE_DEG in the servo's position units (the AX-12A's 8, an X-series' 27)."""
    return round(math.radians(TRACK_TOLERANCE_DEG) * float(units_per_rad(m)))


def gap_max_units(m: Model) -> int:
    """How far (units) a shaft may trail its goal before the goals wait for it: twice its
    response lag at the working speed and one working step. Further
    behind, the servo is slower than the motion allows for (blocked, or a supply below what
    it reports)."""
    rate = float(rad_per_s(speed_units(m.working_speed_rpm, m.servo_model), m.servo_model) * units_per_rad(m))   # units/s
    return math.ceil(rate * (2 * m.servo_response_lag + 1 / m.sample_rate))
