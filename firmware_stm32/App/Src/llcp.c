/* LLCP framing (MRS hexadecimal mode); the format and the receiver's rules are
 * described in llcp.h. */
#include "llcp.h"

/* Parser states. 'b' (re)starts a frame from any state. */
enum {
    ST_IDLE = 0, /* between frames: everything except 'b' is ignored */
    ST_SIZE_HI,
    ST_SIZE_LO,
    ST_DATA_HI,
    ST_DATA_LO,
    ST_SUM_HI,
    ST_SUM_LO
};

/* MRS emits upper-case digits only; the receiver accepts nothing else. */
static const char HEX_DIGITS[] = "0123456789ABCDEF";

/* Value of an upper-case hex digit, or -1. */
static int hex_value(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

/* Writes byte as two hex digits at out[pos] and adds both characters to the checksum. */
static size_t put_hex(char *out, size_t pos, uint8_t byte, uint8_t *sum)
{
    char hi = HEX_DIGITS[byte >> 4];
    char lo = HEX_DIGITS[byte & 0x0Fu];
    out[pos] = hi;
    out[pos + 1u] = lo;
    *sum = (uint8_t)(*sum + (uint8_t)hi + (uint8_t)lo);
    return pos + 2u;
}

size_t llcp_encode(const uint8_t *payload, size_t len, char *out, size_t out_cap)
{
    /* len is checked before LLCP_FRAME_SIZE so the size computation cannot overflow. */
    if (payload == NULL || out == NULL || len == 0u || len > LLCP_MAX_PAYLOAD ||
        out_cap < LLCP_FRAME_SIZE(len)) {
        return 0u;
    }
    uint8_t sum = (uint8_t)'b';
    size_t pos = 0u;
    out[pos++] = 'b';
    pos = put_hex(out, pos, (uint8_t)len, &sum);
    for (size_t i = 0u; i < len; i++) {
        pos = put_hex(out, pos, payload[i], &sum);
    }
    uint8_t unused = 0u; /* the checksum does not cover itself */
    return put_hex(out, pos, sum, &unused);
}

size_t llcp_encode_tx(const uint8_t *payload, size_t len, char *out, size_t out_cap)
{
    if (len > LLCP_TX_MAX_PAYLOAD) {
        return 0u;
    }
    return llcp_encode(payload, len, out, out_cap);
}

void llcp_rx_init(llcp_rx_t *rx, uint32_t gap_ms, llcp_expected_len_fn expected_len)
{
    *rx = (llcp_rx_t){0};
    rx->state = ST_IDLE;
    rx->gap_ms = gap_ms;
    rx->expected_len = expected_len;
}

llcp_rx_result_t llcp_rx_poll(llcp_rx_t *rx, uint32_t now_ms)
{
    /* Unsigned difference: correct across the wrap of the millisecond clock. */
    if (rx->state != ST_IDLE && rx->gap_ms != 0u && (uint32_t)(now_ms - rx->last_ms) > rx->gap_ms) {
        rx->state = ST_IDLE;
        rx->timeouts++;
        return LLCP_RX_ERR_TIMEOUT;
    }
    return LLCP_RX_NONE;
}

/* The last checksum digit arrived: decide whether the frame is delivered. */
static llcp_rx_result_t finish(llcp_rx_t *rx, uint8_t received_sum)
{
    if (received_sum != rx->sum) {
        rx->checksum_errors++;
        return LLCP_RX_ERR_CHECKSUM;
    }
    if (rx->expected_len != NULL) {
        int want = rx->expected_len(rx->payload[0]);
        if (want < 0) {
            rx->unknown_ids++;
            return LLCP_RX_ERR_UNKNOWN_ID;
        }
        if (want != (int)rx->len) {
            rx->length_errors++;
            return LLCP_RX_ERR_LENGTH;
        }
    }
    rx->frames_ok++;
    return LLCP_RX_FRAME;
}

llcp_rx_result_t llcp_rx_byte(llcp_rx_t *rx, char c, uint32_t now_ms)
{
    /* A stale partial frame is dropped first; this character is then handled normally
     * (a 'b' still starts a frame). No frame can complete on the same character. */
    llcp_rx_result_t result = llcp_rx_poll(rx, now_ms);
    rx->last_ms = now_ms;

    if (c == 'b') {
        if (rx->state != ST_IDLE) {
            rx->restarts++;
            result = LLCP_RX_ERR_RESTART;
        }
        rx->state = ST_SIZE_HI;
        rx->sum = (uint8_t)'b';
        rx->count = 0u;
        return result;
    }
    if (rx->state == ST_IDLE) {
        return result; /* junk between frames */
    }

    int v = hex_value(c);
    if (v < 0) {
        rx->state = ST_IDLE;
        rx->hex_errors++;
        return LLCP_RX_ERR_HEX;
    }
    uint8_t digit = (uint8_t)v;
    uint8_t byte = (uint8_t)((rx->hi << 4) | digit); /* meaningful in the *_LO states */
    if (rx->state < ST_SUM_HI) {
        rx->sum = (uint8_t)(rx->sum + (uint8_t)c);
    }

    switch (rx->state) {
    case ST_SIZE_HI:
    case ST_DATA_HI:
    case ST_SUM_HI:
        rx->hi = digit;
        rx->state++; /* to the matching *_LO state */
        break;
    case ST_SIZE_LO:
        rx->len = byte;
        rx->state = byte == 0u ? ST_IDLE : ST_DATA_HI; /* length 0 is ignored */
        break;
    case ST_DATA_LO:
        /* count < len <= LLCP_MAX_PAYLOAD here, so the write is in bounds. */
        rx->payload[rx->count++] = byte;
        rx->state = rx->count == rx->len ? ST_SUM_HI : ST_DATA_HI;
        break;
    default: /* ST_SUM_LO */
        rx->state = ST_IDLE;
        return finish(rx, byte);
    }
    return LLCP_RX_NONE;
}
