/* Board settings: what differs between the custom board and a NUCLEO-F411RE, and what the
 * model file does not say (it describes the arm, not the board). The pin map is in
 * Core/Inc/main.h (CubeMX writes it there from the pin labels of manipulator.ioc) and in
 * docs/board-project.md's table. Each setting may be overridden on the compiler command line, e.g.
 * `make ... HSE_HZ=25000000 HSE_BYPASS=1` (the Makefile passes -DBOARD_HSE_HZ=...). */
#ifndef BOARD_CONFIG_H
#define BOARD_CONFIG_H

/* The external clock on OSC_IN, in Hz: the custom board's crystal, or the 8 MHz that a
 * NUCLEO-F411RE's ST-LINK feeds to PH0 (MCO). manipulator.ioc's RCC.HSE_VALUE and
 * Core/Inc/stm32f4xx_hal_conf.h's HSE_VALUE must say the same (a test and an #error check). */
#ifndef BOARD_HSE_HZ
#define BOARD_HSE_HZ 8000000u
#endif

/* 0: a crystal between OSC_IN and OSC_OUT (custom board). 1: a clock signal on OSC_IN
 * (NUCLEO-F411RE's ST-LINK MCO, the HSE "bypass" mode of RM0383 6.2.1): CubeIDE's
 * Nucleo_Debug and Nucleo_Release configurations define it. */
#ifndef BOARD_HSE_BYPASS
#define BOARD_HSE_BYPASS 0
#endif

/* The PLL (RM0383 6.3.2), as board_clock_config() sets it: VCO input = HSE / M = 1 MHz (allowed 1-2 MHz; 2 MHz is best
 * for jitter, 1 MHz lets every whole-MHz crystal from 4 to 26 MHz work), VCO = 1 MHz * N
 * = 384 MHz (allowed 100-432 MHz), SYSCLK = VCO / P = 96 MHz (at most 100 MHz), USB and
 * SDIO clock = VCO / Q = 48 MHz exactly (USB full speed needs 48 MHz). */
#define BOARD_PLL_VCO_IN_HZ 1000000u
#define BOARD_PLL_M (BOARD_HSE_HZ / BOARD_PLL_VCO_IN_HZ)
#define BOARD_PLL_N 384u
#define BOARD_PLL_P_DIV 4u
#define BOARD_PLL_Q 8u
#define BOARD_SYSCLK_HZ 96000000u

#if (BOARD_HSE_HZ % BOARD_PLL_VCO_IN_HZ) != 0u || BOARD_HSE_HZ < 4000000u || BOARD_HSE_HZ > 26000000u
#error "BOARD_HSE_HZ must be a whole number of MHz from 4 to 26 MHz (RM0383: HSE 4-26 MHz)"
#endif
#if BOARD_HSE_HZ / BOARD_PLL_M * BOARD_PLL_N / BOARD_PLL_P_DIV != BOARD_SYSCLK_HZ
#error "PLL settings do not give BOARD_SYSCLK_HZ"
#endif

/* The servo supply's MOSFET driver switches the 12 V on when the pin is high. The pin is
 * low (supply off) from MX_GPIO_Init on; before that, from reset, the pin floats and an
 * external pull-down on the driver's input must hold the supply off. */
#define BOARD_SERVO_POWER_ACTIVE_HIGH 1

/* Status LEDs light when the pin is high (NUCLEO LD2 on PA5 does). */
#define BOARD_LED_ACTIVE_HIGH 1

/* Longest wait of one I2C step (HAL timeout, ms) before the IMU read counts as failed.
 * A 14-byte burst at 400 kHz takes about 0.4 ms. */
#define BOARD_I2C_TIMEOUT_MS 2u

/* A servo-bus send that has not finished within twice its wire time plus this margin is
 * aborted (a stuck transmitter must not keep the bus busy forever). */
#define BOARD_SERVO_TX_MARGIN_US 1000u

/* The independent watchdog resets the chip when the main loop has not been healthy (a tick
 * run in the last two periods, the clock moving) for this long: 250 ms nominal, 170-470 ms
 * over the LSI oscillator's 17-47 kHz (RM0383 17.3, datasheet 6.3.9). 1-4096 ms. */
#define BOARD_WATCHDOG_MS 250u

/* Reads of the watchdog's status after its prescaler and reload are written before they
 * count as not taken (board_guard.c). An update takes at most 5 LSI periods (RM0383 17.4.4),
 * 0.3 ms at its slowest 17 kHz; a read and its test take 7 cycles (tests/test_board_guard.py
 * prints the Cortex-M4 estimate; the bus only adds to it), so this waits at least 7 ms at
 * 96 MHz, 44 ms at the 16 MHz the chip starts on. */
#define BOARD_WATCHDOG_UPDATE_POLLS 100000u

#endif /* BOARD_CONFIG_H */
