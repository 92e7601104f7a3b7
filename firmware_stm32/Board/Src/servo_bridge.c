/* The servo set-up bridge's packet filter; see servo_bridge.h. */
#include "servo_bridge.h"

#include <stdbool.h>
#include <string.h>

#include "dxl_protocol.h"

#define AX12_ID_ADDRESS 3u
#define AX12_BAUD_RATE_ADDRESS 4u

void servo_bridge_init(servo_bridge_t *bridge)
{
    memset(bridge, 0, sizeof *bridge);
}

/* FF FF ID LEN INST P.. CHK, whole and with a right checksum: may it pass? */
static bool allowed(const uint8_t *p, size_t n)
{
    uint32_t sum = 0u;
    for (size_t i = 2u; i + 1u < n; ++i) sum += p[i];
    if ((~sum & 0xFFu) != p[n - 1u]) return false;
    const uint8_t id = p[2], params = (uint8_t)(p[3] - 2u), inst = p[4];
    switch (inst) {
    case DXL_INST_PING: return params == 0u;
    case DXL_INST_READ: return params == 2u && id != DXL_BROADCAST_ID;
    case DXL_INST_WRITE:
        return params == 2u && id != DXL_BROADCAST_ID
               && (p[5] == AX12_ID_ADDRESS || p[5] == AX12_BAUD_RATE_ADDRESS);
    default: return false;
    }
}

size_t servo_bridge_feed(servo_bridge_t *bridge, uint8_t byte)
{
    uint8_t *p = bridge->packet;
    if (bridge->len < 2u && byte != 0xFFu) {        /* outside a packet: wait for FF FF */
        bridge->len = 0u;
        bridge->dropped++;
        return 0u;
    }
    if (bridge->len == 2u && byte == 0xFFu) {       /* FF FF FF: the header still */
        return 0u;
    }
    if (bridge->len == 3u && (byte < 2u || byte + 4u > SERVO_BRIDGE_MAX_PACKET)) {
        bridge->len = 0u;                           /* LEN no allowed packet has */
        bridge->dropped++;
        return 0u;
    }
    p[bridge->len++] = byte;
    if (bridge->len < 4u || bridge->len < p[3] + 4u) return 0u;
    const size_t n = bridge->len;
    bridge->len = 0u;
    if (!allowed(p, n)) {
        bridge->dropped++;
        return 0u;
    }
    bridge->passed++;
    return n;
}
