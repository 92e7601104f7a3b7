/*
 * The status packet an X-series servo answers the bus driver's status READ with (Protocol
 * 2.0, through its status map: servo_bus.h's SBUS2_AT_*): torque on, Status Return Level 1,
 * at `position`, 12.0 V, 30 deg C, no error. No FF FF FD can stand in it (a position below 0xFF00), so nothing is stuffed.
 * Composing it is the servo's work, not the firmware's: the benches build it beforehand.
 */
#ifndef BENCH_XSERIES_REPLY_H
#define BENCH_XSERIES_REPLY_H

#include <string.h>

#include "dxl_protocol2.h"
#include "model_params.h"
#include "servo_bus.h"

#define XSERIES_REPLY_LEN (DXL2_STATUS_MIN_LEN + SBUS2_STATUS_LEN)

static inline void xseries_reply(uint8_t r[XSERIES_REPLY_LEN], uint8_t id, uint16_t position)
{
    memset(r, 0, XSERIES_REPLY_LEN);
    const uint8_t head[] = { 0xFF, 0xFF, 0xFD, 0x00, id, (uint8_t)(XSERIES_REPLY_LEN - 7),
                             (uint8_t)((XSERIES_REPLY_LEN - 7) >> 8), DXL2_INST_STATUS, 0 };
    memcpy(r, head, sizeof head);
    uint8_t *p = r + sizeof head;   /* the parameters */
    p[SBUS2_AT_TORQUE_ENABLE] = 1u;
    p[SBUS2_AT_STATUS_RETURN_LEVEL] = 1u;
    p[SBUS2_AT_POSITION] = (uint8_t)position;
    p[SBUS2_AT_POSITION + 1] = (uint8_t)(position >> 8);
    p[SBUS2_AT_VOLTAGE] = 120u;
    p[SBUS2_AT_TEMPERATURE] = 30u;
    const uint16_t crc = dxl2_crc(0, r, XSERIES_REPLY_LEN - 2);
    r[XSERIES_REPLY_LEN - 2] = (uint8_t)crc;
    r[XSERIES_REPLY_LEN - 1] = (uint8_t)(crc >> 8);
}

#endif
