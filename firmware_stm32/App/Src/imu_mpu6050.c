/* MPU-6000/6050 set-up and sampling; see imu_mpu6050.h. */
#include "imu_mpu6050.h"

#include "model_params.h"

#define PWR_CLOCK_PLL_GYRO_X 1u     /* SLEEP cleared, CLKSEL = 1 */

static const uint8_t SETTINGS[][2] = {
    { MPU_REG_SMPLRT_DIV, MODEL_MPU_SMPLRT_DIV },
    { MPU_REG_CONFIG, MODEL_MPU_DLPF_CFG },
    { MPU_REG_GYRO_CONFIG, MODEL_MPU_GYRO_FS_SEL << 3 },
    { MPU_REG_ACCEL_CONFIG, MODEL_MPU_ACCEL_FS_SEL << 3 },
    { MPU_REG_INT_ENABLE, MPU_INT_DATA_RDY },
};
#define N_SETTINGS (sizeof SETTINGS / sizeof SETTINGS[0])

bool mpu_init(const port_t *port, uint8_t address)
{
    uint8_t who = 0;
    if (!port->imu_read(port->ctx, address, MPU_REG_WHO_AM_I, &who, 1) || who != MPU_WHO_AM_I) {
        return false;
    }
    if (!port->imu_write(port->ctx, address, MPU_REG_PWR_MGMT_1, PWR_CLOCK_PLL_GYRO_X)) {
        return false;
    }
    for (unsigned i = 0; i < N_SETTINGS; ++i) {
        uint8_t back = 0;
        if (!port->imu_write(port->ctx, address, SETTINGS[i][0], SETTINGS[i][1])
            || !port->imu_read(port->ctx, address, SETTINGS[i][0], &back, 1)
            || back != SETTINGS[i][1]) {
            return false;
        }
    }
    return true;
}

static int32_t be16(const uint8_t *b)
{
    return (int16_t)(uint16_t)((uint16_t)b[0] << 8 | b[1]);
}

/* At full scale, -32768 or 32767 counts, the true value may be beyond it: exactly the v for
 * which v + 32767, taken unsigned, is 65534 or more (one compare). */
static uint32_t full_scale(int32_t v)
{
    return (uint32_t)(v + 32767) >= 65534u;
}

bool mpu_sample(const port_t *port, uint8_t address, mpu_sample_t *out)
{
    const uint8_t *burst = out->burst;
    if (!port->imu_read(port->ctx, address, MPU_REG_INT_STATUS, out->burst, sizeof out->burst)) {
        return false;
    }
    /* accel x, y, z, temperature, gyro x, y, z: the six axes written out, each read once */
    const uint8_t *b = burst + (MPU_REG_ACCEL_XOUT_H - MPU_REG_INT_STATUS);
    const int32_t ax = be16(b), ay = be16(b + 2), az = be16(b + 4);
    const int32_t gx = be16(b + 8), gy = be16(b + 10), gz = be16(b + 12);
    out->accel_g[0] = (float)ax * MODEL_ACCEL_K_X + MODEL_ACCEL_C_X;   /* calibrated (model file) */
    out->accel_g[1] = (float)ay * MODEL_ACCEL_K_Y + MODEL_ACCEL_C_Y;
    out->accel_g[2] = (float)az * MODEL_ACCEL_K_Z + MODEL_ACCEL_C_Z;
#if MODEL_GYRO_CROSS_AXIS
    static const float W[3][3] = { { MODEL_GYRO_W_X }, { MODEL_GYRO_W_Y }, { MODEL_GYRO_W_Z } };
    const float x = (float)gx, y = (float)gy, z = (float)gz;
    for (int i = 0; i < 3; ++i) out->gyro_rad_s[i] = W[i][0] * x + W[i][1] * y + W[i][2] * z;
#else
    out->gyro_rad_s[0] = (float)gx * MODEL_GYRO_K_X;
    out->gyro_rad_s[1] = (float)gy * MODEL_GYRO_K_Y;
    out->gyro_rad_s[2] = (float)gz * MODEL_GYRO_K_Z;
#endif
    out->fresh = (burst[0] & MPU_INT_DATA_RDY) != 0u;
    /* (| rather than ||: no branch per axis) */
    out->saturated = (full_scale(ax) | full_scale(ay) | full_scale(az)
                      | full_scale(gx) | full_scale(gy) | full_scale(gz)) != 0u;
    return true;
}
