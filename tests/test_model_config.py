"""The model file loader: bad input gets a clear error naming the file and the key."""
import re

import pytest

from uavarm.model import config

BASE = config.DEFAULT_MODEL.read_text()


def load_text(tmp_path, text):
    path = tmp_path / "arm.toml"
    path.write_text(text)
    return config.load(path), path


def broken(tmp_path, old, new):
    assert old in BASE, old
    path = tmp_path / "arm.toml"
    path.write_text(BASE.replace(old, new, 1))
    with pytest.raises(config.ModelError) as err:
        config.load(path)
    assert str(path) in str(err.value)
    return str(err.value)


def test_default_model_loads(model):
    assert (model.L1, model.L2, model.L3) == (40.0, 65.0, 73.5)
    assert len(model.sha256) == 64


def test_missing_key(tmp_path):
    assert "geometry.L2: missing" in broken(tmp_path, "L2 = 65.0", "")


def test_wrong_type(tmp_path):
    msg = broken(tmp_path, "L3 = 73.5", 'L3 = "long"')
    assert "geometry.L3" in msg and "expected a number" in msg


def test_negative_length(tmp_path):
    msg = broken(tmp_path, "L2 = 65.0", "L2 = -65.0")
    assert "geometry.L2" in msg and "positive" in msg


def test_min_not_below_max(tmp_path):
    msg = broken(tmp_path, "[joints.theta2]\nmin = -120.0", "[joints.theta2]\nmin = 120.0")
    assert "joints.theta2" in msg and "less than max" in msg


def test_limit_beyond_servo_travel(tmp_path):
    msg = broken(tmp_path, "min = -145.0", "min = -160.0")
    assert "joints.theta1" in msg and "servo position" in msg


def test_duplicate_servo_ids(tmp_path):
    assert "ids must differ" in broken(tmp_path, "id = 2", "id = 1")


def test_cutoff_above_nyquist(tmp_path):
    assert "Nyquist" in broken(tmp_path, "cutoff = 20.0", "cutoff = 60.0")


def test_boolean_is_not_a_number(tmp_path):
    assert "geometry.L1" in broken(tmp_path, "L1 = 40.0", "L1 = true")


def test_not_toml(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text("[geometry\nL1 = ")
    with pytest.raises(config.ModelError, match=re.escape(str(path)) + ".*not valid TOML"):
        config.load(path)


def test_missing_file(tmp_path):
    with pytest.raises(config.ModelError, match="cannot read"):
        config.load(tmp_path / "nope.toml")


def test_codegen_cli_reports_model_errors(tmp_path, capsys):
    from uavarm.codegen.generate import main
    path = tmp_path / "arm.toml"
    path.write_text(BASE.replace("L2 = 65.0", "L2 = -1.0"))
    assert main(["--model", str(path), "--out", str(tmp_path / "gen")]) == 2
    assert "geometry.L2" in capsys.readouterr().err
    assert not (tmp_path / "gen").exists()
