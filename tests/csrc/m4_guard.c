/* Harness of the board guard on the Cortex-M4 emulation (tests/test_board_guard.py):
 * Board/Src/board_guard.c cross-compiled and linked as the firmware links it, with a start-up
 * file built as ST builds theirs (tests/st_startup.py), the firmware's own interrupt handlers
 * (Core/Src/stm32f4xx_it.c) and the board port's supply switch (Board/Src/board_port.c).
 * The registers are the CI declarations' objects; each function below is one run the test
 * reads back through its output array. */
#include <stdint.h>

#include "board_guard.h"
#include "main.h"

#define VECTORS 102u
typedef void (*vector_t)(void);
extern vector_t board_ram_vectors[VECTORS];

/* what the firmware's handlers and the port name (main.c and usbd_conf.c define them) */
UART_HandleTypeDef huart1;
I2C_HandleTypeDef hi2c1;
TIM_HandleTypeDef htim2;
TIM_HandleTypeDef htim3;
PCD_HandleTypeDef hpcd_USB_OTG_FS;

static uint32_t servo_supply;    /* PA8's output level */
static uint32_t halts;
static uint32_t error_handlers;

/* The start-up file's Reset_Handler names these; the emulation never resets. */
void SystemInit(void) { }
int main(void) { return 0; }

void __DSB(void) { }
void guard_halt(void) { halts++; }   /* BOARD_HALT: back to the harness instead of waiting for the watchdog */
void Error_Handler(void) { error_handlers++; }

void HAL_GPIO_WritePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin, GPIO_PinState PinState)
{
    if (GPIOx == SERVO_PWR_GPIO_Port && (GPIO_Pin & SERVO_PWR_Pin)) servo_supply = PinState == GPIO_PIN_SET;
}

/* board_guard_start after a reset with these RCC_CSR flags.
 * out: cause, fault, VTOR, Error_Handler calls, then the table in RAM (VECTORS words). */
void guard_start(uint32_t csr, uint32_t *out)
{
    ci_rcc.CSR = csr;
    const board_reset_t reset = board_guard_start();
    out[0] = reset.cause;
    out[1] = reset.fault;
    out[2] = ci_scb.VTOR;
    out[3] = error_handlers;
    for (uint32_t i = 0; i < VECTORS; i++) out[4u + i] = (uint32_t)(uintptr_t)board_ram_vectors[i];
}

/* After a pin reset's start, for each exception number: the servo supply on, the core takes
 * that exception through the table in RAM (VECTACTIVE = n, then a branch to the entry, which
 * must carry the Thumb bit), then the watchdog's reset and a start.
 * out, three words a number: the supply's level, the halts, the fault the start reports. */
void guard_dispatch(const uint32_t *numbers, uint32_t count, uint32_t *out)
{
    ci_rcc.CSR = RCC_CSR_PINRSTF;
    (void)board_guard_start();
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t n = numbers[k];
        servo_supply = 1u;
        halts = 0u;
        ci_scb.ICSR = n;
        board_ram_vectors[n]();
        out[3u * k] = servo_supply;
        out[3u * k + 1u] = halts;
        ci_rcc.CSR = RCC_CSR_IWDGRSTF | RCC_CSR_PINRSTF;
        out[3u * k + 2u] = board_guard_start().fault;
    }
}
