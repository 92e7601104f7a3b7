/* Dynamixel Protocol 1.0 packets for the AX-12A servo bus (ROBOTIS e-manual "Protocol 1.0";
 * the facts used are the AX-12A's written ones, as that e-manual states them).
 *
 *   instruction  FF FF ID LEN INST P1..PN CHK      LEN = N + 2
 *   status       FF FF ID LEN ERR  P1..PN CHK      CHK = ~(ID + LEN + INST|ERR + P1..PN) & 0xFF
 *
 * Builders write one instruction packet into the caller's buffer and return its length,
 * or 0 when the buffer is too small or an argument is invalid (nothing useful is written
 * then). Multi-byte values are little-endian. A packet is at most DXL_MAX_PACKET_LEN
 * bytes, the DynamixelSDK's limit (TXPACKET_MAX_LEN), so at most 48 servos fit in one
 * SYNC_WRITE of goal position + moving speed.
 *
 * The status parser is fed one received byte at a time. Its window of raw bytes lives in
 * a buffer the caller supplies; a status packet with up to (size - 6) parameter bytes
 * fits. How it resynchronises:
 *   - every FF FF in the window is a candidate start; a candidate is dropped as soon as
 *     its ID > 0xFD, its LEN < 2 or LEN > what the buffer holds, or its error byte > 0x7F
 *     (the SDK's rule: drop a byte and search the next FF FF);
 *   - a candidate is complete when its last byte arrives; if its checksum is right the
 *     packet is reported, otherwise DXL_PARSE_BAD_CHECKSUM is returned and the bytes
 *     inside it are searched again, so a truncated or corrupted packet never swallows
 *     the good packet that follows it;
 *   - when several candidates end on the same byte, the one that started last wins (the
 *     newest header is the real one after garbage or a truncated packet);
 *   - a reported packet discards every byte before it.
 * The parser never touches more than `size` bytes of the buffer.
 *
 * Portable C99: no HAL, no heap, no global state.
 */
#ifndef DXL_PROTOCOL_H
#define DXL_PROTOCOL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define DXL_BROADCAST_ID 254
#define DXL_MAX_ID 253              /* highest servo ID; 0xFE is broadcast */
#define DXL_MAX_PACKET_LEN 250      /* whole packet, header and checksum included (SDK) */
#define DXL_MAX_PARAMS 244          /* DXL_MAX_PACKET_LEN - 6 */
#define DXL_STATUS_MIN_LEN 6        /* FF FF ID LEN ERR CHK: a status without parameters */

/* Instructions (AX-12A: REBOOT and BULK_READ are not supported) */
#define DXL_INST_PING 1
#define DXL_INST_READ 2
#define DXL_INST_WRITE 3
#define DXL_INST_REG_WRITE 4
#define DXL_INST_ACTION 5
#define DXL_INST_RESET 6
#define DXL_INST_SYNC_WRITE 131

/* Status error byte bits */
#define DXL_ERR_VOLTAGE 1
#define DXL_ERR_ANGLE_LIMIT 2
#define DXL_ERR_OVERHEATING 4
#define DXL_ERR_RANGE 8
#define DXL_ERR_CHECKSUM 16
#define DXL_ERR_OVERLOAD 32
#define DXL_ERR_INSTRUCTION 64

/* AX-12A control table: the registers the per-tick SYNC_WRITE covers */
#define DXL_AX_GOAL_POSITION 30     /* 2 bytes, followed by */
#define DXL_AX_MOVING_SPEED 32      /* 2 bytes */
#define DXL_AX_POSITION_MAX 1023
#define DXL_AX_SPEED_MAX 2047       /* 0..1023 joint mode; bit 10 = direction in wheel mode */

/* What one received byte did. */
typedef enum {
    DXL_PARSE_NEED_MORE = 0,    /* nothing complete yet */
    DXL_PARSE_COMPLETE = 1,     /* p->id, p->error, p->params[0 .. p->n_params-1] hold a packet */
    DXL_PARSE_BAD_CHECKSUM = 2, /* a candidate packet ended with a wrong checksum: dropped */
    DXL_PARSE_TOO_LONG = 3      /* a header announced more parameters than the buffer holds */
} dxl_parse_result_t;

/* Status parser state; set up with dxl_parser_init(). The packet fields are valid after
 * DXL_PARSE_COMPLETE until the next dxl_parse_byte() call (params points into buf). */
typedef struct {
    uint8_t *buf;           /* caller's window of received bytes */
    uint16_t size;          /* usable bytes of buf (at most 254) */
    uint16_t len;           /* bytes held in the window */
    uint16_t consumed;      /* bytes to discard at the next call (the reported packet's start and all before it) */
    uint8_t id;
    uint8_t error;
    uint8_t n_params;
    const uint8_t *params;
} dxl_parser_t;

/* The status error byte as named flags (1 = set). */
typedef struct {
    uint8_t voltage;
    uint8_t angle_limit;
    uint8_t overheating;
    uint8_t range;
    uint8_t checksum;
    uint8_t overload;
    uint8_t instruction;
} dxl_error_flags_t;

/* ~(sum of n bytes) & 0xFF: pass the bytes from ID up to the last parameter. */
uint8_t dxl_checksum(const uint8_t *bytes, size_t n);

size_t dxl_build_ping(uint8_t *buf, size_t cap, uint8_t id);
/* id 0..253 (a broadcast READ is never answered) and 1 <= len <= DXL_MAX_PARAMS */
size_t dxl_build_read(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr, uint8_t len);
/* 1 <= n <= DXL_MAX_PARAMS - 1 data bytes written from addr on */
size_t dxl_build_write(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr,
                       const uint8_t *data, size_t n);
size_t dxl_build_reg_write(uint8_t *buf, size_t cap, uint8_t id, uint8_t addr,
                           const uint8_t *data, size_t n);
size_t dxl_build_action(uint8_t *buf, size_t cap, uint8_t id);
/* Factory reset; ID becomes 1. Broadcast is not allowed, so id is 0..253. */
size_t dxl_build_reset(uint8_t *buf, size_t cap, uint8_t id);
/* Broadcast SYNC_WRITE: servo ids[i] gets data[i*data_len .. i*data_len + data_len-1]
 * written from addr on. */
size_t dxl_build_sync_write(uint8_t *buf, size_t cap, uint8_t addr, uint8_t data_len,
                            size_t n_servos, const uint8_t *ids, const uint8_t *data);
/* The per-tick command: goal position (0..1023) and moving speed (0..2047) of n servos,
 * one SYNC_WRITE of 4 bytes each from address 30. */
size_t dxl_build_sync_goal_speed(uint8_t *buf, size_t cap, size_t n_servos, const uint8_t *ids,
                                 const uint16_t *goal, const uint16_t *speed);

/* buf must stay valid while the parser is used; size >= DXL_STATUS_MIN_LEN, larger than
 * 254 is not needed (LEN <= 250). Returns 0, or -1 if buf is NULL or too small. */
int dxl_parser_init(dxl_parser_t *p, uint8_t *buf, size_t size);
/* Forget every byte received so far (e.g. before sending a new instruction). */
void dxl_parser_reset(dxl_parser_t *p);
dxl_parse_result_t dxl_parse_byte(dxl_parser_t *p, uint8_t byte);

void dxl_decode_error(uint8_t error, dxl_error_flags_t *out);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* DXL_PROTOCOL_H */
