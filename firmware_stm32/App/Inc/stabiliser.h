/* The stabiliser's arithmetic, one IMU sample at a time: scaled IMU sample -> generated
 * Butterworth filters -> attitude (the model's estimator: complementary, or quaternion with
 * gyro bias and, optionally, the drone's attitude and velocity from the link) -> target turned into the
 * tilted base frame, ahead by the model's lead time and about the drone's centre of rotation.
 * No I/O: app.c feeds it, motion.c turns the point into joints. */
#ifndef STABILISER_H
#define STABILISER_H

#include <stdbool.h>
#include <stdint.h>

#include "estimator.h"
#include "filters.h"
#include "kinematics.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define STAB_HISTORY 32            /* ticks of attitude history, at least the model's link_delay_max */
#define STAB_DT_MAX_PERIODS 4u     /* the longest time one sample is integrated over, in periods */

/* Why a drone_attitude or drone_velocity message was refused (stab_drone_attitude,
 * stab_drone_velocity). */
typedef enum {
    STAB_LINK_ACCEPTED = 0,
    STAB_LINK_OFF = 1,             /* the model does not fuse it */
    STAB_LINK_NOT_FINITE = 2,      /* NaN, infinite or out of range (roll +-pi, pitch +-pi/2, velocity +-50 m/s) */
    STAB_LINK_OUT_OF_ORDER = 3,    /* seq or stamp not newer than the last accepted one */
    STAB_LINK_STALE = 4,           /* measured longer ago than the history (link_delay_max) */
    STAB_LINK_OPPOSITE = 5,        /* attitude up side down from the estimate: no unique correction */
    STAB_LINK_AHEAD = 6,           /* its stamps ran ahead of the board's clock (beyond the link's jitter) */
    STAB_LINK_DISAGREES = 7,       /* outside the gate: disagrees with the estimate beyond its expected spread */
    STAB_LINK_REJECTED = 8         /* agrees, but the stream is dropped until it agrees for retake_after */
} stab_link_status_t;

/* One stream of the drone's messages (its attitude or its velocity). A message is heard when
 * its timing is good (in order, not stale, stamps not ahead), accepted when the gate also lets
 * it correct the estimate. */
typedef struct {
    bool valid;                    /* a message was accepted since the reset */
    bool heard;                    /* a message was heard since the reset */
    bool refusing;                 /* the gate has refused every message heard since refusing_us */
    bool rejected;                 /* dropped: refused for reject_after, until agreeing for retake_after */
    bool agreeing;                 /* rejected, but every message heard since agreeing_us agreed */
    uint16_t seq;                  /* of the last heard message */
    uint32_t stamp_us;             /* its stamp (drone clock) */
    uint32_t heard_us;             /* local time it was heard */
    uint32_t arrived_us;           /* local time the last finite message arrived, heard or not */
    uint32_t accepted_us;          /* local time of the last accepted one */
    uint32_t offset_us;            /* smallest (arrival - stamp) seen: the clocks' offset */
    uint32_t floor_us;             /* (arrival - stamp) below this: stamps ahead of the board's clock */
    uint32_t delay_us;             /* the last heard message's estimated delay */
    uint32_t refusing_us;
    uint32_t agreeing_us;
    uint32_t accepted;             /* counters */
    uint32_t refused;              /* every refusal, the gate's included */
    uint32_t disagreed;            /* refused by the gate (STAB_LINK_DISAGREES) */
    uint32_t rejections;           /* times the stream was dropped */
} stab_stream_t;

typedef struct {
    filt_accel_t accel_filter[3];
    filt_gyro_t gyro_filter[3];
    est_attitude_t attitude;       /* complementary estimator */
    est_quat_t quat;               /* quaternion estimator */
    float up[3];                   /* the estimate's up direction, base axes */
    float rate[3];                 /* body rate for the lead, base axes, rad/s */
    bool started;                  /* a first sample has set filters and attitude */
    bool engaged;                  /* the last sample's: the arm holds a set position */
    bool accel_idle;               /* the accelerometer's filter was left while the drone's messages corrected */
    uint32_t samples;              /* samples taken since the reset (saturates) */
    uint32_t last_sample_us;       /* when the previous one was taken */
    uint32_t gaps;                 /* samples more than 1.5 periods after the previous one */
    /* the window in which the board has been still (gyro, then accelerometer, per axis;
     * stabiliser.c, bias_at_rest) */
    uint16_t still_n;              /* samples in it so far */
    float still_lo[6], still_hi[6];
    float still_sum[6];            /* gyro and accelerometer, IMU axes */
    /* the quaternion (and velocity) after each sample, and the time of that sample (for the link) */
    float hist_q[STAB_HISTORY][4];
    float hist_v[STAB_HISTORY][3];
    uint32_t hist_us[STAB_HISTORY];
    uint8_t hist_next;             /* slot of the next sample */
    uint8_t hist_len;
    stab_stream_t link;            /* the drone's attitude over the link */
    stab_stream_t vel;             /* the drone's velocity over the link */
    est_vel_t velocity;            /* the IMU's velocity and accelerometer bias estimates (drone_velocity) */
    float vel_last[3];             /* the last accepted drone_velocity (level frame, m/s) */
    float fc_error[3];             /* the flight controller's estimated tilt error, base axes, rad */
    /* the split's Kalman filter per base axis: covariance of (the estimate's tilt error from
     * the bias, fc_error's error) as P00, P01, P11 (rad^2); set at the first split message */
    float split_p[3][3];
    bool split_started;
    float aided_s;                 /* drone seconds the velocity has been fresh at the attitude's messages (to MODEL_SPLIT_SETTLE) */
    uint32_t vel_restarts;         /* velocity estimates restarted (first message, or a jump) */
    bool corrected;                /* a drone message corrected the attitude since the reset ... */
    uint32_t corrected_us;         /* ... at this local time (the gate widens with the time since) */
    float doubt;                   /* gate_sigmas x the disagreement it left (rad) */
} stab_t;

void stab_reset(stab_t *s);
/* One sample taken at now_us: accelerometer in g, gyro in rad/s, both in the IMU's axes.
 * The first sample after a reset starts filters and attitude at rest on it. engaged selects
 * the quaternion estimator's in-flight gains (else it aligns fast with the accelerometer,
 * and takes the gyro bias from each second the board stands still). */
void stab_sample(stab_t *s, const float accel_g[3], const float gyro_rad_s[3], uint32_t now_us, bool engaged);
/* The drone's roll and pitch (rad, Z-Y-X) from its flight controller, measured at stamp_us
 * of its clock, message number seq, arriving at now_us: fused if the model says so and the
 * message is finite, newer than the last, not older than the history, its stamp not ahead of
 * the board's clock, and it agrees with the estimate (the gate, stabiliser.c). */
stab_link_status_t stab_drone_attitude(stab_t *s, uint16_t seq, uint32_t stamp_us, float roll, float pitch,
                                       uint32_t now_us);
/* The drone's velocity (m/s, level heading-following frame, its centre of rotation) from its
 * odometry, measured at stamp_us, message number seq, arriving at now_us: fused if the model
 * says so and the message is finite, within +-50 m/s, timed as drone_attitude's and agrees
 * with the estimate. The first after a silence restarts the velocity estimate on it; one more
 * than 2 m/s on an axis from the last one (an odometry reset) restarts it too, but counts as
 * disagreeing (a restart teaches no tilt). */
stab_link_status_t stab_drone_velocity(stab_t *s, uint16_t seq, uint32_t stamp_us, const float v_level[3],
                                       uint32_t now_us);
/* Is the drone's attitude fresh (accepted within the model's link_timeout of now_us)? */
bool stab_link_fresh(const stab_t *s, uint32_t now_us);
/* Is the drone's velocity fresh (idem)? */
bool stab_velocity_fresh(const stab_t *s, uint32_t now_us);
/* What corrects the attitude estimate at now_us: MSG_SOURCE_* bits (the accelerometer, the
 * drone's attitude, the drone's velocity). */
uint8_t stab_sources(const stab_t *s, uint32_t now_us);
/* The current estimate of the base's roll and pitch (rad), for telemetry and the simulator. */
void stab_attitude(const stab_t *s, float *roll, float *pitch);
/* Where target_level (level frame, mm) is in the tilted base frame at the current attitude
 * predicted lead_time ahead, about the drone's centre of rotation: the point to reach. */
void stab_command_point(const stab_t *s, const float target_level[3], float p_base[3]);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* STABILISER_H */
