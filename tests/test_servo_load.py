"""The simulated AX-12A's Present Load and the simulated arm's weight behind it.

Oracles: the e-manual's text for the register (bits 0-9 a share of the maximum torque, bit 10
the direction, 0 = CCW, the sense in which position units grow), read by the official
DynamixelSDK; the AX-12A's stall torque (1.5 N m at 12 V); and statics worked out here
independently of the simulator: each joint's gravity torque as the derivative of the arm's
potential energy along that joint (virtual work), with the joints' points from plain geometry
(tests/oracles.py) and the masses placed as the simulator's docstring says.
"""
from __future__ import annotations

import math

import dynamixel_sdk as sdk
import numpy as np
import pytest

from oracles import arm_points
from simboard_tools import MODEL, PARK_UNITS, make_board, run_until, running
from uavarm.sim.arm_load import ArmMasses
from uavarm.sim.ax12_sim import AX12, AX12Bus, SdkPort, Supply
from uavarm.sim.board import Gravity, SimBoard

PH = sdk.Protocol1PacketHandler()
STALL_NM_AT_12V = 1.5                  # e-manual: stall torque 1.5 N m at 12 V
UNITS_PER_DEG = 1023 / 300             # e-manual: 0..1023 over 300 deg
G = 9.80665
CW = 0x400                             # bit 10: the load's direction is CW


# ------------------------------------------------------------------ the register alone

def servo_with(outside_nm, volts=12.0):
    servo = AX12(1, voltage=volts)
    servo.outside_torque = lambda: outside_nm
    bus = AX12Bus([servo])
    port = SdkPort(bus)
    assert PH.write1ByteTxRx(port, 1, 24, 1) == (sdk.COMM_SUCCESS, 0)       # torque on
    return servo, port


@pytest.mark.parametrize("outside_nm, volts, expected", [
    (-0.3, 12.0, 205),               # pulled CW: the motor pushes CCW, 0.3 / 1.5 of 1023
    (0.3, 12.0, CW | 205),           # pulled CCW: it pushes CW
    (-0.3, 9.0, 273),                # the same torque at 9 V is a larger share of what it can do
    (-2.0, 12.0, 1023),              # more than it can: all it has
])
def test_present_load_is_the_torque_the_motor_applies(outside_nm, volts, expected):
    servo, port = servo_with(outside_nm, volts)
    assert PH.read2ByteTxRx(port, 1, 40) == (expected, sdk.COMM_SUCCESS, 0)
    # the firmware's status read (32..43) carries the same two bytes, little-endian
    data, result, error = PH.readTxRx(port, 1, 32, 12)
    assert (result, error) == (sdk.COMM_SUCCESS, 0)
    assert data[8] | data[9] << 8 == expected


def test_present_load_is_capped_at_torque_limit_and_zero_when_limp():
    servo, port = servo_with(-0.3)
    assert PH.write2ByteTxRx(port, 1, 34, 100) == (sdk.COMM_SUCCESS, 0)    # Torque Limit
    assert PH.read2ByteTxRx(port, 1, 40)[0] == 100
    assert PH.write1ByteTxRx(port, 1, 24, 0) == (sdk.COMM_SUCCESS, 0)      # limp
    assert PH.read2ByteTxRx(port, 1, 40)[0] == 0
    servo.power_off()
    assert PH.read2ByteTxRx(port, 1, 40)[1] == sdk.COMM_RX_TIMEOUT         # an unpowered servo says nothing


# ------------------------------------------------------------------ the arm's weight

def gravity_oracle(q, up, masses: ArmMasses) -> np.ndarray:
    """Gravity's torque (N m) about each joint in the sense its angle grows: -dU/dq by central
    differences, U the potential energy of the masses at their places."""
    up = np.asarray(up, dtype=float)

    def energy(q):
        shoulder, elbow, ee = (p / 1000 for p in arm_points(MODEL, q))
        along = lambda a, b, d: a + (b - a) * d / np.linalg.norm(b - a)    # d m from a toward b
        placed = [(masses.upper_arm, along(shoulder, elbow, masses.upper_arm_com)), (masses.elbow_servo, elbow),
                  (masses.forearm, along(elbow, ee, masses.forearm_com)),
                  (masses.end_effector, along(elbow, ee, masses.end_effector_com))]
        return sum(kg * G * float(up @ p) for kg, p in placed)

    h = 1e-6
    q = np.asarray(q, dtype=float)
    return np.array([-(energy(q + h * e) - energy(q - h * e)) / (2 * h) for e in np.eye(3)])


def expected_load(gravity_nm: float, direction: int, volts: float = 12.0) -> int:
    """The register's value for the servo holding a joint against gravity_nm (the joint's
    sense), mounted with `direction`: it applies the opposite torque, in its own sense."""
    applied = -gravity_nm * direction                  # N m, CCW (units growing) positive
    magnitude = round(abs(applied) / (STALL_NM_AT_12V * volts / 12) * 1023)
    return magnitude | (CW if applied < 0 else 0)


def up_of(roll_deg, pitch_deg):
    """The world's up in the base's axes, for a base rolled then pitched (Z-Y-X, no yaw)."""
    r, p = math.radians(roll_deg), math.radians(pitch_deg)
    Rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    Ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    return (Ry @ Rx).T @ np.array([0.0, 0.0, 1.0])


def held_board(truth, roll_deg, pitch_deg, joints_deg):
    """A board whose servos (mounted as `truth`) hold the joints near joints_deg with the torque
    on (written through the SDK), the base held at roll/pitch, a 12 V supply that does not
    sag; the shafts at whole units, so they stay put. Returns (board, port, units)."""
    zeros, directions = truth
    units = [round(z + d * a * UNITS_PER_DEG) for z, d, a in zip(zeros, directions, joints_deg)]
    board = SimBoard(MODEL, servo_truth=truth, motion=Gravity(math.radians(roll_deg), math.radians(pitch_deg)),
                     supply=Supply(volts=12.0, resistance=0.0))
    for servo, u in zip(board.bus.servos, units):
        servo.turn_by_hand(u)
    board.bus.power(True)
    port = SdkPort(board.bus)
    for s in MODEL.servos:
        assert PH.write1ByteTxRx(port, s.id, 24, 1) == (sdk.COMM_SUCCESS, 0)
    return board, port, units


MODEL_TRUTH = (tuple(s.zero for s in MODEL.servos), tuple(s.direction for s in MODEL.servos))
REVERSED = ((520, 497, 505), (1, -1, 1))       # joint 2's servo mounted the other way round, all offset


@pytest.mark.parametrize("truth, roll, pitch, joints", [
    (MODEL_TRUTH, 0, 0, (0, 90, 0)),
    (MODEL_TRUTH, 0, 0, (30, 45, -60)),
    (MODEL_TRUTH, 15, -25, (60, -30, 80)),
    (REVERSED, 0, 0, (0, 90, 0)),
    (REVERSED, 10, 20, (-40, 70, -45)),
])
def test_each_servo_reads_the_load_statics_predicts(truth, roll, pitch, joints):
    board, port, units = held_board(truth, roll, pitch, joints)
    zeros, directions = truth
    q = [d * (u - z) / UNITS_PER_DEG for u, z, d in zip(units, zeros, directions)]
    gravity = gravity_oracle(np.radians(q), up_of(roll, pitch), ArmMasses.of(MODEL))
    got = [PH.read2ByteTxRx(port, s.id, 40) for s in MODEL.servos]
    assert all(r[1:] == (sdk.COMM_SUCCESS, 0) for r in got)
    for j, d in enumerate(directions):
        want = expected_load(gravity[j], d)
        signed = lambda v: -(v & 0x3FF) if v & CW else v & 0x3FF
        assert abs(signed(got[j][0]) - signed(want)) <= 1, (j, got[j][0], want, gravity)
    assert np.allclose(board.true_joints(), np.radians(q), atol=1e-9)


def test_arm_held_out_level_loads_joint_2_by_its_lever_arms():
    """By hand: the arm straight out (joint 2 at 90 deg), each mass at its distance from the
    shoulder; joint 2's servo, mounted either way, pushes the joint up."""
    m = ArmMasses.of(MODEL)
    L2, L3 = MODEL.L2 / 1000, MODEL.L3 / 1000
    torque = G * (m.upper_arm * m.upper_arm_com + m.elbow_servo * L2 + m.forearm * (L2 + m.forearm_com)
                  + m.end_effector * (L2 + m.end_effector_com))
    for truth, bit in ((MODEL_TRUTH, 0), (REVERSED, CW)):      # joint 2 up is CCW, or CW reversed
        board, port, units = held_board(truth, 0, 0, (0, 90, 0))
        value = PH.read2ByteTxRx(port, 2, 40)[0]
        q2 = math.radians(truth[1][1] * (units[1] - truth[0][1]) / UNITS_PER_DEG)
        assert value & CW == bit
        assert abs((value & 0x3FF) - torque * math.sin(q2) / STALL_NM_AT_12V * 1023) <= 1


def test_a_limp_arm_reads_no_load():
    board, port, _ = held_board(REVERSED, 10, 20, (-40, 70, -45))
    for s in MODEL.servos:
        assert PH.write1ByteTxRx(port, s.id, 24, 0) == (sdk.COMM_SUCCESS, 0)
        assert PH.read2ByteTxRx(port, s.id, 40) == (0, sdk.COMM_SUCCESS, 0)


def test_true_joints_follow_the_servos_as_mounted_and_servo_joints_the_model():
    board = SimBoard(MODEL, servo_truth=REVERSED)
    board.joint_servos[1].turn_by_hand(400.0)
    assert board.true_joints()[1] == pytest.approx(math.radians(-(400 - 497) / UNITS_PER_DEG))
    model_zero, model_direction = MODEL.servos[1].zero, MODEL.servos[1].direction
    assert board.servo_joints()[1] == pytest.approx(math.radians(model_direction * (400 - model_zero) / UNITS_PER_DEG))


@pytest.mark.parametrize("truth", [((512, 512), (1, 1, 1)), ((512, 512, 512), (1, 0, 1)), ((512, 512, 2000), (1, 1, 1)),
                                   "520,497,505"])
def test_a_bad_servo_truth_is_refused_with_a_message(truth):
    with pytest.raises(ValueError, match="servo truth"):
        SimBoard(MODEL, servo_truth=truth)


def test_the_firmware_reports_the_load_in_its_heartbeat():
    """Enabled and parked: each servo's load in the heartbeat is what statics predicts at the
    shafts' true angles on the supply they report."""
    board = make_board(at=PARK_UNITS)
    board.send("enable", on=1)
    assert run_until(board, lambda: running(board), 3.0) is not None
    board.run(1.0)
    hb = board.heartbeats[-1]
    gravity = gravity_oracle(board.true_joints(), [0.0, 0.0, 1.0], ArmMasses.of(MODEL))
    volts = hb["servo1_voltage"] / 10
    for j, s in enumerate(MODEL.servos):
        want = expected_load(gravity[j], s.direction, volts)
        got = hb[f"servo{j + 1}_load"]
        assert abs((got & 0x3FF) - (want & 0x3FF)) <= 1 and (got & 0x3FF < 2 or got & CW == want & CW), (j, got, want)
