/* CI SCAFFOLDING ONLY (see README.md): the part of the CMSIS device header
 * stm32f411xe.h that the firmware's HAL-using files name. Register layouts and base
 * addresses from RM0383; never linked, never on the real build's include path. */
#ifndef CI_DECLS_STM32F4XX_H
#define CI_DECLS_STM32F4XX_H

#include <stdint.h>
#include <stddef.h>

#define __IO volatile
#define __I volatile const

typedef enum {
    NonMaskableInt_IRQn = -14, HardFault_IRQn = -13, MemoryManagement_IRQn = -12,
    BusFault_IRQn = -11, UsageFault_IRQn = -10, SVCall_IRQn = -5, DebugMonitor_IRQn = -4,
    PendSV_IRQn = -2, SysTick_IRQn = -1,
    TIM2_IRQn = 28, TIM3_IRQn = 29, I2C1_EV_IRQn = 31, I2C1_ER_IRQn = 32,
    USART1_IRQn = 37, OTG_FS_IRQn = 67,
} IRQn_Type;

typedef enum { RESET = 0U, SET = !RESET } FlagStatus, ITStatus;
typedef enum { DISABLE = 0U, ENABLE = !DISABLE } FunctionalState;

typedef struct {
    __IO uint32_t MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFR[2];
} GPIO_TypeDef;

typedef struct {
    __IO uint32_t SR, DR, BRR, CR1, CR2, CR3, GTPR;
} USART_TypeDef;

typedef struct {
    __IO uint32_t CR1, CR2, OAR1, OAR2, DR, SR1, SR2, CCR, TRISE, FLTR;
} I2C_TypeDef;

typedef struct {
    __IO uint32_t CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RCR,
                  CCR1, CCR2, CCR3, CCR4, BDTR, DCR, DMAR, OR;
} TIM_TypeDef;

/* OTG core: only its first registers; the firmware only passes its address around. */
typedef struct {
    __IO uint32_t GOTGCTL, GOTGINT, GAHBCFG, GUSBCFG, GRSTCTL, GINTSTS, GINTMSK;
} USB_OTG_GlobalTypeDef;

#define GPIOA ((GPIO_TypeDef *)0x40020000UL)
#define GPIOB ((GPIO_TypeDef *)0x40020400UL)
#define GPIOC ((GPIO_TypeDef *)0x40020800UL)
#define GPIOH ((GPIO_TypeDef *)0x40021C00UL)
#define TIM2 ((TIM_TypeDef *)0x40000000UL)
#define TIM3 ((TIM_TypeDef *)0x40000400UL)
#define I2C1 ((I2C_TypeDef *)0x40005400UL)
#define USART1 ((USART_TypeDef *)0x40011000UL)
#define USB_OTG_FS ((USB_OTG_GlobalTypeDef *)0x50000000UL)
#define UID_BASE 0x1FFF7A10UL

/* CMSIS core (cmsis_gcc.h defines these as inline "cpsid i" / "cpsie i") */
void __disable_irq(void);
void __enable_irq(void);

#endif
