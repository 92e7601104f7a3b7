/* Servo tracking watch; see servo_track.h. */
#include "servo_track.h"

#include <string.h>

#include "model_params.h"

void track_reset(track_t *t)
{
    memset(t, 0, sizeof *t);
}

static int32_t abs32(int32_t v)
{
    return v < 0 ? -v : v;
}

/* One new reading of a servo at `pos` that was sent `goal` at `speed`. */
static inline __attribute__((always_inline)) bool tracks(const track_servo_t *w, uint16_t pos, uint16_t goal,
                                                        uint16_t speed, uint32_t dt_us)
{
    const int32_t error = (int32_t)goal - (int32_t)pos;
    if (abs32(error) <= (int32_t)MODEL_TRACK_TOL_UNITS) return true;
    if (abs32(error) > (int32_t)MODEL_SERVO_GAP_MAX) return false;   /* behind */
    const int32_t left = (int32_t)goal - (int32_t)w->last_position;
    const int32_t moved = ((int32_t)pos - (int32_t)w->last_position) * (left < 0 ? -1 : 1);
    if (moved <= 0) return false;   /* (no progress at all: the float part is not needed) */
    const float allowed = (float)(speed & 0x3FFu) * MODEL_UNITS_PER_S_PER_SPEED * ((float)dt_us * 1e-6f);
    const float wanted = (float)abs32(left) < allowed ? (float)abs32(left) : allowed;
    return (float)moved >= TRACK_MIN_PROGRESS * wanted;
}

bool track_fault(const track_t *t)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        if (t->servo[i].fault) return true;
    }
    return false;
}

/* Servo i's new reading, if it has one. (Inlined into both paths of track_update().) */
static inline __attribute__((always_inline)) void look_at_servo(track_t *t, const sbus_t *bus, int i, uint32_t now_us)
{
    track_servo_t *w = &t->servo[i];
    const sbus_servo_t *s = &bus->servo[i];
    if (s->reads == w->reads_seen) return;
    w->reads_seen = s->reads;
    t->fresh |= (uint8_t)(1u << i);
    const uint32_t dt_us = now_us - w->last_us;
    if (w->have_last) {
        if (tracks(w, s->present_position, bus->goal[i], bus->speed[i], dt_us)) {
            w->bad_us = 0;
            if (w->fault) {
                w->good_us = w->good_us + dt_us < w->good_us ? UINT32_MAX : w->good_us + dt_us;
                w->fault = w->good_us < TRACK_FAULT_US;
            }
        } else {
            w->good_us = 0;   /* a standing fault clears only after TRACK_FAULT_US of tracking in a row */
            w->bad_us = w->bad_us + dt_us < w->bad_us ? UINT32_MAX : w->bad_us + dt_us;
            w->fault = w->fault || w->bad_us >= TRACK_FAULT_US;
        }
    }
    w->last_position = s->present_position;
    w->last_us = now_us;
    w->have_last = true;
}

/* Each servo's readings since the last look. (Not inlined: the usual tick needs one servo.) */
static __attribute__((noinline)) void look_at_readings(track_t *t, const sbus_t *bus, uint32_t now_us)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) look_at_servo(t, bus, i, now_us);
    t->synced = true;
}

bool track_update(track_t *t, const sbus_t *bus, uint32_t now_us)
{
    /* (the driver's count of all readings says whether there is any to look at) */
    const uint32_t new_reads = bus->status_reads - t->status_reads_seen;
    t->status_reads_seen = bus->status_reads;
    t->fresh = 0;
    if (new_reads == 1u && t->synced) {
        /* the usual tick: one reading, so only the servo the driver read last has moved on
         * from the counts seen */
        look_at_servo(t, bus, bus->last_read, now_us);
    } else if (new_reads != 0u) {
        look_at_readings(t, bus, now_us);
    }
    return track_fault(t);
}
