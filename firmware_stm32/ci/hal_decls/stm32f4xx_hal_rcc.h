/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal_rcc.h / stm32f4xx_hal_rcc_ex.h (STM32F411: no PLLR) of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_RCC_H
#define CI_DECLS_STM32F4XX_HAL_RCC_H

#include "stm32f4xx_hal_def.h"

typedef struct {
    uint32_t PLLState;
    uint32_t PLLSource;
    uint32_t PLLM;
    uint32_t PLLN;
    uint32_t PLLP;
    uint32_t PLLQ;
} RCC_PLLInitTypeDef;

typedef struct {
    uint32_t OscillatorType;
    uint32_t HSEState;
    uint32_t LSEState;
    uint32_t HSIState;
    uint32_t HSICalibrationValue;
    uint32_t LSIState;
    RCC_PLLInitTypeDef PLL;
} RCC_OscInitTypeDef;

typedef struct {
    uint32_t ClockType;
    uint32_t SYSCLKSource;
    uint32_t AHBCLKDivider;
    uint32_t APB1CLKDivider;
    uint32_t APB2CLKDivider;
} RCC_ClkInitTypeDef;

#define RCC_OSCILLATORTYPE_HSE 0x00000001U
#define RCC_HSE_ON 0x00010000U              /* RCC_CR_HSEON */
#define RCC_HSE_BYPASS 0x00050000U          /* RCC_CR_HSEBYP | RCC_CR_HSEON */
#define RCC_PLL_ON 0x02U
#define RCC_PLLSOURCE_HSE 0x00400000U       /* RCC_PLLCFGR_PLLSRC_HSE */
#define RCC_PLLP_DIV4 0x00000004U
#define RCC_CLOCKTYPE_SYSCLK 0x00000001U
#define RCC_CLOCKTYPE_HCLK 0x00000002U
#define RCC_CLOCKTYPE_PCLK1 0x00000004U
#define RCC_CLOCKTYPE_PCLK2 0x00000008U
#define RCC_SYSCLKSOURCE_PLLCLK 0x00000002U
#define RCC_SYSCLK_DIV1 0x00000000U
#define RCC_HCLK_DIV1 0x00000000U
#define RCC_HCLK_DIV2 0x00001000U
#define FLASH_LATENCY_3 0x00000003U
#define PWR_REGULATOR_VOLTAGE_SCALE1 0x0000C000U

HAL_StatusTypeDef HAL_RCC_OscConfig(RCC_OscInitTypeDef *RCC_OscInitStruct);
HAL_StatusTypeDef HAL_RCC_ClockConfig(RCC_ClkInitTypeDef *RCC_ClkInitStruct, uint32_t FLatency);
void HAL_RCC_EnableCSS(void);

/* In the HAL these are register-write macros; here they only take their argument. */
#define __HAL_RCC_PWR_CLK_ENABLE() ((void)0)
#define __HAL_RCC_SYSCFG_CLK_ENABLE() ((void)0)
#define __HAL_RCC_GPIOA_CLK_ENABLE() ((void)0)
#define __HAL_RCC_GPIOB_CLK_ENABLE() ((void)0)
#define __HAL_RCC_GPIOC_CLK_ENABLE() ((void)0)
#define __HAL_RCC_GPIOH_CLK_ENABLE() ((void)0)
#define __HAL_RCC_I2C1_CLK_ENABLE() ((void)0)
#define __HAL_RCC_I2C1_CLK_DISABLE() ((void)0)
#define __HAL_RCC_TIM2_CLK_ENABLE() ((void)0)
#define __HAL_RCC_TIM3_CLK_ENABLE() ((void)0)
#define __HAL_RCC_USART1_CLK_ENABLE() ((void)0)
#define __HAL_RCC_USB_OTG_FS_CLK_ENABLE() ((void)0)
#define __HAL_RCC_USB_OTG_FS_CLK_DISABLE() ((void)0)
#define __HAL_RCC_TIM2_CLK_DISABLE() ((void)0)
#define __HAL_RCC_TIM3_CLK_DISABLE() ((void)0)
#define __HAL_RCC_USART1_CLK_DISABLE() ((void)0)
#define __HAL_PWR_VOLTAGESCALING_CONFIG(__REGULATOR__) ((void)(__REGULATOR__))

#endif
