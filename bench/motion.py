"""`make bench`, motion: how joint 1 and the servos' paths behave at the default set position
and at set positions on the edge of the workspace under heavy rocking, on the simulated
board (the firmware's host build), judged by plain geometry written here.

For each scenario: the range of joint 1's commanded angle once settled (2 s after engage),
its steps of more than 20 deg between consecutive goals, the largest step, the moves whose
path (every joint at the same speed, each arriving at its own time, 9 samples) passes a
joint limit, the body plane or a leg, and the heartbeats that flag the target out of reach;
then the shafts themselves, every simulated step (0.1 ms), judged the same way: with the model
file's servo lag on the default 3S supply (11.1 V, sagging), and worst case, 45 ms of lag on
9.0 V.
Then targets going straight past joint 1's axis: the goals the firmware sends, tick by tick,
against the target.
"""
from __future__ import annotations

import math

import numpy as np

from uavarm.build import firmware
from uavarm.link import messages
from uavarm.sim.board import Gravity, Rocking, SimBoard

UNIT_RAD = math.radians(300.0) / 1023      # AX-12A: 1023 position units over 300 deg
OUT_OF_REACH = 1 << [name for name, _ in messages.FAULTS].index("out_of_reach")


def scenarios():
    rock = lambda deg, hz: Rocking(math.radians(deg), math.radians(deg), hz)
    return [
        ("default set position (park point, on joint 1's axis), level, 10 s", Gravity(), None, 10.0),
        ("default set position, rocking +-5 deg at 0.5 Hz, 10 s", rock(5, 0.5), None, 10.0),
        ("(60, 20, -120), rocking +-27 deg at 0.2 Hz, 30 s", rock(27, 0.2), (60.0, 20.0, -120.0), 30.0),
        ("(60, 20, -120), rocking +-30 deg at 0.2 Hz, 30 s", rock(30, 0.2), (60.0, 20.0, -120.0), 30.0),
        ("(0, 95, -125), near full stretch, rocking +-27 deg at 0.2 Hz, 30 s", rock(27, 0.2), (0.0, 95.0, -125.0), 30.0),
        ("(72, -60, -110), beside a leg, rocking +-27 deg at 0.2 Hz, 30 s", rock(27, 0.2), (72.0, -60.0, -110.0), 30.0),
    ]


def joints(m, units):
    zero = np.array([s.zero for s in m.servos], dtype=float)
    direction = np.array([s.direction for s in m.servos], dtype=float)
    return direction * (np.asarray(units, dtype=float) - zero) * UNIT_RAD


def arm_points(m, q):
    """Joint 3 and the end effector of poses q (N, 3), base frame, mm."""
    q1, q2, q3 = q[:, 0], q[:, 1], q[:, 2]
    out = np.stack([np.cos(q1), -np.sin(q1), np.zeros_like(q1)], axis=1)
    down = np.array([0.0, 0.0, -1.0])
    elbow = m.L1 * down + m.L2 * (np.sin(q2)[:, None] * out + np.cos(q2)[:, None] * down)
    return elbow, elbow + m.L3 * (np.sin(q2 + q3)[:, None] * out + np.cos(q2 + q3)[:, None] * down)


def unsafe(m, q):
    """Poses q (N, 3) past a joint limit, not below the body plane, or in a leg's way."""
    q1 = q[:, 0]
    elbow, ee = arm_points(m, q)
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    bad = ~np.all((q >= lo - 1e-9) & (q <= hi + 1e-9), axis=1)
    bad |= (ee[:, 2] >= m.body_z) | (elbow[:, 2] >= m.body_z)
    near = np.zeros(len(q), dtype=bool)
    for leg in np.radians(m.leg_angles):
        d = np.mod(q1 - leg, math.pi)
        near |= np.minimum(d, math.pi - d) <= math.radians(m.leg_half_width)
    reach = np.maximum(np.hypot(ee[:, 0], ee[:, 1]), np.hypot(elbow[:, 0], elbow[:, 1]))
    return bad | (near & (reach >= m.leg_distance))


def servo_path(a, b, samples=9):
    d = b - a
    t = np.linspace(0.0, 1.0, samples)[:, None] * np.abs(d).max()
    return a + np.sign(d) * np.minimum(t, np.abs(d))


def run(m, motion, target, seconds, settle=2.0, servo_lag=None, supply=None):
    """servo_lag, supply: SimBoard's (None: the model file's lag, a sagging 11.1 V supply)."""
    board = SimBoard(m, motion=motion, servo_lag=servo_lag, supply=supply)
    board.shaft_trace = []
    board.send("enable", on=1)
    board.run(2.2)                              # parked, from hanging straight down
    if target is not None:
        board.send("set_position", **dict(zip("xyz", target)))
    board.send("engage", on=1)
    start, t = board.time, 0.0
    while t < settle + seconds:                 # the drone's keep-alive
        if target is None:
            board.send("engage", on=1)
        else:
            board.send("set_position", **dict(zip("xyz", target)))
        board.run(0.25)
        t += 0.25
    ids = [s.id for s in m.servos]
    q = np.array([joints(m, [c.goal[i] for i in ids]) for c in board.commands if c.time >= start + settle])
    q1 = np.degrees(q[:, 0])
    steps = np.abs(np.diff(q1))
    through = sum(bool(unsafe(m, servo_path(a, b)).any()) for a, b in zip(q, q[1:]))
    beats = [hb["faults"] & OUT_OF_REACH for hb in board.heartbeats[-round(2 * seconds):]]   # 2 Hz
    trace = np.array([row[2:] for row in board.shaft_trace if row[1]], dtype=float)   # supply on
    return {"shafts_out": int(unsafe(m, joints(m, trace)).sum()), "shafts": len(trace),"range": float(q1.max() - q1.min()), "jumps": int((steps > 20.0).sum()), "largest": float(steps.max()),
            "through": through, "moves": len(q) - 1, "engaged": board.heartbeats[-1]["engaged"],
            "out": sum(map(bool, beats)), "beats": len(beats)}


PASS_SPEED, PASS_SIDE, PASS_DEPTH = 300.0, 60.0, -130.0    # mm/s, mm, mm: axis_pass's target


def axis_pass(m, miss, speed=PASS_SPEED, side=PASS_SIDE, depth=PASS_DEPTH, facing_deg=-20.0):
    """A target going straight past joint 1's axis `miss` mm from it at `speed` mm/s, from
    `side` mm on one side (where joint 1 faces at `facing_deg`) to `side` mm on the other,
    then still for 0.4 s: the goals the firmware's motion sends each tick (app_next_goal,
    the host build), started facing the target. Returns (largest error, RMS error, joint 1's
    range) in mm, mm, deg."""
    ffi, lib = firmware.default()
    a = math.radians(facing_deg)
    start = np.array([side * math.cos(a), -side * math.sin(a)])
    along, across = -start / side, np.array([math.sin(a), math.cos(a)]) * miss
    step = speed / m.sample_rate
    path = [np.array([*(start + s * along + across), depth]) for s in np.arange(step, 2 * side + step / 2, step)]
    path += [path[-1]] * round(0.4 * m.sample_rate)
    q = ffi.new("float[3]")
    assert lib.kin_ik_nearest(list(map(float, path[0])), [a, 0.5, -0.5], q) == lib.KIN_OK
    mo, box = ffi.new("motion_t *"), ffi.new("float[2][3]")
    assert lib.motion_start(mo, list(q))
    goals = []
    for target in path:
        sent = list(q)
        lib.app_next_goal(mo, list(map(float, target)), False, [sent, sent], box, q)   # (the shafts at their goals)
        goals.append(list(q))
    goals = np.array(goals)
    err = np.linalg.norm(arm_points(m, goals)[1] - np.array(path), axis=1)
    return float(err.max()), float(np.sqrt(np.mean(err ** 2))), float(np.degrees(np.ptp(goals[:, 0])))


def report(m) -> None:
    print("\nMotion on the simulated board (bench/motion.py): joint 1's commanded angle once settled, "
          "and every move's path judged by plain geometry.\n")
    print("| scenario | joint-1 range (deg) | steps > 20 deg | largest step (deg) | moves through a limit, "
          "the body or a leg | heartbeats out of reach | shaft samples in a limit, the body or a leg: 45 ms "
          "lag, 9.0 V | the same, model lag, 11.1 V |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, motion, target, seconds in scenarios():
        worst = run(m, motion, target, seconds, servo_lag=0.045, supply=9.0)
        r = run(m, motion, target, seconds)
        print(f"| {name} | {r['range']:.1f} | {r['jumps']} | {r['largest']:.1f} | {r['through']} of {r['moves']} "
              f"| {r['out']} of {r['beats']} | {worst['shafts_out']} of {worst['shafts']} "
              f"| {r['shafts_out']} of {r['shafts']} |")
    print(f"\nTargets going straight past joint 1's axis at {PASS_SPEED:g} mm/s (bench/motion.py axis_pass), "
          f"from {PASS_SIDE:g} mm on one side to {PASS_SIDE:g} mm on the other, {-PASS_DEPTH:g} mm down: "
          "the goals sent, tick by tick.\n")
    print("| passes the axis at (mm) | largest error (mm) | RMS error (mm) | joint-1 range (deg) |")
    print("|---:|---:|---:|---:|")
    for miss in (1.0, 6.0, 10.0, 20.0, 30.0):      # (the other side is the mirror image)
        worst, rms, turned = axis_pass(m, miss)
        print(f"| {miss:g} | {worst:.1f} | {rms:.1f} | {turned:.0f} |")
