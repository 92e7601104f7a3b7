"""The servo models `servo.model` may name, and each one's facts: what the loader checks the
[servo] table against and what the generator emits for the firmware (MODEL_DXL_* in
model_params.h).

Sources, the ROBOTIS e-manual of each servo (specifications and control table):
  AX-12A      https://emanual.robotis.com/docs/en/dxl/ax/ax-12a/
  XL430-W250  https://emanual.robotis.com/docs/en/dxl/x/xl430-w250/
  XM430-W350  https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/
The X-series Baud Rate(8) table and its 3 % margin: the same pages, "Baud Rate(8)".
"""
from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from typing import NamedTuple

DEFAULT = "AX-12A"


class Register(NamedTuple):
    address: int
    size: int          # bytes
    name: str          # as the e-manual's control table names it


@dataclass(frozen=True, eq=False)     # one instance per model (MODELS): compared and hashed as itself
class ServoModel:
    name: str
    protocol: int                 # Dynamixel protocol the servo speaks out of the box (1: 1.0, 2: 2.0)
    units_max: int                # Goal Position travel: 0..units_max
    deg_per_unit: Fraction        # position resolution
    no_load_rpm: float            # at no_load_volts; falls in proportion to the supply
    no_load_volts: float
    stall_torque_nm: float        # at no_load_volts
    load_unit_nm: float           # the torque one unit of its load reading (PRESENT_LOAD) stands for, at no_load_volts
    rpm_per_speed_unit: float     # the goal-speed register's unit (Moving Speed / Profile Velocity)
    speed_units_max: int          # the goal speed's upper bound (Moving Speed / Velocity Limit(44))
    bauds: dict                   # Baud Rate register value -> bit/s
    baud_rule: str                # the same, in words
    registers: dict               # role -> Register: the ones the firmware uses or will use
    manual: str

    @property
    def range_deg(self) -> float:
        """The angle from position 0 to units_max."""
        return float(self.units_max * self.deg_per_unit)


# Roles every model has (the firmware's bus driver addresses a register by its role).
COMMON_ROLES = ("BAUD_RATE", "RETURN_DELAY_TIME", "MIN_POSITION_LIMIT", "MAX_POSITION_LIMIT",
                "TEMPERATURE_LIMIT", "MIN_VOLTAGE_LIMIT", "MAX_VOLTAGE_LIMIT", "SHUTDOWN",
                "TORQUE_ENABLE", "LED", "STATUS_RETURN_LEVEL", "GOAL_POSITION", "GOAL_SPEED",
                "PRESENT_POSITION", "PRESENT_SPEED", "PRESENT_LOAD", "PRESENT_VOLTAGE",
                "PRESENT_TEMPERATURE", "MOVING")

# AX-12A (Protocol 1.0): the registers firmware_stm32/App/Src/servo_bus.c and dxl_protocol.h use.
AX_12A = ServoModel(
    name="AX-12A", protocol=1, units_max=1023, deg_per_unit=Fraction(300, 1023),
    # (the legacy AX-12's 0.196 s/60 deg at 10 V, 51 rpm, lies just above the no-load line)
    no_load_rpm=59.0, no_load_volts=12.0, stall_torque_nm=1.5,
    load_unit_nm=1.5 / 1023,                            # Present Load: 1023 the full torque
    rpm_per_speed_unit=0.111, speed_units_max=1023,     # Moving Speed, joint mode
    bauds={n: 2_000_000 / (n + 1) for n in range(1, 255)},     # 7843 bit/s to 1 Mbit/s
    baud_rule="2,000,000 / (n + 1) bit/s (Baud Rate register n = 1..254)",
    registers={
        "BAUD_RATE": Register(4, 1, "Baud Rate"),
        "RETURN_DELAY_TIME": Register(5, 1, "Return Delay Time"),
        "MIN_POSITION_LIMIT": Register(6, 2, "CW Angle Limit"),
        "MAX_POSITION_LIMIT": Register(8, 2, "CCW Angle Limit"),
        "TEMPERATURE_LIMIT": Register(11, 1, "Highest Limit Temperature"),
        "MIN_VOLTAGE_LIMIT": Register(12, 1, "Lowest Limit Voltage"),
        "MAX_VOLTAGE_LIMIT": Register(13, 1, "Highest Limit Voltage"),
        "MAX_TORQUE": Register(14, 2, "Max Torque"),
        "STATUS_RETURN_LEVEL": Register(16, 1, "Status Return Level"),
        "SHUTDOWN": Register(18, 1, "Alarm Shutdown"),
        "TORQUE_ENABLE": Register(24, 1, "Torque Enable"),
        "LED": Register(25, 1, "LED"),
        "CW_COMPLIANCE_MARGIN": Register(26, 1, "CW Compliance Margin"),
        "CCW_COMPLIANCE_MARGIN": Register(27, 1, "CCW Compliance Margin"),
        "CW_COMPLIANCE_SLOPE": Register(28, 1, "CW Compliance Slope"),
        "CCW_COMPLIANCE_SLOPE": Register(29, 1, "CCW Compliance Slope"),
        "GOAL_POSITION": Register(30, 2, "Goal Position"),
        "GOAL_SPEED": Register(32, 2, "Moving Speed"),
        "TORQUE_LIMIT": Register(34, 2, "Torque Limit"),
        "PRESENT_POSITION": Register(36, 2, "Present Position"),
        "PRESENT_SPEED": Register(38, 2, "Present Speed"),
        "PRESENT_LOAD": Register(40, 2, "Present Load"),
        "PRESENT_VOLTAGE": Register(42, 1, "Present Voltage"),
        "PRESENT_TEMPERATURE": Register(43, 1, "Present Temperature"),
        "MOVING": Register(46, 1, "Moving"),
    },
    manual="https://emanual.robotis.com/docs/en/dxl/ax/ax-12a/",
)

# The X-series (Protocol 2.0) control table the two models share; Position Control Mode spans
# 0..4095 over one turn (4096 pulses/rev, 0.088 deg).
X_BAUDS = {0: 9_600, 1: 57_600, 2: 115_200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000, 6: 4_000_000,
           7: 4_500_000}
_X_REGISTERS = {
    "BAUD_RATE": Register(8, 1, "Baud Rate"),
    "RETURN_DELAY_TIME": Register(9, 1, "Return Delay Time"),
    "OPERATING_MODE": Register(11, 1, "Operating Mode"),
    "TEMPERATURE_LIMIT": Register(31, 1, "Temperature Limit"),
    "MAX_VOLTAGE_LIMIT": Register(32, 2, "Max Voltage Limit"),
    "MIN_VOLTAGE_LIMIT": Register(34, 2, "Min Voltage Limit"),
    "PWM_LIMIT": Register(36, 2, "PWM Limit"),
    "VELOCITY_LIMIT": Register(44, 4, "Velocity Limit"),
    "MAX_POSITION_LIMIT": Register(48, 4, "Max Position Limit"),
    "MIN_POSITION_LIMIT": Register(52, 4, "Min Position Limit"),
    "SHUTDOWN": Register(63, 1, "Shutdown"),
    "TORQUE_ENABLE": Register(64, 1, "Torque Enable"),
    "LED": Register(65, 1, "LED"),
    "STATUS_RETURN_LEVEL": Register(68, 1, "Status Return Level"),
    "HARDWARE_ERROR_STATUS": Register(70, 1, "Hardware Error Status"),
    "GOAL_PWM": Register(100, 2, "Goal PWM"),
    "PROFILE_ACCELERATION": Register(108, 4, "Profile Acceleration"),
    "GOAL_SPEED": Register(112, 4, "Profile Velocity"),
    "GOAL_POSITION": Register(116, 4, "Goal Position"),
    "MOVING": Register(122, 1, "Moving"),
    "PRESENT_SPEED": Register(128, 4, "Present Velocity"),
    "PRESENT_POSITION": Register(132, 4, "Present Position"),
    "PRESENT_VOLTAGE": Register(144, 2, "Present Input Voltage"),
    "PRESENT_TEMPERATURE": Register(146, 1, "Present Temperature"),
    # the first of 28 (2 bytes each, RAM: back at their initial values after a power cycle)
    "INDIRECT_ADDRESS": Register(168, 2, "Indirect Address 1"),
    "INDIRECT_DATA": Register(224, 1, "Indirect Data 1"),
}
_X_BAUD_RULE = "9600, 57600, 115200, 1M, 2M, 3M, 4M or 4.5M bit/s (Baud Rate register n = 0..7)"


def _x_series(name: str, no_load_rpm: float, stall_torque_nm: float, load: Register, load_unit_nm: float,
              manual: str) -> ServoModel:
    return ServoModel(
        name=name, protocol=2, units_max=4095, deg_per_unit=Fraction(360, 4096),
        no_load_rpm=no_load_rpm, no_load_volts=12.0, stall_torque_nm=stall_torque_nm, load_unit_nm=load_unit_nm,
        rpm_per_speed_unit=0.229, speed_units_max=1023, bauds=X_BAUDS, baud_rule=_X_BAUD_RULE,
        registers={**_X_REGISTERS, "PRESENT_LOAD": load}, manual=manual)


# Present Load: 0.1 % of the stall torque. Present Current: 2.69 mA, and the stall torque at the
# stall current (4.1 N m at 2.3 A, 12 V).
XL430_W250 = _x_series("XL430-W250", 61.0, 1.5, Register(126, 2, "Present Load"), 1.5 / 1000,
                       "https://emanual.robotis.com/docs/en/dxl/x/xl430-w250/")
XM430_W350 = _x_series("XM430-W350", 46.0, 4.1, Register(126, 2, "Present Current"), 0.00269 * 4.1 / 2.3,
                       "https://emanual.robotis.com/docs/en/dxl/x/xm430-w350/")

MODELS = {m.name: m for m in (AX_12A, XL430_W250, XM430_W350)}


def baud_register(servo: ServoModel, baud: float) -> int:
    """The Baud Rate register value whose rate is nearest baud (the model file's servo.baud is
    checked to be within the UART's 3 % of one)."""
    return min(servo.bauds, key=lambda n: abs(servo.bauds[n] / baud - 1))
