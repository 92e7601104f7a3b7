/* Single-producer single-consumer byte ring; see byte_ring.h. */
#include "byte_ring.h"

/* Keeps the compiler from moving the data copy past the index update that publishes it
 * (one core: ordering the compiler's accesses is enough). */
#if defined(__GNUC__)
#define RING_BARRIER() __asm__ __volatile__("" ::: "memory")
#else
#define RING_BARRIER()
#endif

bool byte_ring_init(byte_ring_t *ring, uint8_t *storage, uint32_t size)
{
    ring->data = storage;
    ring->size = (size >= 2u && (size & (size - 1u)) == 0u) ? size : 0u;
    ring->head = 0u;
    ring->tail = 0u;
    ring->dropped = 0u;
    return ring->size != 0u;
}

size_t byte_ring_used(const byte_ring_t *ring)
{
    return (size_t)(ring->head - ring->tail);
}

size_t byte_ring_free(const byte_ring_t *ring)
{
    return (size_t)ring->size - byte_ring_used(ring);
}

size_t byte_ring_put(byte_ring_t *ring, const uint8_t *bytes, size_t n)
{
    const size_t room = byte_ring_free(ring);
    const size_t stored = n < room ? n : room;
    uint32_t head = ring->head;
    for (size_t i = 0; i < stored; ++i) {
        ring->data[head & (ring->size - 1u)] = bytes[i];
        head++;
    }
    RING_BARRIER();
    ring->head = head;
    ring->dropped += (uint32_t)(n - stored);
    return stored;
}

bool byte_ring_put_all(byte_ring_t *ring, const uint8_t *bytes, size_t n)
{
    if (n > byte_ring_free(ring)) return false;
    return byte_ring_put(ring, bytes, n) == n;
}

size_t byte_ring_take(byte_ring_t *ring, uint8_t *out, size_t cap)
{
    const size_t used = byte_ring_used(ring);
    const size_t taken = cap < used ? cap : used;
    uint32_t tail = ring->tail;
    RING_BARRIER();
    for (size_t i = 0; i < taken; ++i) {
        out[i] = ring->data[tail & (ring->size - 1u)];
        tail++;
    }
    RING_BARRIER();
    ring->tail = tail;
    return taken;
}

void byte_ring_clear(byte_ring_t *ring)
{
    ring->tail = ring->head;
}
