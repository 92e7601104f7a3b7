/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal_i2c.h of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_I2C_H
#define CI_DECLS_STM32F4XX_HAL_I2C_H

#include "stm32f4xx_hal_def.h"

typedef struct {
    uint32_t ClockSpeed;
    uint32_t DutyCycle;
    uint32_t OwnAddress1;
    uint32_t AddressingMode;
    uint32_t DualAddressMode;
    uint32_t OwnAddress2;
    uint32_t GeneralCallMode;
    uint32_t NoStretchMode;
} I2C_InitTypeDef;

typedef enum {
    HAL_I2C_STATE_RESET = 0x00U,
    HAL_I2C_STATE_READY = 0x20U,
    HAL_I2C_STATE_BUSY = 0x24U,
    HAL_I2C_STATE_BUSY_TX = 0x21U,
    HAL_I2C_STATE_BUSY_RX = 0x22U,
    HAL_I2C_STATE_LISTEN = 0x28U,
    HAL_I2C_STATE_BUSY_TX_LISTEN = 0x29U,
    HAL_I2C_STATE_BUSY_RX_LISTEN = 0x2AU,
    HAL_I2C_STATE_ABORT = 0x60U,
    HAL_I2C_STATE_TIMEOUT = 0xA0U,
    HAL_I2C_STATE_ERROR = 0xE0U
} HAL_I2C_StateTypeDef;

typedef enum {
    HAL_I2C_MODE_NONE = 0x00U,
    HAL_I2C_MODE_MASTER = 0x10U,
    HAL_I2C_MODE_SLAVE = 0x20U,
    HAL_I2C_MODE_MEM = 0x40U
} HAL_I2C_ModeTypeDef;

typedef struct {
    I2C_TypeDef *Instance;
    I2C_InitTypeDef Init;
    uint8_t *pBuffPtr;
    uint16_t XferSize;
    __IO uint16_t XferCount;
    __IO uint32_t XferOptions;
    __IO uint32_t PreviousState;
    DMA_HandleTypeDef *hdmatx;
    DMA_HandleTypeDef *hdmarx;
    HAL_LockTypeDef Lock;
    __IO HAL_I2C_StateTypeDef State;
    __IO HAL_I2C_ModeTypeDef Mode;
    __IO uint32_t ErrorCode;
    __IO uint32_t Devaddress;
    __IO uint32_t Memaddress;
    __IO uint32_t MemaddSize;
    __IO uint32_t EventCount;
} I2C_HandleTypeDef;

#define I2C_DUTYCYCLE_2 0x00000000U
#define I2C_ADDRESSINGMODE_7BIT 0x00004000U
#define I2C_DUALADDRESS_DISABLE 0x00000000U
#define I2C_GENERALCALL_DISABLE 0x00000000U
#define I2C_NOSTRETCH_DISABLE 0x00000000U
#define I2C_MEMADD_SIZE_8BIT 0x00000001U
#define I2C_FLAG_BUSY 0x00100002U
#define I2C_FLAG_MASK 0x0000FFFFU
#define __HAL_I2C_GET_FLAG(__HANDLE__, __FLAG__) ((((uint8_t)((__FLAG__) >> 16U)) == 0x01U) ? \
    (((((__HANDLE__)->Instance->SR1) & ((__FLAG__) & I2C_FLAG_MASK)) == ((__FLAG__) & I2C_FLAG_MASK)) ? SET : RESET) : \
    (((((__HANDLE__)->Instance->SR2) & ((__FLAG__) & I2C_FLAG_MASK)) == ((__FLAG__) & I2C_FLAG_MASK)) ? SET : RESET))

HAL_StatusTypeDef HAL_I2C_Init(I2C_HandleTypeDef *hi2c);
HAL_StatusTypeDef HAL_I2C_DeInit(I2C_HandleTypeDef *hi2c);
void HAL_I2C_MspInit(I2C_HandleTypeDef *hi2c);
void HAL_I2C_MspDeInit(I2C_HandleTypeDef *hi2c);
HAL_StatusTypeDef HAL_I2C_Mem_Write(I2C_HandleTypeDef *hi2c, uint16_t DevAddress, uint16_t MemAddress, uint16_t MemAddSize, uint8_t *pData, uint16_t Size, uint32_t Timeout);
HAL_StatusTypeDef HAL_I2C_Mem_Read(I2C_HandleTypeDef *hi2c, uint16_t DevAddress, uint16_t MemAddress, uint16_t MemAddSize, uint8_t *pData, uint16_t Size, uint32_t Timeout);

#endif
