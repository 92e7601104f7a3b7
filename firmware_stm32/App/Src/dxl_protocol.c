/* Dynamixel Protocol 1.0 packet builders and status parser; see dxl_protocol.h. */
#include "dxl_protocol.h"

#include <string.h>

/* Byte offsets inside a packet. */
#define PKT_ID 2u
#define PKT_LEN 3u
#define PKT_INST 4u     /* the error byte in a status packet */
#define PKT_PARAMS 5u

/* The SDK drops a status packet whose LEN exceeds 250 (RXPACKET_MAX_LEN): 254 bytes in all. */
#define PARSER_MAX_SIZE 254u

uint8_t dxl_checksum(const uint8_t *bytes, size_t n)
{
    /* Four bytes at a time: the bytes of a word sum, mod 256, to the low byte of the word
     * plus its shifts by 8, 16 and 24 (whatever the byte order). */
    uint32_t sum = 0;
    const uint8_t *end = bytes + n;
    for (; end - bytes >= 4; bytes += 4) {
        uint32_t w;
        memcpy(&w, bytes, sizeof w);   /* (one unaligned load on the M4) */
        sum += w + (w >> 8) + (w >> 16) + (w >> 24);
    }
    while (bytes < end) {
        sum += *bytes++;
    }
    return (uint8_t)~sum;
}

/* ---------------------------------------------------------------- builders */

/* Room in buf for an instruction packet with n_params parameters? */
static int fits(const uint8_t *buf, size_t cap, size_t n_params)
{
    return buf != NULL && n_params <= DXL_MAX_PARAMS && n_params + 6u <= cap;
}

/* Header, LEN and checksum around the n_params parameters already at buf[5..]. */
static size_t frame(uint8_t *buf, uint8_t id, uint8_t inst, size_t n_params)
{
    buf[0] = 0xFF;
    buf[1] = 0xFF;
    buf[PKT_ID] = id;
    buf[PKT_LEN] = (uint8_t)(n_params + 2u);
    buf[PKT_INST] = inst;
    buf[PKT_PARAMS + n_params] = dxl_checksum(buf + PKT_ID, n_params + 3u);
    return n_params + 6u;
}

static size_t build_no_params(uint8_t *buf, size_t cap, uint8_t id, uint8_t inst)
{
    if (!fits(buf, cap, 0) || id > DXL_BROADCAST_ID) {
        return 0;
    }
    return frame(buf, id, inst, 0);
}

size_t dxl_build_ping(uint8_t *buf, size_t cap, uint8_t id)
{
    return build_no_params(buf, cap, id, DXL_INST_PING);
}

size_t dxl_build_action(uint8_t *buf, size_t cap, uint8_t id)
{
    return build_no_params(buf, cap, id, DXL_INST_ACTION);
}

size_t dxl_build_reset(uint8_t *buf, size_t cap, uint8_t id)
{
    if (id > DXL_MAX_ID) {
        return 0;  /* a broadcast RESET is not allowed */
    }
    return build_no_params(buf, cap, id, DXL_INST_RESET);
}

size_t dxl_build_read(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr, uint8_t len)
{
    /* the reply (len + 6 bytes) must fit in a packet too */
    if (!fits(buf, cap, 2) || id > DXL_MAX_ID || len == 0 || len > DXL_MAX_PARAMS) {
        return 0;
    }
    buf[PKT_PARAMS] = addr;
    buf[PKT_PARAMS + 1u] = len;
    return frame(buf, id, DXL_INST_READ, 2);
}

static size_t build_write(uint8_t *buf, size_t cap, uint8_t id, uint8_t inst, uint8_t addr,
                          const uint8_t *data, size_t n)
{
    if (data == NULL || n == 0 || n > DXL_MAX_PARAMS - 1u || !fits(buf, cap, n + 1u)
        || id > DXL_BROADCAST_ID) {
        return 0;
    }
    buf[PKT_PARAMS] = addr;
    memcpy(buf + PKT_PARAMS + 1u, data, n);
    return frame(buf, id, inst, n + 1u);
}

size_t dxl_build_write(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr,
                       const uint8_t *data, size_t n)
{
    return build_write(buf, cap, id, DXL_INST_WRITE, addr, data, n);
}

size_t dxl_build_reg_write(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr,
                           const uint8_t *data, size_t n)
{
    return build_write(buf, cap, id, DXL_INST_REG_WRITE, addr, data, n);
}

/* Parameters of a SYNC_WRITE (addr, L, then ID + L bytes per servo), or 0 if they do not fit
 * in a packet or an ID is not a servo's. */
static size_t sync_params(size_t n_servos, size_t data_len, const uint8_t *ids)
{
    if (ids == NULL || n_servos == 0 || data_len == 0 || n_servos > DXL_MAX_PARAMS
        || data_len > DXL_MAX_PARAMS) {
        return 0;  /* also keeps the product below from overflowing */
    }
    size_t n_params = 2u + n_servos * (data_len + 1u);
    if (n_params > DXL_MAX_PARAMS) {
        return 0;
    }
    for (size_t i = 0; i < n_servos; i++) {
        if (ids[i] > DXL_MAX_ID) {
            return 0;
        }
    }
    return n_params;
}

size_t dxl_build_sync_write(uint8_t *buf, size_t cap, uint8_t addr, uint8_t data_len,
                            size_t n_servos, const uint8_t *ids, const uint8_t *data)
{
    size_t n_params = sync_params(n_servos, data_len, ids);
    if (n_params == 0 || data == NULL || !fits(buf, cap, n_params)) {
        return 0;
    }
    uint8_t *out = buf + PKT_PARAMS;
    *out++ = addr;
    *out++ = data_len;
    for (size_t i = 0; i < n_servos; i++) {
        *out++ = ids[i];
        memcpy(out, data + i * data_len, data_len);
        out += data_len;
    }
    return frame(buf, DXL_BROADCAST_ID, DXL_INST_SYNC_WRITE, n_params);
}

/* The stabiliser's packet, every tick: one pass writes the bytes and sums the checksum. */
size_t dxl_build_sync_goal_speed(uint8_t *buf, size_t cap, size_t n_servos, const uint8_t *ids,
                                 const uint16_t *goal, const uint16_t *speed)
{
    if (buf == NULL || ids == NULL || goal == NULL || speed == NULL || n_servos == 0
        || n_servos > (DXL_MAX_PARAMS - 2u) / 5u) {
        return 0;
    }
    const size_t n_params = 2u + 5u * n_servos;
    if (n_params + 6u > cap) {
        return 0;
    }
    buf[0] = 0xFF;
    buf[1] = 0xFF;
    buf[PKT_ID] = DXL_BROADCAST_ID;
    buf[PKT_LEN] = (uint8_t)(n_params + 2u);
    buf[PKT_INST] = DXL_INST_SYNC_WRITE;
    buf[PKT_PARAMS] = DXL_AX_GOAL_POSITION;
    buf[PKT_PARAMS + 1u] = 4;
    unsigned sum = DXL_BROADCAST_ID + (unsigned)(n_params + 2u) + DXL_INST_SYNC_WRITE + DXL_AX_GOAL_POSITION + 4u;
    uint8_t *out = buf + PKT_PARAMS + 2u;
    for (size_t i = 0; i < n_servos; i++) {
        const unsigned id = ids[i], g = goal[i], v = speed[i];
        if (id > DXL_MAX_ID || g > DXL_AX_POSITION_MAX || v > DXL_AX_SPEED_MAX) {
            return 0;  /* the servo would answer a range error nobody hears */
        }
        out[0] = (uint8_t)id;
        out[1] = (uint8_t)g;
        out[2] = (uint8_t)(g >> 8);
        out[3] = (uint8_t)v;
        out[4] = (uint8_t)(v >> 8);
        sum += id + g + (g >> 8) + v + (v >> 8);   /* mod 256, g and v count as their low bytes */
        out += 5;
    }
    *out = (uint8_t)~sum;
    return n_params + 6u;
}

/* ------------------------------------------------------------------ parser */

int dxl_parser_init(dxl_parser_t *p, uint8_t *buf, size_t size)
{
    if (p == NULL || buf == NULL || size < DXL_STATUS_MIN_LEN) {
        return -1;
    }
    p->buf = buf;
    p->size = (uint16_t)(size < PARSER_MAX_SIZE ? size : PARSER_MAX_SIZE);
    dxl_parser_reset(p);
    return 0;
}

void dxl_parser_reset(dxl_parser_t *p)
{
    p->len = 0;
    p->consumed = 0;
    p->id = 0;
    p->error = 0;
    p->n_params = 0;
    p->params = p->buf;
}

typedef enum { CAND_DEAD, CAND_OPEN, CAND_DONE, CAND_TOO_LONG } candidate_t;

/* What the window bytes from index s on are: the start of a status packet still arriving
 * (OPEN), one whose last byte is the newest byte (DONE), a header whose LEN just arrived
 * and is too long for the buffer (TOO_LONG), or no packet start (DEAD). Reads only
 * bytes s .. len-1. */
static candidate_t candidate(const dxl_parser_t *p, uint16_t s)
{
    const uint8_t *b = p->buf + s;
    unsigned n = (unsigned)p->len - s;  /* bytes from s to the newest one, >= 1 */

    if (b[0] != 0xFF) {
        return CAND_DEAD;
    }
    if (n < 2) {
        return CAND_OPEN;
    }
    if (b[1] != 0xFF) {
        return CAND_DEAD;
    }
    if (n < 3) {
        return CAND_OPEN;
    }
    if (b[PKT_ID] > DXL_MAX_ID) {
        return CAND_DEAD;
    }
    if (n < 4) {
        return CAND_OPEN;
    }
    unsigned total = b[PKT_LEN] + 4u;
    if (b[PKT_LEN] < 2) {
        return CAND_DEAD;
    }
    if (total > p->size) {
        return (n == 4 && total <= PARSER_MAX_SIZE) ? CAND_TOO_LONG : CAND_DEAD;
    }
    if (n < 5) {
        return CAND_OPEN;
    }
    if (b[PKT_INST] > 0x7F) {
        return CAND_DEAD;
    }
    if (n < total) {
        return CAND_OPEN;
    }
    return n == total ? CAND_DONE : CAND_DEAD;
}

static void drop_front(dxl_parser_t *p, uint16_t k)
{
    if (k == 0) {
        return;
    }
    if (k >= p->len) {
        p->len = 0;
        return;
    }
    memmove(p->buf, p->buf + k, (size_t)(p->len - k));
    p->len = (uint16_t)(p->len - k);
}

dxl_parse_result_t dxl_parse_byte(dxl_parser_t *p, uint8_t byte)
{
    dxl_parse_result_t result = DXL_PARSE_NEED_MORE;

    /* Keep the window from the oldest candidate still arriving on (after the last reported
     * packet's start). An open candidate is shorter than its total length <= size, so
     * this always leaves room for the new byte. */
    uint16_t s = p->consumed;
    while (s < p->len && (p->buf[s] != 0xFF || candidate(p, s) != CAND_OPEN)) {
        s++;   /* (a packet starts with 0xFF: the cheap test first) */
    }
    drop_front(p, s);
    p->consumed = 0;
    if (p->len >= p->size) {
        drop_front(p, 1);  /* unreachable by the argument above; keeps the write in bounds */
    }
    p->buf[p->len++] = byte;

    /* Newest start first: after garbage or a truncated packet the latest header is the real one. */
    for (s = p->len; s-- > 0;) {
        /* only a start whose LEN byte just arrived (too long?) or whose announced length
         * ends here (done?) can report on this byte: skip the others cheaply */
        const unsigned n = (unsigned)p->len - s;
        if (p->buf[s] != 0xFF || !(n == 4u || (n > 4u && n == p->buf[s + PKT_LEN] + 4u))) {
            continue;
        }
        switch (candidate(p, s)) {
        case CAND_DONE: {
            const uint8_t *b = p->buf + s;
            unsigned n_params = b[PKT_LEN] - 2u;
            if (dxl_checksum(b + PKT_ID, n_params + 3u) == b[PKT_PARAMS + n_params]) {
                p->id = b[PKT_ID];
                p->error = b[PKT_INST];
                p->n_params = (uint8_t)n_params;
                p->params = b + PKT_PARAMS;
                p->consumed = (uint16_t)(s + 1u);
                return DXL_PARSE_COMPLETE;
            }
            result = DXL_PARSE_BAD_CHECKSUM;
            break;
        }
        case CAND_TOO_LONG:
            if (result == DXL_PARSE_NEED_MORE) {
                result = DXL_PARSE_TOO_LONG;
            }
            break;
        default:
            break;
        }
    }
    return result;
}

void dxl_decode_error(uint8_t error, dxl_error_flags_t *out)
{
    out->voltage = (error & DXL_ERR_VOLTAGE) != 0;
    out->angle_limit = (error & DXL_ERR_ANGLE_LIMIT) != 0;
    out->overheating = (error & DXL_ERR_OVERHEATING) != 0;
    out->range = (error & DXL_ERR_RANGE) != 0;
    out->checksum = (error & DXL_ERR_CHECKSUM) != 0;
    out->overload = (error & DXL_ERR_OVERLOAD) != 0;
    out->instruction = (error & DXL_ERR_INSTRUCTION) != 0;
}
