"""The drone's messages are claims checked against the arm's own IMU (stabiliser.c's gate),
on the simulated board running the whole firmware, level and still, the arm engaged:
lies about the attitude and the velocity are refused, counted and flagged in the heartbeat
while the estimate goes on without them, and honest data is taken back. The oracle is the
plain truth: the board does not tilt, so any tilt in the estimate is the lie's doing. The
servos are the slowest the tests allow for (45 ms of lag, a 9.0 V supply sagging as they
move), and their shafts are judged by plain geometry at every step (tests/invariants.py).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from invariants import Invariants
from simboard_tools import FAULT, make_board, ready
from uavarm.link import messages
from uavarm.model import config
from uavarm.sim import closed_loop, scenarios
from uavarm.build import variants

MODEL = config.load()
TARGET = dict(x=70.0, y=-20.0, z=-95.0)
SOURCE = {name: 1 << i for i, (name, _) in enumerate(messages.SOURCES)}
PERIOD = 0.02            # the drone's messages at 50 Hz
DELAY = 0.02             # measured this long before they arrive
DRONE_CLOCK_US = 3_000_000_000   # the drone's clock, far from the board's (it wraps in the run)
SLOWEST_LAG, SLOWEST_SUPPLY = 0.045, 9.0   # s, V: the slowest servos the tests allow for


class Drone:
    """The drone's computer: attitude and velocity at 50 Hz, stamped in its own clock, each
    arriving DELAY after it was measured; `claim` says what it sends at a time (default: the
    truth, level and still)."""

    def __init__(self, inv: Invariants, attitude=True, velocity=True):
        self.inv, self.board, self.attitude, self.velocity = inv, inv.board, attitude, velocity
        self.seq = 0
        self.tilts: list[float] = []     # the estimate's tilt (deg) after each period

    def stamp(self, t_meas: float) -> int:
        return (DRONE_CLOCK_US + round(t_meas * 1e6)) & 0xFFFFFFFF

    def fly(self, seconds: float, roll=lambda k: 0.0, velocity=lambda k: (0.0, 0.0, 0.0)):
        """seconds of messages; roll(k) and velocity(k) give the k-th message's claim."""
        for k in range(round(seconds / PERIOD)):
            t_meas = self.board.time - DELAY
            seq = self.seq & 0xFFFF
            if self.attitude:
                self.board.send("drone_attitude", seq=seq, stamp_us=self.stamp(t_meas), roll=roll(k), pitch=0.0)
            if self.velocity:
                vx, vy, vz = velocity(k)
                self.board.send("drone_velocity", seq=seq, stamp_us=self.stamp(t_meas), vx=vx, vy=vy, vz=vz)
            self.seq += 1
            if k % 10 == 0:
                self.board.send("set_position", **TARGET)   # the keep-alive
            self.inv.run(PERIOD)
            self.tilts.append(tilt_deg(self.board))


def tilt_deg(board) -> float:
    """The angle between the estimate's up and the truth's (the board is level)."""
    up = np.array(list(board.app.stab.up))
    return math.degrees(math.acos(min(1.0, up[2] / np.linalg.norm(up))))


def engaged(**drone_kw) -> Drone:
    """A level, still board on the slowest servos, engaged at TARGET with 2 s of honest
    messages behind it; its shafts judged from then on (Invariants)."""
    board = make_board(lag=SLOWEST_LAG, supply=SLOWEST_SUPPLY)
    inv = Invariants(board)
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 2.0) is not None
    board.send("set_position", **TARGET)
    board.send("engage", on=1)
    drone = Drone(inv, **drone_kw)
    drone.fly(2.0)
    hb = board.heartbeats[-1]
    assert hb["engaged"] == 1 and hb["faults"] & (FAULT["drone_attitude_rejected"] | FAULT["drone_velocity_rejected"]) == 0
    return drone


def flags(board) -> tuple[int, int]:
    """(faults, estimate_sources) of the latest heartbeat."""
    hb = board.heartbeats[-1]
    return hb["faults"], hb["estimate_sources"]


@pytest.mark.parametrize("velocity", [False, True], ids=["attitude alone", "with the velocity"])
def test_a_25_deg_roll_claimed_on_a_level_board_is_refused_flagged_and_taken_back_when_true(velocity):
    """The drone claims a constant 25 deg roll for 2 s: the estimate moves <= 3 deg (it is
    never taken: 25 deg is beyond the gate at its widest, 15.4), the stream is dropped after
    reject_after and drone_attitude_rejected raised; the estimate then uses the accelerometer
    (or the velocity). Honest messages again: taken back after retake_after, the flag down."""
    drone = engaged(velocity=velocity)
    board, stab = drone.board, drone.board.app.stab
    accepted = stab.link.accepted
    drone.fly(2.0, roll=lambda k: math.radians(25.0))
    print(f"\n25 deg claimed ({'with' if velocity else 'without'} the velocity): estimate's tilt at most "
          f"{max(drone.tilts[-100:]):.3f} deg; {stab.link.disagreed} refused by the gate")
    assert max(drone.tilts[-100:]) <= 3.0
    assert stab.link.accepted == accepted and stab.link.disagreed >= 99 and stab.link.rejections == 1
    faults, sources = flags(board)
    assert faults & FAULT["drone_attitude_rejected"] and not faults & FAULT["drone_velocity_rejected"]
    assert sources == (SOURCE["drone_velocity"] if velocity else SOURCE["accelerometer"])
    drone.fly(1.0)
    faults, sources = flags(board)
    assert not faults & FAULT["drone_attitude_rejected"] and sources & SOURCE["drone_attitude"]
    assert stab.link.accepted > accepted and max(drone.tilts[-50:]) <= 3.0
    assert drone.inv.shaft_steps > 10_000 and drone.inv.clearance > 0.0   # the shafts, judged


def test_a_roll_jumping_20_deg_each_message_moves_the_estimate_at_most_3_deg():
    """The drone's roll alternates +20 / -20 deg at 50 Hz for 2 s (attitude alone): every
    message is refused; the estimate stays within 3 deg and the stream is flagged."""
    drone = engaged(velocity=False)
    drone.fly(2.0, roll=lambda k: math.radians(20.0 if k % 2 else -20.0))
    stab = drone.board.app.stab
    print(f"\n+-20 deg alternating: estimate's tilt at most {max(drone.tilts[-100:]):.3f} deg")
    assert max(drone.tilts[-100:]) <= 3.0
    assert flags(drone.board)[0] & FAULT["drone_attitude_rejected"]
    assert drone.inv.shaft_steps > 10_000 and drone.inv.clearance > 0.0


def test_velocity_stamps_running_ahead_ten_a_tick_ramping_just_under_a_jump_tilt_at_most_5_deg():
    """1,000 drone_velocity messages in 1 s, ten per 10 ms tick, each stamped 100 ms after the
    one before and 1.9 m/s faster (just under the 2 m/s of an odometry reset; up to 45 m/s and
    back down): the stamps running ahead of the board's clock are refused as such, the rest by
    the gate; the estimate's tilt stays within 5 deg during the attack and the second after,
    and the stream is flagged."""
    drone = engaged(attitude=False)
    board, stab = drone.board, drone.board.app.stab
    ahead, disagreed = stab.vel.refused - stab.vel.disagreed, stab.vel.disagreed
    t_meas, v, step, seq = board.time - DELAY, 0.0, 1.9, drone.seq
    tilts = []
    for tick in range(100):
        for _ in range(10):
            t_meas += 0.1
            if abs(v + step) > 45.0:
                step = -step
            v += step
            board.send("drone_velocity", seq=seq & 0xFFFF, stamp_us=drone.stamp(t_meas), vx=v, vy=0.0, vz=0.0)
            seq += 1
        if tick % 10 == 0:
            board.send("set_position", **TARGET)
        drone.inv.run(0.01)
        tilts.append(tilt_deg(board))
    for _ in range(50):           # then silence but the keep-alive, a second
        board.send("set_position", **TARGET)
        drone.inv.run(0.02)
        tilts.append(tilt_deg(board))
    ahead = stab.vel.refused - stab.vel.disagreed - ahead
    print(f"\nvelocity stamps ahead: tilt at most {max(tilts):.3f} deg; {ahead} refused as ahead of the clock, "
          f"{stab.vel.disagreed - disagreed} by the gate")
    assert max(tilts) <= 5.0
    assert ahead >= 900
    assert stab.vel.rejections == 1 and board.heartbeats[-1]["faults"] & FAULT["drone_velocity_rejected"]
    assert drone.inv.shaft_steps > 10_000 and drone.inv.clearance > 0.0


@pytest.mark.parametrize("name", ["manoeuvre", "hover"])
def test_honest_flights_refuse_nothing(name):
    """The simulator's lateral manoeuvre (10-15 deg, 2.5 m/s legs) and gusty hover, the
    committed model, the flight controller and odometry with their default errors: the gate
    refuses no message of either stream and drops neither (30 s from engage)."""
    scenario = scenarios.load(name)
    run = closed_loop.simulate(scenario, variants.build({}), seed=1,
                               settings=closed_loop.Settings(seconds=30.0, settle=0.0, preflight=2.0))
    print(f"\n{name}: gate refusals {run.gate_refusals}")
    assert run.gate_refusals == {"drone_attitude": (0, 0), "drone_velocity": (0, 0)}
