"""The arm's weight on its joints: the simulated hardware's masses and the torque gravity
exerts about each joint at rest (statics; the arm's inertia in motion is not modelled).

The masses are the hardware's, as the simulator takes it, not the model file's: the
firmware knows none of them. Each is a point mass:

- the elbow servo (an AX-12A, 54.6 g in its e-manual) at the end of the upper arm, on joint
  3's axis;
- the upper arm's brackets at the middle of the upper arm (L2), the forearm's at the
  middle of the forearm (L3): 20 g each, an assumption (two plastic AX-12A brackets and
  screws);
- the end effector at the forearm's end: 30 g, an assumption (a light tool).

The shoulder servo and joint 1's link lie on joint 1's and joint 2's axes (both pass through
the shoulder), so their weight turns no joint of the arm; joint 1's servo is on the drone.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .drone import G


@dataclass(frozen=True)
class ArmMasses:
    """Point masses in kg (where each sits: the module's docstring)."""
    elbow_servo: float = 0.0546
    upper_arm: float = 0.020
    forearm: float = 0.020
    end_effector: float = 0.030


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


def gravity_torques(model, joints, up, masses: ArmMasses = ArmMasses()) -> tuple[float, float, float]:
    """The torque (N m) gravity exerts about each joint, in the sense its angle grows, with the
    joints at `joints` (rad, as they really are) and `up` the unit vector pointing up, in the
    base's axes (level: (0, 0, 1)). The arm's geometry is the model file's (the DH table:
    joint 1 turns the arm's vertical plane, whose horizontal direction is (cos q1, -sin q1,
    0), about the base's z axis; in that plane the upper arm hangs from the shoulder, L1
    below the base, at q2 from straight down, the forearm at q2 + q3)."""
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
    beyond_elbow = [(masses.forearm, along(elbow, L3 / 2, q2 + q3)),
                    (masses.end_effector, along(elbow, L3, q2 + q3))]
    beyond_shoulder = [(masses.upper_arm, along(shoulder, L2 / 2, q2)), (masses.elbow_servo, elbow)] + beyond_elbow
    return (_moment((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), beyond_shoulder, up),
            _moment(axis_23, shoulder, beyond_shoulder, up),
            _moment(axis_23, elbow, beyond_elbow, up))
