/* A byte ring buffer for one producer and one consumer, e.g. an interrupt handler that
 * receives and the main loop that reads. Neither side blocks or disables interrupts: the
 * producer writes only `head`, the consumer only `tail`, and both indices run freely
 * (wrapping at 2^32) over a power-of-two storage, so used = head - tail always.
 * No HAL: built for the host tests too. */
#ifndef BYTE_RING_H
#define BYTE_RING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
typedef struct {
    uint8_t *data;
    uint32_t size;                 /* a power of two */
    volatile uint32_t head;        /* bytes ever put: written by the producer only */
    volatile uint32_t tail;        /* bytes ever taken: written by the consumer only */
    volatile uint32_t dropped;     /* bytes the producer could not store (ring full) */
} byte_ring_t;

/* False (and the ring unusable) unless size is a power of two >= 2. */
bool byte_ring_init(byte_ring_t *ring, uint8_t *storage, uint32_t size);
/* Producer: stores as many of the n bytes as fit, counts the rest as dropped. */
size_t byte_ring_put(byte_ring_t *ring, const uint8_t *bytes, size_t n);
/* Producer: stores all n bytes, or none (false) if they do not fit. */
bool byte_ring_put_all(byte_ring_t *ring, const uint8_t *bytes, size_t n);
/* Consumer: takes up to cap bytes, oldest first. */
size_t byte_ring_take(byte_ring_t *ring, uint8_t *out, size_t cap);
/* Consumer: forgets everything stored so far. */
void byte_ring_clear(byte_ring_t *ring);
size_t byte_ring_used(const byte_ring_t *ring);
size_t byte_ring_free(const byte_ring_t *ring);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* BYTE_RING_H */
