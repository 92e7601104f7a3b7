"""`uavarm calibrate servos`: the servos' zeros and directions, checked on the arm before
anything is written.

Oracles: plain geometry (tests/oracles.py: where the shafts are, the body plane and the legs),
statics with made-up positive masses (which way a servo must push to hold a pose), and the
simulated hardware's truth (each servo's real zero and direction, which the SITL's board knows
and the model file does not)."""
from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest

import oracles
from uavarm.calibrate import servo_zero
from uavarm.calibrate.fit import CalibrationError
from uavarm.model import config


# ---------------------------------------------------------------- the route, before anything moves

def test_the_verification_route_is_clear_with_every_zero_off_and_any_direction_reversed():
    """Random shafts on the route's paths (one joint at a time), each joint's zero off by up to
    ROUTE_SAFE_DEG and its direction either way: every one clear of the body and the legs by
    plain geometry."""
    m = config.load()
    rng = np.random.default_rng(7)
    route = np.radians(servo_zero.ROUTE)
    assert all(np.count_nonzero(b != a) == 1 for a, b in zip(route, route[1:])), "one joint at a time"
    window = math.radians(servo_zero.ROUTE_SAFE_DEG)
    least = math.inf
    for a, b in zip(route, route[1:]):
        s = rng.uniform(0, 1, (20000, 1))
        believed = a + s * (b - a)
        real = believed * rng.choice([-1.0, 1.0], (20000, 3)) + rng.uniform(-window, window, (20000, 3))
        corners = np.array(list(itertools.product((-window, window), repeat=3)))
        for flips in itertools.product((-1.0, 1.0), repeat=3):      # the box's corners, exactly
            real = np.vstack([real, (believed[::50, None, :] * flips + corners).reshape(-1, 3)])
        least = min(least, float(oracles.clearance_mm(m, real).min()))
    print(f"\nleast clearance on the route, zeros off by up to {servo_zero.ROUTE_SAFE_DEG:g} deg, any direction: "
          f"{least:.1f} mm")
    assert least > 0.0


def test_a_model_whose_verification_route_is_not_clear_is_refused_before_the_arm_is_touched(tmp_path):
    path = tmp_path / "manipulator.toml"
    path.write_text(config.DEFAULT_MODEL.read_text().replace("leg_distance = 100.0", "leg_distance = 70.0"))

    class Untouched:
        def __getattr__(self, name):
            raise AssertionError(f"the arm was used ({name}) before the route was checked")
    with pytest.raises(CalibrationError, match="verification poses are not safe"):
        servo_zero.servos(Untouched(), path, lambda text: None, lambda q: True)


@pytest.mark.parametrize("pose", [p for p in servo_zero.VERIFY if p.load_joint])
def test_the_holding_sense_at_a_load_pose_is_gravitys_whatever_the_masses(pose):
    """Statics on the plain-geometry arm: masses at the elbow, along the forearm and at the end
    effector (random, positive); the servo must push against the gradient of their potential
    energy. The prediction needs no masses, so it must hold for every draw."""
    m = config.load()
    rng = np.random.default_rng(3)
    j = pose.load_joint - 1
    q = np.radians(pose.q_deg)
    h = 1e-4
    for _ in range(20):
        masses = rng.uniform(0.005, 0.1, 4)                     # kg: elbow, forearm 1/3, 2/3, end effector

        def potential(qq):
            _, elbow, ee = oracles.arm_points(m, qq)
            points = [elbow, elbow + (ee - elbow) / 3, elbow + 2 * (ee - elbow) / 3, ee]
            if j == 2:                                          # joint 3 carries the forearm only
                points, weights = points[1:], masses[1:]
            else:
                weights = masses
            return sum(w * 9.81 * p[2] / 1000 for w, p in zip(weights, points))
        dq = np.zeros(3)
        dq[j] = h
        holding = (potential(q + dq) - potential(q - dq)) / (2 * h)    # N m the servo must give
        assert abs(holding) > 1e-3
        assert servo_zero.holding_sign(m, pose) == np.sign(holding)


def test_the_poses_are_told_in_the_drones_directions():
    """The forearm at (0, 0, 90) deg points along +x (plain geometry), the drone's front; joint 1
    at 45 deg faces the leg at (cos 45, -sin 45): front and right (-y)."""
    m = config.load()
    _, _, ee = oracles.arm_points(m, np.radians([0.0, 0.0, 90.0]))
    assert ee[0] > 50 and abs(ee[1]) < 1e-9
    words = [servo_zero.sight(m, p) for p in servo_zero.VERIFY]
    assert "pointing towards the drone's front" in words[0]
    assert "swung up towards the drone's front" in words[1]
    assert "towards the front-right landing leg" in words[2]


def test_load_words_read_as_the_control_table_says():
    """Present Load: bits 0-9 the size, bit 10 set for a clockwise load (units shrinking)."""
    assert servo_zero.load_sense(300) == (1, 300)
    assert servo_zero.load_sense(1024 + 300) == (-1, 300)
    assert servo_zero.load_sense(0) == (1, 0)
