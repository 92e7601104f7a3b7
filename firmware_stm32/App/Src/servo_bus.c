/* AX-12A servo bus state machine; see servo_bus.h. */
#include "servo_bus.h"

#include <string.h>

#include "model_params.h"

enum { PHASE_IDLE, PHASE_SENDING, PHASE_AWAIT };
enum { REPLY_NONE, REPLY_OPTIONAL, REPLY_REQUIRED };
enum { DONE_OK, DONE_TIMEOUT };

/* Registers written at enable (AX-12A control table addresses). */
#define AX_RETURN_DELAY 5u
#define AX_CW_ANGLE_LIMIT 6u
#define AX_STATUS_RETURN_LEVEL 16u
#define AX_TORQUE_ENABLE 24u
#define AX_TORQUE_LIMIT 34u
#define STATUS_RETURN_READS 1u    /* answer PING and READ only */
#define TORQUE_LIMIT_FULL 1023u
/* The longest a servo may wait before answering: Return Delay Time 254 x 2 us. A servo
 * not configured yet still has the factory 500 us. */
#define RETURN_DELAY_MAX_US 508u
#define REPLY_MARGIN_US 1000u

enum { CFG_SRL, CFG_RETURN_DELAY, CFG_ANGLE_LIMITS, CFG_TORQUE_LIMIT, CFG_TORQUE_ENABLE, CFG_VERIFY, CFG_STEPS };

static const uint16_t CW_LIMIT[SBUS_SERVOS] = { MODEL_SERVO1_CW_LIMIT, MODEL_SERVO2_CW_LIMIT, MODEL_SERVO3_CW_LIMIT };
static const uint16_t CCW_LIMIT[SBUS_SERVOS] = { MODEL_SERVO1_CCW_LIMIT, MODEL_SERVO2_CCW_LIMIT, MODEL_SERVO3_CCW_LIMIT };

static uint32_t now_us(const sbus_t *bus)
{
    return bus->port->time_us(bus->port->ctx);
}

static void enter(sbus_t *bus, sbus_state_t state)
{
    bus->state = state;
    bus->since_us = now_us(bus);
}

void sbus_init(sbus_t *bus, const port_t *port, const uint8_t ids[SBUS_SERVOS], uint32_t baud)
{
    memset(bus, 0, sizeof *bus);
    bus->port = port;
    bus->byte_us = (10u * 1000000u + baud - 1u) / baud;   /* start + 8 data + stop bits */
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        bus->servo[i].id = bus->ids[i] = ids[i];
        (void)dxl_build_read(bus->read_pkt[i], sizeof bus->read_pkt[i], ids[i], SBUS_STATUS_ADDR, SBUS_STATUS_LEN);
    }
    (void)dxl_parser_init(&bus->parser, bus->rx_buf, sizeof bus->rx_buf);
    enter(bus, SBUS_OFF);
}

/* Everything that describes the servos' live state goes stale with their power. */
static void forget_servo_state(sbus_t *bus)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        bus->servo[i].status_valid = false;
        bus->servo[i].failed = false;
        bus->servo[i].last_error = 0;
    }
    bus->phase = PHASE_IDLE;
    bus->command_pending = false;
    bus->read_due = false;
    bus->read_attempt = 0;
}

void sbus_power(sbus_t *bus, bool on)
{
    bus->port->servo_power(bus->port->ctx, on);
    forget_servo_state(bus);
    bus->cfg_servo = bus->cfg_step = bus->cfg_attempt = 0;
    enter(bus, on ? SBUS_BOOTING : SBUS_OFF);
}

void sbus_command(sbus_t *bus, const uint16_t goal[SBUS_SERVOS], const uint16_t speed[SBUS_SERVOS])
{
    if (bus->state != SBUS_RUNNING) {
        return;
    }
    memcpy(bus->goal, goal, sizeof bus->goal);
    memcpy(bus->speed, speed, sizeof bus->speed);
    bus->command_pending = true;
}

uint32_t sbus_tick_bus_time_us(const sbus_t *bus)
{
    const uint32_t sync = 8u + 5u * SBUS_SERVOS;           /* header, addr, len, checksum + entries */
    const uint32_t read = 8u;
    const uint32_t status = DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN;
    return (sync + read + status) * bus->byte_us + RETURN_DELAY_MAX_US + REPLY_MARGIN_US;
}

/* --------------------------------------------------------------- transactions */

static bool start(sbus_t *bus, size_t len, uint8_t reply, uint8_t id, uint8_t n_params)
{
    if (len == 0 || (size_t)DXL_STATUS_MIN_LEN + n_params > sizeof bus->direct
        || !bus->port->servo_send(bus->port->ctx, bus->tx, len)) {
        return false;   /* (a reply longer than the direct check's buffer is never requested) */
    }
    bus->tx_len = (uint8_t)len;
    bus->reply = reply;
    bus->expect_id = id;
    bus->expect_params = n_params;
    /* a reply may take the longest return delay plus its own bytes, counted from the
     * instruction's last byte */
    bus->timeout_us = RETURN_DELAY_MAX_US + (DXL_STATUS_MIN_LEN + n_params) * bus->byte_us + REPLY_MARGIN_US;
    bus->phase = PHASE_SENDING;   /* (the reply's wait is timed from the end of sending) */
    return true;
}

static sbus_servo_t *servo_of(sbus_t *bus, uint8_t id)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        if (bus->servo[i].id == id) return &bus->servo[i];
    }
    return NULL;
}

static void note_error_byte(sbus_servo_t *s, uint8_t error)
{
    s->last_error = error;
    if (error == 0) return;
    s->error_packets++;
    for (int bit = 0; bit < 7; ++bit) {
        if (error & (1u << bit)) s->error_bits[bit]++;
    }
}

/* One received byte through the resynchronising parser; true when it completed the reply. */
static bool parse_byte(sbus_t *bus, uint8_t byte)
{
    sbus_servo_t *s = servo_of(bus, bus->expect_id);
    dxl_parse_result_t r = dxl_parse_byte(&bus->parser, byte);
    if (r == DXL_PARSE_BAD_CHECKSUM && s != NULL) {
        s->bad_packets++;
    } else if (r == DXL_PARSE_COMPLETE) {
        if (bus->parser.id == bus->expect_id && bus->parser.n_params == bus->expect_params) {
            if (s != NULL) note_error_byte(s, bus->parser.error);
            bus->reply_params = bus->parser.params;
            return true;
        }
        bus->stray_packets++;   /* our own echo, or a packet meant for no request */
    }
    return false;
}

/* Bytes of the expected reply checked as they arrive, in locals (a byte store through bus
 * would make the compiler reload every field). Returns how many of the n bytes fit it;
 * *done when they completed it. */
static size_t direct_bytes(sbus_t *bus, const uint8_t *b, size_t n, bool *done)
{
    const unsigned total = DXL_STATUS_MIN_LEN + bus->expect_params;
    unsigned len = bus->direct_len, sum = bus->direct_sum;
    uint8_t *dst = bus->direct;
    const uint8_t head[4] = { 0xFF, 0xFF, bus->expect_id, (uint8_t)(bus->expect_params + 2u) };
    size_t i = 0;
    *done = false;
    while (i < n) {
        if (len >= 5u) {
            /* the parameters always fit; the checksum byte must make the sum 0xFF */
            size_t k = total - 1u - len;
            if (k > n - i) k = n - i;
            const uint8_t *src = b + i, *end = src + k;
            uint8_t *out = dst + len;
            while (src < end) {
                const uint8_t x = *src++;
                *out++ = x;
                sum += x;
            }
            i += k;
            len += (unsigned)k;
            if (i == n) break;
            if (((sum + b[i]) & 0xFFu) != 0xFFu) break;
            dst[len++] = b[i++];
            *done = true;
            break;
        }
        const uint8_t byte = b[i];
        if (len < 4u ? byte != head[len] : byte > 0x7Fu) break;   /* (the error byte: bit 7 clear) */
        if (len >= 2u) sum += byte;
        dst[len++] = byte;
        ++i;
    }
    bus->direct_len = (uint8_t)len;
    bus->direct_sum = (uint8_t)sum;
    return i;
}

/* The transaction ends with its reply. */
static bool replied(sbus_t *bus, int *how)
{
    bus->phase = PHASE_IDLE;
    *how = DONE_OK;
    return true;   /* bytes after it are dropped when the next request starts */
}

/* The reply so far, or the timeout. Not inlined: the sending phase, polled most often,
 * then needs neither its registers nor its buffer. */
static __attribute__((noinline)) bool receive(sbus_t *bus, int *how)
{
    uint8_t chunk[16];
    size_t n;
    while ((n = bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk)) > 0) {
        size_t i = 0;
        if (!bus->resync) {
            /* the usual case, the expected reply alone on the wire, checked directly */
            bool done;
            i = direct_bytes(bus, chunk, n, &done);
            if (done) {
                sbus_servo_t *s = servo_of(bus, bus->expect_id);
                if (s != NULL) note_error_byte(s, bus->direct[4]);
                bus->reply_params = bus->direct + 5;
                return replied(bus, how);
            }
            if (i < n) {
                /* chunk[i] does not fit: the bytes so far go to the parser, then the rest */
                bus->resync = true;
                for (uint8_t k = 0; k < bus->direct_len; ++k) {
                    if (parse_byte(bus, bus->direct[k])) return replied(bus, how);
                }
            }
        }
        for (; i < n; ++i) {
            if (parse_byte(bus, chunk[i])) return replied(bus, how);
        }
    }
    if (now_us(bus) - bus->phase_us > bus->timeout_us) {
        bus->phase = PHASE_IDLE;
        *how = bus->reply == REPLY_OPTIONAL ? DONE_OK : DONE_TIMEOUT;
        return true;
    }
    return false;
}

/* Advances the transaction on the wire; true when it has ended, with *how. */
static bool transaction_done(sbus_t *bus, int *how)
{
    if (bus->phase == PHASE_SENDING) {
        if (bus->port->servo_busy(bus->port->ctx)) return false;
        if (bus->reply == REPLY_NONE) {
            bus->phase = PHASE_IDLE;
            *how = DONE_OK;
            return true;
        }
        bus->phase = PHASE_AWAIT;
        bus->phase_us = now_us(bus);
    }
    if (bus->phase != PHASE_AWAIT) return false;
    return receive(bus, how);
}

/* Drops whatever arrived since the last request (late replies, noise). */
static void flush_rx(sbus_t *bus)
{
    uint8_t chunk[16];
    while (bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk) > 0) {
    }
    dxl_parser_reset(&bus->parser);
    bus->direct_len = 0;
    bus->direct_sum = 0;
    bus->resync = false;
}

/* --------------------------------------------------------------- configuration */

static size_t build_config_step(sbus_t *bus, uint8_t step, const sbus_servo_t *s, uint16_t cw, uint16_t ccw)
{
    uint8_t data[4];
    switch (step) {
    case CFG_SRL:
        data[0] = STATUS_RETURN_READS;
        return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_STATUS_RETURN_LEVEL, data, 1);
    case CFG_RETURN_DELAY:
        data[0] = MODEL_SERVO_RETURN_DELAY;
        return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_RETURN_DELAY, data, 1);
    case CFG_ANGLE_LIMITS:
        data[0] = (uint8_t)(cw & 0xFFu);
        data[1] = (uint8_t)(cw >> 8);
        data[2] = (uint8_t)(ccw & 0xFFu);
        data[3] = (uint8_t)(ccw >> 8);
        return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_CW_ANGLE_LIMIT, data, 4);
    case CFG_TORQUE_LIMIT:
        data[0] = (uint8_t)(TORQUE_LIMIT_FULL & 0xFFu);
        data[1] = (uint8_t)(TORQUE_LIMIT_FULL >> 8);
        return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_TORQUE_LIMIT, data, 2);
    case CFG_TORQUE_ENABLE:
        data[0] = 1;
        return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_TORQUE_ENABLE, data, 1);
    default:
        return dxl_build_read(bus->tx, sizeof bus->tx, s->id, SBUS_VERIFY_ADDR, SBUS_VERIFY_LEN);
    }
}

/* The read-back of addresses 5..35 shows every register written above. */
static bool config_verified(const sbus_t *bus, uint16_t cw, uint16_t ccw)
{
#define REG8(addr) ((uint16_t)bus->reply_params[(addr) - SBUS_VERIFY_ADDR])
#define REG16(addr) ((uint16_t)(REG8(addr) | REG8((addr) + 1u) << 8))
    return REG8(AX_RETURN_DELAY) == MODEL_SERVO_RETURN_DELAY
        && REG16(AX_CW_ANGLE_LIMIT) == cw && REG16(AX_CW_ANGLE_LIMIT + 2u) == ccw
        && REG8(AX_STATUS_RETURN_LEVEL) == STATUS_RETURN_READS
        && REG8(AX_TORQUE_ENABLE) == 1u
        && REG16(AX_TORQUE_LIMIT) == TORQUE_LIMIT_FULL;
#undef REG8
#undef REG16
}

static void configure(sbus_t *bus)
{
    const int i = bus->cfg_servo;
    sbus_servo_t *s = &bus->servo[i];
    int how;
    if (bus->phase == PHASE_IDLE) {
        flush_rx(bus);
        uint8_t step = bus->cfg_step;
        size_t len = build_config_step(bus, step, s, CW_LIMIT[i], CCW_LIMIT[i]);
        if (step == CFG_VERIFY) {
            (void)start(bus, len, REPLY_REQUIRED, s->id, SBUS_VERIFY_LEN);
        } else {
            (void)start(bus, len, REPLY_OPTIONAL, s->id, 0);
        }
        return;
    }
    if (!transaction_done(bus, &how)) return;
    if (bus->cfg_step < CFG_VERIFY) {
        bus->cfg_step++;
        return;
    }
    if (how == DONE_OK && config_verified(bus, CW_LIMIT[i], CCW_LIMIT[i])) {
        bus->cfg_step = 0;
        bus->cfg_attempt = 0;
        if (++bus->cfg_servo == SBUS_SERVOS) enter(bus, SBUS_RUNNING);
        return;
    }
    if (how == DONE_TIMEOUT) s->timeouts++;
    bus->cfg_step = 0;
    if (++bus->cfg_attempt >= SBUS_CONFIG_ATTEMPTS) {
        s->failed = true;
        enter(bus, SBUS_FAILED);
    } else {
        s->retries++;
    }
}

/* --------------------------------------------------------------- running */

static void take_status(sbus_servo_t *s, const uint8_t *p)
{
    s->present_position = (uint16_t)(p[0] | p[1] << 8);
    s->present_speed = (uint16_t)(p[2] | p[3] << 8);
    s->present_load = (uint16_t)(p[4] | p[5] << 8);
    s->present_voltage = p[6];
    s->present_temperature = p[7];
    s->status_valid = true;
    s->failed = false;
    s->reads++;
}

static void run(sbus_t *bus)
{
    int how;
    if (bus->phase != PHASE_IDLE) {
        if (!transaction_done(bus, &how) || bus->reply == REPLY_NONE) return;
        sbus_servo_t *s = &bus->servo[bus->read_index];
        if (how == DONE_OK) {
            take_status(s, bus->reply_params);
        } else {
            s->timeouts++;
            if (bus->read_attempt < SBUS_READ_RETRIES) {
                bus->read_attempt++;
                s->retries++;
                return;   /* the same servo again after the next command */
            }
            s->failed = true;
        }
        bus->read_attempt = 0;
        bus->read_index = (uint8_t)(bus->read_index + 1u < SBUS_SERVOS ? bus->read_index + 1u : 0u);
        return;
    }
    if (bus->command_pending) {
        size_t len = dxl_build_sync_goal_speed(bus->tx, sizeof bus->tx, SBUS_SERVOS, bus->ids, bus->goal, bus->speed);
        if (start(bus, len, REPLY_NONE, 0, 0)) {
            bus->command_pending = false;
            bus->read_due = true;
            bus->sync_writes++;
        }
    } else if (bus->read_due) {
        flush_rx(bus);
        const sbus_servo_t *s = &bus->servo[bus->read_index];
        memcpy(bus->tx, bus->read_pkt[bus->read_index], sizeof bus->read_pkt[0]);
        if (start(bus, sizeof bus->read_pkt[0], REPLY_REQUIRED, s->id, SBUS_STATUS_LEN)) {
            bus->read_due = false;
        }
    }
}

void sbus_poll(sbus_t *bus)
{
    switch (bus->state) {
    case SBUS_BOOTING:
        if (now_us(bus) - bus->since_us >= MODEL_SERVO_BOOT_MS * 1000u) enter(bus, SBUS_CONFIGURING);
        break;
    case SBUS_CONFIGURING:
        configure(bus);
        break;
    case SBUS_RUNNING:
        run(bus);
        break;
    default:
        break;
    }
}
