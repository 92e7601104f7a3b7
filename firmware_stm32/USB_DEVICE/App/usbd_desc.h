/* USER CODE BEGIN Header */
/**
  ******************************************************************************
  * @file           : usbd_desc.h
  * @brief          : USB device descriptors of the manipulator's virtual COM port.
  *                   The serial number is CubeMX's: 12 hex digits made from the
  *                   chip's 96-bit unique ID (RM0383 24.1).
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

#define  USB_SIZ_STRING_SERIAL       0x1A

/* USER CODE BEGIN EXPORTED_CONSTANTS */

/* USER CODE END EXPORTED_CONSTANTS */

/** Descriptor for the Usb device. */
extern USBD_DescriptorsTypeDef FS_Desc;

#ifdef __cplusplus
}
#endif

#endif /* __USBD_DESC__C__ */
