"""What the drone-side node does, without ROS: the port (opened, lost and reopened every
second), each loop step (the heartbeats in; the drone's attitude and velocity, each
measurement once, a streamed target, or a keep-alive, out), the
status a heartbeat gives, and commands answered once a heartbeat confirms them. A board that
restarts while enabled after a watchdog reset or a fault comes up limp: an error, and (unless
reenable is off) enable is sent again so that it parks; it is never engaged again by itself. The ROS 1
node (ros_node) is an adapter around it: parameters, topics, services, log; a ROS 2 node
would be another.

No ROS import here: a logger (info, warn, error, warn_every(seconds, text)) and a status
callback are passed in.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Callable, Optional, Tuple

from .client import KEEP_ALIVE_S, CommandRefused, LinkError, PortNotFound, RestartWatch
from .message_table import REACH_M, TICK_RATE_HZ
from .messages import (FAULTS, REFUSALS, fault_names, fault_vector_name, reset_cause_name, source_names,
                       state_name)
from .shared import SharedLink

FAULT_TEXT = dict(FAULTS)
# The arm's joints as the generated URDF (generated/uavarm_arm.urdf) names them.
JOINT_NAMES = ("arm_joint1", "arm_joint2", "arm_joint3")


def roll_pitch(x: float, y: float, z: float, w: float) -> Tuple[float, float]:
    """Roll and pitch (rad) of Z-Y-X Euler angles (R = Rz(yaw) Ry(pitch) Rx(roll)) of a
    quaternion, normalised first; ValueError for a zero or non-finite one."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not (math.isfinite(n) and n > 1e-9):
        raise ValueError(f"not a rotation quaternion: ({x}, {y}, {z}, {w})")
    x, y, z, w = x / n, y / n, z / n, w / n
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


def rotate(q: Tuple[float, float, float, float], v: Tuple[float, float, float]) -> Tuple[float, float, float]:
    """v turned by the unit quaternion q = (x, y, z, w): R(q) v."""
    x, y, z, w = q
    vx, vy, vz = v
    return ((1 - 2 * (y * y + z * z)) * vx + 2 * (x * y - w * z) * vy + 2 * (x * z + w * y) * vz,
            2 * (x * y + w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z - w * x) * vz,
            2 * (x * z - w * y) * vx + 2 * (y * z + w * x) * vy + (1 - 2 * (x * x + y * y)) * vz)


def level_point(roll: float, pitch: float, p: Tuple[float, float, float]) -> Tuple[float, float, float]:
    """A point in the drone's body axes (the arm's base turns with it) in the level,
    heading-following frame: Ry(pitch) Rx(roll) p, the Z-Y-X Euler angles without the yaw."""
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    x, y, z = p
    y, z = cr * y - sr * z, sr * y + cr * z
    return cp * x + sp * z, y, -sp * x + cp * z


def level_velocity(q: Tuple[float, float, float, float], v: Tuple[float, float, float],
                   in_body: bool) -> Tuple[float, float, float]:
    """A velocity (m/s) in the gravity-aligned, heading-following frame (the yaw of the
    quaternion q = (x, y, z, w) removed), from body axes (in_body: nav_msgs/Odometry's twist,
    in its child frame) or from the parent (world) frame; ValueError for a bad quaternion."""
    x, y, z, w = q
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not (math.isfinite(n) and n > 1e-9):
        raise ValueError(f"not a rotation quaternion: ({x}, {y}, {z}, {w})")
    x, y, z, w = x / n, y / n, z / n, w / n
    vx, vy, vz = rotate((x, y, z, w), v) if in_body else v
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    c, s = math.cos(yaw), math.sin(yaw)
    return c * vx + s * vy, -s * vx + c * vy, vz


def units_hint(x: float, y: float, z: float) -> str:
    """A hint for a target (m) so far outside the reach that it was surely given in millimetres."""
    if math.sqrt(x * x + y * y + z * z) > 100.0 * REACH_M:
        return f" (millimetres? the services and ~target take metres; the arm reaches {REACH_M:.3f} m)"
    return ""


def describe(hb: dict) -> str:
    return (f"enabled {hb['enabled']} engaged {hb['engaged']} set position "
            f"({hb['set_x'] / 1000:.4f}, {hb['set_y'] / 1000:.4f}, {hb['set_z'] / 1000:.4f}) m "
            f"faults {fault_names(hb['faults'])}")


def servo_load(units: int) -> float:
    """An AX-12A's Present Load (0..1023 of its maximum torque, bit 10 set when clockwise) as a
    fraction, -1..1: positive counter-clockwise."""
    return (units & 0x3FF) / 1023.0 * (-1.0 if units & 0x400 else 1.0)


def status_of(hb: dict, attitude_source: str, velocity_source: str = "none", unexpected_resets: int = 0) -> dict:
    """A heartbeat as the node reports it: SI units (m, s), names for codes; unexpected_resets:
    the board's restarts while enabled after a watchdog reset or a fault (RestartWatch)."""
    return {
        "attitude_source": attitude_source, "velocity_source": velocity_source,
        "unexpected_resets": unexpected_resets,
        "enabled": bool(hb["enabled"]), "engaged": bool(hb["engaged"]), "unreachable": bool(hb["unreachable"]),
        "seq": hb["seq"], "uptime": hb["uptime_ms"] / 1000.0, "state": hb["state"],
        "state_name": state_name(hb["state"]), "refusal_code": hb["refusal"],
        "refusal": REFUSALS[hb["refusal"]][0] if 0 < hb["refusal"] < len(REFUSALS) else "",
        "reset_cause": reset_cause_name(hb["reset_cause"]),
        "last_fault": fault_vector_name(hb["last_fault"]) if hb["last_fault"] else "",
        "faults": hb["faults"], "fault_names": fault_names(hb["faults"]),
        "estimate_sources": source_names(hb["estimate_sources"]),
        "servo_errors": [hb["servo1_error"], hb["servo2_error"], hb["servo3_error"]],
        "set_position": [hb["set_x"] / 1000.0, hb["set_y"] / 1000.0, hb["set_z"] / 1000.0],
        "joints": [hb["p1"], hb["p2"], hb["p3"]],          # the shafts, NaN where not read
        "goal_joints": [hb["q1"], hb["q2"], hb["q3"]],
        "servo_voltage": [hb[f"servo{i}_voltage"] / 10.0 for i in (1, 2, 3)],
        "servo_temperature": [float(hb[f"servo{i}_temperature"]) for i in (1, 2, 3)],
        "servo_load": [servo_load(hb[f"servo{i}_load"]) for i in (1, 2, 3)],
        "link_frames_ok": hb["link_frames_ok"], "link_errors": hb["link_errors"],
        "servo_timeouts": hb["servo_timeouts"],
    }


class ArmCore:
    REOPEN_PERIOD = 1.0

    def __init__(self, port: str, baud: int, log, on_status: Callable[[dict], None], *,
                 attitude_timeout: float = 0.2, keep_alive: bool = True, keep_alive_period: float = KEEP_ALIVE_S,
                 attitude_topic: str = "the attitude topic", reenable: bool = True, clock=time.monotonic,
                 target_rate: float = 50.0):
        """clock: the link's (ArmLink's); step(now) and the inputs' times are on it; reenable:
        enable a board that restarted while enabled (RestartWatch) again; target_rate: the most
        set positions per second a target stream sends (at most the board's tick rate)."""
        if not 0 < target_rate <= TICK_RATE_HZ:
            raise ValueError(f"target_rate must be above 0 and at most the board's tick rate, {TICK_RATE_HZ:g} Hz, "
                             f"got {target_rate}")
        import serial
        self.port, self.baud, self.log, self.on_status = port, baud, log, on_status
        self.clock = clock
        self.attitude_timeout, self.keep_alive, self.keep_alive_period = attitude_timeout, keep_alive, keep_alive_period
        self.attitude_topic, self.reenable = attitude_topic, reenable
        self.restarts = RestartWatch()            # across reopenings: a real board's port goes as it resets
        self._serial_errors = (serial.SerialException, OSError)
        self.link: Optional[SharedLink] = None
        self.link_error = "not opened yet"
        self._reopen_at = 0.0
        self.command_lock = threading.Lock()      # one command (send + confirmation) at a time
        self._attitude = None                     # (roll, pitch, stamp_us, received), until sent
        self._attitude_received = None            # when the last one came
        self._velocity = None                     # ((vx, vy, vz), stamp_us, received), until sent
        self._told_unstamped = False
        self.target_period = 1.0 / target_rate
        self._target = None                       # the stream's latest point (m), until sent
        self._target_sent = None                  # when a streamed set position last went out
        self._streamed = None                     # the last one (mm), until a service sets another
        self._velocity_sent = None                # when the last one was forwarded
        self.attitude_source = "imu"              # what the last step forwarded: "drone" or "imu"
        self.velocity_source = "none"             # "drone" while velocities are forwarded
        self._last_hb = None
        self._last_hb_time = None
        self._silent = False
        self._restarts = 0

    # ---------------------------------------------------------------- inputs

    def attitude(self, roll: float, pitch: float, stamp_us: Optional[int], received: float) -> None:
        """The drone's latest attitude (rad), its stamp (us, its clock; None: stamped now) and
        when it came; forwarded once by the next step."""
        self._attitude = (roll, pitch, self._stamp(stamp_us, received), received)
        self._attitude_received = received

    def velocity(self, v: Tuple[float, float, float], stamp_us: Optional[int], received: float) -> None:
        """The drone's latest velocity (m/s, heading-following frame), its stamp (None: stamped
        now) and when it came; forwarded once by the next step."""
        self._velocity = (v, self._stamp(stamp_us, received), received)

    def target(self, x: float, y: float, z: float) -> None:
        """A streamed target (m, the set position's frame): the latest one is sent as the set
        position by a step, at most every target_period; the board's refusals come in the
        status (refusal, unreachable), as for the service."""
        if not all(math.isfinite(v) for v in (x, y, z)):
            self.log.warn_every(5.0, f"arm: ~target ({x}, {y}, {z}) ignored: not finite")
            return
        hint = units_hint(x, y, z)
        if hint:
            self.log.warn_every(5.0, f"arm: ~target ({x:.4g}, {y:.4g}, {z:.4g}) m is unreachable{hint}")
        self._target = (x, y, z)

    def _stamp(self, stamp_us: Optional[int], received: float) -> int:
        """A measurement's stamp; one without (a header stamp of zero) is stamped on arrival,
        on the link's clock, so that the board sees each measurement once, in order."""
        if stamp_us is not None:
            return stamp_us
        if not self._told_unstamped:
            self._told_unstamped = True
            self.log.warn(f"arm: messages on {self.attitude_topic} carry no stamp (header stamp zero): "
                          "stamped on arrival, which adds the topic's delay to the board's estimate")
        return int(received * 1e6)

    # ---------------------------------------------------------------- the port

    def open(self, now: float) -> None:
        try:
            self.link = SharedLink(self.port, self.baud, clock=self.clock)
        except PortNotFound as exc:
            if self.link_error != str(exc):
                self.log.error(f"arm: {exc}; retrying every {self.REOPEN_PERIOD:.0f} s")
            self.link_error = str(exc)
            self._reopen_at = now + self.REOPEN_PERIOD
            return
        self.link_error = None
        self._last_hb_time, self._silent, self._restarts = now, False, 0
        self.log.info(f"arm: {self.port} open")

    def _lose(self, exc, now: float) -> None:
        why = f"{self.port}: {exc}"
        self.log.error(f"arm: serial link lost ({why}); reopening every {self.REOPEN_PERIOD:.0f} s")
        link, self.link, self.link_error = self.link, None, why
        link.fail(why)
        self._reopen_at = now + self.REOPEN_PERIOD

    def close(self, why: str = "node shut down") -> None:
        if self.link is not None:
            self.link.fail(why)

    # ---------------------------------------------------------------- the loop

    def step(self, now: float) -> None:
        link = self.link
        if link is None:
            if now >= self._reopen_at:
                self.open(now)
            return
        try:
            for hb in link.poll():
                self._on_heartbeat(hb, now)
            self._check_silence(now)
            fresh = self._attitude_received is not None and now - self._attitude_received <= self.attitude_timeout
            self._report_source("drone" if fresh else "imu")
            att, self._attitude = self._attitude, None        # each measurement once
            if att is not None and now - att[3] <= self.attitude_timeout:
                link.send_attitude(att[0], att[1], att[2])
            vel, self._velocity = self._velocity, None
            if vel is not None and now - vel[2] <= self.attitude_timeout:
                link.send_velocity(*vel[0], vel[1])
                self._velocity_sent = now
            if self._target is not None and (self._target_sent is None
                                              or now - self._target_sent >= self.target_period):
                x, y, z = self._target
                self._target = None
                self._streamed = {"x": x * 1000.0, "y": y * 1000.0, "z": z * 1000.0}
                link.send("set_position", **self._streamed)
                self._target_sent = now
            forwarding = self._velocity_sent is not None and now - self._velocity_sent <= self.attitude_timeout
            self._report_velocity("drone" if forwarding else "none")
            if not fresh and link.engaged:
                self.log.warn_every(5.0, "arm: engaged but no attitude on the attitude topic for "
                                         f"{self.attitude_timeout} s"
                                    + ("" if self.keep_alive else "; keep-alive off: the arm will park"))
                if self.keep_alive and now - link.last_sent >= self.keep_alive_period:
                    if self._streamed is not None:      # (the last heartbeat may be older than it)
                        link.send("set_position", **self._streamed)
                    else:
                        link.keep_alive()
        except LinkError:
            pass                                    # failed already (a command thread saw it)
        except self._serial_errors as exc:
            self._lose(exc, now)

    def _report_source(self, source: str) -> None:
        if source == self.attitude_source:
            return
        self.attitude_source = source
        if source == "drone":
            self.log.info(f"arm: forwarding the drone's attitude from {self.attitude_topic} to the board")
        else:
            self.log.warn(f"arm: no attitude on {self.attitude_topic} for {self.attitude_timeout:.2f} s: "
                          "the board runs on its own IMU only")

    def _report_velocity(self, source: str) -> None:
        if source == self.velocity_source:
            return
        self.velocity_source = source
        if source == "drone":
            self.log.info(f"arm: forwarding the drone's velocity from {self.attitude_topic} to the board")
        else:
            self.log.warn(f"arm: no velocity on {self.attitude_topic} for {self.attitude_timeout:.2f} s: the board "
                          "goes on without it")

    def _check_silence(self, now: float) -> None:
        if self._last_hb_time is not None and now - self._last_hb_time > self.link.silence and not self._silent:
            self._silent = True
            self.log.error(f"arm: no heartbeat from the board for {now - self._last_hb_time:.1f} s "
                           "(powered? right port and baud?)")

    def _on_heartbeat(self, hb: dict, now: float) -> None:
        if self._silent:
            self.log.info("arm: heartbeats back")
        self._silent, self._last_hb_time = False, now
        unmeant = self.restarts.check(hb)
        if unmeant is not None:
            self._restarts = self.link.age.restarts
            if self.reenable:
                self.link.send("enable", on=self.restarts.enabled_as)
                self.log.error(f"arm: {unmeant}; enable sent again: {self.restarts.reenabled()} "
                               "(call engage again when ready)")
            else:
                self.log.error(f"arm: {unmeant}; left so (reenable is off): enable it again to park it")
        elif self.link.age.restarts > self._restarts:
            self._restarts = self.link.age.restarts
            self.log.warn(f"arm: the board restarted (its uptime went back to {hb['uptime_ms'] / 1000.0:.1f} s; "
                          f"reset cause {reset_cause_name(hb['reset_cause'])}"
                          + (f", after a {fault_vector_name(hb['last_fault'])}" if hb["last_fault"] else "") + ")")
        before = set() if self._last_hb is None else set(fault_names(self._last_hb["faults"]))
        for name in fault_names(hb["faults"]):
            if name not in before:
                self.log.warn(f"arm: fault {name}: {FAULT_TEXT[name]}")
        self._last_hb = hb
        self.on_status(status_of(hb, self.attitude_source, self.velocity_source, self.restarts.count))

    # ---------------------------------------------------------------- commands

    def command(self, action) -> Tuple[bool, str]:
        """action(link) under the command lock: (True, the confirming heartbeat described) or
        (False, why not)."""
        with self.command_lock:
            link = self.link
            if link is None:
                return False, f"no link to the board: {self.link_error}"
            try:
                return True, describe(action(link))
            except (CommandRefused, LinkError, ValueError) as exc:
                return False, str(exc)
            except self._serial_errors as exc:
                return False, f"serial link lost: {self.port}: {exc}"

    def enable(self, on: bool) -> Tuple[bool, str]:
        return self.command(lambda link: link.enable(on))

    def engage(self, on: bool) -> Tuple[bool, str]:
        return self.command(lambda link: link.engage(on))

    def set_position(self, x: float, y: float, z: float) -> Tuple[bool, str]:
        """The target in metres (the board takes millimetres)."""
        self._streamed = None
        ok, text = self.command(lambda link: link.set_position(x * 1000.0, y * 1000.0, z * 1000.0))
        if not ok:
            text = f"target ({x:.4f}, {y:.4f}, {z:.4f}) m: {text} (board figures in mm){units_hint(x, y, z)}"
        return ok, text
