"""CubeMX's "Generate Code" simulated on the board project (firmware_stm32/): every file
CubeMX owns (Core/, USB_DEVICE/) keeps only its USER CODE sections and what
manipulator.ioc determines, and the model's servo baud and tick, the board's clock, the
microsecond timer, the USB strings and the CDC buffer sizes must still reach the
peripherals: main() runs on the host up to its main loop over a HAL test double
(tests/csrc/fake_cube.c) that records what each HAL init function receives.

The stand-in for CubeMX writes what CubeMX writes from a .ioc key, as CubeMX-written
projects show it (docs/board.md names those compared): a parameter's value verbatim
(TIM3.Period=100 - 1 gives `htim3.Init.Period = 100 - 1;`, a user constant's name gives
that name), the user constants as `#define NAME VALUE` first in main.h's private defines,
the USB_DEVICE parameters as the #defines of usbd_desc.c, usbd_cdc_if.h and usbd_conf.h
(CubeMX's own defaults where the .ioc says nothing: "STMicroelectronics", 2048 bytes),
the NVIC priorities into the MSP set-up, RCC.HSE_VALUE into stm32f4xx_hal_conf.h.
Everything else outside USER CODE is CubeMX's template text, which must name nothing of
the project's own (checked below), so a regeneration cannot drop a link to it.

Oracles: RM0383 (PLL, bus and timer clocks), the HAL's conventions (UM1725: HAL_PPP_Init
calls HAL_PPP_MspInit), the model file, the USB 2.0 full-speed bulk packet size (64).
"""
import re
import shutil
import subprocess
from fractions import Fraction
from pathlib import Path

import pytest

from conftest import ROOT, once_per_run, require_arm_toolchain
from hal_stubs import weak_stubs
from test_stm32_project import cproject_symbols, ioc as ioc_of
from uavarm.build import cbuild, firmware
from uavarm.codegen import generate
from uavarm.model import config

FW = firmware.FIRMWARE
CSRC = ROOT / "tests" / "csrc"
MHZ = 1_000_000
USER_CODE = re.compile(r"(/\* USER CODE BEGIN ([^*]+?) \*/.*?/\* USER CODE END \2 \*/)", re.S)


def cubemx_owned(fw: Path = FW) -> list[Path]:
    return sorted(p for d in ("Core", "USB_DEVICE") for p in (fw / d).rglob("*.[ch]"))


def outside_user_code(text: str) -> str:
    return USER_CODE.sub("", text)


# ------------------------------------------------------------------ the stand-in for CubeMX

def nvic_priority(k, irq):
    return k[f"NVIC.{irq}"].split(":")[1]


def hse_state(k):
    mode = k["PH0 - OSC_IN.Mode"]
    return {"HSE-External-Oscillator": "RCC_HSE_ON", "HSE-External-Clock-Source": "RCC_HSE_BYPASS"}[mode]


def usb(name, default):
    return lambda k: k.get(f"USB_DEVICE.{name}", default)


# (file, a line CubeMX writes with the value as group 1, the value from the .ioc)
RULES = [
    ("Core/Src/main.c", r"huart1\.Init\.BaudRate = (.+);", lambda k: k["USART1.BaudRate"]),
    ("Core/Src/main.c", r"htim2\.Init\.Prescaler = (.+);", lambda k: k["TIM2.Prescaler"]),
    ("Core/Src/main.c", r"htim2\.Init\.Period = (.+);", lambda k: k.get("TIM2.Period", "4294967295")),
    ("Core/Src/main.c", r"htim3\.Init\.Prescaler = (.+);", lambda k: k["TIM3.Prescaler"]),
    ("Core/Src/main.c", r"htim3\.Init\.Period = (.+);", lambda k: k.get("TIM3.Period", "65535")),
    ("Core/Src/main.c", r"hi2c1\.Init\.ClockSpeed = (.+);",
     lambda k: {"I2C_Fast": "400000", "I2C_Standard": "100000"}[k.get("I2C1.I2C_Mode", "I2C_Standard")]),
    ("Core/Src/main.c", r"RCC_OscInitStruct\.HSEState = (.+);", hse_state),
    ("Core/Src/main.c", r"RCC_OscInitStruct\.PLL\.PLLM = (.+);", lambda k: k["RCC.PLLM"]),
    ("Core/Src/main.c", r"RCC_OscInitStruct\.PLL\.PLLN = (.+);", lambda k: k["RCC.PLLN"]),
    ("Core/Src/main.c", r"RCC_OscInitStruct\.PLL\.PLLP = (.+);", lambda k: k["RCC.PLLP"]),
    ("Core/Src/main.c", r"RCC_OscInitStruct\.PLL\.PLLQ = (.+);", lambda k: k["RCC.PLLQ"]),
    ("Core/Src/main.c", r"RCC_ClkInitStruct\.APB1CLKDivider = (.+);", lambda k: k["RCC.APB1CLKDivider"]),
    ("Core/Inc/stm32f4xx_hal_conf.h", r"#define HSE_VALUE +(\d+)U", lambda k: k["RCC.HSE_VALUE"]),
    ("Core/Inc/stm32f4xx_hal_conf.h", r"#define +TICK_INT_PRIORITY +(\d+)U", lambda k: nvic_priority(k, "SysTick_IRQn")),
    ("Core/Src/stm32f4xx_hal_msp.c", r"HAL_NVIC_SetPriority\(TIM3_IRQn, (\d+), 0\);", lambda k: nvic_priority(k, "TIM3_IRQn")),
    ("Core/Src/stm32f4xx_hal_msp.c", r"HAL_NVIC_SetPriority\(USART1_IRQn, (\d+), 0\);", lambda k: nvic_priority(k, "USART1_IRQn")),
    ("USB_DEVICE/Target/usbd_conf.c", r"HAL_NVIC_SetPriority\(OTG_FS_IRQn, (\d+), 0\);", lambda k: nvic_priority(k, "OTG_FS_IRQn")),
    ("USB_DEVICE/App/usbd_desc.c", r'#define USBD_MANUFACTURER_STRING +"(.*)"', usb("MANUFACTURER_STRING", "STMicroelectronics")),
    ("USB_DEVICE/App/usbd_desc.c", r'#define USBD_PRODUCT_STRING_FS +"(.*)"', usb("PRODUCT_STRING_CDC_FS", "STM32 Virtual ComPort")),
    ("USB_DEVICE/App/usbd_desc.c", r'#define USBD_CONFIGURATION_STRING_FS +"(.*)"', usb("CONFIGURATION_STRING_CDC_FS", "CDC Config")),
    ("USB_DEVICE/App/usbd_desc.c", r'#define USBD_INTERFACE_STRING_FS +"(.*)"', usb("INTERFACE_STRING_CDC_FS", "CDC Interface")),
    ("USB_DEVICE/App/usbd_desc.c", r"#define USBD_VID +(\d+)", usb("VID", "1155")),
    ("USB_DEVICE/App/usbd_desc.c", r"#define USBD_PID_FS +(\d+)", usb("PID_CDC_FS", "22336")),
    ("USB_DEVICE/App/usbd_cdc_if.h", r"#define APP_RX_DATA_SIZE +(\d+)", usb("APP_RX_DATA_SIZE", "2048")),
    ("USB_DEVICE/App/usbd_cdc_if.h", r"#define APP_TX_DATA_SIZE +(\d+)", usb("APP_TX_DATA_SIZE", "2048")),
    ("USB_DEVICE/Target/usbd_conf.h", r"#define USBD_SELF_POWERED +(\d+)U", usb("USBD_SELF_POWERED", "1")),
]


def _sub_outside_user_code(text, pattern, value):
    """text with group 1 of pattern replaced by value, only outside USER CODE; and the count."""
    count = 0

    def one(m):
        nonlocal count
        count += 1
        return m.group(0)[:m.start(1) - m.start(0)] + value + m.group(0)[m.end(1) - m.start(0):]

    parts = USER_CODE.split(text)
    # split() with two groups yields: outside, whole section, its name, outside, ...
    for i in range(0, len(parts), 3):
        parts[i] = re.sub(pattern, one, parts[i])
    return "".join(p for i, p in enumerate(parts) if i % 3 != 2), count


def _user_constants_into_main_h(text, k):
    """CubeMX's private defines: the .ioc's user constants first, then the pin labels."""
    constants = [pair.split(",", 1) for pair in k["Mcu.UserConstants"].split(";") if pair]
    head, sep, rest = text.partition("/* Private defines -----------------------------------------------------------*/\n")
    labels = re.match(r"(?:#define \w+ .*\n)*", rest).group(0)
    kept = "".join(l + "\n" for l in labels.splitlines() if re.match(r"#define \w+_(Pin|GPIO_Port|EXTI_IRQn) ", l))
    return head + sep + "".join(f"#define {n} {v}\n" for n, v in constants) + kept + rest[len(labels):]


def regenerate(fw: Path):
    """What "Generate Code" leaves of fw's CubeMX-owned files, from fw's own .ioc."""
    k = ioc_of(fw / "manipulator.ioc")
    for name in sorted({r[0] for r in RULES}):
        path = fw / name
        text = path.read_text()
        for _, pattern, value in (r for r in RULES if r[0] == name):
            text, count = _sub_outside_user_code(text, pattern, value(k))
            assert count == 1, f"{name}: CubeMX's line {pattern!r} found {count} times outside USER CODE"
        path.write_text(text)
    main_h = fw / "Core" / "Inc" / "main.h"
    main_h.write_text(_user_constants_into_main_h(main_h.read_text(), k))


# ------------------------------------------------------------------ nothing of the project outside USER CODE

def project_names():
    """Every name the project's own headers define (application, board port, generated)."""
    names, headers = set(), []
    for folder in (FW / "App" / "Inc", FW / "Board" / "Inc", ROOT / "generated"):
        headers += sorted(folder.glob("*.h"))
    for h in headers:
        text = re.sub(r"/\*.*?\*/", "", h.read_text(), flags=re.S)
        names |= set(re.findall(r"#define\s+(\w+)", text))
        names |= set(re.findall(r"^[A-Za-z_][\w \t*]*?\b(\w+)\s*\([^;{()]*\)\s*;", text, re.M))  # prototypes
        names |= set(re.findall(r"\}\s*(\w+)\s*;", text))                                      # typedef'd structs
    return names - {h.stem.upper() + "_H" for h in headers}, {h.name for h in headers}


def test_cubemx_owned_files_name_nothing_of_the_project_outside_user_code():
    """What CubeMX rewrites must not carry a model value, board setting or application
    call: a regeneration would replace it with the .ioc's literal or drop it."""
    names, headers = project_names()
    assert {"MODEL_SERVO_BAUD", "MODEL_TICK_US", "BOARD_HSE_BYPASS", "BOARD_PLL_M", "app_init",
            "board_clock_config"} <= names
    for path in cubemx_owned():
        rest = outside_user_code(path.read_text())
        code = re.sub(r"/\*.*?\*/", "", rest, flags=re.S)
        used = set(re.findall(r"\b[A-Za-z_]\w*\b", code)) & names
        assert not used, f"{path.relative_to(FW)}: outside USER CODE: {sorted(used)}"
        included = set(re.findall(r'#include "([^"]+)"', rest)) & headers
        assert not included, f"{path.relative_to(FW)}: includes {sorted(included)} outside USER CODE"


def test_the_committed_files_are_what_cubemx_writes_from_the_ioc(tmp_path):
    """Regenerating the committed tree from its own .ioc changes no file."""
    shutil.copytree(FW, tmp_path / "fw", ignore=shutil.ignore_patterns("build", "Debug", "Release"))
    regenerate(tmp_path / "fw")
    for path in cubemx_owned(tmp_path / "fw"):
        rel = path.relative_to(tmp_path / "fw")
        assert path.read_text() == (FW / rel).read_text(), f"{rel} is not what CubeMX writes from the .ioc"


def test_the_stand_in_changes_what_the_ioc_changes(tmp_path):
    """The stand-in for CubeMX is not vacuous: other .ioc values give other lines."""
    fw = tmp_path / "fw"
    shutil.copytree(FW, fw, ignore=shutil.ignore_patterns("build", "Debug", "Release"))
    ioc = fw / "manipulator.ioc"
    text = ioc.read_text().replace("USB_DEVICE.APP_RX_DATA_SIZE=64\n", "")
    text = text.replace("PH0\\ -\\ OSC_IN.Mode=HSE-External-Oscillator", "PH0\\ -\\ OSC_IN.Mode=HSE-External-Clock-Source")
    ioc.write_text(text.replace("Mcu.UserConstants=SERVO_BAUD,", "Mcu.UserConstants=SERVO_BAUD,1"))
    regenerate(fw)
    assert re.search(r"#define APP_RX_DATA_SIZE +2048\n", (fw / "USB_DEVICE/App/usbd_cdc_if.h").read_text())
    assert "RCC_OscInitStruct.HSEState = RCC_HSE_BYPASS;" in (fw / "Core/Src/main.c").read_text()
    assert re.search(r"#define SERVO_BAUD 1\d+\n", (fw / "Core/Inc/main.h").read_text())


# ------------------------------------------------------------------ the start-up on the host

HARNESS_SOURCES = ["Core/Src/main.c", "Core/Src/stm32f4xx_hal_msp.c", "Core/Src/stm32f4xx_it.c",
                   "USB_DEVICE/App/usb_device.c", "USB_DEVICE/App/usbd_desc.c", "USB_DEVICE/App/usbd_cdc_if.c",
                   "USB_DEVICE/Target/usbd_conf.c", "Board/Src/board_clock.c"]


def board_symbols(hse_hz=8_000_000, bypass=0) -> list[str]:
    """The defined symbols of the command-line build (the Makefile's DEFS) for a board."""
    return ["USE_HAL_DRIVER", "STM32F411xE", f"HSE_VALUE={hse_hz}U", f"BOARD_HSE_HZ={hse_hz}u",
            f"BOARD_HSE_BYPASS={bypass}"]


def build_startup(fw: Path, gen: Path, tmp: Path, symbols=None):
    """The CubeMX-owned start-up of fw (with gen's model_params.h) built for the host over the
    HAL double with these defined symbols (default: the default board's): (ffi, lib, the
    shared library's path)."""
    stubs = tmp / "hal_stubs.c"
    stubs.write_text(weak_stubs(FW / "ci" / "hal_decls"))
    includes = [FW / "ci" / "hal_decls"] + [fw / d for d in firmware.source_lists()["FIRMWARE_INCLUDES"]
                                            if d != "../generated"] + [gen, CSRC]
    flags = [f"-D{s}" for s in (symbols or board_symbols())] + [
        "-Dmain=firmware_main", "-Wno-unused-parameter"]   # CubeMX's usbd_conf.c and the generated weak stubs
    sources = [fw / s for s in HARNESS_SOURCES] + [CSRC / "fake_cube.c", stubs]
    ffi, lib = cbuild.load("cube_startup", sources, [CSRC / "fake_cube.h"], include_dirs=includes,
                           extra_flags=flags)
    return ffi, lib, cbuild.build_shared("cube_startup", sources, includes, flags)


def boot(fw: Path, gen: Path, tmp: Path, hse_hz=8_000_000, bypass=0, symbols=None):
    """Builds the CubeMX-owned start-up of fw (with gen's model_params.h) for the host with
    these symbols (default: the board's of hse_hz and bypass) and runs main() to its main
    loop; returns (record, the CDC buffers' sizes, SystemClock_Config's record)."""
    ffi, lib, so = build_startup(fw, gen, tmp, symbols or board_symbols(hse_hz, bypass))
    cube = ffi.addressof(lib, "cube")
    fields = [name for name, _ in ffi.typeof("fake_cube_t").fields]
    assert lib.fake_cube_boot(0, 0) == 1 and not cube.error_handler
    record = {name: getattr(cube, name) for name in fields}
    record["nvic_priority"] = list(cube.nvic_priority)
    record["nvic_enabled"] = list(cube.nvic_enabled)
    lib.fake_cube_usb_strings()
    record["strings"] = [ffi.string(cube.string[i]).decode() for i in range(4)]
    # the host's SET_CONTROL_LINE_STATE (USB CDC PSTN 6.3.12: wValue bit 0 DTR, bit 1 RTS)
    lib.fake_cube_line_state(0x0001)
    record["dtr_set"] = (cube.line_states, cube.dtr)
    lib.fake_cube_line_state(0x0002)
    record["rts_only"] = (cube.line_states, cube.dtr)
    sizes = {}
    for line in subprocess.run(["nm", "-S", "--defined-only", str(so)], capture_output=True, text=True,
                               check=True).stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[3] in ("UserRxBufferFS", "UserTxBufferFS"):
            sizes[parts[3]] = int(parts[1], 16)
    lib.fake_cube_system_clock_config()
    cubemx_clock = {name: getattr(cube, name) for name in ("osc_configs", "hse_state", "pll_m", "pll_n",
                                                                  "pll_p", "pll_q", "apb1_divider", "flash_latency")}
    return record, sizes, cubemx_clock


# HAL constant values (stm32f4xx_hal_rcc.h: RCC_CR and RCC_CFGR field encodings of RM0383 6.3)
RCC_HSE_ON, RCC_HSE_BYPASS = 0x00010000, 0x00050000
RCC_PLLSOURCE_HSE, RCC_SYSCLKSOURCE_PLLCLK = 0x00400000, 0x00000002
APB_DIVISOR = {0x0000: 1, 0x1000: 2, 0x1400: 4, 0x1800: 8, 0x1C00: 16}
IRQ = {"TIM3": 29, "USART1": 37, "OTG_FS": 67}


def check_peripherals(record, sizes, model, hse_hz, bypass):
    """The model's and the board's numbers as the peripherals receive them."""
    r = record
    # clock (RM0383 6.3.2): HSE / M * N / P = SYSCLK, / Q = the USB clock
    assert r["osc_configs"] == 1 and r["clock_configs"] == 1
    assert r["hse_state"] == (RCC_HSE_BYPASS if bypass else RCC_HSE_ON) and r["pll_source"] == RCC_PLLSOURCE_HSE
    vco = Fraction(hse_hz, r["pll_m"]) * r["pll_n"]
    assert 1 * MHZ <= Fraction(hse_hz, r["pll_m"]) <= 2 * MHZ and 100 * MHZ <= vco <= 432 * MHZ
    sysclk, usb_clock = vco / r["pll_p"], vco / r["pll_q"]
    assert r["sysclk_source"] == RCC_SYSCLKSOURCE_PLLCLK and r["ahb_divider"] == 0
    apb1_div = APB_DIVISOR[r["apb1_divider"]]
    assert sysclk == 96 * MHZ and usb_clock == 48 * MHZ and sysclk / apb1_div <= 50 * MHZ
    assert r["flash_latency"] == 3                       # RM0383 table 5: 90 < HCLK <= 100 MHz
    timer_clock = sysclk / apb1_div * (2 if apb1_div > 1 else 1)   # RM0383 6.2: x2 when APB1 divides
    # the microsecond clock and the tick
    assert timer_clock / (r["tim2_prescaler"] + 1) == MHZ and r["tim2_period"] == 2**32 - 1
    tick = Fraction((r["tim3_prescaler"] + 1) * (r["tim3_period"] + 1)) / timer_clock
    assert tick == 1 / Fraction(str(model.sample_rate)) and r["tim3_started_it"] == 1
    # the servo bus, single wire, at the model's baud; the IMU at 400 kHz
    assert r["halfduplex_inits"] == 1 and r["uart_inits"] == 0 and r["baud"] == model.servo_baud
    assert r["i2c_inits"] == 1 and r["i2c_clock_speed"] == 400_000
    # interrupt priorities: servo bus first, then USB, then the tick, SysTick last
    prio = {n: r["nvic_priority"][i] for n, i in IRQ.items()}
    assert all(r["nvic_enabled"][i] for i in IRQ.values())
    assert prio["USART1"] < prio["OTG_FS"] < prio["TIM3"] < r["systick_priority"]
    # USB: the stack started, the project's strings, one full-speed bulk packet a buffer
    assert r["usbd_started"] == 1
    assert r["strings"] == ["uavarm", "uavarm manipulator", "CDC Config", "CDC Interface"]
    assert sizes == {"UserRxBufferFS": 64, "UserTxBufferFS": 64}
    assert r["dtr_set"] == (1, 1) and r["rts_only"] == (2, 0)
    # the board's guard (reset cause, watchdog) after the peripherals; the clock security system on
    assert r["guard_started"] == 1 and r["css_enabled"] == 1


def test_committed_start_up_gives_the_model_and_board_numbers(tmp_path, model):
    record, sizes, cubemx_clock = boot(FW, ROOT / "generated", tmp_path)
    check_peripherals(record, sizes, model, 8_000_000, 0)
    # CubeMX's SystemClock_Config (from the .ioc, not called) sets the same clock as the
    # board's default: the .ioc's clock tree is the default board's
    assert cubemx_clock == {name: record[name] for name in cubemx_clock}


# The boards the build configurations are for, and the clock each has on OSC_IN: a crystal of
# the .ioc's 8 MHz (RCC.HSE_VALUE), or on a NUCLEO-F411RE the ST-LINK's 8 MHz MCO output
# (UM1724, "OSC clock": HSE bypass)
@pytest.mark.parametrize("configuration, bypass", [("Debug", 0), ("Release", 0), ("Nucleo_Debug", 1),
                                                   ("Nucleo_Release", 1)])
def test_each_cubeide_configuration_programs_its_boards_clock(configuration, bypass, tmp_path, model):
    """main() built with exactly the configuration's defined symbols (.cproject): the HSE in
    bypass mode for the Nucleo, oscillator mode for the crystal, and from its 8 MHz the PLL's
    M, N, P, Q giving 96 MHz SYSCLK and 48 MHz USB within RM0383's limits (check_peripherals);
    the rest of the start-up as for every board."""
    record, sizes, _ = boot(FW, ROOT / "generated", tmp_path, symbols=cproject_symbols(configuration))
    check_peripherals(record, sizes, model, 8_000_000, bypass)
    # the tree docs/board.md states (PLLP = RCC_PLLP_DIV4, the HAL value 4)
    assert (record["pll_m"], record["pll_n"], record["pll_p"], record["pll_q"]) == (8, 384, 4, 8)


def test_a_clock_that_does_not_start_stops_the_board_before_any_peripheral(tmp_path):
    """The HSE never ready (HAL_RCC_OscConfig's timeout: a NUCLEO-F411RE built for a crystal,
    a crystal that does not oscillate): main() goes from the board's clock to Error_Handler,
    which stops in board_stop (supply off, LEDs on, watchdog running: tests/test_board_guard.py),
    before any peripheral, the USB stack, the board's guard or the clock security system."""
    ffi, lib, _ = build_startup(FW, ROOT / "generated", tmp_path)
    assert lib.fake_cube_boot(1, 0) == 0
    cube = ffi.addressof(lib, "cube")
    assert cube.error_handler and cube.osc_configs == 1 and cube.clock_configs == 0 and cube.css_enabled == 0
    assert (cube.halfduplex_inits, cube.i2c_inits, cube.tim2_prescaler, cube.usbd_started, cube.guard_started) == \
        (0, 0, 0, 0, 0)


def test_cfg0_closed_runs_the_servo_set_up_bridge_instead_of_the_arm(tmp_path):
    """With the bridge selected, main() starts the peripherals and the board's guard, then
    the bridge, whose loop feeds the watchdog before each poll; the tick timer is never
    started and the main loop never reached."""
    ffi, lib, _ = build_startup(FW, ROOT / "generated", tmp_path)
    assert lib.fake_cube_boot(0, 1) == 0
    cube = ffi.addressof(lib, "cube")
    assert (cube.guard_started, cube.bridge_started, cube.bridge_polled) == (1, 1, 1)
    assert cube.usbd_started == 1 and cube.tim3_started_it == 0 and not cube.error_handler


@pytest.fixture(scope="module")
def other_model_tree(tmp_path_factory):
    """The board project and generated code of a model with another servo baud and tick,
    after `make codegen`: (firmware folder, generated folder, model). Made once per test run
    (the tests copy the folders before changing them)."""
    def make(tmp):
        text = config.DEFAULT_MODEL.read_text()
        text = re.sub(r"(?m)^baud = \d+", "baud = 1000000", text)
        text = re.sub(r"(?m)^sample_rate = [\d.]+", "sample_rate = 200.0", text)
        (tmp / "manipulator.toml").write_text(text)
        shutil.copytree(FW, tmp / "firmware_stm32", ignore=shutil.ignore_patterns("build", "Debug", "Release"))
        assert generate.main(["--model", str(tmp / "manipulator.toml"), "--out", str(tmp / "generated"),
                              "--board", str(tmp / "firmware_stm32")]) == 0
        return str(tmp)
    tmp = Path(once_per_run(tmp_path_factory, "other_model", make))
    fw = tmp / "firmware_stm32"
    m = config.load(tmp / "manipulator.toml")
    assert (m.servo_baud, m.sample_rate) != (config.load().servo_baud, config.load().sample_rate)
    return fw, tmp / "generated", m


def test_a_model_change_reaches_the_peripherals_without_cubemx(other_model_tree, tmp_path):
    """The command-line flow: make codegen only, CubeMX's files as committed otherwise."""
    fw, gen, m = other_model_tree
    record, sizes, _ = boot(fw, gen, tmp_path, hse_hz=25_000_000, bypass=1)
    check_peripherals(record, sizes, m, 25_000_000, 1)


def test_a_model_change_survives_generate_code(other_model_tree, tmp_path):
    """The CubeMX flow: make codegen, then "Generate Code" from the .ioc it wrote; the
    board settings (a 25 MHz external clock) still reach the clock."""
    fw, gen, m = other_model_tree
    regen = tmp_path / "firmware_stm32"
    shutil.copytree(fw, regen)
    regenerate(regen)
    record, sizes, _ = boot(regen, gen, tmp_path, hse_hz=25_000_000, bypass=1)
    check_peripherals(record, sizes, m, 25_000_000, 1)


def test_the_regenerated_project_passes_make_check(other_model_tree, tmp_path):
    """Every firmware source of the regenerated tree compiles for the Cortex-M4 with
    warnings as errors (the HAL-using ones against ci/hal_decls)."""
    require_arm_toolchain()
    fw, gen, _ = other_model_tree
    regen = tmp_path / "firmware_stm32"
    shutil.copytree(fw, regen)
    shutil.copytree(gen, tmp_path / "generated")
    regenerate(regen)
    proc = subprocess.run(["make", "-C", str(regen), "check", f"BUILD={tmp_path / 'build'}"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
