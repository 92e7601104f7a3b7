"""The Cortex-M4F counter (uavarm/m4) on hand-written Thumb-2 snippets whose cycles follow
from the Cortex-M4 Technical Reference Manual: the instruction timings (1-cycle data
processing, MUL 1, SDIV/UDIV 2..12, LDR/STR 2, LDM/STM/PUSH/POP 1+N, branches 1+P), the
load/store pipelining notes with their worked examples, and the FPU timings (VADD/VMUL 1,
VMLA/VFMA 3, VDIV/VSQRT 14, VLDR/VSTR 2, VPUSH/VPOP 1+N). Where the manual gives a range
(P = 1..3, division 2..12) the expected value is the one the counter's table documents.

Every snippet ends in `bx lr`, a branch to a register: 1 + P, P = 2, so 3 cycles; the
expected cycles are the snippet's body plus those 3."""
import struct

import numpy as np
import pytest

from conftest import require_arm_toolchain
from uavarm import m4

RETURN = 3          # bx lr

SNIPPETS = {
    "empty": "",
    # data processing, multiply, bit field: 1 each
    "alu": """movs r1, #1
        add.w r1, r1, #2
        mul r1, r1, r1
        movw r2, #5
        movt r2, #1
        clz r3, r1
        ubfx r3, r2, #1, #3""",
    "divide": """movs r1, #100
        movs r2, #7
        sdiv r3, r1, r2""",
    # single loads apart: 2 each
    "loads_apart": """ldr r2, [r1]
        adds r0, r0, #1
        ldr r3, [r1, #4]""",
    # the manual's examples (registers renamed): "LDR R0,[R1,R5]; LDR R1,[R2]; LDR R2,[R3,#4]
    # normally four cycles total" and "LDR R0,[R1,R2]; STR R0,[R3,#20] normally three"
    "loads_pipelined": """ldr r12, [r1, r0]
        ldr r1, [r2]
        ldr r2, [r3, #4]""",
    "load_store": """ldr r12, [r1, r0]
        str r12, [r3, #20]""",
    # the first load's result forms the second's address: no pipelining, 2 + 2
    "load_dependent": """ldr r12, [r1]
        ldr r0, [r2, r12]""",
    # an address computed by the instruction just before: 1, then 2 + 1 stall
    "address_stall": """adds r1, r1, #4
        ldr r0, [r1]""",
    "multiple": """push {r4, r5, r6, r7}
        ldrd r2, r3, [r1]
        pop {r4, r5, r6, r7}""",
    "fpu": """vadd.f32 s0, s0, s1
        vmul.f32 s0, s0, s1
        vfma.f32 s0, s1, s1
        vmla.f32 s0, s1, s1
        vsqrt.f32 s2, s0
        vdiv.f32 s2, s0, s1
        vmov r12, s0
        vmov s2, s3, r2, r3
        vldr s4, [r1]
        vstr s4, [r1, #4]
        vldr d3, [r1]
        vpush {s16, s17, s18, s19}
        vpop {s16, s17, s18, s19}""",
    "sqrt_div": """vsqrt.f32 s0, s0
        vdiv.f32 s0, s0, s1""",
    # r0 == 0: cmp 1, beq taken to a 16-bit instruction 1 + 1; else cmp, beq 1, three adds
    "branch_short": """cmp r0, #0
        beq 1f
        adds r1, #1
        adds r1, #1
        adds r1, #1
    1:  nop""",
    # a taken branch to a 32-bit instruction on a half-word boundary: P = 1 + 1 (two fetches)
    "branch_unaligned": """cmp.n r0, #0
        beq.n 1f
        nop.n
    1:  add.w r1, r1, #1""",
    "branch_aligned": """cmp.n r0, #0
        beq.n 1f
        nop.n
        nop.n
    1:  add.w r1, r1, #1""",
    # one of the two always fails its condition: still issued, 1 cycle
    "it_else": """cmp r0, #0
        ite eq
        moveq r0, #1
        movne r0, #2""",
    # a double argument arrives in d0 = s0:s1; a fifth word argument on the stack
    "double_words": """vmov r0, r1, d0""",
    "fifth_word": """ldr r0, [sp]""",
    # a load that fails its condition costs 1, not 2
    "it_load": """cmp r0, #0
        it eq
        ldreq r2, [r1]""",
}

# the same body without the final bx lr: push 1+2, bl 1+P (P = 1), leaf's bx lr 3,
# pop {r4, pc} 1+2 and P = 3 (the PC loaded from memory)
CALLER = """
    .global caller
    .thumb_func
    .type caller, %function
caller:
    push {r4, lr}
    bl leaf
    pop {r4, pc}
    .size caller, .-caller
    .thumb_func
    .type leaf, %function
leaf:
    bx lr
    .size leaf, .-leaf
"""


def source() -> str:
    out = ["    .syntax unified", "    .thumb", "    .text"]
    for name, body in SNIPPETS.items():
        out += ["    .align 2", f"    .global {name}", "    .thumb_func", f"    .type {name}, %function",
                f"{name}:", f"        {body}", "        bx lr", f"    .size {name}, .-{name}"]
    return "\n".join(out) + "\n    .align 2\n" + CALLER


@pytest.fixture(scope="module")
def image(tmp_path_factory):
    require_arm_toolchain()
    tmp = tmp_path_factory.mktemp("m4")
    src = tmp / "snippets.S"
    src.write_text(source())
    return m4.build([src], [*SNIPPETS, "caller"], workdir=tmp)


def words(n=8):
    return m4.Arr("uint32", [0] * n)


def run(image, name, r0=0):
    """r0 as given, r1..r3 pointers to zeroed words, a fifth argument 0 on the stack."""
    return image.call(name, [r0, words(), words(), words(), 0], ret="int")


@pytest.mark.parametrize("name, body_cycles, body_insns", [
    ("empty", 0, 0),
    ("alu", 7, 7),
    ("divide", 1 + 1 + 12, 3),
    ("loads_apart", 2 + 1 + 2, 3),
    ("loads_pipelined", 4, 3),
    ("load_store", 3, 2),
    ("load_dependent", 2 + 2, 2),
    ("address_stall", 1 + 2 + 1, 2),
    ("multiple", (1 + 4) + 3 + (1 + 4), 3),
    ("fpu", 1 + 1 + 3 + 3 + 14 + 14 + 1 + 2 + 2 + 2 + 3 + (1 + 4) + (1 + 4), 13),
])
def test_straight_line_cycles_follow_the_manual(image, name, body_cycles, body_insns):
    r = run(image, name)
    assert (r.cycles, r.insns) == (body_cycles + RETURN, body_insns + 1)


@pytest.mark.parametrize("name, r0, body_cycles, body_insns", [
    ("branch_short", 0, 1 + (1 + 1) + 1, 3),
    ("branch_short", 1, 1 + 1 + 3 + 1, 6),
    ("branch_unaligned", 0, 1 + (1 + 2) + 1, 3),
    ("branch_unaligned", 1, 1 + 1 + 1 + 1, 4),
    ("branch_aligned", 0, 1 + (1 + 1) + 1, 3),
    ("it_else", 0, 4, 4),
    ("it_else", 1, 4, 4),
    ("it_load", 0, 1 + 1 + 2, 3),
    ("it_load", 1, 1 + 1 + 1, 3),
])
def test_branches_and_it_blocks_follow_the_manual(image, name, r0, body_cycles, body_insns):
    r = run(image, name, r0)
    assert (r.cycles, r.insns) == (body_cycles + RETURN, body_insns + 1)


def test_it_block_takes_one_side(image):
    assert [run(image, "it_else", r0).ret for r0 in (0, 5)] == [1, 2]


def test_calls_are_attributed_to_their_functions(image):
    r = image.call("caller", [], ret="void")
    assert r.cycles_by_function == {"caller": 3 + 2 + 6, "leaf": 3}
    assert r.insns_by_function == {"caller": 3, "leaf": 1}
    assert r.stack_bytes == 8                                   # r4 and lr
    assert r.func_bytes == 2 + 4 + 2 and r.reached_bytes == 2 + 4 + 2 + 2


def test_stack_and_code_size(image):
    r = run(image, "multiple")
    assert r.stack_bytes == 16
    assert r.func_bytes == 2 + 4 + 2 + 2                        # push, ldrd, pop, bx lr
    assert run(image, "empty").stack_bytes == 0


def test_floats_are_the_ieee_single_results(image):
    rng = np.random.default_rng(4)
    for a, b in rng.uniform(0.01, 100.0, size=(20, 2)).astype(np.float32):
        r = image.call("sqrt_div", [float(a), float(b)], ret="float")
        assert np.float32(r.ret) == np.sqrt(a) / b
        assert r.cycles == 14 + 14 + RETURN


def test_arrays_are_read_back(image):
    r = image.call("load_store", [0, m4.Arr("uint32", [7, 0]), words(), m4.Arr("int32", 8)], ret="int")
    assert r.arrays[0] is None and r.arrays[1] == [7, 0] and r.arrays[3][5] == 7


def test_identical_run_to_run(image):
    first = [run(image, name) for name in SNIPPETS]
    second = [run(image, name) for name in SNIPPETS]
    assert first == second


def test_an_instruction_outside_the_table_is_an_error():
    from uavarm.m4 import costs
    with pytest.raises(KeyError, match="wfi"):
        costs.price([0], {0: costs.Insn(0, 2, "wfi", "")})


def test_a_double_argument_takes_a_d_register(image):
    x = 1.0000000000000002                                      # words 0x00000001, 0x3FF00000
    low, high = struct.unpack("<II", struct.pack("<d", x))
    assert image.call("double_words", [m4.F64(x)], ret="uint32").ret == low == 1
    assert high == 0x3FF00000


def test_a_fifth_word_argument_is_on_the_stack(image):
    r = image.call("fifth_word", [1, 2, m4.Arr("float", 3), 4, m4.U32(0xDEADBEEF)], ret="uint32")
    assert r.ret == 0xDEADBEEF and r.cycles == 2 + RETURN
