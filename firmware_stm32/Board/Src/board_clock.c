/* The board's system clock; see board_clock.h. */
#include "board_clock.h"

#include "main.h"

#if BOARD_PLL_P_DIV != 4u
#error "board_clock_config() sets PLLP to RCC_PLLP_DIV4"
#endif

void board_clock_config(void)
{
    RCC_OscInitTypeDef osc = {0};
    RCC_ClkInitTypeDef clk = {0};

    /* Voltage scale 1: HCLK above 84 MHz (RM0383 5.1.3) */
    __HAL_RCC_PWR_CLK_ENABLE();
    __HAL_PWR_VOLTAGESCALING_CONFIG(PWR_REGULATOR_VOLTAGE_SCALE1);

    osc.OscillatorType = RCC_OSCILLATORTYPE_HSE;
    osc.HSEState = BOARD_HSE_BYPASS ? RCC_HSE_BYPASS : RCC_HSE_ON;
    osc.PLL.PLLState = RCC_PLL_ON;
    osc.PLL.PLLSource = RCC_PLLSOURCE_HSE;
    osc.PLL.PLLM = BOARD_PLL_M;
    osc.PLL.PLLN = BOARD_PLL_N;
    osc.PLL.PLLP = RCC_PLLP_DIV4;
    osc.PLL.PLLQ = BOARD_PLL_Q;
    if (HAL_RCC_OscConfig(&osc) != HAL_OK) {
        Error_Handler();
    }

    clk.ClockType = RCC_CLOCKTYPE_HCLK | RCC_CLOCKTYPE_SYSCLK | RCC_CLOCKTYPE_PCLK1 | RCC_CLOCKTYPE_PCLK2;
    clk.SYSCLKSource = RCC_SYSCLKSOURCE_PLLCLK;
    clk.AHBCLKDivider = RCC_SYSCLK_DIV1;
    clk.APB1CLKDivider = RCC_HCLK_DIV2;          /* APB1 at most 50 MHz */
    clk.APB2CLKDivider = RCC_HCLK_DIV1;
    /* 90 < HCLK <= 100 MHz at 2.7-3.6 V: 3 wait states (RM0383 table 5) */
    if (HAL_RCC_ClockConfig(&clk, FLASH_LATENCY_3) != HAL_OK) {
        Error_Handler();
    }
    /* The clock security system: a crystal that stops switches the chip to its internal
     * oscillator and raises the NMI, whose handler cuts the servo supply (RM0383 6.2.7). */
    HAL_RCC_EnableCSS();
}
