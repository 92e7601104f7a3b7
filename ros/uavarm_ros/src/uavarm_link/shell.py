"""`uavarm link PORT shell [FILE]`: one connection for a whole session. Commands come from a
prompt, a script file or standard input, while a background loop reads the heartbeats and,
while the arm is engaged, repeats the set position so that it stays engaged between commands.

A line is a command (COMMANDS below) or a target: three numbers in mm, comma or space
separated, optionally a fourth, the seconds to hold it (a CSV of targets is a valid script).
At a prompt a failed command prints `error: ...` and the session goes on; from a file or a
pipe the first failure ends it with `error: line N: ...` and exit code 1.
"""
from __future__ import annotations

import math
import re
import sys
import threading
import time

from .client import LinkError
from .messages import fault_names, state_name
from .shared import SharedLink

KEEP_ALIVE_S = 0.2           # the board parks an engaged arm after link.silence_timeout (1 s)
POLL_S = 0.02

COMMANDS = {
    "enable": "servo power on (taken once the servos are configured)",
    "disable": "servo power off",
    "engage": "stabilise at the set position (kept engaged until disengage or the end)",
    "disengage": "park",
    "goto X Y Z [S]": "set position in mm (level frame at the arm's base); hold S seconds",
    "wait S": "hold S seconds (heartbeats and keep-alive go on)",
    "status": "print the next heartbeat",
    "limp / stiff / jog J DEG": "service commands (not engaged): torque off / on, joint J to DEG",
    "help": "this list",
    "quit": "end the session (an engaged arm parks after the link falls silent)",
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
    return (f"[{hb['uptime_ms'] / 1000:7.1f} s] {state_name(hb['state'])}, set "
            f"({hb['set_x']:.1f}, {hb['set_y']:.1f}, {hb['set_z']:.1f}) mm, "
            f"faults: {', '.join(faults) if faults else 'none'}")


class Session:
    """The open link, its heartbeat loop and the commands."""

    def __init__(self, port: str, baud: int, out, clock=time.monotonic):
        self.link = SharedLink(port, baud, clock=clock)
        self.out = out
        self._stop = threading.Event()
        self._shown = None
        self.loop_error = None
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        link = self.link
        while not self._stop.is_set():
            try:
                for hb in link.poll():
                    self._show_changes(hb)
                if link.engaged and link.clock() - link.last_sent >= KEEP_ALIVE_S:
                    link.keep_alive()
            except (LinkError, OSError) as exc:               # (serial.SerialException too)
                self.loop_error = str(exc)
                link.fail(f"the serial port failed ({exc}): unplugged, or the SITL stopped?")
                return
            time.sleep(POLL_S)

    def _show_changes(self, hb: dict) -> None:
        """The live status: a line whenever the state or the faults change."""
        key = (hb["state"], hb["faults"])
        if key != self._shown:
            self._shown = key
            print(status_line(hb), file=self.out, flush=True)

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
        action = {"enable": link.enable, "disable": link.disable, "engage": link.engage,
                  "disengage": link.disengage, "status": link.next_heartbeat,
                  "limp": lambda: link.torque(False), "stiff": lambda: link.torque(True)}[name]
        return status_line(action())

    def _hold(self, seconds: float) -> None:
        clock = self.link.clock
        end = clock() + seconds
        while clock() < end:
            if self.link.broken:
                raise LinkError(f"serial link lost: {self.link.broken}")
            time.sleep(POLL_S)   # (a poll's interval: the link's clock says when the hold ends)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        try:
            self.link.close()
        except OSError:
            pass


def run_shell(port: str, baud: int, lines, interactive: bool, out=None, err=None, clock=time.monotonic) -> int:
    """Run the lines (an iterable of str) on one connection; the exit code. clock: the link's
    (ArmLink's), for the holds too."""
    out, err = out or sys.stdout, err or sys.stderr
    session = Session(port, baud, out, clock)
    try:
        if interactive:
            print("commands: enable, engage, goto X Y Z, disengage, disable, status, wait S, help, quit",
                  file=out, flush=True)
        for number, line in enumerate(lines, 1):
            try:
                command = parse(line)
                if command is None:
                    continue
                if command[0] in ("quit", "exit"):
                    break
                shown = session.run(*command)
                if shown:
                    print(shown, file=out, flush=True)
            except (ShellError, LinkError) as exc:
                if not interactive:
                    print(f"error: line {number}: {exc}", file=err)
                    return 1
                print(f"error: {exc}", file=err, flush=True)
                if session.link.broken:
                    return 1
        if session.link.engaged:
            print("end of the session: the arm is engaged and parks once the link has been silent "
                  "for its timeout", file=out)
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
