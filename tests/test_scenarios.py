"""Scenario files and flight logs (uavarm/sim/scenarios.py): round trips and clear errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from uavarm.sim import drone, scenarios
from uavarm.sim.scenarios import LinkParams, Scenario, ScenarioError, VelocityParams


@pytest.mark.parametrize("name", sorted(scenarios.BUILTIN))
def test_builtin_scenarios_round_trip_through_the_file_format(name):
    s = scenarios.load(name)
    assert s.kind == name
    assert scenarios.parse(scenarios.dump(s)) == s


def test_a_full_scenario_file_round_trips(tmp_path):
    s = Scenario("windy", "hover", {"gust_mps": 1.5, "mean_wind_mps": 4.0}, "datasheet", False,
                 LinkParams(rate_hz=60.0, delay_ms=30.0, jitter_ms=10.0, noise_deg=0.3, slow_deg=0.2, slow_tau_s=12.0,
                            bias_deg=0.1, outages=((20.0, 50.0), (70.0, 71.5))),
                 VelocityParams(rate_hz=100.0, delay_ms=40.0, jitter_ms=2.0, noise_mps=0.1, slow_mps=0.03,
                                slow_tau_s=5.0, outages=((30.0, 40.0),)),
                 (50.0, -10.0, -110.0))
    path = tmp_path / "windy.toml"
    path.write_text(scenarios.dump(s))
    back = scenarios.load(path)
    assert back == Scenario(**{**s.__dict__, "base_dir": tmp_path})
    assert not back.vibrating and not back.imu_errors().vibration
    assert back.flight(2.0, np.random.default_rng(0)).seconds == pytest.approx(2.0)


def test_vibration_defaults_off_on_the_bench_and_on_in_flight():
    assert not scenarios.load("bench").vibrating
    assert scenarios.load("hover").vibrating and scenarios.load("manoeuvre").imu_errors().vibration


def test_flight_log_replay_round_trip(tmp_path):
    """A simulated hover written as a 100 Hz log and replayed gives the same motion."""
    f = drone.hover(12.0, np.random.default_rng(1))
    scenarios.write_csv(f, tmp_path / "log.csv")
    (tmp_path / "replay.toml").write_text('name = "from a log"\nkind = "replay"\n[motion]\ncsv = "log.csv"\n')
    s = scenarios.load(tmp_path / "replay.toml")
    g = s.flight(10.0, np.random.default_rng(99))
    n = len(g.t)
    assert g.seconds == pytest.approx(10.0)
    assert np.degrees(np.abs(g.roll - f.roll[:n])).max() < 0.01
    assert np.degrees(np.abs(g.pitch - f.pitch[:n])).max() < 0.01
    assert np.abs(g.acc - f.acc[:n]).max() < 0.05
    a, b = drone.FlightMotion(f, (0, 0, -80)), drone.FlightMotion(g, (0, 0, -80))
    for t in np.arange(1.0, 9.0, 0.37):
        assert np.allclose(a.imu(t)[0], b.imu(t)[0], atol=0.01)      # g
        assert np.allclose(a.imu(t)[1], b.imu(t)[1], atol=math.radians(0.5))


def _err(tmp_path, text, csv_text=None, seconds=5.0):
    if csv_text is not None:
        (tmp_path / "log.csv").write_text(csv_text)
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as exc:
        scenarios.load(path).flight(seconds, np.random.default_rng(0))
    msg = str(exc.value)
    assert msg.startswith(str(path) + ":") or (csv_text is not None or "replay" in text) and \
        msg.startswith(str(tmp_path / "log.csv") + ":"), msg     # the file at fault, first
    return msg


REPLAY = 'kind = "replay"\n[motion]\ncsv = "log.csv"\n'
HEADER = "t,roll,pitch,ax,ay,az\n"


@pytest.mark.parametrize("text, csv_text, words", [
    ('kind = "hovering"\n', None, ["kind", "bench, hover, manoeuvre, replay"]),
    ('kind = "hover"\ncolour = 1\n', None, ["colour", "unknown key"]),
    ('kind = "hover"\n[motion]\nspeed = 2.0\n', None, ["motion.speed", "not a parameter of kind hover"]),
    ('kind = "hover"\n[motion]\ngust_mps = "strong"\n', None, ["motion.gust_mps", "finite number"]),
    ('kind = "bench"\n[imu]\nprofile = "perfect"\n', None, ["imu.profile", "calibrated"]),
    ('kind = "bench"\n[link]\nrate_hz = 20.0\n', None, ["link.rate_hz", ">= 30 Hz"]),
    ('kind = "bench"\n[link]\ndelay = 20.0\n', None, ["link.delay", "unknown key"]),
    ('kind = "bench"\n[link]\nslow_tau_s = 0.0\n', None, ["link.slow_tau_s", "positive"]),
    ('kind = "bench"\n[velocity]\nrate_hz = 10.0\n', None, ["velocity.rate_hz", ">= 30 Hz"]),
    ('kind = "bench"\n[velocity]\nnoise_mps = -1.0\n', None, ["velocity.noise_mps", "must be >= 0.0"]),
    ('kind = "bench"\n[velocity]\nnoise_deg = 0.1\n', None, ["velocity.noise_deg", "unknown key"]),
    ('kind = "bench"\n[link]\noutages = 3.0\n', None, ["link.outages", "[from, to] pairs"]),
    ('kind = "bench"\n[link]\noutages = [[1.0, 2.0, 3.0]]\n', None, ["link.outages", "[from, to] pairs"]),
    ('kind = "bench"\n[velocity]\noutages = [[5.0, 3.0]]\n', None, ["velocity.outages", "end after it starts"]),
    ('kind = "bench"\n[velocity]\noutages = [[-1.0, 3.0]]\n', None, ["velocity.outages", "must be >= 0.0"]),
    ('kind = "bench"\n[velocity]\noutages = [["a", 3.0]]\n', None, ["velocity.outages", "finite number"]),
    ('kind = "bench"\n[arm]\ntarget = [1.0, 2.0]\n', None, ["arm.target", "[x, y, z]"]),
    ('kind = "bench"\nname = [\n', None, ["not valid TOML"]),
    ('kind = "replay"\n', None, ["motion.csv", "flight log"]),
    (REPLAY, "time,roll,pitch,ax,ay,az\n0,0,0,0,0,0\n", ["line 1", "t,roll,pitch,ax,ay,az"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n1,0,0,0,0,0\n1,0,0,0,0,0\n", ["line 4", "time must increase"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n1,nan,0,0,0,0\n", ["line 3", "finite"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n1,zero,0,0,0,0\n", ["line 3", "not a number"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n1,0,0,0,0\n", ["line 3", "6 finite numbers"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n1,95,0,0,0,0\n", ["(-90, 90)"]),
    (REPLAY, HEADER + "0,0,0,0,0,0\n2,0,0,0,0,0\n", ["lasts 2.00 s", "needs 5.00 s"]),
])
def test_bad_scenarios_are_refused_with_file_and_key(tmp_path, text, csv_text, words):
    msg = _err(tmp_path, text, csv_text)
    for w in words:
        assert w in msg, msg


def test_missing_log_and_unknown_scenario_name(tmp_path):
    msg = _err(tmp_path, REPLAY)
    assert "log.csv" in msg and "cannot read" in msg
    with pytest.raises(ScenarioError, match="not a built-in scenario"):
        scenarios.load(tmp_path / "nope.toml")
