/* CI SCAFFOLDING ONLY (see README.md): stm32f4xx_hal_flash.h declares nothing the firmware
 * calls directly (its macros used by main.c are in stm32f4xx_hal_rcc.h here). */
#include "stm32f4xx_hal_def.h"
