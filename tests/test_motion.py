"""How the arm moves, end to end on the simulated board: at the default set position (on
joint 1's axis) and at set positions on the edge of the workspace under heavy rocking, when
a new set position needs another branch or a route round a leg, and on every move of
engage, disengage and park. Every step is checked by tests/invariants.py (each goal safe,
the servos' path to it safe, its size within the speed sent); these tests add what a fixed
set position must look like: joint 1 still where it has no direction to follow, no hunting,
no jumps.

Each runs on the committed model file's AX-12As and on the same arm made of XM430-W350s
(`uavarm/build/variants.py`'s XM430_EDITS: Protocol 2.0, 4096 units a turn), whose firmware is
built from that model file.

Oracles: plain geometry (tests/oracles.py), the servos' written unit facts (simboard_tools.Servos),
the rocking's own attitude. The figures printed are those of docs/firmware.md's motion table.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import oracles
from invariants import Invariants, quickest_three_turns, turning_points
from simboard_tools import AX, FAMILIES, FAULT, BusLog, Servos, family_board, family_servos, level_ik_ok, ready, \
    shaft_units
from uavarm.sim.board import Gravity, Rocking

KEEP_ALIVE = 0.25          # s between set_position frames (the drone's keep-alive)


def set_position(board, p):
    board.send("set_position", x=float(p[0]), y=float(p[1]), z=float(p[2]))


def engaged(p=None, motion=None, at=None, family="AX-12A", **physics):
    """A board of `family`'s servos enabled, parked, set to p (None: the default, the park
    point), engaged; physics: the servos' lag and supply."""
    board = family_board(family, motion=motion, at=at, **physics)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.0) is not None
    if p is not None:
        set_position(board, p)
    board.send("engage", on=1)
    return board, inv


def hold(board, inv, p, seconds):
    """Runs `seconds`, repeating the set position (or, for the default, engage) as keep-alive."""
    end = board.time + seconds
    while board.time < end - 1e-9:
        if p is None:
            board.send("engage", on=1)
        else:
            set_position(board, p)
        inv.run(min(KEEP_ALIVE, end - board.time), step=0.05)


def deg_per_unit(board) -> float:
    return math.degrees(Servos(board.model).unit_rad)


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("motion, label", [
    (Gravity(), "level"),
    (Rocking(math.radians(5), math.radians(5), 0.5), "rocking +-5 deg at 0.5 Hz"),
])
def test_default_set_position_holds_joint_1(motion, label, family):
    """Engaged with no set_position: the set position is the park point, on joint 1's axis,
    which has no direction of its own. Joint 1's command moves less than 2 deg over 10 s,
    level or rocking, and no joint hunts."""
    board, inv = engaged(motion=motion, family=family)
    hold(board, inv, None, 1.0)
    t0 = board.time
    hold(board, inv, None, 10.0)
    hb = board.heartbeats[-1]
    assert hb["engaged"] == 1
    fig = inv.check_steady(t0, still=isinstance(motion, Gravity))
    j1 = fig["range"][0] * deg_per_unit(board)
    print(f"\n{family}, default set position, {label}: joint 1 range {j1:.2f} deg, largest step "
          f"{fig['step'][0] * deg_per_unit(board):.2f} deg, turns {fig['turns']}")
    assert j1 < 2.0


EDGE = {
    "(60, 20, -120)": (60.0, 20.0, -120.0),                # the set position joint 1 flipped about
    "near full stretch": (0.0, 95.0, -125.0),              # 133 mm from the shoulder (137.5 at most)
    "near the inner sphere": (30.0, 0.0, -110.0),          # 76 mm from the shoulder (75 at least)
    "beside a leg, reaching out": (72.0, -60.0, -110.0),   # joint 1 at 40 deg, a leg's sector at 35..55
}


SLOWEST, QUICKEST = (27.0, 0.045, 9.0), (30.0, 0.0, 12.6)    # rocking amplitude (deg), servo lag (s), supply (V)
# `make test` runs every set position on the slowest servos, and on the quickest the one
# whose shafts come nearest a leg (0.40 mm, docs/verification.md); `make test-long` the
# other three on the quickest; the XM430-W350 arm runs every set position on the slowest
EDGE_RUNS = [(name, *SLOWEST, family) for family in FAMILIES for name in EDGE] + [
    (name, *QUICKEST, "AX-12A") if name == "beside a leg, reaching out" else
    pytest.param(name, *QUICKEST, "AX-12A", marks=pytest.mark.long) for name in EDGE]


@pytest.mark.parametrize("name, amp_deg, lag, volts, family", EDGE_RUNS)
def test_edge_set_positions_under_heavy_rocking(name, amp_deg, lag, volts, family):
    """Set positions at the edge of the workspace, the board rocking +-27 or +-30 deg in roll
    and pitch at 0.2 Hz for 10 s, two of its periods (tilts that carry the target out of
    reach and round the axis), on the slowest servos (45 ms lag, a 9.0 V supply sagging as
    they move) and the quickest (no lag, 12.6 V): no joint-1 step above 20 deg per tick, no
    hunting beyond the rocking's own turns, every move clear and the shafts clear at every
    step (Invariants); out of reach is flagged rather than chased."""
    p = EDGE[name]
    assert level_ik_ok(p)
    motion = Rocking(math.radians(amp_deg), math.radians(amp_deg), 0.2)
    board, inv = engaged(p, motion=motion, lag=lag, supply=volts, family=family)
    t_engage = board.time
    hold(board, inv, p, 2.0)
    t0 = board.time
    hold(board, inv, p, 2 / motion.freq)
    fig = inv.check_steady(t0)
    fig["range"] = inv.check_steady(t_engage)["range"]     # joint 1's range from engage on
    step1 = fig["step"][0] * deg_per_unit(board)
    out = sum(1 for hb in board.heartbeats if hb["faults"] & FAULT["out_of_reach"])
    print(f"\n{family}, {name} {p}, rocking +-{amp_deg:.0f} deg at 0.2 Hz, 10 s, lag {lag * 1e3:.0f} ms, {volts} V: "
          f"shafts judged at {inv.shaft_steps} steps, {inv.clearance:.2f} mm clear at least; joint 1 range from engage "
          f"{fig['range'][0] * deg_per_unit(board):.1f} deg, largest joint-1 step {step1:.2f} deg/tick, turns "
          f"{fig['turns']}, {inv.segments} moves checked, out_of_reach in {out} of {len(board.heartbeats)} heartbeats")
    assert step1 <= 20.0
    assert board.heartbeats[-1]["engaged"] == 1


def test_the_hunting_check_tells_an_oscillation_from_a_fast_move_meeting_a_turn():
    """What the tests above call hunting: a goal that swings 3 units back and forth every 3
    ticks (here on top of a slow ramp) turns three times in 0.06 s; a fast move that ends
    where the target turns back 6 ticks later turns twice in 0.06 s, and then not again for
    a second: not an oscillation. (TICK: 10 ms.)"""
    ramp = np.arange(200) * 0.2
    hunting = ramp + 3.0 * ((np.arange(200) // 3) % 2)
    assert quickest_three_turns(turning_points(hunting)) <= 0.06 + 1e-9
    swing_then_turn = np.concatenate([np.linspace(644.0, 555.0, 10), [556.0, 556.0, 557.0, 557.0, 557.0, 557.0],
                                      np.linspace(556.0, 500.0, 100), np.linspace(501.0, 560.0, 100)])
    turns = turning_points(swing_then_turn)
    assert len(turns) == 3 and (turns[1] - turns[0]) * 0.01 <= 0.06 + 1e-9
    assert quickest_three_turns(turns) >= 1.0


@pytest.mark.parametrize("family", FAMILIES)
def test_a_set_position_past_a_leg_is_reached_round_it(family):
    """From a far reach on one side of a leg to a far reach on its other side: the straight
    joint-space move would sweep through the leg's sector at full reach, so the arm pulls in
    (the tuck), turns, and reaches out again; every move clear, and it arrives."""
    a, b = (95.0, -45.0, -100.0), (45.0, -95.0, -100.0)     # joint 1 at 25 and 65 deg; a leg at 45
    assert level_ik_ok(a) and level_ik_ok(b)
    board, inv = engaged(a, family=family)
    hold(board, inv, a, 2.5)
    assert np.linalg.norm(_ee(board) - a) < 1.5
    routes = board.app.motion.tucks
    hold(board, inv, b, 4.0)
    assert board.app.motion.tucks == routes + 1, "went by the tuck"
    assert np.linalg.norm(_ee(board) - b) < 1.5
    hb = board.heartbeats[-1]
    assert hb["engaged"] == 1 and not hb["faults"] & FAULT["motion_blocked"]


@pytest.mark.parametrize("family", FAMILIES)
def test_a_set_position_on_the_other_branch_is_reached_by_a_checked_transition(family):
    """A set position that the arm's branch (plane toward the target, elbow down) cannot
    reach, but the other plane can: the arm gets there by a route whose every move is
    clear (or the set position is refused with motion_blocked, never jumped to)."""
    a, b = (60.0, 0.0, -120.0), (-60.0, 0.0, -120.0)        # b behind joint 1's axis
    board, inv = engaged(a, family=family)
    hold(board, inv, a, 2.5)
    hold(board, inv, b, 4.0)
    hb = board.heartbeats[-1]
    if hb["faults"] & FAULT["motion_blocked"]:
        assert np.allclose([hb["set_x"], hb["set_y"], hb["set_z"]], a), "refused: the old set position stays"
    else:
        assert np.linalg.norm(_ee(board) - b) < 1.5


@pytest.mark.parametrize("family", FAMILIES)
def test_engage_and_disengage_from_where_the_arm_hangs(family):
    """Enabled with the servos wherever the limp arm hung (here straight down, and turned
    half round on joint 1), the arm parks at park speed from there, engages to a set
    position and parks again: every move checked by the invariants, including the first."""
    sv = family_servos(family)
    for hang_units in ([512, 512, 512], [512 + 400, 600, 480]):     # AX-12A units
        hang = AX.units_to_joints(hang_units)
        assert sv.poses_ok([round(sv.joint_units(j, q)) for j, q in enumerate(hang)])[0]
        board, inv = engaged((60.0, 20.0, -120.0), at=hang, family=family)
        hold(board, inv, (60.0, 20.0, -120.0), 3.0)
        assert board.heartbeats[-1]["engaged"] == 1
        board.send("engage", on=0)
        inv.run(4.0)
        # parked: within the compliance margin (a unit) of the park goal
        park = [round(sv.joint_units(j, math.radians(d))) for j, d in enumerate(sv.model.park_deg)]
        assert all(abs(s - u) <= 1.0 for s, u in zip(shaft_units(board), park))


def _ee(board):
    return oracles.arm_points(board.model, Servos(board.model).units_to_joints(shaft_units(board)))[2]
