"""Drone side of the serial link: commands to the arm and its heartbeats, over pyserial.

    with ArmLink("/dev/ttyACM0") as arm:
        arm.enable()                       # waits until a heartbeat shows it
        arm.set_position(60, 20, -120)     # CommandRefused if the board flags it unreachable
        arm.engage()
        print(arm.status())

Every command is confirmed by the heartbeats (sent every 0.5 s): the call returns when a
heartbeat shows the command took effect, raises CommandRefused when the board's flags say
why it did not, and LinkSilent when no heartbeat comes at all. An engaged arm parks if the
link is silent for the model's link.silence_timeout, so a drone keeps sending: `keep_alive()`
repeats the current set position (only while no new target is being set).
"""
from __future__ import annotations

import math
import struct
import time
from collections import deque

from . import llcp, messages
from .messages import fault_names

# a command is judged on the heartbeats that follow it: the first may predate it
CONFIRM_HEARTBEATS = 2


class LinkError(Exception):
    """The link to the arm failed."""


class PortNotFound(LinkError):
    """The serial port does not exist or cannot be opened."""


class LinkSilent(LinkError):
    """No heartbeat arrived in time (board off, wrong port, cable)."""


class LinkGarbled(LinkSilent):
    """Bytes arrive but no valid frame does (wrong baud, another device)."""


class CommandRefused(LinkError):
    """The board refused a command; the message says why."""


def _f32(v: float) -> float:
    return struct.unpack("<f", struct.pack("<f", v))[0]


def _expected_len(msg_id: int) -> int:
    m = messages.BY_ID.get(msg_id)
    return m.size if m is not None else -1


class ArmLink:
    """port: a device path (or a pyserial URL, or an open serial object for tests); silence:
    seconds without a heartbeat that count as a dead link (default: three heartbeat periods
    of the model file)."""

    def __init__(self, port, baud: int = 115200, *, silence: float | None = None):
        import serial
        if silence is None:
            from .model import config
            silence = 3 * config.load().heartbeat_period
        if isinstance(port, str):
            try:
                self.serial = serial.serial_for_url(port, baudrate=baud, timeout=0)
            except (serial.SerialException, OSError) as exc:
                raise PortNotFound(f"{port}: cannot open the serial port ({exc})") from None
        else:
            self.serial = port
        self.silence = silence
        self.decoder = llcp.Decoder(gap=0.1, expected_len=_expected_len)
        self.heartbeats: deque[dict] = deque(maxlen=100)
        self.bytes_received = 0
        self._attitude_seq = 0

    def close(self) -> None:
        self.serial.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---------------------------------------------------------------- receiving

    def poll(self) -> list[dict]:
        """The heartbeats received since the last call (non-blocking)."""
        data = self.serial.read(4096)
        self.bytes_received += len(data)
        new = []
        for payload in self.decoder.feed(data, time.monotonic()):
            name, fields = messages.decode(payload)
            if name == "heartbeat":
                self.heartbeats.append(fields)
                new.append(fields)
        return new

    def next_heartbeat(self, timeout: float | None = None) -> dict:
        """Wait for the next heartbeat; LinkSilent (or LinkGarbled) if none comes in time."""
        timeout = self.silence if timeout is None else timeout
        start_bytes, end = self.bytes_received, time.monotonic() + timeout
        while True:
            new = self.poll()
            if new:
                return new[0]
            if time.monotonic() > end:
                if self.bytes_received > start_bytes:
                    raise LinkGarbled(f"{self.bytes_received - start_bytes} bytes in {timeout:.1f} s but no "
                                      f"valid heartbeat (checksum errors {self.decoder.checksum_errors}, "
                                      f"bad characters {self.decoder.hex_errors}): wrong baud or device?")
                raise LinkSilent(f"no heartbeat for {timeout:.1f} s: is the board powered and the port right?")
            time.sleep(0.005)

    def status(self) -> dict:
        """The next heartbeat, with the fault bits named under 'fault_names'."""
        hb = dict(self.next_heartbeat())
        hb["fault_names"] = fault_names(hb["faults"])
        return hb

    # ---------------------------------------------------------------- commands

    def send(self, name: str, **fields) -> None:
        self.serial.write(llcp.encode(messages.encode(name, **fields)))
        self.serial.flush()

    def _confirm(self, ok, why) -> dict:
        """Wait for a heartbeat satisfying ok(hb); CommandRefused with why(hb) otherwise."""
        hb = None
        for _ in range(CONFIRM_HEARTBEATS):
            hb = self.next_heartbeat()
            if ok(hb):
                return hb
        raise CommandRefused(why(hb))

    def enable(self, on: bool = True) -> dict:
        """enable 1 is taken once the servos are configured (the heartbeat's state past
        "starting"), so an engage may follow at once."""
        self.send("enable", on=int(on))
        starting = [name for name, _ in messages.STATES].index("starting")
        return self._confirm(lambda hb: hb["enabled"] == int(on) and (not on or hb["state"] > starting),
                             lambda hb: f"enable {int(on)} not taken; faults {fault_names(hb['faults'])}")

    def disable(self) -> dict:
        return self.enable(False)

    def engage(self, on: bool = True) -> dict:
        self.send("engage", on=int(on))

        def why(hb):
            if on and not hb["enabled"]:
                return "engage refused: the arm is not enabled (enable it first)"
            return f"engage {int(on)} not taken; faults {fault_names(hb['faults'])}"
        return self._confirm(lambda hb: hb["engaged"] == int(on), why)

    def disengage(self) -> dict:
        return self.engage(False)

    def set_position(self, x: float, y: float, z: float) -> dict:
        """Target in mm, level frame at the arm's base (z down is negative)."""
        target = (float(x), float(y), float(z))
        if not all(math.isfinite(v) for v in target):
            raise ValueError(f"set_position needs finite coordinates, got {target}")
        self.send("set_position", x=target[0], y=target[1], z=target[2])
        want = tuple(_f32(v) for v in target)

        def taken(hb):
            return (hb["set_x"], hb["set_y"], hb["set_z"]) == want and not hb["unreachable"]

        def why(hb):
            if hb["unreachable"]:
                return (f"set_position {target} refused: unreachable (outside the reach, in the body or a "
                        f"leg); the arm keeps ({hb['set_x']:.1f}, {hb['set_y']:.1f}, {hb['set_z']:.1f})")
            return f"set_position {target} not taken; faults {fault_names(hb['faults'])}"
        return self._confirm(taken, why)

    def send_attitude(self, roll: float, pitch: float, stamp_us: int | None = None) -> None:
        """Forward the drone's attitude (rad) from its flight controller; call at >= 50 Hz."""
        if not (math.isfinite(roll) and math.isfinite(pitch)):
            raise ValueError(f"attitude must be finite, got roll {roll}, pitch {pitch}")
        stamp = int(time.monotonic() * 1e6) if stamp_us is None else stamp_us
        self.send("drone_attitude", seq=self._attitude_seq, stamp_us=stamp & 0xFFFFFFFF, roll=roll, pitch=pitch)
        self._attitude_seq = (self._attitude_seq + 1) & 0xFFFF

    def keep_alive(self) -> None:
        """Repeat the board's current set position, so an engaged arm does not park."""
        if self.heartbeats:
            hb = self.heartbeats[-1]
            self.send("set_position", x=hb["set_x"], y=hb["set_y"], z=hb["set_z"])
