/* Test double of the system registers and the startup file's vector table for the host
 * tests of Board/Src/board_guard.c (tests/test_board_guard.py). */
#ifndef FAKE_GUARD_H
#define FAKE_GUARD_H

#include <stdint.h>

/* cffi:begin */
#define FAKE_VECTORS 102
typedef void (*fake_vector_t)(void);
/* the startup file's table: [0] the stack top, then handlers, Default_Handler where unused */
extern fake_vector_t g_pfnVectors[FAKE_VECTORS];
extern fake_vector_t board_ram_vectors[FAKE_VECTORS];
void Default_Handler(void);
void fake_used_handler(void);
extern uint32_t fake_halts;          /* board_fault's halt, returning here */
extern uint32_t fake_dsbs;
extern uint32_t fake_error_handlers; /* Error_Handler calls */
extern uint32_t fake_irq_disabled;   /* __disable_irq called */
/* the registers, as RCC->CSR, IWDG->KR/PR/RLR/SR, SCB->ICSR/VTOR, DBGMCU->APB1FZ; all zero after the reset */
void fake_guard_reset(void);
uint32_t fake_guard_get(const char *reg);
void fake_guard_set(const char *reg, uint32_t value);
/* Calls entry n of the table in RAM with SCB->ICSR's active exception n, as the core does. */
void fake_guard_dispatch(unsigned n);
/* cffi:end */

#endif
