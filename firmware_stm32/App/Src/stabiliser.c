/* Filters, attitude and IK for one tick; see stabiliser.h. */
#include "stabiliser.h"

#include <string.h>

void stab_reset(stab_t *s)
{
    memset(s, 0, sizeof *s);
    est_set(&s->attitude, 0.0f, 0.0f);   /* level until the first sample */
}

void stab_sample(stab_t *s, const float accel_g[3], const float gyro_rad_s[3])
{
    float acc[3], gyro[3];
    if (!s->started) {
        for (int i = 0; i < 3; ++i) {
            filt_accel_reset(&s->accel_filter[i], accel_g[i]);
            filt_gyro_reset(&s->gyro_filter[i], gyro_rad_s[i]);
        }
        est_reset(&s->attitude, accel_g);
        s->started = true;
    }
    for (int i = 0; i < 3; ++i) {
        acc[i] = filt_accel_step(&s->accel_filter[i], accel_g[i]);
        gyro[i] = filt_gyro_step(&s->gyro_filter[i], gyro_rad_s[i]);
    }
    est_complementary_step(&s->attitude, acc, gyro);
}

/* The first refusal reason of the candidates, when none is valid: unreachable beats the
 * collision reasons only if every candidate is unreachable. */
static kin_status_t solve_base(const float p_base[3], const float q_now[3], float q_out[3])
{
    kin_ik_t ik;
    int k = kin_ik(p_base, q_now, &ik);
    if (k >= 0) {
        memcpy(q_out, ik.q[k], 3 * sizeof(float));
        return KIN_OK;
    }
    kin_status_t why = KIN_UNREACHABLE;
    for (int i = 0; i < KIN_CANDIDATES; ++i) {
        if (ik.status[i] != KIN_UNREACHABLE) {
            why = (kin_status_t)ik.status[i];
            break;
        }
    }
    return why;
}

kin_status_t stab_solve(const stab_t *s, const float target_level[3], const float q_now[3], float q_out[3])
{
    float p_base[3];
    est_level_to_base(&s->attitude, target_level, p_base);
    return solve_base(p_base, q_now, q_out);
}

kin_status_t stab_solve_level(const float target_level[3], const float q_now[3], float q_out[3])
{
    return solve_base(target_level, q_now, q_out);
}

void stab_attitude(const stab_t *s, float *roll, float *pitch)
{
    *roll = s->attitude.roll;
    *pitch = s->attitude.pitch;
}
