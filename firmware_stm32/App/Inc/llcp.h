/* LLCP framing: the MRS "low-level communication protocol" in its hexadecimal mode,
 * so the board talks to the MRS mrs_llcp_ros node on the drone's computer.
 *
 * Wire format (what MRS llcp_prepareMessage() in ctu-mrs/mrs_llcp emits):
 *
 *     'b'  SS  P0 P1 ... Pn-1  CC
 *
 *   SS  payload length n, 1..255, as two upper-case hex digits
 *   Pi  every payload byte as two upper-case hex digits; P0 is the message id
 *   CC  8-bit sum of every ASCII character sent before it ('b', SS and all Pi),
 *       as two upper-case hex digits
 *
 * Anything that is not 'b' may sit between frames (MRS can append '\n').
 *
 * The receiver is stricter than MRS's, which delivers frames with a bad checksum
 * (only flagged) and decodes any non-hex character as a silent 0:
 *   - only upper-case hex digits are accepted. MRS emits nothing else, and with
 *     lower-case excluded 'b' can never occur inside a frame, hence:
 *   - a 'b' anywhere starts a new frame, so a truncated frame never swallows the
 *     next good one;
 *   - any other non-hex character inside a frame drops the frame;
 *   - a checksum mismatch drops the frame;
 *   - a partial frame is dropped after an idle gap (rx->gap_ms, 0 = never);
 *   - length 0 ("b00") is ignored, as MRS does;
 *   - optionally the length must match what expected_len(id) says for the id.
 *
 * Device -> drone frames must carry at most LLCP_TX_MAX_PAYLOAD (127) bytes: the
 * mrs_llcp_ros node keeps the received length (stored as 2 * n hex characters) in a
 * uint8_t, so a longer payload reaches ROS truncated. llcp_encode_tx() enforces it;
 * llcp_encode() allows the protocol's 255 (drone -> device direction, tests).
 *
 * Portable C99: no HAL, no heap, no global state; the receiver state lives in the
 * caller's llcp_rx_t.
 */
#ifndef LLCP_H
#define LLCP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Characters in a frame of n payload bytes: 'b' + 2 + 2n + 2. */
#define LLCP_FRAME_SIZE(n) (5u + 2u * (size_t)(n))

/* cffi:begin */
#define LLCP_MAX_PAYLOAD 255
#define LLCP_TX_MAX_PAYLOAD 127
#define LLCP_FRAME_MAX 515

/* What one received character did. Errors mean a frame was dropped. */
typedef enum {
    LLCP_RX_NONE = 0,           /* character consumed, no frame complete */
    LLCP_RX_FRAME = 1,          /* rx->payload[0 .. rx->len-1] holds a verified frame */
    LLCP_RX_ERR_CHECKSUM = 2,   /* checksum did not match */
    LLCP_RX_ERR_HEX = 3,        /* a character that is neither 'b' nor upper-case hex */
    LLCP_RX_ERR_LENGTH = 4,     /* length differs from expected_len(id) */
    LLCP_RX_ERR_UNKNOWN_ID = 5, /* expected_len(id) < 0 */
    LLCP_RX_ERR_TIMEOUT = 6,    /* partial frame older than the idle gap */
    LLCP_RX_ERR_RESTART = 7     /* 'b' inside a frame: partial frame dropped, new one begun */
} llcp_rx_result_t;

/* Payload length a message id must have, or -1 for an id the device does not know. */
typedef int (*llcp_expected_len_fn)(uint8_t id);

/* Receiver state; set up with llcp_rx_init(), then read the fields freely. */
typedef struct {
    /* configuration */
    uint32_t gap_ms;                   /* idle gap that drops a partial frame, 0 = never */
    llcp_expected_len_fn expected_len; /* NULL = any length accepted */
    /* the last frame, valid after LLCP_RX_FRAME until the next llcp_rx_byte() call */
    uint8_t payload[LLCP_MAX_PAYLOAD];
    uint8_t len;
    /* parser */
    uint8_t state;
    uint8_t count;   /* payload bytes complete */
    uint8_t hi;      /* first digit of the current hex pair */
    uint8_t sum;     /* running checksum */
    uint32_t last_ms;
    /* statistics */
    uint32_t frames_ok;
    uint32_t checksum_errors;
    uint32_t hex_errors;
    uint32_t length_errors;
    uint32_t unknown_ids;
    uint32_t timeouts;
    uint32_t restarts;
} llcp_rx_t;

/* Writes the frame for payload[0..len-1] to out (no terminating NUL).
 * Returns the number of characters written, LLCP_FRAME_SIZE(len), or 0 when
 * len is 0 or > LLCP_MAX_PAYLOAD or out_cap is too small; nothing is written then. */
size_t llcp_encode(const uint8_t *payload, size_t len, char *out, size_t out_cap);

/* llcp_encode() for device -> drone messages: also 0 when len > LLCP_TX_MAX_PAYLOAD. */
size_t llcp_encode_tx(const uint8_t *payload, size_t len, char *out, size_t out_cap);

/* Clears rx (statistics included) and sets the idle gap and the optional length check. */
void llcp_rx_init(llcp_rx_t *rx, uint32_t gap_ms, llcp_expected_len_fn expected_len);

/* Feeds one received character; now_ms is a free-running millisecond clock (wraps). */
llcp_rx_result_t llcp_rx_byte(llcp_rx_t *rx, char c, uint32_t now_ms);

/* Drops a partial frame that has been idle longer than the gap, without waiting for
 * the next character (LLCP_RX_ERR_TIMEOUT if it did, else LLCP_RX_NONE). */
llcp_rx_result_t llcp_rx_poll(llcp_rx_t *rx, uint32_t now_ms);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* LLCP_H */
