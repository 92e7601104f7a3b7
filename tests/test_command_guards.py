"""The control program's guards on commands (app.c), each on the simulated board: what
clears a refusal, which servo faults refuse engage, what a repeated engage does.

Oracles: the documented command semantics (docs/firmware.md: refusal table, heartbeat fields), the AX-12A
e-Manual's status error byte, the Moving Speed values of the model file's speeds."""
import math
import subprocess
import sys

import numpy as np
import pytest

import oracles
from invariants import Invariants
from simboard_tools import FAULT, IDS, MODEL, PARK_SPEED, TRANSIT_SPEED, WORKING_SPEED, BusLog, make_board, ready, sync_goal_speed
from test_fault_injection import TARGET, ReplyTap, at, engaged_board, set_position, with_error
from uavarm.link import messages

REFUSAL = {name: k for k, (name, _) in enumerate(messages.REFUSALS)}
HOLDING = [name for name, _ in messages.STATES].index("holding")
OVERHEATING = 2          # AX-12A status error byte, bit 2


def enabled_board():
    board = make_board()
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.0) is not None
    return board, inv


def test_a_set_position_taken_clears_the_last_refusal():
    """engage while disabled is refused (not_enabled); a set position taken afterwards
    clears command_refused and the refusal."""
    board = make_board()
    inv = Invariants(board, BusLog(board))
    board.send("engage", on=1)
    hb = inv.next_heartbeat()
    assert hb["faults"] & FAULT["command_refused"] and hb["refusal"] == REFUSAL["not_enabled"], hb
    set_position(board, TARGET)
    hb = inv.next_heartbeat()
    assert not hb["faults"] & FAULT["command_refused"] and hb["refusal"] == REFUSAL["none"], hb


@pytest.mark.parametrize("j", [0, 1, 2])
def test_engage_is_refused_while_any_servo_reports_an_error(j):
    """Servo j's status packets carry the overheating bit: engage is refused (servo_fault),
    whichever servo it is."""
    board, inv = enabled_board()
    tap = ReplyTap(board)
    tap.faults[IDS[j]] = with_error(OVERHEATING)
    inv.run(0.2)
    board.send("engage", on=1)
    inv.run(0.02)
    hb = inv.next_heartbeat()
    assert hb["engaged"] == 0 and hb["refusal"] == REFUSAL["servo_fault"], hb


def test_engage_again_while_holding_changes_nothing():
    """Engaged and holding the set position: another engage 1 leaves the arm holding (state
    holding, the working speed), as it was."""
    board, inv = engaged_board()
    inv.run(0.3)
    assert inv.next_heartbeat()["state"] == HOLDING
    t = board.time
    board.send("engage", on=1)
    inv.run(0.1)
    assert all(sync_goal_speed(p.raw)[1] == [WORKING_SPEED] * 3 for p in inv.log.syncs(t))
    hb = inv.next_heartbeat()
    assert hb["engaged"] == 1 and hb["state"] == HOLDING and not hb["faults"] & FAULT["command_refused"], hb


def test_engage_is_refused_while_a_reset_servo_is_set_up_again():
    """Servo 2 browns out while the arm is parked (its RAM back at power-on values): from the
    reading that finds it reset until the write that sets it up again is done, engage is
    refused (servo_fault)."""
    board, inv = enabled_board()
    inv.run(0.3)
    servo = board.bus.servo(IDS[1])
    servo.power_off()
    servo.power_on()
    bus = board.app.bus
    for _ in range(round(0.2 * 1e6 / board.poll_us)):
        board.step(board.poll_us)
        if bus.refit or bus.refitting:
            break
    assert bus.refit or bus.refitting
    board.send("engage", on=1)
    board.step(board.poll_us)
    assert not board.app.engaged and board.app.refusal == REFUSAL["servo_fault"]


def test_engage_before_parked_parks_then_goes_at_transit_speed():
    """Enabled with the arm hanging straight down and engaged at once: it parks first (park
    speed), then goes to the set position at the transit speed, then holds it at the working
    speed."""
    board = make_board(at=[512, 512, 512])
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.5) is not None
    set_position(board, TARGET)
    board.send("engage", on=1)
    for _ in range(40):                       # the drone repeats the set position (keep-alive)
        set_position(board, TARGET)
        inv.run(0.2)
        if board.heartbeats[-1]["state"] == HOLDING:
            break
    assert board.heartbeats[-1]["state"] == HOLDING, board.heartbeats[-1]
    speeds = [sync_goal_speed(p.raw)[1][0] for p in inv.log.syncs()]
    order = [s for k, s in enumerate(speeds) if k == 0 or s != speeds[k - 1]]
    assert order == [PARK_SPEED, TRANSIT_SPEED, WORKING_SPEED], order


def test_a_new_set_position_while_parking_before_engage_waits_for_the_park():
    """Engage taken while the arm still parks (engage parks first), then a new set position
    before the park is done: the park is finished, then the arm goes to the new set position
    and holds it there (not left at the goal unstabilised, reported as parking forever)."""
    board = make_board(at=[512, 512, 512])                  # away from the park pose
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 2.0) is not None
    parking = [name for name, _ in messages.STATES].index("parking")
    assert inv.next_heartbeat()["state"] == parking
    board.send("engage", on=1)
    hb = inv.next_heartbeat()
    assert hb["engaged"] == 1 and hb["state"] == parking, hb
    for _ in range(40):                                      # 10 s, the set position as keep-alive
        set_position(board, TARGET)
        inv.run(0.25)
        if board.heartbeats[-1]["state"] == HOLDING:
            break
    hb = board.heartbeats[-1]
    assert hb["state"] == HOLDING and hb["engaged"] == 1, f"never held the set position: {hb}"
    for _ in range(4):
        set_position(board, TARGET)
        inv.run(0.25)
    assert at(board, TARGET)


HOLD_AT_THE_BODY = """
import math, sys
from uavarm.build import firmware
ffi, lib = firmware.default()
q0 = [float(v) for v in sys.argv[1:4]]
m = ffi.new("motion_t *")
assert lib.motion_start(m, q0), "a safe pose"
q = ffi.new("float[3]")
lib.app_next_goal(m, ffi.NULL, False, [q0, q0], ffi.new("float[2][3]"), q)   # the shafts at the goal
print(*[repr(v) for v in q])
"""


def test_a_last_goal_too_close_to_the_body_to_leave_is_held_and_the_check_ends():
    """The last goal sent is a safe pose with the end effector 0.05 mm below the body plane:
    inside the joints' check, but not clear by the goals' margin, so every step from it is
    refused, the arm's own hold included. The command path gives that goal again (the
    servos stay where they are) and returns; a check that kept asking would hang the board
    (run apart, with a timeout, so such a hang fails here)."""
    m = MODEL
    q2 = math.radians(100.0)
    elbow_z = -m.L1 - m.L2 * math.cos(q2)
    reach = (m.body_z - 0.05 - elbow_z) / -m.L3               # cos(q2 + q3) for the EE at z = -0.05 mm
    q0 = np.array([0.0, q2, math.acos(reach) - q2], dtype=np.float32)
    status, _ = oracles.check_pose(m, q0.astype(float))
    assert status[0] == 0 and oracles.arm_points(m, q0.astype(float))[2][2] == pytest.approx(-0.05, abs=1e-3)
    out = subprocess.run([sys.executable, "-c", HOLD_AT_THE_BODY, *map(repr, q0.tolist())],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert np.array(out.stdout.split(), dtype=np.float32).tolist() == q0.tolist()

