/*
 * The X-series servo-bus driver's work per command on Cortex-M4 (firmware_stm32/App/Src/
 * servo_bus2.c, Dynamixel Protocol 2.0), for `make bench`: the bus running, n commands, each
 * sbus_command(), the SYNC_WRITE of Profile Velocity and Goal Position built and sent, the
 * status READ sent, and its reply (the status map's 13 bytes, 24 in all) parsed and
 * taken, in four sbus_poll() passes. The port is a minimal in-memory bus whose servos answer
 * each READ at once with a status packet built beforehand (composing it is the servo's work).
 *
 * bench/run.py reports (cycles(bench_sbus2(n, 1)) - cycles(bench_sbus2(n, 0))) / n: what a
 * command adds to four idle passes.
 */
#include <string.h>

#include "dxl_protocol2.h"
#include "model_params.h"
#include "servo_bus.h"
#include "xseries_reply.h"

#define REPLY_LEN XSERIES_REPLY_LEN

static const uint8_t IDS[SBUS_SERVOS] = { MODEL_SERVO1_ID, MODEL_SERVO2_ID, MODEL_SERVO3_ID };
static uint32_t now;
static uint8_t replies[SBUS_SERVOS][REPLY_LEN];
static const uint8_t *reply;
static size_t reply_pos;
static sbus_t bus;

/* Each servo's answer to the status READ, at 2048. */
static void build_replies(void)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) xseries_reply(replies[i], IDS[i], 2048u);
}

static uint32_t time_us(void *ctx) { (void)ctx; return now; }
static size_t no_read(void *ctx, uint8_t *buf, size_t cap) { (void)ctx; (void)buf; (void)cap; return 0; }
static bool no_write(void *ctx, const uint8_t *buf, size_t n) { (void)ctx; (void)buf; (void)n; return true; }
/* A READ is answered by the servo it names. */
static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
    if (n > 7 && buf[7] == DXL2_INST_READ) {
        for (int i = 0; i < SBUS_SERVOS; ++i) {
            if (IDS[i] == buf[4]) {
                reply = replies[i];
                reply_pos = 0;
            }
        }
    }
    return true;
}
static bool servo_busy(void *ctx) { (void)ctx; return false; }
static size_t servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    if (reply == NULL) return 0;
    size_t n = REPLY_LEN - reply_pos < cap ? REPLY_LEN - reply_pos : cap;
    memcpy(buf, reply + reply_pos, n);
    reply_pos += n;
    if (reply_pos == REPLY_LEN) reply = NULL;
    return n;
}
static void servo_power(void *ctx, bool on) { (void)ctx; (void)on; }
static void led(void *ctx, uint8_t which, bool on) { (void)ctx; (void)which; (void)on; }
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

static const port_t PORT = { NULL, time_us, no_read, no_write, servo_send, servo_busy, servo_read, servo_power,
                             led, imu_read, imu_write };

/* n commands (or, commands 0, as many sets of idle passes); 1 if each command took one
 * status reading of a servo at 2048. */
int bench_sbus2(uint32_t n, uint32_t commands)
{
    static const uint16_t goal[SBUS_SERVOS] = { 2048, 2048, 2048 };
    static const uint16_t speed[SBUS_SERVOS] = { MODEL_PARK_SPEED, MODEL_PARK_SPEED, MODEL_PARK_SPEED };
    build_replies();
    sbus_init(&bus, &PORT, IDS, MODEL_SERVO_BAUD);
    bus.state = SBUS_RUNNING;   /* configured: the servos answer as set up */
    for (uint32_t k = 0; k < n; ++k) {
        if (commands) sbus_command(&bus, goal, speed);
        for (int pass = 0; pass < 4; ++pass) {
            now += 100u;
            sbus_poll(&bus);
        }
    }
    if (!commands) return 1;
    return bus.status_reads == n && bus.sync_writes == n && bus.servo[0].present_position == 2048u;
}
