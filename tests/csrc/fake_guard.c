/* Test double for board_guard.c; see fake_guard.h. */
#include "fake_guard.h"

#include <string.h>

#include "main.h"

RCC_TypeDef ci_rcc;
IWDG_TypeDef ci_iwdg;
SCB_Type ci_scb;
DBGMCU_TypeDef ci_dbgmcu;
fake_vector_t g_pfnVectors[FAKE_VECTORS];
uint32_t fake_halts;
uint32_t fake_dsbs;
uint32_t fake_error_handlers;
uint32_t fake_irq_disabled;

void Default_Handler(void) { }
void fake_used_handler(void) { }
void fake_halt(void) { fake_halts++; }
void __DSB(void) { fake_dsbs++; }
void __disable_irq(void) { fake_irq_disabled = 1; }
void Error_Handler(void) { fake_error_handlers++; }

static volatile uint32_t *reg(const char *name)
{
    if (strcmp(name, "CSR") == 0) return &ci_rcc.CSR;
    if (strcmp(name, "KR") == 0) return &ci_iwdg.KR;
    if (strcmp(name, "PR") == 0) return &ci_iwdg.PR;
    if (strcmp(name, "RLR") == 0) return &ci_iwdg.RLR;
    if (strcmp(name, "SR") == 0) return &ci_iwdg.SR;
    if (strcmp(name, "APB1FZ") == 0) return &ci_dbgmcu.APB1FZ;
    if (strcmp(name, "ICSR") == 0) return &ci_scb.ICSR;
    if (strcmp(name, "VTOR") == 0) return &ci_scb.VTOR;
    return NULL;
}

void fake_guard_reset(void)
{
    memset(&ci_rcc, 0, sizeof ci_rcc);
    memset(&ci_iwdg, 0, sizeof ci_iwdg);
    memset(&ci_scb, 0, sizeof ci_scb);
    memset(&ci_dbgmcu, 0, sizeof ci_dbgmcu);
    fake_error_handlers = 0;
    fake_irq_disabled = 0;
}

uint32_t fake_guard_get(const char *name) { return *reg(name); }
void fake_guard_set(const char *name, uint32_t value) { *reg(name) = value; }

void fake_guard_dispatch(unsigned n)
{
    ci_scb.ICSR = n;
    board_ram_vectors[n]();
}
