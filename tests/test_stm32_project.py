"""The STM32CubeIDE project in firmware_stm32/: one source list for the three builds, a
clock tree that RM0383 allows, a .ioc written as CubeMX writes it and agreeing with the
model file, the board settings and main.h, a .cproject as STM32CubeIDE writes it, the servo
supply off from reset, a Cortex-M4 compile of every firmware source with warnings as errors
(`make -C firmware_stm32 check`), and command-line builds that never mix old and new.

Oracles: RM0383 (STM32F411 reference manual) clock limits and flash wait states, the
STM32F411xE datasheet's LQFP64 pinout, the conventions of CubeMX- and CubeIDE-written
projects (docs/board.md names those compared), the model file (uavarm.model.config), the
file system (which sources exist), the C preprocessor's includes, and the compiler itself.
"""
import os
import re
import shutil
import struct
import subprocess
import time
import xml.etree.ElementTree as ET
from fractions import Fraction
from pathlib import Path

import pytest

import st_startup
from conftest import ROOT, require_arm_toolchain, skip_unless_ci
from hal_stubs import weak_stubs
from uavarm.build import firmware
from uavarm.model import config

FW = ROOT / "firmware_stm32"
IOC = FW / "manipulator.ioc"
MHZ = 1_000_000

# What STM32CubeMX/CubeIDE generate into the project and this repository does not keep
# (firmware_stm32/.gitignore): HAL, CMSIS, USB library, boilerplate sources.
CUBEMX_PROVIDED_DIRS = ("Drivers", "Middlewares")
CUBEMX_PROVIDED_FILES = ("Core/Src/system_stm32f4xx.c", "Core/Src/syscalls.c", "Core/Src/sysmem.c")


def ioc(path: Path = IOC):
    """manipulator.ioc as a dict (Java properties: `\\ ` and `\\:` escapes)."""
    keys = {}
    for line in path.read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        key, _, value = line.partition("=")
        keys[key.replace("\\ ", " ")] = value.replace("\\:", ":")
    return keys


def ioc_int(k, key):
    """An integer parameter, through the user constant it may name (CubeMX's Mcu.UserConstants)."""
    constants = dict(pair.split(",", 1) for pair in k["Mcu.UserConstants"].split(";") if pair)
    return int(constants.get(k[key], k[key]))


def listed(name):
    return {Path(p) for p in firmware.listed(name)}


def c_defines(header: Path, *names, extra=()):
    """Values of integer macros of a header, as the C preprocessor and compiler compute them
    (host cc: the expressions are plain integer arithmetic)."""
    src = "#include <stdio.h>\n" + f'#include "{header.name}"\nint main(void) {{\n'
    src += "".join(f'  printf("%llu\\n", (unsigned long long)({n}));\n' for n in names) + "  return 0;\n}\n"
    tmp = Path(__import__("tempfile").mkdtemp())
    (tmp / "probe.c").write_text(src)
    subprocess.run(["cc", "-I", str(header.parent), *extra, str(tmp / "probe.c"), "-o", str(tmp / "probe")],
                   check=True, capture_output=True, text=True)
    out = subprocess.run([str(tmp / "probe")], check=True, capture_output=True, text=True).stdout.split()
    return dict(zip(names, map(int, out)))


# ------------------------------------------------------------------ one source list

def test_sources_mk_lists_every_application_and_generated_source():
    app = {p.resolve() for p in (FW / "App" / "Src").glob("*.c")}
    gen = {p.resolve() for p in (ROOT / "generated").glob("*.c")}
    assert listed("APP_SOURCES") == app
    assert listed("GENERATED_SOURCES") == gen, "a generated source is missing from sources.mk"
    every = firmware.listed("FIRMWARE_SOURCES")
    assert len(every) == len(set(every)), "a source is listed twice"
    missing = [p for p in every if not p.exists()]
    assert not missing
    for d in firmware.source_lists()["FIRMWARE_INCLUDES"]:
        assert (FW / d).is_dir(), d


def test_host_build_compiles_the_listed_application():
    assert set(firmware.app_sources()) == listed("APP_SOURCES") | listed("GENERATED_SOURCES")


def cproject_source_files():
    """Every .c file the CubeIDE project builds: its source folders (resolving the linked
    folder of .project), minus exclusions and what CubeMX itself provides."""
    links = {}
    for link in ET.parse(FW / ".project").getroot().iter("link"):
        uri = link.findtext("locationURI")
        m = re.fullmatch(r"PARENT-(\d+)-PROJECT_LOC/(.+)", uri)
        base = FW
        for _ in range(int(m.group(1))):
            base = base.parent
        links[link.findtext("name")] = base / m.group(2)
    configs = list(ET.parse(FW / ".cproject").getroot().iter("sourceEntries"))
    assert configs, "no build configuration in .cproject"
    per_config = []
    for entries in configs:
        files = set()
        for entry in entries.iter("entry"):
            name = entry.get("name")
            if name in CUBEMX_PROVIDED_DIRS:
                continue
            folder = links.get(name, FW / name)
            excluded = [e for e in (entry.get("excluding") or "").split("|") if e]
            for path in folder.rglob("*.c"):
                rel = path.relative_to(folder).as_posix()
                if any(rel == e or rel.startswith(e.rstrip("/") + "/") for e in excluded):
                    continue
                if folder == FW / name and f"{name}/{rel}" in CUBEMX_PROVIDED_FILES:
                    continue
                files.add(path.resolve())
        per_config.append(files)
    return per_config


def test_cubeide_project_builds_exactly_the_listed_sources():
    """The .cproject cannot include sources.mk, so this is what keeps it the same list."""
    for files in cproject_source_files():
        assert files == listed("FIRMWARE_SOURCES"), (
            f"in .cproject, not in sources.mk: {sorted(map(str, files - listed('FIRMWARE_SOURCES')))}; "
            f"in sources.mk, not in .cproject: {sorted(map(str, listed('FIRMWARE_SOURCES') - files))}")


def test_cubeide_include_paths_cover_the_listed_include_folders():
    text = (FW / ".cproject").read_text()
    paths = set(re.findall(r'listOptionValue builtIn="false" value="(?:&quot;)?(\.\./[^"&]+)(?:&quot;)?"', text))
    # include paths are relative to the build folder (Debug/), one level below the project
    resolved = {(FW / "Debug" / p).resolve() for p in paths}
    for d in firmware.source_lists()["FIRMWARE_INCLUDES"]:
        assert (FW / d).resolve() in resolved, d
    assert "hal_decls" not in text, "the CI declarations must never reach the real build"


CIDE = "com.st.stm32cube.ide.mcu.gnu.managedbuild"
# Option values as STM32CubeIDE writes them in the CubeIDE-written projects compared
CIDE_VALUES = {
    "tool.c.compiler.option.optimization.level": {f"{CIDE}.tool.c.compiler.option.optimization.level.value.{v}"
                                                  for v in ("o0", "og", "os", "ofast")},
    "tool.c.compiler.option.debuglevel": {f"{CIDE}.tool.c.compiler.option.debuglevel.value.{v}"
                                          for v in ("g0", "g1", "g", "g3")},
    "option.fpu": {f"{CIDE}.option.fpu.value.fpv4-sp-d16"},
    "option.floatabi": {f"{CIDE}.option.floatabi.value.hard"},
}


def cproject_configurations():
    """{name: {option superClass suffix: option element, and "builder": the builder element}}
    of each build configuration."""
    configs = {}
    for conf in ET.parse(FW / ".cproject").getroot().iter("configuration"):
        if conf.get("artifactExtension") != "elf":
            continue
        configs[conf.get("name")] = {opt.get("superClass").removeprefix(CIDE + "."): opt
                                     for opt in conf.iter("option")}
        configs[conf.get("name")]["builder"] = conf.find(".//builder")
    return configs


# The build configurations: CubeIDE's Debug and Release for a board with its own crystal, and
# their copies for a NUCLEO-F411RE, whose OSC_IN the ST-LINK drives (HSE bypass)
CONFIGURATIONS = {"Debug": "Debug", "Release": "Release", "Nucleo_Debug": "Debug", "Nucleo_Release": "Release"}


def cproject_symbols(configuration: str) -> list[str]:
    """The C compiler's defined symbols (-D) of a build configuration."""
    opts = cproject_configurations()[configuration]
    return [v.get("value") for v in opts["tool.c.compiler.option.definedsymbols"].iter("listOptionValue")]


def test_cproject_has_debug_and_release_as_cubeide_writes_them():
    """The configurations CubeIDE creates, Debug and Release, and their copies for the
    NUCLEO-F411RE (Manage Configurations, New, settings copied: the option.defaults record
    CubeMX compares against when it regenerates keeps its source's name), each with the MCU,
    the linker script CubeIDE names, its own build folder, and option values that occur in
    CubeIDE-written projects; Release optimises (-Os) and leaves DEBUG undefined (DEBUG also
    freezes the watchdog for the debugger: test_board_guard.py); the Nucleo copies add
    BOARD_HSE_BYPASS=1 and nothing else."""
    configs = cproject_configurations()
    assert set(configs) == set(CONFIGURATIONS)
    for name, opts in configs.items():
        kind = CONFIGURATIONS[name]
        defaults = [f.strip() for f in opts["option.defaults"].get("value").split("||")]
        assert defaults[0].startswith("com.st.stm32cube.ide.common.services.build.inputs.revA.")
        assert defaults[1] == kind and defaults[5] == "STM32F411RETx"
        assert "${workspace_loc:/${ProjName}/STM32F411RETX_FLASH.ld}" in defaults
        assert opts["option.target_mcu"].get("value") == "STM32F411RETx"
        script = opts["tool.c.linker.option.script"].get("value")
        assert script == "${workspace_loc:/${ProjName}/STM32F411RETX_FLASH.ld}"
        assert (FW / "STM32F411RETX_FLASH.ld").is_file()
        for option, allowed in CIDE_VALUES.items():
            assert opts[option].get("value") in allowed, (name, option)
        symbols = cproject_symbols(name)
        board = [s for s in symbols if s.startswith("BOARD_") or s.startswith("HSE_")]
        assert set(symbols) - set(board) == {"USE_HAL_DRIVER", "STM32F411xE"} | ({"DEBUG"} if kind == "Debug" else set())
        assert board == (["BOARD_HSE_BYPASS=1"] if name.startswith("Nucleo_") else [])
        optimisation = opts["tool.c.compiler.option.optimization.level"].get("value")
        assert optimisation.endswith(".value.os" if kind == "Release" else ".value.og")
        assert opts["builder"].get("buildPath") == "${workspace_loc:/manipulator}/" + name


def test_makefile_and_cubeide_link_with_the_same_script():
    assert re.search(r"^LDSCRIPT := STM32F411RETX_FLASH\.ld$", (FW / "Makefile").read_text(), re.M)
    script = (FW / "STM32F411RETX_FLASH.ld").read_text()
    k = ioc()
    # the reserve CubeMX/CubeIDE write from the .ioc's heap and stack sizes
    assert re.search(rf"_Min_Heap_Size = {k['ProjectManager.HeapSize']};", script)
    assert re.search(rf"_Min_Stack_Size = {k['ProjectManager.StackSize']};", script)


def test_cubemx_provided_files_are_not_kept():
    ignore = (FW / ".gitignore").read_text().split()
    for d in CUBEMX_PROVIDED_DIRS:
        assert f"/{d}/" in ignore
    for f in CUBEMX_PROVIDED_FILES:
        assert f"/{f}" in ignore


# ------------------------------------------------------------------ clock tree (RM0383)

def test_clock_tree_is_within_rm0383_limits_and_gives_96_and_48_mhz():
    k = ioc()
    hse = int(k["RCC.HSE_VALUE"])
    m, n, q = int(k["RCC.PLLM"]), int(k["RCC.PLLN"]), int(k["RCC.PLLQ"])
    p = int(re.fullmatch(r"RCC_PLLP_DIV(\d)", k["RCC.PLLP"]).group(1))
    assert k["RCC.PLLSourceVirtual"] == "RCC_PLLSOURCE_HSE" and k["RCC.SYSCLKSource"] == "RCC_SYSCLKSOURCE_PLLCLK"
    # RM0383 6.3.2 RCC_PLLCFGR: M 2..63, N 50..432, P in 2/4/6/8, Q 2..15
    assert 2 <= m <= 63 and 50 <= n <= 432 and p in (2, 4, 6, 8) and 2 <= q <= 15
    vco_in = Fraction(hse, m)
    vco = vco_in * n
    assert 1 * MHZ <= vco_in <= 2 * MHZ                     # VCO input 1-2 MHz
    assert 100 * MHZ <= vco <= 432 * MHZ                    # VCO output 100-432 MHz
    sysclk, usb = vco / p, vco / q
    assert sysclk == 96 * MHZ and sysclk <= 100 * MHZ
    assert usb == 48 * MHZ                                  # USB OTG FS needs exactly 48 MHz
    apb1 = sysclk / int(k["RCC.APB1CLKDivider"].rsplit("DIV", 1)[1])
    assert apb1 <= 50 * MHZ                                 # APB1 at most 50 MHz
    # RM0383 table 5: 90 < HCLK <= 100 MHz at 2.7-3.6 V needs 3 wait states, in the clock
    # set-up CubeMX writes from the .ioc and in the board's
    for source in (FW / "Core" / "Src" / "main.c", FW / "Board" / "Src" / "board_clock.c"):
        assert re.search(r"HAL_RCC_ClockConfig\(&\w+, FLASH_LATENCY_3\)", source.read_text()), source.name
    # CubeMX's own derived frequencies agree
    assert int(k["RCC.SYSCLKFreq_VALUE"]) == sysclk and int(k["RCC.48MHZClocksFreq_Value"]) == usb
    assert int(k["RCC.PLLQCLKFreq_Value"]) == usb
    assert int(k["RCC.VCOInputFreq_Value"]) == vco_in and int(k["RCC.VCOOutputFreq_Value"]) == vco
    assert int(k["RCC.APB1TimFreq_Value"]) == 2 * apb1     # timers run at 2 x PCLK1 when APB1 is divided
    assert int(k["RCC.LSE_VALUE"]) == 32768 and int(k["RCC.HSI_VALUE"]) == 16 * MHZ


def test_i2s_pll_values_follow_its_own_input_divider():
    """The I2S PLL is unused but CubeMX stores its frequencies: they must be those of the
    .ioc's PLLI2SM (RM0383 6.3.23 RCC_PLLI2SCFGR: own input divider M, VCO input 1-2 MHz,
    VCO output 100-432 MHz, R 2-7; CubeMX's defaults N = 192, R = 2 when not stored)."""
    k = ioc()
    m, n, r = int(k["RCC.PLLI2SM"]), int(k.get("RCC.PLLI2SN", 192)), int(k.get("RCC.PLLI2SR", 2))
    vco_in = Fraction(int(k["RCC.HSE_VALUE"]), m)
    assert 1 * MHZ <= vco_in <= 2 * MHZ and int(k["RCC.VCOInputMFreq_Value"]) == vco_in
    assert 100 * MHZ <= vco_in * n <= 432 * MHZ and int(k["RCC.VCOI2SOutputFreq_Value"]) == vco_in * n
    assert int(k["RCC.VcooutputI2S"]) == int(k["RCC.I2SClocksFreq_Value"]) == vco_in * n / r


def test_crystal_is_one_board_setting_the_ioc_and_hal_agree_with():
    board = FW / "Board" / "Inc" / "board_config.h"
    v = c_defines(board, "BOARD_HSE_HZ", "BOARD_PLL_M", "BOARD_PLL_N", "BOARD_PLL_P_DIV", "BOARD_PLL_Q")
    k = ioc()
    assert v["BOARD_HSE_HZ"] == int(k["RCC.HSE_VALUE"]) == 8 * MHZ
    assert (v["BOARD_PLL_M"], v["BOARD_PLL_N"], v["BOARD_PLL_Q"]) == \
        (int(k["RCC.PLLM"]), int(k["RCC.PLLN"]), int(k["RCC.PLLQ"]))
    assert k["RCC.PLLP"] == f"RCC_PLLP_DIV{v['BOARD_PLL_P_DIV']}"
    hal_conf = (FW / "Core" / "Inc" / "stm32f4xx_hal_conf.h").read_text()
    assert re.search(r"#define HSE_VALUE\s+(\d+)U", hal_conf).group(1) == str(v["BOARD_HSE_HZ"])
    # another whole-MHz crystal re-derives the PLL to the same 96 / 48 MHz
    v25 = c_defines(board, "BOARD_PLL_M", extra=["-DBOARD_HSE_HZ=25000000u"])
    assert v25["BOARD_PLL_M"] == 25


@pytest.mark.parametrize("hse", ["12500000u", "3000000u", "27000000u"])
def test_a_crystal_the_pll_cannot_use_is_refused_at_compile_time(hse):
    with pytest.raises(subprocess.CalledProcessError):
        c_defines(FW / "Board" / "Inc" / "board_config.h", "BOARD_PLL_M", extra=[f"-DBOARD_HSE_HZ={hse}"])


# ------------------------------------------------------------------ .ioc vs model and main.h

def test_ioc_peripherals_follow_the_model_and_port_h():
    m = config.load()
    k = ioc()
    timer_hz = int(k["RCC.APB1TimFreq_Value"])
    assert k["USART1.BaudRate"] == "SERVO_BAUD" and ioc_int(k, "USART1.BaudRate") == m.servo_baud
    assert k["USART1.VirtualMode"] == "VM_ASYNC"
    assert k["PB6.Mode"] == "Half_duplex(single_wire_mode)" and k["PB6.Signal"] == "USART1_TX"
    assert k["I2C1.I2C_Mode"] == "I2C_Fast"          # CubeMX writes ClockSpeed 400000 for it
    # TIM2: 1 MHz, 32-bit period: the microsecond clock wraps at 2^32 like port.h says
    assert Fraction(timer_hz, int(k["TIM2.Prescaler"]) + 1) == MHZ
    assert int(k["TIM2.Period"]) == 2**32 - 1
    # TIM3: one update per model sample period
    assert k["TIM3.Period"] == "TICK_PERIOD"
    tick = Fraction((int(k["TIM3.Prescaler"]) + 1) * (ioc_int(k, "TIM3.Period") + 1), timer_hz)
    assert tick == Fraction(1) / Fraction(str(m.sample_rate))
    assert k["NVIC.TIM3_IRQn"].startswith("true:")
    assert k["USB_DEVICE.CLASS_NAME_FS"] == "CDC" and k["USB_OTG_FS.VirtualMode"] == "Device_Only"
    assert (k["USB_DEVICE.VirtualMode"], k["USB_DEVICE.VirtualModeFS"]) == ("Cdc", "Cdc_FS")
    assert (k["PA11.Signal"], k["PA12.Signal"]) == ("USB_OTG_FS_DM", "USB_OTG_FS_DP")
    assert "PA9.Signal" not in k, "PA9 (VBUS sensing) stays unused: VBUS sensing is off"
    # the project's USB strings, and CDC buffers of one full-speed bulk packet (USB 2.0
    # 5.8.3: at most 64 bytes) into which a received packet fits whole
    assert (k["USB_DEVICE.MANUFACTURER_STRING"], k["USB_DEVICE.PRODUCT_STRING_CDC_FS"]) == \
        ("uavarm", "uavarm manipulator")
    assert int(k["USB_DEVICE.APP_RX_DATA_SIZE"]) == int(k["USB_DEVICE.APP_TX_DATA_SIZE"]) == 64


# ------------------------------------------------------------------ .ioc as CubeMX writes it

# DS10314 (STM32F411xC/xE datasheet) table 8, LQFP64 pin numbers of the pins the .ioc uses
LQFP64_POSITION = {"PH0 - OSC_IN": 5, "PH1 - OSC_OUT": 6, "PC0": 8, "PC1": 9, "PA5": 21, "PA6": 22, "PB0": 26,
                   "PA8": 41, "PA11": 44, "PA12": 45, "PA13": 46, "PA14": 49, "PB6": 58, "PB8": 61, "PB9": 62}

# (MxCube.Version, MxDb.Version, FirmwarePackage) as CubeMX-written STM32F411 projects pair
# them: a CubeMX release and the STM32CubeF4 package that was current when it shipped
SHIPPED_TOGETHER = {("6.9.2", "DB.6.0.92", "STM32Cube FW_F4 V1.27.1"),
                    ("6.10.0", "DB.6.0.100", "STM32Cube FW_F4 V1.28.0"),
                    ("6.12.0", "DB.6.0.120", "STM32Cube FW_F4 V1.28.1"),
                    ("6.13.0", "DB.6.0.130", "STM32Cube FW_F4 V1.28.1"),
                    ("6.14.1", "DB.6.0.141", "STM32Cube FW_F4 V1.28.2")}


def test_ioc_is_saved_as_cubemx_saves_it():
    """CubeMX 6 writes its header line, then every key once in byte order, Java-properties
    escaped; indexed lists (Mcu.IPn, Mcu.Pinn) run from 0 with their count; every IP's
    IPParameters names exactly its stored parameters."""
    lines = IOC.read_text().splitlines()
    assert lines[0] == "#MicroXplorer Configuration settings - do not modify"
    keys = [line.split("=", 1)[0] for line in lines[1:]]
    assert keys == sorted(keys) and len(keys) == len(set(keys))
    assert all(" " not in k.replace("\\ ", "") for k in keys)
    k = ioc()
    for name, count in (("Mcu.IP", "Mcu.IPNb"), ("Mcu.Pin", "Mcu.PinsNb")):
        indices = sorted(int(key[len(name):]) for key in k if re.fullmatch(re.escape(name) + r"\d+", key))
        assert indices == list(range(int(k[count]))), name
    ips = {k[f"Mcu.IP{i}"] for i in range(int(k["Mcu.IPNb"]))}
    assert ips == {"I2C1", "NVIC", "RCC", "SYS", "TIM2", "TIM3", "USART1", "USB_DEVICE", "USB_OTG_FS"}
    assert [k[f"Mcu.IP{i}"] for i in range(len(ips))] == sorted(ips)
    for ip in ips - {"NVIC", "SYS"}:
        stored = {key.split(".", 1)[1] for key in k if key.startswith(ip + ".") and key != ip + ".IPParameters"}
        assert set(k[ip + ".IPParameters"].split(",")) == stored, ip
    # pins in package order, then the virtual pins; each with its signal
    pins = [k[f"Mcu.Pin{i}"] for i in range(int(k["Mcu.PinsNb"]))]
    physical = [p for p in pins if not p.startswith("VP_")]
    assert pins[:len(physical)] == sorted(physical, key=LQFP64_POSITION.__getitem__)
    assert all(f"{p}.Signal" in k for p in pins)


def test_ioc_versions_and_keys_are_those_of_cubemx_for_this_mcu():
    k = ioc()
    assert (k["Mcu.UserName"], k["Mcu.Name"], k["Mcu.Package"], k["Mcu.CPN"]) == \
        ("STM32F411RETx", "STM32F411R(C-E)Tx", "LQFP64", "STM32F411RET6")
    assert (k["MxCube.Version"], k["MxDb.Version"], k["ProjectManager.FirmwarePackage"]) in SHIPPED_TOGETHER
    assert k["File.Version"] == "6" and k["isbadioc"] == "false"
    # IP parameters with a mode suffix are a CubeMX 4/5 form; CubeMX 6 writes plain names
    assert not [key for key in k if re.match(r"\w+\.VirtualMode-", key)]
    assert k["I2C1.IPParameters"] == "I2C_Mode"
    # the user constants: NAME,VALUE pairs, each used by a parameter
    constants = dict(pair.split(",", 1) for pair in k["Mcu.UserConstants"].split(";"))
    assert set(constants) == {"SERVO_BAUD", "TICK_PERIOD"}
    assert {name for name in constants if name in k.values()} == set(constants)


def test_main_h_has_the_user_constants_as_cubemx_writes_them():
    """CubeMX writes `#define NAME VALUE` for each user constant, in the .ioc's order,
    first in main.h's private defines (as CubeMX-written projects show)."""
    k = ioc()
    main_h = (FW / "Core" / "Inc" / "main.h").read_text()
    block = main_h.split("/* Private defines -----------------------------------------------------------*/\n")[1]
    expected = "".join(f"#define {n} {v}\n" for n, v in (p.split(",", 1) for p in k["Mcu.UserConstants"].split(";")))
    assert block.startswith(expected)


def test_generate_code_leaves_out_only_the_system_clock_call():
    """The .ioc's "Do Not Generate Function Call" (ProjectManager.functionlistsort: rank,
    function, IP, not called, driver, static) is set for SystemClock_Config only, whose
    place the board's clock takes in a USER CODE section; the other inits run in main()."""
    k = ioc()
    entries = [e.split("-") for e in k["ProjectManager.functionlistsort"].split(",")]
    not_called = {name for _, name, _, skip, _, _ in entries if skip == "true"}
    assert not_called == {"SystemClock_Config"}
    main_c = (FW / "Core" / "Src" / "main.c").read_text()
    body = main_c[main_c.index("int main(void)"):main_c.index("/* USER CODE BEGIN 2 */")]
    calls = re.findall(r"^  (\w+)\(\);", body, re.M)
    assert calls == ["HAL_Init", "board_clock_config"] + [name for _, name, _, skip, _, _ in entries if skip == "false"]
    sysinit = body[body.index("/* USER CODE BEGIN SysInit */"):body.index("/* USER CODE END SysInit */")]
    assert "board_clock_config();" in sysinit

def test_main_h_pin_labels_match_the_ioc():
    main_h = (FW / "Core" / "Inc" / "main.h").read_text()
    k = ioc()
    labels = {v: key.split(".")[0] for key, v in k.items() if key.endswith(".GPIO_Label")}
    assert {"SERVO_PWR", "LED0", "LED1", "CFG0", "CFG1", "CFG2", "SERVO_BUS", "IMU_SCL", "IMU_SDA"} <= set(labels)
    for label, pin in labels.items():
        port, number = re.fullmatch(r"P([A-H])(\d+)", pin).groups()
        assert re.search(rf"#define {label}_Pin GPIO_PIN_{number}\b", main_h), label
        assert re.search(rf"#define {label}_GPIO_Port GPIO{port}\b", main_h), label
    inputs = [l for l, p in labels.items() if k[f"{p}.Signal"] == "GPIO_Input"]
    outputs = [l for l, p in labels.items() if k[f"{p}.Signal"] == "GPIO_Output"]
    assert sorted(inputs) == ["CFG0", "CFG1", "CFG2"] and sorted(outputs) == ["LED0", "LED1", "SERVO_PWR"]


def test_servo_supply_is_off_from_reset_until_the_application_switches_it():
    k = ioc()
    assert k["PA8.GPIO_Label"] == "SERVO_PWR"
    assert k["PA8.PinState"] == "GPIO_PIN_RESET" and k["PA8.GPIO_PuPd"] == "GPIO_PULLDOWN"
    assert c_defines(FW / "Board" / "Inc" / "board_config.h", "BOARD_SERVO_POWER_ACTIVE_HIGH") == \
        {"BOARD_SERVO_POWER_ACTIVE_HIGH": 1}
    main_c = (FW / "Core" / "Src" / "main.c").read_text()
    gpio_init = main_c[main_c.index("static void MX_GPIO_Init(void)\n{"):]
    write = re.search(r"HAL_GPIO_WritePin\([^;]*SERVO_PWR_Pin[^;]*GPIO_PIN_RESET\);", gpio_init)
    config_pin = re.search(r"GPIO_InitStruct.Pin = SERVO_PWR_Pin;", gpio_init)
    assert write and config_pin and write.start() < config_pin.start(), \
        "the low level must be written before the pin becomes an output"
    # the application is started only in USER CODE sections, after every peripheral
    user2 = main_c[main_c.index("/* USER CODE BEGIN 2 */"):main_c.index("/* USER CODE END 2 */")]
    assert "app_init(" in user2
    user3 = main_c[main_c.index("/* USER CODE BEGIN 3 */"):main_c.index("/* USER CODE END 3 */")]
    assert "app_poll(" in user3
    # faults (board_fault: supply off, recorded; tests/test_board_guard.py) and Error_Handler cut the supply
    it_c = (FW / "Core" / "Src" / "stm32f4xx_it.c").read_text()
    for handler in ("NMI_Handler", "HardFault_Handler", "MemManage_Handler", "BusFault_Handler",
                    "UsageFault_Handler"):
        body = it_c[it_c.index(f"void {handler}(void)"):]
        assert body.index("board_fault();") < body.index("while (1)"), handler
    err = main_c[main_c.index("void Error_Handler(void)"):]
    assert err.index("board_stop();") < err.index("while (1)")   # supply off first (test_board_guard.py)


# ------------------------------------------------------------------ command-line build

def make(*args, check=True):
    return subprocess.run(["make", "-C", str(FW), *args], capture_output=True, text=True, check=check)


def test_make_check_compiles_every_firmware_source_for_cortex_m4(tmp_path):
    """Warnings are errors; the HAL-using files against ci/hal_decls (declarations only).
    Prints the code and RAM size of the objects."""
    require_arm_toolchain()
    build = tmp_path / "build"
    out = make("check", f"BUILD={build}").stdout
    print(out.splitlines()[-1])
    objs = sorted(build.rglob("*.o"))
    stems = sorted(p.stem for p in objs)
    assert stems == sorted(Path(s).stem for s in firmware.source_lists()["FIRMWARE_SOURCES"])
    undefined = subprocess.run(["arm-none-eabi-nm", "-u", *map(str, objs)], capture_output=True,
                               text=True, check=True).stdout
    assert not re.search(r"\b__aeabi_d\w+", undefined), "double-precision arithmetic on the target"


def test_hal_decls_catch_a_wrong_hal_call(tmp_path):
    """The check is not vacuous: a HAL call with a wrong argument type fails it."""
    require_arm_toolchain()
    bad = tmp_path / "bad.c"
    bad.write_text('#include "main.h"\nvoid f(void) { HAL_GPIO_WritePin(GPIOA, LED0_Pin, 1.0f); '
                   'HAL_UART_Transmit_IT(&huart1, 3, 1); }\n')
    flags = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard",
             "-mfpu=fpv4-sp-d16", "-I", str(FW / "ci" / "hal_decls")]
    flags += [f"-I{FW / d}" for d in firmware.source_lists()["FIRMWARE_INCLUDES"]]
    proc = subprocess.run(["arm-none-eabi-gcc", *flags, "-c", str(bad), "-o", str(tmp_path / "bad.o")],
                          capture_output=True, text=True)
    assert proc.returncode != 0 and "HAL_UART_Transmit_IT" in proc.stderr


def test_board_port_refuses_a_hal_crystal_other_than_the_board_setting(tmp_path):
    require_arm_toolchain()
    proc = make("check", f"BUILD={tmp_path}", "DEFS=-DUSE_HAL_DRIVER -DSTM32F411xE -DHSE_VALUE=25000000U",
                check=False)
    assert proc.returncode != 0 and "board_hse_value_matches_hal" in proc.stderr


def test_make_without_stm32cubef4_says_where_to_get_it(tmp_path):
    if shutil.which("make") is None:
        skip_unless_ci("make", "apt-get install make")
    proc = make(f"BUILD={tmp_path}", check=False)
    assert proc.returncode != 0
    assert "STM32CUBE_F4" in proc.stdout and "github.com/STMicroelectronics/STM32CubeF4" in proc.stdout
    real_rules = (FW / "Makefile").read_text().split("# ---------------------------------------------------------------- without STM32CubeF4")[0]
    assert "-Ici/hal_decls" not in real_rules, "the CI declarations must never reach the real build"


def test_bus_clocks_give_the_model_baud_and_fast_mode_i2c():
    """RM0383 19.3.4: USARTDIV = f_PCLK / (16 x baud) at 16x oversampling, stored as a
    12-bit mantissa and 4-bit fraction; USART1 is on APB2. I2C fast mode needs PCLK1 of
    at least 4 MHz (RM0383 18.6.2, FREQ field)."""
    k = ioc()
    m = config.load()
    pclk2 = int(k["RCC.APB2Freq_Value"])
    usartdiv = Fraction(pclk2, 16 * m.servo_baud)
    brr = round(usartdiv * 16)                      # what the HAL programs, in 1/16 steps
    actual = Fraction(pclk2, brr)
    assert abs(actual / m.servo_baud - 1) < Fraction(1, 100), "servo baud off by 1 % or more"
    assert 1 <= brr >> 4 <= 0xFFF
    assert int(k["RCC.APB1Freq_Value"]) >= 4 * MHZ


def standin_cube_tree(root: Path):
    """An STM32CubeF4-shaped tree whose headers are ci/hal_decls and whose sources are empty
    weak functions of the declared prototypes: enough to run the Makefile's real build
    (paths, flags, linker script, objcopy), with nothing of ST's code. Every file the
    Makefile takes from STM32CUBE_F4 exists."""
    decls = FW / "ci" / "hal_decls"
    hal = root / "Drivers" / "STM32F4xx_HAL_Driver"
    dev = root / "Drivers" / "CMSIS" / "Device" / "ST" / "STM32F4xx"
    usb = root / "Middlewares" / "ST" / "STM32_USB_Device_Library"
    for d in (hal / "Inc" / "Legacy", hal / "Src", dev / "Include", dev / "Source" / "Templates" / "gcc",
              root / "Drivers" / "CMSIS" / "Include", usb / "Core" / "Inc", usb / "Core" / "Src",
              usb / "Class" / "CDC" / "Inc", usb / "Class" / "CDC" / "Src"):
        d.mkdir(parents=True, exist_ok=True)
    for header in sorted(decls.glob("*.h")):
        target = {"stm32f4xx.h": dev / "Include", "usbd_def.h": usb / "Core" / "Inc",
                  "usbd_core.h": usb / "Core" / "Inc", "usbd_cdc.h": usb / "Class" / "CDC" / "Inc"}
        shutil.copy(header, target.get(header.name, hal / "Inc"))
    (hal / "Src" / "stm32f4xx_hal.c").write_text(weak_stubs(decls) + "USBD_ClassTypeDef USBD_CDC;\n")
    modules = re.search(r"CUBE_MODULES := (.*?)\n\S", (FW / "Makefile").read_text(), re.S).group(1)
    for module in modules.replace("\\", " ").split():
        (hal / "Src" / f"stm32f4xx_{module}.c").touch(exist_ok=True)
    (dev / "Source" / "Templates" / "system_stm32f4xx.c").write_text("void SystemInit(void) { }\n")
    (dev / "Source" / "Templates" / "gcc" / "startup_stm32f411xe.s").write_text(st_startup.text())
    for src in ("Core/Src/usbd_core.c", "Core/Src/usbd_ctlreq.c", "Core/Src/usbd_ioreq.c", "Class/CDC/Src/usbd_cdc.c"):
        (usb / src).touch()
    return root


def test_command_line_build_links_elf_bin_hex(tmp_path):
    """`make STM32CUBE_F4=...` end to end against a stand-in tree (see standin_cube_tree):
    every listed source compiles with -Werror and links with the linker script into an
    .elf whose vector table starts the flash, plus .bin and .hex. The tree is given relative
    to where make started, as a shell runs `make -C firmware_stm32 STM32CUBE_F4=cube` from the
    folder that holds cube/ (the shell's PWD is where make started)."""
    require_arm_toolchain()
    standin_cube_tree(tmp_path / "cube")
    build = tmp_path / "build"
    proc = subprocess.run(["bash", "-c", f"cd {tmp_path} && make -C {FW} STM32CUBE_F4=cube BUILD={build}"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    elf, binary, hexfile = (build / f"manipulator.{ext}" for ext in ("elf", "bin", "hex"))
    assert elf.exists() and binary.exists() and hexfile.exists()
    symbols = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    for name in ("main", "Reset_Handler"):
        assert re.search(rf" [TW] {name}$", symbols, re.M), name
    # the application, the board port and the generated code linked in: their compile units in
    # the debug information (link-time optimisation inlines app_init and the like, leaving no
    # symbol of their own)
    info = subprocess.run(["arm-none-eabi-readelf", "--debug-dump=info", str(elf)], capture_output=True, text=True,
                          check=True).stdout
    units = set(re.findall(r"DW_TAG_compile_unit\)\n(?:.*\n)*?.*DW_AT_name\s*:.*?(\S+)\n", info))
    assert {"App/Src/app.c", "Board/Src/board_port.c", "../generated/kinematics.c"} <= units, sorted(units)
    table = struct.unpack(f"<{st_startup.VECTORS}I", binary.read_bytes()[:4 * st_startup.VECTORS])
    stack, reset = table[:2]
    assert stack == 0x2000_0000 + 128 * 1024                 # _estack: top of the 128 KB SRAM
    address = lambda name: int(re.search(rf"^([0-9a-f]+) [TtWw] {name}$", symbols, re.M).group(1), 16)
    assert reset == address("Reset_Handler") | 1 and 0x0800_0000 <= reset < 0x0808_0000   # thumb, in flash
    # ST's construct as linked: the entries of the handlers the firmware leaves to the start-up
    # file hold Default_Handler | 1, while Default_Handler's own address is even
    default = address("Default_Handler")
    unused = [n for n, word in enumerate(table) if word & ~1 == default]
    assert default % 2 == 0 and len(unused) == 54 and {table[n] for n in unused} == {default | 1}
    first = hexfile.read_text().splitlines()[0]
    assert first == ":020000040800F2"                         # Intel HEX: upper address 0x0800
    print(subprocess.run(["arm-none-eabi-size", str(elf)], capture_output=True, text=True).stdout)


@pytest.mark.parametrize("configuration", ["Nucleo_Debug", "Nucleo_Release"])
def test_the_nucleo_configurations_build_for_the_target(configuration, tmp_path):
    """The command-line build with exactly the CubeIDE configuration's defined symbols
    (BOARD_HSE_BYPASS=1, and DEBUG in Nucleo_Debug) compiles with warnings as errors and links.
    The clock those symbols program: test_cubemx_regeneration.py."""
    require_arm_toolchain()
    cube = standin_cube_tree(tmp_path / "cube")
    defs = " ".join(f"-D{symbol}" for symbol in cproject_symbols(configuration))
    proc = make(f"STM32CUBE_F4={cube}", f"BUILD={tmp_path / 'build'}", f"DEFS={defs}", check=False)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "-DBOARD_HSE_BYPASS=1" in proc.stdout and (tmp_path / "build" / "manipulator.elf").exists()


# ------------------------------------------------------------------ builds that never mix old and new

def test_an_incomplete_stm32cube_f4_is_refused_before_anything_compiles(tmp_path):
    """A tree without the CMSIS device folder (a clone without --recursive) is named as such."""
    require_arm_toolchain()
    cube = standin_cube_tree(tmp_path / "cube")
    shutil.rmtree(cube / "Drivers" / "CMSIS" / "Device")
    proc = make(f"STM32CUBE_F4={cube}", f"BUILD={tmp_path / 'build'}", check=False)
    assert proc.returncode != 0
    assert "Drivers/CMSIS/Device/ST/STM32F4xx/Include" in proc.stdout
    assert "startup_stm32f411xe.s" in proc.stdout
    assert not list((tmp_path / "build").rglob("*.o"))


def includers_of(header: str, fw: Path) -> set[str]:
    """Stems of the firmware sources that include header, directly or through other
    headers: `#include "..."` lines followed through the source's own folder and the
    include folders of sources.mk (and ci/hal_decls, as `make check` compiles)."""
    lists = firmware.source_lists()
    dirs = [fw / d for d in lists["FIRMWARE_INCLUDES"]] + [fw / "ci" / "hal_decls"]

    def closure(path, seen):
        for name in re.findall(r'^\s*#\s*include\s+"([^"]+)"', path.read_text(), re.M):
            found = next((d / name for d in [path.parent] + dirs if (d / name).exists()), None)
            if found and found.resolve() not in seen:
                seen.add(found.resolve())
                closure(found, seen)
        return seen

    return {Path(src).stem for src in lists["FIRMWARE_SOURCES"]
            if any(p.name == header for p in closure(fw / src, set()))}


def objects(build: Path) -> dict[str, int]:
    return {o.stem: o.stat().st_mtime_ns for o in build.rglob("*.o")}


def age(*folders: Path):
    """Every file in folders (sources, headers, objects) an hour old, so that a rebuild
    shows in an object's time stamp and only what a test touches is newer."""
    t = time.time() - 3600
    for folder in folders:
        for f in folder.rglob("*"):
            os.utime(f, (t, t))


def test_objects_follow_their_headers_and_the_board_settings(tmp_path):
    """A regenerated model_params.h rebuilds exactly the objects that include it; a board
    setting given after a first build (HSE_BYPASS=1) rebuilds what it compiles into;
    nothing is rebuilt when nothing changed."""
    require_arm_toolchain()
    fw, build = tmp_path / "firmware_stm32", tmp_path / "build"
    shutil.copytree(FW, fw, ignore=shutil.ignore_patterns("build", "Debug", "Release"))
    shutil.copytree(ROOT / "generated", tmp_path / "generated")
    run = lambda *args: subprocess.run(["make", "-C", str(fw), "check", f"BUILD={build}", *args],
                                       capture_output=True, text=True, check=True).stdout
    run()
    age(fw, tmp_path / "generated", build)
    before = objects(build)
    (tmp_path / "generated" / "model_params.h").touch()
    run()
    rebuilt = {name for name, t in objects(build).items() if t != before[name]}
    expected = includers_of("model_params.h", fw)
    assert {"app", "servo_bus", "stabiliser", "imu_mpu6050", "servo_track", "main"} <= expected
    assert rebuilt == expected
    assert " -c " not in run(), "a second build with nothing changed compiled something"
    age(fw, tmp_path / "generated", build)
    before = objects(build)
    run("HSE_BYPASS=1")
    rebuilt = {name for name, t in objects(build).items() if t != before[name]}
    assert "board_clock" in rebuilt and includers_of("board_config.h", fw) <= rebuilt
    assert " -c " not in run("HSE_BYPASS=1")
