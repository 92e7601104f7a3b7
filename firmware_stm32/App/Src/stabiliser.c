/* Filters, attitude, drone-attitude fusion and IK for one tick; see stabiliser.h. */
#include "stabiliser.h"

#include <math.h>
#include <string.h>

#include "fastmath.h"
#include "messages.h"
#include "model_params.h"

/* The history must cover the longest accepted link delay (model/config.py checks it too). */
typedef char stab_history_fits[(MODEL_LINK_HISTORY <= STAB_HISTORY) ? 1 : -1];

/* The clocks' offset estimate may rise by this much per accepted message, so that it follows
 * a drone clock running slower than ours (100 ppm at 50 messages/s). */
#define LINK_OFFSET_CREEP_US 2u
/* A stream's stamps may run ahead of the board's clock by the link's jitter (a message delayed
 * link_delay_max, then one delayed link_delay_min) plus the clocks' drift: 1/5000 (200 ppm). */
#define LINK_JITTER_US (MODEL_LINK_DELAY_MAX_US - MODEL_LINK_DELAY_MIN_US)
#define CLOCK_DRIFT_DIVISOR 5000u

#define VELOCITY_MAX 50.0f    /* m/s: a larger component is refused */
/* m/s: a larger step from one message to the next restarts the velocity estimate: no flight
 * changes its velocity so fast, and an odometry's noise (0.3 m/s white at most) steps that far
 * once in hours */
#define VELOCITY_JUMP 2.0f

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
    if (MODEL_DRONE_VELOCITY) memcpy(s->hist_v[s->hist_next], s->velocity.v, sizeof s->velocity.v);
    s->hist_us[s->hist_next] = now_us;
    s->hist_next = (uint8_t)(s->hist_next + 1u < MODEL_LINK_HISTORY ? s->hist_next + 1u : 0u);   /* (no division) */
    if (s->hist_len < MODEL_LINK_HISTORY) s->hist_len++;
}
#endif

static bool stream_fresh(const stab_stream_t *st, uint32_t now_us)
{
    return st->valid && now_us - st->accepted_us < MODEL_LINK_TIMEOUT_US;
}

bool stab_link_fresh(const stab_t *s, uint32_t now_us)
{
    return MODEL_DRONE_ATTITUDE && stream_fresh(&s->link, now_us);
}

bool stab_velocity_fresh(const stab_t *s, uint32_t now_us)
{
    return MODEL_DRONE_VELOCITY && stream_fresh(&s->vel, now_us);
}

/* Is the stream's timing still the last heard message's (the next one is checked against it)?
 * While messages keep arriving (refused ones too) within the link timeout, for up to
 * reject_after + retake_after without one heard: then a sender whose clock jumped is heard
 * again from scratch, as after a silence. */
#define TIMING_KEPT_US (MODEL_REJECT_AFTER_US + MODEL_RETAKE_AFTER_US)
static bool heard_lately(const stab_stream_t *st, uint32_t now_us)
{
    return st->heard && now_us - st->arrived_us < MODEL_LINK_TIMEOUT_US && now_us - st->heard_us < TIMING_KEPT_US;
}

uint8_t stab_sources(const stab_t *s, uint32_t now_us)
{
    const bool attitude = stab_link_fresh(s, now_us), velocity = stab_velocity_fresh(s, now_us);
    return (uint8_t)((attitude || velocity ? 0u : MSG_SOURCE_ACCELEROMETER) | (attitude ? MSG_SOURCE_DRONE_ATTITUDE : 0u)
                     | (velocity ? MSG_SOURCE_DRONE_VELOCITY : 0u));
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
 * gyro, turned into base axes, is the bias, and its mean specific force, less the
 * accelerometer's bias learnt so far, the up direction (the attitude levelled on it: no
 * error left standing for the gyro's bias to chase, and the split's turns kept). */
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
        for (int i = 0; i < 3; ++i) mean[3 + i] -= s->velocity.accel_bias[i];
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
    s->engaged = engaged;
#if MODEL_ESTIMATOR_QUATERNION
    if (engaged) s->still_n = 0u;   /* a window starts afresh after a flight */
    else bias_at_rest(s, accel_g, gyro_rad_s);
    /* The raw gyro is integrated (no filter delay); the chip's DLPF keeps it from aliasing. */
    const bool aided = stab_velocity_fresh(s, now_us);
    /* the IMU's velocity is integrated while the drone's is heard, fused or not: the gate
     * compares the two */
    const bool tracked = aided || (MODEL_DRONE_VELOCITY && heard_lately(&s->vel, now_us));
    if (stab_link_fresh(s, now_us) || aided) {
        est_quat_propagate(&s->quat, gyro_rad_s, dt, s->up);   /* the drone's messages correct */
        s->accel_idle = true;   /* (the filtered accelerometer is not used meanwhile) */
    } else {
        if (s->accel_idle) {    /* its filter starts again at rest on this sample */
            for (int i = 0; i < 3; ++i) filt_accel_reset(&s->accel_filter[i], accel_g[i]);
            s->accel_idle = false;
        }
        filt_accel_step3(s->accel_filter, accel_g, acc);
        if (engaged) {
            est_quat_step(&s->quat, acc, gyro_rad_s, MODEL_EST_ACCEL_GAIN, MODEL_EST_BIAS_GAIN, MODEL_EST_INNOVATION_SCALE,
                          dt, s->up);
        } else {
            est_quat_step(&s->quat, acc, gyro_rad_s, MODEL_EST_ALIGN_ACCEL_GAIN, MODEL_EST_ALIGN_BIAS_GAIN, 0.0f, dt, s->up);
        }
    }
    memcpy(s->rate, s->quat.rate, sizeof s->rate);
    /* the raw specific force: the chip's DLPF is filter enough for an integral */
    if (tracked) est_vel_predict(&s->velocity, accel_g, s->up, s->rate, dt);
    if (MODEL_DRONE_ATTITUDE || MODEL_DRONE_VELOCITY) remember(s, now_us);
#else
    static const float no_bias[3] = { 0.0f, 0.0f, 0.0f };
    float gyro[3];
    (void)engaged;
    filt_accel_step3(s->accel_filter, accel_g, acc);
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

/* The estimate's attitude (and velocity) at local time t: interpolated between samples,
 * extrapolated past the last one; false if t is older than the history. */
static bool history_at(const stab_t *s, uint32_t t, float q[4], float v[3])
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
                memcpy(v, s->hist_v[k], sizeof s->hist_v[k]);
                normalise4(q);
                return true;
            }
            const float f = (float)ahead / (float)(s->hist_us[newer] - s->hist_us[k]);
            for (int i = 0; i < 4; ++i) q[i] = s->hist_q[k][i] + f * (s->hist_q[newer][i] - s->hist_q[k][i]);
            for (int i = 0; i < 3; ++i) v[i] = s->hist_v[k][i] + f * (s->hist_v[newer][i] - s->hist_v[k][i]);
            normalise4(q);
            return true;
        }
        newer = k;
    }
    return false;
}

/* The timing of a message of stream st, heard lately (fresh) or not: refused if not newer than
 * the last one heard, delayed beyond the model's link_delay_max, or stamped ahead of the board's
 * clock. Delay: arrival - stamp is the clocks' offset plus the delay; its smallest value is the
 * offset plus the link's smallest delay (from the model). The floor under arrival - stamp is
 * set when the stream starts, a jitter below the first one, and falls only at the clocks'
 * drift: stamps that advance faster than the board's clock (several messages' worth in one
 * tick) are refused however small each step. */
typedef struct {
    uint32_t offset, floor, delay;
} timing_t;

static stab_link_status_t admit(const stab_stream_t *st, bool fresh, uint16_t seq, uint32_t stamp_us,
                                uint32_t now_us, timing_t *tm)
{
    if (fresh && ((int16_t)(uint16_t)(seq - st->seq) <= 0 || (int32_t)(stamp_us - st->stamp_us) <= 0)) {
        return STAB_LINK_OUT_OF_ORDER;   /* after a silence a restarted sender is taken again */
    }
    const uint32_t arrival = now_us - stamp_us;
    if (fresh) {
        tm->floor = st->floor_us - (now_us - st->heard_us) / CLOCK_DRIFT_DIVISOR;
        if ((int32_t)(arrival - tm->floor) < 0) return STAB_LINK_AHEAD;   /* (the caller distrusts it) */
    }
    tm->offset = fresh ? st->offset_us + LINK_OFFSET_CREEP_US : arrival;
    if ((int32_t)(arrival - tm->offset) < 0) tm->offset = arrival;
    /* the floor rises with the offset (a drone clock running slow), never falls with it */
    if (!fresh || (int32_t)(tm->offset - LINK_JITTER_US - tm->floor) > 0) tm->floor = tm->offset - LINK_JITTER_US;
    tm->delay = arrival - tm->offset + MODEL_LINK_DELAY_MIN_US;
    return tm->delay > MODEL_LINK_DELAY_MAX_US ? STAB_LINK_STALE : STAB_LINK_ACCEPTED;
}

/* A message of good timing: the stream's timing moves on to it, whatever the gate says. After
 * a silence the gate's count of refusals (not a drop) starts again. */
static void hear(stab_stream_t *st, bool fresh, uint16_t seq, uint32_t stamp_us, uint32_t now_us, const timing_t *tm)
{
    if (!fresh) st->refusing = st->agreeing = false;
    st->heard = true;
    st->seq = seq;
    st->stamp_us = stamp_us;
    st->heard_us = now_us;
    st->offset_us = tm->offset;
    st->floor_us = tm->floor;
    st->delay_us = tm->delay;
}

static void take(stab_stream_t *st, uint32_t now_us)
{
    st->valid = true;
    st->accepted_us = now_us;
    st->accepted++;
}

/* The gate's verdict on a heard message that agrees with the estimate or not: ACCEPTED to fuse
 * it, else why not. A stream refused (by the gate, or for stamps ahead of the board's clock)
 * for reject_after is dropped; a dropped one is taken back once it has agreed for
 * retake_after. */
static void distrust(stab_stream_t *st, uint32_t now_us)
{
    st->agreeing = false;
    if (!st->refusing) {
        st->refusing = true;
        st->refusing_us = now_us;
    }
    if (!st->rejected && now_us - st->refusing_us >= MODEL_REJECT_AFTER_US) {
        st->rejected = true;
        st->rejections++;
    }
}

static stab_link_status_t judge(stab_stream_t *st, bool agrees, uint32_t now_us)
{
    if (!agrees) {
        distrust(st, now_us);
        st->disagreed++;
        return STAB_LINK_DISAGREES;
    }
    st->refusing = false;
    if (!st->rejected) return STAB_LINK_ACCEPTED;
    if (!st->agreeing) {
        st->agreeing = true;
        st->agreeing_us = now_us;
    }
    if (now_us - st->agreeing_us < MODEL_RETAKE_AFTER_US) return STAB_LINK_REJECTED;
    st->rejected = st->agreeing = false;
    return STAB_LINK_ACCEPTED;
}

/* gate_sigmas times how far the tilt may be off: what the last correction by a drone message
 * left, and how far it may have drifted since (rad). (After 71 minutes without one the
 * microsecond count wraps and the gate narrows: it refuses more, never less.) */
static float drift_gate(const stab_t *s, uint32_t now_us)
{
    if (!s->corrected) return MODEL_GATE_DRIFT_MAX;
    return fminf(s->doubt + (float)(now_us - s->corrected_us) * MODEL_GATE_DRIFT_PER_US, MODEL_GATE_DRIFT_MAX);
}

/* A drone message corrected the attitude at now_us, leaving a disagreement of about left (rad). */
static void corrected(stab_t *s, uint32_t now_us, float left)
{
    s->corrected = true;
    s->corrected_us = now_us;
    s->doubt = MODEL_GATE_SIGMAS * left;
}

static stab_link_status_t refuse(stab_stream_t *st, stab_link_status_t why)
{
    st->refused++;
    return why;
}

/* The disagreement of the drone's attitude with the estimate, while the velocity is fused, is
 * split between the flight controller's error (fc_error, its own estimate then, which the
 * velocity's turns leave alone) and the accelerometer's bias; or, with no gain for the bias,
 * all of it the flight controller's (fc_error following every turn of the estimate). */
#define SPLIT (MODEL_ACCEL_BIAS_ATTITUDE_GAIN > 0.0f)

/* The split's gains from a Kalman filter (velocity.py), when the model states the bias it
 * expects; else the fixed gains. */
#define SPLIT_KALMAN (MODEL_SPLIT_BIAS_VAR > 0.0f)

/* One message's split by the Kalman filter of x = (the estimate's tilt error, fc_error's
 * error) per base axis, measured as err = x1 - x0 + white: x0 the bias's tilt (prior
 * accel_bias_prior_g, a random walk of accel_bias_walk_g a minute), x1 first-order Markov
 * (fc_error_deg over fc_error_tau), white drone_attitude_white_deg (est_split_step, from
 * velocity.py). Out: the estimate's turn and fc_error's move (with its fading over the h s
 * since the last message). */
static void split_by_kalman(stab_t *s, float h, const float err[3], float turn[3], float learn[3])
{
    if (!s->split_started) {
        for (int i = 0; i < 3; ++i) {
            s->split_p[i][0] = MODEL_SPLIT_BIAS_VAR;
            s->split_p[i][1] = 0.0f;
            s->split_p[i][2] = MODEL_SPLIT_FC_VAR;
        }
        s->split_started = true;
    }
    for (int i = 0; i < 3; ++i) est_split_step(s->split_p[i], h, err[i], s->fc_error[i], &turn[i], &learn[i]);
}

/* fc_error += delta, within +-fc_error_max_deg per axis. */
static void move_fc_error(stab_t *s, const float delta[3])
{
    for (int i = 0; i < 3; ++i) {
        s->fc_error[i] = fminf(MODEL_FC_ERROR_MAX, fmaxf(-MODEL_FC_ERROR_MAX, s->fc_error[i] + delta[i]));
    }
}

stab_link_status_t stab_drone_attitude(stab_t *s, uint16_t seq, uint32_t stamp_us, float roll, float pitch,
                                       uint32_t now_us)
{
    const bool fresh = stab_link_fresh(s, now_us), heard = heard_lately(&s->link, now_us);
    const uint32_t last_stamp = s->link.stamp_us;
    timing_t tm = { 0u, 0u, 0u };
    float q_then[4], v_then[3], c[4], err[3];
    if (!MODEL_DRONE_ATTITUDE || !MODEL_ESTIMATOR_QUATERNION) return refuse(&s->link, STAB_LINK_OFF);
    if (!(fabsf(roll) <= 3.1415927f && fabsf(pitch) <= 1.5707964f)) {   /* NaN fails too */
        return refuse(&s->link, STAB_LINK_NOT_FINITE);
    }
    s->link.arrived_us = now_us;
    stab_link_status_t why = admit(&s->link, heard, seq, stamp_us, now_us, &tm);
    if (why == STAB_LINK_AHEAD) distrust(&s->link, now_us);
    if (why == STAB_LINK_ACCEPTED && !history_at(s, now_us - tm.delay, q_then, v_then)) why = STAB_LINK_STALE;
    if (why != STAB_LINK_ACCEPTED) return refuse(&s->link, why);
    /* the whole correction (gain 1), scaled below: c = (1 + cos, k (axis sin)) is linear in k */
    est_link_error(q_then, roll, pitch, s->fc_error, 1.0f, c, err);
    if (!(c[0] > 1e-6f)) {   /* c[0] = 1 + cos(disagreement): ~180 deg has no rotation axis */
        return refuse(&s->link, STAB_LINK_OPPOSITE);
    }
    hear(&s->link, heard, seq, stamp_us, now_us, &tm);
    /* The gate: |err| is the sine of the disagreement (under 90 deg: c[0] > 1), against
     * gate_sigmas x hypot(the flight controller's spread, the estimate's drift) */
    const float sin2 = err[0] * err[0] + err[1] * err[1] + err[2] * err[2];
    const float drift = drift_gate(s, now_us);
    /* (the loader keeps it under 45 deg, where this series for its sine is 0.4 % low) */
    const float gate = sqrtf(MODEL_GATE_ATTITUDE * MODEL_GATE_ATTITUDE + drift * drift);
    const float sin_gate = gate * (1.0f - gate * gate * (1.0f / 6.0f));
    why = judge(&s->link, c[0] > 1.0f && sin2 <= sin_gate * sin_gate, now_us);
    if (why != STAB_LINK_ACCEPTED) return refuse(&s->link, why);
    /* with the velocity fresh too, the drone's attitude corrects with gains of their own (none
     * by default: velocity and gyro do better) and teaches fc_error what it disagrees by. The
     * gain is per message, so messages closer than a tick share one (several in a tick do
     * what one does), and one message turns the estimate by at most correction_max_deg. */
    const bool aided = stab_velocity_fresh(s, now_us);
    float k = aided ? MODEL_LINK_GAIN_WITH_VELOCITY : MODEL_LINK_GAIN;
    if (heard) k *= fminf((float)(stamp_us - last_stamp) * (1.0f / (float)MODEL_TICK_US), 1.0f);
    if (k * k * sin2 > MODEL_CORRECTION_MAX_SIN * MODEL_CORRECTION_MAX_SIN) k = MODEL_CORRECTION_MAX_SIN / sqrtf(sin2);
    c[1] *= k;
    c[2] *= k;
    const float left = (1.0f - k) * sqrtf(sin2);   /* (sin ~ angle within the gate) */
    est_quat_rotate_left(c, s->quat.q);
    /* the history takes the same level-frame correction: the next message compares with it */
    for (unsigned n = 0; n < s->hist_len; ++n) est_quat_rotate_left(c, s->hist_q[n]);
    /* the error left after each correction is (bias error) x (message period) / link_gain, so
     * this moves the bias at link_bias_gain / link_gain per second, whatever the message rate */
    est_bias_update(s->quat.bias, err, aided ? MODEL_LINK_BIAS_GAIN_WITH_VELOCITY : MODEL_LINK_BIAS_GAIN);
    /* Not engaged, the split waits for the velocity to settle (MODEL_SPLIT_SETTLE s fresh):
     * the drone's attitude heard before it corrected with link_gain, turning the estimate
     * without the bias, and the velocity loop takes that turn back, which the split, started
     * sooner, would take for the bias moving. */
    const float h = fminf((float)(stamp_us - last_stamp) * 1e-6f, (float)MODEL_LINK_TIMEOUT_US * 1e-6f);
    s->aided_s = aided ? fminf(s->aided_s + h, MODEL_SPLIT_SETTLE) : 0.0f;
    if (aided && fresh && (!SPLIT || s->engaged || s->aided_s >= MODEL_SPLIT_SETTLE)) {
        /* What is left of the disagreement (err) is the flight controller's slowly varying
         * error or, split, also the accelerometer's bias across up (velocity.py): fc_error
         * moves towards the estimate and, split, the estimate towards the flight controller,
         * with the bias that holds it there (the velocity keeps agreeing), by the split's
         * Kalman filter or by fixed gains (fc_error_gain, accel_bias_attitude_gain: per second
         * of the drone's time, fc_error fading at 1 / fc_error_tau). Split, from engage or,
         * on the ground, once the velocity has settled: the time before take-off teaches the
         * split as flight does (the arm at rest levelled on the accelerometer less the bias
         * learnt keeps what it turned). */
        float learn[3], turn[3], across[3];
        if (SPLIT && SPLIT_KALMAN) {
            split_by_kalman(s, h, err, turn, learn);
        } else {
            for (int i = 0; i < 3; ++i) {
                learn[i] = h * (MODEL_FC_ERROR_GAIN * err[i] - (SPLIT ? MODEL_FC_ERROR_FADE : 0.0f) * s->fc_error[i]);
                turn[i] = h * MODEL_ACCEL_BIAS_ATTITUDE_GAIN * err[i];
            }
        }
        move_fc_error(s, learn);
        if (SPLIT) {
            est_vel_tilt_as_bias(q_then, turn, across);   /* the bias moves with the turn */
            est_accel_bias_update(s->velocity.accel_bias, across, 1.0f);
            est_quat_turn(s->quat.q, turn);
            for (unsigned n = 0; n < s->hist_len; ++n) est_quat_turn(s->hist_q[n], turn);
        }
    }
    est_quat_up(s->quat.q, s->up);
    take(&s->link, now_us);
    corrected(s, now_us, left);
    return STAB_LINK_ACCEPTED;
}

/* The velocity estimate (and its history) moved by k e. */
static void shift_velocity(stab_t *s, const float e[3], float k)
{
    for (int i = 0; i < 3; ++i) s->velocity.v[i] += k * e[i];
    for (unsigned n = 0; n < s->hist_len; ++n) {
        for (int i = 0; i < 3; ++i) s->hist_v[n][i] += k * e[i];
    }
}

/* The velocity estimate restarted on a message: no tilt is learnt from it. */
static void restart_velocity(stab_t *s, const float e[3])
{
    shift_velocity(s, e, 1.0f);
    s->vel_restarts++;
}

/* The square of the velocity gate (m/s, on the innovation's length): gate_sigmas x the
 * odometry's spread, and the IMU's velocity error that the tilt's spread (the flight
 * controller's, as the estimate's own, plus its drift) makes: g times it over the velocity
 * correction's time constant (1 / k_v). */
static float velocity_gate2(const stab_t *s, uint32_t now_us)
{
    const float tilt = MODEL_GATE_VELOCITY_PER_RAD * (MODEL_GATE_ATTITUDE + drift_gate(s, now_us));
    return MODEL_GATE_VELOCITY * MODEL_GATE_VELOCITY + tilt * tilt;
}

stab_link_status_t stab_drone_velocity(stab_t *s, uint16_t seq, uint32_t stamp_us, const float v_level[3],
                                       uint32_t now_us)
{
    const bool heard = heard_lately(&s->vel, now_us);
    const uint32_t last_stamp = s->vel.stamp_us;
    timing_t tm = { 0u, 0u, 0u };
    float q_then[4], v_then[3], e[3], turn[3];
    if (!MODEL_DRONE_VELOCITY || !MODEL_ESTIMATOR_QUATERNION) return refuse(&s->vel, STAB_LINK_OFF);
    for (int i = 0; i < 3; ++i) {
        if (!(fabsf(v_level[i]) <= VELOCITY_MAX)) return refuse(&s->vel, STAB_LINK_NOT_FINITE);   /* NaN too */
    }
    s->vel.arrived_us = now_us;
    stab_link_status_t why = admit(&s->vel, heard, seq, stamp_us, now_us, &tm);
    if (why == STAB_LINK_AHEAD) distrust(&s->vel, now_us);
    if (why == STAB_LINK_ACCEPTED && !history_at(s, now_us - tm.delay, q_then, v_then)) why = STAB_LINK_STALE;
    if (why != STAB_LINK_ACCEPTED) return refuse(&s->vel, why);
    hear(&s->vel, heard, seq, stamp_us, now_us, &tm);
    est_vel_innovation(q_then, v_level, s->rate, v_then, e, turn);
    bool jump = false;   /* the odometry's own velocity stepped (a reset or a switch of source) */
    for (int i = 0; i < 3; ++i) {
        jump = jump || !(fabsf(v_level[i] - s->vel_last[i]) <= VELOCITY_JUMP);
        s->vel_last[i] = v_level[i];
    }
    if (!heard && !s->vel.rejected) {   /* the first after a silence: the estimate starts on it */
        restart_velocity(s, e);
        take(&s->vel, now_us);
        return STAB_LINK_ACCEPTED;
    }
    /* gains per second, over the drone's time since the previous message */
    const float h = fminf((float)(stamp_us - last_stamp) * 1e-6f, (float)MODEL_LINK_TIMEOUT_US * 1e-6f);
    const bool agrees = heard && !jump && e[0] * e[0] + e[1] * e[1] + e[2] * e[2] <= velocity_gate2(s, now_us);
    why = judge(&s->vel, agrees, now_us);
    if (why != STAB_LINK_ACCEPTED) {
        /* a jump restarts the estimate; a dropped stream keeps the IMU's velocity on the
         * drone's (restarted where it disagrees), so the two can be compared: no tilt taken */
        if (!agrees && (jump || s->vel.rejected)) restart_velocity(s, e);
        else if (s->vel.rejected) shift_velocity(s, e, h * MODEL_VEL_K_V);
        return refuse(&s->vel, why);
    }
    {
        float d[3];
        shift_velocity(s, e, h * MODEL_VEL_K_V);
        for (int i = 0; i < 3; ++i) d[i] = h * MODEL_VEL_K_T * turn[i];
        est_quat_turn(s->quat.q, d);
        for (unsigned n = 0; n < s->hist_len; ++n) est_quat_turn(s->hist_q[n], d);
        est_bias_update(s->quat.bias, turn, h * MODEL_VEL_K_B);
        if (MODEL_ACCEL_BIAS_LEARNT) {
            /* along up, where a tilt error does not show, the drift is the accelerometer's bias */
            float along[3];
            est_vel_along_up(q_then, e, along);
            shift_velocity(s, along, h * (MODEL_VEL_K_U - MODEL_VEL_K_V));
            est_accel_bias_update(s->velocity.accel_bias, along, h * MODEL_VEL_K_A);
        }
        if (stab_link_fresh(s, now_us) && !SPLIT) {
            /* the flight controller's error takes the turn too: its next message keeps it */
            for (int i = 0; i < 3; ++i) d[i] = -d[i];
            move_fc_error(s, d);
        }
        est_quat_up(s->quat.q, s->up);
    }
    take(&s->vel, now_us);
    corrected(s, now_us, 0.0f);
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
