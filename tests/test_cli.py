"""The `uavarm` command line."""
import math

import pytest

from uavarm import cli
from uavarm.link import messages
from uavarm.link.messages import FAULTS


def test_demo_reaches_engaged_state(capsys):
    assert cli.main(["demo", "--seconds", "2.5"]) == 0
    out = capsys.readouterr().out
    assert "engaged 1" in out and "faults []" in out


def test_codegen_check_passes_through(capsys):
    assert cli.main(["codegen", "--check"]) == 0
    assert "up to date" in capsys.readouterr().out


def demo_events(out: str) -> list[tuple[float, str]]:
    """(simulated time, '->' or '<-') of every line `uavarm demo` printed."""
    events = []
    for line in out.splitlines():
        t, unit, arrow = line.split()[:3]
        assert unit == "s" and arrow in ("->", "<-"), line
        events.append((float(t), arrow))
    return events


def test_demo_prints_in_simulated_time_order(capsys, model):
    assert cli.main(["demo", "--seconds", "4", "--every", "0"]) == 0
    events = demo_events(capsys.readouterr().out)
    times = [t for t, _ in events]
    assert times == sorted(times) and times[-1] <= 4.0
    assert [t for t, arrow in events if arrow == "->"] == [0.0, 1.5, 1.5]   # enable; set position, engage
    beats = [t for t, arrow in events if arrow == "<-"]
    # a heartbeat every link.heartbeat_period from power-up (printed to the hundredth)
    assert len(beats) == int(4.0 / model.heartbeat_period)
    for k, t in enumerate(beats, 1):
        assert abs(t - k * model.heartbeat_period) <= 0.011


def test_demo_prints_a_heartbeat_each_half_second_by_default(capsys, model):
    assert cli.main(["demo", "--seconds", "4"]) == 0
    beats = [t for t, arrow in demo_events(capsys.readouterr().out) if arrow == "<-"]
    assert [math.floor(t / 0.5) for t in beats] == list(range(9))   # the first of each half second, to 4.00 s
    with pytest.raises(SystemExit) as bad:
        cli.main(["demo", "--seconds", "1", "--every", "-1"])
    assert bad.value.code == 2 and "--every: must be a number >= 0" in capsys.readouterr().err


def test_a_line_for_many_heartbeats_says_the_faults_of_them_all():
    lines = cli.HeartbeatLines(0.5)
    hb = dict.fromkeys((name for name, _ in messages.BY_NAME["heartbeat"].fields), 0)
    assert "faults []" in lines.line(0.04, hb)
    assert lines.line(0.08, dict(hb, faults=1 << [n for n, _ in FAULTS].index("link_lost"))) is None
    assert lines.line(0.12, hb) is None
    assert "link_lost" in lines.line(0.52, hb)


def test_demo_of_one_second_prints_what_happened(capsys, model):
    assert cli.main(["demo", "--seconds", "1", "--every", "0"]) == 0
    events = demo_events(capsys.readouterr().out)
    assert events[0] == (0.0, "->")
    assert sum(arrow == "<-" for _, arrow in events) == int(1.0 / model.heartbeat_period)
    assert all(t <= 1.0 for t, _ in events)
