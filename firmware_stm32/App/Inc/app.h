/* The firmware application: link commands, control states, stabiliser tick, servo bus and
 * heartbeat, over the port interface only (no HAL), so it builds for the STM32 and the host.
 *
 * States (SPEC.md "Link to the drone"):
 *   disabled         servo power off
 *   enabled          power on, slow speed, parked pose held
 *   enabled+engaged  working speed, set position held in the level frame (stabilised)
 * enable 0 cuts the power at once and clears engage; engage 1 is refused unless enabled;
 * set_position is accepted in any state unless non-finite (refused) or unreachable from
 * a level base (flagged "unreachable", the previous set position is kept). While engaged,
 * a target that the current tilt puts out of reach holds the joints and flags it. An
 * engaged arm whose link is silent for the model's timeout parks and flags "link lost".
 * An engaged arm also parks when the IMU gives no usable sample for APP_IMU_STALE_TICKS
 * ticks (absent, not sampling, or at full scale) or a servo stops following its goal
 * (servo_track.h); engage is refused while either stands.
 * The heartbeat reports the imu, imu_saturated and servo_tracking bits if they stood at
 * any tick since the previous heartbeat, so a shorter fault is still seen; the other bits
 * as they stand.
 *
 * Main loop: app_poll() as often as possible. Tick: app_request_tick() from the IMU's
 * data-ready or a timer interrupt at the model's sample rate; the next app_poll() runs it.
 */
#ifndef APP_H
#define APP_H

#include <stdbool.h>
#include <stdint.h>

#include "llcp.h"
#include "port.h"
#include "servo_bus.h"
#include "servo_track.h"
#include "stabiliser.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define APP_IMU_RETRY_MS 1000
#define APP_IMU_STALE_TICKS 5          /* ticks without a usable sample before the IMU is faulty */
#define APP_LINK_BYTES_PER_POLL 256    /* a flood of link bytes cannot starve the tick */

typedef struct {
    const port_t *port;
    llcp_rx_t link;
    sbus_t bus;
    stab_t stab;
    track_t track;
    /* control state */
    bool enabled;
    bool engaged;
    bool unreachable;              /* the last set_position was refused as unreachable */
    bool out_of_reach;             /* this tick's tilt put the set position out of reach */
    bool refused;                  /* the last command was refused */
    bool link_lost;                /* latched until engage */
    bool servo_config_failed;      /* latched until enable */
    float set_position[3];         /* level frame, mm */
    float q_cmd[3];                /* the joints last commanded (always a checked pose) */
    /* IMU */
    bool imu_ok;
    uint32_t imu_retry_us;
    uint16_t imu_errors;
    uint16_t imu_stale;            /* ticks in a row without a usable sample (saturates) */
    bool imu_saturated;            /* the latest sample had an axis at full scale */
    uint32_t imu_samples_used;
    uint16_t faults_since_heartbeat;   /* held fault bits seen at ticks since the last heartbeat */
    /* timing */
    volatile uint32_t ticks_requested;
    uint32_t ticks_run;
    uint32_t ticks_missed;         /* requests that came while one was still pending */
    uint32_t last_frame_us;
    uint32_t link_ms;              /* the link receiver's millisecond clock (wraps at 2^32 ms) */
    uint32_t link_ms_base_us;      /* the microsecond time link_ms was last advanced to */
    uint32_t last_heartbeat_us;
    uint32_t heartbeats_sent;
    uint32_t heartbeats_dropped;   /* the link's transmit queue was full */
    uint32_t commands_ignored;     /* valid frames of messages the arm does not take */
    uint32_t drone_attitudes;      /* drone_attitude frames received */
} app_t;

void app_init(app_t *app, const port_t *port);
/* ISR-safe: asks for one stabiliser tick. */
void app_request_tick(app_t *app);
void app_poll(app_t *app);
/* The heartbeat fault bits (MSG_FAULT_*) as they stand. */
uint16_t app_faults(const app_t *app);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* APP_H */
