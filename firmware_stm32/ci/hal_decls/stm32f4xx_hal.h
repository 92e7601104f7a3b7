/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal.h of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_H
#define CI_DECLS_STM32F4XX_HAL_H

/* As the real stm32f4xx_hal.h: the project's HAL configuration (Core/Inc), which
 * includes the module headers it enables (declared in this folder). */
#include "stm32f4xx_hal_def.h"
#include "stm32f4xx_hal_conf.h"

HAL_StatusTypeDef HAL_Init(void);
void HAL_IncTick(void);
void HAL_Delay(uint32_t Delay);
uint32_t HAL_GetTick(void);

#define __HAL_DBGMCU_FREEZE_IWDG() (DBGMCU->APB1FZ |= (DBGMCU_APB1_FZ_DBG_IWDG_STOP))

#endif
