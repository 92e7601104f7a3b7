/* The board's last line of defence, beside the application:
 *
 * watchdog    the independent watchdog (IWDG, its own LSI clock) resets the chip unless the
 *             main loop feeds it, and main() feeds it only while app_healthy() says ticks run
 *             and the clock moves (BOARD_WATCHDOG_MS). Debug builds (DEBUG defined, as
 *             CubeIDE's Debug configurations) stop its count while a debugger halts the core.
 * faults      every fault handler and every interrupt the firmware does not use (the
 *             startup file's Default_Handler, replaced in a copy of the vector table in RAM)
 *             cuts the servo supply, records its exception number in RAM that start-up does
 *             not clear, and halts: the watchdog then resets the chip.
 * stops       Error_Handler (a HAL set-up that failed: the external clock at boot, a
 *             peripheral) cuts the servo supply, lights both LEDs and halts with the
 *             watchdog running, even when start-up had not started it yet: the chip resets
 *             and tries again. A clock that does not start shows as both LEDs flashing
 *             about three times a second (lit until the watchdog's reset, 170-470 ms; dark
 *             for the HAL's 100 ms wait for the clock), and no USB.
 * reset cause read once from RCC_CSR's flags at start-up (then cleared), with the exception
 *             recorded before the reset, for the heartbeat.
 * The clock security system (board_clock.c) turns a crystal that fails later into an NMI: a fault.
 */
#ifndef BOARD_GUARD_H
#define BOARD_GUARD_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* cffi:begin */
typedef struct {
    uint8_t cause;     /* MSG_RESET_* */
    uint8_t fault;     /* the exception number that halted the firmware before this reset, 0 none */
} board_reset_t;

/* After the MX_*_Init() functions: reads and clears the reset cause and the fault record,
 * moves the vector table to RAM with the unused entries replaced, starts the watchdog. */
board_reset_t board_guard_start(void);
/* From the main loop, only while the application is healthy. */
void board_watchdog_feed(void);
/* From a fault or unused interrupt's handler: servo supply off, the active exception
 * recorded, the watchdog running, halt (until it resets the chip). */
void board_fault(void);
/* From Error_Handler: servo supply off, both LEDs on (their pins made outputs, as start-up
 * may not have got that far), interrupts off, the watchdog running, halt. */
void board_stop(void);
/* cffi:end */

#ifdef __cplusplus
}
#endif

#endif /* BOARD_GUARD_H */
