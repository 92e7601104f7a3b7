/*
 * The whole 100 Hz tick of the firmware application on Cortex-M4, for `make bench`:
 * app_init, enable and a set position through LLCP frames, the servos at the park pose, ticks
 * of a level board until the arm is parked, engage, ticks until it follows the set position;
 * then n ticks, each one IMU burst (tilting board), the stabiliser, the followed branch's IK,
 * the swept check, servo map, the SYNC_WRITE, one status READ and the parse of its reply
 * (four main-loop passes). The port is a minimal in-memory board. The drone's attitude and
 * velocity streams are kept fresh (as at 50 Hz, when the model fuses them), so each tick
 * takes the flight path: velocity integrated, no accelerometer correction. Their messages
 * are handled in the main loop between ticks, not by the tick: bench/run.py measures them
 * apart.
 *
 * bench/run.py reports (cycles(bench_run(n, 1)) - cycles(bench_run(n, 0))) / n: what a
 * tick adds to the main loop's idle passes.
 */
#include <string.h>

#include "app.h"
#include "dxl_protocol.h"
#include "dxl_protocol2.h"
#include "imu_mpu6050.h"
#include "llcp.h"
#include "messages.h"
#include "model_params.h"
#include "servo_map.h"

static uint32_t now;
static uint8_t imu_regs[128];
static char link_in[256];
static size_t link_len, link_pos;
#if MODEL_DXL_PROTOCOL == 2u
#include "xseries_reply.h"
#define REPLY_LEN XSERIES_REPLY_LEN
#else
#define REPLY_LEN (DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN)
#endif
static uint8_t replies[SBUS_SERVOS][REPLY_LEN];   /* one per servo */
static const uint8_t *reply;
static size_t reply_len, reply_pos;
static app_t app;

/* Up to cap of the bytes src[*pos .. len-1]. */
static size_t take(const void *src, size_t len, size_t *pos, uint8_t *buf, size_t cap)
{
    size_t n = len - *pos < cap ? len - *pos : cap;
    if (n == 0) return 0;   /* nothing waiting: as the board's rings answer, at once */
    memcpy(buf, (const uint8_t *)src + *pos, n);
    *pos += n;
    return n;
}

static uint32_t time_us(void *ctx) { (void)ctx; return now; }
static size_t link_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    return take(link_in, link_len, &link_pos, buf, cap);
}
static bool link_write(void *ctx, const uint8_t *buf, size_t n) { (void)ctx; (void)buf; (void)n; return true; }
/* The status packet each servo answers a READ with (configured, at `position`), built when
 * the goals change: composing it is the servo's work, not the firmware's. */
static const uint8_t IDS[SBUS_SERVOS] = { MODEL_SERVO1_ID, MODEL_SERVO2_ID, MODEL_SERVO3_ID };
#if MODEL_DXL_PROTOCOL == 2u
/* Protocol 2.0 (X-series): the status map's reading (xseries_reply.h) */
static void build_replies(const uint16_t position[SBUS_SERVOS])
{
    for (int i = 0; i < SBUS_SERVOS; ++i) xseries_reply(replies[i], IDS[i], position[i]);
}
#else
/* Protocol 1.0 (AX-12A): Torque Limit .. */
static void build_replies(const uint16_t position[SBUS_SERVOS])
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        uint8_t *r = replies[i];
        r[0] = r[1] = 0xFF;
        r[2] = IDS[i];
        r[3] = SBUS_STATUS_LEN + 2;
        r[4] = 0;
        memset(r + 5, 0, SBUS_STATUS_LEN);
        r[5 + 2] = 0xFEu;                                     /* Torque Limit 1022 (address 34) */
        r[5 + 3] = 0x03u;
        r[5 + 4] = (uint8_t)position[i];                      /* Present Position (36) */
        r[5 + 5] = (uint8_t)(position[i] >> 8);
        r[5 + 10] = 120u;                                     /* Present Voltage (42): 12.0 V */
        r[REPLY_LEN - 1] = dxl_checksum(r + 2, REPLY_LEN - 3);
    }
}
#endif

/* Every READ is answered at once with the status packet of the requested servo. */
static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
#if MODEL_DXL_PROTOCOL == 2u
    const bool read = n > 7 && buf[7] == DXL2_INST_READ;
    const uint8_t id = n > 4 ? buf[4] : 0;
#else
    const bool read = n == 8 && buf[4] == DXL_INST_READ;
    const uint8_t id = n > 2 ? buf[2] : 0;
#endif
    if (read) {
        for (int i = 0; i < SBUS_SERVOS; ++i) {
            if (IDS[i] == id) reply = replies[i];
        }
        reply_len = REPLY_LEN;
        reply_pos = 0;
    }
    return true;
}

static bool servo_busy(void *ctx) { (void)ctx; return false; }
static size_t servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    return take(reply, reply_len, &reply_pos, buf, cap);
}
static void servo_power(void *ctx, bool on) { (void)ctx; (void)on; }
static void led(void *ctx, uint8_t index, bool on) { (void)ctx; (void)index; (void)on; }
static bool imu_read(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n)
{
    (void)ctx; (void)addr;
    /* (the STM32 port's blocking HAL read then waits ~0.4 ms on the I2C bus: wire time, not
     * the firmware's work, and not counted here) */
    memcpy(buf, imu_regs + reg, n);
    return true;
}
static bool imu_write(void *ctx, uint8_t addr, uint8_t reg, uint8_t value)
{
    (void)ctx; (void)addr;
    imu_regs[reg & 127u] = value;
    return true;
}

static const port_t PORT = {
    NULL, time_us, link_read, link_write, servo_send, servo_busy, servo_read, servo_power, led,
    imu_read, imu_write,
};

static void frame(const uint8_t *payload, size_t n)
{
    link_len += llcp_encode(payload, n, link_in + link_len, sizeof link_in - link_len);
}

static void period(const int32_t *sample, bool request);

/* Ticks of a still, level board, the servos standing on their goals, until done(). */
static bool settle(bool (*done)(void))
{
    const int32_t level[6] = { 0, 0, (int32_t)(1.0f / MODEL_ACCEL_G_PER_LSB), 0, 0, 0 };
    for (int k = 0; k < 300 && !done(); ++k) {
        period(level, true);
        build_replies(app.bus.goal);
    }
    return done();
}

static bool parked(void) { return app.parked && app.stab.samples >= MODEL_IMU_SETTLE_SAMPLES; }
static bool following(void) { return app.engaged && app.parked && app.motion.arrived; }

/* The arm engaged and following the set position; the servos answer from where they stand
 * then (the tracking watch needs 25 ticks to mind that they do not follow the bench's). */
static int setup(void)
{
    static const float park[3] = { MODEL_PARK_Q1, MODEL_PARK_Q2, MODEL_PARK_Q3 };
    uint8_t payload[MSG_SET_POSITION_SIZE];
    uint16_t at_park[SBUS_SERVOS];
    const msg_enable_t enable = { 1 };
    const msg_engage_t engage = { 1 };
    const msg_set_position_t set = { 60.0f, 20.0f, -120.0f };
    imu_regs[MPU_REG_WHO_AM_I] = MPU_WHO_AM_I;
    app_init(&app, &PORT);
    frame(payload, msg_enable_pack(&enable, payload, sizeof payload));
    frame(payload, msg_set_position_pack(&set, payload, sizeof payload));
    app_poll(&app);
    app.bus.state = SBUS_RUNNING;   /* skip the servo boot and configuration: they stand at park */
    (void)servo_joints_to_units(park, at_park);
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        app.bus.servo[i].status_valid = true;
        app.bus.servo[i].present_position = at_park[i];
    }
    build_replies(at_park);
    if (!settle(parked)) return 0;
    frame(payload, msg_engage_pack(&engage, payload, sizeof payload));
    return settle(following);
}

/* One tick period: the IMU sample (accel x, y, z and gyro x, y, z counts) in the chip's
 * registers, the tick requested or not, and four main-loop passes. */
static void period(const int32_t *sample, bool request)
{
    for (int i = 0; i < 3; ++i) {
        const uint16_t a = (uint16_t)sample[i], g = (uint16_t)sample[3 + i];
        imu_regs[MPU_REG_ACCEL_XOUT_H + 2 * i] = (uint8_t)(a >> 8);
        imu_regs[MPU_REG_ACCEL_XOUT_H + 2 * i + 1] = (uint8_t)a;
        imu_regs[MPU_REG_ACCEL_XOUT_H + 8 + 2 * i] = (uint8_t)(g >> 8);
        imu_regs[MPU_REG_ACCEL_XOUT_H + 9 + 2 * i] = (uint8_t)g;
    }
    imu_regs[MPU_REG_INT_STATUS] = MPU_INT_DATA_RDY;   /* a new sample, as the chip flags it */
    now += MODEL_TICK_US;
    /* in flight: the drone's messages fresh (heard and accepted a tick ago) */
    app.stab.link.valid = app.stab.vel.valid = app.stab.link.heard = app.stab.vel.heard = app.engaged;
    app.stab.link.accepted_us = app.stab.vel.accepted_us = now - MODEL_TICK_US;
    app.stab.link.heard_us = app.stab.vel.heard_us = app.stab.link.arrived_us = app.stab.vel.arrived_us = now - MODEL_TICK_US;
    if (request) app_request_tick(&app);
    app_poll(&app);   /* the tick: IMU, stabiliser, IK, command; SYNC_WRITE out */
    app_poll(&app);   /* SYNC_WRITE sent (no reply) */
    app_poll(&app);   /* status READ out */
    app_poll(&app);   /* its reply parsed */
}

/* raw: n + 1 samples. After the setup, one tick first, in both runs (the board starts to
 * rock). Then n periods, with ticks or (ticks = 0) the same main-loop passes without: the
 * idle cost, which bench/run.py subtracts. */
int bench_run(const int32_t *raw, uint32_t n, uint32_t ticks)
{
    int ok = setup();
    const uint32_t writes = app.bus.sync_writes, reads = app.bus.status_reads;
    period(raw, true);
    for (uint32_t k = 1; k <= n; ++k) period(raw + 6 * k, ticks != 0);
    /* still engaged, and every tick had its SYNC_WRITE and its status reading, as on the
     * board, whose main loop runs many passes per tick: the ticks measured were the
     * stabilising path with all of its bus traffic, not a parked arm */
    const uint32_t expected = 1u + (ticks ? n : 0u);
    return ok && app.engaged && app.bus.sync_writes - writes == expected && app.bus.status_reads - reads == expected;
}

/* One drone message: the attitude claims the estimate's own (so the gate takes it), the
 * velocity a constant one. */
static stab_link_status_t drone_message(uint32_t which, uint16_t seq)
{
    static const float v[3] = { 0.5f, -0.2f, 0.0f };
    float roll, pitch;
    if (which == 2) return stab_drone_velocity(&app.stab, seq, now - 20000u, v, now);
    stab_attitude(&app.stab, &roll, &pitch);
    return stab_drone_attitude(&app.stab, seq, now - 20000u, roll, pitch, now);
}

/* The cost of one drone message handled by the stabiliser in the main loop (which 1:
 * drone_attitude, 2: drone_velocity): after the setup and n ticks, a first message restarts
 * its stream, two ticks pass, and a second one (second = 1) is fused like every message in
 * flight, or none (second = 0). bench/run.py takes the difference. */
int bench_message(const int32_t *raw, uint32_t n, uint32_t which, uint32_t second)
{
    int ok = setup();
    for (uint32_t k = 0; k + 2 < n; ++k) period(raw + 6 * k, true);
    app.stab.link.valid = app.stab.vel.valid = app.stab.link.heard = app.stab.vel.heard = false;
    stab_link_status_t first = drone_message(which, 1);
    period(raw + 6 * (n - 2), true);
    period(raw + 6 * (n - 1), true);
    stab_link_status_t next = second ? drone_message(which, 2) : STAB_LINK_ACCEPTED;
    return ok && first == STAB_LINK_ACCEPTED && next == STAB_LINK_ACCEPTED;
}

/* The cost of one main-loop pass with (with = 1) or without (0) one piece of its work, after
 * the setup and n ticks (what 1: a new set_position received, decoded and handled while
 * engaged, the route to it checked; 2: a heartbeat packed, framed and written). bench/run.py
 * takes the difference. */
int bench_pass(const int32_t *raw, uint32_t n, uint32_t what, uint32_t with)
{
    int ok = setup();
    for (uint32_t k = 0; k < n; ++k) period(raw + 6 * k, true);
    app.last_heartbeat_us = now - (what == 2 && with ? MODEL_HEARTBEAT_MS * 1000u : 0u);
    const uint32_t sent = app.heartbeats_sent;
    if (what == 1 && with) {
        uint8_t payload[MSG_SET_POSITION_SIZE];
        const msg_set_position_t set = { 55.0f, 15.0f, -125.0f };
        frame(payload, msg_set_position_pack(&set, payload, sizeof payload));
    }
    app_poll(&app);
    if (what == 1) return ok && app.engaged && app.set_position[0] == (with ? 55.0f : 60.0f);
    return ok && app.heartbeats_sent - sent == (with ? 1u : 0u);
}
