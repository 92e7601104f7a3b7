/* The board as a Dynamixel adapter on its own servo bus, for setting new servos up
 * (`uavarm servos setup`): chosen at reset by CFG0 (its solder bridge, or on a NUCLEO-F411RE
 * a wire from A5 to GND), the board then does not run the arm; it passes instruction packets
 * from USB to the servo bus at the baud rate the host sets for its port, and the bus's bytes
 * back (board_port.c).
 *
 * Only the packets that set a servo up pass: PING, READ, and a WRITE of one byte into the
 * ID or the Baud Rate register of one servo. Anything else (a goal, torque, limits, a
 * broadcast write, SYNC_WRITE, REG_WRITE, ACTION, RESET, a bad checksum) is dropped, so no
 * motion can be commanded through the bridge. No HAL here: host-tested.
 */
#ifndef SERVO_BRIDGE_H
#define SERVO_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
#define SERVO_BRIDGE_MAX_PACKET 8u          /* the longest that passes: a WRITE of one byte */

typedef struct {
    uint8_t packet[SERVO_BRIDGE_MAX_PACKET];
    uint8_t len;                            /* bytes of the packet being gathered */
    uint32_t passed;                        /* packets let through */
    uint32_t dropped;                       /* packets refused, and stray bytes between packets */
} servo_bridge_t;

void servo_bridge_init(servo_bridge_t *bridge);
/* One byte from the host. Returns the length of the packet it completes, if that packet
 * may pass (it is then in bridge->packet until the next call), else 0. */
size_t servo_bridge_feed(servo_bridge_t *bridge, uint8_t byte);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* SERVO_BRIDGE_H */
