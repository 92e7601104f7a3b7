/* CI SCAFFOLDING ONLY (see README.md): declarations matching stm32f4xx_hal_pcd.h / stm32f4xx_hal_pcd_ex.h / stm32f4xx_ll_usb.h of STM32CubeF4;
 * no bodies; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_HAL_PCD_H
#define CI_DECLS_STM32F4XX_HAL_PCD_H

#include "stm32f4xx_hal_def.h"

typedef struct {
    uint32_t dev_endpoints;
    uint32_t Host_channels;
    uint32_t dma_enable;
    uint32_t speed;
    uint32_t ep0_mps;
    uint32_t phy_itface;
    uint32_t Sof_enable;
    uint32_t low_power_enable;
    uint32_t lpm_enable;
    uint32_t battery_charging_enable;
    uint32_t vbus_sensing_enable;
    uint32_t use_dedicated_ep1;
    uint32_t use_external_vbus;
} PCD_InitTypeDef;

typedef struct {
    uint8_t num;
    uint8_t is_in;
    uint8_t is_stall;
    uint8_t is_iso_incomplete;
    uint8_t type;
    uint8_t data_pid_start;
    uint8_t even_odd_frame;
    uint16_t tx_fifo_num;
    uint32_t maxpacket;
    uint8_t *xfer_buff;
    uint32_t dma_addr;
    uint32_t xfer_len;
    uint32_t xfer_size;
    uint32_t xfer_count;
} PCD_EPTypeDef;

typedef enum {
    HAL_PCD_STATE_RESET = 0x00,
    HAL_PCD_STATE_READY = 0x01,
    HAL_PCD_STATE_ERROR = 0x02,
    HAL_PCD_STATE_BUSY = 0x03,
    HAL_PCD_STATE_TIMEOUT = 0x04
} PCD_StateTypeDef;

typedef struct {
    USB_OTG_GlobalTypeDef *Instance;
    PCD_InitTypeDef Init;
    __IO uint8_t USB_Address;
    PCD_EPTypeDef IN_ep[16];
    PCD_EPTypeDef OUT_ep[16];
    HAL_LockTypeDef Lock;
    __IO PCD_StateTypeDef State;
    __IO uint32_t ErrorCode;
    uint32_t Setup[12];
    void *pData;
} PCD_HandleTypeDef;

#define PCD_SPEED_FULL 2U                  /* USBD_FS_SPEED */
#define PCD_PHY_EMBEDDED 2U                /* USB_OTG_EMBEDDED_PHY */

HAL_StatusTypeDef HAL_PCD_Init(PCD_HandleTypeDef *hpcd);
HAL_StatusTypeDef HAL_PCD_DeInit(PCD_HandleTypeDef *hpcd);
void HAL_PCD_MspInit(PCD_HandleTypeDef *hpcd);
void HAL_PCD_MspDeInit(PCD_HandleTypeDef *hpcd);
HAL_StatusTypeDef HAL_PCD_Start(PCD_HandleTypeDef *hpcd);
HAL_StatusTypeDef HAL_PCD_Stop(PCD_HandleTypeDef *hpcd);
void HAL_PCD_IRQHandler(PCD_HandleTypeDef *hpcd);
void HAL_PCD_SOFCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_SetupStageCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_ResetCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_SuspendCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_ResumeCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_ConnectCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_DisconnectCallback(PCD_HandleTypeDef *hpcd);
void HAL_PCD_DataOutStageCallback(PCD_HandleTypeDef *hpcd, uint8_t epnum);
void HAL_PCD_DataInStageCallback(PCD_HandleTypeDef *hpcd, uint8_t epnum);
void HAL_PCD_ISOOUTIncompleteCallback(PCD_HandleTypeDef *hpcd, uint8_t epnum);
void HAL_PCD_ISOINIncompleteCallback(PCD_HandleTypeDef *hpcd, uint8_t epnum);
HAL_StatusTypeDef HAL_PCD_SetAddress(PCD_HandleTypeDef *hpcd, uint8_t address);
HAL_StatusTypeDef HAL_PCD_EP_Open(PCD_HandleTypeDef *hpcd, uint8_t ep_addr, uint16_t ep_mps, uint8_t ep_type);
HAL_StatusTypeDef HAL_PCD_EP_Close(PCD_HandleTypeDef *hpcd, uint8_t ep_addr);
HAL_StatusTypeDef HAL_PCD_EP_Receive(PCD_HandleTypeDef *hpcd, uint8_t ep_addr, uint8_t *pBuf, uint32_t len);
HAL_StatusTypeDef HAL_PCD_EP_Transmit(PCD_HandleTypeDef *hpcd, uint8_t ep_addr, uint8_t *pBuf, uint32_t len);
uint32_t HAL_PCD_EP_GetRxCount(PCD_HandleTypeDef const *hpcd, uint8_t ep_addr);
HAL_StatusTypeDef HAL_PCD_EP_SetStall(PCD_HandleTypeDef *hpcd, uint8_t ep_addr);
HAL_StatusTypeDef HAL_PCD_EP_ClrStall(PCD_HandleTypeDef *hpcd, uint8_t ep_addr);
HAL_StatusTypeDef HAL_PCD_EP_Flush(PCD_HandleTypeDef *hpcd, uint8_t ep_addr);
HAL_StatusTypeDef HAL_PCDEx_SetTxFiFo(PCD_HandleTypeDef *hpcd, uint8_t fifo, uint16_t size);
HAL_StatusTypeDef HAL_PCDEx_SetRxFiFo(PCD_HandleTypeDef *hpcd, uint16_t size);

/* In the HAL a register-write macro; here it only takes its argument. */
#define __HAL_PCD_GATE_PHYCLOCK(__HANDLE__) ((void)(__HANDLE__))

#endif
