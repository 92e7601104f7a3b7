/* The firmware's main loop on the host, run in C for the passes the simulation on Python's
 * side has nothing to do in: no packet to deliver to a servo, no IMU sample to latch, no
 * bytes the application sent to take. The servos' replies, known in advance, wait here and
 * reach the UART at their passes. Each pass is what the simulated board's step() does
 * (the tick interrupt when due, the clock, app_poll, app_watch) at the same times, so a run
 * through here is the same run, only without a trip to Python for every pass.
 */
#ifndef HOST_LOOP_H
#define HOST_LOOP_H

#include <stdbool.h>
#include <stdint.h>

#include "app.h"
#include "host_port.h"

/* cffi:begin */
#define HOST_ARRIVING_CAP 1024

typedef struct {
    int64_t now_us;          /* the board's time: that of the last pass, since it started */
    int64_t stop_us;         /* no pass at or after this time (the next event Python must see) */
    int64_t poll_us;         /* main-loop period */
    int64_t next_tick_us;    /* when the tick interrupt next requests a tick */
    int64_t tick_us;
    int64_t frozen_at_us;    /* the board's time the clock shows (it stands while frozen) */
    uint32_t start_us;       /* the clock's reading at time 0 */
    bool tick_interrupt;     /* false: the interrupt has stopped */
    bool clock_frozen;
    bool servo_power;        /* the supply as the simulation last saw it */
    /* bytes from the servos still on the wire, in order: each reaches the UART at the first
     * pass at or after its time (board time, us) */
    uint8_t arriving[HOST_ARRIVING_CAP];
    int64_t arriving_us[HOST_ARRIVING_CAP];
    uint32_t arriving_head;
    uint32_t arriving_len;
} host_loop_t;

/* Queue n bytes from the servos, arriving at at_us[i] (not before those queued); returns
 * how many fitted. */
uint32_t host_loop_arrive(host_loop_t *loop, const uint8_t *bytes, const int64_t *at_us, uint32_t n);
/* Hand the UART the queued bytes that have arrived by loop->now_us; returns how many. */
uint32_t host_loop_deliver(host_loop_t *loop, host_port_t *hp);

/* Run passes at now_us + poll_us, + 2 poll_us, ... while they fall before stop_us, each
 * after the bytes that have arrived by then are delivered; stop after a pass that
 * transmitted on the servo bus or the link, or switched the servo supply.
 * Returns the passes run (loop->now_us, next_tick_us and frozen_at_us follow them). */
uint32_t host_loop_run(host_loop_t *loop, host_port_t *hp, app_t *app);
/* cffi:end */

#endif /* HOST_LOOP_H */
