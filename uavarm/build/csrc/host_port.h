/* The port interface (firmware_stm32/App/Inc/port.h) on the host: plain buffers that
 * Python fills and drains, so tests and the simulated board reach the application only
 * through what the hardware has: link bytes, servo-bus bytes, the supply switch, LEDs,
 * IMU registers and time.
 *
 *   link     host_port_link_push() = bytes from the drone; host_port_link_take() = bytes
 *            the application sent (heartbeats).
 *   servo    host_port_servo_take() = bytes the application transmitted (forward them to
 *            the bus simulator); host_port_servo_push() = bytes the servos sent back. A
 *            send keeps the line busy for its bytes' time at the configured baud.
 *   IMU      a 128-byte MPU-6050 register file: reads and writes go to imu_regs (reads
 *            auto-increment; one that covers INT_STATUS clears its DATA_RDY bit, as the
 *            chip does); imu_present = false makes every transfer fail (NACK).
 *   time     now_us, set by Python.
 */
#ifndef HOST_PORT_H
#define HOST_PORT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "port.h"

/* cffi:begin */
#define HOST_FIFO_CAP 8192

typedef struct {
    uint8_t data[HOST_FIFO_CAP];
    size_t head;       /* next byte to read */
    size_t len;        /* bytes held */
} host_fifo_t;

typedef struct {
    port_t port;                  /* give &port to app_init() */
    uint32_t now_us;
    uint32_t servo_baud;
    /* link */
    host_fifo_t link_in;
    host_fifo_t link_out;
    bool link_refuse_writes;      /* fault injection: the transmit queue is full */
    /* servo bus */
    host_fifo_t servo_out;
    host_fifo_t servo_in;
    uint32_t servo_tx_end_us;
    bool servo_tx_active;
    uint32_t servo_sends;
    bool servo_power;
    uint32_t servo_power_switches;
    /* LEDs */
    bool led[2];
    /* IMU */
    uint8_t imu_address;
    bool imu_present;
    uint8_t imu_regs[128];
    uint32_t imu_reads;
    uint32_t imu_writes;
} host_port_t;

void host_port_init(host_port_t *hp, uint32_t servo_baud, uint8_t imu_address);
/* Bytes into the application's link input; returns how many fitted. */
size_t host_port_link_push(host_port_t *hp, const uint8_t *buf, size_t n);
/* Up to cap bytes the application wrote to the link. */
size_t host_port_link_take(host_port_t *hp, uint8_t *buf, size_t cap);
/* Bytes the servos sent, into the application's servo input; returns how many fitted. */
size_t host_port_servo_push(host_port_t *hp, const uint8_t *buf, size_t n);
/* Up to cap bytes the application transmitted on the servo bus. */
size_t host_port_servo_take(host_port_t *hp, uint8_t *buf, size_t cap);
/* cffi:end */

#endif /* HOST_PORT_H */
