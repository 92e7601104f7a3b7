/* USB CDC link queues; see cdc_link.h. */
#include "cdc_link.h"

void cdc_link_init(cdc_link_t *link, cdc_link_transmit_fn transmit, void *transmit_ctx)
{
    byte_ring_init(&link->rx, link->rx_storage, CDC_LINK_RX_SIZE);
    byte_ring_init(&link->tx, link->tx_storage, CDC_LINK_TX_SIZE);
    link->transfer_len = 0u;
    link->in_flight = false;
    link->fresh_connection = false;
    link->dtr = false;
    link->transmit = transmit;
    link->transmit_ctx = transmit_ctx;
    link->transfers = 0u;
    link->frames_refused = 0u;
}

void cdc_link_on_receive(cdc_link_t *link, const uint8_t *bytes, size_t n)
{
    byte_ring_put(&link->rx, bytes, n);
}

void cdc_link_on_transmit_done(cdc_link_t *link)
{
    link->in_flight = false;
}

void cdc_link_on_connect(cdc_link_t *link)
{
    /* A transfer started before a bus reset never completes: forget it. */
    link->in_flight = false;
    link->fresh_connection = true;
}

void cdc_link_on_line_state(cdc_link_t *link, bool dtr)
{
    if (dtr && !link->dtr) link->fresh_connection = true;   /* a host opened the port */
    link->dtr = dtr;
}

size_t cdc_link_read(cdc_link_t *link, uint8_t *buf, size_t cap)
{
    return byte_ring_take(&link->rx, buf, cap);
}

/* After a (re)connection, what was queued for the previous host is stale. */
static void forget_stale(cdc_link_t *link)
{
    if (link->fresh_connection) {
        link->fresh_connection = false;
        byte_ring_clear(&link->tx);
        link->transfer_len = 0u;
    }
}

bool cdc_link_write(cdc_link_t *link, const uint8_t *buf, size_t n)
{
    forget_stale(link);
    if (!byte_ring_put_all(&link->tx, buf, n)) {
        link->frames_refused++;
        return false;
    }
    cdc_link_pump(link);
    return true;
}

void cdc_link_pump(cdc_link_t *link)
{
    forget_stale(link);
    if (link->in_flight) return;
    if (link->transfer_len == 0u) {
        link->transfer_len = (uint16_t)byte_ring_take(&link->tx, link->transfer, sizeof link->transfer);
        if (link->transfer_len == 0u) return;
    }
    link->in_flight = true;            /* before the call: completion may interrupt right after it */
    if (link->transmit(link->transmit_ctx, link->transfer, link->transfer_len) == CDC_LINK_SENT) {
        link->transfer_len = 0u;
        link->transfers++;
    } else {
        link->in_flight = false;       /* keep the bytes; the next pump retries */
    }
}
