"""The simulated board behind a pseudo-terminal: `uavarm sitl [SCENARIO]`.

The firmware application (host build) runs in real time (or `speed` times faster) with the
simulated servos and IMU; a pseudo-terminal stands in for the board's USB virtual COM port,
so the link client, the ROS node or a terminal program cannot tell it from the real board:
LLCP frames in, heartbeats every 0.5 s out.

Scenarios: `level` (default), `tilt:ROLL,PITCH` (degrees, held still) and
`rock:ROLL,PITCH,HZ` (bench tilting: sinusoidal roll and pitch of those amplitudes).
"""
from __future__ import annotations

import math
import os
import threading
import time
import tty

from .board import Gravity, Rocking, SimBoard
from .imu_model import Mpu6050Sensor

# A simulated second is run in slices no longer than this, so input is never late by more.
SLICE_S = 0.002


SCENARIOS = "level, tilt:ROLL,PITCH (deg) or rock:ROLL,PITCH,HZ (deg, deg, Hz)"


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

    def __init__(self, scenario: str | None = None, *, speed: float = 1.0, model=None, **board_options):
        """board_options: SimBoard's (sensor, imu_mounting_rpy_deg, servo_lag: the hardware as it is)."""
        if not speed > 0:
            raise ValueError(f"speed must be positive, got {speed}")
        self.speed = speed
        self.board = SimBoard(model, motion=motion_of(scenario), record=False, **board_options)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)          # bytes pass unchanged: no echo, no line editing
        os.set_blocking(self._master, False)
        self.device = os.ttyname(self._slave)
        self._stop = threading.Event()

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        for fd in (self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def _read_input(self) -> None:
        while True:
            try:
                data = os.read(self._master, 4096)
            except (BlockingIOError, OSError):
                return
            if not data:
                return
            self.board.send_bytes(data)

    def _write_output(self) -> None:
        out = self.board.take_link_output()
        while out:
            try:
                n = os.write(self._master, out)
            except BlockingIOError:
                return      # nobody is reading: heartbeats are dropped, as a full USB queue would
            out = out[n:]

    def run(self) -> None:
        start = time.monotonic()
        try:
            while not self._stop.is_set():
                self._read_input()
                target_us = round((time.monotonic() - start) * self.speed * 1e6)
                end_us = min(target_us, self.board.now_us + round(SLICE_S * 1e6))
                self.board.run_until_us(end_us)
                self._write_output()
                if self.board.now_us >= target_us:
                    time.sleep(0.0005)
        finally:
            self.close()


def angles_of(text: str) -> tuple[float, float, float]:
    """ROLL,PITCH,YAW in degrees."""
    try:
        values = tuple(float(v) for v in text.split(","))
        if len(values) != 3 or not all(map(math.isfinite, values)):
            raise ValueError
    except ValueError:
        raise ValueError(f"{text!r}: use ROLL,PITCH,YAW in degrees") from None
    return values


def main(scenario: str | None, speed: float, imu: str = "white", seed: int = 0,
         imu_mounting: tuple[float, float, float] | None = None, servo_lag: float = 0.0) -> int:
    sitl = Sitl(scenario, speed=speed, sensor=Mpu6050Sensor(imu, seed=seed), imu_mounting_rpy_deg=imu_mounting,
                servo_lag=servo_lag)
    print(f"simulated board on {sitl.device} (scenario {scenario or 'level'}, speed {speed}x, IMU {imu} "
          f"seed {seed}, servo lag {servo_lag * 1000:g} ms); Ctrl-C stops", flush=True)
    try:
        sitl.run()
    except KeyboardInterrupt:
        print("stopped")
    return 0
