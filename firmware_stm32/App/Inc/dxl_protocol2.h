/* Dynamixel Protocol 2.0 packets for X-series servos (XL430-W250, XM430-W350), beside the
 * Protocol 1.0 ones of dxl_protocol.h (ROBOTIS e-manual "Protocol 2.0").
 *
 *   instruction  FF FF FD 00 ID LEN_L LEN_H INST     P1..PN CRC_L CRC_H
 *   status       FF FF FD 00 ID LEN_L LEN_H 55  ERR  P1..PN CRC_L CRC_H
 *
 * LEN counts the bytes after it (instruction, parameters, CRC) as sent, stuffing included.
 * Byte stuffing: from the instruction to the last parameter, every FF FF FD is sent as
 * FF FF FD FD, so a header never appears inside a packet. The CRC is CRC-16 with
 * polynomial 0x8005 (no reflection, initial value 0) over every byte before it, stuffed.
 *
 * Builders write one instruction packet into the caller's buffer and return its length,
 * or 0 when the buffer is too small or an argument is invalid (nothing useful is written
 * then; the buffer is never written past cap). Multi-byte values are little-endian. A
 * packet is at most DXL2_MAX_PACKET_LEN bytes, the DynamixelSDK's limit.
 *
 * The status parser is fed one received byte at a time (or a buffer, which it takes byte
 * by byte). Its window of raw bytes lives in a buffer the caller supplies; a status packet
 * of up to `size` bytes as sent (stuffing included) fits. How it resynchronises:
 *   - every FF FF FD 00 in the window is a candidate start; a candidate is dropped as soon
 *     as its ID > 252, its LEN < 4 or LEN > DXL2_MAX_LENGTH (the SDK's limit), its whole
 *     packet is longer than the buffer, or its instruction is not STATUS (0x55);
 *   - a candidate is complete when its last byte arrives; its CRC is checked, then its
 *     stuffing (each FF FF FD followed by the FD added when it was sent); a wrong one is
 *     reported (DXL2_PARSE_BAD_CRC, DXL2_PARSE_BAD_STUFFING) and the bytes inside it are
 *     searched again, so a truncated or corrupted packet never swallows the good packet
 *     that follows it;
 *   - when several candidates end on the same byte, the one that started last wins;
 *   - a reported packet discards itself and every byte before it.
 * The stuffing is removed in place: params points to the parameters as the servo meant
 * them. Whether the ID is the one asked is the caller's check, as with Protocol 1.0.
 * The parser never touches more than `size` bytes of the buffer.
 *
 * Portable C99: no HAL, no heap, no global state.
 */
#ifndef DXL_PROTOCOL2_H
#define DXL_PROTOCOL2_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define DXL2_BROADCAST_ID 254
#define DXL2_MAX_ID 252             /* highest servo ID; 0xFD and 0xFF would look like a header */
#define DXL2_MAX_PACKET_LEN 1024    /* whole instruction packet, stuffed (SDK TXPACKET_MAX_LEN) */
#define DXL2_MAX_LENGTH 1024        /* largest LEN of a status packet (SDK RXPACKET_MAX_LEN) */
#define DXL2_MAX_READ 1020          /* DXL2_MAX_LENGTH - 4: data bytes one status packet holds */
#define DXL2_STATUS_MIN_LEN 11      /* a status without parameters */

/* Instructions */
#define DXL2_INST_PING 0x01
#define DXL2_INST_READ 0x02
#define DXL2_INST_WRITE 0x03
#define DXL2_INST_REBOOT 0x08
#define DXL2_INST_STATUS 0x55
#define DXL2_INST_SYNC_READ 0x82
#define DXL2_INST_SYNC_WRITE 0x83

/* Status error byte: bit 7 is the alert (a hardware error: see the servo's Hardware Error
 * Status register), bits 0..6 the error number. */
#define DXL2_ERR_ALERT 0x80
#define DXL2_ERRNUM_RESULT_FAIL 1
#define DXL2_ERRNUM_INSTRUCTION 2
#define DXL2_ERRNUM_CRC 3
#define DXL2_ERRNUM_DATA_RANGE 4
#define DXL2_ERRNUM_DATA_LENGTH 5
#define DXL2_ERRNUM_DATA_LIMIT 6
#define DXL2_ERRNUM_ACCESS 7

/* What one received byte did. */
typedef enum {
    DXL2_PARSE_NEED_MORE = 0,    /* nothing complete yet */
    DXL2_PARSE_COMPLETE = 1,     /* p->id, p->error, p->params[0 .. p->n_params-1] hold a packet */
    DXL2_PARSE_BAD_CRC = 2,      /* a candidate packet ended with a wrong CRC: dropped */
    DXL2_PARSE_TOO_LONG = 3,     /* a header announced a packet longer than the buffer */
    DXL2_PARSE_BAD_STUFFING = 4  /* right CRC, but an FF FF FD without its added FD: dropped */
} dxl2_parse_result_t;

/* Status parser state; set up with dxl2_parser_init(). The packet fields are valid after
 * DXL2_PARSE_COMPLETE until the next dxl2_parse_byte() call (params points into buf). */
typedef struct {
    uint8_t *buf;           /* caller's window of received bytes */
    uint16_t size;          /* usable bytes of buf (at most DXL2_MAX_LENGTH + 7) */
    uint16_t len;           /* bytes held in the window */
    uint16_t consumed;      /* bytes to discard at the next call (the reported packet and all before it) */
    uint8_t id;
    uint8_t error;          /* the raw error byte */
    uint16_t n_params;
    const uint8_t *params;
} dxl2_parser_t;

/* The status error byte, split. */
typedef struct {
    uint8_t hardware_error; /* the alert bit */
    uint8_t number;         /* 0 (none) or DXL2_ERRNUM_* */
} dxl2_error_t;

/* CRC-16 (polynomial 0x8005) of n bytes, continuing from crc (0 to start). */
uint16_t dxl2_crc(uint16_t crc, const uint8_t *bytes, size_t n);

/* The CRC is linear (no final XOR): a packet's CRC is the CRC of it with some bytes 0, XOR
 * each such byte's share, which depends only on the byte and on how many bytes follow it
 * up to the CRC. share[b] for a byte b with `after` bytes after it. So a packet whose changing
 * bytes stand at fixed places gets its CRC by one lookup for each of them. */
void dxl2_crc_shares(uint16_t share[256], unsigned after);

/* id 0..252 or broadcast (every servo answers, one after the other) */
size_t dxl2_build_ping(uint8_t *buf, size_t cap, uint8_t id);
/* id 0..252 and 1 <= len <= DXL2_MAX_READ */
size_t dxl2_build_read(uint8_t *buf, size_t cap, uint8_t id, uint16_t addr, uint16_t len);
/* n >= 1 data bytes written from addr on; id 0..252 or broadcast */
size_t dxl2_build_write(uint8_t *buf, size_t cap, uint8_t id, uint16_t addr,
                        const uint8_t *data, size_t n);
/* id 0..252 or broadcast */
size_t dxl2_build_reboot(uint8_t *buf, size_t cap, uint8_t id);
/* Broadcast SYNC_WRITE: servo ids[i] gets data[i*data_len .. i*data_len + data_len-1]
 * written from addr on (e.g. goal positions: addr 116, data_len 4). */
size_t dxl2_build_sync_write(uint8_t *buf, size_t cap, uint16_t addr, uint16_t data_len,
                             size_t n_servos, const uint8_t *ids, const uint8_t *data);
/* Broadcast SYNC_READ: each of ids[0..n_servos-1] answers, in that order, with a status
 * packet holding its data_len (1..DXL2_MAX_READ) bytes from addr on. */
size_t dxl2_build_sync_read(uint8_t *buf, size_t cap, uint16_t addr, uint16_t data_len,
                            size_t n_servos, const uint8_t *ids);

/* buf must stay valid while the parser is used; size >= DXL2_STATUS_MIN_LEN, larger than
 * DXL2_MAX_LENGTH + 7 is not needed. Returns 0, or -1 if buf is NULL or too small. */
int dxl2_parser_init(dxl2_parser_t *p, uint8_t *buf, size_t size);
/* Forget every byte received so far (e.g. before sending a new instruction). */
void dxl2_parser_reset(dxl2_parser_t *p);
dxl2_parse_result_t dxl2_parse_byte(dxl2_parser_t *p, uint8_t byte);
/* Feeds data[0..n-1] byte by byte and stops after the first byte whose result is not
 * DXL2_PARSE_NEED_MORE; *used (may be NULL) is the number of bytes taken. */
dxl2_parse_result_t dxl2_parse_bytes(dxl2_parser_t *p, const uint8_t *data, size_t n, size_t *used);

void dxl2_decode_error(uint8_t error, dxl2_error_t *out);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* DXL_PROTOCOL2_H */
