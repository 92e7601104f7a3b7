/* X-series (Dynamixel Protocol 2.0: XL430-W250, XM430-W350) servo bus state machine, the
 * same sbus_* API as the AX-12A's servo_bus.c; see servo_bus.h. */
#include "servo_bus.h"

#include <string.h>

#include "model_params.h"

#if MODEL_DXL_PROTOCOL == 2u   /* (Protocol 1.0, the AX-12A: servo_bus.c) */

enum { PHASE_IDLE, PHASE_SENDING, PHASE_AWAIT };
enum { REPLY_NONE, REPLY_OPTIONAL, REPLY_REQUIRED };
enum { NOT_DONE, DONE_OK, DONE_TIMEOUT };   /* how a transaction stands */

/* The X-series control table, from the model's facts (model_params.h). */
#define X_RETURN_DELAY MODEL_DXL_RETURN_DELAY_TIME          /* then Drive Mode, Operating Mode */
#define X_TEMPERATURE_LIMIT MODEL_DXL_TEMPERATURE_LIMIT     /* then Max and Min Voltage Limit */
#define X_VELOCITY_LIMIT MODEL_DXL_VELOCITY_LIMIT           /* then Max and Min Position Limit */
#define X_SHUTDOWN MODEL_DXL_SHUTDOWN
#define X_TORQUE_ENABLE MODEL_DXL_TORQUE_ENABLE             /* the first RAM address */
#define X_STATUS_RETURN_LEVEL MODEL_DXL_STATUS_RETURN_LEVEL
#define X_HARDWARE_ERROR MODEL_DXL_HARDWARE_ERROR_STATUS
#define X_GOAL_PWM MODEL_DXL_GOAL_PWM
#define X_PROFILE_ACCELERATION MODEL_DXL_PROFILE_ACCELERATION   /* then Profile Velocity, Goal Position */
#define X_PROFILE_VELOCITY MODEL_DXL_GOAL_SPEED
#define X_GOAL_POSITION MODEL_DXL_GOAL_POSITION
#define X_INDIRECT_ADDRESS MODEL_DXL_INDIRECT_ADDRESS       /* Indirect Address 1 (of 28, 2 bytes each) */
/* the registers each write and read spans lie next to each other */
typedef char x_table_layout[(MODEL_DXL_OPERATING_MODE == X_RETURN_DELAY + 2u
                             && MODEL_DXL_MAX_VOLTAGE_LIMIT == X_TEMPERATURE_LIMIT + 1u
                             && MODEL_DXL_MIN_VOLTAGE_LIMIT == X_TEMPERATURE_LIMIT + 3u
                             && MODEL_DXL_PWM_LIMIT == X_TEMPERATURE_LIMIT + 5u
                             && MODEL_DXL_MAX_POSITION_LIMIT == X_VELOCITY_LIMIT + 4u
                             && MODEL_DXL_MIN_POSITION_LIMIT == X_VELOCITY_LIMIT + 8u
                             && X_PROFILE_VELOCITY == X_PROFILE_ACCELERATION + 4u
                             && X_GOAL_POSITION == X_PROFILE_VELOCITY + 4u
                             && SBUS2_STATUS_ADDR == MODEL_DXL_INDIRECT_DATA
                             && SBUS2_VERIFY_ADDR == X_RETURN_DELAY
                             && SBUS2_VERIFY_ADDR + SBUS2_VERIFY_LEN == MODEL_DXL_PRESENT_TEMPERATURE + 1u
                             && MODEL_DXL_PRESENT_LOAD_SIZE == 2u && MODEL_DXL_PRESENT_VOLTAGE_SIZE == 2u) ? 1 : -1];

/* The status map: the register behind each byte of a status reading (Indirect Address k
 * points at STATUS_MAP[k - 1]), in the order of servo_bus.h's SBUS2_AT_* */
#define BYTES2(a) (a), (a) + 1u
#define BYTES4(a) (a), (a) + 1u, (a) + 2u, (a) + 3u
static const uint16_t STATUS_MAP[SBUS2_STATUS_LEN] = {
    X_TORQUE_ENABLE, X_STATUS_RETURN_LEVEL, X_HARDWARE_ERROR, BYTES2(MODEL_DXL_PRESENT_LOAD),
    BYTES2(MODEL_DXL_PRESENT_SPEED), BYTES4(MODEL_DXL_PRESENT_POSITION), MODEL_DXL_PRESENT_VOLTAGE,
    MODEL_DXL_PRESENT_TEMPERATURE
};
typedef char status_map_order[(SBUS2_AT_STATUS_RETURN_LEVEL == SBUS2_AT_TORQUE_ENABLE + 1
                               && SBUS2_AT_HARDWARE_ERROR == SBUS2_AT_STATUS_RETURN_LEVEL + 1
                               && SBUS2_AT_CURRENT == SBUS2_AT_HARDWARE_ERROR + 1
                               && SBUS2_AT_VELOCITY == SBUS2_AT_CURRENT + 2
                               && SBUS2_AT_POSITION == SBUS2_AT_VELOCITY + 2
                               && SBUS2_AT_VOLTAGE == SBUS2_AT_POSITION + 4
                               && SBUS2_AT_TEMPERATURE == SBUS2_AT_VOLTAGE + 1
                               && SBUS2_STATUS_LEN == SBUS2_AT_TEMPERATURE + 1
                               && SBUS2_STATUS_LEN <= 28) ? 1 : -1];   /* (Indirect Address 1..28) */

#define STATUS_RETURN_READS 1u        /* answer PING and READ only */
#define POSITION_CONTROL 3u           /* Operating Mode */
#define DRIVE_MODE 0u                 /* normal direction, velocity-based profile */
/* The safety registers at the factory's values (e-manual control tables): Temperature Limit,
 * the supply's limits (0.1 V), PWM Limit (100 %), and Shutdown on overheating, electrical shock and overload
 * (the servo drops its own torque and raises Hardware Error Status until rebooted). */
#if defined(MODEL_DXL_XM430_W350)
#define SAFE_TEMPERATURE_C 80u
#define SAFE_VOLTAGE_HIGH 160u
#define SAFE_VOLTAGE_LOW 95u
#elif defined(MODEL_DXL_XL430_W250)
#define SAFE_TEMPERATURE_C 72u
#define SAFE_VOLTAGE_HIGH 140u
#define SAFE_VOLTAGE_LOW 60u
#else
#error "servo_bus2.c knows the safety limits of the XM430-W350 and XL430-W250 only"
#endif
#define SAFE_SHUTDOWN 0x34u
#define PWM_LIMIT 885u
/* The torque cap (Goal PWM): in full, or servo.bench_torque_limit of it on the bench (the
 * model gives that share in 1023ths) */
#define GOAL_PWM_FULL PWM_LIMIT
#define GOAL_PWM_BENCH ((PWM_LIMIT * MODEL_SERVO_BENCH_TORQUE_LIMIT + 511u) / 1023u)
/* Velocity Limit: Profile Velocity above it is refused, so it is the model's top speed */
#define VELOCITY_LIMIT MODEL_DXL_SPEED_MAX
/* The status map reads Present Velocity's low two bytes and Present Input Voltage's low one:
 * enough while the velocity stays within Velocity Limit and the supply within the servo's
 * voltage limit. */
typedef char status_map_widths[(VELOCITY_LIMIT <= 32767u && SAFE_VOLTAGE_HIGH <= 255u) ? 1 : -1];
/* The longest a servo may wait before answering: Return Delay Time 254 x 2 us. */
#define RETURN_DELAY_MAX_US 508u
#define REPLY_MARGIN_US 1000u
#define INSTRUCTION_LEN 10u           /* header, ID, LEN, instruction, CRC */
#define READ_LEN (INSTRUCTION_LEN + 4u)
#define SYNC_ENTRY_LEN 8u             /* Profile Velocity, Goal Position */
#define SYNC_HEAD 12u                 /* FF FF FD 00, ID, LEN, instruction, address, data length */
#define SYNC_LEN (SYNC_HEAD + (1u + SYNC_ENTRY_LEN) * SBUS_SERVOS + 2u)
typedef char packet_sizes[(READ_LEN == SBUS2_READ_LEN && SYNC_LEN == SBUS2_SYNC_MAX) ? 1 : -1];
/* The SYNC_WRITE is never stuffed, so its length is fixed and its entries are written in
 * place: an ID is at most 0xFC, and a value below 0xFF00 has no FF above its lowest byte, so
 * no FF FF (let alone FF FF FD) can stand anywhere from its instruction on. */
typedef char sync_write_never_stuffed[(MODEL_DXL_POSITION_MAX < 0xFF00u && MODEL_DXL_SPEED_MAX < 0xFF00u
                                       && X_PROFILE_VELOCITY < 0xFF00u) ? 1 : -1];
#define READING_CRC_BYTES (1u + SBUS2_STATUS_LEN)   /* a status reading's error byte and parameters */
#define READING_LEN (DXL2_STATUS_MIN_LEN + SBUS2_STATUS_LEN)

/* The CRC's share of each byte that changes from packet to packet (dxl2_crc_shares): of the
 * SYNC_WRITE's speeds and goals their two low bytes (the two high ones are 0), of a status
 * reading its error byte and parameters. One lookup a byte: a tick's CRCs cost a third of
 * what they cost byte by byte. The same for every bus: filled by the first sbus_init. */
static uint16_t sync_shares[SBUS_SERVOS][4][256];
static uint16_t reading_shares[READING_CRC_BYTES][256];
static bool shares_filled;

static void fill_shares(void)
{
    if (shares_filled) return;
    const unsigned values = (1u + SYNC_ENTRY_LEN) * SBUS_SERVOS;   /* the bytes from the first ID to the CRC */
    static const uint8_t at[4] = { 1u, 2u, 5u, 6u };   /* in an entry: ID, speed's 4 bytes, goal's 4 */
    for (unsigned i = 0; i < SBUS_SERVOS; ++i) {
        for (unsigned k = 0; k < 4u; ++k) {
            dxl2_crc_shares(sync_shares[i][k], values - 1u - ((1u + SYNC_ENTRY_LEN) * i + at[k]));
        }
    }
    for (unsigned k = 0; k < READING_CRC_BYTES; ++k) {
        dxl2_crc_shares(reading_shares[k], READING_CRC_BYTES - 1u - k);
    }
    shares_filled = true;
}

enum { CFG_READ, CFG_WRITE, CFG_VERIFY, CFG_STATUS };   /* configuration steps of each servo */
/* its writes, in order (bits of sbus_t.cfg_mask): the torque off if the EEPROM must be
 * written (it is locked while the torque is on), the EEPROM ones, then the RAM ones */
enum { W_TORQUE_OFF, W_MODES, W_SAFETY, W_LIMITS, W_SHUTDOWN, W_SRL, W_MAP, W_GOAL_PWM, W_PROFILE,
       W_TORQUE_ENABLE, CFG_WRITES };
#define EEPROM_WRITES ((1u << W_MODES) | (1u << W_SAFETY) | (1u << W_LIMITS) | (1u << W_SHUTDOWN))
/* A servo found reset (its RAM back at the power-on values) is set up again by these. */
enum { R_SRL, R_GOAL_PWM, R_HOLD, R_TORQUE_ON, REFIT_WRITES };
#define WRITE_MAX (2u * SBUS2_STATUS_LEN)   /* the status map */

static const uint16_t MIN_LIMIT[SBUS_SERVOS] = { MODEL_SERVO1_CW_LIMIT, MODEL_SERVO2_CW_LIMIT, MODEL_SERVO3_CW_LIMIT };
static const uint16_t MAX_LIMIT[SBUS_SERVOS] = { MODEL_SERVO1_CCW_LIMIT, MODEL_SERVO2_CCW_LIMIT, MODEL_SERVO3_CCW_LIMIT };

static uint32_t now_us(const sbus_t *bus)
{
    return bus->port->time_us(bus->port->ctx);
}

static void enter(sbus_t *bus, sbus_state_t state)
{
    bus->state = state;
    bus->since_us = now_us(bus);
}

/* (The Cortex-M4 and the host are little-endian, as the protocol: a word is written whole.) */
typedef char little_endian[(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__) ? 1 : -1];

static void put32(uint8_t *p, uint32_t v)
{
    memcpy(p, &v, sizeof v);
}

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static uint32_t get32(const uint8_t *p)
{
    uint32_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

static uint16_t get16(const uint8_t *p)
{
    uint16_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

/* The first 8 bytes of servo id's status packet with n_params parameters: FF FF FD 00 ID
 * LEN_L LEN_H 55 (then the error byte); the CRC of them. */
static uint16_t status_head(uint8_t head[8], uint8_t id, unsigned n_params)
{
    const unsigned len = n_params + 4u;   /* instruction, error, parameters, CRC */
    const uint8_t h[8] = { 0xFFu, 0xFFu, 0xFDu, 0x00u, id, (uint8_t)(len & 0xFFu), (uint8_t)(len >> 8), DXL2_INST_STATUS };
    memcpy(head, h, sizeof h);
    return dxl2_crc(0, h, sizeof h);
}

void sbus_init(sbus_t *bus, const port_t *port, const uint8_t ids[SBUS_SERVOS], uint32_t baud)
{
    memset(bus, 0, sizeof *bus);
    fill_shares();
    bus->port = port;
    bus->byte_us = (10u * 1000000u + baud - 1u) / baud;   /* start + 8 data + stop bits */
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        bus->servo[i].id = ids[i];
        bus->read2_len[i] = (uint8_t)dxl2_build_read(bus->read2_pkt[i], sizeof bus->read2_pkt[i], ids[i],
                                                     SBUS2_STATUS_ADDR, SBUS2_STATUS_LEN);
        static const uint8_t zero_reading[READING_CRC_BYTES];
        bus->reply2_crc0[i] = dxl2_crc(status_head(bus->reply2_head[i], ids[i], SBUS2_STATUS_LEN), zero_reading,
                                       sizeof zero_reading);
    }
    /* the SYNC_WRITE with every value 0: its head and IDs stay, the values and CRC change */
    static const uint8_t zeros[SBUS_SERVOS * SYNC_ENTRY_LEN];
    bus->sync2_len = (uint8_t)dxl2_build_sync_write(bus->sync2_pkt, sizeof bus->sync2_pkt, X_PROFILE_VELOCITY,
                                                    SYNC_ENTRY_LEN, SBUS_SERVOS, ids, zeros);
    bus->sync2_crc0 = get16(bus->sync2_pkt + SYNC_LEN - 2u);
    (void)dxl2_parser_init(&bus->parser2, bus->rx2_buf, sizeof bus->rx2_buf);
    enter(bus, SBUS_OFF);
}

/* Everything that describes the servos' live state goes stale with their power. */
static void forget_servo_state(sbus_t *bus)
{
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        bus->servo[i].status_valid = false;
        bus->servo[i].failed = false;
        bus->servo[i].last_error = 0;
        bus->servo[i].hardware_error = 0;
    }
    bus->phase = PHASE_IDLE;
    bus->command_pending = false;
    bus->read_due = false;
    bus->read_attempt = 0;
    bus->limp = bus->limp_pending = false;
    bus->refit = bus->refit_steps = 0;
    bus->refitting = false;
    bus->remap = 0;
    bus->remapping = false;
}

void sbus_power(sbus_t *bus, bool on)
{
    bus->port->servo_power(bus->port->ctx, on);
    forget_servo_state(bus);
    bus->cfg_servo = bus->cfg_step = bus->cfg_attempt = 0;
    bus->torque_limit = GOAL_PWM_FULL;
    enter(bus, on ? SBUS_BOOTING : SBUS_OFF);
}

void sbus_power_limp(sbus_t *bus)
{
    sbus_power(bus, true);
    bus->limp = true;   /* configured with Torque Enable 0: nothing is commanded until sbus_limp(false) */
    bus->torque_limit = GOAL_PWM_BENCH;   /* a wrong calibration pushes gently */
}

void sbus_full_torque(sbus_t *bus)
{
    if (bus->torque_limit == GOAL_PWM_FULL) return;
    bus->torque_limit = GOAL_PWM_FULL;
    if (bus->state != SBUS_RUNNING || bus->limp) return;   /* (written when configured, or with the torque) */
    bus->command_pending = false;
    bus->refit = (uint8_t)((1u << SBUS_SERVOS) - 1u);
}

void sbus_command(sbus_t *bus, const uint16_t goal[SBUS_SERVOS], const uint16_t speed[SBUS_SERVOS])
{
    if (bus->state != SBUS_RUNNING || bus->limp) return;
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
    if (on) bus->refit_steps = 0;   /* (a refit under way stops: no torque on after the limp) */
}

void sbus_read(sbus_t *bus)
{
    if (bus->state == SBUS_RUNNING) bus->read_due = true;
}

uint32_t sbus_tick_bus_time_us(const sbus_t *bus)
{
    const uint32_t status = DXL2_STATUS_MIN_LEN + SBUS2_STATUS_LEN;
    return (SYNC_LEN + READ_LEN + status) * bus->byte_us + RETURN_DELAY_MAX_US + REPLY_MARGIN_US;
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

/* Sends the len bytes at pkt to servo s, whose status packet has n_params parameters. */
static inline __attribute__((always_inline)) bool request(sbus_t *bus, const uint8_t *pkt, size_t len, uint8_t reply, sbus_servo_t *s, uint8_t n_params)
{
    if (!send(bus, pkt, len, reply)) return false;
    bus->expect_servo = s;
    bus->expect_id = s->id;
    bus->expect_params = n_params;
    const unsigned i = (unsigned)(s - bus->servo);
    if (n_params == SBUS2_STATUS_LEN) {   /* a status reading's: built at init */
        bus->expect2_head = bus->reply2_head[i];
        bus->expect2_crc = bus->reply2_crc0[i];
    } else {
        bus->expect2_crc = status_head(bus->other2_head, s->id, n_params);
        bus->expect2_head = bus->other2_head;
    }
    /* a reply may take the longest return delay plus its own bytes, counted from the
     * instruction's last byte */
    bus->timeout_us = RETURN_DELAY_MAX_US + (DXL2_STATUS_MIN_LEN + n_params) * bus->byte_us + REPLY_MARGIN_US;
    return true;
}

/* The status error byte: the alert (bit 7: Hardware Error Status is not 0) and the error
 * number, counted in error_bits[number - 1]. */
static void note_error_byte(sbus_servo_t *s, uint8_t error)
{
    s->last_error = error;
    if (error == 0) return;
    s->error_packets++;
    const unsigned number = error & 0x7Fu;
    if (number >= 1u && number <= 7u) s->error_bits[number - 1u]++;
}

/* One received byte through the resynchronising parser; true when it completed the reply. */
static bool parse_byte(sbus_t *bus, uint8_t byte)
{
    sbus_servo_t *s = bus->expect_servo;
    const dxl2_parse_result_t r = dxl2_parse_byte(&bus->parser2, byte);
    if (r == DXL2_PARSE_BAD_CRC || r == DXL2_PARSE_BAD_STUFFING) {
        s->bad_packets++;
    } else if (r == DXL2_PARSE_COMPLETE) {
        if (bus->parser2.id == bus->expect_id && bus->parser2.n_params == bus->expect_params) {
            note_error_byte(s, bus->parser2.error);
            bus->reply_params = bus->parser2.params;
            return true;
        }
        if (bus->parser2.id == bus->expect_id && bus->parser2.n_params == 0u && (bus->parser2.error & 0x7Fu) != 0u) {
            /* the servo refused the request, its error number without parameters: shown, and
             * the request fails as if unanswered */
            note_error_byte(s, bus->parser2.error);
            return false;
        }
        bus->stray_packets++;   /* a packet meant for no request (the parser skips our own echo) */
    }
    return false;
}

/* Do the first n bytes held fit the expected reply's head, FF FF FD 00 ID LEN_L LEN_H 55? */
static bool head_fits(const sbus_t *bus, unsigned n)
{
    const uint8_t *d = bus->direct2, *head = bus->expect2_head;
    if (n >= 8u) return get32(d) == get32(head) && get32(d + 4) == get32(head + 4);   /* (the usual: all at once) */
    for (unsigned k = 0; k < n; ++k) {
        if (d[k] != head[k]) return false;
    }
    return true;
}

/* Does an FF FF FD stand in d[first - 2 .. end - 1] with its FD at first or later? An FD is
 * rare: four bytes at a time are looked at for one (a word with a zero byte where an FD
 * was) before any byte is looked at closely. */
static inline __attribute__((always_inline)) bool has_ff_ff_fd(const uint8_t *d, unsigned first, unsigned end)
{
    uint32_t fd_bytes = 0;
    unsigned k = first;
    for (; k + 4u <= end; k += 4u) {
        const uint32_t w = get32(d + k) ^ 0xFDFDFDFDu;
        fd_bytes |= (w - 0x01010101u) & ~w;
    }
    if (k < end && end >= first + 4u) {   /* the last bytes: a word overlapping the one before */
        const uint32_t w = get32(d + end - 4u) ^ 0xFDFDFDFDu;
        fd_bytes |= (w - 0x01010101u) & ~w;
        k = end;
    }
    for (k = (fd_bytes & 0x80808080u) != 0u ? first : k; k < end; ++k) {
        if (d[k] == 0xFDu && d[k - 1u] == 0xFFu && d[k - 2u] == 0xFFu) return true;
    }
    return false;
}

/* All total bytes of the expected reply held (its first 8 fit): is its CRC right, with no
 * FF FF FD from the instruction to the last parameter? (A servo stuffs one, which lengthens
 * LEN: the parser judges that reply.) */
static bool whole_fits(const sbus_t *bus, unsigned total)
{
    const uint8_t *d = bus->direct2;
    if (bus->expect_params != SBUS2_STATUS_LEN) {   /* not a status reading (request) */
        return dxl2_crc(bus->expect2_crc, d + 8, total - 10u) == get16(d + total - 2u) && !has_ff_ff_fd(d, 9u, total - 2u);
    }
    /* a status reading, of a length known here: the loops unrolled (a CRC lookup is then 4
     * instructions; 32 is more than READING_CRC_BYTES can be, at most 1 + 28) */
    uint32_t crc = bus->expect2_crc;
#pragma GCC unroll 32
    for (unsigned k = 0; k < READING_CRC_BYTES; ++k) crc ^= reading_shares[k][d[8u + k]];
    return crc == get16(d + READING_LEN - 2u) && !has_ff_ff_fd(d, 9u, READING_LEN - 2u);
}

/* The len bytes received for the request, which do not fit the expected reply, through the
 * parser, as all that follows; true when they completed the reply. */
static bool resync_direct(sbus_t *bus, unsigned len)
{
    bus->resync = true;
    for (unsigned k = 0; k < len; ++k) {
        if (parse_byte(bus, bus->direct2[k])) return true;
    }
    return false;
}

/* What arrived of the expected reply, read straight into bus->direct2; true when it completed
 * it. At the first byte that does not fit, everything received for the request goes to the
 * parser instead. (The parser costs hundreds of cycles a byte: the usual reply needs none.) */
static inline __attribute__((always_inline)) bool receive_direct(sbus_t *bus)
{
    const unsigned total = DXL2_STATUS_MIN_LEN + bus->expect_params;
    size_t n;
    while ((n = bus->port->servo_read(bus->port->ctx, bus->direct2 + bus->direct_len, total - bus->direct_len)) > 0) {
        const unsigned len = bus->direct_len + (unsigned)n;
        bus->direct_len = (uint8_t)len;
        if (!head_fits(bus, len) || (len == total && !whole_fits(bus, total))) return resync_direct(bus, len);
        if (len == total) {
            note_error_byte(bus->expect_servo, bus->direct2[8]);
            bus->reply_params = bus->direct2 + 9;
            return true;
        }
    }
    return false;
}

/* What arrived since, through the parser; true when it completed the reply. */
static bool receive_resync(sbus_t *bus)
{
    uint8_t chunk[16];
    size_t n;
    while ((n = bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk)) > 0) {
        for (size_t i = 0; i < n; ++i) {
            if (parse_byte(bus, chunk[i])) return true;   /* (bytes after the reply are dropped at the next request) */
        }
    }
    return false;
}

/* The reply so far, or the timeout. */
static inline __attribute__((always_inline)) int receive(sbus_t *bus)
{
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

/* Advances the transaction on the wire: has it ended, and how? */
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

/* Drops whatever arrived since the last request (late replies, noise). */
static inline __attribute__((always_inline)) void flush_rx(sbus_t *bus)
{
    uint8_t chunk[16];
    while (bus->port->servo_read(bus->port->ctx, chunk, sizeof chunk) > 0) {
    }
    if (bus->resync) dxl2_parser_reset(&bus->parser2);   /* (only a resync feeds the parser) */
    bus->direct_len = 0;
    bus->resync = false;
}

/* --------------------------------------------------------------- configuration */

static const uint8_t WRITE_LEN[CFG_WRITES] = { 1u, 3u, 7u, 12u, 1u, 1u, WRITE_MAX, 2u, 8u, 1u };

/* Each write, its first register and its bytes for servo i (the torque off if the bus is limp). */
static uint8_t write_of(const sbus_t *bus, unsigned w, unsigned i, uint8_t data[WRITE_MAX])
{
    switch (w) {
    case W_TORQUE_OFF:
        data[0] = 0u;
        return X_TORQUE_ENABLE;
    case W_MODES:
        data[0] = MODEL_SERVO_RETURN_DELAY;
        data[1] = DRIVE_MODE;
        data[2] = POSITION_CONTROL;
        return X_RETURN_DELAY;
    case W_SAFETY:
        data[0] = SAFE_TEMPERATURE_C;
        data[1] = (uint8_t)(SAFE_VOLTAGE_HIGH & 0xFFu);
        data[2] = (uint8_t)(SAFE_VOLTAGE_HIGH >> 8);
        data[3] = (uint8_t)(SAFE_VOLTAGE_LOW & 0xFFu);
        data[4] = (uint8_t)(SAFE_VOLTAGE_LOW >> 8);
        data[5] = (uint8_t)(PWM_LIMIT & 0xFFu);
        data[6] = (uint8_t)(PWM_LIMIT >> 8);
        return X_TEMPERATURE_LIMIT;
    case W_LIMITS:   /* the joint limits in servo units: the servo itself refuses a goal outside */
        put32(data, VELOCITY_LIMIT);
        put32(data + 4, MAX_LIMIT[i]);
        put32(data + 8, MIN_LIMIT[i]);
        return X_VELOCITY_LIMIT;
    case W_SHUTDOWN:
        data[0] = SAFE_SHUTDOWN;
        return X_SHUTDOWN;
    case W_SRL:
        data[0] = STATUS_RETURN_READS;
        return X_STATUS_RETURN_LEVEL;
    case W_MAP:
        for (unsigned k = 0; k < SBUS2_STATUS_LEN; ++k) put16(data + 2u * k, STATUS_MAP[k]);
        return X_INDIRECT_ADDRESS;
    case W_GOAL_PWM:
        data[0] = (uint8_t)(bus->torque_limit & 0xFFu);
        data[1] = (uint8_t)(bus->torque_limit >> 8);
        return X_GOAL_PWM;
    case W_PROFILE:   /* no acceleration ramp (0: at once), the park speed until the first command */
        put32(data, 0u);
        put32(data + 4, MODEL_PARK_SPEED);
        return X_PROFILE_ACCELERATION;
    default:   /* W_TORQUE_ENABLE */
        data[0] = bus->limp ? 0u : 1u;
        return X_TORQUE_ENABLE;
    }
}

/* The writes whose registers differ, in a reading from Return Delay Time on (reply_params).
 * (The status map lies past it: it is written at every configuration and proved by a reading
 * through it.) */
static uint16_t writes_needed(const sbus_t *bus, unsigned i)
{
    uint16_t mask = 0;
    uint8_t data[WRITE_MAX];
    for (unsigned w = W_MODES; w < CFG_WRITES; ++w) {
        if (w == W_MAP) continue;
        const uint8_t addr = write_of(bus, w, i, data);
        if (memcmp(bus->reply_params + (addr - SBUS2_VERIFY_ADDR), data, WRITE_LEN[w]) != 0) mask |= (uint16_t)(1u << w);
    }
    if ((mask & EEPROM_WRITES) && bus->reply_params[X_TORQUE_ENABLE - SBUS2_VERIFY_ADDR] != 0u) {
        mask |= 1u << W_TORQUE_OFF;
    }
    return mask;
}

static inline __attribute__((always_inline)) void take_status(sbus_t *bus, sbus_servo_t *s, const uint8_t *p);

/* Is a status reading the servo's state? A servo that answers a READ has Status Return Level
 * 1 or 2: 0 there is its status map back at the initial values (the RAM lost with the power),
 * every byte of the reading 0. */
static bool mapped(const uint8_t *p)
{
    return p[SBUS2_AT_STATUS_RETURN_LEVEL] != 0u;
}

/* Per servo: read what it holds (Return Delay Time .. Present Temperature), write what
 * differs (EEPROM wears: nothing is rewritten at every enable) and the status map, read it
 * all back, then read the status through the map. A servo that does not answer the first
 * read gets every write. */
static void configure(sbus_t *bus)
{
    const unsigned i = bus->cfg_servo;
    sbus_servo_t *s = &bus->servo[i];
    if (bus->phase == PHASE_IDLE) {
        flush_rx(bus);
        if (bus->cfg_step == CFG_WRITE) {
            uint8_t data[WRITE_MAX];
            const unsigned w = (unsigned)__builtin_ctz(bus->cfg_mask);
            const uint8_t addr = write_of(bus, w, i, data);
            const size_t len = dxl2_build_write(bus->tx, sizeof bus->tx, s->id, addr, data, WRITE_LEN[w]);
            (void)request(bus, bus->tx, len, REPLY_OPTIONAL, s, 0);
        } else if (bus->cfg_step == CFG_STATUS) {
            (void)request(bus, bus->read2_pkt[i], bus->read2_len[i], REPLY_REQUIRED, s, SBUS2_STATUS_LEN);
        } else {
            const size_t len = dxl2_build_read(bus->tx, sizeof bus->tx, s->id, SBUS2_VERIFY_ADDR, SBUS2_VERIFY_LEN);
            (void)request(bus, bus->tx, len, REPLY_REQUIRED, s, SBUS2_VERIFY_LEN);
        }
        return;
    }
    const int how = transaction(bus);
    if (how == NOT_DONE) return;
    switch (bus->cfg_step) {
    case CFG_READ:
        bus->cfg_mask = how == DONE_OK ? (uint16_t)(writes_needed(bus, i) | 1u << W_MAP)
                                       : (uint16_t)((1u << CFG_WRITES) - 1u);
        bus->cfg_step = CFG_WRITE;
        return;
    case CFG_WRITE: {
        const unsigned w = (unsigned)__builtin_ctz(bus->cfg_mask);
        if ((1u << w) & EEPROM_WRITES) s->eeprom_writes++;
        bus->cfg_mask &= (uint16_t)(bus->cfg_mask - 1u);
        if (!bus->cfg_mask) bus->cfg_step = CFG_VERIFY;
        return;
    }
    default:
        break;
    }
    if (how == DONE_OK && bus->cfg_step == CFG_VERIFY && writes_needed(bus, i) == 0) {
        bus->cfg_step = CFG_STATUS;
        return;
    }
    if (how == DONE_OK && bus->cfg_step == CFG_STATUS && mapped(bus->reply_params)) {
        take_status(bus, s, bus->reply_params);
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

/* A signed reading as the AX-12A's registers give it: the magnitude (at most 1023), bit 10
 * set for the negative (clockwise) direction. */
static uint16_t ax_style(int32_t v)
{
    const uint32_t magnitude = v < 0 ? (uint32_t)(-(int64_t)v) : (uint32_t)v;
    return (uint16_t)((magnitude > 1023u ? 1023u : magnitude) | (v < 0 ? 0x400u : 0u));
}

/* A status reading through the map (mapped). Torque Enable 0 while running,
 * with no hardware error: the servo lost its RAM (a supply dip resets it, torque off) and
 * goes limp; it is set up again at once (refit). (A hardware error turns the torque off
 * too: that servo stays off until rebooted, reported by its error byte's alert bit.) */
static inline __attribute__((always_inline)) void take_status(sbus_t *bus, sbus_servo_t *s, const uint8_t *p)
{
    const int32_t position = (int32_t)get32(p + SBUS2_AT_POSITION);
    s->present_position = (uint16_t)(position < 0 ? 0u : position > (int32_t)MODEL_DXL_POSITION_MAX
                                      ? MODEL_DXL_POSITION_MAX : (uint32_t)position);
    s->present_speed = ax_style((int16_t)get16(p + SBUS2_AT_VELOCITY));
    s->present_current = (int16_t)get16(p + SBUS2_AT_CURRENT);
    s->present_load = ax_style(s->present_current);
    s->present_voltage = p[SBUS2_AT_VOLTAGE];
    s->present_temperature = p[SBUS2_AT_TEMPERATURE];
    s->hardware_error = p[SBUS2_AT_HARDWARE_ERROR];
    for (unsigned bits = s->hardware_error; bits != 0u; bits &= bits - 1u) {
        s->hardware_error_bits[__builtin_ctz(bits)]++;
    }
    s->status_valid = true;
    s->failed = false;
    s->reads++;
    const unsigned i = (unsigned)(s - bus->servo);
    const uint8_t bit = (uint8_t)(1u << i);
    const bool refit_under_way = bus->refit_steps != 0 && bus->refit_servo == i;
    /* (limp: torque off on purpose; a reset then is set right when the torque comes back on) */
    if (p[SBUS2_AT_TORQUE_ENABLE] == 0u && s->hardware_error == 0u && bus->state == SBUS_RUNNING && !bus->limp
        && !(bus->refit & bit) && !refit_under_way) {
        s->resets++;
        bus->resets++;
        bus->refit |= bit;
    }
}

/* The refit's next write to servo refit_servo: Status Return Level 1, the torque cap as
 * configured, holding where it stands (no acceleration ramp, the park speed, Goal Position =
 * Present Position), then the torque on. */
static size_t build_refit(sbus_t *bus)
{
    const sbus_servo_t *s = &bus->servo[bus->refit_servo];
    uint8_t data[WRITE_MAX];
    switch (__builtin_ctz(bus->refit_steps)) {
    case R_SRL:
        data[0] = STATUS_RETURN_READS;
        return dxl2_build_write(bus->tx, sizeof bus->tx, s->id, X_STATUS_RETURN_LEVEL, data, 1u);
    case R_GOAL_PWM:
        data[0] = (uint8_t)(bus->torque_limit & 0xFFu);
        data[1] = (uint8_t)(bus->torque_limit >> 8);
        return dxl2_build_write(bus->tx, sizeof bus->tx, s->id, X_GOAL_PWM, data, 2u);
    case R_HOLD:
        put32(data, 0u);
        put32(data + 4, MODEL_PARK_SPEED);
        put32(data + 8, s->present_position);
        return dxl2_build_write(bus->tx, sizeof bus->tx, s->id, X_PROFILE_ACCELERATION, data, 12u);
    default:   /* R_TORQUE_ON */
        data[0] = 1u;
        return dxl2_build_write(bus->tx, sizeof bus->tx, s->id, X_TORQUE_ENABLE, data, 1u);
    }
}

/* The queued speeds and goals into the SYNC_WRITE; its length, or 0 when a value is out of
 * its register's range (nobody would hear the servo's error). */
static size_t sync_fill(sbus_t *bus)
{
    uint8_t *entry = bus->sync2_pkt + SYNC_HEAD;   /* ID, Profile Velocity, Goal Position */
    uint16_t crc = bus->sync2_crc0;
    for (int i = 0; i < SBUS_SERVOS; ++i, entry += 1u + SYNC_ENTRY_LEN) {
        const unsigned speed = bus->speed[i], goal = bus->goal[i];
        if (goal > MODEL_DXL_POSITION_MAX || speed > MODEL_DXL_SPEED_MAX) return 0;
        put32(entry + 1, speed);
        put32(entry + 5, goal);
        const uint16_t (*share)[256] = sync_shares[i];
        crc ^= share[0][speed & 0xFFu] ^ share[1][speed >> 8] ^ share[2][goal & 0xFFu] ^ share[3][goal >> 8];
    }
    bus->sync2_pkt[SYNC_LEN - 2u] = (uint8_t)crc;
    bus->sync2_pkt[SYNC_LEN - 1u] = (uint8_t)(crc >> 8);
    return bus->sync2_len;
}

/* A status read's end: the reading, or a retry, or the servo marked failed; then the next.
 * A reading with the status map lost is no reading: the map is written again and the same
 * servo read again at once. */
static void read_done(sbus_t *bus, int how)
{
    sbus_servo_t *s = &bus->servo[bus->read_index];
    const bool map_lost = how == DONE_OK && !mapped(bus->reply_params);
    if (how == DONE_OK && !map_lost) {
        take_status(bus, s, bus->reply_params);
        bus->status_reads++;
        bus->last_read = bus->read_index;
    } else {
        if (map_lost) {
            bus->remap |= (uint8_t)(1u << bus->read_index);
        } else {
            s->timeouts++;
        }
        if (bus->read_attempt < SBUS_READ_RETRIES) {
            bus->read_attempt++;
            s->retries++;
            if (map_lost) bus->read_due = true;
            return;   /* the same servo again: after the next command, or once its map is written */
        }
        s->failed = true;
    }
    bus->read_attempt = 0;
    bus->read_index = (uint8_t)(bus->read_index + 1u < SBUS_SERVOS ? bus->read_index + 1u : 0u);
}

static void run(sbus_t *bus)
{
    if (bus->phase != PHASE_IDLE) {
        const int how = transaction(bus);
        if (how == NOT_DONE || bus->reply == REPLY_NONE) return;
        if (bus->remapping) {
            bus->remapping = false;
            return;
        }
        if (bus->refitting) {
            bus->refit_steps &= (uint8_t)(bus->refit_steps - 1u);
            bus->refitting = bus->refit_steps != 0;
            return;
        }
        read_done(bus, how);
        return;
    }
    if (!bus->refit_steps) bus->refitting = false;
    if (bus->limp_pending) {
        static const uint8_t torque_off = 0u;
        const size_t len = dxl2_build_write(bus->tx, sizeof bus->tx, DXL2_BROADCAST_ID, X_TORQUE_ENABLE, &torque_off, 1u);
        if (send(bus, bus->tx, len, REPLY_NONE)) bus->limp_pending = false;
    } else if (bus->command_pending) {
        if (send(bus, bus->sync2_pkt, sync_fill(bus), REPLY_NONE)) {
            bus->command_pending = false;
            bus->read_due = true;
            bus->sync_writes++;
        }
    } else if (bus->remap) {
        const unsigned i = (unsigned)__builtin_ctz(bus->remap);
        uint8_t data[WRITE_MAX];
        const uint8_t addr = write_of(bus, W_MAP, i, data);
        const size_t len = dxl2_build_write(bus->tx, sizeof bus->tx, bus->servo[i].id, addr, data, WRITE_LEN[W_MAP]);
        flush_rx(bus);
        if (request(bus, bus->tx, len, REPLY_OPTIONAL, &bus->servo[i], 0)) {
            bus->remap &= (uint8_t)~(1u << i);
            bus->remapping = true;
            bus->remaps++;
        }
    } else if (bus->refit_steps || bus->refit) {
        if (!bus->refit_steps) {
            const unsigned i = (unsigned)__builtin_ctz(bus->refit);
            bus->refit &= (uint8_t)~(1u << i);
            bus->refit_servo = (uint8_t)i;
            bus->refit_steps = (uint8_t)((1u << REFIT_WRITES) - 1u);
            bus->refits++;
        }
        flush_rx(bus);
        bus->refitting = true;
        (void)request(bus, bus->tx, build_refit(bus), REPLY_OPTIONAL, &bus->servo[bus->refit_servo], 0);
    } else if (bus->read_due) {
        flush_rx(bus);
        const unsigned i = bus->read_index;
        if (request(bus, bus->read2_pkt[i], bus->read2_len[i], REPLY_REQUIRED, &bus->servo[i], SBUS2_STATUS_LEN)) {
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

#endif /* MODEL_DXL_PROTOCOL == 2u */
