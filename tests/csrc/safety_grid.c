/* The application's own command path (app.c's command_servos, engage and disengage as
 * app.c does them) on an app_t set up in memory: app.c is compiled into this file so its
 * static functions are reachable; nothing of it is re-implemented here. Its goals go to the
 * real servo driver (servo_bus.c, or servo_bus2.c for the X-series) through a port whose
 * servos move as the model of uavarm/sim/ax12_sim.py (AX-12A) or uavarm/sim/xseries_sim.py
 * (XM430-W350) does (written again here for speed; tests/test_safety_grid.py checks the two
 * against each other): each shaft follows a profile that moves toward its goal at the speed
 * asked, capped at the no-load speed x supply / 12 V, with a first-order lag (the AX-12A's
 * stops within its compliance margin, 1 unit, of the profile). */
#include "safety_grid.h"

#include <math.h>

#include "app.c"

#define SUBSTEP_US 1000u               /* the servos' integration step */
#define STILL 0.01f                    /* units: a shaft moved less since the last sample stands still */
#if MODEL_DXL_PROTOCOL == 2u
#include "dxl_protocol2.h"
#define NO_LOAD_UNITS_PER_S (46.0f * 4096.0f / 60.0f)           /* XM430-W350: 46 rpm at 12 V */
#define UNITS_PER_S_PER_SPEED (0.229f * 4096.0f / 60.0f)        /* Profile Velocity: 0.229 rpm a unit */
#define REPLY_LEN (DXL2_STATUS_MIN_LEN + SBUS2_STATUS_LEN)
#else
#define NO_LOAD_UNITS_PER_S (59.0f * 6.0f * 1023.0f / 300.0f)   /* 59 rpm at 12 V */
#define UNITS_PER_S_PER_SPEED (0.111f * 6.0f * 1023.0f / 300.0f)
#define COMPLIANCE_MARGIN 1.0f
#define REPLY_LEN (DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN)
#endif

typedef struct {
    uint32_t now_us;
    float lag_s, volts;
    float goal[SBUS_SERVOS], speed[SBUS_SERVOS], profile[SBUS_SERVOS], shaft[SBUS_SERVOS];
    uint8_t reply[REPLY_LEN];
    size_t reply_len;
} servos_t;

static servos_t servos;
static const uint8_t IDS[SBUS_SERVOS] = { MODEL_SERVO1_ID, MODEL_SERVO2_ID, MODEL_SERVO3_ID };

static int index_of(uint8_t id)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        if (IDS[i] == id) return i;
    }
    return -1;
}

static uint32_t time_us(void *ctx) { (void)ctx; return servos.now_us; }
static size_t link_read(void *ctx, uint8_t *buf, size_t cap) { (void)ctx; (void)buf; (void)cap; return 0; }
static bool link_write(void *ctx, const uint8_t *buf, size_t n) { (void)ctx; (void)buf; (void)n; return true; }
static bool servo_busy(void *ctx) { (void)ctx; return false; }
static void servo_power(void *ctx, bool on) { (void)ctx; (void)on; }
static void led(void *ctx, uint8_t index, bool on) { (void)ctx; (void)index; (void)on; }
static bool imu_read(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n)
{
    (void)ctx; (void)addr; (void)reg; (void)buf; (void)n;
    return false;
}
static bool imu_write(void *ctx, uint8_t addr, uint8_t reg, uint8_t value)
{
    (void)ctx; (void)addr; (void)reg; (void)value;
    return false;
}

#if MODEL_DXL_PROTOCOL == 2u
static uint32_t le32(const uint8_t *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

/* A SYNC_WRITE of Profile Velocity and Goal Position sets speeds and goals; the status READ
 * (through the status map, servo_bus.h's SBUS2_AT_*) is answered at once with the torque on,
 * Status Return Level 1, where the shaft stands (rounded to a unit) and the supply. */
static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
    if (n >= 14 && buf[7] == DXL2_INST_SYNC_WRITE) {
        for (size_t k = 12; k + 9 <= n - 2; k += 9) {
            const int i = index_of(buf[k]);
            if (i < 0) continue;
            servos.speed[i] = (float)le32(buf + k + 1);
            servos.goal[i] = (float)le32(buf + k + 5);
        }
    } else if (n == 14 && buf[7] == DXL2_INST_READ) {
        const int i = index_of(buf[4]);
        uint8_t *r = servos.reply;
        memset(r, 0, sizeof servos.reply);
        const uint8_t head[] = { 0xFF, 0xFF, 0xFD, 0x00, buf[4], (uint8_t)(REPLY_LEN - 7), 0, DXL2_INST_STATUS, 0 };
        memcpy(r, head, sizeof head);
        uint8_t *p = r + sizeof head;
        const uint16_t at = (uint16_t)lroundf(servos.shaft[i < 0 ? 0 : i]);
        const uint16_t volts = (uint16_t)lroundf(servos.volts * 10.0f);
        p[SBUS2_AT_TORQUE_ENABLE] = 1;
        p[SBUS2_AT_STATUS_RETURN_LEVEL] = 1;
        p[SBUS2_AT_POSITION] = (uint8_t)at;
        p[SBUS2_AT_POSITION + 1] = (uint8_t)(at >> 8);
        p[SBUS2_AT_VOLTAGE] = (uint8_t)volts;
        p[SBUS2_AT_VOLTAGE + 1] = (uint8_t)(volts >> 8);
        p[SBUS2_AT_TEMPERATURE] = 30;
        const uint16_t crc = dxl2_crc(0, r, REPLY_LEN - 2);   /* (nothing in it to stuff) */
        r[REPLY_LEN - 2] = (uint8_t)crc;
        r[REPLY_LEN - 1] = (uint8_t)(crc >> 8);
        servos.reply_len = i < 0 ? 0 : REPLY_LEN;
    }
    return true;
}
#else
/* A SYNC_WRITE sets goals and speeds; a READ of registers 32..43 is answered at once with
 * where the shaft stands (rounded to a unit), Torque Limit 1022 and the supply. */
static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
    if (n >= 8 && buf[4] == DXL_INST_SYNC_WRITE) {
        for (size_t k = 7; k + 5 <= n - 1; k += 5) {
            const int i = index_of(buf[k]);
            if (i < 0) continue;
            servos.goal[i] = (float)(buf[k + 1] | buf[k + 2] << 8);
            servos.speed[i] = (float)((buf[k + 3] | buf[k + 4] << 8) & 0x3FF);
        }
    } else if (n == 8 && buf[4] == DXL_INST_READ) {
        const int i = index_of(buf[2]);
        uint8_t *r = servos.reply;
        memset(r, 0, sizeof servos.reply);
        r[0] = r[1] = 0xFF;
        r[2] = buf[2];
        r[3] = SBUS_STATUS_LEN + 2;
        const uint16_t at = (uint16_t)lroundf(servos.shaft[i < 0 ? 0 : i]);
        r[5 + 2] = 0xFE;                       /* Torque Limit 1022 (34) */
        r[5 + 3] = 0x03;
        r[5 + 4] = (uint8_t)at;                /* Present Position (36) */
        r[5 + 5] = (uint8_t)(at >> 8);
        r[5 + 10] = (uint8_t)lroundf(servos.volts * 10.0f);   /* Present Voltage (42) */
        r[5 + 11] = 30;                        /* Present Temperature (43) */
        r[sizeof servos.reply - 1] = dxl_checksum(r + 2, sizeof servos.reply - 3);
        servos.reply_len = i < 0 ? 0 : sizeof servos.reply;
    }
    return true;
}
#endif

static size_t servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    const size_t n = servos.reply_len < cap ? servos.reply_len : cap;
    memcpy(buf, servos.reply, n);
    memmove(servos.reply, servos.reply + n, servos.reply_len - n);
    servos.reply_len -= n;
    return n;
}

static const port_t PORT = { NULL, time_us, link_read, link_write, servo_send, servo_busy, servo_read, servo_power,
                             led, imu_read, imu_write };

/* The servos moved on by h seconds. */
static void servos_step(float h)
{
    const float cap = NO_LOAD_UNITS_PER_S * servos.volts / 12.0f;
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        const float asked = servos.speed[i] * UNITS_PER_S_PER_SPEED;
        const float travel = (servos.speed[i] == 0.0f || asked > cap ? cap : asked) * h;
        const float before = servos.profile[i];
        const float left = servos.goal[i] - before;
        servos.profile[i] = fabsf(left) <= travel ? servos.goal[i] : before + copysignf(travel, left);
        if (servos.lag_s <= 0.0f) {
            servos.shaft[i] = servos.profile[i];
            continue;
        }
#if MODEL_DXL_PROTOCOL == 2u
        /* the lag's exact answer to a profile moving linearly within the step */
        const float slope = (servos.profile[i] - before) / h, trail = slope * servos.lag_s;
        servos.shaft[i] = servos.profile[i] - trail + (servos.shaft[i] - before + trail) * expf(-h / servos.lag_s);
#else
        const float err = servos.profile[i] - servos.shaft[i];
        if (fabsf(err) > COMPLIANCE_MARGIN) servos.shaft[i] += err * -expm1f(-h / servos.lag_s);
#endif
    }
}

/* An enabled, configured arm whose servos stand (and are commanded) at `start`, parked, the
 * board tilted by (roll, pitch): false if the application would not start from there. */
static bool arm_at(app_t *app, const float start[3], float roll, float pitch)
{
    uint16_t units[SBUS_SERVOS];
    memset(app, 0, sizeof *app);
    if (!servo_joints_to_units(start, units)) return false;
    app->port = &PORT;
    app->enabled = true;
    sbus_init(&app->bus, &PORT, IDS, MODEL_SERVO_BAUD);
    app->bus.state = SBUS_RUNNING;
    for (unsigned i = 0; i < SBUS_SERVOS; ++i) {   /* configured, read where they stand */
        sbus_servo_t *s = &app->bus.servo[i];
        s->present_position = units[i];
        s->present_voltage = (uint8_t)lroundf(servos.volts * 10.0f);
        s->status_valid = true;
        servos.goal[i] = servos.profile[i] = servos.shaft[i] = (float)units[i];
        servos.speed[i] = 0.0f;
        shaft_stands(app, i, start[i]);   /* (as start_motion) */
    }
    servos.reply_len = 0;
    stab_reset(&app->stab);
    est_set(&app->stab.attitude, roll, pitch);
    est_attitude_up(&app->stab.attitude, app->stab.up);   /* the estimate's up direction (rate 0) */
    if (!motion_start(&app->motion, start)) return false;
    memcpy(app->q_cmd, start, sizeof app->q_cmd);
    app->parked = true;
    return true;
}

/* `ticks` ticks: what tick() does for the servos (the shafts watched, command_servos), the
 * bus traffic it starts, then the servos moving for a tick. Each goal app.c hands the bus
 * joins goals[] and the shafts after every substep in which one moved join shafts[] (units),
 * with the run's number. */
static void run_ticks(app_t *app, uint32_t ticks, grid_out_t *out, uint32_t run_no)
{
    const uint32_t readings = app->bus.status_reads;
    for (uint32_t k = 0; k < ticks; ++k) {
        (void)track_update(&app->track, &app->bus, servos.now_us);
        app->bus.command_pending = false;
        command_servos(app);
        if (app->bus.command_pending && out->n_goals < out->cap_goals) {
            memcpy(out->goals + 3 * out->n_goals, app->q_cmd, sizeof app->q_cmd);
            out->goal_run[out->n_goals++] = run_no;
        }
        for (int p = 0; p < 8; ++p) sbus_poll(&app->bus);   /* SYNC_WRITE, READ, its reply */
        for (uint32_t s = 1; s <= MODEL_TICK_US / SUBSTEP_US; ++s) {
            servos.now_us += SUBSTEP_US;
            servos_step((float)SUBSTEP_US * 1e-6f);
            const float *last = out->shafts + 3 * (out->n_shafts - 1);
            const bool moved = out->n_shafts == 0 || out->shaft_run[out->n_shafts - 1] != run_no
                               || fabsf(last[0] - servos.shaft[0]) > STILL || fabsf(last[1] - servos.shaft[1]) > STILL
                               || fabsf(last[2] - servos.shaft[2]) > STILL;
            if (moved && out->n_shafts < out->cap_shafts) {
                memcpy(out->shafts + 3 * out->n_shafts, servos.shaft, sizeof servos.shaft);
                out->shaft_run[out->n_shafts++] = run_no;
            }
        }
    }
    out->readings += app->bus.status_reads - readings;
}

void safety_grid(const float start[3], const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                 uint32_t ticks, float lag_s, float volts, grid_out_t *out)
{
    static app_t app;
    uint32_t run_no = 0;
    out->n_goals = out->n_shafts = 0;
    out->refused = out->readings = 0;
    servos.lag_s = lag_s;
    servos.volts = volts;
    for (size_t t = 0; t < n_tilts; ++t) {
        for (size_t i = 0; i < n_targets; ++i, ++run_no) {
            if (!arm_at(&app, start, tilts[2 * t], tilts[2 * t + 1])) return;
            const float *level = targets + 3 * i;
            memcpy(app.set_position, level, sizeof app.set_position);
            app.set_on_axis = motion_on_axis(level);
            /* engage from parked: as on_engage once the arm is ready */
            if (!head_for(&app, app.set_position)) {
                out->refused++;
                continue;
            }
            app.engaged = true;
            run_ticks(&app, ticks, out, run_no);
            /* engage 0 */
            disengage(&app);
            if (app.motion_refused) {
                out->refused++;
                continue;
            }
            run_ticks(&app, ticks, out, run_no);
        }
    }
}

void servo_model(float lag_s, float volts, const float *goals, const float *speeds, size_t n, float start,
                 float *shafts)
{
    servos.lag_s = lag_s;
    servos.volts = volts;
    servos.profile[0] = servos.shaft[0] = start;
    for (size_t k = 0; k < n; ++k) {
        servos.goal[0] = goals[k];
        servos.speed[0] = speeds[k];
        servos_step((float)SUBSTEP_US * 1e-6f);
        shafts[k] = servos.shaft[0];
    }
}
