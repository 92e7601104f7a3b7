/* HAL test double for the host tests of board_port.c; see fake_hal.h. */
#define _POSIX_C_SOURCE 200809L
#include "fake_hal.h"

#include <pthread.h>
#include <sched.h>
#include <string.h>

#include "main.h"
#include "usbd_cdc_if.h"

fake_hal_t fake;
UART_HandleTypeDef huart1;
I2C_HandleTypeDef hi2c1;
TIM_HandleTypeDef htim2;
static TIM_TypeDef tim2_regs;
static I2C_TypeDef i2c1_regs;
static uint8_t *rx_target;
static bool gpio_mode_on_i2c_pins;

#define SR2_BUSY 0x0002u

static unsigned port_index(const GPIO_TypeDef *port)
{
    return (unsigned)(((uintptr_t)port - (uintptr_t)GPIOA) / 0x400u) & 7u;
}

static bool sda_held_low(void)
{
    return fake.stuck_pulses < 0 || (int)fake.scl_pulses < fake.stuck_pulses;
}

void fake_reset(void)
{
    memset(&fake, 0, sizeof fake);
    memset(&huart1, 0, sizeof huart1);
    memset(&hi2c1, 0, sizeof hi2c1);
    memset(&htim2, 0, sizeof htim2);
    memset(&tim2_regs, 0, sizeof tim2_regs);
    memset(&i2c1_regs, 0, sizeof i2c1_regs);
    huart1.Instance = USART1;
    huart1.Init.BaudRate = 200000u;
    huart1.gState = HAL_UART_STATE_READY;
    huart1.RxState = HAL_UART_STATE_READY;
    hi2c1.Instance = &i2c1_regs;
    htim2.Instance = &tim2_regs;
    rx_target = NULL;
    gpio_mode_on_i2c_pins = false;
    fake.stuck_pulses = 0;
    fake.idr[0] = fake.idr[1] = fake.idr[2] = 0xFFFFu;   /* inputs pulled up */
}

void fake_set_time_us(uint32_t t)
{
    tim2_regs.CNT = t;
}

/* A free-running TIM2 for code that busy-waits on it (the I2C bus-clear pulses). */
static volatile int clock_running;
static pthread_t clock_thread;

static void *clock_ticks(void *arg)
{
    (void)arg;
    while (clock_running) {
        tim2_regs.CNT = tim2_regs.CNT + 1u;
        sched_yield();
    }
    return NULL;
}

void fake_clock_run(bool on)
{
    if (on && !clock_running) {
        clock_running = 1;
        pthread_create(&clock_thread, NULL, clock_ticks, NULL);
    } else if (!on && clock_running) {
        clock_running = 0;
        pthread_join(clock_thread, NULL);
    }
}

void fake_uart_tx_complete(void)
{
    huart1.gState = HAL_UART_STATE_READY;
    HAL_UART_TxCpltCallback(&huart1);
}

bool fake_uart_rx_byte(uint8_t b)
{
    if (huart1.RxState != HAL_UART_STATE_BUSY_RX || fake.transmitter_on) return false;
    *rx_target = b;
    huart1.RxState = HAL_UART_STATE_READY;
    HAL_UART_RxCpltCallback(&huart1);
    return true;
}

void fake_uart_overrun(void)
{
    huart1.RxState = HAL_UART_STATE_READY;
    HAL_UART_ErrorCallback(&huart1);
}

void fake_i2c_bus_stuck(int pulses)
{
    fake.stuck_pulses = pulses;
    fake.scl_pulses = 0;
    i2c1_regs.SR2 |= SR2_BUSY;
}

/* ---- UART */
HAL_StatusTypeDef HAL_HalfDuplex_EnableTransmitter(UART_HandleTypeDef *huart)
{
    (void)huart;
    fake.transmitter_on = 1;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_HalfDuplex_EnableReceiver(UART_HandleTypeDef *huart)
{
    (void)huart;
    if (fake.refuse_enable_receiver) return HAL_BUSY;
    fake.transmitter_on = 0;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Transmit_IT(UART_HandleTypeDef *huart, const uint8_t *pData, uint16_t Size)
{
    if (huart->gState != HAL_UART_STATE_READY) return HAL_BUSY;
    huart->gState = HAL_UART_STATE_BUSY_TX;
    memcpy(fake.tx, pData, Size);
    fake.tx_len = Size;
    fake.transmit_calls++;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Receive_IT(UART_HandleTypeDef *huart, uint8_t *pData, uint16_t Size)
{
    if (fake.refuse_receive_arm || huart->RxState != HAL_UART_STATE_READY || Size != 1u) return HAL_BUSY;
    huart->RxState = HAL_UART_STATE_BUSY_RX;
    rx_target = pData;
    fake.receive_arms++;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_AbortReceive(UART_HandleTypeDef *huart)
{
    huart->RxState = HAL_UART_STATE_READY;
    rx_target = NULL;
    fake.receive_aborts++;
    return HAL_OK;
}

/* On a handle already set up (UM1725): the new Init values taken, both states READY. */
HAL_StatusTypeDef HAL_HalfDuplex_Init(UART_HandleTypeDef *huart)
{
    fake.halfduplex_inits++;
    fake.baud_set = huart->Init.BaudRate;
    fake.receive_armed_at_init = huart->RxState == HAL_UART_STATE_BUSY_RX;
    huart->gState = HAL_UART_STATE_READY;
    huart->RxState = HAL_UART_STATE_READY;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_AbortTransmit(UART_HandleTypeDef *huart)
{
    huart->gState = HAL_UART_STATE_READY;
    fake.aborts++;
    return HAL_OK;
}

/* ---- GPIO */
void HAL_GPIO_Init(GPIO_TypeDef *GPIOx, const GPIO_InitTypeDef *GPIO_Init)
{
    const bool output = GPIO_Init->Mode == GPIO_MODE_OUTPUT_PP || GPIO_Init->Mode == GPIO_MODE_OUTPUT_OD;
    uint16_t *outputs = &fake.outputs[port_index(GPIOx)];
    *outputs = (uint16_t)(output ? *outputs | GPIO_Init->Pin : *outputs & ~GPIO_Init->Pin);
    if (GPIOx == IMU_SCL_GPIO_Port && (GPIO_Init->Pin & IMU_SCL_Pin)) {
        gpio_mode_on_i2c_pins = GPIO_Init->Mode == GPIO_MODE_OUTPUT_OD;
    }
}

void HAL_GPIO_WritePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin, GPIO_PinState PinState)
{
    uint16_t *odr = &fake.odr[port_index(GPIOx)];
    const bool scl_rises = GPIOx == IMU_SCL_GPIO_Port && (GPIO_Pin & IMU_SCL_Pin) && PinState == GPIO_PIN_SET
                           && !(*odr & IMU_SCL_Pin);
    if (scl_rises && gpio_mode_on_i2c_pins) fake.scl_pulses++;
    if (PinState == GPIO_PIN_SET) *odr = (uint16_t)(*odr | GPIO_Pin);
    else *odr = (uint16_t)(*odr & ~GPIO_Pin);
}

GPIO_PinState HAL_GPIO_ReadPin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    if (GPIOx == IMU_SDA_GPIO_Port && GPIO_Pin == IMU_SDA_Pin && gpio_mode_on_i2c_pins) {
        return sda_held_low() ? GPIO_PIN_RESET : GPIO_PIN_SET;
    }
    return (fake.idr[port_index(GPIOx)] & GPIO_Pin) ? GPIO_PIN_SET : GPIO_PIN_RESET;
}

/* ---- I2C */
HAL_StatusTypeDef HAL_I2C_Init(I2C_HandleTypeDef *hi2c)
{
    fake.i2c_inits++;
    gpio_mode_on_i2c_pins = false;
    if (sda_held_low()) i2c1_regs.SR2 |= SR2_BUSY;
    else i2c1_regs.SR2 &= ~SR2_BUSY;
    hi2c->State = HAL_I2C_STATE_READY;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_I2C_DeInit(I2C_HandleTypeDef *hi2c)
{
    fake.i2c_deinits++;
    hi2c->State = HAL_I2C_STATE_RESET;
    return HAL_OK;
}

static HAL_StatusTypeDef transfer(uint16_t DevAddress, uint16_t MemAddress, uint16_t MemAddSize,
                                  uint16_t Size, uint32_t Timeout)
{
    fake.dev_address = DevAddress;
    fake.mem_address = MemAddress;
    fake.mem_add_size = MemAddSize;
    fake.size = Size;
    fake.timeout = Timeout;
    fake.transfers++;
    if (i2c1_regs.SR2 & SR2_BUSY) return HAL_BUSY;
    return (HAL_StatusTypeDef)fake.i2c_status;
}

HAL_StatusTypeDef HAL_I2C_Mem_Read(I2C_HandleTypeDef *hi2c, uint16_t DevAddress, uint16_t MemAddress,
                                   uint16_t MemAddSize, uint8_t *pData, uint16_t Size, uint32_t Timeout)
{
    (void)hi2c;
    HAL_StatusTypeDef st = transfer(DevAddress, MemAddress, MemAddSize, Size, Timeout);
    if (st == HAL_OK) {
        for (uint16_t i = 0; i < Size; ++i) pData[i] = fake.regs[(MemAddress + i) & 0xFFu];
    }
    return st;
}

HAL_StatusTypeDef HAL_I2C_Mem_Write(I2C_HandleTypeDef *hi2c, uint16_t DevAddress, uint16_t MemAddress,
                                    uint16_t MemAddSize, uint8_t *pData, uint16_t Size, uint32_t Timeout)
{
    (void)hi2c;
    HAL_StatusTypeDef st = transfer(DevAddress, MemAddress, MemAddSize, Size, Timeout);
    if (st == HAL_OK) {
        for (uint16_t i = 0; i < Size; ++i) fake.regs[(MemAddress + i) & 0xFFu] = pData[i];
    }
    return st;
}

/* ---- TIM */
HAL_StatusTypeDef HAL_TIM_Base_Start(TIM_HandleTypeDef *htim)
{
    (void)htim;
    return HAL_OK;
}

/* ---- USB CDC */
uint8_t CDC_Transmit_FS(uint8_t *Buf, uint16_t Len)
{
    if (fake.cdc_answer == USBD_OK && fake.cdc_sent_len + Len <= sizeof fake.cdc_sent) {
        memcpy(fake.cdc_sent + fake.cdc_sent_len, Buf, Len);
        fake.cdc_sent_len += Len;
    }
    return (uint8_t)fake.cdc_answer;
}
