/* The stabiliser's arithmetic, one IMU sample at a time: scaled IMU sample -> generated
 * Butterworth filters -> complementary attitude -> target turned into the tilted base
 * frame -> generated IK and selection. No I/O: app.c feeds it and commands the servos. */
#ifndef STABILISER_H
#define STABILISER_H

#include <stdbool.h>

#include "estimator.h"
#include "filters.h"
#include "kinematics.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
typedef struct {
    filt_accel_t accel_filter[3];
    filt_gyro_t gyro_filter[3];
    est_attitude_t attitude;
    bool started;                  /* a first sample has set filters and attitude */
} stab_t;

void stab_reset(stab_t *s);
/* One sample: accelerometer in g, gyro in rad/s, both in the IMU's axes. The first sample
 * after a reset starts filters and attitude at rest on it. */
void stab_sample(stab_t *s, const float accel_g[3], const float gyro_rad_s[3]);
/* Joints that put the end effector on target_level (level frame, mm) at the current
 * attitude: the valid IK candidate nearest q_now. Writes q_out only when it returns KIN_OK;
 * otherwise returns why the best candidate was refused. */
kin_status_t stab_solve(const stab_t *s, const float target_level[3], const float q_now[3], float q_out[3]);
/* The same for a level base (no tilt): is target_level reachable at all? */
kin_status_t stab_solve_level(const float target_level[3], const float q_now[3], float q_out[3]);
/* The current estimate of the base's roll and pitch (rad), for telemetry and the simulator. */
void stab_attitude(const stab_t *s, float *roll, float *pitch);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* STABILISER_H */
