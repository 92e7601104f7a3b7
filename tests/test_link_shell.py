"""`uavarm link PORT shell`: one connection for a whole session against the SITL: commands and
targets from a script, standard input or a prompt, the arm kept engaged between them, and
every bad line or lost port one `error:` line, never a traceback. A session held for a time
runs in this process on the SITL's clock (simulated time, however busy the machine); the
command line's own tests wait only for what the heartbeats confirm."""
import io
import re
import subprocess
import sys
import threading
import time

import pytest

from uavarm.link.messages import fault_names, state_name
from uavarm.link.shell import ShellError, parse, run_shell
from uavarm.model import config
from uavarm.sim.sitl import Sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)

SPEED = 2.0          # simulated seconds per real second


@pytest.fixture
def sitl():
    s = Sitl(speed=SPEED).start()
    yield s
    s.stop()


def shell(sitl, text, *args):
    return subprocess.run([sys.executable, "-m", "uavarm.cli", "link", sitl.device, "shell", *args],
                          input=text, capture_output=True, text=True, timeout=60)


def test_lines_are_commands_or_targets():
    assert parse("  # a comment") is None and parse("") is None
    assert parse("enable") == ("enable", [])
    assert parse("60,20,-120") == ("goto", [60.0, 20.0, -120.0])          # a CSV row
    assert parse("60 20 -120 1.5") == ("goto", [60.0, 20.0, -120.0, 1.5])
    assert parse("GOTO 1, 2, 3  # comment") == ("goto", [1.0, 2.0, 3.0])
    assert parse("wait 2") == ("wait", [2.0])
    for bad, why in (("fly", "unknown command"), ("goto 1 2", "takes 3-4 numbers"), ("wait", "takes 1"),
                     ("goto nan 0 -100", "finite"), ("60,x,-120", "not a number"), ("wait -1", ">= 0"),
                     ("jog 4 10", "joint must be 1, 2 or 3"), ("enable 1", "takes 0")):
        with pytest.raises(ShellError, match=why):
            parse(bad)


def test_a_script_keeps_the_arm_engaged_between_its_commands(sitl):
    """Engaged for three link silence timeouts with no command sent: the session's own
    keep-alive holds it; the targets are taken; the end of input is said."""
    m = config.load()
    hold = 3 * m.link_silence_timeout                         # simulated seconds
    script = f"enable\nengage\n60,20,-120,{hold}\n40 0 -140\nstatus\n"
    out, err = io.StringIO(), io.StringIO()
    assert run_shell(sitl.device, 115200, script.splitlines(), interactive=False, out=out, err=err,
                     clock=sitl.clock) == 0, err.getvalue()
    out = out.getvalue()
    assert err.getvalue() == ""
    # the board's heartbeats up to the script's last command (the arm parks once it ends)
    last = float(re.search(r"status: ok \[\s*([\d.]+) s\]", out).group(1))
    hbs = [h for h in sitl.board.heartbeats if h["uptime_ms"] <= last * 1000 + 1]
    first = next(i for i, h in enumerate(hbs) if h["engaged"])
    assert all(h["engaged"] and "link_lost" not in fault_names(h["faults"]) for h in hbs[first:]), \
        "the arm disengaged during the session"
    assert (hbs[-1]["set_x"], hbs[-1]["set_y"], hbs[-1]["set_z"]) == (40.0, 0.0, -140.0)
    assert state_name(hbs[-1]["state"]) in ("moving", "holding")
    assert hbs[-1]["uptime_ms"] - hbs[first]["uptime_ms"] >= 3 * m.link_silence_timeout * 1000
    assert "goto: ok" in out and "parks once the link has been silent" in out


def test_a_csv_of_targets_from_a_file(sitl, tmp_path):
    targets = tmp_path / "targets.csv"
    targets.write_text("# x, y, z (mm), seconds\n60,20,-120,0.2\n40,0,-140,0.2\n")
    out = shell(sitl, "", "--script", str(targets))
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("goto: ok") == 2
    assert sitl.board.heartbeats[-1]["set_x"] == pytest.approx(40.0)


def test_the_first_bad_line_of_a_script_stops_it_with_its_number(sitl):
    out = shell(sitl, "enable\n\nfly away\nengage\n")
    assert out.returncode == 1 and out.stderr.strip() == "error: line 3: unknown command 'fly' (help lists them)"
    assert sitl.board.heartbeats[-1]["engaged"] == 0          # engage never sent
    out = shell(sitl, "goto 500 0 0\n")
    assert out.returncode == 1 and out.stderr.startswith("error: line 1: set_position (500.0, 0.0, 0.0) refused: "
                                                         "unreachable")
    out = shell(sitl, "", "--script", "/no/such/targets.csv")
    assert out.returncode == 1 and out.stderr == "error: --script /no/such/targets.csv: No such file or directory\n"


def test_at_a_prompt_a_refusal_is_told_and_the_session_goes_on(sitl, capsys):
    lines = ["engage", "fly", "enable", "help", "status"]
    assert run_shell(sitl.device, 115200, lines, interactive=True, clock=sitl.clock) == 0
    out, err = capsys.readouterr()
    assert "error: engage refused" in err and "error: unknown command 'fly'" in err
    assert "enable: ok" in out and "wait S" in out and "status: ok" in out


def test_a_port_that_vanishes_mid_session_ends_it_with_one_line(sitl):
    proc = subprocess.Popen([sys.executable, "-m", "uavarm.cli", "link", sitl.device, "shell"],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdin.write("enable\nwait 30\nstatus\n")
    proc.stdin.flush()
    end = time.monotonic() + 60
    while not sitl.board.heartbeats or not sitl.board.heartbeats[-1]["enabled"]:
        assert time.monotonic() < end, "enable not taken"    # (a hang guard: about 1 s)
        time.sleep(0.05)                                       # (waits for the board's heartbeat)
    sitl.stop()
    try:
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 1
    assert "Traceback" not in err and re.match(r"error: line [12]: serial link lost: the serial port failed", err) and err.count("\n") == 1


# ---------------------------------------------------------------- a board that restarts

def reset_once_engaged(sitl, out):
    """Resets the SITL's chip (its watchdog) once the shell said its engage was taken (on
    `out`): the event, not a time."""
    def run():
        end = sitl.clock() + 30
        while "engage: ok" not in out.getvalue():
            if sitl.clock() > end:
                return
            time.sleep(0.01)                                   # (a poll of the shell's output)
        sitl.reset("watchdog")
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def since_reset(sitl) -> list[dict]:
    """The board's heartbeats from its restart on (its uptime went back)."""
    hbs = sitl.board.heartbeats
    k = max(i for i in range(1, len(hbs)) if hbs[i]["uptime_ms"] < hbs[i - 1]["uptime_ms"])
    return hbs[k:]


def torque_on_everywhere(sitl) -> bool:
    return all(s.register("torque_enable") == 1 for s in sitl.board.bus.servos)


def test_a_board_reset_mid_script_ends_it_with_an_error_and_enables_it_again(sitl):
    """Engaged, then the board's watchdog resets it: the script ends at the line it was on
    with the restart named, and the board is enabled again, so it parks with the torque on
    (not engaged: never engaged again by the shell)."""
    out, err = io.StringIO(), io.StringIO()
    reset = reset_once_engaged(sitl, out)
    code = run_shell(sitl.device, 115200, ["enable", "engage", "wait 20", "status"], interactive=False,
                     out=out, err=err, clock=sitl.clock)
    reset.join(timeout=5)
    assert code == 1, (out.getvalue(), err.getvalue())
    assert re.fullmatch(r"error: line 3: the board restarted while enabled \(reset cause watchdog, up [\d.]+ s "
                        r"again\): it came up with the servo power off, the arm limp; it was engaged; enabled "
                        r"again: it parks \(engage again when ready\)\n", err.getvalue()), err.getvalue()
    end = sitl.clock() + 10.0
    while state_name(since_reset(sitl)[-1]["state"]) != "parked":
        assert sitl.clock() < end, "the board enabled again did not park"
        time.sleep(0.05)                                       # (until its heartbeat says so)
    hbs = since_reset(sitl)
    assert not hbs[0]["enabled"] and hbs[-1]["enabled"] and not any(h["engaged"] for h in hbs)
    assert torque_on_everywhere(sitl) and sitl.board.servo_power


def test_at_a_prompt_a_board_reset_is_said_at_once_and_with_no_reenable_left_off(sitl):
    """The same reset at a prompt: said on the spot (the session goes on); with reenable off
    the board stays disabled, its servo supply off."""
    out, err = io.StringIO(), io.StringIO()
    reset = reset_once_engaged(sitl, out)
    m = config.load()
    assert run_shell(sitl.device, 115200, ["enable", "engage", f"wait {3 * m.link_silence_timeout}", "status"],
                     interactive=True, out=out, err=err, clock=sitl.clock, reenable=False) == 0
    reset.join(timeout=5)
    out, err = out.getvalue(), err.getvalue()
    assert re.search(r"^error: the board restarted while enabled \(reset cause watchdog, .*; it was engaged; "
                     r"left so \(--no-reenable\)$", err, re.M), err
    assert "status: ok" in out
    hbs = since_reset(sitl)
    assert len(hbs) >= 4 and not any(h["enabled"] for h in hbs) and not sitl.board.servo_power
    from uavarm.cli import parser                             # the command line's switch for it
    assert parser().parse_args(["link", sitl.device, "shell", "--no-reenable"]).reenable is False
    assert parser().parse_args(["link", sitl.device, "shell"]).reenable is True
