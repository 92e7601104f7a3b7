/* The board's watchdog, fault record and reset cause; see board_guard.h. */
#include "board_guard.h"

#include <stdbool.h>
#include <stddef.h>

#include "board_config.h"
#include "board_port.h"
#include "main.h"
#include "messages.h"

/* IWDG keys and prescaler (RM0383 17.4): the LSI (about 32 kHz) / 32 counts milliseconds. */
#define IWDG_KEY_START 0xCCCCu
#define IWDG_KEY_UNLOCK 0x5555u
#define IWDG_KEY_RELOAD 0xAAAAu
#define IWDG_PRESCALER_32 3u
#if BOARD_WATCHDOG_MS < 1u || BOARD_WATCHDOG_MS > 4096u
#error "BOARD_WATCHDOG_MS must be 1-4096 (the IWDG's 12-bit reload at LSI / 32)"
#endif

/* The STM32F411's vector table: 16 system exceptions and 86 interrupt positions (RM0383
 * table 37). Its copy in RAM is aligned to the table's size rounded up to a power of two
 * (ARMv7-M B3.2.5: VTOR). */
#define BOARD_VECTORS 102u
typedef void (*board_vector_t)(void);
extern const board_vector_t g_pfnVectors[BOARD_VECTORS];   /* the startup file's table */
extern void Default_Handler(void);                          /* its handler of every unused entry */
board_vector_t board_ram_vectors[BOARD_VECTORS] __attribute__((aligned(512)));   /* VTOR points here */

/* Kept over a reset (not zeroed by the startup code): what halted the firmware. */
#define FAULT_RECORD_MAGIC 0xFA017EC0u
typedef struct {
    uint32_t magic;
    uint32_t exception;
} fault_record_t;
static fault_record_t fault_record __attribute__((section(".noinit")));

#ifdef BOARD_HALT
void BOARD_HALT(void);   /* host tests: return instead of halting */
#else
static void BOARD_HALT(void)
{
    for (;;) {
    }
}
#endif

static uint8_t reset_cause(uint32_t csr)
{
    /* A power-on reset also sets the brown-out and pin flags, every internal reset the pin
     * flag (it drives NRST): the most specific flag first (RM0383 6.3.21). */
    if (csr & RCC_CSR_PORRSTF) return MSG_RESET_POWER_ON;
    if (csr & RCC_CSR_BORRSTF) return MSG_RESET_BROWN_OUT;
    if (csr & RCC_CSR_IWDGRSTF) return MSG_RESET_WATCHDOG;
    if (csr & RCC_CSR_WWDGRSTF) return MSG_RESET_WINDOW_WATCHDOG;
    if (csr & RCC_CSR_LPWRRSTF) return MSG_RESET_LOW_POWER;
    if (csr & RCC_CSR_SFTRSTF) return MSG_RESET_SOFTWARE;
    if (csr & RCC_CSR_PINRSTF) return MSG_RESET_PIN;
    return MSG_RESET_UNKNOWN;
}

static void unused_interrupt(void)
{
    board_fault();
}

/* A vector's address without the Thumb bit. ST's start-up file makes each unused entry a
 * .thumb_set alias of Default_Handler, so the table holds Default_Handler | 1, while
 * Default_Handler itself is a plain label whose address C sees even. */
static uintptr_t code_address(board_vector_t vector)
{
    return (uintptr_t)vector & ~(uintptr_t)1u;
}

static void vectors_to_ram(void)
{
    const uintptr_t unused = code_address(Default_Handler);
    for (size_t i = 0; i < BOARD_VECTORS; ++i) {
        board_ram_vectors[i] = code_address(g_pfnVectors[i]) == unused ? unused_interrupt : g_pfnVectors[i];
    }
    SCB->VTOR = (uint32_t)(uintptr_t)board_ram_vectors;
    __DSB();
}

/* Starts the watchdog with BOARD_WATCHDOG_MS, or restarts its period if it runs, as
 * HAL_IWDG_Init does: the new prescaler and reload cross into the LSI's domain (IWDG_SR's
 * PVU and RVU set meanwhile, RM0383 17.4.4), and only then does the reload key load the
 * counter. False if they were not taken within BOARD_WATCHDOG_UPDATE_POLLS reads of the
 * status: the watchdog then counts with what it had (after reset, 512 ms at 32 kHz). */
static bool watchdog_start(void)
{
#ifdef DEBUG
    __HAL_DBGMCU_FREEZE_IWDG();         /* debug builds: a debugger's halt stops its count */
#endif
    IWDG->KR = IWDG_KEY_START;          /* starts the LSI too; cannot be stopped until reset */
    IWDG->KR = IWDG_KEY_UNLOCK;
    IWDG->PR = IWDG_PRESCALER_32;
    IWDG->RLR = BOARD_WATCHDOG_MS - 1u;
    for (uint32_t polls = 0u; (IWDG->SR & (IWDG_SR_PVU | IWDG_SR_RVU)) != 0u;) {
        if (++polls == BOARD_WATCHDOG_UPDATE_POLLS) return false;
    }
    IWDG->KR = IWDG_KEY_RELOAD;
    return true;
}

board_reset_t board_guard_start(void)
{
    board_reset_t reset = { reset_cause(RCC->CSR), 0u };
    RCC->CSR |= RCC_CSR_RMVF;
    /* RAM does not survive a power-on or brown-out reset: the record is noise then */
    const bool ram_kept = reset.cause != MSG_RESET_POWER_ON && reset.cause != MSG_RESET_BROWN_OUT;
    if (ram_kept && fault_record.magic == FAULT_RECORD_MAGIC && fault_record.exception <= 0xFFu) {
        reset.fault = (uint8_t)fault_record.exception;
    }
    fault_record.magic = 0u;
    vectors_to_ram();
    if (!watchdog_start()) {
        Error_Handler();                /* not supervised as set: stop rather than run */
    }
    return reset;
}

void board_watchdog_feed(void)
{
    IWDG->KR = IWDG_KEY_RELOAD;
}

void board_fault(void)
{
    board_servo_power_off();
    fault_record.exception = SCB->ICSR & SCB_ICSR_VECTACTIVE_Msk;
    fault_record.magic = FAULT_RECORD_MAGIC;
    (void)watchdog_start();             /* a fault before board_guard_start ends in a reset too */
    BOARD_HALT();
}

void board_stop(void)
{
    board_stop_outputs();
    __disable_irq();
    (void)watchdog_start();
    BOARD_HALT();
}
