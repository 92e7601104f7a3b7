/* libFuzzer harness: the LLCP receiver (firmware_stm32/App/Src/llcp.c), byte by byte.
 *
 * Input: [config] then a stream of characters fed to llcp_rx_byte(). The byte 0xFF is an
 * escape (it is no LLCP character, so feeding it would only test one more non-hex
 * character): the byte after it advances the millisecond clock (0..0xEF ms, or 2^(k+16)
 * ms for 0xF0 + k, so the clock also wraps) and llcp_rx_poll() is called.
 *   config bit 0: idle gap 50 ms (the firmware's) instead of none
 *   config bit 1: length check with the generated msg_expected_len()
 *
 * Checked on every character, besides what ASan/UBSan see:
 *   - a delivered frame has 1..255 bytes, and with the length check its length is
 *     msg_expected_len(id);
 *   - it is exactly the characters fed since the last 'b': llcp_encode() of the
 *     delivered payload gives them back, and no idle gap longer than the configured one
 *     fell inside it;
 *   - every result is counted in its statistics counter, and nothing else is;
 *   - the payload index stays within the announced length (an overrun of payload[] would
 *     stay inside the llcp_rx_t, where AddressSanitizer does not look).
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "llcp.h"
#include "messages.h"

#define CHECK(cond) do { if (!(cond)) { __builtin_trap(); } } while (0)

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) {
        return 0;
    }
    const uint8_t config = data[0];
    const uint32_t gap = (config & 1u) ? 50u : 0u;
    llcp_rx_t rx;
    llcp_rx_init(&rx, gap, (config & 2u) ? msg_expected_len : NULL);

    /* the characters since the last 'b' and the largest clock step among them */
    static char since_b[LLCP_FRAME_MAX + 1];
    size_t since_len = 0;
    int in_frame = 0;
    uint32_t max_step = 0;
    uint32_t counts[8] = {0};

    uint32_t now = 0;
    uint32_t last_char_ms = 0;
    for (size_t i = 1; i < size; ++i) {
        uint8_t c = data[i];
        if (c == 0xFFu) {
            if (++i >= size) {
                break;
            }
            uint8_t d = data[i];
            now += d < 0xF0u ? d : (uint32_t)(1ull << ((d - 0xF0u) + 16u));
            llcp_rx_result_t r = llcp_rx_poll(&rx, now);
            CHECK(r == LLCP_RX_NONE || r == LLCP_RX_ERR_TIMEOUT);
            counts[r]++;
            if (r == LLCP_RX_ERR_TIMEOUT) {
                in_frame = 0;
            }
            continue;
        }
        uint32_t step = now - last_char_ms;
        last_char_ms = now;
        if (c == 'b') {
            since_len = 0;
            in_frame = 1;
            max_step = 0;
        } else if (in_frame && step > max_step) {
            max_step = step;
        }
        if (in_frame && since_len < sizeof since_b) {
            since_b[since_len++] = (char)c;
        }

        llcp_rx_result_t r = llcp_rx_byte(&rx, (char)c, now);
        CHECK((unsigned)r <= LLCP_RX_ERR_RESTART);
        CHECK(rx.count <= rx.len);   /* (payload[] is inside rx: ASan cannot see past it) */
        counts[r]++;
        if (r == LLCP_RX_FRAME) {
            CHECK(rx.len >= 1u);   /* (<= 255 by its type) */
            if (config & 2u) {
                CHECK(msg_expected_len(rx.payload[0]) == (int)rx.len);
            }
            char frame[LLCP_FRAME_MAX];
            size_t n = llcp_encode(rx.payload, rx.len, frame, sizeof frame);
            CHECK(n == LLCP_FRAME_SIZE(rx.len));
            CHECK(in_frame && n == since_len && memcmp(frame, since_b, n) == 0);
            CHECK(gap == 0u || max_step <= gap);
            /* the transmit encoder agrees up to its own limit */
            size_t n_tx = llcp_encode_tx(rx.payload, rx.len, frame, sizeof frame);
            CHECK(n_tx == (rx.len <= LLCP_TX_MAX_PAYLOAD ? n : 0u));
        }
        if (r != LLCP_RX_NONE && c != 'b') {
            in_frame = 0;   /* the frame ended (delivered or dropped) */
        }
    }
    CHECK(counts[LLCP_RX_FRAME] == rx.frames_ok);
    CHECK(counts[LLCP_RX_ERR_CHECKSUM] == rx.checksum_errors);
    CHECK(counts[LLCP_RX_ERR_HEX] == rx.hex_errors);
    CHECK(counts[LLCP_RX_ERR_LENGTH] == rx.length_errors);
    CHECK(counts[LLCP_RX_ERR_UNKNOWN_ID] == rx.unknown_ids);
    CHECK(counts[LLCP_RX_ERR_TIMEOUT] == rx.timeouts);
    CHECK(counts[LLCP_RX_ERR_RESTART] == rx.restarts);
    return 0;
}
