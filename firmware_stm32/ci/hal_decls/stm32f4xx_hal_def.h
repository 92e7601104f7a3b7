/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal_def.h of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_DEF_H
#define CI_DECLS_STM32F4XX_HAL_DEF_H

#include "stm32f4xx.h"

typedef enum {
    HAL_OK = 0x00U,
    HAL_ERROR = 0x01U,
    HAL_BUSY = 0x02U,
    HAL_TIMEOUT = 0x03U
} HAL_StatusTypeDef;

typedef enum {
    HAL_UNLOCKED = 0x00U,
    HAL_LOCKED = 0x01U
} HAL_LockTypeDef;

#define UNUSED(X) (void)X

typedef struct __DMA_HandleTypeDef DMA_HandleTypeDef;   /* only pointed to */

#endif
