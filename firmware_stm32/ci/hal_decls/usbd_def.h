/* CI SCAFFOLDING ONLY (see README.md): declarations matching usbd_def.h of the
 * STM32_USB_Device_Library v2.11 (as STM32CubeMX copies it); never linked, never on the
 * real build's include path. */
#ifndef CI_DECLS_USBD_DEF_H
#define CI_DECLS_USBD_DEF_H

#include "usbd_conf.h"

#ifndef USBD_MAX_SUPPORTED_CLASS
#define USBD_MAX_SUPPORTED_CLASS 1U
#endif

#define USB_LEN_DEV_DESC 0x12U
#define USB_LEN_LANGID_STR_DESC 0x04U
#define USBD_IDX_MFC_STR 0x01U
#define USBD_IDX_PRODUCT_STR 0x02U
#define USBD_IDX_SERIAL_STR 0x03U
#define USB_DESC_TYPE_DEVICE 0x01U
#define USB_DESC_TYPE_STRING 0x03U
#define USB_MAX_EP0_SIZE 64U
#define USBD_STATE_DEFAULT 0x01U
#define USBD_STATE_ADDRESSED 0x02U
#define USBD_STATE_CONFIGURED 0x03U
#define USBD_STATE_SUSPENDED 0x04U

typedef struct usb_setup_req {
    uint8_t bmRequest;
    uint8_t bRequest;
    uint16_t wValue;
    uint16_t wIndex;
    uint16_t wLength;
} USBD_SetupReqTypedef;

struct _USBD_HandleTypeDef;

typedef struct _Device_cb {
    uint8_t (*Init)(struct _USBD_HandleTypeDef *pdev, uint8_t cfgidx);
    uint8_t (*DeInit)(struct _USBD_HandleTypeDef *pdev, uint8_t cfgidx);
    uint8_t (*Setup)(struct _USBD_HandleTypeDef *pdev, USBD_SetupReqTypedef *req);
    uint8_t (*EP0_TxSent)(struct _USBD_HandleTypeDef *pdev);
    uint8_t (*EP0_RxReady)(struct _USBD_HandleTypeDef *pdev);
    uint8_t (*DataIn)(struct _USBD_HandleTypeDef *pdev, uint8_t epnum);
    uint8_t (*DataOut)(struct _USBD_HandleTypeDef *pdev, uint8_t epnum);
    uint8_t (*SOF)(struct _USBD_HandleTypeDef *pdev);
    uint8_t (*IsoINIncomplete)(struct _USBD_HandleTypeDef *pdev, uint8_t epnum);
    uint8_t (*IsoOUTIncomplete)(struct _USBD_HandleTypeDef *pdev, uint8_t epnum);
    uint8_t *(*GetHSConfigDescriptor)(uint16_t *length);
    uint8_t *(*GetFSConfigDescriptor)(uint16_t *length);
    uint8_t *(*GetOtherSpeedConfigDescriptor)(uint16_t *length);
    uint8_t *(*GetDeviceQualifierDescriptor)(uint16_t *length);
} USBD_ClassTypeDef;

typedef enum {
    USBD_SPEED_HIGH = 0U,
    USBD_SPEED_FULL = 1U,
    USBD_SPEED_LOW = 2U,
} USBD_SpeedTypeDef;

typedef enum {
    USBD_OK = 0U,
    USBD_BUSY,
    USBD_EMEM,
    USBD_FAIL,
} USBD_StatusTypeDef;

typedef struct {
    uint8_t *(*GetDeviceDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetLangIDStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetManufacturerStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetProductStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetSerialStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetConfigurationStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
    uint8_t *(*GetInterfaceStrDescriptor)(USBD_SpeedTypeDef speed, uint16_t *length);
} USBD_DescriptorsTypeDef;

typedef struct {
    uint32_t status;
    uint32_t total_length;
    uint32_t rem_length;
    uint32_t maxpacket;
    uint16_t is_used;
    uint16_t bInterval;
} USBD_EndpointTypeDef;

typedef struct _USBD_HandleTypeDef {
    uint8_t id;
    uint32_t dev_config;
    uint32_t dev_default_config;
    uint32_t dev_config_status;
    USBD_SpeedTypeDef dev_speed;
    USBD_EndpointTypeDef ep_in[16];
    USBD_EndpointTypeDef ep_out[16];
    __IO uint32_t ep0_state;
    uint32_t ep0_data_len;
    __IO uint8_t dev_state;
    __IO uint8_t dev_old_state;
    uint8_t dev_address;
    uint8_t dev_connection_status;
    uint8_t dev_test_mode;
    uint32_t dev_remote_wakeup;
    uint8_t ConfIdx;
    USBD_SetupReqTypedef request;
    USBD_DescriptorsTypeDef *pDesc;
    USBD_ClassTypeDef *pClass[USBD_MAX_SUPPORTED_CLASS];
    void *pClassData;
    void *pClassDataCmsit[USBD_MAX_SUPPORTED_CLASS];
    void *pUserData[USBD_MAX_SUPPORTED_CLASS];
    void *pData;
    void *pBosDesc;
    void *pConfDesc;
    uint32_t classId;
    uint32_t NumClasses;
} USBD_HandleTypeDef;

#ifndef LOBYTE
#define LOBYTE(x) ((uint8_t)((x) & 0x00FFU))
#endif
#ifndef HIBYTE
#define HIBYTE(x) ((uint8_t)(((x) & 0xFF00U) >> 8U))
#endif
#define __ALIGN_END __attribute__ ((aligned (4U)))
#define __ALIGN_BEGIN

#endif
