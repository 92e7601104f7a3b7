/* AX-12A (Dynamixel Protocol 1.0) servo bus state machine; see servo_bus.h. */
#include "servo_bus.h"

#include <string.h>

#include "model_params.h"
#if MODEL_DXL_PROTOCOL == 1u   /* (Protocol 2.0, the X-series: servo_bus2.c) */
enum { PHASE_IDLE, PHASE_SENDING, PHASE_AWAIT };
enum { REPLY_NONE, REPLY_OPTIONAL, REPLY_REQUIRED };
enum { NOT_DONE, DONE_OK, DONE_TIMEOUT };   /* how a transaction stands */

/* Registers written at enable (AX-12A control table addresses). */
#define AX_RETURN_DELAY 5u
#define AX_CW_ANGLE_LIMIT 6u
#define AX_STATUS_RETURN_LEVEL 16u
#define AX_TORQUE_ENABLE 24u
#define AX_TORQUE_LIMIT 34u
#define AX_PRESENT_POSITION 36u
#define STATUS_RETURN_READS 1u    /* answer PING and READ only */
#define MAX_TORQUE 1023u                /* the EEPROM's Max Torque: a servo's Torque Limit at power-on */
/* Torque Limit as configured: one below Max Torque, so that a servo that lost its RAM (its
 * Torque Limit back at Max Torque) is told apart at its next status reading */
#define TORQUE_LIMIT_SET (MAX_TORQUE - 1u)
/* (the bench's, lower, is told apart from Max Torque as well) */
typedef char bench_limit_below_max_torque[MODEL_SERVO_BENCH_TORQUE_LIMIT < MAX_TORQUE ? 1 : -1];
/* The longest a servo may wait before answering: Return Delay Time 254 x 2 us. A servo
 * not configured yet still has the factory 500 us. */
#define RETURN_DELAY_MAX_US 508u
#define REPLY_MARGIN_US 1000u

enum { CFG_READ, CFG_WRITE, CFG_VERIFY };   /* configuration steps of each servo */
/* its writes, in order (bits of sbus_t.cfg_mask); the EEPROM ones first */
enum { CFG_W_SRL, CFG_W_RETURN_DELAY, CFG_W_ANGLE_LIMITS, CFG_W_SAFETY, CFG_W_SHUTDOWN, CFG_W_TORQUE_LIMIT,
       CFG_W_TORQUE_ENABLE, CFG_WRITES };

/* The SYNC_WRITE of goal position and moving speed (dxl_protocol.h): FF FF FE LEN 83 1E 04, then
 * per servo its ID, goal (2 bytes) and speed (2 bytes), then the checksum. */
#define SYNC_ENTRY(i) (7u + 5u * (unsigned)(i))
typedef char sync_pkt_fits[(sizeof ((sbus_t *)0)->sync_pkt == SYNC_ENTRY(SBUS_SERVOS) + 1u) ? 1 : -1];
/* sync_fill() checks a set of values against a limit with one compare of their OR */
typedef char limits_are_all_ones[((DXL_AX_POSITION_MAX & (DXL_AX_POSITION_MAX + 1)) == 0
                                  && (DXL_AX_SPEED_MAX & (DXL_AX_SPEED_MAX + 1)) == 0) ? 1 : -1];

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
    static const uint16_t zero[SBUS_SERVOS];
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        bus->servo[i].id = ids[i];
        (void)dxl_build_read(bus->read_pkt[i], sizeof bus->read_pkt[i], ids[i], SBUS_STATUS_ADDR, SBUS_STATUS_LEN);
    }
    bus->sync_len = (uint8_t)dxl_build_sync_goal_speed(bus->sync_pkt, sizeof bus->sync_pkt, SBUS_SERVOS, ids,
                                                       zero, zero);
    /* with zero goals and speeds its checksum covers the constant bytes alone */
    bus->sync_sum0 = (uint8_t)~bus->sync_pkt[SYNC_ENTRY(SBUS_SERVOS)];
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
    bus->limp = bus->limp_pending = false;
}

void sbus_power(sbus_t *bus, bool on)
{
    bus->port->servo_power(bus->port->ctx, on);
    forget_servo_state(bus);
    bus->cfg_servo = bus->cfg_step = bus->cfg_attempt = 0;
    bus->torque_limit = TORQUE_LIMIT_SET;
    enter(bus, on ? SBUS_BOOTING : SBUS_OFF);
}

void sbus_power_limp(sbus_t *bus)
{
    sbus_power(bus, true);
    bus->limp = true;   /* configured with Torque Enable 0: nothing is commanded until sbus_limp(false) */
    bus->torque_limit = MODEL_SERVO_BENCH_TORQUE_LIMIT;   /* a wrong calibration pushes gently */
}

void sbus_full_torque(sbus_t *bus)
{
    if (bus->torque_limit == TORQUE_LIMIT_SET) return;
    bus->torque_limit = TORQUE_LIMIT_SET;
    if (bus->state != SBUS_RUNNING || bus->limp) return;   /* (written when configured, or with the torque) */
    bus->command_pending = false;
    bus->refit = (uint8_t)((1u << SBUS_SERVOS) - 1u);
}

void sbus_command(sbus_t *bus, const uint16_t goal[SBUS_SERVOS], const uint16_t speed[SBUS_SERVOS])
{
    if (bus->state != SBUS_RUNNING || bus->limp) {
        return;
    }
    memcpy(bus->goal, goal, sizeof bus->goal);
    memcpy(bus->speed, speed, sizeof bus->speed);
    bus->command_pending = true;
}

void sbus_limp(sbus_t *bus, bool on)
{
    if (bus->state != SBUS_RUNNING || on == bus->limp) return;
    bus->limp = on;
    bus->limp_pending = on;
    bus->command_pending = false;
    /* torque back on: each servo set up again as after a brown-out, holding where it stands */
    bus->refit = on ? 0u : (uint8_t)((1u << SBUS_SERVOS) - 1u);
}

void sbus_read(sbus_t *bus)
{
    if (bus->state == SBUS_RUNNING) bus->read_due = true;
}

uint32_t sbus_tick_bus_time_us(const sbus_t *bus)
{
    const uint32_t sync = 8u + 5u * SBUS_SERVOS;           /* header, addr, len, checksum + entries */
    const uint32_t read = 8u;
    const uint32_t status = DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN;
    return (sync + read + status) * bus->byte_us + RETURN_DELAY_MAX_US + REPLY_MARGIN_US;
}

/* --------------------------------------------------------------- transactions */

/* Sends the len bytes at pkt; false if len is 0 or the port cannot send now. */
static bool send(sbus_t *bus, const uint8_t *pkt, size_t len, uint8_t reply)
{
    if (len == 0 || !bus->port->servo_send(bus->port->ctx, pkt, len)) return false;
    bus->reply = reply;
    bus->phase = PHASE_SENDING;   /* (a reply's wait is timed from the end of sending) */
    return true;
}

/* Sends a request to servo s, whose status packet has n_params parameters. */
static bool request(sbus_t *bus, const uint8_t *pkt, size_t len, uint8_t reply, sbus_servo_t *s, uint8_t n_params)
{
    if ((size_t)DXL_STATUS_MIN_LEN + n_params > sizeof bus->direct || !send(bus, pkt, len, reply)) {
        return false;   /* (a reply longer than the direct check's buffer is never requested) */
    }
    bus->expect_servo = s;
    bus->expect_id = s->id;
    bus->expect_params = n_params;
    bus->expect_head[0] = bus->expect_head[1] = 0xFFu;
    bus->expect_head[2] = s->id;
    bus->expect_head[3] = (uint8_t)(n_params + 2u);
    /* a reply may take the longest return delay plus its own bytes, counted from the
     * instruction's last byte */
    bus->timeout_us = RETURN_DELAY_MAX_US + (DXL_STATUS_MIN_LEN + n_params) * bus->byte_us + REPLY_MARGIN_US;
    return true;
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
    sbus_servo_t *s = bus->expect_servo;
    dxl_parse_result_t r = dxl_parse_byte(&bus->parser, byte);
    if (r == DXL_PARSE_BAD_CHECKSUM) {
        s->bad_packets++;
    } else if (r == DXL_PARSE_COMPLETE) {
        if (bus->parser.id == bus->expect_id && bus->parser.n_params == bus->expect_params) {
            note_error_byte(s, bus->parser.error);
            bus->reply_params = bus->parser.params;
            return true;
        }
        bus->stray_packets++;   /* our own echo, or a packet meant for no request */
    }
    return false;
}

/* Do the first n (up to 5) bytes held fit FF FF ID LEN ERR, with bit 7 of the error byte
 * clear? */
static inline bool head_fits(const sbus_t *bus, unsigned n)
{
    const uint8_t *d = bus->direct;
    return (n < 1u || d[0] == 0xFFu) && (n < 2u || d[1] == 0xFFu) && (n < 3u || d[2] == bus->expect_id)
        && (n < 4u || d[3] == bus->expect_params + 2u) && (n < 5u || d[4] <= 0x7Fu);
}

static inline uint32_t word_at(const uint8_t *p)
{
    uint32_t w;
    memcpy(&w, p, sizeof w);   /* (one unaligned load on the M4) */
    return w;
}

/* The sum, mod 256, of the status reply's bytes from ID on, written out for the usual reply
 * (dxl_checksum()'s loop and call cost more than the sum): whole words, whose bytes sum to
 * the low byte of each word plus its shifts by 8, 16 and 24. */
#define STATUS_WORDS ((DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN - 2) / 4)
typedef char status_is_whole_words_from_id[(DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN - 2) % 4 == 0 ? 1 : -1];
static inline uint8_t status_sum(const uint8_t *p)
{
    uint32_t sum = 0;
    for (int k = 0; k < STATUS_WORDS; ++k) {
        const uint32_t w = word_at(p + 4 * k);
        sum += w + (w >> 8) + (w >> 16) + (w >> 24);
    }
    return (uint8_t)sum;
}

/* Do the n bytes held of the expected reply fit it? Its header, any parameters, and once all
 * are there the checksum. */
static inline __attribute__((always_inline)) bool direct_fits(const sbus_t *bus, unsigned n)
{
    const unsigned total = DXL_STATUS_MIN_LEN + bus->expect_params;
    if (n < total) return head_fits(bus, n);
    /* all of it (usually at one read): FF FF ID LEN compared as one word; with the checksum
     * byte itself, the bytes from ID on sum to 0xFF: their checksum is 0 */
    if (word_at(bus->direct) != word_at(bus->expect_head) || bus->direct[4] > 0x7Fu) {
        return false;
    }
    if (total == DXL_STATUS_MIN_LEN + SBUS_STATUS_LEN) return status_sum(bus->direct + 2) == 0xFFu;
    return dxl_checksum(bus->direct + 2, total - 2u) == 0u;
}

/* The len bytes received for the request, which do not fit the expected reply, through the
 * parser, as all that follows (receive()); true when they completed the reply. Not inlined,
 * like receive_resync(): the usual reply needs neither. */
static __attribute__((noinline)) bool resync_direct(sbus_t *bus, unsigned len)
{
    bus->resync = true;
    for (unsigned k = 0; k < len; ++k) {
        if (parse_byte(bus, bus->direct[k])) return true;
    }
    return false;
}

/* What arrived of the expected reply, read straight into bus->direct; true when it completed
 * it. At the first byte that does not fit, everything received for the request goes to the
 * parser instead. */
static inline __attribute__((always_inline)) bool receive_direct(sbus_t *bus)
{
    const unsigned total = DXL_STATUS_MIN_LEN + bus->expect_params;
    size_t n;
    while ((n = bus->port->servo_read(bus->port->ctx, bus->direct + bus->direct_len, total - bus->direct_len)) > 0) {
        const unsigned len = bus->direct_len + (unsigned)n;
        bus->direct_len = (uint8_t)len;
        if (!direct_fits(bus, len)) return resync_direct(bus, len);
        if (len == total) {
            note_error_byte(bus->expect_servo, bus->direct[4]);
            bus->reply_params = bus->direct + 5;
            return true;
        }
    }
    return false;
}

/* What arrived since, through the parser; true when it completed the reply. */
static __attribute__((noinline)) bool receive_resync(sbus_t *bus)
{
    uint8_t chunk[16];
    size_t n;
    while ((n = bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk)) > 0) {
        for (size_t i = 0; i < n; ++i) {
            if (parse_byte(bus, chunk[i])) return true;
        }
    }
    return false;
}

/* The reply so far, or the timeout. (Inlined, with receive_direct() and direct_fits():
 * sbus_poll() saves no more registers for it, and the usual reply then costs no calls.) */
static inline __attribute__((always_inline)) int receive(sbus_t *bus)
{
    /* (bytes after the reply are dropped when the next request starts) */
    if ((!bus->resync && receive_direct(bus)) || (bus->resync && receive_resync(bus))) {
        bus->phase = PHASE_IDLE;
        return DONE_OK;
    }
    if (now_us(bus) - bus->phase_us > bus->timeout_us) {
        bus->phase = PHASE_IDLE;
        return bus->reply == REPLY_OPTIONAL ? DONE_OK : DONE_TIMEOUT;
    }
    return NOT_DONE;
}

/* Advances the transaction on the wire: has it ended, and how? (Inlined: run() calls it at
 * every poll while a transaction is on.) */
static inline __attribute__((always_inline)) int transaction(sbus_t *bus)
{
    if (bus->phase == PHASE_SENDING) {
        if (bus->port->servo_busy(bus->port->ctx)) return NOT_DONE;
        if (bus->reply == REPLY_NONE) {
            bus->phase = PHASE_IDLE;
            return DONE_OK;
        }
        bus->phase = PHASE_AWAIT;
        bus->phase_us = now_us(bus);
    }
    if (bus->phase != PHASE_AWAIT) return NOT_DONE;
    return receive(bus);
}

/* Drops whatever arrived since the last request (late replies, noise). (Inlined: it comes
 * before every status read.) */
static inline __attribute__((always_inline)) void flush_rx(sbus_t *bus)
{
    uint8_t chunk[16];
    while (bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk) > 0) {
    }
    if (bus->resync) dxl_parser_reset(&bus->parser);   /* (only a resync feeds the parser) */
    bus->direct_len = 0;
    bus->resync = false;
}

/* --------------------------------------------------------------- configuration */

/* The registers as the servo should hold them (AX-12A control table, from Return Delay Time
 * on); the safety ones at the factory's values: Highest Limit Temperature 70 deg C, supply
 * 6.0-14.0 V, Max Torque 1023, Alarm Shutdown on overheating and overload (the servo drops
 * its own torque, which the tracking watch then sees). */
#define AX_HIGHEST_TEMPERATURE 11u
#define AX_ALARM_SHUTDOWN 18u
#define SAFE_TEMPERATURE_C 70u
#define SAFE_VOLTAGE_LOW 60u           /* 0.1 V */
#define SAFE_VOLTAGE_HIGH 140u
#define SAFE_SHUTDOWN 0x24u            /* overheating (bit 2), overload (bit 5) */

/* Each write, its first register and its bytes for servo i (the torque off if the bus is limp). */
static uint8_t write_of(const sbus_t *bus, unsigned w, unsigned i, uint8_t data[5])
{
    switch (w) {
    case CFG_W_SRL:
        data[0] = STATUS_RETURN_READS;
        return AX_STATUS_RETURN_LEVEL;
    case CFG_W_RETURN_DELAY:
        data[0] = MODEL_SERVO_RETURN_DELAY;
        return AX_RETURN_DELAY;
    case CFG_W_ANGLE_LIMITS:
        data[0] = (uint8_t)(CW_LIMIT[i] & 0xFFu);
        data[1] = (uint8_t)(CW_LIMIT[i] >> 8);
        data[2] = (uint8_t)(CCW_LIMIT[i] & 0xFFu);
        data[3] = (uint8_t)(CCW_LIMIT[i] >> 8);
        return AX_CW_ANGLE_LIMIT;
    case CFG_W_SAFETY:
        data[0] = SAFE_TEMPERATURE_C;
        data[1] = SAFE_VOLTAGE_LOW;
        data[2] = SAFE_VOLTAGE_HIGH;
        data[3] = (uint8_t)(MAX_TORQUE & 0xFFu);
        data[4] = (uint8_t)(MAX_TORQUE >> 8);
        return AX_HIGHEST_TEMPERATURE;
    case CFG_W_SHUTDOWN:
        data[0] = SAFE_SHUTDOWN;
        return AX_ALARM_SHUTDOWN;
    case CFG_W_TORQUE_LIMIT:
        data[0] = (uint8_t)(bus->torque_limit & 0xFFu);
        data[1] = (uint8_t)(bus->torque_limit >> 8);
        return AX_TORQUE_LIMIT;
    default:   /* CFG_W_TORQUE_ENABLE */
        data[0] = bus->limp ? 0u : 1u;
        return AX_TORQUE_ENABLE;
    }
}

static const uint8_t WRITE_LEN[CFG_WRITES] = { 1u, 1u, 4u, 5u, 1u, 2u, 1u };

/* The writes whose registers differ, in a read of addresses 5..43 (reply_params). */
static uint8_t writes_needed(const sbus_t *bus, unsigned i)
{
    uint8_t mask = 0, data[5];
    for (unsigned w = 0; w < CFG_WRITES; ++w) {
        const uint8_t addr = write_of(bus, w, i, data);
        if (memcmp(bus->reply_params + (addr - SBUS_VERIFY_ADDR), data, WRITE_LEN[w]) != 0) mask |= (uint8_t)(1u << w);
    }
    return mask;
}

static inline __attribute__((always_inline)) void take_status(sbus_t *bus, sbus_servo_t *s, const uint8_t *p);

/* Per servo: read what it holds (5..43), write what differs (EEPROM wears: nothing is
 * rewritten at every enable), read it all back. A servo that does not answer the first read
 * (Status Return Level 0) gets every write. */
static void configure(sbus_t *bus)
{
    const unsigned i = bus->cfg_servo;
    sbus_servo_t *s = &bus->servo[i];
    if (bus->phase == PHASE_IDLE) {
        flush_rx(bus);
        size_t len;
        if (bus->cfg_step == CFG_WRITE) {
            uint8_t data[5];
            const unsigned w = (unsigned)__builtin_ctz(bus->cfg_mask);
            const uint8_t addr = write_of(bus, w, i, data);
            len = dxl_build_write(bus->tx, sizeof bus->tx, s->id, addr, data, WRITE_LEN[w]);
            (void)request(bus, bus->tx, len, REPLY_OPTIONAL, s, 0);
        } else {
            len = dxl_build_read(bus->tx, sizeof bus->tx, s->id, SBUS_VERIFY_ADDR, SBUS_VERIFY_LEN);
            (void)request(bus, bus->tx, len, REPLY_REQUIRED, s, SBUS_VERIFY_LEN);
        }
        return;
    }
    const int how = transaction(bus);
    if (how == NOT_DONE) return;
    switch (bus->cfg_step) {
    case CFG_READ:
        bus->cfg_mask = how == DONE_OK ? writes_needed(bus, i) : (uint8_t)((1u << CFG_WRITES) - 1u);
        bus->cfg_step = bus->cfg_mask ? CFG_WRITE : CFG_VERIFY;
        return;
    case CFG_WRITE: {
        const unsigned w = (unsigned)__builtin_ctz(bus->cfg_mask);
        if (w < CFG_W_TORQUE_LIMIT) s->eeprom_writes++;
        bus->cfg_mask &= (uint8_t)(bus->cfg_mask - 1u);
        if (!bus->cfg_mask) bus->cfg_step = CFG_VERIFY;
        return;
    }
    default:
        break;
    }
    if (how == DONE_OK && writes_needed(bus, i) == 0) {
        take_status(bus, s, bus->reply_params + (SBUS_STATUS_ADDR - SBUS_VERIFY_ADDR));
        bus->cfg_step = CFG_READ;
        bus->cfg_attempt = 0;
        if (++bus->cfg_servo == SBUS_SERVOS) enter(bus, SBUS_RUNNING);
        return;
    }
    if (how == DONE_TIMEOUT) s->timeouts++;
    bus->cfg_step = CFG_READ;
    if (++bus->cfg_attempt >= SBUS_CONFIG_ATTEMPTS) {
        s->failed = true;
        enter(bus, SBUS_FAILED);
    } else {
        s->retries++;
    }
}

/* --------------------------------------------------------------- running */

/* A status reading of registers 32..43. Torque Limit back at Max Torque while running (the
 * full one and the bench's are both below it): the servo lost its RAM (a brown-out), its
 * torque is off and it goes limp; it is configured again at once (refit). (An overload or
 * overheating Shutdown sets Torque Limit to 0: the tracking watch's business, not a reset.) */
static inline __attribute__((always_inline)) void take_status(sbus_t *bus, sbus_servo_t *s, const uint8_t *p)
{
    const uint8_t *q = p + (AX_PRESENT_POSITION - SBUS_STATUS_ADDR);
    s->present_position = (uint16_t)(q[0] | q[1] << 8);
    s->present_speed = (uint16_t)(q[2] | q[3] << 8);
    s->present_load = (uint16_t)(q[4] | q[5] << 8);
    s->present_voltage = q[6];
    s->present_temperature = q[7];
    s->status_valid = true;
    s->failed = false;
    s->reads++;
    const uint8_t *limit = p + (AX_TORQUE_LIMIT - SBUS_STATUS_ADDR);
    const uint8_t bit = (uint8_t)(1u << (s - bus->servo));
    /* (limp: torque off on purpose; a reset then is set right when the torque comes back on,
     * by the refit already due when a reading asked for while limp comes back) */
    if ((limit[0] | limit[1] << 8) == MAX_TORQUE && bus->state == SBUS_RUNNING && !bus->limp && !(bus->refit & bit)) {
        s->resets++;
        bus->resets++;
        bus->refit |= bit;
    }
}

/* The servo's RAM as configured, in one WRITE of 24..35: torque on, holding where it stands
 * (Goal Position = Present Position, at the park speed), compliance as after power-up, Torque
 * Limit as configured (the bench's on the bench). */
static size_t build_refit(sbus_t *bus, const sbus_servo_t *s)
{
    const uint16_t at = s->present_position;
    const uint8_t data[12] = {
        1u, 0u, 1u, 1u, 32u, 32u,                              /* Torque Enable, LED, compliance */
        (uint8_t)(at & 0xFFu), (uint8_t)(at >> 8),              /* Goal Position */
        (uint8_t)(MODEL_PARK_SPEED & 0xFFu), (uint8_t)(MODEL_PARK_SPEED >> 8),
        (uint8_t)(bus->torque_limit & 0xFFu), (uint8_t)(bus->torque_limit >> 8),
    };
    return dxl_build_write(bus->tx, sizeof bus->tx, s->id, AX_TORQUE_ENABLE, data, sizeof data);
}

/* The queued goals and speeds into the SYNC_WRITE; its length, or 0 when a value is out of
 * range (the servo would answer a range error nobody hears) or the ids cannot be sent. */
static size_t sync_fill(sbus_t *bus)
{
    unsigned goals = 0, speeds = 0, sum = bus->sync_sum0;
    uint8_t *e = bus->sync_pkt + SYNC_ENTRY(0);
    for (int i = 0; i < SBUS_SERVOS; ++i, e += 5) {
        const uint32_t g = bus->goal[i], v = bus->speed[i];
        const uint32_t w = g | v << 16;   /* the entry's goal and speed bytes, first at bits 0..7 */
        goals |= g;
        speeds |= v;
        e[1] = (uint8_t)w;
        e[2] = (uint8_t)(w >> 8);
        e[3] = (uint8_t)(w >> 16);
        e[4] = (uint8_t)(w >> 24);
        sum += w + (w >> 8) + (w >> 16) + (w >> 24);   /* mod 256, the sum of those 4 bytes */
    }
    *e = (uint8_t)~sum;
    /* (a packet with a value out of range is never sent: the next command rewrites it) */
    return goals > DXL_AX_POSITION_MAX || speeds > DXL_AX_SPEED_MAX ? 0 : bus->sync_len;
}

static void run(sbus_t *bus)
{
    if (bus->phase != PHASE_IDLE) {
        const int how = transaction(bus);
        if (how == NOT_DONE || bus->reply == REPLY_NONE) return;
        if (bus->refitting) {
            bus->refitting = false;
            return;
        }
        sbus_servo_t *s = &bus->servo[bus->read_index];
        if (how == DONE_OK) {
            take_status(bus, s, bus->reply_params);
            bus->status_reads++;
            bus->last_read = bus->read_index;
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
    if (bus->limp_pending) {
        static const uint8_t torque_off = 0u;
        const size_t len = dxl_build_write(bus->tx, sizeof bus->tx, DXL_BROADCAST_ID, AX_TORQUE_ENABLE, &torque_off, 1u);
        if (send(bus, bus->tx, len, REPLY_NONE)) bus->limp_pending = false;
    } else if (bus->command_pending) {
        if (send(bus, bus->sync_pkt, sync_fill(bus), REPLY_NONE)) {
            bus->command_pending = false;
            bus->read_due = true;
            bus->sync_writes++;
        }
    } else if (bus->refit) {
        flush_rx(bus);
        const unsigned i = (unsigned)__builtin_ctz(bus->refit);
        if (request(bus, bus->tx, build_refit(bus, &bus->servo[i]), REPLY_OPTIONAL, &bus->servo[i], 0)) {
            bus->refit &= (uint8_t)~(1u << i);
            bus->refitting = true;
            bus->refits++;
        }
    } else if (bus->read_due) {
        flush_rx(bus);
        const unsigned i = bus->read_index;
        if (request(bus, bus->read_pkt[i], sizeof bus->read_pkt[i], REPLY_REQUIRED, &bus->servo[i], SBUS_STATUS_LEN)) {
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

#endif /* MODEL_DXL_PROTOCOL == 1u */
