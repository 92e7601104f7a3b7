"""A linked Cortex-M4F program image: compile and link C (or assembly) with the GNU Arm
toolchain and newlib, and read back what the emulator and the cost table need: the loadable
segments, the function symbols with their sizes and every instruction's disassembly."""
from __future__ import annotations

import bisect
import re
import struct
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from . import costs

CPU_FLAGS = ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"]
# No startup files: the emulator loads .data in place and RAM starts zeroed, which is the
# state a startup file leaves behind. newlib-nano with the nosys stubs; libm last.
LINK_FLAGS = ["-nostartfiles", "--specs=nano.specs", "--specs=nosys.specs", "-Wl,--gc-sections"]
LIBS = ["-lm"]

FLASH, FLASH_SIZE = 0x0800_0000, 512 * 1024     # STM32F411RE
RAM, RAM_SIZE = 0x2000_0000, 128 * 1024

# .data is linked at its RAM address (no load address in flash): loading the segments
# initialises it directly.
LINKER_SCRIPT = f"""
MEMORY {{
  FLASH (rx) : ORIGIN = {FLASH:#x}, LENGTH = {FLASH_SIZE}
  RAM (rwx)  : ORIGIN = {RAM:#x}, LENGTH = {RAM_SIZE}
}}
SECTIONS {{
  .text : {{ *(.text .text.*) *(.rodata .rodata.*) }} > FLASH
  .ARM.exidx : {{ *(.ARM.exidx .ARM.exidx.*) }} > FLASH
  .data : {{ *(.data .data.*) }} > RAM
  .bss : {{ *(.bss .bss.* COMMON) }} > RAM
  end = ALIGN(8);
}}
"""

# "8000010:	f8d0 3004 	ldr.w	r3, [r0, #4]	@ comment"
_DISASM = re.compile(r"^\s*([0-9a-f]+):\t([0-9a-f ]+?)\s*\t(\S+)\s*([^@;<]*)")


class ToolError(RuntimeError):
    """A toolchain command failed; the message carries its output."""


def _run(cmd) -> str:
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    except FileNotFoundError:
        raise ToolError(f"{cmd[0]} not found: the Cortex-M4 figures need the GNU Arm toolchain "
                        "(Debian: apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi)") from None
    if proc.returncode != 0:
        raise ToolError(f"{' '.join(map(str, cmd))}\n{proc.stdout}{proc.stderr}")
    return proc.stdout


@dataclass(frozen=True)
class Function:
    name: str
    addr: int
    size: int


class Image:
    """The ELF of one link, decoded once; `call` runs one of its functions."""

    def __init__(self, elf: Path):
        self.elf = Path(elf)
        data = self.elf.read_bytes()
        self.segments = _load_segments(data)
        self.end = max((addr + size for addr, _, size in self.segments if addr >= RAM), default=RAM)
        self.functions: dict[str, Function] = {}
        self.symbols: dict[str, int] = {}      # every defined symbol's address (nm: no Thumb bit)
        for line in _run(["arm-none-eabi-nm", "-S", "--defined-only", self.elf]).splitlines():
            parts = line.split()
            if len(parts) >= 3:
                self.symbols.setdefault(parts[-1], int(parts[0], 16))
            if len(parts) == 4 and parts[2] in "tTwW":
                f = Function(parts[3], int(parts[0], 16) & ~1, int(parts[1], 16))
                self.functions.setdefault(f.name, f)
        self._starts = sorted((f.addr, f.name) for f in self.functions.values())
        self.insns: dict[int, costs.Insn] = {}
        for line in _run(["arm-none-eabi-objdump", "-d", self.elf]).splitlines():
            m = _DISASM.match(line)
            if m:
                addr = int(m.group(1), 16)
                size = len(m.group(2).replace(" ", "")) // 2
                self.insns[addr] = costs.Insn(addr, size, m.group(3), m.group(4).strip())

    def function_at(self, addr: int) -> str:
        i = bisect.bisect_right(self._starts, (addr, "\uffff")) - 1
        if i >= 0:
            f = self.functions[self._starts[i][1]]
            if f.addr <= addr < f.addr + max(f.size, 2):
                return f.name
        return "?"

    def read(self, addr: int, size: int) -> bytes:
        """size bytes at addr as the image loads them (zeros where a segment has no file bytes)."""
        for start, data, memsz in self.segments:
            if start <= addr and addr + size <= start + memsz:
                return (data + bytes(memsz - len(data)))[addr - start:addr - start + size]
        raise ValueError(f"{addr:#x}+{size} is not in one loaded segment")

    def call(self, func: str, args=(), ret: str = "float", max_insns: int = 20_000_000, setup=None):
        """Run func(*args) once; see emulate.call."""
        from . import emulate
        return emulate.call(self, func, args, ret, max_insns, setup)


def _load_segments(data: bytes) -> list[tuple[int, bytes, int]]:
    """(address, file bytes, memory size) of each PT_LOAD segment of a 32-bit little-endian ELF."""
    if data[:6] != b"\x7fELF\x01\x01":
        raise ToolError("not a 32-bit little-endian ELF")
    phoff, = struct.unpack_from("<I", data, 28)
    phentsize, phnum = struct.unpack_from("<HH", data, 42)
    segments = []
    for i in range(phnum):
        ptype, offset, vaddr, _paddr, filesz, memsz = struct.unpack_from("<6I", data, phoff + i * phentsize)
        if ptype == 1 and memsz:
            segments.append((vaddr, data[offset:offset + filesz], memsz))
    return segments


def build(sources, funcs, cflags=(), workdir: Path | None = None) -> Image:
    """Compile and link `sources` (C or .S) for the Cortex-M4F at -O2 (a later -O in cflags
    wins) and keep `funcs` and whatever they reach. The ELF stays in `workdir` if one is
    given; otherwise it is built in a temporary folder, removed once decoded."""
    if workdir is None:
        with tempfile.TemporaryDirectory(prefix="uavarm-m4-") as tmp:
            return build(sources, funcs, cflags, Path(tmp))
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    script = workdir / "m4.ld"
    script.write_text(LINKER_SCRIPT)
    elf = workdir / "m4.elf"
    _run(["arm-none-eabi-gcc", "-O2", *CPU_FLAGS, "-ffunction-sections", "-fdata-sections", *cflags,
          *map(str, sources), *LINK_FLAGS, "-T", script, *[f"-Wl,--undefined={f}" for f in funcs],
          "-Wl,--entry=0", "-o", elf, *LIBS])
    image = Image(elf)
    missing = [f for f in funcs if f not in image.functions]
    if missing:
        raise ToolError(f"not in the linked image: {', '.join(missing)}")
    return image
