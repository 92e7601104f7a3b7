/* libFuzzer harness: the Dynamixel Protocol 1.0 status parser
 * (firmware_stm32/App/Src/dxl_protocol.c), byte by byte.
 *
 * Input: [small size] then the received bytes. The same bytes go to two parsers, one with
 * a small window of 6 + (first byte % 44) bytes (the servo bus uses 48) and one with the
 * largest useful window (254); each window is a heap block of exactly that size, so
 * AddressSanitizer sees any access past it. Wherever the input holds the four bytes
 * "RST!", both parsers are reset (dxl_parser_reset), as the servo bus does before each
 * request.
 *
 * Checked on every DXL_PARSE_COMPLETE, besides what ASan/UBSan see:
 *   - the packet lies inside the window: params - 5 .. params + n_params (checksum);
 *   - it is the last n_params + 6 bytes received since the last reset, the newest byte
 *     last: FF FF ID LEN ERR P1..PN CHK with ID <= 253, LEN = N + 2, ERR <= 0x7F and the
 *     right checksum (dxl_checksum), and p->id / p->error are ID / ERR;
 *   - the small window reports a packet only if it fits: n_params + 6 <= size.
 * Also: a packet received alone right after a reset is always reported by a window it
 * fits in (the parser loses no clean packet).
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "dxl_protocol.h"

#define CHECK(cond) do { if (!(cond)) { __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const uint8_t RESET_MARK[4] = { 'R', 'S', 'T', '!' };

typedef struct {
    dxl_parser_t p;
    uint8_t *buf;
    size_t size;
    unsigned completes;
} window_t;

static void check_complete(const window_t *w, const uint8_t *stream, size_t n_stream)
{
    const dxl_parser_t *p = &w->p;
    const size_t total = (size_t)p->n_params + DXL_STATUS_MIN_LEN;
    CHECK(total <= w->size);
    CHECK(p->params >= w->buf + 5 && p->params + p->n_params + 1 <= w->buf + w->size);
    const uint8_t *pkt = p->params - 5;
    /* the newest byte closes the packet, and the packet is what was received */
    CHECK(total <= n_stream);
    CHECK(memcmp(pkt, stream + n_stream - total, total) == 0);
    CHECK(pkt[0] == 0xFF && pkt[1] == 0xFF);
    CHECK(pkt[2] <= DXL_MAX_ID && pkt[2] == p->id);
    CHECK(pkt[3] == p->n_params + 2u);
    CHECK(pkt[4] <= 0x7Fu && pkt[4] == p->error);
    CHECK(dxl_checksum(pkt + 2, total - 3u) == pkt[total - 1u]);
}

static int setup(window_t *w, size_t size)
{
    w->buf = malloc(size);
    w->size = size;
    w->completes = 0;
    return w->buf != NULL && dxl_parser_init(&w->p, w->buf, size) == 0;
}

/* Is stream[0 .. n-1] exactly one well-formed status packet? */
static int clean_packet(const uint8_t *s, size_t n)
{
    return n >= DXL_STATUS_MIN_LEN && s[0] == 0xFF && s[1] == 0xFF && s[2] <= DXL_MAX_ID
        && s[3] >= 2u && (size_t)s[3] + 4u == n && s[4] <= 0x7Fu
        && dxl_checksum(s + 2, n - 3u) == s[n - 1u];
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) {
        return 0;
    }
    window_t w[2];
    if (!setup(&w[0], DXL_STATUS_MIN_LEN + data[0] % 44u) || !setup(&w[1], 254)) {
        abort();
    }
    /* the bytes received since the last reset (both parsers see the same) */
    static uint8_t stream[4096];
    size_t n_stream = 0;
    for (size_t i = 1; i < size; ++i) {
        if (i + 4 <= size && memcmp(data + i, RESET_MARK, 4) == 0) {
            for (int k = 0; k < 2; ++k) {
                dxl_parser_reset(&w[k].p);
                w[k].completes = 0;
            }
            n_stream = 0;
            i += 3;
            continue;
        }
        if (n_stream == sizeof stream) {
            /* keep the newest 256 bytes: a packet is at most 254 */
            memmove(stream, stream + sizeof stream - 256, 256);
            n_stream = 256;
        }
        stream[n_stream++] = data[i];
        for (int k = 0; k < 2; ++k) {
            dxl_parse_result_t r = dxl_parse_byte(&w[k].p, data[i]);
            CHECK((unsigned)r <= DXL_PARSE_TOO_LONG);
            if (r == DXL_PARSE_COMPLETE) {
                check_complete(&w[k], stream, n_stream);
                w[k].completes++;
            }
            /* a clean packet alone since the reset is never lost */
            if (n_stream <= w[k].size && w[k].completes == 0 && clean_packet(stream, n_stream)) {
                CHECK(r == DXL_PARSE_COMPLETE);
            }
        }
    }
    free(w[0].buf);
    free(w[1].buf);
    return 0;
}
