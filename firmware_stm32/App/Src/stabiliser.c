/* Filters, attitude, drone-attitude fusion and IK for one tick; see stabiliser.h. */
#include "stabiliser.h"

#include <math.h>
#include <string.h>

#include "fastmath.h"
#include "model_params.h"

/* The history must cover the longest accepted link delay (model/config.py checks it too). */
typedef char stab_history_fits[(MODEL_LINK_HISTORY <= STAB_HISTORY) ? 1 : -1];

/* The clocks' offset estimate may rise by this much per accepted message, so that it follows
 * a drone clock running slower than ours (100 ppm at 50 messages/s). */
#define LINK_OFFSET_CREEP_US 2u

void stab_reset(stab_t *s)
{
    memset(s, 0, sizeof *s);
    est_set(&s->attitude, 0.0f, 0.0f);   /* level until the first sample */
    s->quat.q[0] = 1.0f;
    s->up[2] = 1.0f;
}

#if MODEL_ESTIMATOR_QUATERNION
static void remember(stab_t *s, uint32_t now_us)
{
    memcpy(s->hist_q[s->hist_next], s->quat.q, sizeof s->quat.q);
    s->hist_us[s->hist_next] = now_us;
    s->hist_next = (uint8_t)(s->hist_next + 1u < MODEL_LINK_HISTORY ? s->hist_next + 1u : 0u);   /* (no division) */
    if (s->hist_len < MODEL_LINK_HISTORY) s->hist_len++;
}
#endif

bool stab_link_fresh(const stab_t *s, uint32_t now_us)
{
    return MODEL_DRONE_ATTITUDE && s->link_valid && now_us - s->link_accepted_us < MODEL_LINK_TIMEOUT_US;
}

/* The first sample after a reset: filters and attitude at rest on it. Not inlined: the
 * per-sample path then needs fewer registers saved. */
static __attribute__((noinline)) void start(stab_t *s, const float accel_g[3], const float gyro_rad_s[3])
{
    for (int i = 0; i < 3; ++i) {
        filt_accel_reset(&s->accel_filter[i], accel_g[i]);
        filt_gyro_reset(&s->gyro_filter[i], gyro_rad_s[i]);
    }
    est_reset(&s->attitude, accel_g);
    est_quat_reset(&s->quat, accel_g);
    s->quat.bias[0] = MODEL_GYRO_BIAS0_X;   /* the model file's calibration; learnt on at rest */
    s->quat.bias[1] = MODEL_GYRO_BIAS0_Y;
    s->quat.bias[2] = MODEL_GYRO_BIAS0_Z;
    s->started = true;
}

/* The time since the previous sample (s): measured, as the IMU's own clock may run a few
 * percent off the tick's (a sample then repeats, and the next one covers twice the time);
 * at most STAB_DT_MAX_PERIODS periods (after a gap, the attitude holds what it had). */
static inline float sample_dt(stab_t *s, uint32_t now_us)
{
    uint32_t us = now_us - s->last_sample_us;
    s->last_sample_us = now_us;
    if (us > MODEL_TICK_US + MODEL_TICK_US / 2u) {   /* a tick or more without a sample, or the first */
        if (s->samples > 1u) s->gaps++;
        if (s->samples <= 1u) us = MODEL_TICK_US;
        else if (us > STAB_DT_MAX_PERIODS * MODEL_TICK_US) us = STAB_DT_MAX_PERIODS * MODEL_TICK_US;
    }
    return (float)us * 1e-6f;
}

#if MODEL_ESTIMATOR_QUATERNION
/* Not engaged, the quaternion estimator's gyro bias is also measured directly: the mean
 * gyro over every STILL_SAMPLES samples (one second) in which no gyro axis spread more than
 * STILL_GYRO_SPREAD (rad/s) and no accelerometer axis more than STILL_ACCEL_SPREAD (g)
 * between its highest and lowest reading. The MPU-6050 at rest spreads about 0.1 deg/s and
 * 15 mg (6 sigma of its noise through the 21 Hz DLPF); a hand on the drone, or its props
 * turning, far more. The window restarts at every sample that spreads it too far; its mean
 * gyro, turned into base axes, is the bias, and its mean specific force the up direction
 * (the attitude levelled on it: no error left standing for the bias to chase). */
#define STILL_SAMPLES 100u
#define STILL_GYRO_SPREAD 0.0087f     /* 0.5 deg/s */
#define STILL_ACCEL_SPREAD 0.03f
static __attribute__((noinline)) void bias_at_rest(stab_t *s, const float accel_g[3], const float gyro_rad_s[3])
{
    static const float ZERO[3] = { 0.0f, 0.0f, 0.0f };
    const float v[6] = { gyro_rad_s[0], gyro_rad_s[1], gyro_rad_s[2], accel_g[0], accel_g[1], accel_g[2] };
    bool still = s->still_n > 0u;
    for (int i = 0; i < 6; ++i) {
        s->still_lo[i] = fminf(s->still_lo[i], v[i]);
        s->still_hi[i] = fmaxf(s->still_hi[i], v[i]);
        still = still && s->still_hi[i] - s->still_lo[i] <= (i < 3 ? STILL_GYRO_SPREAD : STILL_ACCEL_SPREAD);
    }
    if (!still) {   /* a window starts at this sample */
        s->still_n = 0u;
        memset(s->still_sum, 0, sizeof s->still_sum);
        memcpy(s->still_lo, v, sizeof v);
        memcpy(s->still_hi, v, sizeof v);
    }
    for (int i = 0; i < 6; ++i) s->still_sum[i] += v[i];
    if (++s->still_n == STILL_SAMPLES) {
        float mean[6], base[3];
        for (int i = 0; i < 6; ++i) mean[i] = s->still_sum[i] * (1.0f / (float)STILL_SAMPLES);
        est_quat_reset(&s->quat, &mean[3]);              /* level on the mean up, bias zero */
        est_rate(mean, ZERO, base);                      /* the mean gyro in base axes */
        for (int i = 0; i < 3; ++i) base[i] = -base[i];
        est_bias_update(s->quat.bias, base, 1.0f);       /* bias = that mean, within the model's clamp */
        s->still_n = 0u;
    }
}
#endif

void stab_sample(stab_t *s, const float accel_g[3], const float gyro_rad_s[3], uint32_t now_us, bool engaged)
{
    float acc[3];
    if (!s->started) start(s, accel_g, gyro_rad_s);
    if (s->samples < UINT32_MAX) s->samples++;
    const float dt = sample_dt(s, now_us);
    filt_accel_step3(s->accel_filter, accel_g, acc);
#if MODEL_ESTIMATOR_QUATERNION
    if (engaged) s->still_n = 0u;   /* a window starts afresh after a flight */
    else bias_at_rest(s, accel_g, gyro_rad_s);
    /* The raw gyro is integrated (no filter delay); the chip's DLPF keeps it from aliasing. */
    if (stab_link_fresh(s, now_us)) {
        est_quat_step(&s->quat, acc, gyro_rad_s, 0.0f, 0.0f, 0.0f, dt, s->up);   /* the drone's attitude corrects */
    } else if (engaged) {
        est_quat_step(&s->quat, acc, gyro_rad_s, MODEL_EST_ACCEL_GAIN, MODEL_EST_BIAS_GAIN, MODEL_EST_INNOVATION_SCALE,
                      dt, s->up);
    } else {
        est_quat_step(&s->quat, acc, gyro_rad_s, MODEL_EST_ALIGN_ACCEL_GAIN, MODEL_EST_ALIGN_BIAS_GAIN, 0.0f, dt, s->up);
    }
    memcpy(s->rate, s->quat.rate, sizeof s->rate);
    if (MODEL_DRONE_ATTITUDE) remember(s, now_us);
#else
    static const float no_bias[3] = { 0.0f, 0.0f, 0.0f };
    float gyro[3];
    (void)engaged;
    for (int i = 0; i < 3; ++i) gyro[i] = filt_gyro_step(&s->gyro_filter[i], gyro_rad_s[i]);
    est_complementary_step(&s->attitude, acc, gyro, dt);
    est_attitude_up(&s->attitude, s->up);
    est_rate(gyro, no_bias, s->rate);
#endif
}

static void normalise4(float q[4])
{
    const float inv = 1.0f / sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; ++i) q[i] *= inv;
}

/* The estimate's attitude at local time t (interpolated between samples, extrapolated past
 * the last one); false if t is older than the history. */
static bool attitude_at(const stab_t *s, uint32_t t, float q[4])
{
    unsigned newer = MODEL_LINK_HISTORY;   /* none yet */
    for (unsigned n = 0; n < s->hist_len; ++n) {
        const unsigned k = (s->hist_next + MODEL_LINK_HISTORY - 1u - n) % MODEL_LINK_HISTORY;
        const int32_t ahead = (int32_t)(t - s->hist_us[k]);
        if (ahead >= 0) {
            if (newer == MODEL_LINK_HISTORY) {
                /* after the last sample: ahead along its rate, q (x) (1, w dt / 2) */
                const float h = 0.5e-6f * (float)ahead;
                const float *p = s->hist_q[k], *w = s->quat.rate;
                const float d[4] = { 1.0f, w[0] * h, w[1] * h, w[2] * h };
                q[0] = p[0] * d[0] - p[1] * d[1] - p[2] * d[2] - p[3] * d[3];
                q[1] = p[0] * d[1] + p[1] * d[0] + p[2] * d[3] - p[3] * d[2];
                q[2] = p[0] * d[2] - p[1] * d[3] + p[2] * d[0] + p[3] * d[1];
                q[3] = p[0] * d[3] + p[1] * d[2] - p[2] * d[1] + p[3] * d[0];
                normalise4(q);
                return true;
            }
            const float f = (float)ahead / (float)(s->hist_us[newer] - s->hist_us[k]);
            for (int i = 0; i < 4; ++i) q[i] = s->hist_q[k][i] + f * (s->hist_q[newer][i] - s->hist_q[k][i]);
            normalise4(q);
            return true;
        }
        newer = k;
    }
    return false;
}

stab_link_status_t stab_drone_attitude(stab_t *s, uint16_t seq, uint32_t stamp_us, float roll, float pitch,
                                       uint32_t now_us)
{
    stab_link_status_t why = STAB_LINK_ACCEPTED;
    const bool fresh = stab_link_fresh(s, now_us);
    float q_then[4], c[4], err[3];
    if (!MODEL_DRONE_ATTITUDE || !MODEL_ESTIMATOR_QUATERNION) {
        why = STAB_LINK_OFF;
    } else if (!(fabsf(roll) <= 3.1415927f && fabsf(pitch) <= 1.5707964f)) {   /* NaN fails too */
        why = STAB_LINK_NOT_FINITE;
    } else if (fresh && ((int16_t)(uint16_t)(seq - s->link_seq) <= 0
                         || (int32_t)(stamp_us - s->link_stamp_us) <= 0)) {
        why = STAB_LINK_OUT_OF_ORDER;   /* after a silence a restarted sender is taken again */
    }
    if (why != STAB_LINK_ACCEPTED) {
        s->link_refused++;
        return why;
    }
    /* Delay: arrival - stamp is the clocks' offset plus the delay; its smallest value is the
     * offset plus the link's smallest delay (from the model). */
    const uint32_t arrival = now_us - stamp_us;
    uint32_t offset = fresh ? s->link_offset_us + LINK_OFFSET_CREEP_US : arrival;
    if ((int32_t)(arrival - offset) < 0) offset = arrival;
    const uint32_t delay = arrival - offset + MODEL_LINK_DELAY_MIN_US;
    if (delay > MODEL_LINK_DELAY_MAX_US || !attitude_at(s, now_us - delay, q_then)) {
        s->link_refused++;
        return STAB_LINK_STALE;
    }
    est_link_error(q_then, roll, pitch, MODEL_LINK_GAIN, c, err);
    if (!(c[0] > 1e-6f)) {   /* c[0] = 1 + cos(disagreement): ~180 deg has no rotation axis */
        s->link_refused++;
        return STAB_LINK_OPPOSITE;
    }
    est_quat_rotate_left(c, s->quat.q);
    /* the history takes the same level-frame correction: the next message compares with it */
    for (unsigned n = 0; n < s->hist_len; ++n) est_quat_rotate_left(c, s->hist_q[n]);
    /* the error left after each correction is (bias error) x (message period) / link_gain, so
     * this moves the bias at link_bias_gain / link_gain per second, whatever the message rate */
    est_bias_update(s->quat.bias, err, MODEL_LINK_BIAS_GAIN);
    est_quat_up(s->quat.q, s->up);
    s->link_valid = true;
    s->link_seq = seq;
    s->link_stamp_us = stamp_us;
    s->link_accepted_us = now_us;
    s->link_offset_us = offset;
    s->link_delay_us = delay;
    s->link_accepted++;
    return STAB_LINK_ACCEPTED;
}

void stab_attitude(const stab_t *s, float *roll, float *pitch)
{
    *roll = fm_atan2f(s->up[1], s->up[2]);
    *pitch = fm_atan2f(-s->up[0], sqrtf(s->up[1] * s->up[1] + s->up[2] * s->up[2]));
}

void stab_command_point(const stab_t *s, const float target_level[3], float p_base[3])
{
    est_command_point(s->up, s->rate, target_level, p_base);
}
