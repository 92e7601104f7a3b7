/* The system clock of the board (board_config.h): HSE from a crystal or an external clock
 * of BOARD_HSE_HZ, PLL to 96 MHz SYSCLK and exactly 48 MHz for USB, APB1 48 MHz, APB2 and
 * the timers 96 MHz. main.c calls it in a USER CODE section in place of CubeMX's
 * SystemClock_Config, whose call manipulator.ioc leaves out ("Do Not Generate Function
 * Call"): CubeMX writes that one with the .ioc's fixed numbers, so the board settings
 * (the Makefile's HSE_HZ and HSE_BYPASS) would not reach it. */
#ifndef BOARD_CLOCK_H
#define BOARD_CLOCK_H

void board_clock_config(void);

#endif /* BOARD_CLOCK_H */
