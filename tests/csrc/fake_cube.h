/* Test double of the HAL and USB device library for the host run of the CubeMX-owned
 * start-up (tests/test_cubemx_regeneration.py): main() up to its main loop, with every
 * peripheral's init structure recorded as the HAL receives it. Compiled with the CI
 * declarations (firmware_stm32/ci/hal_decls), so every call matches the HAL's prototypes;
 * the functions not defined here are empty weak stubs generated from those declarations. */
#ifndef FAKE_CUBE_H
#define FAKE_CUBE_H

#include <stdint.h>

/* cffi:begin */
typedef struct {
    int reached_main_loop;           /* main() got to its first app_poll() */
    int error_handler;               /* Error_Handler() was called */
    int hse_fails;                   /* HAL_RCC_OscConfig answers HAL_TIMEOUT: the HSE does not start */
    int bridge_selected;             /* board_servo_bridge_selected's answer (CFG0 closed) */
    uint32_t bridge_started, bridge_polled, watchdog_fed;   /* bridge_polled: the feeds before its first poll */
    uint32_t system_clock_config;    /* calls of CubeMX's SystemClock_Config */
    /* what HAL_RCC_OscConfig and HAL_RCC_ClockConfig received (HAL constant values) */
    uint32_t osc_configs, hse_state, pll_state, pll_source, pll_m, pll_n, pll_p, pll_q;
    uint32_t clock_configs, sysclk_source, ahb_divider, apb1_divider, apb2_divider, flash_latency;
    uint32_t css_enabled;            /* HAL_RCC_EnableCSS calls */
    uint32_t guard_started;          /* board_guard_start calls */
    /* board_link_line_state: calls and the last DTR */
    uint32_t line_states;
    int dtr;
    uint32_t line_coding_baud;       /* board_link_line_coding's last bit rate */
    /* USART1 */
    uint32_t halfduplex_inits, uart_inits, baud;
    /* I2C1 */
    uint32_t i2c_inits, i2c_clock_speed;
    /* TIM2 and TIM3 as HAL_TIM_Base_Init received them; TIM3's update interrupt started */
    uint32_t tim2_prescaler, tim2_period, tim3_prescaler, tim3_period, tim3_started_it;
    /* NVIC preemption priority given to an IRQ number (SysTick's by HAL_Init), and whether
     * it was enabled; the HAL's init functions call the MSP set-up, as the HAL does */
    uint32_t systick_priority;
    uint32_t nvic_priority[96];
    uint8_t nvic_enabled[96];
    /* the USB device stack */
    uint32_t usbd_started;
    char string[4][64];              /* manufacturer, product, configuration, interface */
} fake_cube_t;

extern fake_cube_t cube;

/* Runs the firmware's main() until its main loop, Error_Handler (hse_fails: the external
 * clock does not start) or the servo set-up bridge's first poll (bridge: CFG0 closed);
 * returns cube.reached_main_loop. */
int fake_cube_boot(int hse_fails, int bridge);
/* Calls CubeMX's SystemClock_Config alone (main() leaves it out). */
void fake_cube_system_clock_config(void);
/* The host's CDC SET_CONTROL_LINE_STATE request with this wValue (bit 0 DTR), as the USB
 * CDC class hands it to usbd_cdc_if.c. */
void fake_cube_line_state(uint16_t w_value);
/* Asks the device descriptor table for its four strings (into cube.string). */
void fake_cube_usb_strings(void);
/* cffi:end */

#endif
