"""The arm's weight on its joints: the arm's masses and the torque gravity exerts about each
joint at rest (statics; the arm's inertia in motion is not modelled).

The masses and their centres are the model file's [masses] (the URDF's inertials come from
the same keys); the firmware uses none of them. Each is a point mass:

- the elbow servo (an AX-12A) at the end of the upper arm, on joint 3's axis;
- the upper arm's brackets at masses.upper_arm_com from the shoulder, the forearm's at
  masses.forearm_com from the elbow;
- the end effector (the tool) at masses.end_effector_com from the elbow.

The shoulder servo and joint 1's link lie on joint 1's and joint 2's axes (both pass through
the shoulder), so their weight turns no joint of the arm; joint 1's servo is on the drone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .drone import G


@dataclass(frozen=True)
class ArmMasses:
    """Point masses in kg and their distances in m along their links (the module's docstring)."""
    elbow_servo: float
    upper_arm: float
    upper_arm_com: float
    forearm: float
    forearm_com: float
    end_effector: float
    end_effector_com: float

    @classmethod
    def of(cls, model) -> "ArmMasses":
        """The model file's [masses] (g, mm)."""
        m = model.masses
        return cls(elbow_servo=m.servo / 1000, upper_arm=m.upper_arm / 1000, upper_arm_com=m.upper_arm_com / 1000,
                   forearm=m.forearm / 1000, forearm_com=m.forearm_com / 1000,
                   end_effector=m.end_effector / 1000, end_effector_com=m.end_effector_com / 1000)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _moment(axis, about, masses_at, up):
    """The torque (N m) about `axis` (unit, through point `about`, m) of the weights of
    (kg, point) pairs, gravity pulling against `up`."""
    total = 0.0
    for kg, p in masses_at:
        r = (p[0] - about[0], p[1] - about[1], p[2] - about[2])
        f = (-kg * G * up[0], -kg * G * up[1], -kg * G * up[2])
        m = _cross(r, f)
        total += axis[0] * m[0] + axis[1] * m[1] + axis[2] * m[2]
    return total


def gravity_torques(model, joints, up, masses: ArmMasses | None = None) -> tuple[float, float, float]:
    """The torque (N m) gravity exerts about each joint, in the sense its angle grows, with the
    joints at `joints` (rad, as they really are) and `up` the unit vector pointing up, in the
    base's axes (level: (0, 0, 1)); masses: the model file's unless given. The arm's geometry is the model file's (the DH table:
    joint 1 turns the arm's vertical plane, whose horizontal direction is (cos q1, -sin q1,
    0), about the base's z axis; in that plane the upper arm hangs from the shoulder, L1
    below the base, at q2 from straight down, the forearm at q2 + q3)."""
    masses = masses or ArmMasses.of(model)
    q1, q2, q3 = joints
    h = (math.cos(q1), -math.sin(q1), 0.0)
    down = (0.0, 0.0, -1.0)
    axis_23 = _cross(down, h)            # joints 2 and 3 turn about it as their angles grow
    L1, L2, L3 = model.L1 / 1000, model.L2 / 1000, model.L3 / 1000

    def along(start, length, angle):
        s, c = math.sin(angle), math.cos(angle)
        return tuple(start[k] + length * (s * h[k] + c * down[k]) for k in range(3))

    shoulder = (0.0, 0.0, -L1)
    elbow = along(shoulder, L2, q2)
    beyond_elbow = [(masses.forearm, along(elbow, masses.forearm_com, q2 + q3)),
                    (masses.end_effector, along(elbow, masses.end_effector_com, q2 + q3))]
    beyond_shoulder = [(masses.upper_arm, along(shoulder, masses.upper_arm_com, q2)),
                       (masses.elbow_servo, elbow)] + beyond_elbow
    return (_moment((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), beyond_shoulder, up),
            _moment(axis_23, shoulder, beyond_shoulder, up),
            _moment(axis_23, elbow, beyond_elbow, up))
