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

/* CMSIS core (cmsis_gcc.h defines these as inline "cpsid i" / "cpsie i" / "dsb") */
void __disable_irq(void);
void __enable_irq(void);
void __DSB(void);

/* The reset and clock controller, the independent watchdog, the Cortex-M4 system control
 * block (only its first registers) and the debug MCU block, for the board's supervision
 * (Board/Src/board_guard.c). On the chip they sit at RCC_BASE, IWDG_BASE, SCB_BASE and
 * DBGMCU_BASE; here they are objects, which the host test double defines. */
typedef struct {
    __IO uint32_t CR, PLLCFGR, CFGR, CIR, AHB1RSTR, AHB2RSTR, RESERVED0[2], APB1RSTR, APB2RSTR,
                  RESERVED1[2], AHB1ENR, AHB2ENR, RESERVED2[2], APB1ENR, APB2ENR, RESERVED3[2],
                  AHB1LPENR, AHB2LPENR, RESERVED4[2], APB1LPENR, APB2LPENR, RESERVED5[2], BDCR, CSR,
                  RESERVED6[2], SSCGR, PLLI2SCFGR, RESERVED7, DCKCFGR;
} RCC_TypeDef;

typedef struct {
    __IO uint32_t KR, PR, RLR, SR;
} IWDG_TypeDef;

typedef struct {
    __I uint32_t CPUID;
    __IO uint32_t ICSR, VTOR, AIRCR, SCR, CCR;
} SCB_Type;

typedef struct {
    __IO uint32_t IDCODE, CR, APB1FZ, APB2FZ;
} DBGMCU_TypeDef;

extern RCC_TypeDef ci_rcc;
extern IWDG_TypeDef ci_iwdg;
extern SCB_Type ci_scb;
extern DBGMCU_TypeDef ci_dbgmcu;
#define RCC (&ci_rcc)
#define IWDG (&ci_iwdg)
#define SCB (&ci_scb)
#define DBGMCU (&ci_dbgmcu)

/* IWDG_SR: a prescaler / reload value update still on its way to the LSI domain (RM0383 17.4.4);
 * DBGMCU_APB1_FZ: the watchdog's counter stopped while the core is halted (RM0383, DBG_IWDG_STOP) */
#define IWDG_SR_PVU (1UL << 0)
#define IWDG_SR_RVU (1UL << 1)
#define DBGMCU_APB1_FZ_DBG_IWDG_STOP (1UL << 12)

/* RCC_CSR reset flags (RM0383 6.3.21) and SCB_ICSR's active exception (ARMv7-M B3.2.4) */
#define RCC_CSR_RMVF (1UL << 24)
#define RCC_CSR_BORRSTF (1UL << 25)
#define RCC_CSR_PINRSTF (1UL << 26)
#define RCC_CSR_PORRSTF (1UL << 27)
#define RCC_CSR_SFTRSTF (1UL << 28)
#define RCC_CSR_IWDGRSTF (1UL << 29)
#define RCC_CSR_WWDGRSTF (1UL << 30)
#define RCC_CSR_LPWRRSTF (1UL << 31)
#define SCB_ICSR_VECTACTIVE_Msk 0x1FFUL

#endif
