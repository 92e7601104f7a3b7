"""Drone side of the serial link: commands to the arm and its heartbeats, over pyserial.

    with ArmLink("/dev/ttyACM0") as arm:
        arm.enable()                       # waits until a heartbeat shows it
        arm.set_position(60, 20, -120)     # CommandRefused if the board flags it unreachable
        arm.engage()
        print(arm.status())

Every command is confirmed by the heartbeats (sent every link.heartbeat_period of the model
file): a ping follows it, and the board, which takes frames in order, answers the ping once it
has taken the command, so only heartbeats that come after that pong judge it. The call returns
when such a heartbeat shows the command took effect, raises CommandRefused when the board's
flags say why it did not (or none shows it within CONFIRM_S of the board's time), and
LinkSilent when no heartbeat comes for SILENCE_S (LinkGarbled: bytes come but no valid frame;
LinkLate: valid heartbeats come, all too late to trust). No rule counts heartbeats, so they
hold at any heartbeat period.

An engaged, limp or jogged arm parks if the link is silent for the model's
link.silence_timeout (a ping does not count), so a drone keeps sending: `keep_alive()`
repeats the current set position (only while no new target is being set), and within
`with arm.kept_alive():` every poll does so once nothing was sent for KEEP_ALIVE_S (the
calibrations on the bench).

Only fresh heartbeats count: each carries a sequence number and the board's uptime, and one
that arrives more than STALE_S later than the board's clock says it should (queued while no
one read the port) is dropped and counted, never used to confirm a command. None can
have waited longer than since the port was last read empty, so a board whose clock runs slow
(a simulated board behind real time) is not taken for one whose heartbeats queued. Gaps in
the sequence and board restarts (uptime going back) are counted too; RestartWatch tells the
restarts that leave an arm limp (its watchdog or a fault reset it while it was enabled).

Time is this computer's monotonic clock, or `clock` (a function returning seconds): a
simulated board in the same process (uavarm.sim.sitl) lends its own, so that timeouts and
ages count in the time it keeps.
"""
from __future__ import annotations

import contextlib
import math
import struct
import time
from collections import deque

from . import llcp, messages
from .messages import fault_names, fault_vector_name, refusal_reason, reset_cause_name

try:
    from termios import error as _TermiosError
except ImportError:      # (not POSIX)
    class _TermiosError(Exception):
        pass

# s: a heartbeat that arrives this much later than the board's clock says it was sent waited
# in the port's buffer (this computer read it too seldom): dropped as stale
STALE_S = 0.5
# s without a fresh heartbeat that count as a dead link (ArmLink's default)
SILENCE_S = 1.5
# s of the board's time after it took a command within which a heartbeat must show the
# command took effect (enable waits for the servos to be configured: about 0.3 s)
CONFIRM_S = 1.0
# s: a command's ping not answered by then (a frame lost to noise) is sent again
PING_AGAIN_S = 0.25
# the pings that follow commands count from here (uavarm calibrate link counts from 0)
COMMAND_PING_SEQ = 0xC000
# bytes taken from the port in one poll at most (about 400 heartbeats)
READ_LIMIT = 65536
# s between keep-alives: the board parks an engaged, limp or jogged arm after
# link.silence_timeout (1 s) without a frame
KEEP_ALIVE_S = 0.2
# enable's value for the bench, and the heartbeat's enabled then (model/messages.py)
BENCH = 2
# the heartbeat's state and refusal values the confirmations wait past
STARTING = [name for name, _ in messages.STATES].index("starting")
IMU_NOT_READY = [name for name, _ in messages.REFUSALS].index("imu_not_ready")
# the resets a board does not mean (heartbeat.reset_cause): an enabled arm comes up limp
UNMEANT_RESETS = ("watchdog", "window_watchdog")


def bench_note(hb: dict) -> str:
    """What a status line adds for a bench-enabled arm (heartbeat enabled 2)."""
    return " (bench: enabled limp)" if hb["enabled"] == BENCH else ""


class LinkError(Exception):
    """The link to the arm failed."""


class PortNotFound(LinkError):
    """The serial port does not exist or cannot be opened."""


class LinkSilent(LinkError):
    """No heartbeat arrived in time (board off, wrong port, cable)."""


class LinkGarbled(LinkSilent):
    """Bytes arrive but no valid frame does (wrong baud, another device)."""


class LinkLate(LinkSilent):
    """Valid heartbeats arrive, but each more than STALE_S after it was sent: they waited in
    the port's buffer (this computer reads it too seldom)."""


class CommandRefused(LinkError):
    """The board refused a command; the message says why, `heartbeat` shows it."""

    def __init__(self, why: str, heartbeat: dict | None = None):
        super().__init__(why)
        self.heartbeat = heartbeat


def _f32(v: float) -> float:
    return struct.unpack("<f", struct.pack("<f", v))[0]


def _ms_since(first_ms: int, hb: dict) -> int:
    """Milliseconds of the board's time from first_ms (an uptime_ms) to heartbeat hb."""
    return (hb["uptime_ms"] - first_ms) & 0xFFFFFFFF


def _expected_len(msg_id: int) -> int:
    m = messages.BY_ID.get(msg_id)
    return m.size if m is not None else -1


class HeartbeatAge:
    """Sequence and age checks of the heartbeats, from their seq and uptime_ms fields.

    The age of a heartbeat is how much later than the freshest one it arrived, measured on the
    board's clock: arrival time minus uptime, less the least such value seen. The least value
    may rise by DRIFT per second, so clocks 1,000 ppm apart do not age fresh heartbeats. Given
    the time since the port was last read empty (read_gap), the age is at most that plus how
    much older than the newest of its read it is: it was sent after that read, and before the
    newest, whatever the two clocks' rates."""

    DRIFT = 1e-3

    def __init__(self, stale_after: float = STALE_S):
        self.stale_after = stale_after
        self.floor = None          # the least (arrival - uptime) seen, s
        self.floor_at = 0.0
        self.last = None           # (seq, uptime_ms, board time in s) of the last heartbeat
        self.lost = 0              # heartbeats missing from the sequence
        self.stale = 0             # heartbeats dropped as older than stale_after
        self.stale_age = 0.0       # the age of the last one dropped (s)
        self.restarts = 0          # the board's uptime went back: it restarted

    def fresh(self, batch: list[dict], now: float, read_gap: float | None = None) -> list[dict]:
        """The heartbeats of one read that are at most stale_after old, each with its 'age' (s);
        read_gap: seconds since the port was last read empty (None: not known)."""
        if not batch:
            return []
        times = [self._board_time(hb) for hb in batch]
        offsets = [now - t for t in times]
        if self.floor is not None:
            self.floor += self.DRIFT * (now - self.floor_at)
        self.floor = min(offsets) if self.floor is None else min(self.floor, min(offsets))
        self.floor_at = now
        kept = []
        for hb, t, offset in zip(batch, times, offsets):
            hb["age"] = offset - self.floor
            if read_gap is not None:
                hb["age"] = min(hb["age"], read_gap + max(0.0, times[-1] - t))
            if hb["age"] > self.stale_after:
                self.stale += 1
                self.stale_age = hb["age"]
            else:
                kept.append(hb)
        return kept

    def _board_time(self, hb: dict) -> float:
        """The board's uptime in s, counted on past the 49.7-day wrap of uptime_ms; counts
        sequence gaps and restarts on the way."""
        if self.last is not None:
            seq, uptime, board_time = self.last
            step = (hb["uptime_ms"] - uptime) & 0xFFFFFFFF
            if step < 1 << 31:
                self.lost += (hb["seq"] - seq - 1) & 0xFFFF
                self.last = (hb["seq"], hb["uptime_ms"], board_time + step / 1000.0)
                return self.last[2]
            self.restarts += 1
            self.floor = None              # a new clock: ages start over
        self.last = (hb["seq"], hb["uptime_ms"], hb["uptime_ms"] / 1000.0)
        return self.last[2]


class RestartWatch:
    """Tells when a board restarted while it was enabled because its watchdog reset it or a
    fault halted it (the heartbeat's uptime went back; reset_cause, last_fault): it comes up
    with the servo supply off, the arm hanging limp. Fed every fresh heartbeat, of one link or
    of several in turn to the same board (a real board's USB port goes away as it resets)."""

    def __init__(self):
        self.last = None           # the previous heartbeat
        self.count = 0             # such restarts seen
        self.enabled_as = 1        # enable's value before the last such restart (BENCH: limp again)

    def check(self, hb: dict) -> str | None:
        """What to report if hb shows such a restart, else None."""
        last, self.last = self.last, hb
        went_back = last is not None and (hb["uptime_ms"] - last["uptime_ms"]) & 0xFFFFFFFF >= 1 << 31
        cause = reset_cause_name(hb["reset_cause"])
        if not (went_back and last["enabled"] and (cause in UNMEANT_RESETS or hb["last_fault"])):
            return None
        self.count += 1
        self.enabled_as = last["enabled"]
        after = f" after a {fault_vector_name(hb['last_fault'])}" if hb["last_fault"] else ""
        return (f"the board restarted while enabled (reset cause {cause}{after}, up {hb['uptime_ms'] / 1000:.1f} s "
                f"again): it came up with the servo power off, the arm limp"
                + ("; it was engaged" if last["engaged"] else "")
                + ("; it was bench-enabled (enable 2, limp)" if last["enabled"] == BENCH else ""))

    def reenabled(self) -> str:
        """What enabling it again as it was (enable_as) does."""
        return "it parks" if self.enabled_as != BENCH else "limp again, as on the bench"


class ArmLink:
    """port: a device path (or a pyserial URL, or an open serial object for tests); silence:
    seconds without a fresh heartbeat that count as a dead link."""

    def __init__(self, port, baud: int = 115200, *, silence: float = SILENCE_S, clock=time.monotonic):
        import serial
        self.clock = clock
        if isinstance(port, str):
            try:
                self.serial = serial.serial_for_url(port, baudrate=baud, timeout=0)
            except (serial.SerialException, OSError, _TermiosError) as exc:   # (termios: gone while opening)
                raise PortNotFound(f"{port}: cannot open the serial port ({exc})") from None
        else:
            self.serial = port
        self.silence = silence
        self.age = HeartbeatAge()
        self.decoder = llcp.Decoder(gap=0.1, expected_len=_expected_len)
        self.heartbeats: deque[dict] = deque(maxlen=100)
        self.streamed: dict[str, deque] = {"imu_raw": deque(maxlen=10_000), "servo_status": deque(maxlen=10_000)}
        self.pongs: deque[tuple[dict, float]] = deque(maxlen=10_000)   # (pong, self.clock() read)
        self.bytes_received = 0
        self._emptied_at = None    # when a read last left the port empty
        self.last_sent = -math.inf  # clock() when a frame was last sent
        self.keep_alive_every = None   # s: each poll repeats the set position after this long unsent
        self._attitude_seq = 0
        self._velocity_seq = 0
        self.frames_in = 0           # valid frames received: a heartbeat's 'frame' is its number
        self._pings_sent = 0         # pings that followed commands
        self._answered: dict[int, int | None] = {}   # such a ping's seq: its pong's frame number

    def close(self) -> None:
        self.serial.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---------------------------------------------------------------- receiving

    def poll(self) -> list[dict]:
        """The fresh heartbeats received since the last call, oldest first (non-blocking)."""
        data, emptied = b"", False
        while len(data) < READ_LIMIT:     # all that is queued, so a batch's newest dates the rest
            chunk = self.serial.read(4096)
            if not chunk:
                emptied = True
                break
            data += chunk
        self.bytes_received += len(data)
        now = self.clock()
        read_gap = None if self._emptied_at is None else now - self._emptied_at
        self._emptied_at = now if emptied else None
        batch = []
        for payload in self.decoder.feed(data, now):
            name, fields = messages.decode(payload)
            self.frames_in += 1
            if name == "heartbeat":
                fields["frame"] = self.frames_in
                batch.append(fields)
            elif name in self.streamed:
                self.streamed[name].append(fields)
            elif name == "pong":
                self.pongs.append((fields, now))
                if self._answered.get(fields["seq"], 0) is None:
                    self._answered[fields["seq"]] = self.frames_in
        new = self.age.fresh(batch, now, read_gap)
        self.heartbeats.extend(new)
        if self.keep_alive_every is not None and now - self.last_sent >= self.keep_alive_every:
            self.keep_alive()
        return new

    @contextlib.contextmanager
    def kept_alive(self, every: float = KEEP_ALIVE_S):
        """Within: each poll (every wait for a heartbeat, a stream or the user, if it polls)
        repeats the set position once nothing was sent for `every` s, so a limp, jogged or
        engaged arm stays so while this program runs."""
        before, self.keep_alive_every = self.keep_alive_every, every
        try:
            yield self
        finally:
            self.keep_alive_every = before

    def next_heartbeat(self, timeout: float | None = None) -> dict:
        """Wait for the next fresh heartbeat (the newest if several came at once); LinkSilent
        (LinkGarbled, LinkLate) if none comes in time."""
        timeout = self.silence if timeout is None else timeout
        since, end = self.counts(), self.clock() + timeout
        while True:
            new = self.poll()
            if new:
                return new[-1]
            if self.clock() > end:
                raise self.no_heartbeat(timeout, since)
            time.sleep(0.005)   # (a poll's interval: how long is the clock's to say)

    def counts(self) -> tuple[int, int, int, int]:
        """(bytes, stale heartbeats, checksum errors, bad characters) received so far."""
        return self.bytes_received, self.age.stale, self.decoder.checksum_errors, self.decoder.hex_errors

    def no_heartbeat(self, timeout: float, since: tuple[int, int, int, int]) -> LinkSilent:
        """Why no fresh heartbeat came in `timeout` s, from the counts() before: late heartbeats,
        bytes that are no frame, or nothing at all."""
        n_bytes, stale, checksum, bad = (now - before for now, before in zip(self.counts(), since))
        if stale:
            return LinkLate(f"{stale} heartbeat(s) in {timeout:.1f} s but each too late to trust (the last "
                            f"{self.age.stale_age:.1f} s old, more than {self.age.stale_after:g} s): this "
                            "computer reads the port too seldom (too busy?)")
        if n_bytes:
            return LinkGarbled(f"{n_bytes} bytes in {timeout:.1f} s but no valid heartbeat (checksum errors "
                               f"{checksum}, bad characters {bad}): wrong baud or device?")
        return LinkSilent(f"no heartbeat for {timeout:.1f} s: is the board powered and the port right?")

    def status(self) -> dict:
        """The next heartbeat, with the fault bits named under 'fault_names'."""
        hb = dict(self.next_heartbeat())
        hb["fault_names"] = fault_names(hb["faults"])
        return hb

    # ---------------------------------------------------------------- commands

    def send(self, name: str, **fields) -> None:
        self.serial.write(llcp.encode(messages.encode(name, **fields)))
        try:
            self.serial.flush()
        except _TermiosError as exc:     # pyserial lets tcdrain's error through: a port that went away
            raise OSError(*exc.args) from None
        if name != "ping":               # (a ping keeps nothing alive)
            self.last_sent = self.clock()

    def _ping_after_command(self) -> int:
        """Ping the board; its pong comes once every frame sent before it has been taken."""
        seq = COMMAND_PING_SEQ | self._pings_sent & 0x3FFF
        self._pings_sent += 1
        self._answered[seq] = None
        self.ping(seq)
        return seq

    def _after_command(self) -> dict:
        """The first fresh heartbeat the board sent after it took the command just sent: one
        that came after the pong of a ping that followed the command (pinged again every
        PING_AGAIN_S, for a frame lost to noise)."""
        seqs, asked = [self._ping_after_command()], self.clock()
        try:
            while True:
                hb = self.next_heartbeat()
                answers = [self._answered[s] for s in seqs if self._answered[s] is not None]
                if answers and hb["frame"] > min(answers):
                    return hb
                if self.clock() - asked >= PING_AGAIN_S:
                    seqs.append(self._ping_after_command())
                    asked = self.clock()
        finally:
            for s in seqs:
                del self._answered[s]

    def _confirm(self, ok, why, refused=lambda hb: hb["refusal"]) -> dict:
        """Wait for a heartbeat the board sent after it took the command that satisfies ok(hb);
        CommandRefused with why(hb) at the first that shows it refused (each command sets the
        heartbeat's refusal afresh), or if none shows it within CONFIRM_S of the board's time."""
        return self._until(self._after_command(), ok, why, refused)

    def _until(self, hb: dict, ok, why, refused=lambda hb: False) -> dict:
        """From hb on, the first heartbeat that satisfies ok(hb), within CONFIRM_S of the board's
        time; CommandRefused with why(hb) at one that shows refused(hb) or after that."""
        first_ms = hb["uptime_ms"]
        while not ok(hb):
            if refused(hb) or _ms_since(first_ms, hb) >= CONFIRM_S * 1000:
                raise CommandRefused(why(hb), hb)
            hb = self.next_heartbeat()
        return hb

    def enable(self, on: bool = True, *, limp: bool = False) -> dict:
        """enable 1 is taken once the servos are configured (the heartbeat's state past
        "starting"), so an engage may follow at once. limp: enable 2, the bench (to calibrate
        the servos): configured with the torque off, the arm limp where it hangs; the board
        never moves it on its own, and engage is refused, until enable (1) parks it."""
        value = BENCH if on and limp else int(on)
        self.send("enable", on=value)

        def why(hb):
            if hb["refusal"]:
                return f"enable {value} refused: {refusal_reason(hb['refusal'])}"
            return f"enable {value} not taken; faults {fault_names(hb['faults'])}"
        return self._confirm(lambda hb: hb["enabled"] == value and (not on or hb["state"] > STARTING), why)

    def disable(self) -> dict:
        return self.enable(False)

    def engage(self, on: bool = True) -> dict:
        """engage 1 on a board just powered up waits for its IMU to settle (refused as
        imu_not_ready meanwhile: sent again, for up to CONFIRM_S of the board's time)."""
        def why(hb):
            if on and not hb["enabled"]:
                return "engage refused: the arm is not enabled (enable it first)"
            if on and hb["refusal"]:
                return f"engage refused: {refusal_reason(hb['refusal'])}; faults {fault_names(hb['faults'])}"
            return f"engage {int(on)} not taken; faults {fault_names(hb['faults'])}"
        first_ms = None
        while True:
            self.send("engage", on=int(on))
            try:
                return self._confirm(lambda hb: hb["engaged"] == int(on), why)
            except CommandRefused as refused:
                hb = refused.heartbeat
                first_ms = hb["uptime_ms"] if first_ms is None else first_ms
                if not (on and hb["refusal"] == IMU_NOT_READY and _ms_since(first_ms, hb) < CONFIRM_S * 1000):
                    raise

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
        return self._confirm(taken, why, refused=lambda hb: hb["unreachable"] or hb["refusal"])

    # ---------------------------------------------------------------- service (bring-up, calibration)

    def _service(self, name: str, **fields) -> dict:
        """Send a service command; the heartbeat that took it, or CommandRefused with the reason."""
        self.send(name, **fields)
        hb = self._after_command()
        if hb["refusal"]:
            raise CommandRefused(f"{name} refused: {refusal_reason(hb['refusal'])}", hb)
        return hb

    def stream(self, imu_every: int = 0, servos: bool = False) -> dict:
        """Ask for imu_raw every imu_every ticks (0 off) and servo_status after each status read."""
        for frames in self.streamed.values():
            frames.clear()
        return self._service("stream", imu_every=int(imu_every), servos=int(bool(servos)))

    def torque(self, on: bool) -> dict:
        """Torque off (limp: move the arm by hand, positions still read) or back on: taken once
        the servos are set up again (the state past "starting"), so a jog may follow at once."""
        hb = self._service("torque", on=int(bool(on)))
        if not on:
            return hb
        return self._until(hb, lambda hb: hb["state"] > STARTING,
                           lambda hb: f"torque 1 taken, but the servos were not set up again within {CONFIRM_S:g} s; "
                                      f"faults {fault_names(hb['faults'])}")

    def jog(self, joint: int, *, angle: float | None = None, units: int | None = None) -> dict:
        """Joint 1-3 to an angle (rad) or by servo units, at park speed, checked like every move."""
        if (angle is None) == (units is None):
            raise ValueError("jog takes exactly one of angle (rad) and units")
        mode, value = (0, float(angle)) if angle is not None else (1, float(units))
        return self._service("jog", joint=int(joint), mode=mode, value=value)

    def collect(self, name: str, seconds: float, keep: bool = False) -> list[dict]:
        """The streamed frames of `name` that arrive during the next `seconds` (keep: and
        those that came since the last collect)."""
        self.poll()
        if not keep:
            self.streamed[name].clear()
        end = self.clock() + seconds
        while self.clock() < end:
            self.poll()
            time.sleep(0.005)   # (a poll's interval)
        return list(self.streamed[name])

    def send_attitude(self, roll: float, pitch: float, stamp_us: int | None = None) -> None:
        """Forward the drone's attitude (rad) from its flight controller; call at >= 50 Hz."""
        if not (math.isfinite(roll) and math.isfinite(pitch)):
            raise ValueError(f"attitude must be finite, got roll {roll}, pitch {pitch}")
        stamp = int(self.clock() * 1e6) if stamp_us is None else stamp_us
        self.send("drone_attitude", seq=self._attitude_seq, stamp_us=stamp & 0xFFFFFFFF, roll=roll, pitch=pitch)
        self._attitude_seq = (self._attitude_seq + 1) & 0xFFFF

    def send_velocity(self, vx: float, vy: float, vz: float, stamp_us: int | None = None) -> None:
        """Forward the drone's velocity (m/s, gravity-aligned heading-following frame, its
        centre of rotation) from its odometry; call at >= 50 Hz, each measurement once."""
        if not all(math.isfinite(v) for v in (vx, vy, vz)):
            raise ValueError(f"velocity must be finite, got ({vx}, {vy}, {vz})")
        stamp = int(self.clock() * 1e6) if stamp_us is None else stamp_us
        self.send("drone_velocity", seq=self._velocity_seq, stamp_us=stamp & 0xFFFFFFFF, vx=vx, vy=vy, vz=vz)
        self._velocity_seq = (self._velocity_seq + 1) & 0xFFFF

    def ping(self, seq: int) -> float:
        """Send ping `seq` (stamped with the link's clock in microseconds); the clock() it left
        at. The board's pong lands in self.pongs."""
        sent = self.clock()
        self.send("ping", seq=seq & 0xFFFF, stamp_us=int(sent * 1e6) & 0xFFFFFFFF)
        return sent

    def keep_alive(self) -> None:
        """Repeat the board's current set position, so an engaged, limp or jogged arm does not
        park (the board takes it as no new command: the last refusal stands)."""
        if self.heartbeats:
            hb = self.heartbeats[-1]
            self.send("set_position", x=hb["set_x"], y=hb["set_y"], z=hb["set_z"])
