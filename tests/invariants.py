"""The safety invariants of a fault-injection run on the simulated board, checked after
every step (tests/test_fault_injection.py). Everything is observed where the hardware
would see it: the servo-bus packets (BusLog), the supply switch, and the heartbeat frames.

Oracles, independent of the C under test: tests/oracles.py's plain geometry through
simboard_tools.Servos.poses_ok (joint limits, body, legs, with the servo rounding), the
model's servo map, the servos' written speed unit (the AX-12A's 0.111 rpm, the X-series'
0.229), the model's heartbeat period and tick, Protocol 1.0 or 2.0 framing: the board's
own model file says which servos it has.
"""
from __future__ import annotations

import math

import numpy as np

from simboard_tools import FAULT, MODEL, TICK, US, BusLog, Servos, shaft_units
import oracles
from uavarm.link import messages
from uavarm.sim.board import SimBoard

HB = MODEL.heartbeat_period
DITHER_RAD = math.radians(300.0) / 1023    # goal moves this small are rounding (an AX-12A's unit)


class Invariants:
    """After every check():
    - every servo packet left with the supply on and after the servos' boot time;
    - every SYNC_WRITE commands a pose inside the joint limits and clear of the body and
      the legs (plain geometry), at the park, transit or working speed;
    - motion: every goal is at most what its speed moves in the time since the previous
      one (plus a unit of rounding) from it, and the path the servos take between the two
      (each joint at that speed, arriving at its own time) is clear, sampled;
    - the shafts themselves (the simulated servos' positions, lagging and slowed by their
      supply as they are) stand in a safe pose at every physics step (the board's main-loop
      step) from the firmware's first command after power-on or torque-on until the torque
      or the supply goes off; `shaft_steps` counts the steps judged and `clearance` keeps the
      least distance (mm) from the body plane and the legs' zones;
    - every heartbeat has finite set position and joints (no NaN reaches the drone or a
      servo), engaged only while enabled, enabled exactly while the supply is on, and
      only known fault bits;
    - heartbeats keep coming: none further apart than the period (plus one main-loop pass);
    - ticks keep running: a SYNC_WRITE at least every `max_sync_gap` while the arm is
      enabled and its servos configured (and not limp on purpose: from the broadcast WRITE
      of Torque Enable 0 to the next SYNC_WRITE).
    disable() sends "enable 0" and checks the supply is off within one tick."""

    def __init__(self, board: SimBoard, log: BusLog | None = None):
        self.board = board
        self.servos = Servos(board.model)
        self.log = log or BusLog(board)
        self.n_tx = self.n_hb = 0
        self.checks = 0
        self.poll = board.poll_us / 1e6
        self.max_sync_gap = TICK + self.poll + 1e-9
        self._sync_from: float | None = None
        self._last_goal: tuple[float, list[int]] | None = None    # (time, units) while powered
        self.limp = False                 # torque off on purpose: no SYNC_WRITE is due
        self.segments = 0
        board.shaft_trace = []
        self._judged_from: float | None = None   # shafts judged from this time (commanded) on
        self.shaft_steps = 0
        self.clearance = math.inf
        self.kept: list[tuple[np.ndarray, np.ndarray]] | None = None   # [] keeps (times, units) judged

    def power_at(self, t: float) -> tuple[bool, float]:
        """(on, since when) of the servo supply at time t."""
        state, since = False, 0.0
        for when, on in self.board.power_log:
            if when <= t + 1e-12:
                state, since = on, when
        return state, since

    def check(self) -> None:
        board, log, sv = self.board, self.log, self.servos
        for k in range(self.n_tx, len(log.tx)):
            p = log.tx[k]
            assert log.tx_power[k], f"{p.raw.hex(' ')} sent with the servo power off"
            assert p.start - self.power_at(p.start)[1] >= board.model.servo_boot_time - 1e-9, "sent during boot"
            if p.inst == 0x83:
                self.limp = False
                if self._judged_from is None or self._judged_from < self.power_at(p.start)[1]:
                    self._check_shafts(p.start)
                    self._judged_from = p.start
                goal, speed = sv.sync_goal_speed(p.raw)
                assert sv.poses_ok(goal)[0], ("unsafe command", goal, sv.units_to_joints(goal))
                assert speed in ([sv.park_speed] * 3, [sv.transit_speed] * 3, [sv.working_speed] * 3), speed
                self._check_move(p.start, goal, speed[0])
            elif sv.is_torque_off_to_all(p):
                self.limp = True          # torque off on purpose, until the next SYNC_WRITE
                self._check_shafts(p.start)
                self._judged_from = None
        self.n_tx = len(log.tx)
        self._check_shafts(board.time)
        for k in range(self.n_hb, len(board.heartbeats)):
            hb, t = board.heartbeats[k], board.heartbeat_times[k]
            assert not hb["engaged"] or hb["enabled"], hb
            assert bool(hb["enabled"]) == self.power_at(t)[0], (t, hb)   # (2: on, the bench)
            assert all(math.isfinite(hb[f]) for f in ("set_x", "set_y", "set_z", "q1", "q2", "q3")), hb
            assert hb["faults"] < 1 << len(messages.FAULTS), hb
            before = board.heartbeat_times[k - 1] if k > 0 else 0.0
            assert t - before <= HB + self.poll + 1e-9, f"heartbeat gap {t - before:.4f} s at {t:.3f} s"
        self.n_hb = len(board.heartbeats)
        last = board.heartbeat_times[-1] if board.heartbeat_times else 0.0
        assert board.time - last <= HB + self.poll + 1e-9, f"no heartbeat since {last:.3f} s"
        self._check_ticks()
        self.checks += 1

    def _check_move(self, t: float, goal: list[int], speed: int) -> None:
        """The move from the previous goal (same power-on) to this one: bounded, and clear
        along the servos' path."""
        on_since = self.power_at(t)[1]
        if self._last_goal is not None and self._last_goal[0] >= on_since:
            t0, before = self._last_goal
            # a servo the firmware found reset (limp where it sagged) is held where it stands:
            # for it the move starts from its shaft, not from its last goal
            shafts = self._shafts()
            before = [s if shafts is not None and abs(g - s) <= 1.0 and abs(g - b) > 1.0 else b
                      for g, s, b in zip(goal, shafts or goal, before)]
            travel = self.servos.speed_units_per_s(speed) * max(t - t0, TICK) + 1.0
            jump = max(abs(a - b) for a, b in zip(goal, before))
            assert jump <= travel, f"goal moved {jump} units at {t:.3f} s; speed {speed} allows {travel:.1f}"
            path = oracles.servo_path(before, goal)
            assert self.servos.poses_ok(path).all(), ("unsafe on the way", before, goal)
            self.segments += 1
        self._last_goal = (t, list(goal))

    def _check_shafts(self, until: float) -> None:
        """The shafts at every recorded step up to `until` (s): safe by plain geometry while
        judged (the supply on, since the first command after power-on or torque-on)."""
        board, sv = self.board, self.servos
        trace = board.shaft_trace
        n = next((k for k, row in enumerate(trace) if row[0] > until * US + 1e-6), len(trace))
        rows, board.shaft_trace = trace[:n], trace[n:]
        ids = [s.id for s in board.bus.servos]
        if not rows or self._judged_from is None or sorted(ids) != sorted(sv.ids):
            return
        a = np.array(rows, dtype=float)
        t = a[:, 0] / US
        power_on = max((when for when, on in board.power_log if on and when <= self._judged_from), default=math.inf)
        power_off = min((when for when, on in board.power_log if not on and when > power_on), default=math.inf)
        judged = (a[:, 1] > 0) & (t >= self._judged_from) & (t < power_off)
        units = a[judged][:, 2:][:, [ids.index(i) for i in sv.ids]]
        if not len(units):
            return
        ok = sv.poses_ok(units)
        bad = np.flatnonzero(~ok)
        assert not len(bad), (f"shafts in an unsafe pose at {t[judged][bad[0]]:.4f} s", units[bad[0]],
                               np.degrees(sv.units_to_joints(units[bad[0]])))
        self.shaft_steps += len(units)
        if self.kept is not None:
            self.kept.append((t[judged], units))
        self.clearance = min(self.clearance, float(oracles.clearance_mm(board.model, sv.units_to_joints(units)).min()))

    def shafts_at(self, times) -> np.ndarray:
        """The shafts (units, joint order) judged last at or before each of `times` (kept: set
        `kept = []` first)."""
        t = np.concatenate([k[0] for k in self.kept])
        units = np.concatenate([k[1] for k in self.kept])
        return units[np.maximum(np.searchsorted(t, times, side="right") - 1, 0)]

    def goals(self, since: float = -1.0) -> np.ndarray:
        """The SYNC_WRITE goals (units, one row per tick) sent after `since`."""
        return np.array([self.servos.sync_goal_speed(p.raw)[0] for p in self.log.syncs(since)], dtype=float).reshape(-1, 3)

    def check_steady(self, since: float, still: bool = False, min_gap: float = 0.1) -> dict:
        """At a fixed set position from `since` on: no joint hunts. On a still board no goal
        turns back at all; on a moving one no goal turns back and forth, turn after turn,
        less than `min_gap` s apart (an oscillation faster than the tilt that drives it:
        three turns within twice `min_gap`). A single quick turn, where a fast move meets
        the target's own turn, is not an oscillation. Moves of up to DITHER_RAD (rounding
        flips of a still target: an AX-12A's unit, three of an X-series') do not count.
        Returns the figures: per joint the range (units), the largest step (units per tick)
        and the number of turns."""
        dither = max(1, round(DITHER_RAD / self.servos.unit_rad))
        g = self.goals(since)
        turns = [turning_points(g[:, j], dither) for j in range(3)]
        for j, at in enumerate(turns):
            if still:
                assert not at, f"joint {j + 1}'s goal turns back {len(at)} times on a still board since {since:.2f} s"
            span = quickest_three_turns(at)
            assert span >= 2 * min_gap - 1e-9, f"joint {j + 1} turns back and forth three times within {span:.3f} s (hunting)"
        steps = np.abs(np.diff(g, axis=0)).max(axis=0) if len(g) > 1 else np.zeros(3)
        return {"range": g.max(axis=0) - g.min(axis=0), "step": steps, "turns": [len(t) for t in turns]}

    def _shafts(self) -> list[float] | None:
        """The simulated shafts' positions, if every servo is on the bus."""
        on_bus = {s.id for s in self.board.bus.servos}
        return shaft_units(self.board) if on_bus.issuperset(self.servos.ids) else None

    def _check_ticks(self) -> None:
        """While the servos run, a SYNC_WRITE at least every tick: the tick is never starved."""
        board = self.board
        if not (board.app.bus.state == 3 and board.servo_power) or self.limp:
            self._sync_from = None
            return
        if self._sync_from is None:
            self._sync_from = board.time
        times = [self._sync_from] + [p.start for p in self.log.syncs(self._sync_from)]
        times.append(board.time - TICK)     # the last one is at most a tick old
        for a, b in zip(times, times[1:]):
            assert b - a <= self.max_sync_gap, f"no SYNC_WRITE for {b - a:.4f} s after {a:.3f} s"
        self._sync_from = max(times[-2], self._sync_from)

    def run(self, seconds: float, step: float = 0.01) -> None:
        """Runs `seconds`, checking after every `step`."""
        end = self.board.time + seconds
        while self.board.time < end - 1e-9:
            self.board.run(min(step, end - self.board.time))
            self.check()

    def run_until(self, cond, timeout: float, step: float = 0.01) -> float | None:
        """Runs until cond() holds, checking after every step; the time, or None."""
        end = self.board.time + timeout
        while self.board.time < end - 1e-9:
            if cond():
                return self.board.time
            self.board.run(min(step, end - self.board.time))
            self.check()
        return self.board.time if cond() else None

    def next_heartbeat(self) -> dict:
        n = len(self.board.heartbeats)
        assert self.run_until(lambda: len(self.board.heartbeats) > n, HB + 0.02, step=0.002) is not None
        return self.board.heartbeats[-1]

    def flagged(self, name: str, within: float) -> float:
        """Runs until a heartbeat carries fault `name`; the time of that heartbeat."""
        start = len(self.board.heartbeats)
        t = self.run_until(lambda: any(hb["faults"] & FAULT[name] for hb in self.board.heartbeats[start:]),
                           within, step=0.005)
        assert t is not None, f"{name} not flagged within {within} s: {self.board.heartbeats[start:]}"
        return t

    def clear(self, name: str, within: float) -> dict:
        """Runs until a heartbeat no longer carries fault `name`; that heartbeat."""
        start = len(self.board.heartbeats)
        t = self.run_until(lambda: any(not hb["faults"] & FAULT[name] for hb in self.board.heartbeats[start:]),
                           within, step=0.005)
        assert t is not None, f"{name} still flagged after {within} s"
        return next(hb for hb in self.board.heartbeats[start:] if not hb["faults"] & FAULT[name])

    def disable(self) -> None:
        """enable 0: the supply is off within one tick, and no packet leaves after."""
        self.board.send("enable", on=0)
        t = self.board.time
        self.board.run(TICK)
        assert not self.board.servo_power, "power off within a tick of the disable frame"
        t_off = self.board.power_log[-1][0] if self.board.power_log else 0.0
        assert t_off - t <= TICK
        self.check()
        self.board.run(0.05)
        assert not [p for p in self.log.tx if p.start > t_off + 1e-9]
        self.check()


def quickest_three_turns(turns: list[int]) -> float:
    """s: the shortest time any three consecutive turns (tick indices) span; inf if fewer."""
    spans = (np.asarray(turns[2:]) - np.asarray(turns[:-2])) * TICK
    return float(spans.min()) if len(spans) else math.inf


def turning_points(values, dither: int = 1) -> list[int]:
    """Where a sequence turns back (the index of each extreme), ignoring moves of up to
    `dither` from the last extreme (a value that flips between two neighbours does not turn)."""
    turns, direction, extreme, at = [], 0, None, 0
    for i, v in enumerate(values):
        if extreme is None:
            extreme, at = v, i
        elif direction == 0:
            if abs(v - extreme) > dither:
                direction, extreme, at = (1 if v > extreme else -1), v, i
        elif (v - extreme) * direction > 0:
            extreme, at = v, i
        elif abs(v - extreme) > dither:
            turns.append(at)
            direction, extreme, at = -direction, v, i
    return turns
