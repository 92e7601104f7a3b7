/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal_cortex.h of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_CORTEX_H
#define CI_DECLS_STM32F4XX_HAL_CORTEX_H

#include "stm32f4xx_hal_def.h"

void HAL_NVIC_SetPriority(IRQn_Type IRQn, uint32_t PreemptPriority, uint32_t SubPriority);
void HAL_NVIC_EnableIRQ(IRQn_Type IRQn);
void HAL_NVIC_DisableIRQ(IRQn_Type IRQn);

#endif
