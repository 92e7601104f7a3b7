"""First-flight hardening, on the simulated board: servos that brown out, engage before the
arm is ready, a link whose own output comes back, a tick interrupt or clock that stops, an
IMU whose clock runs off the tick's. Each is a fault a board meets in its first flights; each
test drives it through the bytes and signals the hardware has and checks the reaction the
fault table states, with tests/invariants.py watching every step. Engage at every
moment of start-up and engage with a servo silent run on AX-12As and on XM430-W350s
(simboard_tools.FAMILIES); the rest on AX-12As (the X-series' brown-out and EEPROM tests are
test_xseries_board.py's and test_servo_bus2.py's).

Oracles: the AX-12A control table (Torque Enable at 24, RAM reset to its power-on values),
the heartbeat's written layout, plain geometry, the rocking's own attitude (scipy).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from invariants import Invariants
from simboard_tools import (
    FAMILIES, FAULT, IDS, IMU_SETTLE_S, MODEL, PARK_SPEED, TICK, BusLog, family_board, make_board, ready, run_until,
    running, shaft_units, sync_goal_speed,
)
from uavarm.link import messages
from uavarm.sim.board import Rocking, SimBoard

TARGET = (70.0, -20.0, -95.0)
REFUSAL = {name: k for k, (name, _) in enumerate(messages.REFUSALS)}
STATE = {name: k for k, (name, _) in enumerate(messages.STATES)}
TORQUE_ENABLE = 24                # AX-12A e-manual control table


def set_position(board, p):
    board.send("set_position", x=float(p[0]), y=float(p[1]), z=float(p[2]))


def engaged(**kw):
    board = make_board(**kw)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.0) is not None
    set_position(board, TARGET)
    board.send("engage", on=1)
    assert inv.run_until(lambda: board.heartbeats and board.heartbeats[-1]["state"] == STATE["holding"], 2.0)
    return board, inv


def keep_alive(inv, seconds, every=0.2):
    end = inv.board.time + seconds
    while inv.board.time < end - 1e-9:
        set_position(inv.board, TARGET)
        inv.run(min(every, end - inv.board.time))


# ---------------------------------------------------------------- servos that brown out

@pytest.mark.parametrize("j", [0, 1, 2])
def test_a_servo_that_browns_out_is_set_up_again_and_the_arm_parks(j):
    """Servo j's supply dips while engaged: it comes back with its RAM reset (torque off, limp
    where it sagged). Its next status reading shows Torque Enable 0; the driver writes it up
    again at once (torque on, LED off, compliance as after power-up, holding where it stands
    at the park speed, Torque Limit as configured), counts it, the heartbeat says servo_reset, and the arm parks from where it now is; engage works
    again after."""
    board, inv = engaged()
    servo = board.bus.servo(IDS[j])
    servo.power_off()
    servo.power_on()                                  # RAM back to its power-on values
    sagged = float(round(servo.position) + 25 | 1)    # a little while limp (an odd unit: every bit)
    servo._pos = servo._profile = sagged
    assert servo.table[TORQUE_ENABLE] == 0
    t0 = board.time
    assert inv.run_until(lambda: servo.table[TORQUE_ENABLE] == 1, 3 * 3 * TICK) is not None
    print(f"\nservo {j + 1} reset: torque on again {(board.time - t0) * 1e3:.0f} ms later")
    assert (servo.register("goal_position"), servo.register("moving_speed"), servo.register("led")) \
        == (sagged, PARK_SPEED, 0)
    # the AX-12A's power-up compliance (e-manual: margins 1, slopes 32); Torque Limit one below
    # Max Torque, as enable configures it
    assert [servo.register(f"{side}_compliance_{what}") for what in ("margin", "slope") for side in ("cw", "ccw")] \
        == [1, 1, 32, 32]
    assert servo.register("torque_limit") == 1022
    keep_alive(inv, 0.6)
    hb = board.heartbeats[-1]
    assert hb["servo_resets"] == 1 and hb["faults"] & FAULT["servo_reset"] and hb["engaged"] == 0, hb
    assert inv.run_until(lambda: board.heartbeats[-1]["state"] == STATE["parked"], 4.0) is not None
    board.send("engage", on=1)
    assert inv.run_until(lambda: board.heartbeats[-1]["state"] == STATE["holding"], 3.0) is not None
    assert not board.heartbeats[-1]["faults"] & FAULT["servo_reset"], "cleared by the next engage"


def test_enable_writes_the_eeprom_only_where_it_differs():
    """A servo whose EEPROM already holds the configuration gets no EEPROM write at enable;
    one whose safety registers were changed (Alarm Shutdown off, a high temperature limit)
    gets just those written back."""
    board = make_board()
    board.send("enable", on=1)
    assert run_until(board, lambda: running(board), 0.5) is not None
    board.send("enable", on=0)
    board.run(0.1)
    first = [board.app.bus.servo[j].eeprom_writes for j in range(3)]
    s = board.bus.servo(IDS[1])
    s.set_register("shutdown", 0)
    s.set_register("temperature_limit", 95)
    n = len(board.commands)
    board.send("enable", on=1)
    assert run_until(board, lambda: len(board.commands) > n, 0.5) is not None
    again = [board.app.bus.servo[j].eeprom_writes - first[j] for j in range(3)]
    assert again == [0, 2, 0], again
    assert s.register("shutdown") == 0x24 and s.register("temperature_limit") == 70


# ---------------------------------------------------------------- engage only when ready

@pytest.mark.parametrize("family", FAMILIES)
def test_engage_at_every_moment_of_start_up(family):
    """engage sent 0 to 0.9 s after power-up and enable: refused while the servos boot and are
    configured (servos_starting) and while the IMU has not given the estimator one time
    constant of samples (imu_not_ready); taken once both hold, and then the arm goes from
    the park pose at the transit speed, never at the working speed from where it hung."""
    seen = set()
    for at in np.arange(0.0, 0.91, 0.05):
        board = family_board(family, at=[0.0, 0.0, 0.0])      # hanging with every joint at its zero
        inv = Invariants(board, BusLog(board))
        board.send("enable", on=1)
        inv.run(at)
        # the IMU gives one sample per tick from the first (at 10 ms): enough once there are
        # one time constant's worth
        servos, imu = running(board), round(board.time / TICK) >= round(IMU_SETTLE_S / TICK)
        board.send("engage", on=1)
        inv.run(TICK)
        want = "none" if servos and imu else "servos_starting" if not servos else "imu_not_ready"
        assert board.app.refusal == REFUSAL[want], (at, board.app.refusal, want)
        assert bool(board.app.engaged) == (want == "none")
        seen.add(want)
    assert seen == {"servos_starting", "imu_not_ready", "none"}


@pytest.mark.parametrize("family", FAMILIES)
def test_engage_with_a_servo_silent_is_refused_with_the_reason(family):
    """Servo 3 stops answering after configuration (servo_timeout stands): engage is refused
    (servo_fault) until it answers again."""
    board = family_board(family)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.0) is not None
    gone = board.bus.servo(IDS[2])
    board.bus.servos.remove(gone)
    inv.run(0.3)
    board.send("engage", on=1)
    inv.run(TICK)
    assert not board.app.engaged and board.app.refusal == REFUSAL["servo_fault"]
    hb = inv.next_heartbeat()
    assert hb["refusal"] == REFUSAL["servo_fault"] and hb["faults"] & FAULT["servo_timeout"]
    board.bus.add(gone)
    inv.run(0.3)
    board.send("engage", on=1)
    inv.run(TICK)
    assert board.app.engaged


def test_engage_before_the_imu_has_given_a_sample_is_refused():
    board = make_board()
    board.hp.imu_present = False
    board.send("enable", on=1)
    board.run(1.0)
    board.send("engage", on=1)
    board.run(TICK)
    assert not board.app.engaged and board.app.refusal == REFUSAL["imu_not_ready"]


# ---------------------------------------------------------------- link liveness

def test_the_boards_own_output_looped_back_does_not_keep_the_link_alive():
    """Everything the board sends comes back to it (a terminal that echoes). The drone stops
    sending: the arm parks after the link's silence timeout as without the echo, and the
    heartbeat counts the echoed frames."""
    board, inv = engaged()
    set_position(board, TARGET)                       # the drone's last frame
    board.link_echo = True
    t_last = board.time
    inv.run(MODEL.link_silence_timeout + 0.6)
    hb = board.heartbeats[-1]
    assert hb["engaged"] == 0 and hb["faults"] & FAULT["link_lost"], hb
    assert hb["link_echoes"] >= 2
    parked_at = min(p.start for p in inv.log.syncs(t_last) if sync_goal_speed(p.raw)[1] == [PARK_SPEED] * 3)
    assert MODEL.link_silence_timeout <= parked_at - t_last <= MODEL.link_silence_timeout + 2 * TICK


# ---------------------------------------------------------------- the tick and the clock

def test_a_stopped_tick_interrupt_is_made_up_from_the_clock_and_flagged():
    """The tick timer's interrupt stops for 5 s while the drone keeps the link alive: the main
    loop runs the ticks from the microsecond clock (a SYNC_WRITE every tick on), the heartbeats
    say timing and count the late ticks; the arm stays engaged and stabilised."""
    board, inv = engaged()
    board.tick_interrupt = False
    inv.max_sync_gap = 1.5 * TICK + 2 * board.poll_us / 1e6   # ticks from the clock: at 1.5 periods
    t0 = board.time
    keep_alive(inv, 5.0)
    syncs = inv.log.syncs(t0)
    assert len(syncs) >= 5.0 / (1.5 * TICK) - 2
    hbs = [hb for hb, t in zip(board.heartbeats, board.heartbeat_times) if t > t0 + 0.1]
    assert all(hb["faults"] & FAULT["timing"] and hb["engaged"] == 1 for hb in hbs), hbs
    assert hbs[-1]["ticks_late"] >= len(syncs) - 2
    board.tick_interrupt = True
    keep_alive(inv, 1.1)
    assert not board.heartbeats[-1]["faults"] & FAULT["timing"]


def test_a_stopped_clock_cuts_the_servo_power():
    """The microsecond clock stops (TIM2): nothing can be timed, no link silence, no bus
    timeout. Three ticks later the servo supply is off, and the fault latches until enable."""
    board, inv = engaged()
    board.clock_frozen = True
    t0 = board.time
    board.run(5 * TICK)
    assert not board.servo_power
    off_at = board.power_log[-1][0]
    assert off_at - t0 <= (3 + 1) * TICK + 1e-9     # README: the clock still for 3 ticks
    board.clock_frozen = False
    board.run(0.6)
    hb = board.heartbeats[-1]
    assert hb["enabled"] == 0 and hb["faults"] & FAULT["timing"], hb
    board.send("enable", on=1)
    board.run(0.6)
    assert board.heartbeats[-1]["enabled"] == 1 and not board.heartbeats[-1]["faults"] & FAULT["timing"]


# ---------------------------------------------------------------- sensor timing

@pytest.mark.parametrize("error", [-0.02, 0.0, 0.02])
def test_an_imu_clock_off_by_two_percent_keeps_the_attitude(error):
    """The MPU-6050's clock 2 % slow or fast against the tick's: samples repeat (no new data
    at a tick) or are skipped. The estimator integrates the measured time between the
    samples it takes, so the attitude on a rocking bench (+-10 deg at 0.3 Hz, ideal sensor,
    not engaged) stays within 0.5 deg RMS of the truth, as with the clocks in step."""
    from uavarm.sim.imu_model import Mpu6050Sensor
    motion = Rocking(math.radians(10), math.radians(8), 0.3)
    board = SimBoard(MODEL, motion=motion, imu_clock_error=error, sensor=Mpu6050Sensor("ideal", seed=0))
    roll, pitch = board.ffi.new("float *"), board.ffi.new("float *")
    stab = board.ffi.addressof(board.app, "stab")
    board.run(2.0)
    errors = []
    for _ in range(600):
        board.run(TICK)
        board.lib.stab_attitude(stab, roll, pitch)
        r_true, p_true = motion.attitude(board.time)
        est = Rotation.from_euler("YX", [pitch[0], roll[0]])
        truth = Rotation.from_euler("YX", [p_true, r_true])
        errors.append(math.degrees((est.inv() * truth).magnitude()))
    rms = float(np.sqrt(np.mean(np.square(errors))))
    print(f"\nIMU clock {error:+.0%}: attitude error rms {rms:.3f} deg, samples more than 1.5 periods "
          f"apart {board.app.stab.gaps}")
    assert rms < 0.5
    if error < 0:
        assert board.app.stab.gaps > 0, "the slow clock's repeated samples were seen"
