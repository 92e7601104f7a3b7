"""An MPU-6050 as its register file: what the firmware's I2C reads and writes see.

Written from the InvenSense register map (RM-MPU-6000A rev 4.2) and datasheet (PS-MPU-6000A
rev 3.4), independently of the firmware's driver: WHO_AM_I reads 0x68, the chip powers up
asleep (PWR_MGMT_1 = 0x40) and its data registers stay at 0 until woken, and samples are
big-endian int16 scaled by the full-scale range the configuration registers select; each
sample sets DATA_RDY_INT in INT_STATUS, which a read of INT_STATUS clears (register map 4.16).
The values it latches come from the sensor model (uavarm.sim.imu_model: noise, bias, scale,
vibration, the low-pass filter and the decimation that CONFIG and SMPLRT_DIV select).
"""
from __future__ import annotations

import math

REG_SMPLRT_DIV = 0x19
REG_CONFIG = 0x1A
REG_GYRO_CONFIG = 0x1B
REG_ACCEL_CONFIG = 0x1C
REG_INT_STATUS = 0x3A           # bit 0 DATA_RDY_INT: set on each sample, cleared by reading it
DATA_RDY = 0x01
REG_ACCEL_XOUT_H = 0x3B
REG_GYRO_XOUT_H = 0x43
REG_PWR_MGMT_1 = 0x6B
REG_WHO_AM_I = 0x75
WHO_AM_I = 0x68
SLEEP = 0x40

ACCEL_LSB_PER_G = (16384, 8192, 4096, 2048)           # AFS_SEL 0..3
GYRO_FULL_SCALE_DPS = (250, 500, 1000, 2000)           # FS_SEL 0..3


def _int16(value: float) -> int:
    return max(-32768, min(32767, round(value)))


class Mpu6050:
    """regs: a writable 128-byte buffer (e.g. the host port's register file)."""

    def __init__(self, regs):
        self.regs = regs
        self.power_on()

    def power_on(self) -> None:
        self.regs[:] = bytes(len(self.regs))
        self.regs[REG_PWR_MGMT_1] = SLEEP
        self.regs[REG_WHO_AM_I] = WHO_AM_I

    @property
    def asleep(self) -> bool:
        return bool(self.regs[REG_PWR_MGMT_1] & SLEEP)

    @property
    def dlpf_cfg(self) -> int:
        return self.regs[REG_CONFIG] & 7

    @property
    def smplrt_div(self) -> int:
        return self.regs[REG_SMPLRT_DIV]

    @property
    def accel_lsb_per_g(self) -> int:
        return ACCEL_LSB_PER_G[self.regs[REG_ACCEL_CONFIG] >> 3 & 3]

    @property
    def gyro_lsb_per_rad_s(self) -> float:
        full_scale = GYRO_FULL_SCALE_DPS[self.regs[REG_GYRO_CONFIG] >> 3 & 3]
        return 32768 / math.radians(full_scale)

    def sample(self, accel_g, gyro_rad_s, temperature_c: float = 25.0) -> None:
        """Latch one sample (IMU axes): specific force in g, angular rate in rad/s."""
        if self.asleep:
            return
        words = [a * self.accel_lsb_per_g for a in accel_g]
        words.append((temperature_c - 36.53) * 340)   # datasheet: T = raw / 340 + 36.53
        words += [w * self.gyro_lsb_per_rad_s for w in gyro_rad_s]
        data = b"".join(_int16(w).to_bytes(2, "big", signed=True) for w in words)
        self.regs[REG_ACCEL_XOUT_H:REG_ACCEL_XOUT_H + 14] = data
        self.regs[REG_INT_STATUS] |= DATA_RDY       # (the host port clears it when read)
