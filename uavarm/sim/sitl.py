"""The simulated board behind a pseudo-terminal: `uavarm sitl [SCENARIO]`; and a simulated
servo bus behind one, as through a Dynamixel adapter: `uavarm sitl --servo-bus`.

The firmware application (host build) runs in real time (or `speed` times faster) with the
simulated servos and IMU; a pseudo-terminal stands in for the board's USB virtual COM port,
so the link client, the ROS node or a terminal program cannot tell it from the real board:
LLCP frames in, heartbeats every 0.5 s out.

A machine too busy to run the board in real time makes it fall behind: it then catches up,
at no more than CATCH_UP times the speed asked, and says so (`warn`, stderr by default) when
it is more than LAG_WARN_S behind, so late heartbeats are not taken for a broken link. A link
client in the same process can keep the board's time instead of the wall clock's
(`ArmLink(device, clock=sitl.clock)`): its timeouts, the heartbeats' ages and the delays it
measures then count in simulated time, whatever the load.

Scenarios: `level` (default), `tilt:ROLL,PITCH` (degrees, held still) and
`rock:ROLL,PITCH,HZ` (bench tilting: sinusoidal roll and pitch of those amplitudes).

A hand on the hardware, for rehearsing the bring-up: commands typed at the SITL's own
terminal (`read_commands`, or `submit` / `handle` from a test) turn the board to a face,
move a limp joint, or say where everything is (COMMANDS). They run in the board's thread
between two slices of its run, so the board never sees half a command.
"""
from __future__ import annotations

import fcntl
import math
import os
import select
import struct
import sys
import threading
import time
import tty
from collections import deque
from concurrent.futures import CancelledError, Future

import numpy as np

from .. import rotation
from .ax12_sim import AX12, AX12Bus
from .xseries_sim import XServo
from .board import Gravity, Rocking, SimBoard, Turning, reset_cause_value
from .imu_model import Mpu6050Sensor
from ..model import config

# A simulated second is run in slices no longer than this, so input is never late by more.
SLICE_S = 0.002
# Ahead of the wall clock, the board waits up to this long (s) for input before it runs on:
# its output is never later than that (a USB full-speed frame is 1 ms). Behind by no more
# than AT_ONCE_S, it catches up at once; further behind, at CATCH_UP.
WAIT_S = 0.002
AT_ONCE_S = 0.005
# bytes of output the SITL holds for a reader that is behind (a busy machine), about 14 s of
# heartbeats and a stream at twice real time; beyond, the oldest are dropped
OUTPUT_KEPT = 256 * 1024
# ioctl reading a tty's struct termios2 (Linux, asm-generic): its speeds are the bit rates
TCGETS2 = 0x802C542A
# The firmware's main loop runs every this many simulated microseconds (the closed-loop
# simulator's: 0.36 s of CPU per simulated second engaged, against 0.57 s at SimBoard's
# 100 us, so a busy machine keeps up more often).
POLL_US = 250
# Behind real time by more than this (s), the board says so; again at most every LAG_REPORT_S
# while it stays behind, and once when it has caught up.
LAG_WARN_S = 0.1
LAG_REPORT_S = 5.0
# Behind real time, the board catches up at no more than this many times the speed asked.
# Flat out (7.3 times real time idle, 2.2 to 2.6 times engaged beside busy processes, on a
# 2-core VM) a program that paces itself on the wall clock, as a node's 10 ms loop and its
# keep-alive do, looked that much slower to the board than to a real one: a pause of 0.4 s in
# it could become the 1 s of silence after which the board parks an engaged arm. At this
# rate that takes a pause of 0.8 s (beside a real board, 1 s).
CATCH_UP = 1.25
# clock() raises once the board's time has stood still this long (s of wall time): a hang
# guard for clients that wait on it.
STALL_S = 30.0


class SitlStalled(RuntimeError):
    """The simulated board's clock stopped (the SITL stopped or hung)."""


SCENARIOS = "level, tilt:ROLL,PITCH (deg) or rock:ROLL,PITCH,HZ (deg, deg, Hz)"

# How long (simulated s) a hand takes to turn the board to a face, and how far (rad) the axis
# it turns about is from the exact one: a face is reached a few degrees off (up to twice this),
# as by hand. (Turns about exact axes would leave cross-axis terms of the gyro unseen.)
TURN_S = 1.5
HAND_OFF_AXIS = math.radians(3.0)
COMMANDS = """commands (a hand on the simulated hardware):
  turn X|Y|Z up|down  turn the board by hand, over 1.5 s, until that IMU axis (as printed on
                      the breakout) points up or down, a few degrees off as by hand; then hold
                      it still
  level               turn the board back level (the arm's base z up)
  move joint J DEG    turn limp joint J (1-3) by hand to DEG degrees (its true angle)
  hold zero           hold every limp joint at its true 0 deg (hanging straight down, joint 1
                      turned to +x): the servo calibration's zero pose
  where               the joints' true angles, the board's attitude, each servo's state
  help                this list"""
AXES = {"x": 0, "y": 1, "z": 2}


def holding_load(servo) -> str:
    """What a holding servo reads of its load, in its own register's units and sense."""
    if isinstance(servo, XServo):
        name = "present_current" if servo.model.current_sensing else "present_load"
        value = servo.register(name)
        return f"{name.replace('_', ' ')} {abs(value)} {'CCW' if value >= 0 else 'CW'}"
    load = servo.present_load()
    return f"load {load & 0x3FF} {'CW' if load & 0x400 else 'CCW'}"


def degrees_text(radians: float) -> str:
    """An angle in degrees to 0.1, never "-0.0"."""
    return f"{round(math.degrees(radians), 1) + 0.0:.1f}"


def motion_of(scenario: str | None):
    if scenario in (None, "", "level"):
        return Gravity()
    kind, _, args = scenario.partition(":")
    shapes = {"tilt": 2, "rock": 3}
    try:
        values = [float(v) for v in args.split(",")]
        if kind not in shapes or len(values) != shapes[kind] or not all(map(math.isfinite, values)):
            raise ValueError
    except ValueError:
        raise ValueError(f"scenario {scenario!r}: use {SCENARIOS}") from None
    if kind == "tilt":
        return Gravity(math.radians(values[0]), math.radians(values[1]))
    if not 0 < values[2] <= 10:
        raise ValueError(f"scenario {scenario!r}: rocking frequency must be in (0, 10] Hz")
    return Rocking(math.radians(values[0]), math.radians(values[1]), values[2])


class Sitl:
    """The board and its pseudo-terminal. `device` is the path to open; `run()` serves it until
    `stop()` (from another thread) or Ctrl-C."""

    def __init__(self, scenario: str | None = None, *, speed: float = 1.0, model=None,
                 link_delay: tuple[float, float] = (0.0, 0.0), warn=None, **board_options):
        """link_delay: seconds (simulated) the link's bytes take to the board and back from it;
        warn(text): where lagging behind real time is reported (default: stderr);
        board_options: SimBoard's (sensor, imu_mounting_rpy_deg, servo_lag, supply, servo_truth: the
        hardware as it is)."""
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        if not all(0 <= d <= 1 for d in link_delay):
            raise ValueError(f"link delay must be 0 to 1000 ms each way, got {link_delay}")
        self.speed = speed
        self._delay_us = [round(d * 1e6) for d in link_delay]
        self._inbound: deque[tuple[int, bytes]] = deque()    # (due board us, bytes) on their way in
        self._outbound: deque[tuple[int, bytes]] = deque()   # and out
        self._outbound_bytes = 0
        self.board = SimBoard(model, motion=motion_of(scenario), record=False, poll_us=POLL_US, **board_options)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)          # bytes pass unchanged: no echo, no line editing
        os.set_blocking(self._master, False)
        self.device = os.ttyname(self._slave)
        self._stop = threading.Event()
        self._thread = None
        self._warn = warn or (lambda text: print(text, file=sys.stderr, flush=True))
        self.lag = 0.0                   # s of real time the board is behind, now
        self.max_lag = 0.0               # and at most, since it started
        self._lag_told = None            # (wall time, board us) of the last lag report
        self._clock_seen = (0, time.monotonic())
        self._resets: deque[tuple[str, int]] = deque()      # asked of the board's thread
        self._commands: deque[tuple[str, Future]] = deque()  # typed commands, for the board's thread

    def start(self) -> "Sitl":
        """run() in a daemon thread; stop() ends it."""
        self._thread = threading.Thread(target=self.run, daemon=True, name="sitl")
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=10)

    def reset(self, cause: str = "watchdog", last_fault: int = 0) -> None:
        """Reset the simulated chip (SimBoard.reset) between two slices of its run, as its
        watchdog or a fault would: the port stays open, the heartbeats start again from zero."""
        reset_cause_value(cause)               # (a bad name raises here, not in the board's thread)
        self._resets.append((cause, last_fault))

    def submit(self, text: str) -> Future:
        """A command (COMMANDS) for the running board: handled between two slices of its run;
        the Future's result is what it did (cancelled if the SITL stops first)."""
        done = Future()
        if self._stop.is_set():
            done.cancel()
        else:
            self._commands.append((text, done))
        return done

    def read_commands(self, stream=None, write=None) -> threading.Thread:
        """Commands read line by line from `stream` (default stdin, prompting if a terminal) on
        a thread of their own, each handled by the running board and what it did written
        (default stdout). At the end of the stream the thread ends; the SITL runs on."""
        stream = sys.stdin if stream is None else stream
        write = write or (lambda text: print(text, flush=True))

        def serve():
            prompt = stream.isatty()
            while True:
                if prompt:
                    print("sitl> ", end="", flush=True)
                try:
                    line = stream.readline()
                except (OSError, ValueError):       # no usable stdin: the board runs on
                    return
                if not line:
                    return
                if line.strip():
                    try:
                        write(self.submit(line).result())
                    except CancelledError:
                        return
        thread = threading.Thread(target=serve, daemon=True, name="sitl-commands")
        if stream is not None:
            thread.start()
        return thread

    def handle(self, text: str) -> str:
        """Do one command (COMMANDS) to the board, now: call it between runs of the board (the
        running SITL does, for submit()). Returns what it did, or why not, in one line."""
        words = text.lower().split()
        if words[:1] == ["turn"] and len(words) == 3 and words[1] in AXES and words[2] in ("up", "down"):
            return self._turn_face(words[1], words[2] == "up")
        if words == ["level"]:
            return self._turn_to(np.array([0.0, 0.0, 1.0]), "the board is level (its z up)")
        if words[:2] == ["move", "joint"] and len(words) == 4:
            return self._move_joint(words[2], words[3])
        if words == ["hold", "zero"]:
            return self._hold_zero()
        if words == ["where"]:
            return self._where()
        if words in (["help"], ["?"]):
            return COMMANDS
        return f"unknown command {text.strip()!r}: one of turn X|Y|Z up|down, level, move joint J DEG, " \
               "hold zero, where, help"

    def _orientation(self) -> np.ndarray:
        """The board's orientation now (base axes to the world's; yaw left out)."""
        motion, t = self.board.motion, self.board.time
        if hasattr(motion, "orientation"):
            return motion.orientation(t)
        roll, pitch = motion.attitude(t)
        return rotation.from_vector((0.0, pitch, 0.0)) @ rotation.from_vector((roll, 0.0, 0.0))

    def _turn_face(self, axis: str, up: bool) -> str:
        direction = self.board.imu_axis(AXES[axis]) * (1.0 if up else -1.0)
        way = "up" if up else "down"
        return self._turn_to(direction, f"the IMU's {axis.upper()} axis points {way}", off_axis=True)

    def _turn_to(self, target: np.ndarray, what: str, off_axis: bool = False) -> str:
        """The board turned by hand, the shortest way, until `target` (base axes) points up
        (off_axis: about an axis HAND_OFF_AXIS off that way's, so that it ends a few degrees off)."""
        start = self._orientation()
        up = start[2]                                  # the world's up in base axes
        axis = np.cross(target, up)
        angle = math.atan2(np.linalg.norm(axis), float(target @ up))
        if angle < (3 * HAND_OFF_AXIS if off_axis else 1e-6):
            return f"already so: {what}"
        if np.linalg.norm(axis) < 1e-9:                # upside down
            # flipped over the next axis (Z over X, X over Y, Y over Z): the six faces in the
            # IMU calibration's order then turn the board over each of its axes
            other = np.eye(3)[(int(np.argmax(np.abs(target))) + 1) % 3]
            axis = other - (other @ target) * target
        axis = axis / np.linalg.norm(axis)
        if off_axis:    # a hand's turn is never about the exact axis
            aside = np.cross(axis, target)
            axis = math.cos(HAND_OFF_AXIS) * axis + math.sin(HAND_OFF_AXIS) * aside / np.linalg.norm(aside)
        self.board.motion = Turning(start, axis * angle, self.board.time, TURN_S)
        return f"turning the board by hand, {math.degrees(angle):.0f} deg over {TURN_S:g} s, until {what}"

    def _move_joint(self, joint: str, degrees: str) -> str:
        try:
            j, deg = int(joint), float(degrees)
        except ValueError:
            return f"move joint {joint} {degrees}: use move joint J DEG, J 1 to 3, DEG in degrees"
        if not 1 <= j <= len(self.board.joint_servos) or not math.isfinite(deg):
            return f"move joint {joint} {degrees}: use move joint J DEG, J 1 to 3, DEG in degrees"
        servo = self.board.joint_servos[j - 1]
        if servo is None:
            return f"joint {j} has no servo"
        if servo.torque_on:
            return f"joint {j} holds its position: the torque is on"
        units = self.board.truth_units(j - 1, math.radians(deg))
        top = self.board.model.servo_units_max
        if not 0 <= units <= top:
            return f"joint {j} at {deg:g} deg is past its servo's travel (units {units:.0f}, 0 to {top})"
        servo.turn_by_hand(units)
        return f"joint {j} turned by hand to {deg:g} deg (servo {servo.id} at {units:.1f} units)"

    def _hold_zero(self) -> str:
        held, holding = [], []
        for j, servo in enumerate(self.board.joint_servos, 1):
            if servo is None:
                continue
            if servo.torque_on:
                holding.append(j)
            else:
                units = self.board.truth_units(j - 1, 0.0)
                servo.turn_by_hand(units)
                held.append(f"{j} ({units:g} units)")
        said = [f"joints {', '.join(held)} held at 0 deg"] if held else []
        said += [f"joint {j} holds its position: the torque is on" for j in holding]
        return "; ".join(said) or "no joint has a servo"

    def _where(self) -> str:
        joints = ", ".join(degrees_text(q) for q in self.board.true_joints())
        roll, pitch = (degrees_text(a) for a in self.board.motion.attitude(self.board.time))
        states = []
        for j, servo in enumerate(self.board.joint_servos, 1):
            if servo is None:
                states.append(f"{j} missing")
            elif not servo.powered:
                states.append(f"{j} unpowered")
            elif servo.torque_on:
                states.append(f"{j} holding, {holding_load(servo)}")
            else:
                states.append(f"{j} limp")
        return f"joints {joints} deg (true); board roll {roll}, pitch {pitch} deg; servos: {', '.join(states)}"

    def clock(self) -> float:
        """The board's simulated time (s), for a link client in this process to keep
        (ArmLink(device, clock=sitl.clock)). SitlStalled once it has not moved for STALL_S."""
        now_us, wall = self.board.now_us, time.monotonic()
        if now_us != self._clock_seen[0]:
            self._clock_seen = (now_us, wall)
        elif wall - self._clock_seen[1] > STALL_S:
            raise SitlStalled(f"the simulated board's clock has stood at {now_us / 1e6:.3f} s for "
                              f"{wall - self._clock_seen[1]:.0f} s: the SITL stopped or hung")
        return now_us / 1e6

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def _read_input(self) -> None:
        """The bytes written to the port, due delay_in after the board's time now (the link's
        delays count in the board's time, the one a client keeping sitl.clock sees)."""
        while True:
            try:
                data = os.read(self._master, 4096)
            except (BlockingIOError, OSError):
                return
            if not data:
                return
            self._inbound.append((self.board.now_us + self._delay_us[0] if self._delay_us[0] else 0, data))

    def _run_until_us(self, end_us: int) -> None:
        """The board run to end_us, the input handed to it as each piece's delay ends."""
        while self._inbound and self._inbound[0][0] <= end_us:
            due, data = self._inbound.popleft()
            self.board.run_until_us(max(due, self.board.now_us))
            self.board.send_bytes(data)
        self.board.run_until_us(end_us)

    def _write_output(self) -> None:
        out = self.board.take_link_output()
        if out:
            self._outbound.append((self.board.now_us + self._delay_us[1], out))
            self._outbound_bytes += len(out)
        while self._outbound and self._outbound[0][0] <= self.board.now_us:
            due, out = self._outbound.popleft()
            try:
                n = os.write(self._master, out)
            except BlockingIOError:
                n = 0
            self._outbound_bytes -= n
            if n < len(out):   # the reader is behind: the rest waits, as in the host's USB buffers
                self._outbound.appendleft((due, out[n:]))
                break
        while self._outbound_bytes > OUTPUT_KEPT:
            self._outbound_bytes -= len(self._outbound.popleft()[1])   # nobody reads: the oldest dropped

    def run(self) -> None:
        """The board kept at real time times the speed, a slice at a time, until stop()."""
        start = last = time.monotonic()
        try:
            while not self._stop.is_set():
                wall = time.monotonic()
                target_us = round((wall - start) * self.speed * 1e6)
                pace_us = target_us if target_us - self.board.now_us <= round(AT_ONCE_S * self.speed * 1e6) \
                    else self.board.now_us + round((wall - last) * self.speed * CATCH_UP * 1e6)
                last = wall
                while self._resets:
                    self.board.reset(*self._resets.popleft())
                while self._commands:
                    text, done = self._commands.popleft()
                    try:
                        done.set_result(self.handle(text))
                    except Exception as exc:   # a command's slip must not stop the board
                        done.set_result(f"{text.strip()!r} failed: {exc}")
                self._read_input()
                end_us = min(target_us, pace_us, self.board.now_us + round(SLICE_S * 1e6))
                self._run_until_us(end_us)
                self._write_output()
                self._watch_lag(target_us - self.board.now_us)
                if self.board.now_us >= target_us:
                    select.select([self._master], [], [], WAIT_S)   # ahead of the wall clock: wait
        finally:
            while self._commands:
                self._commands.popleft()[1].cancel()
            self.close()

    def _watch_lag(self, behind_us: int) -> None:
        """Report falling behind real time: how far, and how fast the board ran since the last
        report (the speed asked was self.speed)."""
        self.lag = max(0, behind_us) / 1e6 / self.speed
        self.max_lag = max(self.max_lag, self.lag)
        wall, now_us = time.monotonic(), self.board.now_us
        told = self._lag_told
        if told is None and self.lag > LAG_WARN_S or told is not None and wall - told[0] >= LAG_REPORT_S:
            if self.lag > LAG_WARN_S:
                rate = "" if told is None else \
                    f", running at {(now_us - told[1]) / 1e6 / (wall - told[0]):.2f}x real time since the last report"
                self._warn(f"sitl: the simulated board is {self.lag:.2f} s behind real time (speed {self.speed:g}x "
                           f"asked{rate}): the machine is too busy; its heartbeats come late")
                self._lag_told = (wall, now_us)
            elif told is not None:
                self._warn(f"sitl: the simulated board has caught up with real time (at most "
                           f"{self.max_lag:.2f} s behind)")
                self._lag_told = None


class ServoBusPort:
    """A Dynamixel adapter (as a ROBOTIS U2D2 with its power hub) on a simulated AX-12A bus,
    behind a pseudo-terminal: what is written to `device` goes out on the bus at the baud the
    port is set to (as pyserial sets it), and the servos' replies come back. Simulated time
    runs only while bytes are on the wire and the replies are written at once, so what the
    port answers does not depend on this machine's speed. `servos` are the AX12 objects
    connected (default: one AX-12A as it ships, id 1 at 1 Mbit/s); change `bus.servos`
    while holding `lock` to plug one out and another in."""

    def __init__(self, servos=None):
        self.bus = AX12Bus([AX12(1)] if servos is None else servos, baud=1_000_000)
        self.lock = threading.Lock()
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.device = os.ttyname(self._slave)
        self._stop = threading.Event()

    def baud(self) -> int:
        """The baud rate the port is set to (Linux termios2: any rate, as pyserial sets it)."""
        buf = bytearray(44)                               # struct termios2
        fcntl.ioctl(self._slave, TCGETS2, buf)
        return struct.unpack_from("<I", buf, 40)[0]       # c_ospeed

    def stop(self) -> None:
        self._stop.set()

    def run(self) -> None:
        """Serves the port until stop() (from another thread) or Ctrl-C."""
        try:
            while not self._stop.is_set():
                if not select.select([self._master], [], [], 0.02)[0]:
                    continue
                try:
                    data = os.read(self._master, 4096)
                except OSError:
                    continue
                with self.lock:
                    self.bus.baud = self.baud()
                    self.bus.write(data)
                    self.bus.settle()
                    reply = self.bus.read()
                if reply:
                    os.write(self._master, reply)
        finally:
            for fd in (self._master, self._slave):
                os.close(fd)


def serve_servo_bus() -> int:
    """`uavarm sitl --servo-bus`: one AX-12A as it ships on a simulated bus behind a pty."""
    port = ServoBusPort()
    print(f"simulated servo bus on {port.device}: one AX-12A as it ships (id 1 at 1 Mbit/s), as through a "
          "Dynamixel adapter; Ctrl-C stops", flush=True)
    try:
        port.run()
    except KeyboardInterrupt:
        print("stopped")
    return 0


def angles_of(text: str) -> tuple[float, float, float]:
    """ROLL,PITCH,YAW in degrees."""
    try:
        values = tuple(float(v) for v in text.split(","))
        if len(values) != 3 or not all(map(math.isfinite, values)):
            raise ValueError
    except ValueError:
        raise ValueError(f"{text!r}: use ROLL,PITCH,YAW in degrees") from None
    return values


def link_delay_of(text: str) -> tuple[float, float]:
    """UP[,DOWN] in milliseconds (DOWN: as UP) -> seconds each way."""
    try:
        values = tuple(float(v) for v in text.split(","))
        if len(values) not in (1, 2) or not all(0 <= v <= 1000 for v in values):
            raise ValueError
    except ValueError:
        raise ValueError(f"link delay {text!r}: use UP[,DOWN] in milliseconds, each 0 to 1000") from None
    return values[0] / 1000, values[-1] / 1000


def integers_of(text: str, what: str, allowed: set[int] | range, described: str) -> tuple[int, int, int]:
    """Three comma-separated integers, each in `allowed` (`described` says which)."""
    try:
        values = tuple(int(v) for v in text.split(","))
        if len(values) != 3 or not all(v in allowed for v in values):
            raise ValueError
    except ValueError:
        raise ValueError(f"{what} {text!r}: use three of {described}, comma-separated") from None
    return values


def mounted_servos(model, zeros: tuple[int, ...] | None, directions: tuple[int, ...] | None):
    """SimBoard's servo_truth from what was given, the rest as the model file says (None: all of it)."""
    if zeros is None and directions is None:
        return None
    return (zeros or tuple(s.zero for s in model.servos), directions or tuple(s.direction for s in model.servos))


def main(scenario: str | None, speed: float, imu: str = "white", seed: int = 0,
         imu_mounting: tuple[float, float, float] | None = None, servo_lag: float | None = None,
         link_delay: tuple[float, float] = (0.0, 0.0), supply: float | None = None,
         servo_zeros: tuple[int, int, int] | None = None, servo_directions: tuple[int, int, int] | None = None,
         motors_on: bool = False, commands=None) -> int:
    """`uavarm sitl`: the board served in real time, commands (COMMANDS) read from `commands`
    (default stdin). Its scenarios are all on the bench: the IMU feels the propellers only
    with motors_on (the `calibrated` and `datasheet` profiles' vibration)."""
    model = config.load()
    sensor = Mpu6050Sensor(imu, seed=seed, vibration_from=0.0 if motors_on else math.inf)
    sitl = Sitl(scenario, speed=speed, model=model, sensor=sensor,
                imu_mounting_rpy_deg=imu_mounting, servo_lag=servo_lag, link_delay=link_delay, supply=supply,
                servo_truth=mounted_servos(model, servo_zeros, servo_directions))
    lag = sitl.board.model.servo_response_lag if servo_lag is None else servo_lag
    print(f"simulated board on {sitl.device} (scenario {scenario or 'level'}, speed {speed}x, IMU {imu} "
          f"seed {seed}, motors {'on' if motors_on else 'off'}, servo lag {lag * 1000:g} ms, "
          f"supply {sitl.board.bus.supply.volts:g} V, link delay {link_delay[0] * 1000:g} ms in, "
          f"{link_delay[1] * 1000:g} ms out); Ctrl-C stops", flush=True)
    zeros, directions = sitl.board.servo_truth
    print(f"servos mounted with zeros {', '.join(f'{z:g}' for z in zeros)} units, directions "
          f"{', '.join(f'{d:+d}' for d in directions)}; type commands here (help lists them)", flush=True)
    sitl.read_commands(commands)
    try:
        sitl.run()
    except KeyboardInterrupt:
        print("stopped")
    return 0
