"""An X-series arm on the simulated board: the firmware built from the model file made an arm of
XM430-W350s (servo.model = "XM430-W350", uavarm/build/variants.py's XM430_EDITS) runs against three simulated XM430-W350s (uavarm/sim/xseries_sim.py)
that SimBoard makes from the model file itself, as it makes AX-12As for the committed one.

Oracles, none taken from the C under test: plain geometry (tests/oracles.py) on the simulated
shafts, turned into joint angles here from the XM430's 4096 units a turn and the model file's
zeros and directions; Protocol 2.0's SYNC_WRITE layout (Profile Velocity(112) and Goal
Position(116), 4 bytes each, per the e-manual) read from the bus bytes by the simulator's
packet reader, whose framing test_servo_bus2 checks against the SDK.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import oracles
from simboard_tools import Servos, family_lib, family_servos
from uavarm.link import messages
from uavarm.sim.board import SimBoard
from uavarm.sim.xseries_sim import XM430_W350, XServo

KEEP_ALIVE = 0.25                 # s between the drone's frames


@pytest.fixture(scope="module")
def xm430():
    """(model, ffi, lib): the firmware built for the host from the model file made an
    XM430-W350 arm (uavarm/build/variants.py's XM430_EDITS)."""
    return (family_servos("XM430-W350").model, *family_lib("XM430-W350"))


def joints_of(model, units) -> np.ndarray:
    """Joint angles (rad) of shaft positions (..., 3) in the model's servo units."""
    return Servos(model).units_to_joints(units)


def board_of(xm430, **kw) -> SimBoard:
    model, ffi, lib = xm430
    board = SimBoard(model, lib=(ffi, lib), **kw)
    board.shaft_trace = []
    return board


def keep(board, seconds: float, **set_position) -> None:
    """Runs `seconds`, the drone keeping the link alive with engage (or a set position)."""
    end = board.time + seconds
    while board.time < end - 1e-9:
        if set_position:
            board.send("set_position", **set_position)
        else:
            board.send("engage", on=1)
        board.run(min(KEEP_ALIVE, end - board.time))


def unsafe_shafts(board) -> list:
    """The traced shaft positions (supply on) that plain geometry refuses, with the servo rounding."""
    rows = np.array(board.shaft_trace, dtype=float)
    on = rows[rows[:, 1] > 0]
    status, _ = oracles.check_pose(Servos(board.model).relaxed, joints_of(board.model, on[:, 2:]))
    return on[status != 0].tolist()


def test_the_simulated_board_makes_the_model_files_servos(xm430):
    board = board_of(xm430)
    assert [type(s) for s in board.bus.servos] == [XServo] * 3
    assert [s.model.name for s in board.bus.servos] == ["XM430-W350"] * 3
    assert [s.id for s in board.bus.servos] == [s.id for s in xm430[0].servos]
    assert all(s.register("baud_rate") == 3 for s in board.bus.servos)         # 1 Mbit/s


def test_an_xm430_arm_engages_at_its_set_position_and_every_goal_and_shaft_is_safe(xm430):
    """From hanging straight down (every shaft at its zero): enable, engage; the end
    effector, by plain geometry from the shafts, comes to the set position the heartbeat
    reports; every goal the bus carried and every shaft position on the way is a pose
    plain geometry accepts."""
    model = xm430[0]
    board = board_of(xm430)
    board.send("enable", on=1)
    board.run(1.5)
    keep(board, 4.0)
    hb = board.heartbeats[-1]
    assert hb["engaged"] and hb["faults"] == 0, hb
    ee = oracles.arm_points(model, joints_of(model, [s.position for s in board.bus.servos]))[2]
    set_point = np.array([hb["set_x"], hb["set_y"], hb["set_z"]])
    assert np.linalg.norm(ee - set_point) < 0.3, (ee, set_point)   # 0.088 deg a unit at ~140 mm: 0.2 mm a joint
    goals = np.array([[c.goal[s.id] for s in model.servos] for c in board.commands])
    assert len(goals) > 100
    status, _ = oracles.check_pose(Servos(model).relaxed, joints_of(model, goals))
    assert (status == 0).all(), goals[status != 0][:3]
    assert not unsafe_shafts(board)


def test_an_xm430_arm_routed_round_a_leg_and_parked_keeps_its_shafts_safe(xm430):
    """A set position on the far side of a leg from where the arm works (the route turns joint
    1 with the arm tucked), then disengage (the park), on the slowest servos the tests allow
    for (45 ms of lag, a 9.0 V supply sagging as they move): the shafts, lagging their goals,
    stand in a safe pose at every main-loop pass."""
    model = xm430[0]
    board = board_of(xm430, servo_lag=0.045, supply=9.0)
    board.send("enable", on=1)
    board.run(1.5)
    keep(board, 3.0)
    leg = math.radians(model.leg_angles[0])
    # beside the first leg, reaching out past the leg distance: the arm goes round, not through
    far = (model.leg_distance + 10.0) * np.array([math.cos(leg + 0.6), -math.sin(leg + 0.6)])
    keep(board, 6.0, x=float(far[0]), y=float(far[1]), z=-110.0)
    board.send("engage", on=0)
    board.run(4.0)
    hb = board.heartbeats[-1]
    assert not hb["engaged"] and hb["faults"] == 0, hb
    q1 = joints_of(model, np.array(board.shaft_trace, dtype=float)[:, 2:])[:, 0]
    assert np.ptp(q1) > math.radians(20), "joint 1 hardly turned: the move tested nothing"
    assert not unsafe_shafts(board)


class HoldingShortXServo(XServo):
    """An XM430-W350 that stands `short` units short of each goal it reaches: its position P
    gain against the arm's weight, with no I term (Position I Gain is 0 from the factory)."""
    short = 0

    def _advance(self, h):
        super()._advance(h)
        goal = self.register("goal_position")
        if self._profile == goal and self.torque_on:
            self._pos = goal - self.short


def test_an_xm430_holding_short_of_its_goals_within_the_tracking_tolerance_is_not_flagged(xm430):
    """Joints 2 and 3 hold 20 units (1.76 deg) short of every goal they reach, as a servo
    without an integral term does under load: within the 2.35 deg a shaft may stand from its
    goal (27 of the XM430's units, 8 of an AX-12A's), so moving between set positions and
    holding there never raises servo_tracking and the arm stays engaged."""
    model = xm430[0]
    servos = []
    for j, s in enumerate(model.servos):
        servo = HoldingShortXServo(XM430_W350, s.id, table={"baud_rate": 3})
        servo.short = 20 if j else 0
        servos.append(servo)
    board = board_of(xm430, servos=servos)
    board.send("enable", on=1)
    board.run(1.5)
    a, b = dict(x=60.0, y=20.0, z=-120.0), dict(x=40.0, y=-50.0, z=-110.0)
    board.send("set_position", **a)
    keep(board, 2.0)
    for p in (a, b, a, b):
        keep(board, 1.5, **p)
    tracking = 1 << [name for name, _ in messages.FAULTS].index("servo_tracking")
    assert not any(hb["faults"] & tracking for hb in board.heartbeats)
    assert board.heartbeats[-1]["engaged"]
    assert abs(board.bus.servos[1].position - board.bus.servos[1].register("goal_position")) == 20


@pytest.mark.parametrize("j", [0, 1, 2])
def test_an_xm430_that_browns_out_while_engaged_is_set_up_where_it_sagged_and_the_arm_parks(xm430, j):
    """Servo j's supply dips while the arm is engaged: its RAM comes back at its power-on
    values, the status map with it (every byte it reads 0), the torque off, the shaft where it
    sagged. That reading is not taken: the map is written again and the servo read again, so
    its reset is seen with its true position; it is set up again holding there, the heartbeat
    says servo_reset, the arm parks from where it is, every goal and every shaft position a
    safe pose, no reading of position 0 taken; engage works again after. On the slowest
    servos the tests allow for (45 ms of lag, 9.0 V sagging as they move)."""
    model = xm430[0]
    board = board_of(xm430, servo_lag=0.045, supply=9.0)
    board.send("enable", on=1)
    board.run(1.5)
    p = dict(x=60.0, y=20.0, z=-120.0)
    board.send("set_position", **p)
    keep(board, 2.0)                                    # engage
    keep(board, 1.0, **p)
    assert board.heartbeats[-1]["engaged"]
    servo, bus = board.bus.servos[j], board.app.bus
    servo.power_off()
    servo.power_on()
    sagged = round(servo.position) + 25                 # a little way while limp (2.2 deg)
    servo.turn_by_hand(sagged)
    assert servo.register("torque_enable") == 0 and servo.register("indirect_address_1") == 224
    n, t0 = len(board.commands), board.time
    seen, reset_at = [], []                             # servo j's readings from now on; when its reset was seen
    while board.time < t0 + 0.6:
        reads, resets = bus.servo[j].reads, bus.resets
        board.run(0.002)
        if bus.servo[j].reads != reads:
            seen.append(bus.servo[j].present_position)
        if bus.resets != resets:
            reset_at.append(board.time)
        board.send("set_position", **p)
    hb = board.heartbeats[-1]
    reset = 1 << [name for name, _ in messages.FAULTS].index("servo_reset")
    assert hb["servo_resets"] == 1 and hb["faults"] & reset and not hb["engaged"], hb
    assert bus.remaps == 1 and bus.refits == 1
    lo, hi = servo.register("min_position_limit"), servo.register("max_position_limit")
    assert seen[0] == sagged and all(lo <= u <= hi for u in seen), seen[:5]     # never a position of 0
    assert servo.register("torque_enable") == 1 and servo.register("indirect_address_1") == 64
    goals = np.array([[c.goal[s.id] for s in model.servos] for c in board.commands[n:]])
    status, _ = oracles.check_pose(Servos(model).relaxed, joints_of(model, goals))
    assert len(goals) > 20 and (status == 0).all(), goals[status != 0][:3]
    keep(board, 4.0)
    board.send("engage", on=1)
    keep(board, 3.0)
    hb = board.heartbeats[-1]
    assert hb["engaged"] and not hb["faults"] & reset, hb
    assert not unsafe_shafts(board)
    print(f"\nservo {j + 1} browned out: its reset seen {(reset_at[0] - t0) * 1e3:.0f} ms later, from its first "
          f"reading; {len(goals)} goals of the park from where it sagged, all safe")


def test_an_overheated_xm430_shuts_itself_down_and_the_next_move_parks_the_arm(xm430):
    """Above its Temperature Limit (80 deg C) the XM430's Shutdown turns its torque off and
    raises Hardware Error Status's overheating bit; its status packets carry the alert bit (7).
    Holding still, the heartbeat shows servo_error with that alert; the next move finds the
    shaft not following: servo_tracking, the arm parks (by the others; the limp one stays).
    Cooled, a new enable (its supply off and on clears the shutdown) and the arm works again;
    every shaft position, powered, a safe pose."""
    model = xm430[0]
    fault = {name: 1 << i for i, (name, _) in enumerate(messages.FAULTS)}
    board = board_of(xm430)
    board.send("enable", on=1)
    board.run(1.5)
    p, other = dict(x=60.0, y=20.0, z=-120.0), dict(x=40.0, y=-50.0, z=-110.0)
    board.send("set_position", **p)
    keep(board, 2.0)
    keep(board, 1.0, **p)
    assert board.heartbeats[-1]["engaged"]
    servo = board.bus.servos[1]
    servo.temperature = 85.0
    keep(board, 0.3, **p)
    assert servo.register("torque_enable") == 0 and servo.register("hardware_error_status") == 0x04
    hb = board.heartbeats[-1]
    assert hb["servo2_error"] == 0x80 and hb["faults"] & fault["servo_error"] and hb["engaged"], hb
    assert board.app.bus.resets == 0, "a shutdown is not a brown-out"
    keep(board, 1.0, **other)
    hb = board.heartbeats[-1]
    assert hb["faults"] & fault["servo_tracking"] and not hb["engaged"], hb
    servo.temperature = 40.0
    board.send("enable", on=0)
    board.run(0.1)
    board.send("enable", on=1)
    board.run(1.5)
    keep(board, 3.0)
    keep(board, 2.0, **other)
    hb = board.heartbeats[-1]
    assert hb["engaged"] and hb["servo2_error"] == 0 and not hb["faults"] & fault["servo_error"], hb
    ee = oracles.arm_points(model, joints_of(model, [s.position for s in board.bus.servos]))[2]
    assert np.linalg.norm(ee - [other["x"], other["y"], other["z"]]) < 0.5, ee
    assert not unsafe_shafts(board)


def test_the_closed_loop_simulator_flies_an_xm430_variant_of_the_model_file():
    """The committed model file with the XM430-W350 edits (the simulator's and the report's
    --set path) flies 10 s of hover on XM430-W350s: the end effector, from the simulated
    shafts and the drone's true attitude (the simulator's error, through the SymPy model's
    forward kinematics), within 3 mm RMS."""
    from uavarm.build import variants
    from uavarm.sim import closed_loop, scenarios
    variant = variants.build(variants.XM430_EDITS)
    assert variant.model.servo_model.name == "XM430-W350"
    servos = closed_loop.make_servos(variant.model, 0.0265, True)
    assert [type(s) for s in servos] == [XServo] * 3
    run = closed_loop.simulate(scenarios.load("hover"), variant, 0,
                               closed_loop.Settings(seconds=10.0, preflight=3.0, settle=3.0))
    e = np.linalg.norm(run.error_mm[run.scored], axis=1)
    assert run.scored.sum() > 900 and np.isfinite(e).all()
    assert math.sqrt(np.mean(e ** 2)) < 3.0, math.sqrt(np.mean(e ** 2))
    out_of_reach = 1 << [name for name, _ in messages.FAULTS].index("out_of_reach")
    assert set(run.faults) <= {out_of_reach}, run.faults      # at most a gust's tilt out of reach


@pytest.mark.realtime
def test_the_sitl_serves_an_xm430_arm_to_the_link_client(xm430):
    """The SITL with the XM430-W350 build (the board the user rehearses on once the model file
    names the servo): the link client enables it, it parks, goes to a set position when
    engaged (the end effector by plain geometry from the simulated shafts within 0.5 mm of
    it), and disable cuts the supply."""
    from uavarm.link import ArmLink
    from uavarm.sim.sitl import Sitl
    model, ffi, lib = xm430
    target = np.array([60.0, 20.0, -120.0])
    sitl = Sitl(speed=2.0, model=model, lib=(ffi, lib)).start()

    def wait_for(arm, cond, sim_seconds):
        end = sitl.board.time + sim_seconds
        while sitl.board.time < end:
            hb = arm.next_heartbeat()
            arm.keep_alive()
            if cond(hb):
                return hb
        return None

    def ee():
        return oracles.arm_points(model, joints_of(model, [s.position for s in sitl.board.bus.servos]))[2]
    try:
        with ArmLink(sitl.device, clock=sitl.clock) as arm:
            moved = sitl.submit("move joint 2 30").result(timeout=60)
            assert "turned by hand to 30 deg" in moved and "(servo 2 at" in moved, moved   # in 4096 units a turn
            assert abs(sitl.board.bus.servos[1].position - (2048 + model.servos[1].direction * 30 * 4096 / 360)) < 1
            assert arm.enable()["enabled"] == 1
            park = np.radians(model.park_deg)
            assert wait_for(arm, lambda hb: np.abs([hb["p1"] - park[0], hb["p2"] - park[1], hb["p3"] - park[2]]).max()
                            < math.radians(0.5), 4.0) is not None, "the park was not reached"
            arm.set_position(*target)
            assert arm.engage()["engaged"] == 1
            assert wait_for(arm, lambda hb: np.linalg.norm(ee() - target) < 0.5, 4.0) is not None, ee()
            where = sitl.submit("where").result(timeout=60)
            assert where.count("holding, present current") == 3, where
            assert arm.disable()["enabled"] == 0
            assert not sitl.board.servo_power
    finally:
        sitl.stop()


def test_an_xm430_holding_the_arm_reads_the_current_its_weight_asks(xm430):
    """Level, engaged at a set position: each of joints 2 and 3 reads the Present Current that
    holds its share of the arm's weight. Oracle: planar statics with the model file's masses
    (g times each mass's horizontal distance from the joint's axis, in the arm's plane), the
    XM430-W350's 4.1 N m at 2.3 A and its 2.69 mA unit, in the servo's own sense."""
    model = xm430[0]
    board = board_of(xm430)
    board.send("enable", on=1)
    board.run(1.5)
    board.send("set_position", x=60.0, y=20.0, z=-120.0)
    board.send("engage", on=1)
    keep(board, 4.0, x=60.0, y=20.0, z=-120.0)
    assert board.heartbeats[-1]["engaged"]
    q = joints_of(model, [s.position for s in board.bus.servos])
    ms = model.masses
    g, l2 = 9.80665, model.L2 / 1000
    elbow_x = l2 * math.sin(q[1])                               # in the arm's plane, m from the shoulder's axis
    beyond = [(ms.forearm, ms.forearm_com), (ms.end_effector, ms.end_effector_com)]   # g, mm from the elbow
    forearm_x = [(kg / 1000, d / 1000 * math.sin(q[1] + q[2])) for kg, d in beyond]
    weight_torque = {                                           # N m, the sense the joint's angle grows
        1: -g * (ms.servo / 1000 * elbow_x + ms.upper_arm / 1000 * ms.upper_arm_com / 1000 * math.sin(q[1])
                 + sum(kg * (elbow_x + x) for kg, x in forearm_x)),
        2: -g * sum(kg * x for kg, x in forearm_x)}
    for j, torque in weight_torque.items():
        servo, sense = board.bus.servos[j], model.servos[j].direction
        expected = sense * -torque * 2.3 / 4.1 / 0.00269     # the motor holds against the weight
        assert abs(servo.register("present_current") - expected) <= 1.0, (j + 1, servo.register("present_current"), expected)
    assert abs(weight_torque[1]) > 0.02, "the test pose puts too little weight on joint 2 to tell"
