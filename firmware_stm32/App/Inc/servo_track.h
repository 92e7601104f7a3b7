/* Does each servo's shaft follow its goal? A stuck shaft (jammed gear, limp after the
 * servo's own Shutdown) or one that creeps away from its goal (slipping, failing position
 * sensor) is noticed from the driver's status reads, without a model of the load:
 *
 *   a reading is "not tracking" when the shaft is more than MODEL_TRACK_TOL_UNITS (2.35 deg in
 *   the servo's units: an AX-12A's 8, an X-series' 27) from the goal
 *   it was sent and, since the servo's previous reading, it moved toward that goal by less
 *   than TRACK_MIN_PROGRESS of what its Moving Speed allows (or of the distance left);
 *   a reading further than MODEL_SERVO_GAP_MAX from its goal is "behind" (a servo slower
 *   than the motion allows for: blocked, or a supply below what it reports: the
 *   application holds the goals while any servo is) and does not track either;
 *   the fault stands once readings have not tracked for TRACK_FAULT_US in a row, and
 *   clears once they have tracked for as long (a goal that sweeps past a stuck shaft on
 *   its way does not clear it).
 *
 * A healthy AX-12A moves at its Moving Speed (no load: ~0.111 rpm per unit, AX-12A
 * e-manual) until it is within its compliance margin of the goal, so it passes easily;
 * the tolerance covers compliance and sag under the arm's weight.
 */
#ifndef SERVO_TRACK_H
#define SERVO_TRACK_H

#include <stdbool.h>
#include <stdint.h>

#include "servo_bus.h"

#ifdef __cplusplus
extern "C" {
#endif

#define TRACK_MIN_PROGRESS 0.25f   /* (float: outside the cffi block) */

/* cffi:begin */
#define TRACK_FAULT_US 250000u

typedef struct {
    uint16_t reads_seen;           /* the driver's read counter when last looked at */
    uint16_t last_position;        /* units, at the previous reading */
    uint32_t last_us;
    uint32_t bad_us;               /* how long its readings have not tracked ... */
    uint32_t good_us;              /* ... or have, since the fault stood */
    bool have_last;
    bool fault;
} track_servo_t;

typedef struct {
    track_servo_t servo[SBUS_SERVOS];
    uint32_t status_reads_seen;    /* the driver's count of all readings when last looked at */
    bool synced;                   /* each reads_seen is its servo's count as of status_reads_seen
                                      (not after track_reset(): the driver's counts go on) */
    uint8_t fresh;                 /* bit i: servo i was read since the update before the last */
} track_t;

void track_reset(track_t *t);
/* Looks at the readings the driver took since the last call (`fresh` says whose), against
 * the goal and speed the driver last sent (call before the next command is queued). Returns
 * track_fault(). */
bool track_update(track_t *t, const sbus_t *bus, uint32_t now_us);
/* Any servo's tracking fault standing. */
bool track_fault(const track_t *t);

/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* SERVO_TRACK_H */
