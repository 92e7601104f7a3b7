"""The board's guard (firmware_stm32/Board/Src/board_guard.c) on the host, over test doubles of
the HAL (tests/csrc/fake_hal.c) and of the system registers and the startup file's vector
table (tests/csrc/fake_guard.c).

Oracles: RM0383 (RCC_CSR reset flags 6.3.21; a power-on reset also sets BORRSTF and PINRSTF,
every internal reset PINRSTF; IWDG keys 0xCCCC start, 0x5555 unlock, 0xAAAA reload, timeout
= 4 * 2^PR * (RLR + 1) / f_LSI, 17.3), ARMv7-M (ICSR.VECTACTIVE is the active exception
number; VTOR needs the table's size rounded up to a power of two as alignment; an exception
entry branches to the vector, which must carry the Thumb bit), the pin map (servo supply on
PA8, high = on), the heartbeat's reset cause names, and ST's start-up file as it is linked
(tests/st_startup.py: a plain Default_Handler label, every handler a .thumb_set alias of it).
"""
import struct

import pytest

import st_startup
from conftest import ROOT, require_arm_toolchain
from test_stm32_project import c_defines
from hal_stubs import weak_stubs
from uavarm import m4
from uavarm.build import cbuild, firmware, target
from uavarm.link.messages import RESET_CAUSES, fault_vector_name

FW = firmware.FIRMWARE
CSRC = ROOT / "tests" / "csrc"
CAUSE = {name: k for k, (name, _) in enumerate(RESET_CAUSES)}
BORRST, PINRST, PORRST, SFTRST, IWDGRST, WWDGRST, LPWRRST = (1 << b for b in range(25, 32))
RMVF = 1 << 24
SERVO_PWR = (0, 8)                       # PA8
LSI_HZ = 32_000                          # nominal; 17-47 kHz


def build_guard(*defines):
    lists = firmware.source_lists()
    sources = [FW / "Board" / "Src" / "board_guard.c", FW / "Board" / "Src" / "board_port.c",
               CSRC / "fake_hal.c", CSRC / "fake_guard.c"] + [FW / p for p in lists["BOARD_LOGIC_SOURCES"]]
    includes = [FW / "ci" / "hal_decls"] + [FW / d for d in lists["FIRMWARE_INCLUDES"]] + [CSRC]
    headers = [FW / "App" / "Inc" / "port.h", FW / "Board" / "Inc" / "board_port.h",
               FW / "Board" / "Inc" / "board_guard.h", CSRC / "fake_hal.h", CSRC / "fake_guard.h"]
    return cbuild.load("board_guard", sources, headers, include_dirs=includes,
                       extra_flags=["-pthread", "-DBOARD_HALT=fake_halt", *defines])


@pytest.fixture(scope="module")
def built():
    return build_guard()


@pytest.fixture
def guard(built):
    ffi, lib = built
    lib.fake_reset()
    lib.fake_guard_reset()
    port = lib.board_port_start()
    # as the firmware's: its own handlers (reset, the five faults, SVC, DebugMon, PendSV, SysTick,
    # TIM3, USART1, OTG_FS), the reserved entries 0, every other interrupt Default_Handler
    for i in range(lib.FAKE_VECTORS):
        lib.g_pfnVectors[i] = lib.Default_Handler
    for used in (1, 2, 3, 4, 5, 6, 11, 12, 14, 15, 16 + 29, 16 + 37, 16 + 67):
        lib.g_pfnVectors[used] = lib.fake_used_handler
    for reserved in (0, 7, 8, 9, 10, 13):
        lib.g_pfnVectors[reserved] = ffi.NULL
    return ffi, lib, port


def start(lib, csr):
    lib.fake_guard_set(b"CSR", csr)
    reset = lib.board_guard_start()
    assert lib.fake_guard_get(b"CSR") & RMVF, "the flags are cleared for the next reset"
    return reset.cause, reset.fault


@pytest.mark.parametrize("flags, cause", [
    (PORRST | BORRST | PINRST, "power_on"), (BORRST | PINRST, "brown_out"), (IWDGRST | PINRST, "watchdog"),
    (WWDGRST | PINRST, "window_watchdog"), (LPWRRST | PINRST, "low_power"), (SFTRST | PINRST, "software"),
    (PINRST, "pin"), (0, "unknown")])
def test_the_reset_cause_is_the_most_specific_flag(guard, flags, cause):
    assert start(guard[1], flags) == (CAUSE[cause], 0)


def test_the_watchdog_runs_250_ms_and_is_fed_by_the_reload_key(guard):
    lib = guard[1]
    start(lib, PINRST)
    timeout = 4 * 2 ** lib.fake_guard_get(b"PR") * (lib.fake_guard_get(b"RLR") + 1) / LSI_HZ
    assert timeout == pytest.approx(0.250) and lib.fake_guard_get(b"KR") == 0xAAAA
    lib.fake_guard_set(b"KR", 0)
    lib.board_watchdog_feed()
    assert lib.fake_guard_get(b"KR") == 0xAAAA


@pytest.mark.parametrize("debug", [False, True], ids=["release", "debug"])
def test_debug_builds_stop_the_watchdog_while_a_debugger_halts_the_core(debug):
    """DBGMCU_APB1_FZ.DBG_IWDG_STOP (RM0383, bit 12) set by the start in a build with DEBUG
    defined (CubeIDE's Debug configurations), left clear otherwise (the flight build)."""
    ffi, lib = build_guard(*(["-DDEBUG"] if debug else []))
    lib.fake_reset()
    lib.fake_guard_reset()
    lib.board_port_start()
    start(lib, PINRST)
    assert bool(lib.fake_guard_get(b"APB1FZ") & 1 << 12) == debug
    assert lib.fake_guard_get(b"APB1FZ") & ~(1 << 12) == 0


def test_a_stop_cuts_the_supply_lights_both_leds_and_leaves_the_watchdog_running(guard):
    """board_stop, Error_Handler's, on a board whose start-up stopped before its pins and its
    watchdog were set up (the external clock at boot): PA8 an output driven low, PA5 and PA6
    (LD2, LED1) outputs driven high, interrupts off, the watchdog started with its 250 ms and
    loaded, halted."""
    lib = guard[1]
    lib.fake_reset()
    lib.fake_guard_reset()
    halts = lib.fake_halts
    lib.board_stop()
    supply, leds = 1 << 8, 1 << 5 | 1 << 6
    assert lib.fake.outputs[0] == supply | leds and lib.fake.odr[0] == leds
    assert lib.fake_irq_disabled and lib.fake_halts == halts + 1
    timeout = 4 * 2 ** lib.fake_guard_get(b"PR") * (lib.fake_guard_get(b"RLR") + 1) / LSI_HZ
    assert timeout == pytest.approx(0.250) and lib.fake_guard_get(b"KR") == 0xAAAA


def test_every_unused_interrupt_cuts_the_servo_supply_and_is_recorded_over_the_reset(guard):
    ffi, lib, port = guard
    dsbs = lib.fake_dsbs
    start(lib, PORRST | BORRST | PINRST)
    vtor = lib.fake_guard_get(b"VTOR")
    table = int(ffi.cast("uintptr_t", lib.board_ram_vectors))
    assert vtor == table & 0xFFFFFFFF and table % 512 == 0 and lib.fake_dsbs == dsbs + 1
    unused = [n for n in range(lib.FAKE_VECTORS) if lib.g_pfnVectors[n] == lib.Default_Handler]
    assert len(unused) == 102 - 19
    assert all(lib.board_ram_vectors[n] == lib.g_pfnVectors[n] for n in range(102) if n not in unused)
    for n in unused:
        port.servo_power(port.ctx, True)
        assert lib.fake.odr[0] >> 8 & 1
        halts = lib.fake_halts
        lib.fake_guard_dispatch(n)
        assert lib.board_ram_vectors[n] != lib.Default_Handler
        assert lib.fake_halts == halts + 1 and not lib.fake.odr[0] >> 8 & 1, fault_vector_name(n)
        assert start(lib, IWDGRST | PINRST) == (CAUSE["watchdog"], n)   # the watchdog's reset
        assert start(lib, PINRST) == (CAUSE["pin"], 0)                   # reported once


def test_a_fault_handler_records_its_exception(guard):
    ffi, lib, port = guard
    start(lib, PINRST)
    port.servo_power(port.ctx, True)
    assert lib.fake.odr[0] >> 8 & 1
    halts = lib.fake_halts
    lib.fake_guard_set(b"ICSR", 3)              # HardFault active
    lib.board_fault()
    assert not lib.fake.odr[0] >> 8 & 1 and lib.fake_halts == halts + 1
    assert fault_vector_name(start(lib, IWDGRST | PINRST)[1]) == "HardFault"


def test_a_fault_before_the_start_still_ends_in_the_watchdogs_reset(guard):
    """A fault in the start-up before board_guard_start (the clock set-up, say) starts the
    watchdog itself with its 250 ms, so the halt ends in a reset, and the next start names
    the fault."""
    lib = guard[1]
    lib.fake_reset()
    lib.fake_guard_reset()
    lib.fake_guard_set(b"ICSR", 3)              # HardFault active
    lib.board_fault()
    timeout = 4 * 2 ** lib.fake_guard_get(b"PR") * (lib.fake_guard_get(b"RLR") + 1) / LSI_HZ
    assert timeout == pytest.approx(0.250) and lib.fake_guard_get(b"KR") == 0xAAAA
    assert fault_vector_name(start(lib, IWDGRST | PINRST)[1]) == "HardFault"


@pytest.mark.parametrize("exception, reported", [(255, 255), (256, 0), (511, 0)])
def test_a_record_is_reported_only_if_its_exception_fits_the_heartbeats_byte(guard, exception, reported):
    """ICSR.VECTACTIVE is 9 bits; the heartbeat names the last fault in one byte. A record
    whose number does not fit is not this chip's (it has 102 vectors): nothing is reported
    rather than its low byte."""
    lib = guard[1]
    start(lib, PINRST)
    lib.fake_guard_set(b"ICSR", exception)
    lib.board_fault()
    assert start(lib, IWDGRST | PINRST) == (CAUSE["watchdog"], reported)


@pytest.mark.parametrize("flags, cause", [(PORRST | BORRST | PINRST, "power_on"), (BORRST | PINRST, "brown_out")],
                         ids=["power_on", "brown_out"])
def test_a_record_left_in_ram_is_not_this_runs_fault_after_power_was_lost(guard, flags, cause):
    """A brown-out, like a power-on, means the RAM the record sits in lost its supply: what
    it holds is not the last run's fault, even when it reads as a valid record (here the
    record the NMI of the clock security system left, as RAM that kept its content would
    show it). Nor is it reported after the next reset."""
    lib = guard[1]
    start(lib, PINRST)
    lib.fake_guard_set(b"ICSR", 2)
    lib.board_fault()
    assert start(lib, flags) == (CAUSE[cause], 0)
    assert start(lib, IWDGRST | PINRST) == (CAUSE["watchdog"], 0)


# ------------------------------------------------------------------ on the Cortex-M4, with ST's start-up file

USED_IRQS = {"TIM3_IRQHandler", "USART1_IRQHandler", "OTG_FS_IRQHandler"}   # Core/Src/stm32f4xx_it.c


@pytest.fixture(scope="module", params=[False, True], ids=["st_startup", "thumb_func_default_handler"])
def m4_guard(request, tmp_path_factory):
    """board_guard.c cross-compiled with the project's flags and linked with a start-up file
    built as ST's (or, second, one whose Default_Handler is a .thumb_func), the firmware's
    interrupt handlers and the port's supply switch; run in the Cortex-M4 emulation."""
    require_arm_toolchain()
    tmp = tmp_path_factory.mktemp("m4_guard")
    startup = tmp / "startup_stm32f411xe.s"
    startup.write_text(st_startup.text(thumb_func_default_handler=request.param))
    stubs = tmp / "hal_stubs.c"
    stubs.write_text(weak_stubs(FW / "ci" / "hal_decls"))
    lists = firmware.source_lists()
    sources = [FW / "Board" / "Src" / "board_guard.c", FW / "Board" / "Src" / "board_port.c",
               FW / "Core" / "Src" / "stm32f4xx_it.c", CSRC / "m4_guard.c", stubs, startup]
    sources += [FW / p for p in lists["BOARD_LOGIC_SOURCES"]]
    includes = [FW / "ci" / "hal_decls"] + [FW / d for d in lists["FIRMWARE_INCLUDES"]]
    cflags = target.M4_CFLAGS + ["-Wno-unused-parameter",   # the generated weak stubs
                                 "-DUSE_HAL_DRIVER", "-DSTM32F411xE", "-DHSE_VALUE=8000000U",
                                 "-DBOARD_HALT=guard_halt", "-Wl,--defsym=_estack=0x20020000"]
    cflags += [f"-I{d}" for d in includes]
    return m4.build(sources, ["guard_start", "guard_dispatch"], cflags, workdir=tmp)


def test_with_st_startup_every_unused_vector_is_replaced_and_cuts_the_supply(m4_guard):
    """The table the start-up file links (read from the image): the entries of the handlers
    the firmware does not define hold Default_Handler's address, with the Thumb bit that
    .thumb_set gives them; after board_guard_start each of those, and no other, points to the
    guard's handler (Thumb bit set), VTOR to the table in RAM; each of them taken as an
    exception cuts the supply, halts, and is the fault reported after the watchdog's reset."""
    image = m4_guard
    symbols, names = image.symbols, [None] + st_startup.handler_names()
    default = symbols["Default_Handler"] & ~1
    table = list(struct.unpack(f"<{st_startup.VECTORS}I",
                               image.read(symbols["g_pfnVectors"], 4 * st_startup.VECTORS)))
    unused = [n for n in range(1, st_startup.VECTORS) if table[n] & ~1 == default]
    assert {names[n] for n in unused} == {name for name in names[16:] if name} - USED_IRQS
    assert len(unused) == 54 and {table[n] for n in unused} == {default | 1}
    out = image.call("guard_start", [m4.U32(PINRST), m4.Arr("uint32", 4 + st_startup.VECTORS)], ret="void").arrays[1]
    ram = out[4:]
    assert out[:4] == [CAUSE["pin"], 0, symbols["board_ram_vectors"], 0]
    assert [ram[n] for n in unused] == [symbols["unused_interrupt"] | 1] * len(unused)
    assert [ram[n] for n in range(st_startup.VECTORS) if n not in unused] == \
        [table[n] for n in range(st_startup.VECTORS) if n not in unused]
    out = image.call("guard_dispatch", [m4.Arr("uint32", unused), len(unused), m4.Arr("uint32", 3 * len(unused))],
                     ret="void").arrays[2]
    for k, n in enumerate(unused):
        assert out[3 * k:3 * k + 3] == [0, 1, n], f"{names[n]}: supply, halts, fault reported"


class WatchdogRegisters:
    """The IWDG as RM0383 17.3-17.4 describes it, on the emulated bus: 0x5555 in KR opens PR
    and RLR to writing, any other key closes them; a write to an open PR or RLR sets PVU or
    RVU in SR until the value has crossed into the LSI's domain, here for `busy_reads` reads
    of SR (None: it never crosses). `log` holds every write and SR read, in order."""
    NAMES = {0: "KR", 4: "PR", 8: "RLR"}

    def __init__(self, base: int, busy_reads: int | None):
        self.base, self.busy_reads = base, busy_reads
        self.log, self.writable, self.pending, self.left = [], False, 0, 0

    def setup(self, uc):
        from unicorn import UC_HOOK_MEM_READ, UC_HOOK_MEM_WRITE
        uc.hook_add(UC_HOOK_MEM_WRITE, self._write, begin=self.base, end=self.base + 11)
        uc.hook_add(UC_HOOK_MEM_READ, self._read_sr, begin=self.base + 12, end=self.base + 15)

    def _write(self, uc, access, address, size, value, data):
        name = self.NAMES[address - self.base]
        self.log.append((name, value))
        if name == "KR":
            self.writable = value == 0x5555
        elif self.writable:
            self.pending |= 1 if name == "PR" else 2      # PVU, RVU
            self.left = self.busy_reads

    def _read_sr(self, uc, access, address, size, value, data):
        if self.left is None or self.left > 0:
            self.left = None if self.left is None else self.left - 1
        else:
            self.pending = 0
        uc.mem_write(address, struct.pack("<I", self.pending))   # what the load then reads
        self.log.append(("SR", self.pending))


@pytest.mark.parametrize("m4_guard", [False], ids=["st_startup"], indirect=True)
def test_the_watchdog_is_loaded_only_once_its_settings_are_taken_and_the_wait_is_bounded(m4_guard):
    """As HAL_IWDG_Init: start, unlock, prescaler and reload (250 ms at LSI / 32), then the
    status read until PVU and RVU are clear, and only then the reload key. Settings never
    taken: BOARD_WATCHDOG_UPDATE_POLLS reads, no reload key, Error_Handler; the run returns."""
    image = m4_guard
    polls = c_defines(FW / "Board" / "Inc" / "board_config.h", "BOARD_WATCHDOG_UPDATE_POLLS")["BOARD_WATCHDOG_UPDATE_POLLS"]
    iwdg = WatchdogRegisters(image.symbols["ci_iwdg"], busy_reads=3)
    out = image.call("guard_start", [m4.U32(PINRST), m4.Arr("uint32", 4 + st_startup.VECTORS)], ret="void",
                     setup=iwdg.setup).arrays[1]
    settings = [("KR", 0xCCCC), ("KR", 0x5555), ("PR", 3), ("RLR", 249)]
    assert iwdg.log == settings + [("SR", 3)] * 3 + [("SR", 0), ("KR", 0xAAAA)] and out[3] == 0
    assert 4 * 2 ** 3 * 250 / LSI_HZ == pytest.approx(0.250)
    iwdg = WatchdogRegisters(image.symbols["ci_iwdg"], busy_reads=None)
    r = image.call("guard_start", [m4.U32(PINRST), m4.Arr("uint32", 4 + st_startup.VECTORS)], ret="void",
                   setup=iwdg.setup, max_insns=20 * polls)     # a wait without its bound fails here
    assert iwdg.log == settings + [("SR", 3)] * polls and r.arrays[1][3] == 1
    print(f"a poll of the watchdog's status: {r.cycles_by_function['board_guard_start'] / polls:.2f} est. cycles")
