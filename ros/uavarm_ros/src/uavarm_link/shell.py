"""`uavarm link PORT shell [FILE]`: one connection for a whole session. Commands come from a
prompt, a script file or standard input, while a background loop reads the heartbeats and
repeats the set position so that an engaged, limp or jogged arm stays so between commands
(the board parks it after link.silence_timeout without a frame). A board that restarts while
enabled after a watchdog reset or a fault (it comes up limp) is an error: said at once and,
unless reenable is off, enabled again so that it parks; it is never engaged again by itself.

A line is a command (COMMANDS below) or a target: three numbers in mm, comma or space
separated, optionally a fourth, the seconds to hold it (a CSV of targets is a valid script).
At a prompt a failed command prints `error: ...` and the session goes on; from a file or a
pipe the first failure (or such a restart) ends it with `error: line N: ...` and exit code 1.
"""
from __future__ import annotations

import math
import re
import sys
import threading
import time

from .client import BENCH, KEEP_ALIVE_S, LinkError, RestartWatch, bench_note
from .messages import fault_names, state_name
from .shared import SharedLink

POLL_S = 0.02

COMMANDS = {
    "enable": "servo power on (taken once the servos are configured); from the bench: parks",
    "enable limp": "the bench, to calibrate the servos: power on, the torque off, never moved by the "
                   "board on its own (silence, the drone, disengage: limp); engage refused until enable",
    "disable": "servo power off",
    "engage": "stabilise at the set position (kept engaged until disengage or the end)",
    "disengage": "park",
    "goto X Y Z [S]": "set position in mm (level frame at the arm's base); hold S seconds",
    "wait S": "hold S seconds (heartbeats and keep-alive go on)",
    "status": "print the next heartbeat",
    "limp / stiff / jog J DEG": "service commands (not engaged, the drone not flying): torque off / on, "
                                "joint J to DEG",
    "help": "this list",
    "quit": "end the session (an engaged, limp or jogged arm parks after the link falls silent)",
}


class ShellError(ValueError):
    """A line that is not a command."""


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ShellError(f"{what}: not a number: {text!r}") from None
    if not math.isfinite(value):
        raise ShellError(f"{what}: must be finite, got {text}")
    return value


def parse(line: str) -> tuple[str, list[float]] | None:
    """(command, numbers) of a line; None for a blank line or a comment (#)."""
    line = line.split("#", 1)[0].strip()
    if not line:
        return None
    words = [w for w in re.split(r"[,\s]+", line) if w]
    if re.fullmatch(r"[-+.\d]", words[0][0]) or words[0].lower() in ("nan", "inf", "-inf"):
        words.insert(0, "goto")                               # a bare target (a CSV row)
    name, args = words[0].lower(), words[1:]
    if name == "enable" and [a.lower() for a in args] == ["limp"]:
        return "enable limp", []
    arity = {"goto": (3, 4), "wait": (1, 1), "jog": (2, 2)}.get(name, (0, 0))
    known = {"enable", "disable", "engage", "disengage", "goto", "wait", "status", "limp", "stiff", "jog",
             "help", "quit", "exit"}
    if name not in known:
        raise ShellError(f"unknown command {words[0]!r} (help lists them)")
    if not arity[0] <= len(args) <= arity[1]:
        raise ShellError(f"{name} takes {arity[0] if arity[0] == arity[1] else f'{arity[0]}-{arity[1]}'} "
                         f"numbers, got {len(args)}")
    numbers = [_number(a, name) for a in args]
    if name == "wait" and numbers[0] < 0 or name == "goto" and len(numbers) == 4 and numbers[3] < 0:
        raise ShellError(f"{name}: seconds must be >= 0")
    if name == "jog" and numbers[0] not in (1.0, 2.0, 3.0):
        raise ShellError(f"jog: joint must be 1, 2 or 3, got {args[0]}")
    return name, numbers


def status_line(hb: dict) -> str:
    faults = fault_names(hb["faults"])
    return (f"[{hb['uptime_ms'] / 1000:7.1f} s] {state_name(hb['state'])}{bench_note(hb)}, set "
            f"({hb['set_x']:.1f}, {hb['set_y']:.1f}, {hb['set_z']:.1f}) mm, "
            f"faults: {', '.join(faults) if faults else 'none'}")


class Session:
    """The open link, its heartbeat loop and the commands. err: where a restart is said at once
    (None: only by restart_error); reenable: enable a board that restarted while enabled."""

    def __init__(self, port: str, baud: int, out, clock=time.monotonic, err=None, reenable: bool = True):
        self.link = SharedLink(port, baud, clock=clock)
        self.link.keep_alive_every = KEEP_ALIVE_S          # each poll of the loop keeps the arm alive
        self.out, self.err, self.reenable = out, err, reenable
        self._stop = threading.Event()
        self._shown = None
        self.loop_error = None
        self.restarts = RestartWatch()
        self.restart_error = None          # the last such restart, said
        self._say_lock = threading.Lock()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        link = self.link
        while not self._stop.is_set():
            try:
                for hb in link.poll():
                    self._show_changes(hb)
                    self._watch_restart(hb)
            except (LinkError, OSError) as exc:               # (serial.SerialException too)
                self.loop_error = str(exc)
                link.fail(f"the serial port failed ({exc}): unplugged, or the SITL stopped?")
                return
            time.sleep(POLL_S)

    def _watch_restart(self, hb: dict) -> None:
        text = self.restarts.check(hb)
        if text is None:
            return
        if self.reenable:
            self.link.send("enable", on=self.restarts.enabled_as)
            text += f"; enabled again: {self.restarts.reenabled()} (engage again when ready)"
        else:
            text += "; left so (--no-reenable)"
        self.restart_error = text
        if self.err is not None:
            self.say(f"error: {text}", self.err)

    def _show_changes(self, hb: dict) -> None:
        """The live status: a line whenever the state or the faults change."""
        key = (hb["state"], hb["faults"], hb["enabled"])
        if key != self._shown:
            self._shown = key
            self.say(status_line(hb), self.out)

    def say(self, text: str, file) -> None:
        """Print one whole line (the loop and the commands print from two threads)."""
        with self._say_lock:
            print(text, file=file, flush=True)

    def run(self, name: str, numbers: list[float]) -> str | None:
        """Do one command; the line to print, or None. LinkError (CommandRefused too) if the
        board refused it or the link failed."""
        shown = self._run(name, numbers)
        return shown if shown is None or name == "help" else f"{name}: ok {shown}"

    def _run(self, name: str, numbers: list[float]) -> str | None:
        link = self.link
        if name == "help":
            return "\n".join(f"  {k:<26} {v}" for k, v in COMMANDS.items())
        if name == "wait":
            self._hold(numbers[0])
            return None
        if name == "goto":
            hb = link.set_position(*numbers[:3])
            if len(numbers) == 4:
                self._hold(numbers[3])
            return status_line(hb)
        if name == "jog":
            hb = link.jog(int(numbers[0]), angle=math.radians(numbers[1]))
            return status_line(hb)
        action = {"enable": link.enable, "enable limp": lambda: link.enable(limp=True), "disable": link.disable,
                  "engage": link.engage, "disengage": link.disengage, "status": link.next_heartbeat,
                  "limp": lambda: link.torque(False), "stiff": lambda: link.torque(True)}[name]
        return status_line(action())

    def _hold(self, seconds: float) -> None:
        clock = self.link.clock
        end = clock() + seconds
        while clock() < end:
            if self.link.broken:
                raise LinkError(f"serial link lost: {self.link.broken}")
            if self.err is None and self.restart_error:
                raise LinkError(self.restart_error)
            time.sleep(POLL_S)   # (a poll's interval: the link's clock says when the hold ends)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        try:
            self.link.close()
        except OSError:
            pass


def run_shell(port: str, baud: int, lines, interactive: bool, out=None, err=None, clock=time.monotonic,
              reenable: bool = True) -> int:
    """Run the lines (an iterable of str) on one connection; the exit code. clock: the link's
    (ArmLink's), for the holds too; reenable: enable a board that restarted while enabled."""
    out, err = out or sys.stdout, err or sys.stderr
    session = Session(port, baud, out, clock, err=err if interactive else None, reenable=reenable)
    number = 0
    try:
        if interactive:
            session.say("commands: enable, engage, goto X Y Z, disengage, disable, status, wait S, help, quit", out)
        for number, line in enumerate(lines, 1):
            try:
                if not interactive and session.restart_error:
                    raise LinkError(session.restart_error)
                command = parse(line)
                if command is None:
                    continue
                if command[0] in ("quit", "exit"):
                    break
                shown = session.run(*command)
                if shown:
                    session.say(shown, out)
            except (ShellError, LinkError) as exc:
                if not interactive:
                    session.say(f"error: line {number}: {exc}", err)
                    return 1
                session.say(f"error: {exc}", err)
                if session.link.broken:
                    return 1
        if not interactive and session.restart_error:
            session.say(f"error: line {number}: {session.restart_error}", err)
            return 1
        last = session.link.heartbeats[-1] if session.link.heartbeats else None
        held = "engaged" if session.link.engaged else last and state_name(last["state"])
        if held in ("limp", "jogging", "jogged") and last["enabled"] == BENCH:
            session.say(f"end of the session: the arm is {held} on the bench and goes limp (it stays so) once the "
                        "link has been silent for its timeout", out)
        elif held in ("engaged", "limp", "jogging", "jogged"):
            session.say(f"end of the session: the arm is {held} and parks once the link has been silent for its "
                        "timeout", out)
        return 0
    finally:
        session.close()


def prompt_lines(prompt: str = "arm> "):
    """Lines typed at a prompt, until end of input (Ctrl-D)."""
    while True:
        try:
            yield input(prompt)
        except EOFError:
            print()
            return
