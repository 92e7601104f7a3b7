/* Dynamixel Protocol 2.0 packet builders and status parser; see dxl_protocol2.h. */
#include "dxl_protocol2.h"

#include <string.h>

/* Byte offsets inside a packet. */
#define PKT_ID 4u
#define PKT_LEN_L 5u
#define PKT_LEN_H 6u
#define PKT_INST 7u     /* the stuffed part starts here */
#define PKT_ERROR 8u    /* status packets */
#define PKT_HEAD 7u     /* FF FF FD 00 ID LEN_L LEN_H */

#define PARSER_MAX_SIZE (DXL2_MAX_LENGTH + PKT_HEAD)

/* CRC-16/0x8005 of each byte value (the CRC of x followed by a zero byte): one lookup per
 * byte instead of eight shifts. */
static const uint16_t crc_table[256] = {
    0x0000, 0x8005, 0x800F, 0x000A, 0x801B, 0x001E, 0x0014, 0x8011,
    0x8033, 0x0036, 0x003C, 0x8039, 0x0028, 0x802D, 0x8027, 0x0022,
    0x8063, 0x0066, 0x006C, 0x8069, 0x0078, 0x807D, 0x8077, 0x0072,
    0x0050, 0x8055, 0x805F, 0x005A, 0x804B, 0x004E, 0x0044, 0x8041,
    0x80C3, 0x00C6, 0x00CC, 0x80C9, 0x00D8, 0x80DD, 0x80D7, 0x00D2,
    0x00F0, 0x80F5, 0x80FF, 0x00FA, 0x80EB, 0x00EE, 0x00E4, 0x80E1,
    0x00A0, 0x80A5, 0x80AF, 0x00AA, 0x80BB, 0x00BE, 0x00B4, 0x80B1,
    0x8093, 0x0096, 0x009C, 0x8099, 0x0088, 0x808D, 0x8087, 0x0082,
    0x8183, 0x0186, 0x018C, 0x8189, 0x0198, 0x819D, 0x8197, 0x0192,
    0x01B0, 0x81B5, 0x81BF, 0x01BA, 0x81AB, 0x01AE, 0x01A4, 0x81A1,
    0x01E0, 0x81E5, 0x81EF, 0x01EA, 0x81FB, 0x01FE, 0x01F4, 0x81F1,
    0x81D3, 0x01D6, 0x01DC, 0x81D9, 0x01C8, 0x81CD, 0x81C7, 0x01C2,
    0x0140, 0x8145, 0x814F, 0x014A, 0x815B, 0x015E, 0x0154, 0x8151,
    0x8173, 0x0176, 0x017C, 0x8179, 0x0168, 0x816D, 0x8167, 0x0162,
    0x8123, 0x0126, 0x012C, 0x8129, 0x0138, 0x813D, 0x8137, 0x0132,
    0x0110, 0x8115, 0x811F, 0x011A, 0x810B, 0x010E, 0x0104, 0x8101,
    0x8303, 0x0306, 0x030C, 0x8309, 0x0318, 0x831D, 0x8317, 0x0312,
    0x0330, 0x8335, 0x833F, 0x033A, 0x832B, 0x032E, 0x0324, 0x8321,
    0x0360, 0x8365, 0x836F, 0x036A, 0x837B, 0x037E, 0x0374, 0x8371,
    0x8353, 0x0356, 0x035C, 0x8359, 0x0348, 0x834D, 0x8347, 0x0342,
    0x03C0, 0x83C5, 0x83CF, 0x03CA, 0x83DB, 0x03DE, 0x03D4, 0x83D1,
    0x83F3, 0x03F6, 0x03FC, 0x83F9, 0x03E8, 0x83ED, 0x83E7, 0x03E2,
    0x83A3, 0x03A6, 0x03AC, 0x83A9, 0x03B8, 0x83BD, 0x83B7, 0x03B2,
    0x0390, 0x8395, 0x839F, 0x039A, 0x838B, 0x038E, 0x0384, 0x8381,
    0x0280, 0x8285, 0x828F, 0x028A, 0x829B, 0x029E, 0x0294, 0x8291,
    0x82B3, 0x02B6, 0x02BC, 0x82B9, 0x02A8, 0x82AD, 0x82A7, 0x02A2,
    0x82E3, 0x02E6, 0x02EC, 0x82E9, 0x02F8, 0x82FD, 0x82F7, 0x02F2,
    0x02D0, 0x82D5, 0x82DF, 0x02DA, 0x82CB, 0x02CE, 0x02C4, 0x82C1,
    0x8243, 0x0246, 0x024C, 0x8249, 0x0258, 0x825D, 0x8257, 0x0252,
    0x0270, 0x8275, 0x827F, 0x027A, 0x826B, 0x026E, 0x0264, 0x8261,
    0x0220, 0x8225, 0x822F, 0x022A, 0x823B, 0x023E, 0x0234, 0x8231,
    0x8213, 0x0216, 0x021C, 0x8219, 0x0208, 0x820D, 0x8207, 0x0202,
};

/* The CRC of byte x followed by another zero byte: crc_table[x] carried one byte on. With it
 * two bytes take two lookups and no carry in between (the CRC is linear: the second byte's
 * share and the carry of the first add). Estimated on the Cortex-M4 (uavarm.m4, -O2): 8.5
 * cycles a byte, against 12 a byte at a time and 79 bit by bit. */
static const uint16_t crc_table2[256] = {
    0x0000, 0x8603, 0x8C03, 0x0A00, 0x9803, 0x1E00, 0x1400, 0x9203,
    0xB003, 0x3600, 0x3C00, 0xBA03, 0x2800, 0xAE03, 0xA403, 0x2200,
    0xE003, 0x6600, 0x6C00, 0xEA03, 0x7800, 0xFE03, 0xF403, 0x7200,
    0x5000, 0xD603, 0xDC03, 0x5A00, 0xC803, 0x4E00, 0x4400, 0xC203,
    0x4003, 0xC600, 0xCC00, 0x4A03, 0xD800, 0x5E03, 0x5403, 0xD200,
    0xF000, 0x7603, 0x7C03, 0xFA00, 0x6803, 0xEE00, 0xE400, 0x6203,
    0xA000, 0x2603, 0x2C03, 0xAA00, 0x3803, 0xBE00, 0xB400, 0x3203,
    0x1003, 0x9600, 0x9C00, 0x1A03, 0x8800, 0x0E03, 0x0403, 0x8200,
    0x8006, 0x0605, 0x0C05, 0x8A06, 0x1805, 0x9E06, 0x9406, 0x1205,
    0x3005, 0xB606, 0xBC06, 0x3A05, 0xA806, 0x2E05, 0x2405, 0xA206,
    0x6005, 0xE606, 0xEC06, 0x6A05, 0xF806, 0x7E05, 0x7405, 0xF206,
    0xD006, 0x5605, 0x5C05, 0xDA06, 0x4805, 0xCE06, 0xC406, 0x4205,
    0xC005, 0x4606, 0x4C06, 0xCA05, 0x5806, 0xDE05, 0xD405, 0x5206,
    0x7006, 0xF605, 0xFC05, 0x7A06, 0xE805, 0x6E06, 0x6406, 0xE205,
    0x2006, 0xA605, 0xAC05, 0x2A06, 0xB805, 0x3E06, 0x3406, 0xB205,
    0x9005, 0x1606, 0x1C06, 0x9A05, 0x0806, 0x8E05, 0x8405, 0x0206,
    0x8009, 0x060A, 0x0C0A, 0x8A09, 0x180A, 0x9E09, 0x9409, 0x120A,
    0x300A, 0xB609, 0xBC09, 0x3A0A, 0xA809, 0x2E0A, 0x240A, 0xA209,
    0x600A, 0xE609, 0xEC09, 0x6A0A, 0xF809, 0x7E0A, 0x740A, 0xF209,
    0xD009, 0x560A, 0x5C0A, 0xDA09, 0x480A, 0xCE09, 0xC409, 0x420A,
    0xC00A, 0x4609, 0x4C09, 0xCA0A, 0x5809, 0xDE0A, 0xD40A, 0x5209,
    0x7009, 0xF60A, 0xFC0A, 0x7A09, 0xE80A, 0x6E09, 0x6409, 0xE20A,
    0x2009, 0xA60A, 0xAC0A, 0x2A09, 0xB80A, 0x3E09, 0x3409, 0xB20A,
    0x900A, 0x1609, 0x1C09, 0x9A0A, 0x0809, 0x8E0A, 0x840A, 0x0209,
    0x000F, 0x860C, 0x8C0C, 0x0A0F, 0x980C, 0x1E0F, 0x140F, 0x920C,
    0xB00C, 0x360F, 0x3C0F, 0xBA0C, 0x280F, 0xAE0C, 0xA40C, 0x220F,
    0xE00C, 0x660F, 0x6C0F, 0xEA0C, 0x780F, 0xFE0C, 0xF40C, 0x720F,
    0x500F, 0xD60C, 0xDC0C, 0x5A0F, 0xC80C, 0x4E0F, 0x440F, 0xC20C,
    0x400C, 0xC60F, 0xCC0F, 0x4A0C, 0xD80F, 0x5E0C, 0x540C, 0xD20F,
    0xF00F, 0x760C, 0x7C0C, 0xFA0F, 0x680C, 0xEE0F, 0xE40F, 0x620C,
    0xA00F, 0x260C, 0x2C0C, 0xAA0F, 0x380C, 0xBE0F, 0xB40F, 0x320C,
    0x100C, 0x960F, 0x9C0F, 0x1A0C, 0x880F, 0x0E0C, 0x040C, 0x820F,
};

uint16_t dxl2_crc(uint16_t crc, const uint8_t *bytes, size_t n)
{
    uint32_t c = crc;
    size_t i = 0;
    for (; i + 2u <= n; i += 2u) {
        c = (uint32_t)crc_table2[(c >> 8) ^ bytes[i]] ^ crc_table[(c & 0xFFu) ^ bytes[i + 1u]];
    }
    if (i < n) {
        c = ((c << 8) ^ crc_table[(c >> 8) ^ bytes[i]]) & 0xFFFFu;
    }
    return (uint16_t)c;
}

void dxl2_crc_shares(uint16_t share[256], unsigned after)
{
    for (unsigned b = 0; b < 256u; ++b) {
        uint32_t c = crc_table[b];             /* the CRC of b alone, from 0 */
        for (unsigned k = 0; k < after; ++k) {
            c = ((c << 8) ^ crc_table[c >> 8]) & 0xFFFFu;   /* then a zero byte */
        }
        share[b] = (uint16_t)c;
    }
}

/* ---------------------------------------------------------------- builders */

/* A packet being written; ok drops to 0 when it no longer fits in cap. */
typedef struct {
    uint8_t *buf;
    size_t cap;
    size_t n;
    int ok;
} writer_t;

static void put(writer_t *w, uint8_t byte)
{
    if (w->ok && w->n < w->cap) {
        w->buf[w->n++] = byte;
    } else {
        w->ok = 0;
    }
}

/* A byte from the instruction to the last parameter: an FD after FF FF gets a second FD.
 * (An added FD follows an FD, never FF FF, so it needs no stuffing itself.) */
static void put_stuffed(writer_t *w, uint8_t byte)
{
    put(w, byte);
    if (w->ok && byte == 0xFD && w->n >= PKT_INST + 3u
        && w->buf[w->n - 2u] == 0xFF && w->buf[w->n - 3u] == 0xFF) {
        put(w, 0xFD);
    }
}

static void put_u16(writer_t *w, uint16_t v)
{
    put_stuffed(w, (uint8_t)v);
    put_stuffed(w, (uint8_t)(v >> 8));
}

/* Header, ID, room for LEN, and the instruction. */
static writer_t start(uint8_t *buf, size_t cap, uint8_t id, uint8_t inst)
{
    writer_t w = { buf, cap, 0, buf != NULL };
    static const uint8_t head[PKT_HEAD] = { 0xFF, 0xFF, 0xFD, 0x00, 0, 0, 0 };
    for (unsigned i = 0; i < PKT_HEAD; i++) {
        put(&w, head[i]);
    }
    if (w.ok) {
        w.buf[PKT_ID] = id;
    }
    put_stuffed(&w, inst);
    return w;
}

/* LEN and CRC around what was written; the packet's length, or 0 if it did not fit. */
static size_t finish(writer_t *w)
{
    const size_t total = w->n + 2u;
    if (!w->ok || total > w->cap || total > DXL2_MAX_PACKET_LEN) {
        return 0;
    }
    const size_t length = total - PKT_HEAD;
    w->buf[PKT_LEN_L] = (uint8_t)length;
    w->buf[PKT_LEN_H] = (uint8_t)(length >> 8);
    const uint16_t crc = dxl2_crc(0, w->buf, w->n);
    w->buf[w->n] = (uint8_t)crc;
    w->buf[w->n + 1u] = (uint8_t)(crc >> 8);
    return total;
}

static int servo_id(uint8_t id)
{
    return id <= DXL2_MAX_ID;
}

static int servo_or_broadcast(uint8_t id)
{
    return id <= DXL2_MAX_ID || id == DXL2_BROADCAST_ID;
}

size_t dxl2_build_ping(uint8_t *buf, size_t cap, uint8_t id)
{
    if (!servo_or_broadcast(id)) {
        return 0;
    }
    writer_t w = start(buf, cap, id, DXL2_INST_PING);
    return finish(&w);
}

size_t dxl2_build_reboot(uint8_t *buf, size_t cap, uint8_t id)
{
    if (!servo_or_broadcast(id)) {
        return 0;
    }
    writer_t w = start(buf, cap, id, DXL2_INST_REBOOT);
    return finish(&w);
}

size_t dxl2_build_read(uint8_t *buf, size_t cap, uint8_t id, uint16_t addr, uint16_t len)
{
    if (!servo_id(id) || len == 0 || len > DXL2_MAX_READ) {
        return 0;  /* a broadcast READ is never answered; the reply must fit in a packet */
    }
    writer_t w = start(buf, cap, id, DXL2_INST_READ);
    put_u16(&w, addr);
    put_u16(&w, len);
    return finish(&w);
}

size_t dxl2_build_write(uint8_t *buf, size_t cap, uint8_t id, uint16_t addr,
                        const uint8_t *data, size_t n)
{
    if (!servo_or_broadcast(id) || data == NULL || n == 0 || n > DXL2_MAX_PACKET_LEN) {
        return 0;
    }
    writer_t w = start(buf, cap, id, DXL2_INST_WRITE);
    put_u16(&w, addr);
    for (size_t i = 0; i < n && w.ok; i++) {
        put_stuffed(&w, data[i]);
    }
    return finish(&w);
}

/* A SYNC list: 1..DXL2_MAX_ID + 1 servo IDs and 1 <= data_len <= DXL2_MAX_READ. */
static int sync_list_ok(uint16_t data_len, size_t n_servos, const uint8_t *ids)
{
    if (ids == NULL || n_servos == 0 || n_servos > DXL2_MAX_ID + 1u || data_len == 0
        || data_len > DXL2_MAX_READ) {
        return 0;
    }
    for (size_t i = 0; i < n_servos; i++) {
        if (!servo_id(ids[i])) {
            return 0;
        }
    }
    return 1;
}

size_t dxl2_build_sync_write(uint8_t *buf, size_t cap, uint16_t addr, uint16_t data_len,
                             size_t n_servos, const uint8_t *ids, const uint8_t *data)
{
    if (!sync_list_ok(data_len, n_servos, ids) || data == NULL) {
        return 0;
    }
    writer_t w = start(buf, cap, DXL2_BROADCAST_ID, DXL2_INST_SYNC_WRITE);
    put_u16(&w, addr);
    put_u16(&w, data_len);
    for (size_t i = 0; i < n_servos && w.ok; i++) {
        put_stuffed(&w, ids[i]);
        const uint8_t *d = data + i * data_len;
        for (size_t k = 0; k < data_len; k++) {
            put_stuffed(&w, d[k]);
        }
    }
    return finish(&w);
}

size_t dxl2_build_sync_read(uint8_t *buf, size_t cap, uint16_t addr, uint16_t data_len,
                            size_t n_servos, const uint8_t *ids)
{
    if (!sync_list_ok(data_len, n_servos, ids)) {
        return 0;
    }
    writer_t w = start(buf, cap, DXL2_BROADCAST_ID, DXL2_INST_SYNC_READ);
    put_u16(&w, addr);
    put_u16(&w, data_len);
    for (size_t i = 0; i < n_servos; i++) {
        put_stuffed(&w, ids[i]);   /* (an ID is at most 0xFC: never stuffed) */
    }
    return finish(&w);
}

/* ------------------------------------------------------------------ parser */

int dxl2_parser_init(dxl2_parser_t *p, uint8_t *buf, size_t size)
{
    if (p == NULL || buf == NULL || size < DXL2_STATUS_MIN_LEN) {
        return -1;
    }
    p->buf = buf;
    p->size = (uint16_t)(size < PARSER_MAX_SIZE ? size : PARSER_MAX_SIZE);
    dxl2_parser_reset(p);
    return 0;
}

void dxl2_parser_reset(dxl2_parser_t *p)
{
    p->len = 0;
    p->consumed = 0;
    p->id = 0;
    p->error = 0;
    p->n_params = 0;
    p->params = p->buf;
}

typedef enum { CAND_DEAD, CAND_OPEN, CAND_DONE, CAND_TOO_LONG } candidate_t;

static unsigned length_field(const uint8_t *b)
{
    return b[PKT_LEN_L] | ((unsigned)b[PKT_LEN_H] << 8);
}

/* What the window bytes from index s on are: the start of a status packet still arriving
 * (OPEN), one whose last byte is the newest byte (DONE), a header whose LEN just arrived
 * and is too long for the buffer (TOO_LONG), or no packet start (DEAD). Reads only
 * bytes s .. len-1. */
static candidate_t candidate(const dxl2_parser_t *p, uint16_t s)
{
    static const uint8_t header[4] = { 0xFF, 0xFF, 0xFD, 0x00 };
    const uint8_t *b = p->buf + s;
    const unsigned n = (unsigned)p->len - s;  /* bytes from s to the newest one, >= 1 */

    for (unsigned i = 0; i < sizeof header; i++) {
        if (i >= n) {
            return CAND_OPEN;
        }
        if (b[i] != header[i]) {
            return CAND_DEAD;
        }
    }
    if (n <= PKT_ID) {
        return CAND_OPEN;
    }
    if (b[PKT_ID] > DXL2_MAX_ID) {
        return CAND_DEAD;
    }
    if (n <= PKT_LEN_H) {
        return CAND_OPEN;
    }
    const unsigned length = length_field(b);
    if (length < DXL2_STATUS_MIN_LEN - PKT_HEAD || length > DXL2_MAX_LENGTH) {
        return CAND_DEAD;
    }
    const unsigned total = length + PKT_HEAD;
    if (total > p->size) {
        return n == PKT_HEAD ? CAND_TOO_LONG : CAND_DEAD;
    }
    if (n <= PKT_INST) {
        return CAND_OPEN;
    }
    if (b[PKT_INST] != DXL2_INST_STATUS) {
        return CAND_DEAD;
    }
    if (n < total) {
        return CAND_OPEN;
    }
    return n == total ? CAND_DONE : CAND_DEAD;
}

/* Is every FF FF FD between the instruction and the CRC (at b[end]) followed by the FD
 * added when it was sent? With out != NULL, also write the bytes without those added FDs
 * to out (which may be b + PKT_INST: the bytes only move down) and return their count;
 * returns -1 when the stuffing is wrong. */
static long unstuff(const uint8_t *b, unsigned end, uint8_t *out)
{
    long n_out = 0;
    unsigned before = 0;   /* the two bytes before, as received (out may overwrite them) */
    for (unsigned k = PKT_INST; k < end; k++) {
        const uint8_t byte = b[k];
        if (out != NULL) {
            out[n_out] = byte;
        }
        n_out++;
        if (byte == 0xFD && before == 0xFFFFu) {
            if (k + 1u >= end || b[k + 1u] != 0xFD) {
                return -1;
            }
            k++;   /* the added FD */
            before = 0xFDFDu;
        } else {
            before = ((before << 8) | byte) & 0xFFFFu;
        }
    }
    return n_out;
}

static void drop_front(dxl2_parser_t *p, uint16_t k)
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

/* The complete candidate at s with a right CRC and stuffing, as the reported packet. */
static void report(dxl2_parser_t *p, uint16_t s, unsigned end)
{
    uint8_t *b = p->buf + s;
    /* INST and ERR are never stuffed: the parameters start right after them */
    const long n_out = unstuff(b, end, b + PKT_INST);
    p->id = b[PKT_ID];
    p->error = b[PKT_ERROR];
    p->n_params = (uint16_t)(n_out - 2);
    p->params = b + PKT_ERROR + 1u;
    p->consumed = p->len;
}

dxl2_parse_result_t dxl2_parse_byte(dxl2_parser_t *p, uint8_t byte)
{
    dxl2_parse_result_t result = DXL2_PARSE_NEED_MORE;

    /* Keep the window from the oldest candidate still arriving on (after the last reported
     * packet). An open candidate is shorter than its total length <= size, so this always
     * leaves room for the new byte. */
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
        /* only a start whose LEN just arrived (too long?) or whose announced length ends
         * here (done?) can report on this byte: skip the others cheaply */
        const unsigned n = (unsigned)p->len - s;
        if (p->buf[s] != 0xFF
            || !(n == PKT_HEAD || (n > PKT_HEAD && n == length_field(p->buf + s) + PKT_HEAD))) {
            continue;
        }
        switch (candidate(p, s)) {
        case CAND_DONE: {
            const uint8_t *b = p->buf + s;
            const unsigned crc_at = n - 2u;
            if (dxl2_crc(0, b, crc_at) != (b[crc_at] | ((unsigned)b[crc_at + 1u] << 8))) {
                result = DXL2_PARSE_BAD_CRC;
            } else if (unstuff(b, crc_at, NULL) < 0) {
                result = DXL2_PARSE_BAD_STUFFING;
            } else {
                report(p, s, crc_at);
                return DXL2_PARSE_COMPLETE;
            }
            break;
        }
        case CAND_TOO_LONG:
            if (result == DXL2_PARSE_NEED_MORE) {
                result = DXL2_PARSE_TOO_LONG;
            }
            break;
        default:
            break;
        }
    }
    return result;
}

dxl2_parse_result_t dxl2_parse_bytes(dxl2_parser_t *p, const uint8_t *data, size_t n, size_t *used)
{
    dxl2_parse_result_t result = DXL2_PARSE_NEED_MORE;
    size_t i = 0;
    while (i < n && result == DXL2_PARSE_NEED_MORE) {
        result = dxl2_parse_byte(p, data[i++]);
    }
    if (used != NULL) {
        *used = i;
    }
    return result;
}

void dxl2_decode_error(uint8_t error, dxl2_error_t *out)
{
    out->hardware_error = (error & DXL2_ERR_ALERT) != 0;
    out->number = (uint8_t)(error & ~DXL2_ERR_ALERT);
}
