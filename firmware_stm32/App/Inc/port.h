/* The board, as the portable application sees it.
 *
 * Everything board-specific goes through this table of functions: the STM32 port fills it
 * with HAL calls, the host port (uavarm/csrc/host_port.c) with buffers that Python reads
 * and writes, so the same application runs on the drone and in tests. Every function must
 * return at once (no blocking); `ctx` is the port's own state.
 */
#ifndef PORT_H
#define PORT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
typedef struct {
    void *ctx;
    /* Free-running microsecond clock; wraps after 2^32 us (the application only subtracts). */
    uint32_t (*time_us)(void *ctx);

    /* Link to the drone (USB CDC). read: bytes received since the last call, up to cap.
     * write: queue all n bytes for sending, or none (false) when the queue is full. */
    size_t (*link_read)(void *ctx, uint8_t *buf, size_t cap);
    bool (*link_write)(void *ctx, const uint8_t *buf, size_t n);

    /* Servo bus (half-duplex UART). send: switch the line to transmit, send n bytes, and
     * release it to receive as soon as the last stop bit is out; false if still sending.
     * busy: a send is still in progress. read: bytes received while the line was released. */
    bool (*servo_send)(void *ctx, const uint8_t *buf, size_t n);
    bool (*servo_busy)(void *ctx);
    size_t (*servo_read)(void *ctx, uint8_t *buf, size_t cap);
    /* The 12 V servo supply switch. */
    void (*servo_power)(void *ctx, bool on);

    /* Status LEDs, 0 and 1. */
    void (*led)(void *ctx, uint8_t index, bool on);

    /* IMU on I2C (7-bit address): burst register read / single register write; false on
     * a bus error or NACK. */
    bool (*imu_read)(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n);
    bool (*imu_write)(void *ctx, uint8_t addr, uint8_t reg, uint8_t value);
} port_t;
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* PORT_H */
