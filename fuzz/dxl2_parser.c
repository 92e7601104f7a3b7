/* libFuzzer harness: the Dynamixel Protocol 2.0 status parser
 * (firmware_stm32/App/Src/dxl_protocol2.c), byte by byte.
 *
 * Input: [small size] then the received bytes. The same bytes go to two parsers, one with
 * a small window of 11 + (first byte % 64) bytes and one with the largest useful window
 * (DXL2_MAX_LENGTH + 7; the servo bus uses 192); each window is a heap block of exactly that
 * size, so AddressSanitizer sees any access past it. Wherever the input holds the four bytes
 * "RST!", both parsers are reset (dxl2_parser_reset), as the servo bus does before each
 * request.
 *
 * Checked on every DXL2_PARSE_COMPLETE, besides what ASan/UBSan see, against the protocol's
 * written format (written again here, not the parser's helpers, CRC aside):
 *   - the packet is the last LEN + 7 bytes received since the last reset, the newest byte
 *     last: FF FF FD 00 ID LEN_L LEN_H 55 ERR P1..PN CRC_L CRC_H with ID <= 252, the CRC
 *     (dxl2_crc, itself checked against the SDK by tests/test_dxl_protocol2.py) right, and
 *     every FF FF FD from the instruction on followed by the FD added to it;
 *   - p->id and p->error are ID and ERR, and p->params .. + n_params are P1..PN with the
 *     added FDs taken out, inside the window;
 *   - the small window reports a packet only if it fits: LEN + 7 <= size.
 * Also: a packet received alone right after a reset is always reported by a window it
 * fits in (the parser loses no clean packet).
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "dxl_protocol2.h"

#define CHECK(cond) do { if (!(cond)) { __builtin_trap(); } } while (0)
#define HEAD 7u                          /* FF FF FD 00 ID LEN_L LEN_H */
#define LARGE (DXL2_MAX_LENGTH + HEAD)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const uint8_t RESET_MARK[4] = { 'R', 'S', 'T', '!' };

typedef struct {
    dxl2_parser_t p;
    uint8_t *buf;
    size_t size;
    unsigned completes;
} window_t;

/* The bytes s[from .. to-1] with the FD after each FF FF FD taken out, into out; their count,
 * or -1 if an FF FF FD is not followed by its FD. */
static long unstuffed(const uint8_t *s, size_t from, size_t to, uint8_t *out)
{
    long n = 0;
    for (size_t k = from; k < to; ++k) {
        out[n++] = s[k];
        if (n >= 3 && out[n - 3] == 0xFF && out[n - 2] == 0xFF && out[n - 1] == 0xFD) {
            if (k + 1 >= to || s[k + 1] != 0xFD) {
                return -1;
            }
            ++k;
        }
    }
    return n;
}

/* Is s[0 .. n-1] exactly one well-formed status packet? */
static int clean_packet(const uint8_t *s, size_t n)
{
    static uint8_t body[LARGE];
    if (n < DXL2_STATUS_MIN_LEN || s[0] != 0xFF || s[1] != 0xFF || s[2] != 0xFD || s[3] != 0x00
        || s[4] > DXL2_MAX_ID || (size_t)(s[5] | s[6] << 8) + HEAD != n || s[7] != DXL2_INST_STATUS) {
        return 0;
    }
    return dxl2_crc(0, s, n - 2) == (s[n - 2] | s[n - 1] << 8) && unstuffed(s, HEAD, n - 2, body) >= 2;
}

static void check_complete(const window_t *w, const uint8_t *stream, size_t n_stream)
{
    static uint8_t body[LARGE];
    const dxl2_parser_t *p = &w->p;
    /* the packet's head is left as it came (the parser unstuffs from the instruction on) */
    const uint8_t *head = p->params - (HEAD + 2u);
    CHECK(head >= w->buf);
    const size_t total = (size_t)(head[5] | head[6] << 8) + HEAD;
    CHECK(total <= w->size && head + total <= w->buf + w->size);
    CHECK(total <= n_stream);
    const uint8_t *pkt = stream + n_stream - total;   /* as received, the newest byte last */
    CHECK(clean_packet(pkt, total));
    CHECK(pkt[4] == p->id && pkt[8] == p->error);
    const long n_body = unstuffed(pkt, HEAD, total - 2, body);   /* 55 ERR P1..PN */
    CHECK(n_body >= 2 && (size_t)n_body - 2u == p->n_params);
    CHECK(p->params + p->n_params <= w->buf + w->size);
    CHECK(memcmp(p->params, body + 2, p->n_params) == 0);
}

static int setup(window_t *w, size_t size)
{
    w->buf = malloc(size);
    w->size = size;
    w->completes = 0;
    return w->buf != NULL && dxl2_parser_init(&w->p, w->buf, size) == 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) {
        return 0;
    }
    window_t w[2];
    if (!setup(&w[0], DXL2_STATUS_MIN_LEN + data[0] % 64u) || !setup(&w[1], LARGE)) {
        abort();
    }
    /* the bytes received since the last reset (both parsers see the same) */
    static uint8_t stream[4 * LARGE];
    size_t n_stream = 0;
    for (size_t i = 1; i < size; ++i) {
        if (i + 4 <= size && memcmp(data + i, RESET_MARK, 4) == 0) {
            for (int k = 0; k < 2; ++k) {
                dxl2_parser_reset(&w[k].p);
                w[k].completes = 0;
            }
            n_stream = 0;
            i += 3;
            continue;
        }
        if (n_stream == sizeof stream) {
            /* keep the newest LARGE bytes: a packet is at most that */
            memmove(stream, stream + sizeof stream - LARGE, LARGE);
            n_stream = LARGE;
        }
        stream[n_stream++] = data[i];
        for (int k = 0; k < 2; ++k) {
            dxl2_parse_result_t r = dxl2_parse_byte(&w[k].p, data[i]);
            CHECK((unsigned)r <= DXL2_PARSE_BAD_STUFFING);
            if (r == DXL2_PARSE_COMPLETE) {
                check_complete(&w[k], stream, n_stream);
                w[k].completes++;
            }
            /* a clean packet alone since the reset is never lost */
            if (n_stream <= w[k].size && w[k].completes == 0 && clean_packet(stream, n_stream)) {
                CHECK(r == DXL2_PARSE_COMPLETE);
            }
        }
    }
    free(w[0].buf);
    free(w[1].buf);
    return 0;
}
