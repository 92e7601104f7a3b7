/* The link to the drone over a USB CDC virtual COM port, without blocking anyone.
 *
 * Receive: the USB interrupt hands each OUT packet to cdc_link_on_receive(), which queues
 * it in a ring (bytes that do not fit are dropped and counted: LLCP's checksum throws the
 * damaged frame away); the main loop reads the ring through the port's link_read.
 * Transmit: the port's link_write queues a whole frame or refuses it (queue full, e.g. no
 * host reading); cdc_link_pump() hands queued bytes to the USB stack one transfer at a
 * time whenever the previous transfer has completed, from the main loop only, and retries
 * when the stack is busy. A fresh connection (CDC class init) or a host opening the port
 * (DTR rising) drops what queued up while nobody was listening: a process that opens the
 * port after an hour reads the board's state now, not an hour's old heartbeats. No HAL here: the transmit function is passed in.
 */
#ifndef CDC_LINK_H
#define CDC_LINK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "byte_ring.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define CDC_LINK_RX_SIZE 1024      /* 12 heartbeat-sized frames; the main loop drains it each pass */
#define CDC_LINK_TX_SIZE 1024
#define CDC_LINK_TRANSFER_MAX 256  /* bytes per USB transfer (the stack splits it into packets) */

typedef enum {
    CDC_LINK_SENT = 0,             /* the stack took the transfer; completion comes later */
    CDC_LINK_BUSY = 1,             /* the stack is still sending: try again later */
    CDC_LINK_FAIL = 2,             /* not connected: try again later */
} cdc_link_result_t;

typedef cdc_link_result_t (*cdc_link_transmit_fn)(void *ctx, uint8_t *buf, uint16_t len);

typedef struct {
    byte_ring_t rx;
    byte_ring_t tx;
    uint8_t rx_storage[CDC_LINK_RX_SIZE];
    uint8_t tx_storage[CDC_LINK_TX_SIZE];
    uint8_t transfer[CDC_LINK_TRANSFER_MAX];   /* owned by the USB stack while in flight */
    uint16_t transfer_len;                     /* bytes in transfer not yet taken by the stack */
    volatile bool in_flight;                   /* set by the main loop, cleared by the USB interrupt */
    volatile bool fresh_connection;            /* set by the USB interrupt, handled by the pump */
    bool dtr;                                  /* the host's DTR, as last set */
    cdc_link_transmit_fn transmit;
    void *transmit_ctx;
    uint32_t transfers;                        /* transfers the stack accepted */
    uint32_t frames_refused;                   /* link_write calls refused for lack of room */
} cdc_link_t;

void cdc_link_init(cdc_link_t *link, cdc_link_transmit_fn transmit, void *transmit_ctx);

/* USB interrupt side. */
void cdc_link_on_receive(cdc_link_t *link, const uint8_t *bytes, size_t n);
void cdc_link_on_transmit_done(cdc_link_t *link);
void cdc_link_on_connect(cdc_link_t *link);
void cdc_link_on_line_state(cdc_link_t *link, bool dtr);

/* Main loop side. */
size_t cdc_link_read(cdc_link_t *link, uint8_t *buf, size_t cap);
bool cdc_link_write(cdc_link_t *link, const uint8_t *buf, size_t n);
void cdc_link_pump(cdc_link_t *link);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* CDC_LINK_H */
