"""The MPU-6050 driver (firmware_stm32/App/Src/imu_mpu6050.c) at register level, on the
host build with the host port's I2C register file driven by uavarm.sim.mpu6050_sim.

Oracle: InvenSense's register map (RM-MPU-6000A rev 4.2) and product specification
(PS-MPU-6000A rev 3.4), whose numbers are written out here: register addresses, bit
fields, the DLPF table, sensitivities. The expected register values come from the model
file through those tables, not from the generated C.
"""
import math

import numpy as np
import pytest

from uavarm.build import firmware
from uavarm.model import config
from uavarm.sim.mpu6050_sim import Mpu6050

# RM-MPU-6000A: register addresses
SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG = 0x19, 0x1A, 0x1B, 0x1C
INT_ENABLE, INT_STATUS, ACCEL_XOUT_H, PWR_MGMT_1, WHO_AM_I = 0x38, 0x3A, 0x3B, 0x6B, 0x75
# RM-MPU-6000A 4.3 (register 26): DLPF_CFG -> (accel bandwidth Hz, accel delay ms,
# gyro bandwidth Hz, gyro delay ms, gyro output rate Hz)
DLPF_TABLE = {
    0: (260, 0.0, 256, 0.98, 8000),
    1: (184, 2.0, 188, 1.9, 1000),
    2: (94, 3.0, 98, 2.8, 1000),
    3: (44, 4.9, 42, 4.8, 1000),
    4: (21, 8.5, 20, 8.3, 1000),
    5: (10, 13.8, 10, 13.4, 1000),
    6: (5, 19.0, 5, 18.6, 1000),
}
FS_SEL = {250: 0, 500: 1, 1000: 2, 2000: 3}                # GYRO_CONFIG bits 4:3
AFS_SEL = {2: 0, 4: 1, 8: 2, 16: 3}                        # ACCEL_CONFIG bits 4:3
ACCEL_LSB_PER_G = {2: 16384, 4: 8192, 8: 4096, 16: 2048}   # PS-MPU-6000A table 6.2
GYRO_LSB_PER_DPS = {250: 131.0, 500: 65.5, 1000: 32.8, 2000: 16.4}   # PS-MPU-6000A table 6.1
PROPELLER_BAND_HZ = (57.0, 97.0)                           # propeller vibration

MODEL = config.load()


class Chip:
    """The host port with a simulated MPU-6050 behind it."""

    def __init__(self):
        self.ffi, self.lib = firmware.default()
        self.hp = self.ffi.new("host_port_t *")
        self.lib.host_port_init(self.hp, MODEL.servo_baud, MODEL.imu_address)
        self.sim = Mpu6050(memoryview(self.ffi.buffer(self.hp.imu_regs)))
        self.port = self.ffi.addressof(self.hp[0], "port")

    @property
    def regs(self):
        return self.hp.imu_regs

    def init(self, address=MODEL.imu_address):
        return self.lib.mpu_init(self.port, address)

    def read(self):
        out = self.ffi.new("mpu_sample_t *")
        ok = self.lib.mpu_sample(self.port, MODEL.imu_address, out)
        return ok, out

    def set_words(self, words, fresh=True):
        """The sample registers (accel x y z, temperature, gyro x y z) and DATA_RDY."""
        self.regs[ACCEL_XOUT_H:ACCEL_XOUT_H + 14] = b"".join(w.to_bytes(2, "big", signed=True) for w in words)
        self.regs[INT_STATUS] = 0x01 if fresh else 0x00


def dlpf_cfg_of_model():
    """The DLPF_CFG whose accelerometer bandwidth the model file names."""
    return next(cfg for cfg, row in DLPF_TABLE.items() if row[0] == MODEL.dlpf_bandwidth)


def test_init_wakes_the_chip_and_writes_each_setting_the_model_implies():
    chip = Chip()
    assert chip.sim.asleep                                  # power-on state: SLEEP set
    assert chip.init()
    assert not chip.sim.asleep
    assert chip.regs[PWR_MGMT_1] == 0x01                    # SLEEP 0, CLKSEL 1 (PLL, X gyro)
    cfg = dlpf_cfg_of_model()
    assert chip.regs[CONFIG] == cfg                         # EXT_SYNC_SET 0, DLPF_CFG
    gyro_rate = DLPF_TABLE[cfg][4]
    assert gyro_rate / (1 + chip.regs[SMPLRT_DIV]) == MODEL.sample_rate
    assert chip.regs[GYRO_CONFIG] == FS_SEL[MODEL.gyro_range_dps] << 3
    assert chip.regs[ACCEL_CONFIG] == AFS_SEL[MODEL.accel_range_g] << 3
    assert chip.regs[INT_ENABLE] == 0x01                    # DATA_RDY_EN


def test_wrong_who_am_i_is_refused_before_anything_is_written():
    chip = Chip()
    chip.regs[WHO_AM_I] = 0x70                              # an MPU-6500 answers 0x70
    assert not chip.init()
    assert chip.hp.imu_writes == 0 and chip.sim.asleep


@pytest.mark.parametrize("fault", ["absent", "other address"])
def test_i2c_errors_are_reported(fault):
    chip = Chip()
    if fault == "absent":
        chip.hp.imu_present = False
        assert not chip.init()
    else:
        assert not chip.init(address=MODEL.imu_address ^ 1)   # AD0 the other way: NACK
    chip.hp.imu_present = True
    assert chip.init()
    chip.hp.imu_present = False                             # lost after set-up
    ok, _ = chip.read()
    assert not ok


def scaled(words):
    """Accel (g) and gyro (rad/s) of sample words by the datasheet: the model's range over
    32768 counts, in float32 like the firmware."""
    g_per_lsb = np.float32(1 / ACCEL_LSB_PER_G[MODEL.accel_range_g])
    rad_per_lsb = np.float32(math.radians(MODEL.gyro_range_dps) / 32768)
    accel = [float(np.float32(w) * g_per_lsb) for w in words[0:3]]
    gyro = [float(np.float32(w) * rad_per_lsb) for w in words[4:7]]
    return accel, gyro


@pytest.mark.parametrize("words, fresh, saturated", [
    ([0x1234, -2, -32768, 0x7FFF, -1, 0x0100, 0x00FF], True, True),     # accel z at full scale
    ([100, -200, 16384, 0, 5, -6, 7], True, False),
    ([100, -200, 16384, 0, 5, 32767, 7], False, True),                  # gyro y at full scale
    ([-32767, 32766, 0, -32768, 0, 0, -1], True, False),                # temperature does not count
])
def test_burst_read_is_one_15_byte_transfer_of_big_endian_words(words, fresh, saturated):
    chip = Chip()
    assert chip.init()
    chip.set_words(words, fresh)
    reads = chip.hp.imu_reads
    ok, out = chip.read()
    assert ok and chip.hp.imu_reads == reads + 1
    accel, gyro = scaled(words)
    assert list(out.accel_g) == accel
    assert list(out.gyro_rad_s) == pytest.approx(gyro, rel=1.2e-7, abs=0)   # (float32 rounding of the constant)
    assert (out.fresh, out.saturated) == (fresh, saturated)


def test_scaling_uses_the_datasheet_sensitivities_of_the_model_ranges():
    chip = Chip()
    assert chip.init()
    lsb_g = ACCEL_LSB_PER_G[MODEL.accel_range_g]
    lsb_dps = GYRO_LSB_PER_DPS[MODEL.gyro_range_dps]
    chip.set_words([lsb_g, -lsb_g // 2, 0, 0, round(100 * lsb_dps), round(-10 * lsb_dps), 0])
    ok, out = chip.read()
    assert ok
    assert list(out.accel_g) == pytest.approx([1.0, -0.5, 0.0], rel=1e-6)
    # the datasheet rounds the sensitivity (65.5 for 32768 / 500): allow that rounding
    assert list(out.gyro_rad_s) == pytest.approx([math.radians(100), math.radians(-10), 0.0], rel=1e-3, abs=1e-9)


def test_a_simulated_sample_reads_back_within_one_count():
    chip = Chip()
    assert chip.init()
    accel_in, gyro_in = (0.1, -0.2, 0.97), (0.5, -1.0, 2.0)
    chip.sim.sample(accel_in, gyro_in)
    ok, out = chip.read()
    assert ok
    g_lsb = 1 / ACCEL_LSB_PER_G[MODEL.accel_range_g]
    assert list(out.accel_g) == pytest.approx(accel_in, abs=g_lsb)
    assert list(out.gyro_rad_s) == pytest.approx(gyro_in, rel=1e-3, abs=1e-3)


def test_dlpf_is_a_setting_the_datasheet_offers_at_the_1khz_rate():
    """DLPF_CFG 0 (and 7) would switch the gyro output to 8 kHz and break SMPLRT_DIV."""
    cfg = dlpf_cfg_of_model()
    assert DLPF_TABLE[cfg][4] == 1000


def test_dlpf_puts_the_propeller_band_well_below_its_corner_without_lagging_a_tick():
    """Anti-aliasing before the 100 Hz sampling folds 57-97 Hz down to 3-43 Hz: the band's
    lower edge at least two corner frequencies up (both sensors, datasheet bandwidths),
    and the filter's delay within one sample period."""
    accel_bw, accel_delay_ms, gyro_bw, gyro_delay_ms, _ = DLPF_TABLE[dlpf_cfg_of_model()]
    assert PROPELLER_BAND_HZ[0] >= 2 * max(accel_bw, gyro_bw)
    assert max(accel_delay_ms, gyro_delay_ms) <= 1000 / MODEL.sample_rate


@pytest.mark.parametrize("cross", [None, [[0.0, 0.015, -0.02], [0.012, 0.0, 0.008], [-0.018, 0.019, 0.0]]],
                         ids=["no cross-axis", "cross-axis"])
def test_the_firmware_undoes_the_calibrated_bias_and_scale_and_starts_from_the_gyro_offset(cross):
    """The calibrated reading undone: the accelerometer's (counts / 8192 - bias) / scale; the
    gyro's rates solved from reading = diag(scale) (I + C) rate (numpy), the estimator's
    starting bias the offset solved the same way."""
    from uavarm.build import variants
    bias, scale, gyro_dps = [0.05, -0.03, 0.07], [1.02, 0.98, 1.01], [1.5, -2.0, 0.75]
    gyro_scale = [1.025, 0.97, 1.004]
    edits = {"imu.accel_bias": bias, "imu.accel_scale": scale, "imu.gyro_bias_dps": gyro_dps,
             "imu.gyro_scale": gyro_scale}
    if cross:
        edits["imu.gyro_cross_axis"] = cross
    v = variants.build(edits)
    reads = np.diag(gyro_scale) @ (np.eye(3) + np.array(cross or np.zeros((3, 3))))
    ffi, lib, m = v.ffi, v.lib, v.model
    hp = ffi.new("host_port_t *")
    lib.host_port_init(hp, m.servo_baud, m.imu_address)
    Mpu6050(memoryview(ffi.buffer(hp.imu_regs)))
    port = ffi.addressof(hp[0], "port")
    assert lib.mpu_init(port, m.imu_address)
    counts = [3000, -7000, 9500]                                 # what the chip reads (8192 counts/g)
    gyro_counts = [6550, -13100, 655]                            # 65.536 counts per deg/s at +-500
    words = counts + [0] + gyro_counts                           # temperature between
    hp.imu_regs[0x3B:0x3B + 14] = b"".join(w.to_bytes(2, "big", signed=True) for w in words)   # ACCEL_XOUT_H..
    hp.imu_regs[0x3A] = 0x01                                     # INT_STATUS: DATA_RDY
    out = ffi.new("mpu_sample_t *")
    assert lib.mpu_sample(port, m.imu_address, out)
    expected = [(c / 8192 - b) / s for c, b, s in zip(counts, bias, scale)]
    assert list(out.accel_g) == pytest.approx(expected, abs=2e-7)
    rates = np.linalg.solve(reads, np.radians(np.array(gyro_counts) / 65.536))
    assert list(out.gyro_rad_s) == pytest.approx(rates, rel=1e-6, abs=1e-7)
    stab = ffi.new("stab_t *")
    lib.stab_reset(stab)
    lib.stab_sample(stab, [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 0, False)
    # the offset as the calibrated rate reads it (mounting: identity)
    assert list(stab.quat.bias) == pytest.approx(np.linalg.solve(reads, np.radians(gyro_dps)), abs=1e-6)
