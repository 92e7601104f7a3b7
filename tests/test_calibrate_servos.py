"""`uavarm calibrate servos`: the servos' zeros and directions, checked on the arm before
anything is written.

Oracles: plain geometry (tests/oracles.py: where the shafts are, the body plane and the legs),
statics with made-up positive masses (which way a servo must push to hold a pose), and the
simulated hardware's truth (each servo's real zero and direction, which the SITL's board knows
and the model file does not)."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import oracles
from conftest import wait_simulated
from test_calibrate import SECONDS, enabled_sitl, run_sitl
from test_servo_models import xm430_text
from test_xseries_board import xm430  # noqa: F401 (a fixture: the XM430-W350 build)
from uavarm.calibrate import servo_zero
from uavarm.calibrate.fit import CalibrationError
from uavarm.link import ArmLink
from uavarm.model import config

# the tests on the SITL: a simulated board in real time, a stage of their own (Makefile)
realtime = pytest.mark.realtime


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


# ---------------------------------------------------------------- on the SITL, a user at the arm

TRUTH_ZERO = (516, 497, 505)       # the units each servo reads with its joint at 0 deg
TRUTH_DIRECTION = (1, -1, 1)       # joint 2's servo mounted the other way round
TRUTH = (TRUTH_ZERO, TRUTH_DIRECTION)
NEAR_DEG = 10.0                    # a pose the user takes for the one asked about


@pytest.fixture
def lab_model(tmp_path):
    """The model file as a lab has it before its first servo calibration: every zero at the
    centre, joint 2's servo stated as mounted the other way round (as it is)."""
    path = tmp_path / "manipulator.toml"
    text = config.DEFAULT_MODEL.read_text()
    joint2 = "[servo.theta2]\nid = 2\nzero = 512\ndirection = 1"
    assert joint2 in text
    path.write_text(text.replace(joint2, joint2[:-1] + "-1"))
    return path


class User:
    """The simulated user at the arm. At the zero pose, holds each limp joint at its true angle
    off_deg (0: exactly); answers each jog question from what the shaft really did (joint
    `wrong` the other way round); and each verification question by comparing the arm's true
    pose with the one asked about (within NEAR_DEG), or yes to everything if careless."""

    def __init__(self, sitl, model, off_deg=(0.0, 0.0, 0.0), wrong=None, careless=False):
        self.s, self.m, self.off, self.wrong, self.careless = sitl, model, off_deg, wrong, careless
        self.said: list[str] = []

    def true_deg(self):
        return np.degrees(self.s.board.true_joints())

    def ask(self, text):
        self.said.append(text)
        if text.startswith("Hold the arm hanging"):
            for j, deg in enumerate(self.off, 1):
                assert "turned by hand" in self.s.submit(f"move joint {j} {deg}").result(timeout=60)
        wait_simulated(self.s, 0.2)

    def confirm(self, question):
        self.said.append(question)
        if question.startswith("Did joint"):
            j = int(question.split()[2]) - 1                   # jogged from where it was held
            wait_simulated(self.s, 10.0, until=lambda: abs(self.true_deg()[j] - self.off[j]) > 3.0)
            seen = self.true_deg()[j] > self.off[j]
            return seen != (self.wrong == j + 1)
        if question.startswith("Is the arm now"):
            pose = next(p for p in servo_zero.VERIFY if servo_zero.sight(self.m, p) in question)
            return self.careless or bool(np.all(np.abs(self.true_deg() - pose.q_deg) < NEAR_DEG))
        return True                    # write it; and write an unusual one all the same


def bench(truth=TRUTH, **options):
    """A SITL whose servos are mounted as truth, the arm disabled (as after power-up), every
    shaft position recorded; and a link to it."""
    s = run_sitl(servo_truth=truth, **options)
    s.board.shaft_trace = []
    return s, ArmLink(s.device, clock=s.clock)


def least_clearance(s, m, truth) -> float:
    """The least clearance (mm, plain geometry) of the arm's true poses while powered: each
    shaft's position in the units of the model m's servo, mounted as truth says."""
    rows = np.array([r[2:5] for r in s.board.shaft_trace if r[1]], dtype=float)
    zero, direction = (np.array(v, float) for v in truth)
    q = direction * (rows - zero) * math.radians(m.servo_range_deg) / m.servo_units_max
    return float(oracles.clearance_mm(m, q).min())


@realtime
def test_a_right_calibration_goes_through_with_the_verification_move(lab_model, capsys):
    """From a disabled arm: enabled limp (nothing driven with the model's values), the zero
    pose, three jogs, three verification poses, the write: the servos' true zeros and
    directions, the supply off at the end, and no shaft ever in the body or a leg."""
    m, user, end = assert_calibrated(lab_model, capsys)
    assert end["enabled"] == 0
    # the steps of a calibration without the check, plus one question per verification pose
    assert user.said == [servo_zero.ZERO_POSE, *servo_zero.DIRECTION_QUESTIONS,
                         *[f"Is the arm now {servo_zero.sight(m, p)}?" for p in servo_zero.VERIFY],
                         f"write these changes to {lab_model}?"]


def assert_calibrated(lab, capsys, truth=TRUTH, **sitl_options):
    """The calibration of the arm whose model file is lab, by a careful user: the servos' true
    zeros and directions written, both load checks passed, no shaft ever in the body or a
    leg. (model written, the user, the last heartbeat)."""
    s, arm = bench(truth, **sitl_options)
    user = User(s, config.load(lab))
    try:
        assert servo_zero.servos(arm, lab, user.ask, user.confirm, seconds=SECONDS)
        end = arm.next_heartbeat()
    finally:
        arm.close()
        s.stop()
    m = config.load(lab)
    assert [sv.zero for sv in m.servos] == list(truth[0])
    assert [sv.direction for sv in m.servos] == list(truth[1])
    out = capsys.readouterr().out
    loads = [line.strip() for line in out.splitlines() if "holds against gravity the way direction" in line]
    least = least_clearance(s, m, truth)
    with capsys.disabled():
        print("\n" + "\n".join(loads) + f"\nleast clearance of the shafts: {least:.1f} mm")
    assert len(loads) == 2, out
    assert least > 0.0
    return m, user, end


CASES = {
    # a wrong keypress on joint 3's direction, and a user who then says yes to every pose
    "joint 3's direction answered wrongly": (dict(wrong=3, careless=True), True,
                                             r"servo holds the arm pushing .* direction of joint 2 or of joint 3 is wrong"),
    # joint 2 held 25 deg off at the zero pose: its zero is 85 units from the file's
    "joint 2 held 25 deg off": (dict(off_deg=(0.0, 25.0, 0.0)), False, r"servo\.theta2\.zero .*--allow-unusual"),
    "joint 2 held 25 deg off, allowed": (dict(off_deg=(0.0, 25.0, 0.0)), True,
                                         r"was not the upper arm still hanging .* take the zero pose again"),
    # joint 2 held 25 deg the other way and answered the other way round, every pose said yes to
    "joint 2 held -25 deg off and answered wrongly": (dict(off_deg=(0.0, -25.0, 0.0), wrong=2, careless=True), True,
                                                      r"servo holds the arm pushing .* direction of joint 2 or of joint 3 is wrong"),
    # both mistakes at once: stopped before the arm moves
    "joint 2 held 25 deg off and joint 3 answered wrongly": (dict(off_deg=(0.0, 25.0, 0.0), wrong=3), False,
                                                             r"servo\.theta2\.zero .*servo\.theta3\.direction"),
}


@realtime
@pytest.mark.parametrize("case", list(CASES))
def test_a_wrong_calibration_is_refused_before_anything_is_written(lab_model, case):
    """Each refused with what to do, the file's bytes unchanged, the supply off at the end, and
    no shaft ever in the body or a leg (the verification route is safe with the mistake)."""
    user_options, allow, message = CASES[case]
    assert_refused(lab_model, user_options, allow, message)


def assert_refused(lab, user_options, allow, message, truth=TRUTH, **sitl_options):
    """The calibration of the arm whose model file is lab, the user as user_options say,
    refused with message: the file's bytes unchanged, the supply off at the end, and no shaft
    ever in the body or a leg."""
    before = lab.read_bytes()
    s, arm = bench(truth, **sitl_options)
    user = User(s, config.load(lab), **user_options)
    try:
        with pytest.raises(CalibrationError, match=message):
            servo_zero.servos(arm, lab, user.ask, user.confirm, seconds=SECONDS, allow_unusual=allow)
        end = arm.next_heartbeat()
    finally:
        arm.close()
        s.stop()
    assert lab.read_bytes() == before
    assert end["enabled"] == 0
    assert least_clearance(s, config.load(lab), truth) > 0.0


@realtime
def test_an_enabled_arm_goes_limp_only_once_the_user_holds_it(lab_model):
    """A parked arm (the model's calibration right: no mounting given) is asked to be held
    before its torque goes off."""
    s, arm = enabled_sitl()
    torque = {}

    def ask(text):
        torque.setdefault(text.split(":")[0].split(",")[0], [sv.torque_on for sv in s.board.bus.servos])
        if text.startswith("Hold the arm hanging"):
            assert "held at 0 deg" in s.submit("hold zero").result(timeout=60)
        wait_simulated(s, 0.2)
    try:
        with pytest.raises(CalibrationError, match="unusual result"):      # joint 2: -1 in the file, +1 here
            servo_zero.servos(arm, lab_model, ask, lambda q: True, seconds=SECONDS)
    finally:
        arm.close()
        s.stop()
    assert torque["Hold the arm with one hand"] == [True] * 3
    assert torque["Hold the arm hanging straight down"] == [False] * 3


@realtime
def test_a_servo_unplugged_after_the_enable_is_named(lab_model):
    s, arm = bench()
    before = lab_model.read_bytes()
    try:
        arm.enable(limp=True)
        s.board.bus.servos = s.board.bus.servos[:2]                  # joint 3's cable pulled
        with pytest.raises(CalibrationError, match=r"no readings from the servo of joint\(s\) \[3\]"):
            servo_zero.servos(arm, lab_model, lambda text: wait_simulated(s, 0.2), lambda q: True, seconds=SECONDS)
    finally:
        arm.close()
        s.stop()
    assert lab_model.read_bytes() == before


@realtime
def test_a_servo_unplugged_before_the_enable_is_said(lab_model):
    s, arm = bench()
    s.board.bus.servos = s.board.bus.servos[:2]
    try:
        with pytest.raises(CalibrationError, match=r"the servos did not all answer .*servo_config.*connected"):
            servo_zero.servos(arm, lab_model, lambda text: wait_simulated(s, 0.2), lambda q: True, seconds=SECONDS)
    finally:
        arm.close()
        s.stop()


def test_the_command_line_will_not_answer_the_servo_calibrations_questions(tmp_path, capsys):
    """--yes would answer every direction and verification question yes: refused before the
    port is opened."""
    from uavarm import cli
    assert cli.main(["calibrate", "servos", "/dev/no-such-port", "--yes"]) == 2
    assert "--yes is not for `uavarm calibrate servos`" in capsys.readouterr().err


# ---------------------------------------------------------------- an X-series arm

# The same servos' mounting as TRUTH's, in XM430-W350 units (e-manuals: the AX-12A 300 deg over
# 1023 units about 512, the XM430-W350 360 deg over 4096 about 2048): each zero the same angle
# off the centre as there.
X_TRUTH_ZERO = tuple(round(2048 + (z - 512) * (300 / 1023) / (360 / 4096)) for z in TRUTH_ZERO)
X_TRUTH = (X_TRUTH_ZERO, TRUTH_DIRECTION)


@pytest.fixture
def xm430_lab(tmp_path, xm430):
    """(model file as a lab has it before its first servo calibration, SITL options): an
    XM430-W350 arm, every zero at the centre, joint 2's servo stated as mounted the other way
    round (as it is), served by the XM430-W350 build."""
    model, ffi, lib = xm430
    text = xm430_text()                  # the same arm's model file, as a lab writes it
    joint2 = "[servo.theta2]\nid = 2\nzero = 2048\ndirection = 1"
    assert joint2 in text
    path = tmp_path / "manipulator.toml"
    path.write_text(text.replace(joint2, joint2[:-1] + "-1"))
    return path, dict(model=model, lib=(ffi, lib))


@realtime
def test_an_xm430_arm_is_calibrated_with_the_verification_move(xm430_lab, capsys):
    """As for the AX-12A: jogs of 6 deg (68 units), the zeros in 4096 units a turn, and the
    load checks read the XM430-W350's Present Current (the firmware's load word): its sense is
    gravity's at both load poses, and no shaft is ever in the body or a leg."""
    lab, options = xm430_lab
    m, _, end = assert_calibrated(lab, capsys, X_TRUTH, **options)
    assert end["enabled"] == 0
    assert m.servo_model.name == "XM430-W350"


@realtime
def test_an_xm430_joint_answered_the_wrong_way_is_caught_by_its_present_current(xm430_lab):
    """Joint 3's jog answered the wrong way and every pose said yes to: the Present Current
    at the forearm-level pose pushes the other way than that direction says; nothing written."""
    lab, options = xm430_lab
    assert_refused(lab, dict(wrong=3, careless=True), True,
                   r"servo holds the arm pushing .* direction of joint 2 or of joint 3 is wrong", X_TRUTH, **options)
