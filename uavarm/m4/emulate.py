"""One call of a linked function in unicorn's Cortex-M4 model: the arguments placed as the
hard-float procedure call standard (AAPCS-VFP) places them, every executed instruction
traced, priced by the cost table, attributed to its function; the stack it used."""
from __future__ import annotations

import struct
from collections import Counter
from dataclasses import dataclass, field

from . import costs
from .image import FLASH, FLASH_SIZE, RAM, RAM_SIZE, Image

RETURN = 0x0FFF_0000            # the caller's return address: the run stops on reaching it
PAINT = struct.pack("<I", 0x5AC3_3CA5)

_ELEMENTS = {"float": "f", "double": "d", "int32": "i", "uint32": "I", "int16": "h", "uint16": "H",
             "int8": "b", "uint8": "B"}


@dataclass(frozen=True)
class U32:
    value: int


@dataclass(frozen=True)
class F64:
    value: float


class Arr:
    """A pointer argument: an array of `ctype` in emulated RAM, from values or a length (zeros)."""

    def __init__(self, ctype: str, values):
        self.format = "<" + _ELEMENTS[ctype]
        self.values = [0] * values if isinstance(values, int) else list(values)

    def pack(self) -> bytes:
        return b"".join(struct.pack(self.format, v) for v in self.values)

    def unpack(self, data: bytes) -> list:
        return [v for (v,) in struct.iter_unpack(self.format, data)]


@dataclass
class Result:
    func: str
    ret: object                     # None for void
    arrays: list                    # the Arr arguments' contents after the call (None: a scalar)
    insns: int                      # instructions issued (IT-skipped ones included)
    cycles: int                     # estimated cycles (costs.py)
    insns_by_function: dict = field(repr=False)
    cycles_by_function: dict = field(repr=False)
    func_bytes: int                 # code size of the called function
    reached_bytes: int              # code size of every function the call executed
    stack_bytes: int                # stack the call wrote below the caller's stack pointer


def _bits(x: float) -> int:
    return struct.unpack("<I", struct.pack("<f", x))[0]


def _place_arguments(uc, A, args, arrays_at: list, sp: int) -> int:
    """Registers and stacked words of the call; returns the stack pointer at the call."""
    core, single, stacked = [], [None] * 16, b""
    for arg, addr in zip(args, arrays_at):
        if isinstance(arg, float):
            free = next((i for i, s in enumerate(single) if s is None), None)
            if free is None:
                stacked += struct.pack("<f", arg)
            else:
                single[free] = _bits(arg)
        elif isinstance(arg, F64):
            free = next((i for i in range(0, 16, 2) if single[i] is None and single[i + 1] is None), None)
            lo, hi = struct.unpack("<II", struct.pack("<d", arg.value))
            if free is None:
                stacked += b"\0" * (len(stacked) % 8) + struct.pack("<II", lo, hi)
            else:
                single[free:free + 2] = [lo, hi]
        elif isinstance(arg, (Arr, U32, int)):
            word = addr if isinstance(arg, Arr) else (arg.value if isinstance(arg, U32) else arg)
            if len(core) < 4:
                core.append(word & 0xFFFF_FFFF)
            else:
                stacked += struct.pack("<I", word & 0xFFFF_FFFF)
        else:
            raise TypeError(f"argument {arg!r}: a float, an int, U32, F64 or Arr")
    for i, word in enumerate(core):
        uc.reg_write(getattr(A, f"UC_ARM_REG_R{i}"), word)
    for i, word in enumerate(single):
        if word is not None:
            uc.reg_write(getattr(A, f"UC_ARM_REG_S{i}"), word)
    sp = (sp - len(stacked)) & ~7
    uc.mem_write(sp, stacked)
    return sp


def _return_value(uc, A, ret: str):
    r0, s0, s1 = (uc.reg_read(getattr(A, f"UC_ARM_REG_{r}")) for r in ("R0", "S0", "S1"))
    values = {"void": lambda: None,
              "float": lambda: struct.unpack("<f", struct.pack("<I", s0))[0],
              "double": lambda: struct.unpack("<d", struct.pack("<II", s0, s1))[0],
              "int": lambda: struct.unpack("<i", struct.pack("<I", r0))[0],
              "uint32": lambda: r0}
    return values[ret]()


def call(image: Image, func: str, args, ret: str, max_insns: int, setup=None) -> Result:
    """setup(uc), if given, runs before the call: hooks that model a peripheral's registers."""
    from unicorn import UC_ARCH_ARM, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc, UcError
    from unicorn import arm_const as A

    if ret not in ("void", "float", "double", "int", "uint32"):
        raise ValueError(f"return type {ret!r}: one of void, float, double, int, uint32")
    uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
    uc.ctl_set_cpu_model(A.UC_CPU_ARM_CORTEX_M4)      # FPU (CP10, CP11) enabled at reset
    uc.reg_write(A.UC_ARM_REG_FPSCR, 0)               # round to nearest, no flush to zero
    uc.mem_map(FLASH, FLASH_SIZE)
    uc.mem_map(RAM, RAM_SIZE)
    uc.mem_map(RETURN, 0x1000)
    for addr, data, _size in image.segments:
        uc.mem_write(addr, data)

    arrays_at, free = [], (image.end + 15) & ~15        # arrays right after .bss
    for arg in args:
        arrays_at.append(free if isinstance(arg, Arr) else None)
        if isinstance(arg, Arr):
            uc.mem_write(free, arg.pack())
            free = (free + len(arg.pack()) + 15) & ~15
    sp = _place_arguments(uc, A, args, arrays_at, RAM + RAM_SIZE)
    uc.reg_write(A.UC_ARM_REG_SP, sp)
    uc.reg_write(A.UC_ARM_REG_LR, RETURN | 1)

    # Stack painting: the lowest word below the stack pointer that no longer holds the paint
    # is the deepest the call went. (A memory-write hook would be exact but changes what
    # unicorn 2.1 executes.)
    stack_floor = (free + 255) & ~255
    uc.mem_write(stack_floor, PAINT * ((sp - stack_floor) // 4))
    if setup is not None:
        setup(uc)
    trace = []
    uc.hook_add(UC_HOOK_CODE, lambda _uc, addr, _size, _data: trace.append(addr),
                begin=FLASH, end=FLASH + FLASH_SIZE - 1)
    try:
        uc.emu_start(image.functions[func].addr | 1, RETURN, count=max_insns)
    except UcError as e:
        pc = uc.reg_read(A.UC_ARM_REG_PC)
        raise RuntimeError(f"{func}: {e} at {pc:#x} ({image.function_at(pc)}) after {len(trace)} "
                           "instructions") from None
    if uc.reg_read(A.UC_ARM_REG_PC) != RETURN:
        raise RuntimeError(f"{func}: no return within {max_insns} instructions")

    counts, cycles = costs.price(trace, image.insns)
    insns_by, cycles_by = Counter(), Counter()
    for addr, n in counts.items():
        name = image.function_at(addr)
        insns_by[name] += n
        cycles_by[name] += cycles[addr]
    painted = bytes(uc.mem_read(stack_floor, sp - stack_floor))
    deepest = next((i for i in range(0, len(painted), 4) if painted[i:i + 4] != PAINT), len(painted))
    arrays = [arg.unpack(bytes(uc.mem_read(at, len(arg.pack())))) if at is not None else None
              for arg, at in zip(args, arrays_at)]
    return Result(func, _return_value(uc, A, ret), arrays, sum(counts.values()), sum(cycles.values()),
                  dict(insns_by), dict(cycles_by), image.functions[func].size,
                  sum(image.functions[f].size for f in insns_by if f in image.functions), len(painted) - deepest)
