/* The port interface on the STM32F411 with the STM32CubeF4 HAL; see board_port.h. */
#include "board_port.h"

#include <string.h>

#include "byte_ring.h"
#include "cdc_link.h"
#include "main.h"
#include "servo_bridge.h"
#include "usbd_cdc_if.h"

/* The HAL's idea of the crystal must be the board's. */
typedef char board_hse_value_matches_hal[(HSE_VALUE == BOARD_HSE_HZ) ? 1 : -1];

#define SERVO_TX_MAX 128u          /* longest Dynamixel packet the application builds is ~40 bytes */
#define SERVO_RX_SIZE 256u         /* several status packets; the application drains it each pass */

typedef struct {
    /* servo bus */
    uint8_t tx[SERVO_TX_MAX];
    volatile bool tx_busy;         /* set by servo_send, cleared by the TC interrupt or the timeout */
    volatile bool release_pending; /* the TC interrupt found the handle locked: retry from the main loop */
    uint32_t tx_start_us;
    uint32_t tx_limit_us;
    uint32_t tx_timeouts;
    byte_ring_t rx;
    uint8_t rx_storage[SERVO_RX_SIZE];
    uint8_t rx_byte;               /* HAL_UART_Receive_IT target, one byte at a time */
    uint32_t rx_errors;
    /* IMU */
    uint32_t i2c_errors;
    uint32_t i2c_recoveries;
    /* link */
    cdc_link_t link;
} board_t;

static board_t board;
static port_t port;
static servo_bridge_t bridge;
static volatile uint32_t host_baud;   /* the host's line coding, from the USB interrupt; 0 none yet */

/* ------------------------------------------------------------------ time */

static uint32_t time_us(void *ctx)
{
    (void)ctx;
    return __HAL_TIM_GET_COUNTER(&htim2);
}

/* ------------------------------------------------------------------ servo bus */

static void servo_rx_arm(void)
{
    /* HAL_BUSY just means reception is already armed. */
    (void)HAL_UART_Receive_IT(&huart1, &board.rx_byte, 1u);
}

static void servo_release_line(void)
{
    board.release_pending = HAL_HalfDuplex_EnableReceiver(&huart1) != HAL_OK;
    board.tx_busy = false;
}

static bool servo_busy(void *ctx)
{
    if (board.release_pending) servo_release_line();
    if (board.tx_busy && time_us(ctx) - board.tx_start_us > board.tx_limit_us) {
        (void)HAL_UART_AbortTransmit(&huart1);
        servo_release_line();
        board.tx_timeouts++;
    }
    return board.tx_busy;
}

static bool servo_send(void *ctx, const uint8_t *buf, size_t n)
{
    if (servo_busy(ctx) || n == 0u || n > SERVO_TX_MAX) return false;
    memcpy(board.tx, buf, n);
    /* 10 bits a byte (start, 8 data, stop) at the model's baud, doubled, plus a margin */
    const uint32_t wire_us = (uint32_t)((10u * 1000000ull * n + huart1.Init.BaudRate - 1u) / huart1.Init.BaudRate);
    board.tx_limit_us = 2u * wire_us + BOARD_SERVO_TX_MARGIN_US;
    board.tx_start_us = time_us(ctx);
    board.tx_busy = true;
    if (HAL_HalfDuplex_EnableTransmitter(&huart1) != HAL_OK
        || HAL_UART_Transmit_IT(&huart1, board.tx, (uint16_t)n) != HAL_OK) {
        servo_release_line();
        return false;
    }
    return true;
}

static size_t servo_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    if (huart1.RxState == HAL_UART_STATE_READY) servo_rx_arm();   /* re-arm after an error */
    return byte_ring_take(&board.rx, buf, cap);
}

static void servo_power(void *ctx, bool on)
{
    (void)ctx;
    const bool level = BOARD_SERVO_POWER_ACTIVE_HIGH ? on : !on;
    HAL_GPIO_WritePin(SERVO_PWR_GPIO_Port, SERVO_PWR_Pin, level ? GPIO_PIN_SET : GPIO_PIN_RESET);
}

void board_servo_power_off(void)
{
    servo_power(NULL, false);
}

/* TC: the last stop bit is on the wire, so the servo may answer from now on. */
void HAL_UART_TxCpltCallback(UART_HandleTypeDef *huart)
{
    if (huart->Instance == USART1) servo_release_line();
}

void HAL_UART_RxCpltCallback(UART_HandleTypeDef *huart)
{
    if (huart->Instance != USART1) return;
    byte_ring_put(&board.rx, &board.rx_byte, 1u);
    servo_rx_arm();
}

/* Overrun, framing or noise error: count it; the servo-bus parser rejects the damaged
 * packet by its checksum. Reception is re-armed here or, failing that, at the next read. */
void HAL_UART_ErrorCallback(UART_HandleTypeDef *huart)
{
    if (huart->Instance != USART1) return;
    board.rx_errors++;
    if (huart->RxState == HAL_UART_STATE_READY) servo_rx_arm();
}

/* ------------------------------------------------------------------ link */

static size_t link_read(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    return cdc_link_read(&board.link, buf, cap);
}

static bool link_write(void *ctx, const uint8_t *buf, size_t n)
{
    (void)ctx;
    return cdc_link_write(&board.link, buf, n);
}

static cdc_link_result_t cdc_transmit(void *ctx, uint8_t *buf, uint16_t len)
{
    (void)ctx;
    switch (CDC_Transmit_FS(buf, len)) {
    case USBD_OK: return CDC_LINK_SENT;
    case USBD_BUSY: return CDC_LINK_BUSY;
    default: return CDC_LINK_FAIL;
    }
}

void board_link_connected(void)
{
    cdc_link_on_connect(&board.link);
}

void board_link_received(const uint8_t *bytes, uint32_t n)
{
    cdc_link_on_receive(&board.link, bytes, n);
}

void board_link_transmitted(void)
{
    cdc_link_on_transmit_done(&board.link);
}

void board_link_line_state(bool dtr)
{
    cdc_link_on_line_state(&board.link, dtr);
}

void board_link_line_coding(uint32_t baud)
{
    host_baud = baud;
}

/* ------------------------------------------------------------------ LEDs */

static void led(void *ctx, uint8_t index, bool on)
{
    (void)ctx;
    const GPIO_PinState level = (BOARD_LED_ACTIVE_HIGH ? on : !on) ? GPIO_PIN_SET : GPIO_PIN_RESET;
    if (index == 0u) HAL_GPIO_WritePin(LED0_GPIO_Port, LED0_Pin, level);
    else if (index == 1u) HAL_GPIO_WritePin(LED1_GPIO_Port, LED1_Pin, level);
}

void board_stop_outputs(void)
{
    GPIO_InitTypeDef pin = {0};
    board_servo_power_off();             /* the levels first, then the pins outputs, as MX_GPIO_Init */
    led(NULL, 0u, true);
    led(NULL, 1u, true);
    __HAL_RCC_GPIOA_CLK_ENABLE();        /* PA8, PA5, PA6 (main.h) */
    pin.Mode = GPIO_MODE_OUTPUT_PP;
    pin.Speed = GPIO_SPEED_FREQ_LOW;
    pin.Pin = SERVO_PWR_Pin;
    pin.Pull = GPIO_PULLDOWN;
    HAL_GPIO_Init(SERVO_PWR_GPIO_Port, &pin);
    pin.Pin = LED0_Pin | LED1_Pin;
    pin.Pull = GPIO_NOPULL;
    HAL_GPIO_Init(LED0_GPIO_Port, &pin);
}

/* ------------------------------------------------------------------ IMU */

/* A slave left mid-byte (e.g. the MCU reset during a read) holds SDA low and the I2C
 * block sees the bus busy forever (and the HAL would first wait 25 ms for it to clear).
 * Recovery as in the I2C specification (UM10204 3.1.16): up to nine SCL pulses until SDA
 * is released, a STOP, then the I2C block is re-initialised (HAL_I2C_Init resets it).
 * About 100 us, from the main loop only. */
static void wait_us(uint32_t us)
{
    const uint32_t start = time_us(NULL);
    while (time_us(NULL) - start < us) {
    }
}

static void i2c_bus_recover(void)
{
    GPIO_InitTypeDef pins = {0};
    board.i2c_recoveries++;
    (void)HAL_I2C_DeInit(&hi2c1);
    HAL_GPIO_WritePin(IMU_SCL_GPIO_Port, IMU_SCL_Pin | IMU_SDA_Pin, GPIO_PIN_SET);
    pins.Pin = IMU_SCL_Pin | IMU_SDA_Pin;
    pins.Mode = GPIO_MODE_OUTPUT_OD;
    pins.Pull = GPIO_NOPULL;
    pins.Speed = GPIO_SPEED_FREQ_LOW;
    HAL_GPIO_Init(IMU_SCL_GPIO_Port, &pins);
    for (int i = 0; i < 9 && HAL_GPIO_ReadPin(IMU_SDA_GPIO_Port, IMU_SDA_Pin) == GPIO_PIN_RESET; ++i) {
        HAL_GPIO_WritePin(IMU_SCL_GPIO_Port, IMU_SCL_Pin, GPIO_PIN_RESET);
        wait_us(5u);
        HAL_GPIO_WritePin(IMU_SCL_GPIO_Port, IMU_SCL_Pin, GPIO_PIN_SET);
        wait_us(5u);
    }
    HAL_GPIO_WritePin(IMU_SDA_GPIO_Port, IMU_SDA_Pin, GPIO_PIN_RESET);   /* STOP: SDA rises while SCL is high */
    wait_us(5u);
    HAL_GPIO_WritePin(IMU_SDA_GPIO_Port, IMU_SDA_Pin, GPIO_PIN_SET);
    wait_us(5u);
    (void)HAL_I2C_Init(&hi2c1);                                          /* MspInit: pins back to I2C1 */
}

/* Before a transfer: false (at once) if the bus is stuck, after trying to free it. */
static bool i2c_bus_free(void)
{
    if (__HAL_I2C_GET_FLAG(&hi2c1, I2C_FLAG_BUSY) == RESET) return true;
    i2c_bus_recover();
    return __HAL_I2C_GET_FLAG(&hi2c1, I2C_FLAG_BUSY) == RESET;
}

/* A NACK (HAL_ERROR: no IMU at that address) is just a failure; a timeout or busy bus
 * is also a reason to reset the bus. */
static bool i2c_result(HAL_StatusTypeDef status)
{
    if (status == HAL_OK) return true;
    board.i2c_errors++;
    if (status != HAL_ERROR) i2c_bus_recover();
    return false;
}

static bool imu_read(void *ctx, uint8_t addr, uint8_t reg, uint8_t *buf, size_t n)
{
    (void)ctx;
    if (n == 0u || n > 0xFFFFu || !i2c_bus_free()) return false;
    return i2c_result(HAL_I2C_Mem_Read(&hi2c1, (uint16_t)(addr << 1), reg, I2C_MEMADD_SIZE_8BIT,
                                       buf, (uint16_t)n, BOARD_I2C_TIMEOUT_MS));
}

static bool imu_write(void *ctx, uint8_t addr, uint8_t reg, uint8_t value)
{
    (void)ctx;
    if (!i2c_bus_free()) return false;
    return i2c_result(HAL_I2C_Mem_Write(&hi2c1, (uint16_t)(addr << 1), reg, I2C_MEMADD_SIZE_8BIT,
                                        &value, 1u, BOARD_I2C_TIMEOUT_MS));
}

/* ------------------------------------------------------------------ start */

uint8_t board_config_inputs(void)
{
    /* pulled up; a closed solder bridge pulls the pin to ground */
    uint8_t bits = 0u;
    if (HAL_GPIO_ReadPin(CFG0_GPIO_Port, CFG0_Pin) == GPIO_PIN_RESET) bits |= 1u;
    if (HAL_GPIO_ReadPin(CFG1_GPIO_Port, CFG1_Pin) == GPIO_PIN_RESET) bits |= 2u;
    if (HAL_GPIO_ReadPin(CFG2_GPIO_Port, CFG2_Pin) == GPIO_PIN_RESET) bits |= 4u;
    return bits;
}

const port_t *board_port_start(void)
{
    memset(&board, 0, sizeof board);
    byte_ring_init(&board.rx, board.rx_storage, SERVO_RX_SIZE);
    cdc_link_init(&board.link, cdc_transmit, NULL);
    port = (port_t){
        .ctx = &board, .time_us = time_us, .link_read = link_read, .link_write = link_write,
        .servo_send = servo_send, .servo_busy = servo_busy, .servo_read = servo_read,
        .servo_power = servo_power, .led = led, .imu_read = imu_read, .imu_write = imu_write,
    };
    board_servo_power_off();
    (void)HAL_TIM_Base_Start(&htim2);
    servo_release_line();
    servo_rx_arm();
    return &port;
}

void board_port_poll(void)
{
    cdc_link_pump(&board.link);
}

/* ------------------------------------------------------------------ servo set-up bridge */

bool board_servo_bridge_selected(void)
{
    return (board_config_inputs() & 1u) != 0u;          /* CFG0 closed */
}

void board_servo_bridge_start(void)
{
    servo_bridge_init(&bridge);
    led(NULL, 0u, true);
}

/* The bus at the host's bit rate: reception stopped, USART1 set up again, reception re-armed. */
static void bridge_set_baud(uint32_t baud)
{
    (void)HAL_UART_AbortReceive(&huart1);
    huart1.Init.BaudRate = baud;
    (void)HAL_HalfDuplex_Init(&huart1);
    servo_release_line();
    servo_rx_arm();
}

void board_servo_bridge_poll(void)
{
    uint8_t buf[64];
    const uint32_t baud = host_baud;
    if (baud != 0u && baud != huart1.Init.BaudRate && !servo_busy(NULL)) bridge_set_baud(baud);
    servo_power(NULL, board.link.dtr);
    size_t n = cdc_link_read(&board.link, buf, sizeof buf);
    for (size_t i = 0u; i < n; ++i) {
        const size_t len = servo_bridge_feed(&bridge, buf[i]);
        if (len == 0u) continue;
        while (servo_busy(NULL)) {
        }                                               /* ends: a stuck send is aborted */
        (void)servo_send(NULL, bridge.packet, len);
    }
    n = servo_read(NULL, buf, sizeof buf);
    if (n > 0u) (void)cdc_link_write(&board.link, buf, n);
    cdc_link_pump(&board.link);
}
