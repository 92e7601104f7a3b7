"""Cortex-M4F instruction counts and estimated cycles of one C function call.

The C is cross-compiled and linked with newlib's libm (image.py), one call runs in the
unicorn emulator's Cortex-M4 model (emulate.py), and every instruction it executes is
priced with the cost table of the Cortex-M4 Technical Reference Manual (costs.py). The
counts are deterministic: the same code and inputs give the same figures on any machine,
however loaded. Cycles are an estimate at zero flash wait states, without interrupts.

    from uavarm import m4
    image = m4.build(["fk.c"], ["fk"], cflags=["-Iinclude"])
    r = image.call("fk", [m4.Arr("float", [0.1, 0.2, 0.3]), m4.Arr("float", 3)], ret="void")
    r.insns, r.cycles, r.arrays[1], r.cycles_by_function, r.func_bytes, r.stack_bytes

Arguments: a Python float is a float, an int an int32, `U32(x)` a uint32, `F64(x)` a double,
`Arr(type, values or length)` a pointer to an array in emulated RAM, read back after the
call into `Result.arrays` (one entry per argument, None for the scalars).
"""
from .emulate import Arr, F64, U32, Result
from .image import Image, ToolError, build

__all__ = ["Arr", "F64", "U32", "Image", "Result", "ToolError", "build"]
