"""Regression tests of what the fuzz harnesses found (fuzz/, docs/fuzzing.md). Each test
names what escaped before the fix. The same inputs are committed to the harness's seed
corpus (fuzz/corpus/<harness>/regress-*), so the harness replays them too.

All from model_loader: uavarm.model.config.load must answer any bytes with a Model or a
ModelError naming file and key, and the code generator's park check must then end with a
pass or a ModelError; before the fixes these escaped as other exceptions or ran for minutes.
The C harnesses found nothing in the firmware (one app_link finding was the harness's own
check, docs/fuzzing.md).
"""
from __future__ import annotations

import contextlib
import signal

import pytest
import sympy as sp

from conftest import ROOT
from uavarm.codegen import generate
from uavarm.model import config, kinematics

BASE = config.DEFAULT_MODEL.read_text()
SEEDS = ROOT / "fuzz" / "corpus" / "model_loader"


def load_error(tmp_path, text: str) -> str:
    path = tmp_path / "arm.toml"
    path.write_text(text)
    with pytest.raises(config.ModelError) as err:
        config.load(path)
    assert str(path) in str(err.value)
    return str(err.value)


def edited(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new, 1)


def test_deeply_nested_arrays_and_tables(tmp_path):
    """RecursionError out of tomllib (found: inline tables nested ~300 deep)."""
    for text in ("a = " + "[" * 2000 + "]" * 2000, "a = " + "{b = " * 1000 + "1" + "}" * 1000):
        assert "nested too deeply" in load_error(tmp_path, text)


def test_integer_longer_than_python_parses(tmp_path):
    """ValueError (int from more than 4300 decimal digits) out of tomllib."""
    assert "not valid TOML" in load_error(tmp_path, edited("L1 = 40.0", "L1 = " + "9" * 5000))


@pytest.mark.parametrize("old, new, key", [
    ("L1 = 40.0", "L1 = " + "4" * 400, "geometry.L1"),                      # OverflowError in float()
    ("leg_distance = 100.0", "leg_distance = 1" + "0" * 400, "collision.leg_distance"),
    ("units_max = 1023", "units_max = 0x" + "F" * 4000, "servo.units_max"),   # ValueError printing it
    ("leg_angles = [45.0,", "leg_angles = [0x" + "F" * 4000 + ",", "collision.leg_angles[0]"),
])
def test_integers_beyond_64_bits(tmp_path, old, new, key):
    msg = load_error(tmp_path, edited(old, new))
    assert key in msg and "64-bit range" in msg


def test_subnormal_sample_rate(tmp_path):
    """OverflowError: round(1000 / 5e-324) = round(inf)."""
    msg = load_error(tmp_path, edited("sample_rate = 100.0", "sample_rate = 5e-324"))
    assert "imu.sample_rate" in msg and "1000 Hz / n" in msg


@pytest.mark.parametrize("value", ["1e-300", "5e-324", "0.5"])
def test_servo_range_below_one_degree(tmp_path, value):
    """TypeError (SymPy: 1023 / 0 = zoo) from range_deg = 1e-300."""
    msg = load_error(tmp_path, edited("range_deg = 300.0", f"range_deg = {value}"))
    assert "servo.range_deg" in msg and ">= 1.0" in msg


@pytest.mark.parametrize("old, new, key", [
    ("L3 = 73.5", "L3 = 1e300", "geometry.L3"),           # check_park ran for minutes
    ("L2 = 65.0", "L2 = 1.7976931348623157e308", "geometry.L2"),
    ("L1 = 40.0", "L1 = 10000.5", "geometry.L1"),
    ("body_z = 0.0", "body_z = -1e300", "collision.body_z"),
    ("leg_distance = 100.0", "leg_distance = 1e39", "collision.leg_distance"),   # no float32
])
def test_lengths_at_most_ten_metres(tmp_path, old, new, key):
    msg = load_error(tmp_path, edited(old, new))
    assert key in msg


@pytest.mark.parametrize("old, new, key", [
    ("L2 = 65.0", "L2 = 2.2250738585072014e-308", "geometry.L2"),   # exact park check: minutes
    ("L1 = 40.0", "L1 = 5e-324", "geometry.L1"),
    ("L3 = 73.5", "L3 = 0.0009", "geometry.L3"),
])
def test_links_at_least_a_micrometre(tmp_path, old, new, key):
    msg = load_error(tmp_path, edited(old, new))
    assert key in msg and "at least 0.001 mm" in msg


def test_shoulder_offset_may_be_zero(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(edited("L1 = 40.0", "L1 = 0.0"))
    assert config.load(path).L1 == 0.0


def test_ten_metre_arm_still_loads(tmp_path):
    path = tmp_path / "arm.toml"
    # (exactly calibrated: 3 deg off, a 10 m forearm swings 1 m past the legs wherever it hangs)
    path.write_text(edited("L3 = 73.5", "L3 = 10000.0").replace("zero_tolerance_deg = 3.0", "zero_tolerance_deg = 0.0"))
    model = config.load(path)
    assert model.L3 == 10000.0
    generate.check_park(model)   # (SymPy, exact: well under a second at this size)


@contextlib.contextmanager
def deadline(seconds: int):
    """Fail instead of hanging (SIGALRM, Unix)."""
    def expired(*_):
        raise TimeoutError(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize("value", ["40.28633809204152", "4.028633809204152"])
def test_model_numbers_stay_exact_rationals(tmp_path, value):
    """A timeout of the harness: sp.nsimplify(40.28633809204152) guessed
    5*2**(227/394)*3**(76/197)*5**(111/394)*7**(82/197), and the exact park check (and the
    code generator) ran for minutes on it. The model's numbers are now taken as rationals of
    their 15-digit decimals (nsimplify(..., rational=True)), which is what the committed
    model's numbers already were, so the generated code did not change."""
    path = tmp_path / "arm.toml"
    path.write_text(edited("L1 = 40.0", f"L1 = {value}"))
    model = config.load(path)
    L1 = -kinematics.dh_rows(model)[0][3]
    assert L1.is_Rational and abs(float(L1) / float(value) - 1) < 1e-14
    with deadline(60):
        generate.check_park(model)
    assert sp.nsimplify(0.95, rational=True) == sp.Rational(19, 20)   # (nice decimals unchanged)


# The seeds that are a valid model (the bug was the time its exact numbers took): each must
# load and pass the park check within the deadline. Every other regress-* seed is refused.
VALID_SEEDS = {"regress-long-decimal-length"}


def test_regression_inputs_are_in_the_seed_corpus(tmp_path):
    """The committed regress-* seeds: every one is refused by the loader with a ModelError,
    except the valid models of VALID_SEEDS, which load and pass the park check in time."""
    seeds = sorted(SEEDS.glob("regress-*"))
    assert len(seeds) >= 7
    assert VALID_SEEDS <= {s.name for s in seeds}
    for seed in seeds:
        path = tmp_path / seed.name
        path.write_bytes(seed.read_bytes())
        if seed.name in VALID_SEEDS:
            with deadline(60):
                generate.check_park(config.load(path))
        else:
            with pytest.raises(config.ModelError):
                config.load(path)
