"""The model file loader: bad input gets a clear error naming the file and the key."""
import dataclasses
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

import oracles
from conftest import once_per_run
from uavarm.codegen import generate
from uavarm.model import config, pose_tolerance, servo_models

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


# --- unknown keys and implausible values ----------------------------------------------------

def test_typo_of_a_key_names_the_key_meant(tmp_path):
    msg = broken(tmp_path, "L3 = 73.5", "L33 = 73.5")
    assert "geometry.L33: unknown key (did you mean geometry.L3?)" in msg


def test_every_unknown_key_is_named(tmp_path):
    msg = broken(tmp_path, "[geometry]", "[geometryy]")
    for name in ("L1", "L2", "L3"):
        assert f"geometryy.{name}: unknown key (did you mean geometry.{name}?)" in msg


def test_many_unknown_keys_are_counted(tmp_path):
    msg = broken(tmp_path, "[mount]", "[junk]\n" + "".join(f"k{i} = {i}\n" for i in range(100)) + "[mount]")
    assert msg.count("unknown key") == config.UNKNOWN_KEYS_NAMED + 1      # (the last in "N more unknown keys")
    assert f"and {100 - config.UNKNOWN_KEYS_NAMED} more unknown keys" in msg


def test_calibration_keys_may_be_absent(tmp_path):
    text = BASE
    for line in ("accel_bias = [0.0, 0.0, 0.0]\n", "accel_scale = [1.0, 1.0, 1.0]\n",
                 "gyro_bias_dps = [0.0, 0.0, 0.0]\n", "gyro_scale = [1.0, 1.0, 1.0]\n",
                 "gyro_cross_axis = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]\n"):
        assert line in text
        text = text.replace(line, "", 1)
    line = "response_lag = 0.0265\n"
    assert line in text
    text = text.replace(line, "", 1)
    model, _ = load_text(tmp_path, text)
    assert model.imu_calibration == config.ImuCalibration()
    assert model.servo_response_lag == 0.0265          # the AX-12A's no-load control law: 32 units / 1207 units/s


def test_every_other_key_is_required(tmp_path):
    """The known keys are the committed model's keys; each one but the calibration is
    reported missing when it is deleted, so none is known without being read."""
    import tomlkit
    leaves = []
    doc = tomllib.loads(BASE)
    stack = [("", doc)]
    while stack:
        prefix, node = stack.pop()
        for k, v in node.items():
            (stack.append((f"{prefix}{k}.", v)) if isinstance(v, dict) else leaves.append(f"{prefix}{k}"))
    assert sorted(leaves) == sorted(config.KNOWN_KEYS)
    optional = {"imu.accel_bias", "imu.accel_scale", "imu.gyro_bias_dps", "imu.gyro_scale", "imu.gyro_cross_axis",
                "servo.response_lag", "servo.model"}
    for key in leaves:
        doc = tomlkit.parse(BASE)
        *tables, name = key.split(".")
        node = doc
        for t in tables:
            node = node[t]
        del node[name]
        path = tmp_path / "arm.toml"
        path.write_text(tomlkit.dumps(doc))
        if key in optional:
            config.load(path)
            continue
        with pytest.raises(config.ModelError, match=re.escape(f"{key}: missing")):
            config.load(path)


# AX-12A e-manual, Baud Rate (address 4): 2,000,000 / (n + 1) bit/s, n = 0..254; 3 % of
# error is within the UART's tolerance. Its own table: n = 16 for 115200 (117647, -2.1 %).
@pytest.mark.parametrize("baud", [1_000_000, 500_000, 400_000, 250_000, 200_000, 117_647, 115_200, 57_600,
                                  9_600])
def test_bauds_an_ax12a_runs_at_load(tmp_path, baud):
    model, _ = load_text(tmp_path, BASE.replace("baud = 200000", f"baud = {baud}", 1))
    assert model.servo_baud == baud


@pytest.mark.parametrize("baud", [
    300_000,     # between n = 5 (333333, +11 %) and n = 6 (285714, -4.8 %)
    800_000,     # between n = 1 (1000000, +25 %) and n = 2 (666667, -17 %)
    600_000,     # n = 2: 666667, +11 %; n = 3: 500000, -17 %
])
def test_bauds_no_ax12a_register_gives_are_refused(tmp_path, baud):
    msg = broken(tmp_path, "baud = 200000", f"baud = {baud}")
    assert "servo.baud: " in msg and "2,000,000 / (n + 1)" in msg and "3%" in msg


# --- servo, park, link and IMU keys ---------------------------------------------------------

NO_CROSS = "gyro_cross_axis = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]"


@pytest.mark.parametrize("old, new, key, words", [
    ("accel_range_g = 4 ", "accel_range_g = 3 ", "imu.accel_range_g", "one of [2, 4, 8, 16]"),
    ("accel_range_g = 4 ", "accel_range_g = 4.0 ", "imu.accel_range_g", "expected an integer"),
    ("gyro_range_dps = 500", "gyro_range_dps = 300", "imu.gyro_range_dps", "one of [250, 500, 1000, 2000]"),
    ("dlpf_bandwidth = 21", "dlpf_bandwidth = 50", "imu.dlpf_bandwidth", "one of"),
    ("i2c_address = 0x68", "i2c_address = 0x70", "imu.i2c_address", "one of [104, 105]"),
    ("sample_rate = 100.0", "sample_rate = 300.0", "imu.sample_rate", "1000 Hz / n"),
    ("sample_rate = 100.0", "sample_rate = 2000.0", "imu.sample_rate", "1000 Hz / n"),
    ("sample_rate = 100.0", "sample_rate = 3.0", "imu.sample_rate", "1000 Hz / n"),
    ("mounting_rpy = [0.0, 0.0, 0.0]", "mounting_rpy = [0.0, 0.0]", "imu.mounting_rpy", "expected 3"),
    ("mounting_rpy = [0.0, 0.0, 0.0]", "mounting_rpy = [0.0, 190.0, 0.0]", "imu.mounting_rpy[1]", "within"),
    ("gyro_scale = [1.0, 1.0, 1.0]", "gyro_scale = [1.0, 1.2, 1.0]", "imu.gyro_scale[1]", "within [0.9, 1.1]"),
    ("gyro_scale = [1.0, 1.0, 1.0]", "gyro_scale = [1.0, 1.0]", "imu.gyro_scale", "expected 3 scale factors"),
    (NO_CROSS, "gyro_cross_axis = [[0.0, 0.01, 0.0], [0.0, 0.0, 0.0]]", "imu.gyro_cross_axis", "expected 3 rows"),
    (NO_CROSS, "gyro_cross_axis = [0.0, 0.0, 0.0]", "imu.gyro_cross_axis", "expected 3 rows"),
    (NO_CROSS, "gyro_cross_axis = [[0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]", "imu.gyro_cross_axis[0]",
     "expected 3 sensitivities"),
    (NO_CROSS, "gyro_cross_axis = [[0.0, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.0]]", "imu.gyro_cross_axis[1][1]",
     "must be 0"),
    (NO_CROSS, "gyro_cross_axis = [[0.0, 0.0, 0.05], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]", "imu.gyro_cross_axis[0][2]",
     "within [-0.04, 0.04]"),
    (NO_CROSS, "gyro_cross_axis = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [nan, 0.0, 0.0]]", "imu.gyro_cross_axis[2][0]",
     "finite number"),
    (NO_CROSS, 'gyro_cross_axis = [[0.0, "0.01", 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]', "imu.gyro_cross_axis[0][1]",
     "finite number"),
    ("offset = [0.0, 0.0, -80.0]", "offset = [0.0, -80.0]", "mount.offset", "expected 3 lengths"),
    ("offset = [0.0, 0.0, -80.0]", "offset = [0.0, 0.0, -2e4]", "mount.offset[2]", "within"),
    ("offset = [0.0, 0.0, -80.0]", "", "mount.offset", "missing"),
    ("return_delay_us = 20", "return_delay_us = 21", "servo.return_delay_us", "even"),
    ("return_delay_us = 20", "return_delay_us = 510", "servo.return_delay_us", "<= 508"),
    ("return_delay_us = 20", "return_delay_us = -2", "servo.return_delay_us", ">= 0"),
    ("park_speed_rpm = 10.0", "park_speed_rpm = 0.0", "servo.park_speed_rpm", ">= 0.111"),
    ("bench_torque_limit = 0.35", "bench_torque_limit = 0.05", "servo.bench_torque_limit", ">= 0.1"),
    ("bench_torque_limit = 0.35", "bench_torque_limit = 1.5", "servo.bench_torque_limit", "<= 1.0"),
    ("bench_torque_limit = 0.35", "", "servo.bench_torque_limit", "missing"),
    ("park_speed_rpm = 10.0", "park_speed_rpm = 200.0", "servo.park_speed_rpm", "<= 113.5"),
    ("working_speed_rpm = 59.0", "working_speed_rpm = 114.0", "servo.working_speed_rpm", "<= 113.5"),
    ("working_speed_rpm = 59.0", "working_speed_rpm = -5.0", "servo.working_speed_rpm", ">= 0.111"),
    ("boot_time = 0.1", "boot_time = -0.1", "servo.boot_time", "negative"),
    ("boot_time = 0.1", "", "servo.boot_time", "missing"),
    ("response_lag = 0.0265", "response_lag = -0.01", "servo.response_lag", "negative"),
    ("response_lag = 0.0265", "response_lag = 0.3", "servo.response_lag", "<= 0.15"),
    ("q = [0.0, 60.0, -110.0]", "q = [0.0, 60.0]", "park.q", "expected 3 angles"),
    ("q = [0.0, 60.0, -110.0]", "q = [0.0, 60.0, -110.0, 0.0]", "park.q", "expected 3 angles"),
    ("q = [0.0, 60.0, -110.0]", 'q = [0.0, "60", -110.0]', "park.q[1]", "finite number"),
    ("q = [0.0, 60.0, -110.0]", "q = 60.0", "park.q", "expected a list"),
    ("silence_timeout = 1.0", "silence_timeout = 0.01", "link.silence_timeout", ">= 0.02"),
    ("heartbeat_period = 0.04", "heartbeat_period = 0.0", "link.heartbeat_period", "positive"),
    ("heartbeat_period = 0.04", "heartbeat_period = 0.6", "link.heartbeat_period", "<= 0.5"),
    ("heartbeat_period = 0.04", "heartbeat_period = 0.005", "link.heartbeat_period", "at least one tick (10 ms)"),
    ("heartbeat_period = 0.04", "heartbeat_period = 0.0405", "link.heartbeat_period", "whole milliseconds"),
    ("frame_gap = 0.05", "frame_gap = 0", "link.frame_gap", "positive"),
    ("transit_speed_rpm = 30.0", "transit_speed_rpm = 0.0", "servo.transit_speed_rpm", ">= 0.111"),
    ("transit_speed_rpm = 30.0", "", "servo.transit_speed_rpm", "missing"),
    ("axis_hold_radius = 3.0", "axis_hold_radius = -1.0", "motion.axis_hold_radius", "negative"),
    ("axis_release_radius = 5.0", "axis_release_radius = 2.0", "motion.axis_release_radius",
     "at least axis_hold_radius (3.0)"),
    ("axis_release_radius = 5.0", "axis_release_radius = 140.0", "motion.axis_release_radius",
     "less than the arm's reach"),
    ("follow_window_deg = 90.0", "follow_window_deg = 181.0", "motion.follow_window_deg", "<= 180"),
    ("stretch_margin = 1.0", "stretch_margin = 20.0", "motion.stretch_margin", "<= 13.8"),
    ("stretch_margin = 1.0", "", "motion.stretch_margin", "missing"),
    ("accel_bias_bandwidth = 2.0", "accel_bias_bandwidth = -0.5", "estimator.accel_bias_bandwidth", "negative"),
    ("accel_bias_bandwidth = 2.0", "accel_bias_bandwidth = 6.0", "estimator.accel_bias_bandwidth", "<= 5"),
    ("accel_bias_max_g = 0.08", "accel_bias_max_g = 0.6", "estimator.accel_bias_max_g", "<= 0.5"),
    ("accel_bias_max_g = 0.08", "accel_bias_max_g = 0.0", "estimator.accel_bias_max_g", "positive"),
    # keys the loader does not know
    ("L3 = 73.5", "L3 = 73.5\nL4 = 20.0", "geometry.L4", "unknown key"),
    ("[servo.theta3]", "[servo.theta4]\nid = 4\n[servo.theta3]", "servo.theta4.id", "unknown key"),
    ('kind = "quaternion"', 'kind = "quaternion"\ncomplementary_weight = 0.9', "estimator.complementary_weight",
     "unknown key"),
    # the masses: grams, centres on their links
    ("servo = 54.6", "servo = 0.0546", "masses.servo", "grams (kilograms by mistake?)"),
    ("end_effector = 30.0 ", "end_effector = -30.0 ", "masses.end_effector", "positive"),
    ("upper_arm_com = 32.5", "upper_arm_com = 70.0", "masses.upper_arm_com",
     "must lie on the upper arm (L2): 0 to 65.0 mm from the shoulder, got 70.0"),
    ("forearm_com = 36.75", "forearm_com = -1.0", "masses.forearm_com", "0 to 73.5 mm from the elbow"),
    ("forearm_com = 36.75", "", "masses.forearm_com", "missing"),
    ("end_effector_com = 73.5", 'end_effector_com = "tip"', "masses.end_effector_com", "expected a number"),
    # link lengths in metres by mistake
    ("L2 = 65.0", "L2 = 0.065", "geometry.L2", "millimetres"),
    ("L3 = 73.5", "L3 = 0.0735", "geometry.L3", "millimetres"),
    ("L1 = 40.0", "L1 = 0.04", "geometry.L1", "millimetres"),
])
def test_bad_new_keys_name_file_and_key(tmp_path, old, new, key, words):
    msg = broken(tmp_path, old, new)
    assert f": {key}: " in msg and words in msg, msg


def test_new_keys_load(model):
    assert model.servo_return_delay_us == 20 and model.servo_boot_time == 0.1
    assert (model.park_speed_rpm, model.transit_speed_rpm, model.working_speed_rpm) == (10.0, 30.0, 59.0)
    m = model.motion
    assert (m.axis_hold_radius, m.axis_release_radius, m.follow_window_deg, m.stretch_margin) == (3.0, 5.0, 90.0, 1.0)
    assert model.park_deg == (0.0, 60.0, -110.0)
    assert (model.link_silence_timeout, model.heartbeat_period, model.link_frame_gap) == (1.0, 0.04, 0.05)
    assert (model.imu_address, model.accel_range_g, model.gyro_range_dps, model.dlpf_bandwidth) == \
        (0x68, 4, 500, 21)
    assert model.imu_mounting_rpy_deg == (0.0, 0.0, 0.0)
    assert model.mount_offset == (0.0, 0.0, -80.0)


# Park poses and what the plain geometry of oracles.py says about them (verified below).
BAD_PARKS = [
    ([0.0, 0.0, 120.0], 2, "outside the joint limits"),     # theta3 max is 114.76
    ([0.0, 90.0, 90.0], 3, "not below the body"),           # forearm points up: ee at z = +33.5
    ([45.0, 90.0, 0.0], 4, "in a landing leg"),             # ee 138.5 mm out, in leg 45's plane
]


@pytest.mark.parametrize("q, status, words", BAD_PARKS)
def test_codegen_rejects_bad_park_pose(tmp_path, model, q, status, words):
    assert oracles.check_pose(model, np.radians(q))[0][0] == status     # the pose really is bad
    path = tmp_path / "arm.toml"
    path.write_text(BASE.replace("q = [0.0, 60.0, -110.0]", f"q = {q}", 1))
    with pytest.raises(config.ModelError) as err:    # the loader (body, legs) or the generator (limits)
        generate.render(path)
    msg = str(err.value)
    assert str(path) in msg and "park.q" in msg and words in msg, msg


def test_good_park_poses_pass(model):
    """Valid poses other than the default, including one inside a leg's sector but short."""
    for q in [(0.0, 90.0, 0.0), (-130.0, 20.0, 30.0)]:          # reaching out; near a leg but short
        assert oracles.check_pose(model, np.radians(q))[0][0] == 0
        generate.check_park(dataclasses.replace(model, park_deg=q))


def test_park_check_agrees_with_plain_geometry(model):
    """check_park (exact SymPy at the pose) against oracles.check_pose (numpy trigonometry)
    on random poses over and beyond the joint ranges, away from the decision boundaries."""
    rng = np.random.default_rng(22)
    seen = set()
    for q in rng.uniform(-160.0, 160.0, size=(120, 3)).round(1):
        status, clear = oracles.check_pose(model, np.radians(q), margin=1e-6)
        if not clear[0]:
            continue
        seen.add(int(status[0]))
        try:
            generate.check_park(dataclasses.replace(model, park_deg=tuple(q)))
            verdict = 0
        except config.ModelError as exc:
            verdict = next(s for s, words in ((2, "joint limits"), (3, "body"), (4, "leg"))
                           if words in str(exc))
        assert verdict == status[0], (q, verdict, status[0])
    assert seen == {0, 2, 3, 4}, seen      # every verdict was exercised


def test_codegen_cli_reports_bad_park(tmp_path, capsys):
    path = tmp_path / "arm.toml"
    path.write_text(BASE.replace("q = [0.0, 60.0, -110.0]", "q = [0.0, 90.0, 90.0]", 1))
    assert generate.main(["--model", str(path), "--out", str(tmp_path / "gen")]) == 2
    assert "park.q" in capsys.readouterr().err
    assert not (tmp_path / "gen").exists()


# --- model_params.h against the datasheets ---------------------------------------------------
# MPU-6000/6050 register map and product specification (rev 3.4 / 4.2): accelerometer
# sensitivity 16384, 8192, 4096, 2048 LSB/g for AFS_SEL 0..3 (+-2, 4, 8, 16 g); gyro full scale
# +-250, 500, 1000, 2000 deg/s for FS_SEL 0..3 over the int16 range (131, 65.5, 32.8, 16.4
# LSB/(deg/s)); sample rate = 1 kHz / (1 + SMPLRT_DIV) with the DLPF on; DLPF_CFG 0..6 gives an
# accelerometer bandwidth of 260, 184, 94, 44, 21, 10, 5 Hz. AX-12A: Moving Speed unit about
# 0.111 rpm (1..1023), Return Delay Time in 2 us units, position 0..1023 over 300 deg.
ACCEL_LSB_PER_G = {2: 16384, 4: 8192, 8: 4096, 16: 2048}
AFS_SEL = {2: 0, 4: 1, 8: 2, 16: 3}
GYRO_FS_SEL = {250: 0, 500: 1, 1000: 2, 2000: 3}
GYRO_LSB_PER_DPS_NOMINAL = {250: 131.0, 500: 65.5, 1000: 32.8, 2000: 16.4}
DLPF_CFG = {260: 0, 184: 1, 94: 2, 44: 3, 21: 4, 10: 5, 5: 6}

PARAMS_VARIANT = {
    "leg_angles = [45.0, -45.0, 135.0, -135.0]": "leg_angles = [30.0, -150.0, 100.0]",
    "leg_half_width = 10.0": "leg_half_width = 8.0",
    "sample_rate = 100.0": "sample_rate = 200.0",
    "i2c_address = 0x68": "i2c_address = 0x69",
    "accel_range_g = 4 ": "accel_range_g = 16 ",
    "gyro_range_dps = 500": "gyro_range_dps = 2000",
    "dlpf_bandwidth = 21": "dlpf_bandwidth = 94",
    "return_delay_us = 20": "return_delay_us = 250",
    "park_speed_rpm = 10.0": "park_speed_rpm = 3.3",
    "working_speed_rpm = 59.0": "working_speed_rpm = 113.5",
    "boot_time = 0.1": "boot_time = 0.25",
    "q = [0.0, 60.0, -110.0]": "q = [0.0, 90.0, -30.5]",
    "silence_timeout = 1.0": "silence_timeout = 0.75",
    "heartbeat_period = 0.04": "heartbeat_period = 0.2",
    "frame_gap = 0.05": "frame_gap = 0.02",
    "complementary_gyro_weight = 0.95": "complementary_gyro_weight = 0.98",
    "velocity_bandwidth = 0.25": "velocity_bandwidth = 0.4",
    "accel_bias_bandwidth = 2.0": "accel_bias_bandwidth = 0.7",
}


def _number(value):
    value = value.rstrip("uf") if not value.startswith("0x") else value.rstrip("u")
    return int(value, 0) if re.fullmatch(r"-?(0x[0-9a-fA-F]+|\d+)", value) else float(value)


def _defines(text):
    """Each MODEL_ #define's number, or tuple of numbers for a list (an initializer)."""
    out = {}
    for name, value in re.findall(r"^#define (MODEL_\w+)\s+([^\s,]+(?:, [^\s,]+)*)", text, re.M):
        out[name] = tuple(map(_number, value.split(", "))) if ", " in value else _number(value)
    return out


def _as_f32(x):
    """The float32 a C literal (or an exact value) denotes."""
    return float(np.float32(x))


@pytest.fixture(scope="module", params=["committed", "variant"])
def params(request, tmp_path_factory):
    if request.param == "committed":
        path = config.DEFAULT_MODEL
        text = (config.DEFAULT_MODEL.parents[1] / "generated" / "model_params.h").read_text()
    else:
        def make(folder):        # (rendered once per test run: seconds of SymPy)
            model_text = BASE
            for old, new in PARAMS_VARIANT.items():
                assert old in model_text, old
                model_text = model_text.replace(old, new, 1)
            (folder / "arm.toml").write_text(model_text)
            return str(folder / "arm.toml"), generate.render(folder / "arm.toml")["model_params.h"]
        path, text = once_per_run(tmp_path_factory, "params_variant", make)
        path = Path(path)
    return tomllib.loads(path.read_text()), _defines(text)


def test_mpu_registers_follow_the_datasheet(params):
    raw, d = params
    imu = raw["imu"]
    assert d["MODEL_MPU_ADDRESS"] == imu["i2c_address"]
    assert 1000 / (1 + d["MODEL_MPU_SMPLRT_DIV"]) == imu["sample_rate"]
    assert d["MODEL_MPU_SMPLRT_DIV"] == 1000 / imu["sample_rate"] - 1
    assert d["MODEL_MPU_DLPF_CFG"] == DLPF_CFG[imu["dlpf_bandwidth"]]
    assert d["MODEL_MPU_ACCEL_FS_SEL"] == AFS_SEL[imu["accel_range_g"]]
    assert d["MODEL_MPU_GYRO_FS_SEL"] == GYRO_FS_SEL[imu["gyro_range_dps"]]
    assert _as_f32(d["MODEL_ACCEL_G_PER_LSB"]) == _as_f32(1 / ACCEL_LSB_PER_G[imu["accel_range_g"]])
    rad_per_lsb = math.radians(imu["gyro_range_dps"]) / 32768
    nominal = math.radians(1 / GYRO_LSB_PER_DPS_NOMINAL[imu["gyro_range_dps"]])
    for axis, scale in zip("XYZ", imu.get("gyro_scale", [1.0, 1.0, 1.0])):
        assert _as_f32(d[f"MODEL_GYRO_K_{axis}"]) == _as_f32(rad_per_lsb / scale)
        assert abs(d[f"MODEL_GYRO_K_{axis}"] * scale / nominal - 1) < 2e-3     # the datasheet's rounding
    assert d["MODEL_SAMPLE_RATE_HZ"] == imu["sample_rate"]
    assert _as_f32(d["MODEL_SAMPLE_PERIOD_S"]) == _as_f32(1 / imu["sample_rate"])
    assert d["MODEL_TICK_US"] == 1_000_000 / imu["sample_rate"]
    assert _as_f32(d["MODEL_COMPLEMENTARY_GYRO_WEIGHT"]) == _as_f32(raw["estimator"]["complementary_gyro_weight"])


def test_velocity_gains_place_the_documented_poles(params):
    """The velocity loop's gains put the small-angle error dynamics (model/velocity.py) at a
    triple pole at -velocity_bandwidth, and the loop along up at a double pole at
    -accel_bias_bandwidth: the eigenvalues of those linear systems (numpy), from the header."""
    raw, d = params
    est = raw["estimator"]
    g = 9.80665
    k_v, k_t, k_b = d["MODEL_VEL_K_V"], d["MODEL_VEL_K_T"], d["MODEL_VEL_K_B"]
    # state (e_v, tilt error, gyro bias error): e_v' = g d - k_v e_v, d' = -k_t e_v - b, b' = k_b e_v
    tilt_loop = np.array([[-k_v, g, 0.0], [-k_t, 0.0, -1.0], [k_b, 0.0, 0.0]])
    assert np.allclose(np.linalg.eigvals(tilt_loop), -est["velocity_bandwidth"], atol=2e-2 * est["velocity_bandwidth"])
    # state (e_u, bias error along up): e_u' = -g b_u - k_u e_u, b_u' = k_a e_u
    along_up = np.array([[-d["MODEL_VEL_K_U"], -g], [d["MODEL_VEL_K_A"], 0.0]])
    assert np.allclose(np.linalg.eigvals(along_up), -est["accel_bias_bandwidth"],
                       atol=2e-2 * est["accel_bias_bandwidth"])
    assert d["MODEL_ACCEL_BIAS_LEARNT"] == 1


def test_leg_values_are_the_collision_tables(params):
    """The legs' planes folded onto [0, 180) deg (legs half a turn apart block one plane),
    in radians; the half width in radians; the distance in mm."""
    raw, d = params
    c = raw["collision"]
    want = sorted({a % 180.0 for a in c["leg_angles"]})
    assert d["MODEL_LEG_PLANES"] == len(want)
    assert [_as_f32(g) for g in d["MODEL_LEG_PLANE_ANGLES"]] == [_as_f32(math.radians(a)) for a in want]
    assert _as_f32(d["MODEL_LEG_HALF_WIDTH"]) == _as_f32(math.radians(c["leg_half_width"]))
    assert d["MODEL_LEG_DISTANCE"] == c["leg_distance"]


def test_servo_link_and_park_values(params):
    raw, d = params
    s = raw["servo"]
    assert d["MODEL_SERVO_RETURN_DELAY"] * 2 == s["return_delay_us"]
    assert d["MODEL_PARK_SPEED"] == min(1023, max(1, round(s["park_speed_rpm"] / 0.111)))
    assert d["MODEL_WORKING_SPEED"] == min(1023, max(1, round(s["working_speed_rpm"] / 0.111)))
    assert d["MODEL_TRANSIT_SPEED"] == min(1023, max(1, round(s["transit_speed_rpm"] / 0.111)))
    # how far a goal moves per tick: the Moving Speed register's 0.111 rpm units for one tick
    tick = 1 / raw["imu"]["sample_rate"]
    for name in ("PARK", "TRANSIT", "WORKING"):
        assert _as_f32(d[f"MODEL_{name}_STEP"]) == _as_f32(d[f"MODEL_{name}_SPEED"] * 0.111 * 2 * math.pi / 60 * tick)
    motion = raw["motion"]
    assert _as_f32(d["MODEL_AXIS_HOLD_RADIUS"]) == _as_f32(motion["axis_hold_radius"])
    assert _as_f32(d["MODEL_AXIS_RELEASE_RADIUS"]) == _as_f32(motion["axis_release_radius"])
    assert _as_f32(d["MODEL_FOLLOW_WINDOW"]) == _as_f32(math.radians(motion["follow_window_deg"]))
    assert d["MODEL_SERVO_BOOT_MS"] == round(s["boot_time"] * 1000)
    assert d["MODEL_SERVO_BAUD"] == s["baud"]
    for j, name in enumerate(config.JOINTS, start=1):
        assert d[f"MODEL_SERVO{j}_ID"] == s[name]["id"]
        ends = sorted(s[name]["zero"] + s[name]["direction"] * raw["joints"][name][k] * 1023 / 300
                      for k in ("min", "max"))
        assert (d[f"MODEL_SERVO{j}_CW_LIMIT"], d[f"MODEL_SERVO{j}_CCW_LIMIT"]) == \
            (math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9))
        assert _as_f32(d[f"MODEL_PARK_Q{j}"]) == _as_f32(math.radians(raw["park"]["q"][j - 1]))
    link = raw["link"]
    assert d["MODEL_LINK_SILENCE_MS"] == round(link["silence_timeout"] * 1000)
    assert d["MODEL_HEARTBEAT_MS"] == round(link["heartbeat_period"] * 1000)
    assert d["MODEL_LINK_FRAME_GAP_MS"] == round(link["frame_gap"] * 1000)


def test_speed_units_examples():
    """Worked examples of round(rpm / 0.111): 10 rpm -> 90, 59 rpm (no-load at 12 V) -> 532,
    the 1023 ceiling at 113.5 rpm, and the floor of 1 (0 would mean "no speed limit")."""
    from uavarm.model import servo
    assert [servo.speed_units(r, servo_models.AX_12A) for r in (10.0, 59.0, 113.5, 0.111, 0.05)] == [90, 532, 1023, 1, 1]


# --- poses within the servos' zero tolerance --------------------------------------------------
def _box_clearance(m, q_deg, tol_deg, n=41):
    """The least clearance (oracles.clearance_mm, plain geometry) over an n x n x n grid of the
    joint vectors within tol_deg of q_deg (corners and edges included), and where."""
    axes = [np.linspace(d - tol_deg, d + tol_deg, n) for d in q_deg]
    q = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    c = oracles.clearance_mm(m, np.radians(q))
    return float(c.min()), q[int(np.argmin(c))]


def test_shipped_park_is_clear_within_the_zero_tolerance(model):
    """The shipped park pose keeps 69.5 mm from the body plane with every joint 3 deg off
    (joint 3 at 40 + 65 cos 63 deg below the base), and the loader's bound agrees."""
    assert model.servo_zero_tolerance_deg == 3.0
    sampled, _ = _box_clearance(model, model.park_deg, 3.0)
    assert sampled == pytest.approx(40.0 + 65.0 * math.cos(math.radians(63.0)), abs=1e-6)
    bound = pose_tolerance.least(model, model.park_deg, 3.0)
    assert sampled - 1.0 <= bound.mm <= sampled + 1e-9
    assert (bound.part, bound.boundary) == ("joint 3", "body plane")


def test_park_safe_only_with_a_perfect_calibration_is_refused(tmp_path, model):
    """[0, 90, 30]: the end effector 3.25 mm below the body plane; 3 deg more on joints 2 and 3
    lift it above. Plain geometry says so; the loader refuses it, naming pose, joints, clearance."""
    q = (0.0, 90.0, 30.0)
    assert oracles.clearance_mm(model, np.radians([q]))[0] == pytest.approx(40 - 73.5 * 0.5)
    sampled, worst = _box_clearance(model, q, 3.0)
    assert sampled < 0 and list(worst[1:] - q[1:]) == pytest.approx([3.0, 3.0])
    msg = broken(tmp_path, "q = [0.0, 60.0, -110.0]", f"q = {list(q)}")
    assert "park.q" in msg and "q=[0, 90, 30]" in msg and "only safe with a perfect calibration" in msg, msg
    assert "joint 2 +3.0 deg and joint 3 +3.0 deg off" in msg and "the end effector" in msg, msg
    past = float(re.search(r"is ([\d.]+) mm past the body plane", msg).group(1))
    assert past == pytest.approx(-sampled, abs=1.0)           # the bound, within its cells' width
    exact = BASE.replace("q = [0.0, 60.0, -110.0]", f"q = {list(q)}").replace(
        "zero_tolerance_deg = 3.0", "zero_tolerance_deg = 0.0")
    load_text(tmp_path, exact)                                 # with a perfect calibration it is clear


def test_tolerance_bound_is_conservative_against_plain_geometry(model):
    """On random poses and tolerances the loader's bound never exceeds the clearance sampled
    on the box (it would let a pose pass that is not clear)."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        q = rng.uniform(-150.0, 150.0, size=3)
        tol = float(rng.uniform(0.5, 10.0))
        sampled, _ = _box_clearance(model, q, tol, n=15)
        assert pose_tolerance.least(model, q, tol).mm <= sampled + 1e-9, (q, tol)


def test_a_tuck_must_stay_inside_the_leg_distance_within_the_tolerance(tmp_path):
    """With the leg distance 8 mm only hanging straight down can turn past a leg: exactly
    (0 mm off the axis), not with the joints 3 deg off (the end effector 65 sin 3 + 73.5 sin 6
    = 11.1 mm out)."""
    short = BASE.replace("leg_distance = 100.0", "leg_distance = 8.0")
    m, _ = load_text(tmp_path, short.replace("zero_tolerance_deg = 3.0", "zero_tolerance_deg = 0.0"))
    assert generate.tuck(m) == (0.0, 0.0)
    msg = broken(tmp_path, "leg_distance = 100.0", "leg_distance = 8.0")
    assert "park.q" in msg and "past a leg" in msg, msg


@pytest.mark.parametrize("share, units", [(0.35, 358), (0.1, 102), (1.0, 1022)])
def test_bench_torque_limit_reaches_the_firmware_in_torque_limit_units(tmp_path, share, units):
    """servo.bench_torque_limit of the AX-12A's maximum torque (Torque Limit 1023, its
    e-manual), rounded; never 1023 itself, which marks a servo whose RAM reset."""
    path = tmp_path / "arm.toml"
    path.write_text(BASE.replace("bench_torque_limit = 0.35", f"bench_torque_limit = {share}", 1))
    header = generate.render(path)["model_params.h"]
    assert re.search(rf"#define MODEL_SERVO_BENCH_TORQUE_LIMIT {units}u\b", header), header


def test_the_slowest_heartbeat_fits_the_drone_sides_rules():
    """Three of the slowest heartbeats fit in the client's silence, two in its confirmation."""
    from uavarm.link.client import CONFIRM_S, SILENCE_S
    assert 3 * config.HEARTBEAT_SLOWEST_S <= SILENCE_S and 2 * config.HEARTBEAT_SLOWEST_S <= CONFIRM_S
