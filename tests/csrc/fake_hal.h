/* Test double of the few STM32CubeF4 HAL functions Board/Src/board_port.c calls, for the
 * host tests of the port's logic (tests/test_board_port.py). Compiled with the CI
 * declarations (firmware_stm32/ci/hal_decls), so the calls match the HAL's prototypes.
 * Behaviour modelled on the HAL documentation (UM1725): Transmit_IT returns at once and
 * the TC interrupt later calls HAL_UART_TxCpltCallback; Receive_IT(1 byte) arms one
 * reception whose completion calls HAL_UART_RxCpltCallback with RxState back to READY;
 * I2C Mem_Read/Mem_Write take the 7-bit address shifted left by one. */
#ifndef FAKE_HAL_H
#define FAKE_HAL_H

#include <stdbool.h>
#include <stdint.h>

/* cffi:begin */
typedef struct {
    /* servo bus (USART1) */
    uint8_t tx[256];
    uint16_t tx_len;
    uint32_t transmit_calls;
    int transmitter_on;              /* 1 after EnableTransmitter, 0 after EnableReceiver */
    uint32_t receive_arms;
    int refuse_receive_arm;          /* Receive_IT answers HAL_BUSY (e.g. handle locked) */
    int refuse_enable_receiver;      /* EnableReceiver answers HAL_BUSY (handle locked) */
    uint32_t aborts;
    uint32_t receive_aborts;
    uint32_t halfduplex_inits;
    uint32_t baud_set;               /* the BaudRate the last HAL_HalfDuplex_Init took */
    int receive_armed_at_init;       /* a reception was still armed when it was called */
    /* GPIO: output and input levels, pins HAL_GPIO_Init made outputs; [port index A=0..H=7] bit = pin */
    uint16_t odr[8];
    uint16_t idr[8];
    uint16_t outputs[8];
    uint32_t scl_pulses;             /* SCL (PB8) low-to-high edges while a GPIO output */
    /* I2C1 */
    uint16_t dev_address;
    uint16_t mem_address;
    uint16_t mem_add_size;
    uint16_t size;
    uint32_t timeout;
    uint32_t transfers;
    int i2c_status;                  /* what Mem_Read/Mem_Write return (HAL_StatusTypeDef) */
    uint8_t regs[256];               /* the addressed device's registers */
    int stuck_pulses;                /* SCL pulses before a stuck slave lets SDA go; -1 never */
    uint32_t i2c_inits;
    uint32_t i2c_deinits;
    /* USB CDC */
    int cdc_answer;                  /* what CDC_Transmit_FS returns (USBD_StatusTypeDef) */
    uint8_t cdc_sent[4096];
    uint32_t cdc_sent_len;
} fake_hal_t;

extern fake_hal_t fake;

void fake_reset(void);
void fake_set_time_us(uint32_t t);
/* TIM2 counting by itself (in a thread) instead of only when set. */
void fake_clock_run(bool on);
void fake_uart_tx_complete(void);     /* the TC interrupt */
bool fake_uart_rx_byte(uint8_t b);    /* RXNE interrupt; false if no reception was armed */
void fake_uart_overrun(void);         /* ORE: the HAL ends the reception, then ErrorCallback */
/* A slave holds SDA low (I2C BUSY set) until it has seen `pulses` SCL pulses; -1: for ever. */
void fake_i2c_bus_stuck(int pulses);
/* cffi:end */

#endif
