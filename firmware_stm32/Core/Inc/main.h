/* USER CODE BEGIN Header */
/**
  ******************************************************************************
  * @file           : main.h
  * @brief          : Header for main.c file.
  *                   Pin labels and shared handles of the uavarm manipulator board.
  *                   CubeMX writes the private defines from manipulator.ioc: its user
  *                   constants (SERVO_BAUD, TICK_PERIOD: the model file's, which make
  *                   codegen writes into the .ioc and here) and the pin labels. Keep
  *                   edits inside USER CODE sections so that regeneration keeps them.
  ******************************************************************************
  */
/* USER CODE END Header */

/* Define to prevent recursive inclusion -------------------------------------*/
#ifndef __MAIN_H
#define __MAIN_H

#ifdef __cplusplus
extern "C" {
#endif

/* Includes ------------------------------------------------------------------*/
#include "stm32f4xx_hal.h"

/* Private includes ----------------------------------------------------------*/
/* USER CODE BEGIN Includes */
#include "board_config.h"
/* USER CODE END Includes */

/* Exported types ------------------------------------------------------------*/
/* USER CODE BEGIN ET */

/* USER CODE END ET */

/* Exported constants --------------------------------------------------------*/
/* USER CODE BEGIN EC */

/* USER CODE END EC */

/* Exported macro ------------------------------------------------------------*/
/* USER CODE BEGIN EM */

/* USER CODE END EM */

/* Exported functions prototypes ---------------------------------------------*/
void Error_Handler(void);

/* USER CODE BEGIN EFP */
extern UART_HandleTypeDef huart1;
extern I2C_HandleTypeDef hi2c1;
extern TIM_HandleTypeDef htim2;
extern TIM_HandleTypeDef htim3;
/* USER CODE END EFP */

/* Private defines -----------------------------------------------------------*/
#define SERVO_BAUD 200000
#define TICK_PERIOD 9999
#define CFG0_Pin GPIO_PIN_0
#define CFG0_GPIO_Port GPIOC
#define CFG1_Pin GPIO_PIN_1
#define CFG1_GPIO_Port GPIOC
#define LED0_Pin GPIO_PIN_5
#define LED0_GPIO_Port GPIOA
#define LED1_Pin GPIO_PIN_6
#define LED1_GPIO_Port GPIOA
#define CFG2_Pin GPIO_PIN_0
#define CFG2_GPIO_Port GPIOB
#define SERVO_PWR_Pin GPIO_PIN_8
#define SERVO_PWR_GPIO_Port GPIOA
#define SERVO_BUS_Pin GPIO_PIN_6
#define SERVO_BUS_GPIO_Port GPIOB
#define IMU_SCL_Pin GPIO_PIN_8
#define IMU_SCL_GPIO_Port GPIOB
#define IMU_SDA_Pin GPIO_PIN_9
#define IMU_SDA_GPIO_Port GPIOB

/* USER CODE BEGIN Private defines */

/* USER CODE END Private defines */

#ifdef __cplusplus
}
#endif

#endif /* __MAIN_H */
