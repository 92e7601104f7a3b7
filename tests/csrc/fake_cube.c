/* HAL and USB library test double for the start-up of the CubeMX-owned files; see fake_cube.h. */
#include "fake_cube.h"

#include <setjmp.h>
#include <string.h>

#include "main.h"
#include "app.h"
#include "board_guard.h"
#include "board_port.h"
#include "usbd_core.h"
#include "usbd_cdc.h"
#include "usbd_desc.h"
#include "usbd_cdc_if.h"

int firmware_main(void);            /* main.c's main(), renamed by the build */
void SystemClock_Config(void);
void HAL_MspInit(void);

fake_cube_t cube;
USBD_ClassTypeDef USBD_CDC;
static jmp_buf boot;

int fake_cube_boot(int hse_fails, int bridge)
{
    memset(&cube, 0, sizeof cube);
    cube.hse_fails = hse_fails;
    cube.bridge_selected = bridge;
    if (setjmp(boot) == 0) {
        (void)firmware_main();
    }
    return cube.reached_main_loop;
}

void fake_cube_system_clock_config(void)
{
    memset(&cube, 0, sizeof cube);
    SystemClock_Config();
    cube.system_clock_config++;
}

void fake_cube_line_state(uint16_t w_value)
{
    USBD_SetupReqTypedef req = { .bmRequest = 0x21u, .bRequest = CDC_SET_CONTROL_LINE_STATE, .wValue = w_value };
    (void)USBD_Interface_fops_FS.Control(CDC_SET_CONTROL_LINE_STATE, (uint8_t *)&req, 0u);
}

void fake_cube_usb_strings(void)
{
    uint8_t *(*const get[4])(USBD_SpeedTypeDef, uint16_t *) = {
        FS_Desc.GetManufacturerStrDescriptor, FS_Desc.GetProductStrDescriptor,
        FS_Desc.GetConfigurationStrDescriptor, FS_Desc.GetInterfaceStrDescriptor,
    };
    for (unsigned i = 0; i < 4u; i++) {
        uint16_t len = 0;
        cube.string[i][0] = '\0';
        (void)get[i](USBD_SPEED_FULL, &len);
    }
}

/* ---- the application and the board port: main() only starts them */
void app_init(app_t *app, const port_t *port) { (void)app; (void)port; }
void app_poll(app_t *app) { (void)app; cube.reached_main_loop = 1; longjmp(boot, 1); }
void app_request_tick(app_t *app) { (void)app; }
void app_watch(app_t *app) { (void)app; }
const port_t *board_port_start(void) { return NULL; }
void board_port_poll(void) { }
void board_servo_power_off(void) { }
void board_link_connected(void) { }
void board_link_received(const uint8_t *bytes, uint32_t n) { (void)bytes; (void)n; }
void board_link_transmitted(void) { }
void board_link_line_state(bool dtr) { cube.line_states++; cube.dtr = dtr; }
void board_link_line_coding(uint32_t baud) { cube.line_coding_baud = baud; }
bool board_servo_bridge_selected(void) { return cube.bridge_selected; }
void board_servo_bridge_start(void) { cube.bridge_started++; }
/* main() polls the bridge for ever: the first poll, after the watchdog's feed, ends the run here. */
void board_servo_bridge_poll(void) { cube.bridge_polled = cube.watchdog_fed; longjmp(boot, 3); }
board_reset_t board_guard_start(void) { cube.guard_started++; return (board_reset_t){ 0u, 0u }; }
void board_watchdog_feed(void) { cube.watchdog_fed++; }
void board_fault(void) { }
bool app_healthy(const app_t *app) { (void)app; return true; }

/* Error_Handler() stops in board_stop() (tests/test_board_guard.py checks what it does): leave it here. */
void board_stop(void)
{
    cube.error_handler = 1;
    longjmp(boot, 2);
}

/* ---- HAL start-up: the MSP set-up and the SysTick priority (UM1725, HAL_Init) */
HAL_StatusTypeDef HAL_Init(void)
{
    HAL_MspInit();
    cube.systick_priority = TICK_INT_PRIORITY;
    return HAL_OK;
}

/* ---- RCC */
HAL_StatusTypeDef HAL_RCC_OscConfig(RCC_OscInitTypeDef *o)
{
    cube.osc_configs++;
    if (cube.hse_fails) return HAL_TIMEOUT;      /* HSERDY never set within HSE_STARTUP_TIMEOUT */
    cube.hse_state = o->HSEState;
    cube.pll_state = o->PLL.PLLState;
    cube.pll_source = o->PLL.PLLSource;
    cube.pll_m = o->PLL.PLLM;
    cube.pll_n = o->PLL.PLLN;
    cube.pll_p = o->PLL.PLLP;
    cube.pll_q = o->PLL.PLLQ;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_RCC_ClockConfig(RCC_ClkInitTypeDef *c, uint32_t FLatency)
{
    cube.clock_configs++;
    cube.sysclk_source = c->SYSCLKSource;
    cube.ahb_divider = c->AHBCLKDivider;
    cube.apb1_divider = c->APB1CLKDivider;
    cube.apb2_divider = c->APB2CLKDivider;
    cube.flash_latency = FLatency;
    return HAL_OK;
}

void HAL_RCC_EnableCSS(void)
{
    cube.css_enabled++;
}

/* ---- peripherals */
HAL_StatusTypeDef HAL_HalfDuplex_Init(UART_HandleTypeDef *huart)
{
    cube.halfduplex_inits++;
    cube.baud = huart->Init.BaudRate;
    HAL_UART_MspInit(huart);
    return HAL_OK;
}

HAL_StatusTypeDef HAL_UART_Init(UART_HandleTypeDef *huart)
{
    (void)huart;
    cube.uart_inits++;
    return HAL_OK;
}

HAL_StatusTypeDef HAL_I2C_Init(I2C_HandleTypeDef *hi2c)
{
    cube.i2c_inits++;
    cube.i2c_clock_speed = hi2c->Init.ClockSpeed;
    HAL_I2C_MspInit(hi2c);
    return HAL_OK;
}

HAL_StatusTypeDef HAL_TIM_Base_Init(TIM_HandleTypeDef *htim)
{
    if (htim->Instance == TIM2) {
        cube.tim2_prescaler = htim->Init.Prescaler;
        cube.tim2_period = htim->Init.Period;
    } else if (htim->Instance == TIM3) {
        cube.tim3_prescaler = htim->Init.Prescaler;
        cube.tim3_period = htim->Init.Period;
    }
    HAL_TIM_Base_MspInit(htim);
    return HAL_OK;
}

HAL_StatusTypeDef HAL_TIM_Base_Start_IT(TIM_HandleTypeDef *htim)
{
    if (htim->Instance == TIM3) cube.tim3_started_it++;
    return HAL_OK;
}

void HAL_NVIC_SetPriority(IRQn_Type IRQn, uint32_t PreemptPriority, uint32_t SubPriority)
{
    (void)SubPriority;
    if ((unsigned)IRQn < 96u) cube.nvic_priority[IRQn] = PreemptPriority;
}

void HAL_NVIC_EnableIRQ(IRQn_Type IRQn)
{
    if ((unsigned)IRQn < 96u) cube.nvic_enabled[IRQn] = 1;
}

HAL_StatusTypeDef HAL_PCD_Init(PCD_HandleTypeDef *hpcd)
{
    HAL_PCD_MspInit(hpcd);
    return HAL_OK;
}

/* ---- USB device library: the stack starts through usbd_conf.c's low-level calls */
USBD_StatusTypeDef USBD_Init(USBD_HandleTypeDef *pdev, USBD_DescriptorsTypeDef *pdesc, uint8_t id)
{
    pdev->pDesc = pdesc;
    pdev->id = id;
    return USBD_LL_Init(pdev);
}

USBD_StatusTypeDef USBD_Start(USBD_HandleTypeDef *pdev)
{
    cube.usbd_started++;
    return USBD_LL_Start(pdev);
}

void USBD_GetString(uint8_t *desc, uint8_t *unicode, uint16_t *len)
{
    (void)unicode;
    for (unsigned i = 0; i < 4u; i++) {
        if (cube.string[i][0] == '\0') {
            strncpy(cube.string[i], (const char *)desc, sizeof cube.string[i] - 1u);
            break;
        }
    }
    *len = (uint16_t)strlen((const char *)desc);
}
