/* MPU-6000/6050 over the port's I2C functions: set-up from the model file and the 14-byte
 * sample burst (register map: InvenSense RM-MPU-6000A rev 4.2). */
#ifndef IMU_MPU6050_H
#define IMU_MPU6050_H

#include <stdbool.h>
#include <stdint.h>

#include "port.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define MPU_REG_SMPLRT_DIV 25
#define MPU_REG_CONFIG 26
#define MPU_REG_GYRO_CONFIG 27
#define MPU_REG_ACCEL_CONFIG 28
#define MPU_REG_INT_ENABLE 56
#define MPU_REG_INT_STATUS 58       /* DATA_RDY_INT (bit 0): a new sample; cleared by reading it */
#define MPU_REG_ACCEL_XOUT_H 59     /* accel x, y, z, temperature, gyro x, y, z: big-endian int16 */
#define MPU_REG_PWR_MGMT_1 107
#define MPU_REG_WHO_AM_I 117
#define MPU_WHO_AM_I 104            /* 0x68 whatever the AD0 pin says */
#define MPU_SAMPLE_BYTES 14
#define MPU_INT_DATA_RDY 1u
#define MPU_BURST_BYTES 15          /* INT_STATUS and the sample, one transfer */

/* One burst, decoded and scaled (mpu_sample). */
typedef struct {
    float accel_g[3];               /* counts x the range / 32768, calibrated (the model file), IMU axes */
    float gyro_rad_s[3];
    bool fresh;                     /* DATA_RDY was set: the chip latched a sample since the last read */
    bool saturated;                 /* an accelerometer or gyro axis at -32768 or 32767 counts: the
                                       true value may be beyond it */
    uint8_t burst[MPU_BURST_BYTES]; /* the registers as read, INT_STATUS .. GYRO_ZOUT_L */
} mpu_sample_t;

/* Checks WHO_AM_I, wakes the chip on the gyro-X PLL clock, and writes sample rate divider,
 * digital low-pass, ranges and the data-ready interrupt from the model file, then reads
 * them back. False if the chip did not answer or a setting did not stick. */
bool mpu_init(const port_t *port, uint8_t address);
/* One 15-byte burst from INT_STATUS: the data-ready flag (which the read clears) and the
 * sample, scaled to g and rad/s with the model's ranges, and whether an axis is at full
 * scale. False on a bus error. A chip that stops sampling (asleep after a brown-out, hung)
 * still answers, with fresh = false. */
bool mpu_sample(const port_t *port, uint8_t address, mpu_sample_t *out);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* IMU_MPU6050_H */
