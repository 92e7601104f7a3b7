"""The SITL's own prompt: a hand on the simulated hardware for rehearsing the bring-up.

The commands are driven through `Sitl.handle` with the board run by the test (no threads),
through `submit` / `read_commands` on a running SITL, and once through `uavarm sitl`'s
stdin. Oracles: gravity as the IMU's datasheet scale reads it (1 g along the axis turned up),
the e-manual's 300 deg over 1023 units, and the servos' mounting the test gives.
"""
from __future__ import annotations

import io
import math
import os
import queue
import signal
import subprocess
import sys
import threading

import numpy as np
import pytest

from conftest import wait_simulated
from uavarm.sim.imu_model import Mpu6050Sensor
from uavarm.sim.sitl import HAND_OFF_AXIS, TURN_S, Sitl

UNITS_PER_DEG = 1023 / 300
TRUTH = ((520, 497, 505), (1, -1, 1))           # joint 2's servo mounted the other way round
MOUNTING = (10.0, -20.0, 30.0)                   # the IMU as it really sits (deg)


def raw_accel_g(board) -> np.ndarray:
    """The IMU's accelerometer registers (ACCEL_XOUT_H.., big-endian int16) in g at the
    full scale the firmware chose."""
    regs = bytes(board.imu.regs[0x3B:0x41])
    words = [int.from_bytes(regs[k:k + 2], "big", signed=True) for k in (0, 2, 4)]
    return np.array(words) / board.imu.accel_lsb_per_g


@pytest.fixture
def sitl():
    s = Sitl(servo_truth=TRUTH, imu_mounting_rpy_deg=MOUNTING, sensor=Mpu6050Sensor("ideal"))
    s.board.run(0.05)                      # the firmware has set the IMU up
    yield s
    s.close()


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("way", ["up", "down"])
def test_turning_puts_that_imu_axis_up_or_down(sitl, axis, way):
    said = sitl.handle(f"turn {'xyz'[axis]} {way}")
    assert said.startswith("turning the board by hand") and f"{'XYZ'[axis]} axis points {way}" in said
    sitl.board.run(TURN_S + 0.2)
    want = np.zeros(3)
    want[axis] = 1.0 if way == "up" else -1.0
    got = raw_accel_g(sitl.board)
    off = math.degrees(math.acos(np.clip(got @ want / np.linalg.norm(got), -1, 1)))
    assert abs(np.linalg.norm(got) - 1) < 0.002 and off < 2 * math.degrees(HAND_OFF_AXIS) + 0.2, (got, off)
    assert "already so" in sitl.handle(f"turn {'xyz'[axis]} {way}")


def test_the_turn_is_a_turn_and_level_comes_back(sitl):
    """Half way through, the board is between the faces and the gyro sees it turning; `level`
    brings the base's z up again (the IMU then reads its mounting's tilt)."""
    sitl.handle("turn x down")
    sitl.board.run(TURN_S / 2)
    half = raw_accel_g(sitl.board)
    assert 0.3 < np.linalg.norm(half[[1, 2]]) and abs(half[0]) < 0.95
    sitl.board.run(TURN_S)
    sitl.handle("level")
    sitl.board.run(TURN_S + 0.2)
    roll, pitch = sitl.board.motion.attitude(sitl.board.time)
    assert abs(roll) < 1e-9 and abs(pitch) < 1e-9
    assert "roll 0.0, pitch 0.0" in sitl.handle("where")


def test_moving_a_limp_joint_turns_its_shaft_to_the_true_angle(sitl):
    said = sitl.handle("move joint 2 30")
    units = 497 - 30 * UNITS_PER_DEG
    assert said == f"joint 2 turned by hand to 30 deg (servo 2 at {units:.1f} units)"
    assert sitl.board.joint_servos[1].position == pytest.approx(units)
    assert math.degrees(sitl.board.true_joints()[1]) == pytest.approx(30.0)
    sitl.board.run(0.1)                                        # and it stays there
    assert sitl.board.joint_servos[1].position == pytest.approx(units)
    assert sitl.handle("hold zero") == "joints 1 (520 units), 2 (497 units), 3 (505 units) held at 0 deg"
    assert [s.position for s in sitl.board.joint_servos] == [520, 497, 505]
    assert sitl.handle("where").startswith("joints 0.0, 0.0, 0.0 deg (true)")


def test_a_joint_whose_torque_is_on_is_not_moved(sitl):
    servo = sitl.board.joint_servos[1]
    sitl.board.bus.power(True)
    servo.set_register("torque_enable", 1)
    before = servo.position
    assert sitl.handle("move joint 2 30") == "joint 2 holds its position: the torque is on"
    assert "joint 2 holds its position: the torque is on" in sitl.handle("hold zero")
    assert servo.position == before
    assert sitl.board.joint_servos[0].position == 520                  # the limp ones were held at 0
    assert "2 holding, load" in sitl.handle("where")


@pytest.mark.parametrize("text, said", [
    ("spin", "unknown command 'spin'"),
    ("turn w up", "unknown command"),
    ("turn x sideways", "unknown command"),
    ("move joint 2", "unknown command"),
    ("move joint 9 10", "use move joint J DEG"),
    ("move joint two 10", "use move joint J DEG"),
    ("move joint 2 1e400", "use move joint J DEG"),
    ("move joint 1 200", "past its servo's travel"),
    ("", "unknown command"),
])
def test_bad_input_gets_one_line_and_changes_nothing(sitl, text, said):
    before = [s.position for s in sitl.board.joint_servos]
    reply = sitl.handle(text)
    assert said in reply and "\n" not in reply
    assert [s.position for s in sitl.board.joint_servos] == before


def test_help_lists_every_command(sitl):
    text = sitl.handle("help")
    for command in ("turn X|Y|Z up|down", "level", "move joint J DEG", "hold zero", "where", "help"):
        assert command in text


# ------------------------------------------------------------- on a running SITL

@pytest.mark.realtime
def test_commands_typed_on_a_running_sitl_reach_its_board():
    s = Sitl(speed=2.0, sensor=Mpu6050Sensor("ideal")).start()
    replies = []
    try:
        reader = s.read_commands(io.StringIO("turn y up\n\nmove joint 1 20\nbogus\n"), replies.append)
        reader.join(timeout=60)                   # a hang guard: each reply waits for the board's thread
        assert not reader.is_alive()
        assert len(replies) == 3 and replies[2].startswith("unknown command")
        assert wait_simulated(s, TURN_S + 1.0, lambda: raw_accel_g(s.board)[1] > 0.99)
        assert math.degrees(s.board.true_joints()[0]) == pytest.approx(20.0)
        assert s.submit("where").result(timeout=60).startswith("joints 20.0")
    finally:
        s.stop()
    assert s.submit("where").cancelled()              # stopped: nothing waits for it


@pytest.mark.realtime
def test_uavarm_sitl_takes_commands_on_stdin_and_runs_on_after_eof():
    # Ctrl-C as at a terminal: a run started in the background (`cmd &` in a script) ignores
    # SIGINT, and its children would inherit that. (-X faulthandler: a SIGABRT makes it print
    # every thread's stack, should it not end.)
    proc = subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", "uavarm.cli", "sitl", "--speed", "2",
                             "--servo-zeros", "520,497,505", "--servo-directions", "1,-1,1"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))

    lines = queue.Queue()
    threading.Thread(target=lambda: [lines.put(text) for text in proc.stdout], daemon=True).start()

    def line():
        return lines.get(timeout=60)         # a hang guard
    try:
        assert line().startswith("simulated board on /dev/pts/")
        assert "zeros 520, 497, 505 units, directions +1, -1, +1" in line()
        proc.stdin.write("move joint 2 30\nwhere\n")
        proc.stdin.close()                                               # EOF: the board runs on
        assert line().strip() == f"joint 2 turned by hand to 30 deg (servo 2 at {497 - 30 * UNITS_PER_DEG:.1f} units)"
        assert line().startswith("joints -2.3, 30.0, 2.1 deg (true)")
        assert proc.poll() is None
    finally:
        os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)
            proc.wait(timeout=30)
            pytest.fail(f"uavarm sitl did not end within 30 s of Ctrl-C; its threads:\n{proc.stderr.read()}")
    assert "Traceback" not in proc.stderr.read()


@pytest.mark.realtime
def test_an_imu_calibration_rehearsed_with_the_prompts_turns_finds_the_sensors_errors(tmp_path, capsys):
    """The user of docs/bring-up.md's rehearsal: at each of the calibration's six positions,
    the SITL's `turn` command for it, then Enter once the turn is over."""
    from uavarm import calibrate
    from uavarm.link import ArmLink
    from uavarm.model import config

    model = tmp_path / "manipulator.toml"
    model.write_bytes(config.DEFAULT_MODEL.read_bytes())
    s = Sitl(speed=2.0, sensor=Mpu6050Sensor("datasheet", seed=3, vibration_from=math.inf)).start()
    faces = iter(["level", "turn z down", "turn x up", "turn x down", "turn y up", "turn y down"])

    def ask(text):
        said = s.submit(next(faces)).result(timeout=60)
        if said.startswith("turning"):
            wait_simulated(s, TURN_S + 0.3)
    try:
        with ArmLink(s.device, clock=s.clock) as arm:
            arm.next_heartbeat()
            assert calibrate.imu(arm, model, ask, lambda q: True, seconds=2.0)
    finally:
        s.stop()
    truth, cal = s.board.sensor.draw, config.load(model).imu_calibration
    assert np.abs(np.array(cal.accel_bias) - truth.accel_bias).max() <= 0.002            # 2 mg
    assert np.abs(np.array(cal.gyro_scale) / truth.gyro_scale - 1).max() <= 0.002        # 0.2 %
    assert "over 5 turns" in capsys.readouterr().out
