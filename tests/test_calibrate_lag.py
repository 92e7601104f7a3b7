"""Servo lag identification: the fit alone on records made by scipy.signal, then `uavarm
calibrate lag` end to end over the link to the SITL, whose servos lag their goal by a
"hardware truth" time constant the model file does not know.

The fit's verdict and the end-to-end run on AX-12As and on XM430-W350s, whose readings are
in finer units (e-manuals: 300 deg over 1023 units; 360 deg over 4096).

Oracles: scipy.signal's simulation of a first-order lag with dead time; the simulated
servos' own time constant (their motion model, apart from the firmware and the fit).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from uavarm.build import variants
from uavarm.calibrate import fit, guide
from uavarm.calibrate.fit import CalibrationError
from uavarm.link import ArmLink
from uavarm.model import config
from uavarm.sim.sitl import Sitl

from simboard_tools import family_lib, family_servos
from test_calibrate import enabled_sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)

SPEED = 2.0                        # simulated seconds per real second
UNITS_PER_S = 180.0                # a goal ramp about the park speed's
DEG_PER_UNIT = {"AX-12A": 300 / 1023, "XM430-W350": 360 / 4096}     # the e-manuals'
AX = DEG_PER_UNIT["AX-12A"]


def ramp_record(dead, tau, start=0.0, travel=50.0, period=0.03, seed=0):
    """(t, goal, position) read every `period` s: the goal ramps `travel` units and stops, the
    shaft follows through x' = (g(t - dead) - x) / tau (scipy.signal), readings rounded to
    whole units, each at its own jitter within the period."""
    rng = np.random.default_rng(seed)
    fine = np.arange(0.0, 0.8, 1e-4)
    goal = start + np.clip((fine - 0.05) * UNITS_PER_S, 0.0, abs(travel)) * math.copysign(1, travel)
    delayed = np.interp(fine - dead, fine, goal)
    _, shaft, _ = signal.lsim(([1.0], [tau, 1.0]), delayed - start, fine)
    t = np.arange(0.0, 0.8, period) + rng.uniform(0, period / 3, size=round(0.8 / period))
    t = t[t < fine[-1]]
    return t, np.round(np.interp(t, fine, goal)), np.round(np.interp(t, fine, shaft + start))


@pytest.mark.parametrize("dead, tau", [(0.0, 0.02), (0.004, 0.0265), (0.01, 0.045)])
def test_the_fit_finds_the_lag_behind_a_ramp(dead, tau):
    """The lag dead + tau within 2 ms over six draws of the readings' timing; how it splits
    into the two is not (readings 30 ms apart and whole units: up to 10 ms off), and is not
    used."""
    for seed in range(6):
        records = [ramp_record(dead, tau, seed=seed), ramp_record(dead, tau, start=50.0, travel=-50.0, seed=seed + 10)]
        assert fit.fit_servo_lag(records, 1, AX).lag == pytest.approx(dead + tau, abs=0.002)


def test_the_fit_refuses_a_shaft_that_did_not_follow():
    t, goal, _ = ramp_record(0.0, 0.02)
    with pytest.raises(CalibrationError, match="joint 2's servo moved 0 of the 50 units its goal did"):
        fit.fit_servo_lag([(t, goal, np.zeros_like(goal))], 2, AX)


def test_the_fit_refuses_a_shaft_pushed_about():
    t, goal, pos = ramp_record(0.0, 0.02)
    pos = pos + np.where(np.arange(len(pos)) % 4 == 0, 6.0, 0.0)     # a hand on the arm
    with pytest.raises(CalibrationError, match="does not follow its goal like a lag"):
        fit.fit_servo_lag([(t, goal, pos)], 3, AX)


TICK = 0.01                        # s: the firmware's goals, one a tick (sample_rate 100 Hz)
JOG_DEG = math.degrees(0.25)       # the lag calibration's jog, at the park speed (10 rpm)


def tick_jog(tau, deg_per_unit, back=False, pushed_deg=0.0):
    """(t, goal, position) of a jog as the firmware makes it, read in a servo's units: a goal
    step every tick along a 60 deg/s ramp of JOG_DEG, the servo's profile reaching each step
    as the next is sent, the shaft following that profile through x' = (p - x) / tau
    (scipy.signal). The servo is read every third tick (three servos in turn), just after it,
    here from the ramp's first step on: of the three ticks a reading may fall on, the one whose
    readings, 30 ms apart, cut the ramp's corners the most. pushed_deg: every fourth reading
    that far off (a hand on the arm)."""
    fine = np.arange(0.0, 0.8, 1e-4)

    def ramp(t):
        return np.clip((t - 0.05) * 60.0, 0.0, JOG_DEG)
    sent = ramp(0.05 + np.floor((fine - 0.05 + 1e-9) / TICK) * TICK)
    profile = ramp(fine - TICK)
    shaft = signal.lsim(([1.0], [tau, 1.0]), profile, fine)[1] if tau > 0 else profile
    t = 0.05 + TICK * (1 + 3 * np.arange(-1, 24)) + 2e-4
    off = np.where(np.arange(len(t)) % 4 == 0, pushed_deg, 0.0)
    sign = -1.0 if back else 1.0
    return (t, np.round(2048 + sign * np.interp(t, fine, sent) / deg_per_unit),
            np.round(2048 + sign * (np.interp(t, fine, shaft) + off) / deg_per_unit))


@pytest.mark.parametrize("servo", DEG_PER_UNIT)
def test_the_fit_judges_the_shafts_motion_not_its_units(servo):
    """A servo that follows its profile at once, jogged out and back: the misfit is all the
    ramp's corners, 0.15 deg rms, which is 0.5 of an AX-12A's units and 1.8 of an XM430-W350's.
    Taken on both, the lag one tick (the jog's own); a hand pushing the shaft 1.8 deg (6 of an
    AX-12A's units) at every fourth reading is refused on both."""
    d = DEG_PER_UNIT[servo]
    assert fit.fit_servo_lag([tick_jog(0.0, d), tick_jog(0.0, d, back=True)], 1, d).lag == \
        pytest.approx(TICK, abs=0.001)
    with pytest.raises(CalibrationError, match="does not follow its goal like a lag"):
        fit.fit_servo_lag([tick_jog(0.0, d, pushed_deg=6 * AX), tick_jog(0.0, d, True, 6 * AX)], 1, d)


# ---------------------------------------------------------------- through the SITL

@pytest.fixture
def model_copy(tmp_path):
    path = tmp_path / "manipulator.toml"
    path.write_text(config.DEFAULT_MODEL.read_text())
    return path


def servo_arm(path, servo):
    """SITL options for an arm of `servo`s, whose model file is written at path: the committed
    one, or for XM430-W350s it made an arm of them (variants.XM430_EDITS) and its build."""
    if servo == "AX-12A":
        return {}
    path.write_text(variants.edited_text(variants.XM430_EDITS))
    return dict(model=family_servos(servo).model, lib=family_lib(servo))


def calibrated(path, truth, **sitl_options):
    """The model file at path after `calibrate lag` on a SITL whose servos lag by truth (s)."""
    s, arm = enabled_sitl(servo_lag=truth, **sitl_options)
    try:
        assert guide.lag(arm, path, lambda text: None, lambda q: True)
    finally:
        arm.close()
        s.stop()
    return config.load(path)


@pytest.mark.parametrize("servo", DEG_PER_UNIT)
@pytest.mark.parametrize("truth", [0.015, 0.045])
def test_lag_calibration_measures_the_servos_and_moves_the_lead_time(model_copy, truth, servo, monkeypatch):
    """The shafts lag by `truth` (first order) behind their speed-limited profile (an AX-12A's
    Moving Speed; an XM430-W350's Profile Velocity): the servo lag written is that within 3 ms
    (the rest: the goal's way over the bus and the reading's age), each joint's readings fitted
    in its servo's units, and the lead time moves by the difference."""
    options = servo_arm(model_copy, servo)
    before = config.load(model_copy)
    assert before.servo_model.name == servo
    units, fit_servo_lag = [], fit.fit_servo_lag

    def fitted(records, joint, deg_per_unit):       # the units each joint's readings are fitted in
        units.append(deg_per_unit)
        return fit_servo_lag(records, joint, deg_per_unit)
    monkeypatch.setattr(fit, "fit_servo_lag", fitted)
    after = calibrated(model_copy, truth, **options)
    assert units == pytest.approx([DEG_PER_UNIT[servo]] * 3)
    assert after.servo_response_lag == pytest.approx(truth, abs=0.003)
    moved = after.estimator.lead_time - before.estimator.lead_time
    assert moved == pytest.approx(after.servo_response_lag - before.servo_response_lag, abs=1e-4)
    assert "# Seconds the shaft lags its goal" in model_copy.read_text()      # comments kept


def test_a_lag_beyond_an_ax12a_and_a_lead_time_moved_far_are_refused(model_copy):
    """Shafts lagging 90 ms (more than an AX-12A's 80 ms: blocked, loaded or under-powered):
    refused with both keys named, the lead time having moved 63.5 ms; the file as it was."""
    s, arm = enabled_sitl(servo_lag=0.09)
    before = model_copy.read_bytes()
    try:
        with pytest.raises(CalibrationError) as err:
            guide.lag(arm, model_copy, lambda text: None, lambda q: True)
    finally:
        arm.close()
        s.stop()
    msg = str(err.value)
    assert "servo.response_lag" in msg and "outside an AX-12A's 5-80 ms" in msg, msg
    assert "estimator.lead_time" in msg and "more than 30 ms" in msg and "--allow-unusual" in msg, msg
    assert model_copy.read_bytes() == before


def test_lag_calibration_with_a_servo_unplugged_names_it_and_writes_nothing(model_copy):
    s, arm = enabled_sitl(servo_lag=0.02)
    before = model_copy.read_bytes()
    s.board.bus.servos = s.board.bus.servos[:2]                  # joint 3's cable pulled
    try:
        with pytest.raises(CalibrationError, match="joint 3's servo"):
            guide.lag(arm, model_copy, lambda text: None, lambda q: True)
    finally:
        arm.close()
        s.stop()
    assert model_copy.read_bytes() == before


def test_lag_calibration_refuses_an_arm_not_enabled(model_copy):
    s = Sitl(speed=SPEED).start()
    before = model_copy.read_bytes()
    try:
        with ArmLink(s.device, clock=s.clock) as arm:
            with pytest.raises(CalibrationError, match="must be enabled and not engaged"):
                guide.lag(arm, model_copy, lambda text: None, lambda q: True)
    finally:
        s.stop()
    assert model_copy.read_bytes() == before

