/* The port interface (App/Inc/port.h) on the STM32F411 with the STM32CubeF4 HAL.
 *
 * time        TIM2, a 32-bit counter at 1 MHz, free running: wraps at 2^32 us like port.h says.
 * servo bus   USART1 in single-wire half-duplex mode (HAL_HalfDuplex_Init), interrupt
 *             driven: a send switches the line to transmit and starts HAL_UART_Transmit_IT;
 *             the transmit-complete interrupt (TC: last stop bit out) switches it back to
 *             receive, so a reply after the servo's Return Delay is not missed. Received
 *             bytes go one by one into a ring the application reads. A send that does not
 *             complete in time is aborted.
 * link        USB CDC (USB_DEVICE/App/usbd_cdc_if.c) through Board/Src/cdc_link.c.
 * IMU         I2C1 at 400 kHz, HAL_I2C_Mem_Read/Mem_Write with a short timeout: called
 *             from the main loop (the tick runs there), never from an interrupt.
 * servo power, LEDs: GPIO.
 *
 * The 100 Hz tick comes from TIM3 (main.c: HAL_TIM_PeriodElapsedCallback -> app_request_tick).
 */
#ifndef BOARD_PORT_H
#define BOARD_PORT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "port.h"

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
/* Starts the time base and servo-bus reception; returns the port for app_init(). Call
 * after the MX_*_Init() functions. */
const port_t *board_port_start(void);
/* From the main loop, after app_poll(): moves queued link bytes to USB. */
void board_port_poll(void);
/* The three configuration inputs (solder bridges to ground read as 1), bit i = CFGi. */
uint8_t board_config_inputs(void);

/* USB CDC glue, called by USB_DEVICE/App/usbd_cdc_if.c from the USB interrupt. */
void board_link_connected(void);
void board_link_received(const uint8_t *bytes, uint32_t n);
void board_link_transmitted(void);
/* CDC SET_CONTROL_LINE_STATE: DTR set when a host opens the port. */
void board_link_line_state(bool dtr);
/* CDC SET_LINE_CODING: the bit rate the host set for its port (used by the servo set-up bridge). */
void board_link_line_coding(uint32_t baud);

/* The servo set-up bridge (servo_bridge.h), instead of the application: selected when CFG0
 * reads closed at reset; main() then starts it and polls it for ever, feeding the watchdog.
 * The servo supply is on while the host has the port open (DTR), LED0 lit. */
bool board_servo_bridge_selected(void);
void board_servo_bridge_start(void);
void board_servo_bridge_poll(void);

/* Servo supply off at once, without the HAL state machine: for Error_Handler and faults. */
void board_servo_power_off(void);
/* Servo supply off and both LEDs on, the three pins made outputs first (board_stop: start-up
 * may stop before MX_GPIO_Init has run). */
void board_stop_outputs(void);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* BOARD_PORT_H */
