"""`uavarm` answers every user error with one line `error: ...` on stderr and a non-zero exit
(2 for what argparse refuses, 1 for what fails at run time), never a Python traceback."""
import argparse
import fcntl
import os
import subprocess
import sys
import termios
import time
import tomllib
import tty
from pathlib import Path

import pytest

from conftest import ROOT
from uavarm import cli
from uavarm.sim.sitl import Sitl

PORT = "/dev/no-such-arm"


def uavarm(*argv, **kw):
    return subprocess.Popen([sys.executable, "-m", "uavarm.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT, **kw)


def assert_clean_error(proc, out, err):
    assert "Traceback" not in err, err
    assert proc.returncode not in (0, None), (proc.returncode, out, err)
    assert len([line for line in err.splitlines() if "error: " in line]) == 1, err


def finished(proc, timeout=120):
    out, err = proc.communicate(timeout=timeout)
    return out, err


@pytest.fixture(scope="module")
def busy_port():
    """A pseudo-terminal another process holds exclusively (TIOCEXCL: opening it again fails
    with EBUSY, except for root, who then opens a port on which nothing answers)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    fcntl.ioctl(slave, termios.TIOCEXCL)
    yield os.ttyname(slave)
    os.close(slave)
    os.close(master)


INPUTS = [
    # argparse (exit 2)
    [],
    ["fly"],
    ["demo", "--seconds", "nan"],
    ["demo", "--seconds", "0"],
    ["demo", "--roll", "ten"],
    ["demo", "--target", "60", "20"],
    ["link", PORT, "goto", "nan", "0", "-100"],
    ["link", PORT, "goto", "inf", "0", "-100"],
    ["link", PORT, "goto", "60", "20"],
    ["link", PORT, "jog", "4", "10"],
    ["link", PORT, "fly"],
    ["link", PORT, "status", "--baud", "fast"],
    ["sitl", "--speed", "0"],
    ["sitl", "--speed", "nan"],
    ["sitl", "--seed", "-1"],
    ["sitl", "tilt:ten,5"],
    ["sitl", "--imu-mounting", "1,2"],
    ["sitl", "--imu", "perfect"],
    ["sitl", "--link-delay-ms", "fast"],
    ["sitl", "--link-delay-ms", "5,-1"],
    ["sitl", "--link-delay-ms", "1,2,3"],
    ["sim", "bench", "--seconds", "-1"],
    ["sim", "bench", "--seeds", "0"],
    ["sim", "bench", "--poll-us", "1"],
    ["sim", "bench", "--jobs", "0"],
    ["calibrate", "imu", PORT, "--seconds", "0"],
    ["calibrate", "gyro", PORT],
    ["calibrate", "link", PORT, "--upstream-ms", "-3"],
    ["codegen", "--no-such-option"],
    # at run time (exit 1, or the subcommand's own 2)
    ["link", PORT, "status"],
    ["link", "/dev/null", "status"],            # not a serial port
    ["link", "{busy}", "status"],
    ["calibrate", "imu", PORT],
    ["calibrate", "imu", PORT, "--model", "/no/such/model.toml"],
    ["calibrate", "imu", PORT, "--upstream-ms", "5"],
    ["calibrate", "link", PORT],
    ["sim", "nowhere.toml"],
    ["sim", "bench", "--estimator", "kalman"],
    ["sim", "bench", "--set", "estimator.nope=1"],
    ["sim", "bench", "--set", "estimator.kind"],
    ["sim", "bench", "--set", "estimator.complementary_gyro_weight=0.98"],
    ["workspace", "--model", "/no/such/model.toml"],
    ["codegen", "--check", "--model", "/no/such/model.toml"],
]


@pytest.mark.parametrize("argv", INPUTS, ids=lambda a: " ".join(a) or "(nothing)")
def test_user_errors_are_one_line_without_a_traceback(argv, busy_port):
    proc = uavarm(*[a.replace("{busy}", busy_port) for a in argv])
    assert_clean_error(proc, *finished(proc))


@pytest.mark.realtime
def test_port_vanishing_during_monitor():
    """The SITL stops (as a board unplugged) while `monitor` is printing its heartbeats."""
    sitl = Sitl(speed=2.0).start()
    proc = uavarm("link", sitl.device, "monitor")
    try:
        first = proc.stdout.readline()
        assert first.startswith("#"), first      # a heartbeat: the link works
    finally:
        sitl.stop()
    out, err = finished(proc)
    assert_clean_error(proc, out, err)
    assert sitl.device in err


def fds_of(pid: int) -> set[str]:
    folder = Path(f"/proc/{pid}/fd")
    out = set()
    for fd in folder.iterdir():
        try:
            out.add(os.readlink(fd))
        except OSError:
            pass
    return out


def test_port_vanishing_during_goto():
    """The port goes away while `goto` waits for the heartbeats that confirm it."""
    master, slave = os.openpty()
    tty.setraw(slave)
    device = os.ttyname(slave)
    proc = uavarm("link", device, "goto", "60", "20", "-120")
    try:
        while device not in fds_of(proc.pid) and proc.poll() is None:
            time.sleep(0.001)      # until the command has the port open (an event, not a time)
    finally:
        os.close(master)
        os.close(slave)
    assert_clean_error(proc, *finished(proc))


def test_version_is_the_package_version():
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    proc = uavarm("--version")
    out, err = finished(proc)
    assert proc.returncode == 0 and out.startswith(f"uavarm {version} ")
    # app.h: APP_FIRMWARE_VERSION 0x000700u, 0.7.0
    assert "(firmware 0.7.0)" in out


def test_codegen_help_names_the_command(capsys):
    with pytest.raises(SystemExit) as done:
        cli.main(["codegen", "--help"])
    assert done.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: uavarm codegen") and "python -m" not in out


def subparsers(ap: argparse.ArgumentParser):
    for action in ap._actions:
        if isinstance(action, argparse._SubParsersAction):
            return action.choices
    return {}


def test_every_option_with_a_default_says_it():
    for name, sub in subparsers(cli.parser()).items():
        for action in sub._actions:
            if action.default in (None, argparse.SUPPRESS) or action.nargs == 0:
                continue    # (flags, help)
            assert action.help and "default" in action.help, (name, action.dest, action.help)
