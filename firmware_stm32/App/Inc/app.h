/* The firmware application: link commands, control states, stabiliser tick, servo bus and
 * heartbeat, over the port interface only (no HAL), so it builds for the STM32 and the host.
 *
 * States:
 *   disabled         servo power off
 *   enabled          power on; from where the servos report the arm to be, to the parked
 *                    pose at park speed, held there
 *   enabled+engaged  (parked first if not yet since enable) to the set position at transit
 *                    speed, then held in the level frame (stabilised) at working speed
 * Every move goes through motion.c and is checked before the bus (app_next_goal).
 * enable 0 cuts the power at once and clears engage; engage 1 is refused unless enabled with
 * the servos configured; set_position is accepted in any state unless non-finite (refused),
 * outside the workspace from a level base (flagged "unreachable", the previous set position
 * is kept) or, engaged, without a clear route (refused, "motion blocked"). While engaged, a
 * target that the current tilt puts out of reach is followed to the nearest point the
 * arm's branch reaches and flagged. An engaged arm whose link is silent for the model's
 * timeout parks and flags "link lost"; so does a limp or jogged one (torque on first). Every
 * frame sent to the arm keeps the link alive but ping, which is answered and nothing more.
 * An engaged arm also parks when the IMU gives no usable sample for APP_IMU_STALE_TICKS
 * ticks (absent, not sampling, or at full scale) or a servo stops following its goal
 * (servo_track.h); engage is refused while either stands.
 * Every goal is checked as a move from wherever the shafts may be (between each servo's
 * latest reading and the goals that may still pull it), and moves no faster than the
 * slowest servo can at the supply it reports; while a shaft is far behind its goal the goals
 * wait for it (flagged servo_lagging, with the joint).
 * The heartbeat reports the imu, imu_saturated and servo_tracking bits if they stood at
 * any tick since the previous heartbeat, so a shorter fault is still seen; the other bits
 * as they stand.
 *
 * Bench (enable 2, refused while engaged or flying): the servos powered and configured with the
 * torque off, no goal sent, the arm limp where it hangs and read. The model's zeros and
 * directions are not trusted yet (they are what the calibration finds), so until enable 0 or
 * 1 the firmware never moves the arm on its own: what would park it (the link silent, the
 * drone heard, engage 0 from a jogged or held pose, a servo found reset) turns the torque off
 * instead, and engage is refused (refusal "bench"). The service commands work as below.
 * enable 1 ends the bench: the torque on and the arm parks. The heartbeat's enabled is 2.
 *
 * Service (for bring-up and calibration; refused while engaged or flying, taken while enabled).
 * Flying: a drone_attitude or drone_velocity came within the link's silence timeout; each
 * ends a service state (torque on, park) and stops the streams. set_position is no sign of
 * flight: it is also the keep-alive of a calibration on the bench.
 *   torque 0/1       limp (torque off, supply on, positions still read) and back on,
 *                    holding where the arm stands; engage, engage 0 (park) and jog also
 *                    turn it back on
 *   jog              one joint to an angle or by servo units at park speed, checked like
 *                    every move; engage parks first
 *   stream           imu_raw every N ticks and servo_status after each status read, sent
 *                    from app_poll (not the tick); engage stops both
 *
 * Main loop: app_poll() as often as possible. Tick: app_request_tick() from the IMU's
 * data-ready or a timer interrupt at the model's sample rate; the next app_poll() runs it.
 */
#ifndef APP_H
#define APP_H

#include <stdbool.h>
#include <stdint.h>

#include "imu_mpu6050.h"
#include "llcp.h"
#include "motion.h"
#include "port.h"
#include "servo_bus.h"
#include "servo_track.h"
#include "stabiliser.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define APP_FIRMWARE_VERSION 0x000700u   /* 0.7.0: major, minor, patch bytes (the heartbeat's "firmware") */
#define APP_IMU_RETRY_MS 1000
#define APP_CLOCK_STALL_TICKS 3        /* ticks in a row with the microsecond clock standing still */
#define APP_IMU_STALE_TICKS 5          /* ticks without a usable sample before the IMU is faulty */
#define APP_LINK_BYTES_PER_POLL 256    /* a flood of link bytes cannot starve the tick */

/* where motion goes when it starts from the servos' readings (enable, torque back on) */
#define APP_START_PARK 0
#define APP_START_HOLD 1               /* stay where the arm stands (torque back on) */
#define APP_START_JOG 2                /* go to jog_goal (a jog that turned the torque back on) */

typedef struct {
    const port_t *port;
    llcp_rx_t link;
    sbus_t bus;
    stab_t stab;
    track_t track;
    motion_t motion;
    /* control state */
    bool enabled;
    bool bench;                    /* enabled limp for calibration (enable 2): the firmware never moves it */
    bool engaged;
    bool unreachable;              /* the last set_position was refused as unreachable */
    bool out_of_reach;             /* this tick's tilt put the set position out of reach */
    bool refused;                  /* the last command was refused ... */
    uint8_t refusal;               /* ... and why (MSG_REFUSAL_*) */
    bool servo_reset;              /* a servo was found reset (latched until engage or enable) */
    bool timing_fault;             /* the clock stood still: power cut (latched until enable) */
    bool motion_refused;           /* no clear route for the last move asked (until the next) */
    bool parked;                   /* the arm has been at the park pose since enable */
    bool link_lost;                /* latched until engage */
    bool flying;                   /* a drone_attitude or drone_velocity came at last_drone_us, ... */
    uint32_t last_drone_us;        /* ... within the link's silence timeout: no service commands */
    bool servo_config_failed;      /* latched until enable */
    float set_position[3];         /* level frame, mm */
    bool set_on_axis;              /* ... on joint 1's axis: joint 1 holds while following */
    float q_cmd[3];                /* the joints last commanded (every move to them checked) */
    float shafts[2][2][3];         /* where the shafts may be (rad): joint i in s[0][i]..s[1][i] of ... */
    uint8_t shafts_now;            /* ... s = shafts[shafts_now] (the other: the next tick's) */
    float before;                  /* the goal before q_cmd of the servo read after it was sent ... */
    uint8_t before_servo;          /* ... that servo ... */
    uint32_t before_syncs;         /* ... and the driver's SYNC_WRITEs before it was sent */
    uint8_t behind;                /* bit i: servo i was read further than MODEL_SERVO_GAP_MAX from its goal */
    /* service */
    bool jog;                      /* the motion's aim is a jogged pose, not the park pose */
    uint8_t start_to;              /* APP_START_*: where motion goes when it starts */
    float jog_goal[3];             /* with APP_START_JOG */
    uint8_t stream_imu_every;      /* imu_raw every N ticks, 0 off */
    uint8_t stream_imu_ticks;
    bool stream_servos;            /* servo_status after each status read */
    bool imu_raw_ready;            /* imu_burst holds a read to stream */
    uint8_t imu_burst[MPU_BURST_BYTES];
    uint32_t imu_burst_us;
    uint16_t imu_raw_seq;
    uint32_t servo_reads_streamed; /* bus.status_reads already streamed */
    uint16_t servo_status_seq;
    /* IMU */
    bool imu_ok;
    uint32_t imu_retry_us;
    uint16_t imu_errors;
    uint16_t imu_stale;            /* ticks in a row without a usable sample (saturates) */
    bool imu_saturated;            /* the latest sample had an axis at full scale */
    uint32_t imu_samples_used;
    uint16_t faults_since_heartbeat;   /* held fault bits seen at ticks since the last heartbeat */
    uint8_t lagging_since_heartbeat;   /* servos found behind their goals since then (bits) */
    /* timing */
    volatile uint32_t ticks_requested;
    uint32_t ticks_run;
    uint32_t ticks_missed;         /* requests that came while one was still pending */
    uint32_t last_frame_us;
    uint32_t link_ms;              /* the link receiver's millisecond clock (wraps at 2^32 ms) */
    uint32_t link_ms_base_us;      /* the microsecond time link_ms was last advanced to */
    uint32_t last_heartbeat_us;
    uint16_t heartbeat_seq;        /* the next heartbeat's number */
    uint32_t heartbeats_sent;
    uint32_t heartbeats_dropped;   /* the link's transmit queue was full */
    uint32_t commands_ignored;     /* valid frames of messages the arm does not take */
    uint32_t link_echoes;          /* frames with the board's own heartbeat id: an echo, not life */
    uint32_t servo_resets;         /* servos found reset and configured again */
    uint32_t last_tick_us;         /* when the last tick ran */
    uint32_t ticks_late;           /* ticks run from the clock because the tick interrupt was late */
    uint8_t clock_stalls;          /* ticks in a row with the clock standing still */
    bool tick_due;                 /* app_watch found the tick interrupt late: app_poll ticks */
    uint8_t led_ticks;             /* ticks since the LEDs were last set */
    uint8_t reset_cause;           /* set by the board after app_init: why the chip last reset (MSG_RESET_*) */
    uint8_t last_fault;            /* set by the board: the exception that halted the firmware before, 0 none */
    uint32_t drone_attitudes;      /* drone_attitude frames received */
    uint32_t drone_velocities;     /* drone_velocity frames received */
} app_t;

void app_init(app_t *app, const port_t *port);
/* ISR-safe: asks for one stabiliser tick. */
void app_request_tick(app_t *app);
void app_poll(app_t *app);
/* Supervision, from the main loop after app_poll(): a tick interrupt late by half a period
 * is made up from the clock by the next app_poll() (counted, flagged "timing"). (Three ticks
 * with the clock standing still cut the servo power: nothing can be timed.) */
void app_watch(app_t *app);
/* Is the loop healthy (ticks running, the clock moving)? The board feeds its watchdog only then. */
bool app_healthy(const app_t *app);
/* The next goal: motion.c's proposal (following target, tilted base frame, mm, unless NULL),
 * checked with kin_check_span as a move from wherever the shafts may be (joint i between
 * shafts[0][i] and shafts[1][i], rad), offered smaller while refused, the last goal again if
 * nothing passes; the speed of its step. `box`: where the shafts may be once q is sent (the
 * span grown to hold q and MOTION_GOAL_MARGIN about it). command_servos' core. */
motion_speed_t app_next_goal(motion_t *mo, const float *target, bool pinned, const float shafts[2][3],
                             float box[2][3], float q[3]);
/* The heartbeat fault bits (MSG_FAULT_*) as they stand. */
uint16_t app_faults(const app_t *app);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* APP_H */
