/* USER CODE BEGIN Header */
/**
  ******************************************************************************
  * @file           : usbd_desc.h
  * @brief          : USB device descriptors of the manipulator's virtual COM port.
  ******************************************************************************
  */
/* USER CODE END Header */

#ifndef __USBD_DESC__C__
#define __USBD_DESC__C__

#ifdef __cplusplus
 extern "C" {
#endif

#include "usbd_def.h"

/* USER CODE BEGIN INCLUDE */

/* USER CODE END INCLUDE */

#define DEVICE_ID1          (UID_BASE)
#define DEVICE_ID2          (UID_BASE + 0x4U)
#define DEVICE_ID3          (UID_BASE + 0x8U)

/* 2 header bytes + 24 hex digits of the 96-bit unique ID, in UTF-16 */
#define USB_SIZ_STRING_SERIAL       0x32U

/** Descriptor for the Usb device. */
extern USBD_DescriptorsTypeDef FS_Desc;

#ifdef __cplusplus
}
#endif

#endif /* __USBD_DESC__C__ */
