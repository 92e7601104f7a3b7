/* Test double for board_guard.c; see fake_guard.h. */
#include "fake_guard.h"

#include <string.h>

#include "main.h"

RCC_TypeDef ci_rcc;
IWDG_TypeDef ci_iwdg;
SCB_Type ci_scb;
fake_vector_t g_pfnVectors[FAKE_VECTORS];
uint32_t fake_halts;
uint32_t fake_dsbs;

void Default_Handler(void) { }
void fake_used_handler(void) { }
void fake_halt(void) { fake_halts++; }
void __DSB(void) { fake_dsbs++; }

static volatile uint32_t *reg(const char *name)
{
    if (strcmp(name, "CSR") == 0) return &ci_rcc.CSR;
    if (strcmp(name, "KR") == 0) return &ci_iwdg.KR;
    if (strcmp(name, "PR") == 0) return &ci_iwdg.PR;
    if (strcmp(name, "RLR") == 0) return &ci_iwdg.RLR;
    if (strcmp(name, "ICSR") == 0) return &ci_scb.ICSR;
    if (strcmp(name, "VTOR") == 0) return &ci_scb.VTOR;
    return NULL;
}

uint32_t fake_guard_get(const char *name) { return *reg(name); }
void fake_guard_set(const char *name, uint32_t value) { *reg(name) = value; }

void fake_guard_dispatch(unsigned n)
{
    ci_scb.ICSR = n;
    board_ram_vectors[n]();
}
