"""A start-up file for the STM32F411xE built the way ST builds theirs (CMSIS device F4,
`startup_stm32f411xe.s`, the file CubeIDE and the command-line build take from STM32CubeF4),
written here from RM0383's vector table (table 37) so that the tests link what the real build
links. The constructs that matter are ST's:

- `Default_Handler` is a plain label: no `.thumb_func`, no `%function` type, so its symbol's
  value, and C's `&Default_Handler`, is even;
- every handler name is `.weak` and `.thumb_set` to `Default_Handler`, so a table entry of a
  handler the firmware does not define holds `Default_Handler | 1` (the Thumb bit);
- the reserved positions hold 0.

The Reset_Handler body is shortened (stack, SystemInit, main): nothing here runs it.
"""

SYSTEM = ["Reset_Handler", "NMI_Handler", "HardFault_Handler", "MemManage_Handler", "BusFault_Handler",
          "UsageFault_Handler", None, None, None, None, "SVC_Handler", "DebugMon_Handler", None,
          "PendSV_Handler", "SysTick_Handler"]          # exceptions 1..15 (ARMv7-M B1.5.2)

# RM0383 table 37: IRQ position -> handler name (without "_IRQHandler"); the others are reserved
IRQS = {
    0: "WWDG", 1: "PVD", 2: "TAMP_STAMP", 3: "RTC_WKUP", 4: "FLASH", 5: "RCC",
    **{6 + k: f"EXTI{k}" for k in range(5)},
    **{11 + k: f"DMA1_Stream{k}" for k in range(7)},
    18: "ADC", 23: "EXTI9_5", 24: "TIM1_BRK_TIM9", 25: "TIM1_UP_TIM10", 26: "TIM1_TRG_COM_TIM11",
    27: "TIM1_CC", 28: "TIM2", 29: "TIM3", 30: "TIM4", 31: "I2C1_EV", 32: "I2C1_ER", 33: "I2C2_EV",
    34: "I2C2_ER", 35: "SPI1", 36: "SPI2", 37: "USART1", 38: "USART2", 40: "EXTI15_10",
    41: "RTC_Alarm", 42: "OTG_FS_WKUP", 47: "DMA1_Stream7", 49: "SDIO", 50: "TIM5", 51: "SPI3",
    **{56 + k: f"DMA2_Stream{k}" for k in range(5)},
    67: "OTG_FS", 68: "DMA2_Stream5", 69: "DMA2_Stream6", 70: "DMA2_Stream7", 71: "USART6",
    72: "I2C3_EV", 73: "I2C3_ER", 81: "FPU", 84: "SPI4", 85: "SPI5",
}
IRQ_POSITIONS = 86
VECTORS = 16 + IRQ_POSITIONS                               # 102 words, the stack top first


def handler_names() -> list[str | None]:
    """The table's entries 1..101: a handler name, or None where the table holds 0."""
    return SYSTEM + [f"{IRQS[n]}_IRQHandler" if n in IRQS else None for n in range(IRQ_POSITIONS)]


def text(thumb_func_default_handler: bool = False) -> str:
    """The file; thumb_func_default_handler marks Default_Handler `.thumb_func` (as some
    hand-written start-up files do), so that its address carries the Thumb bit too."""
    names = handler_names()
    words = "\n".join(f"  .word {name or 0}" for name in names)
    aliases = "\n".join(f"  .weak {name}\n  .thumb_set {name},Default_Handler"
                        for name in names if name and name != "Reset_Handler")
    return f"""\
  .syntax unified
  .cpu cortex-m4
  .fpu softvfp
  .thumb

.global g_pfnVectors
.global Default_Handler

  .section .text.Reset_Handler
  .weak Reset_Handler
  .type Reset_Handler, %function
Reset_Handler:
  ldr sp, =_estack
  bl SystemInit
  bl main
  bx lr
.size Reset_Handler, .-Reset_Handler

  .section .text.Default_Handler,"ax",%progbits
{"  .thumb_func" if thumb_func_default_handler else ""}
Default_Handler:
Infinite_Loop:
  b Infinite_Loop
  .size Default_Handler, .-Default_Handler

  .section .isr_vector,"a",%progbits
  .type g_pfnVectors, %object
g_pfnVectors:
  .word _estack
{words}
  .size g_pfnVectors, .-g_pfnVectors

{aliases}
"""
