"""servo.model: each servo model's facts against its e-manual, the loader's checks of the
[servo] table against them, and an XM430-W350 model file generated with its defines.

The expected numbers below are typed from the ROBOTIS e-manual pages (specifications and
control tables), not taken from model/servo_models.py:
  https://emanual.robotis.com/docs/en/dxl/ax/ax-12a/
  https://emanual.robotis.com/docs/en/dxl/x/xl430-w250/
  https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/
"""
import math
import re
import subprocess
from pathlib import Path

import pytest

from conftest import once_per_run
from test_model_config import BASE, _defines, broken, load_text
from uavarm.build import variants
from uavarm.codegen import generate
from uavarm.model import config, servo_models

ROOT = Path(__file__).resolve().parents[1]

# Control tables: name -> (address, size in bytes).
AX_12A_TABLE = {
    "Baud Rate": (4, 1), "Return Delay Time": (5, 1), "CW Angle Limit": (6, 2), "CCW Angle Limit": (8, 2),
    "Highest Limit Temperature": (11, 1), "Lowest Limit Voltage": (12, 1), "Highest Limit Voltage": (13, 1),
    "Max Torque": (14, 2), "Status Return Level": (16, 1), "Alarm LED": (17, 1), "Alarm Shutdown": (18, 1),
    "Torque Enable": (24, 1), "LED": (25, 1), "CW Compliance Margin": (26, 1), "CCW Compliance Margin": (27, 1),
    "CW Compliance Slope": (28, 1), "CCW Compliance Slope": (29, 1), "Goal Position": (30, 2),
    "Moving Speed": (32, 2), "Torque Limit": (34, 2), "Present Position": (36, 2), "Present Speed": (38, 2),
    "Present Load": (40, 2), "Present Voltage": (42, 1), "Present Temperature": (43, 1), "Registered": (44, 1),
    "Moving": (46, 1), "Lock": (47, 1), "Punch": (48, 2),
}
X_TABLE = {
    "Model Number": (0, 2), "ID": (7, 1), "Baud Rate": (8, 1), "Return Delay Time": (9, 1), "Drive Mode": (10, 1),
    "Operating Mode": (11, 1), "Protocol Type": (13, 1), "Homing Offset": (20, 4), "Temperature Limit": (31, 1),
    "Max Voltage Limit": (32, 2), "Min Voltage Limit": (34, 2), "PWM Limit": (36, 2), "Velocity Limit": (44, 4),
    "Max Position Limit": (48, 4), "Min Position Limit": (52, 4), "Shutdown": (63, 1), "Torque Enable": (64, 1),
    "LED": (65, 1), "Status Return Level": (68, 1), "Hardware Error Status": (70, 1), "Goal PWM": (100, 2),
    "Goal Velocity": (104, 4), "Profile Acceleration": (108, 4), "Profile Velocity": (112, 4),
    "Goal Position": (116, 4), "Moving": (122, 1), "Present PWM": (124, 2), "Present Velocity": (128, 4),
    "Present Position": (132, 4), "Present Input Voltage": (144, 2), "Present Temperature": (146, 1),
    "Indirect Address 1": (168, 2), "Indirect Data 1": (224, 1),
}
XL430_TABLE = {**X_TABLE, "Present Load": (126, 2)}
XM430_TABLE = {**X_TABLE, "Current Limit": (38, 2), "Goal Current": (102, 2), "Present Current": (126, 2)}
X_BAUDS = {0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000, 6: 4_000_000, 7: 4_500_000}

# Specifications: protocol, position 0..max over degrees, the manual's resolution (deg), no-load
# rpm and stall torque (N m) at 12 V, the speed register's unit (rpm), control table.
MANUAL = {
    "AX-12A": dict(protocol=1, position_max=1023, travel_deg=300.0, resolution_deg=0.29, no_load_rpm=59.0,
                   stall_nm=1.5, rpm_per_unit=0.111, speed_reg="Moving Speed", load_reg="Present Load",
                   table=AX_12A_TABLE),
    "XL430-W250": dict(protocol=2, position_max=4095, travel_deg=360.0 * 4095 / 4096, resolution_deg=0.088,
                       no_load_rpm=61.0, stall_nm=1.5, rpm_per_unit=0.229, speed_reg="Profile Velocity",
                       load_reg="Present Load", table=XL430_TABLE),
    "XM430-W350": dict(protocol=2, position_max=4095, travel_deg=360.0 * 4095 / 4096, resolution_deg=0.088,
                       no_load_rpm=46.0, stall_nm=4.1, rpm_per_unit=0.229, speed_reg="Profile Velocity",
                       load_reg="Present Current", table=XM430_TABLE),
}


def test_the_known_models_are_the_three():
    assert sorted(servo_models.MODELS) == sorted(MANUAL)
    assert servo_models.DEFAULT == "AX-12A"


@pytest.mark.parametrize("name", sorted(MANUAL))
def test_facts_are_the_e_manuals(name):
    facts, manual = servo_models.MODELS[name], MANUAL[name]
    assert facts.protocol == manual["protocol"]
    assert facts.units_max == manual["position_max"]
    assert facts.range_deg == pytest.approx(manual["travel_deg"], abs=1e-9)
    assert float(facts.deg_per_unit) == pytest.approx(manual["resolution_deg"], abs=0.005)   # the manual rounds it
    assert (facts.no_load_rpm, facts.no_load_volts, facts.stall_torque_nm) == (manual["no_load_rpm"], 12.0,
                                                                               manual["stall_nm"])
    assert facts.rpm_per_speed_unit == manual["rpm_per_unit"]
    for role, reg in facts.registers.items():
        assert manual["table"].get(reg.name) == (reg.address, reg.size), (role, reg)
    assert facts.registers["GOAL_SPEED"].name == manual["speed_reg"]
    assert facts.registers["PRESENT_LOAD"].name == manual["load_reg"]
    assert facts.registers["GOAL_POSITION"].name == "Goal Position"
    assert facts.registers["PRESENT_POSITION"].name == "Present Position"
    assert set(servo_models.COMMON_ROLES) <= set(facts.registers)


def test_x_series_bauds_are_the_baud_rate_table():
    for facts in (servo_models.XL430_W250, servo_models.XM430_W350):
        assert facts.bauds == X_BAUDS


def test_ax12a_bauds_are_its_baud_rate_rule():
    """AX-12A e-manual, Baud Rate(4): 2,000,000 / (value + 1), its table's examples; 7843 bit/s to 1 Mbit/s."""
    bauds = servo_models.AX_12A.bauds
    for n, rate in {1: 1_000_000, 3: 500_000, 4: 400_000, 7: 250_000, 9: 200_000, 16: 117_647.06,
                    34: 57_142.86, 103: 19_230.77, 207: 9_615.38}.items():
        assert bauds[n] == pytest.approx(rate, abs=0.01)
    assert min(bauds.values()) == pytest.approx(7843, abs=1) and max(bauds.values()) == 1_000_000


def test_ax12a_facts_are_the_registers_the_firmware_uses():
    """The AX-12A's facts are what servo_bus.c and dxl_protocol.h address today."""
    app = ROOT / "firmware_stm32" / "App"
    c = {k: int(v) for k, v in re.findall(r"#define (\w+) (\d+)u?\b", (app / "Src" / "servo_bus.c").read_text()
                                           + (app / "Inc" / "dxl_protocol.h").read_text())}
    regs = {role: reg.address for role, reg in servo_models.AX_12A.registers.items()}
    assert (c["AX_RETURN_DELAY"], c["AX_CW_ANGLE_LIMIT"], c["AX_STATUS_RETURN_LEVEL"], c["AX_TORQUE_ENABLE"],
            c["AX_TORQUE_LIMIT"], c["AX_PRESENT_POSITION"], c["AX_HIGHEST_TEMPERATURE"], c["AX_ALARM_SHUTDOWN"],
            c["DXL_AX_GOAL_POSITION"], c["DXL_AX_MOVING_SPEED"], c["DXL_AX_POSITION_MAX"]) == \
        (regs["RETURN_DELAY_TIME"], regs["MIN_POSITION_LIMIT"], regs["STATUS_RETURN_LEVEL"], regs["TORQUE_ENABLE"],
         regs["TORQUE_LIMIT"], regs["PRESENT_POSITION"], regs["TEMPERATURE_LIMIT"], regs["SHUTDOWN"],
         regs["GOAL_POSITION"], regs["GOAL_SPEED"], servo_models.AX_12A.units_max)


# --- the loader ---------------------------------------------------------------------------------

SERVO_HEAD = 'model = "AX-12A"\n'
AX_TRAVEL = "units_max = 1023\nrange_deg = 300.0"
X_TRAVEL = "units_max = 4095\nrange_deg = 359.912109375"


def xm430_text(model="XM430-W350", baud=1_000_000, travel=X_TRAVEL, zero=2048):
    text = BASE.replace(SERVO_HEAD, f'model = "{model}"\n', 1).replace("baud = 200000", f"baud = {baud}", 1)
    text = text.replace(AX_TRAVEL, travel, 1)
    return text.replace("zero = 512", f"zero = {zero}")


def test_the_committed_file_names_the_ax12a(model):
    assert SERVO_HEAD in BASE and AX_TRAVEL in BASE
    assert model.servo_model is servo_models.AX_12A


def test_an_absent_model_is_the_ax12a(tmp_path):
    model, _ = load_text(tmp_path, BASE.replace(SERVO_HEAD, "", 1))
    assert model.servo_model is servo_models.AX_12A


@pytest.mark.parametrize("name", ["XL430-W250", "XM430-W350"])
def test_an_x_series_file_loads(tmp_path, name):
    model, _ = load_text(tmp_path, xm430_text(name))
    assert model.servo_model.name == name
    assert (model.servo_units_max, model.servo_range_deg, model.servo_baud) == (4095, 359.912109375, 1_000_000)
    assert [s.zero for s in model.servos] == [2048] * 3


@pytest.mark.parametrize("baud", [9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000])
def test_x_series_bauds_load(tmp_path, baud):
    assert load_text(tmp_path, xm430_text(baud=baud))[0].servo_baud == baud


@pytest.mark.parametrize("old, new, key, words", [
    (SERVO_HEAD, 'model = "AX-12"\n', "servo.model", "must be one of 'AX-12A', 'XL430-W250', 'XM430-W350', got 'AX-12'"),
    (SERVO_HEAD, "model = 12\n", "servo.model", "must be one of 'AX-12A', 'XL430-W250', 'XM430-W350', got 12"),
    (SERVO_HEAD, 'model = "XM430-W350"\n', "servo.units_max",
     "the XM430-W350's positions run 0..4095 (servo.model = \"XM430-W350\"), got 1023"),
    (AX_TRAVEL, "units_max = 1023\nrange_deg = 360.0", "servo.range_deg",
     "the AX-12A's 1023 units span 300.0 deg"),
    (AX_TRAVEL, "units_max = 4095\nrange_deg = 300.0", "servo.units_max", "the AX-12A's positions run 0..1023"),
])
def test_bad_servo_model_values_name_the_key(tmp_path, old, new, key, words):
    msg = broken(tmp_path, old, new)
    assert f": {key}: " in msg and words in msg, msg


@pytest.mark.parametrize("text, key, words", [
    (xm430_text(travel="units_max = 4095\nrange_deg = 360.0"), "servo.range_deg",
     "the XM430-W350's 4095 units span 359.912109375 deg"),
    (xm430_text(baud=200_000), "servo.baud", "an XM430-W350 runs at 9600, 57600, 115200, 1M"),
    (xm430_text(baud=500_000), "servo.baud", "beyond the UART's 3% tolerance"),
    (xm430_text(baud=5_000_000), "servo.baud", "<= 4500000"),
    (xm430_text(zero=4096), "servo.theta1.zero", "<= 4095"),
    # an AX-12A's centre on an X-series servo: joint 1's -145 deg limit at 512 - 1650 units
    (xm430_text(zero=512), "joints.theta1", "outside 0..4095, the XM430-W350's travel"),
    (xm430_text().replace("working_speed_rpm = 59.0", "working_speed_rpm = 235.0"), "servo.working_speed_rpm",
     "<= 234.2"),    # Velocity Limit(44) at most 1023 x 0.229 rpm
])
def test_x_series_files_are_checked_against_the_x_series(tmp_path, text, key, words):
    path = tmp_path / "arm.toml"
    path.write_text(text)
    with pytest.raises(config.ModelError) as err:
        config.load(path)
    msg = str(err.value)
    assert str(path) in msg and f": {key}: " in msg and words in msg, msg


def test_an_x_series_variant_is_the_x_series_model():
    """The simulated board makes the servos the model file names: an X-series variant's model
    is the X-series one, its units and baud as edited; the AX-12A's stays the AX-12A."""
    changes = {"servo.model": "XM430-W350", "servo.units_max": 4095, "servo.range_deg": 359.912109375,
               "servo.baud": 1_000_000, **{f"servo.theta{j}.zero": 2048 for j in (1, 2, 3)}}
    model = variants.model_of(changes)
    assert model.servo_model is servo_models.MODELS["XM430-W350"]
    assert (model.servo_units_max, model.servo_baud, [s.zero for s in model.servos]) == (4095, 1_000_000, [2048] * 3)
    assert variants.model_of({"servo.model": "AX-12A"}).servo_model is servo_models.AX_12A


# --- the generated defines ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def xm430_generated(tmp_path_factory):
    def make(folder):       # (generated once per test run: seconds of SymPy)
        (folder / "arm.toml").write_text(xm430_text())
        assert generate.main(["--model", str(folder / "arm.toml"), "--out", str(folder / "generated")]) == 0
        return str(folder / "generated")
    return Path(once_per_run(tmp_path_factory, "xm430_generated", make))


def _expected_defines(name, baud_register):
    manual = MANUAL[name]
    table = manual["table"]
    out = {"MODEL_DXL_PROTOCOL": manual["protocol"], "MODEL_DXL_POSITION_MAX": manual["position_max"],
           "MODEL_DXL_BAUD_REGISTER": baud_register, "MODEL_DXL_NO_LOAD_RPM": manual["no_load_rpm"],
           "MODEL_DXL_STALL_TORQUE_NM": manual["stall_nm"], "MODEL_DXL_RPM_PER_SPEED_UNIT": manual["rpm_per_unit"],
           f"MODEL_DXL_{name.replace('-', '_')}": 1}
    for role, reg_name in {"GOAL_POSITION": "Goal Position", "GOAL_SPEED": manual["speed_reg"],
                           "PRESENT_POSITION": "Present Position", "PRESENT_LOAD": manual["load_reg"],
                           "TORQUE_ENABLE": "Torque Enable", "STATUS_RETURN_LEVEL": "Status Return Level",
                           "RETURN_DELAY_TIME": "Return Delay Time", "PRESENT_TEMPERATURE": "Present Temperature",
                           "BAUD_RATE": "Baud Rate", "LED": "LED", "MOVING": "Moving"}.items():
        out[f"MODEL_DXL_{role}"], out[f"MODEL_DXL_{role}_SIZE"] = table[reg_name]
    return out


def test_xm430_file_generates_its_defines(xm430_generated):
    files = {p.name for p in xm430_generated.iterdir()}
    assert set(generate.OUTPUTS) <= files
    got = _defines((xm430_generated / "model_params.h").read_text())
    expected = _expected_defines("XM430-W350", baud_register=3)      # 1 Mbit/s
    expected.update({"MODEL_DXL_PRESENT_VOLTAGE": 144, "MODEL_DXL_PRESENT_VOLTAGE_SIZE": 2,
                     "MODEL_DXL_PRESENT_SPEED": 128, "MODEL_DXL_PRESENT_SPEED_SIZE": 4,
                     "MODEL_DXL_OPERATING_MODE": 11, "MODEL_DXL_PROFILE_ACCELERATION": 108,
                     "MODEL_DXL_HARDWARE_ERROR_STATUS": 70, "MODEL_DXL_MIN_POSITION_LIMIT": 52,
                     "MODEL_DXL_MAX_POSITION_LIMIT": 48, "MODEL_DXL_MAX_POSITION_LIMIT_SIZE": 4})
    assert {k: got.get(k) for k in expected} == pytest.approx(expected)
    assert "MODEL_DXL_AX_12A" not in got and "MODEL_DXL_TORQUE_LIMIT" not in got    # no such register
    assert got["MODEL_DXL_DEG_PER_UNIT"] == pytest.approx(360 / 4096, rel=1e-6)
    # the servo map in 4096 units per turn around 2048: each joint limit in whole units inside it
    per_deg = 4096 / 360
    assert got["MODEL_RAD_PER_UNIT"] == pytest.approx(math.radians(1 / per_deg), rel=1e-6)
    model = config.parse(xm430_text().encode(), Path("arm.toml"))
    for j, limit in enumerate(model.limits, 1):
        assert got[f"MODEL_SERVO{j}_CW_LIMIT"] == math.ceil(2048 + limit.min_deg * per_deg - 1e-9)
        assert got[f"MODEL_SERVO{j}_CCW_LIMIT"] == math.floor(2048 + limit.max_deg * per_deg + 1e-9)
    # the speeds in Profile Velocity units of 0.229 rpm (park 10, transit 30, working 59 rpm)
    assert (got["MODEL_PARK_SPEED"], got["MODEL_TRANSIT_SPEED"], got["MODEL_WORKING_SPEED"]) == (44, 131, 258)
    assert got["MODEL_WORKING_STEP"] == pytest.approx(258 * 0.229 * 2 * math.pi / 60 / model.sample_rate, rel=1e-6)
    assert got["MODEL_UNITS_PER_S_PER_SPEED"] == pytest.approx(0.229 * 6 * per_deg, rel=1e-6)
    # the goals' speed limit at the supply: the XM430-W350's 46 rpm at 12 V, not the AX-12A's 59
    assert got["MODEL_STEP_PER_DECIVOLT"] == pytest.approx(
        model.servo_speed_margin * 46.0 / 12.0 / 10 * 2 * math.pi / 60 / model.sample_rate, rel=1e-6)


def test_committed_defines_are_the_ax12a(model):
    got = _defines((ROOT / "generated" / "model_params.h").read_text())
    expected = _expected_defines("AX-12A", baud_register=9)      # 200000 = 2,000,000 / (9 + 1)
    assert {k: got.get(k) for k in expected} == pytest.approx(expected)
    assert got["MODEL_DXL_DEG_PER_UNIT"] == pytest.approx(300 / 1023, rel=1e-6)
    assert got["MODEL_STEP_PER_DECIVOLT"] == pytest.approx(
        model.servo_speed_margin * 59.0 / 12.0 / 10 * 2 * math.pi / 60 / model.sample_rate, rel=1e-6)


@pytest.mark.parametrize("which", ["committed", "XM430-W350"])
def test_the_bus_driver_of_the_servos_protocol_is_built(which, xm430_generated, tmp_path):
    """servo_bus.c speaks Protocol 1.0 (AX-12A), servo_bus2.c Protocol 2.0 (X-series): both
    are in the firmware's sources, and the model's servo decides which one defines the
    sbus_* functions; the other compiles to nothing."""
    generated = ROOT / "generated" if which == "committed" else xm430_generated
    app = ROOT / "firmware_stm32" / "App"
    defined = {}
    for name in ("servo_bus.c", "servo_bus2.c"):
        obj = tmp_path / (name + ".o")
        run = subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "-o", str(obj),
                              "-I", str(generated), "-I", str(app / "Inc"), str(app / "Src" / name)],
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        symbols = subprocess.run(["nm", "--defined-only", "-g", str(obj)], capture_output=True, text=True,
                                 check=True).stdout.split()
        defined[name] = {s for s in symbols if s.startswith("sbus_")}
    api = {"sbus_init", "sbus_power", "sbus_power_limp", "sbus_full_torque", "sbus_command", "sbus_limp",
           "sbus_read", "sbus_poll", "sbus_tick_bus_time_us"}
    speaks = "servo_bus.c" if which == "committed" else "servo_bus2.c"
    other = "servo_bus2.c" if which == "committed" else "servo_bus.c"
    assert defined[speaks] == api and defined[other] == set()
