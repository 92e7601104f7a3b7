"""Estimated Cortex-M4F cycles of an executed instruction stream.

The table follows the Cortex-M4 Technical Reference Manual (r0p1): the processor instruction
timings (table 3-1), the load/store timing notes beside it, and the FPU instruction timings.
Zero flash wait states, no interrupts, no bus contention.

    instructions                                        cycles
    data processing, shifts, bit fields, MOVW/MOVT,
      extends, saturation, CLZ/RBIT/REV, IT, NOP        1
    MUL MLA MLS, long and DSP multiplies               1
    SDIV UDIV                                          12   the manual's 2..12 (early
                                                            termination): taken at its bound
    LDR* STR* (single)                                 2    1 when pipelined, see below
    LDRD STRD                                          3    1+N, N = 2
    LDM STM PUSH POP                                   1+N  N = registers in the list
    TBB TBH                                            2+P
    B B<cond> BL BX BLX CBZ CBNZ                       1    +P when taken
    any write to the PC (POP {..pc}, LDR pc, MOV pc)   +P
    VADD VSUB VMUL VNMUL VABS VNEG VCMP(E) VCVT
      VMOV (one register, immediate) VMRS VMSR         1
    VMOV of two core registers <-> two S or one D      2
    VMLA VMLS VNMLA VNMLS VFMA VFMS VFNMA VFNMS        3
    VDIV VSQRT                                         14
    VLDR VSTR                                          2    3 for a double
    VLDM VSTM VPUSH VPOP                               1+N  N = 32-bit words moved
    an IT-block instruction whose condition failed     1

Pipeline interactions, from the load/store timing notes:
  - a single LDR/STR directly after a single LDR costs one cycle less (address and data
    phases overlap), unless the first load's destination forms the second's address;
  - a load or store whose address register the instruction just before computed (a data
    processing result) waits one more cycle: there is no forwarding path to the address unit.

P, the pipeline refill after a taken branch, is 1..3 in the manual "depending on the
alignment and width of the target instruction, and whether the processor manages to
speculate the address early". This table takes: 1 for a branch to an immediate address,
2 for a branch to a register (BX, BLX, MOV pc), 3 for a PC loaded from memory (POP, LDM,
LDR, TBB/TBH: "three cycles for the pipeline reload"); plus 1, up to 3 in all, when the
target is a 32-bit instruction that is not word-aligned (two fetches). The return from the
measured function counts its refill without that alignment term (the caller is unknown).

Not modelled (each makes the estimate low or high by a cycle here and there): IT folded
onto a preceding 16-bit instruction (0 cycles instead of 1), a store with an immediate
offset completing in one cycle when nothing follows it onto the bus, the early termination
of divisions, flash wait states and the ART accelerator.
"""
from __future__ import annotations

import re
from collections import Counter

_CONDS = {"eq", "ne", "cs", "cc", "hs", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt",
          "gt", "le", "al"}

_ALU = set("""adc add addw adr and asr bfc bfi bic clz cmn cmp eor lsl lsr mov movw movt mvn neg
    nop orn orr pkhbt pkhtb qadd qdadd qdsub qsub rbit rev rev16 revsh ror rrx rsb sadd8 sadd16
    sbc sbfx sel ssat ssub8 ssub16 sub subw sxtab sxtah sxtb sxth teq tst uadd8 uadd16 ubfx
    usat usub8 usub16 uxtab uxtah uxtb uxth
    mul mla mls smull umull smlal umlal umaal smulbb smulbt smultb smultt smulwb smulwt smlabb
    smlabt smlatb smlatt smlawb smlawt smmul smmla smmls smuad smusd smlad smlsd smlald smlsld""".split())
_COMPARES = {"cmp", "cmn", "tst", "teq", "nop"}
_LONG_MUL = {"smull", "umull", "smlal", "umlal", "umaal", "smlald", "smlsld"}
_DIV = {"sdiv", "udiv"}
_LOADS = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrt", "ldrbt", "ldrht", "ldrex"}
_STORES = {"str", "strb", "strh", "strt", "strbt", "strht", "strex"}
_MULTIPLE = {"ldm", "ldmia", "ldmdb", "ldmfd", "stm", "stmia", "stmdb", "stmea", "push", "pop"}
_DIRECT_BRANCHES = {"b", "bl", "cbz", "cbnz"}
_FPU_1 = {"vadd", "vsub", "vmul", "vnmul", "vabs", "vneg", "vcmp", "vcmpe", "vcvt", "vcvtr", "vcvtb",
          "vcvtt", "vmrs", "vmsr"}
_FPU_MAC = {"vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"}
_FPU_MEM = {"vldr", "vstr"}
_FPU_MULTIPLE = {"vldm", "vldmia", "vldmdb", "vstm", "vstmia", "vstmdb", "vpush", "vpop"}
_KNOWN = (_ALU | _DIV | _LOADS | _STORES | _MULTIPLE | _DIRECT_BRANCHES | _FPU_1 | _FPU_MAC | _FPU_MEM
          | _FPU_MULTIPLE | {"ldrd", "strd", "tbb", "tbh", "bx", "blx", "vmov", "vdiv", "vsqrt"})
_BRANCHES = _DIRECT_BRANCHES | {"bx", "blx"}

DIV_CYCLES = 12
FP_DIV_CYCLES = 14
FP_MAC_CYCLES = 3

_ALIASES = {"ip": "r12", "fp": "r11", "sl": "r10", "sb": "r9"}
_REG = re.compile(r"\b(r1[0-5]|r\d|sp|lr|pc|ip|fp|sl|sb)\b")


def root_of(mnemonic: str) -> str:
    """The instruction without width, type, flag-setting or condition suffixes:
    'vmovgt.f32' -> 'vmov', 'bne.n' -> 'b', 'lsls' -> 'lsl', 'bics' -> 'bic', 'itte' -> 'it'."""
    head = mnemonic.lower().split(".")[0]
    if head in _KNOWN:
        return head
    if re.fullmatch(r"it[te]{0,3}", head):
        return "it"
    if head.endswith("s") and head[:-1] in _KNOWN - _BRANCHES:
        return head[:-1]
    body = head[:-2] if head[-2:] in _CONDS else head
    for root in (body, body[:-1] if body.endswith("s") else None):  # 'bls', 'movseq'
        if root in _KNOWN:
            return root
    return head


def _regs(text: str) -> frozenset[str]:
    return frozenset(_ALIASES.get(r, r) for r in _REG.findall(text))


def _list_words(operands: str) -> int:
    """32-bit words in a register list: '{r4, r5, lr}' -> 3, '{s16-s19}' -> 4, '{d8-d9}' -> 4."""
    inside = operands[operands.index("{") + 1:operands.index("}")]
    words = 0
    for item in filter(None, (i.strip() for i in inside.split(","))):
        first, _, last = item.partition("-")
        count = int(last.strip()[1:]) - int(first[1:]) + 1 if last else 1
        words += count * (2 if first.startswith("d") else 1)
    return words


class Insn:
    """One disassembled instruction and what pricing it needs."""
    __slots__ = ("addr", "size", "mnemonic", "operands", "root", "kind", "base", "refill",
                 "dests", "address_regs", "it_len")

    def __init__(self, addr: int, size: int, mnemonic: str, operands: str):
        self.addr, self.size, self.mnemonic, self.operands = addr, size, mnemonic, operands
        self.root = root_of(mnemonic)
        ops = operands.split(",")
        first = _regs(ops[0]) if ops else frozenset()
        bracket = re.search(r"\[([^\]]*)\]", operands)
        root = self.root
        self.kind, self.dests, self.it_len = "other", frozenset(), 0
        self.address_regs = _regs(bracket.group(1)) if bracket else frozenset()
        self.refill = 2 if "pc" in first else 0        # MOV pc / ADD pc: a register branch
        if root == "it":
            self.base, self.it_len = 1, len(mnemonic) - 1
        elif root in _ALU:
            self.kind, self.base = "alu", 1
            if root not in _COMPARES:
                self.dests = _regs(",".join(ops[:2])) if root in _LONG_MUL else first
        elif root in _DIV:
            self.kind, self.base, self.dests = "alu", DIV_CYCLES, first
        elif root in _LOADS or root in _STORES:
            self.kind, self.base = ("load" if root in _LOADS else "store"), 2
            self.dests = first if root in _LOADS else frozenset()
            self.refill = 3 if "pc" in first else 0
        elif root in ("ldrd", "strd"):
            self.kind, self.base = "memory", 3
        elif root in _MULTIPLE or root in _FPU_MULTIPLE:
            self.kind, self.base = "memory", 1 + _list_words(operands)
            self.address_regs = frozenset({"sp"}) if root in ("push", "pop", "vpush", "vpop") else first
            self.refill = 3 if "pc" in _regs(operands[operands.index("{"):]) else 0
        elif root in _FPU_MEM:
            self.kind, self.base = "memory", 3 if operands.startswith("d") else 2
        elif root in ("tbb", "tbh"):
            self.kind, self.base, self.refill = "memory", 2, 3
        elif root in _DIRECT_BRANCHES:
            self.base, self.refill = 1, 1
        elif root in ("bx", "blx"):
            self.base, self.refill = 1, 2 if first else 1
        elif root == "vmov":
            self.kind, self.base = "fpu", 2 if len(_regs(operands)) >= 2 else 1   # two core registers
            self.dests = first
        elif root in _FPU_1:
            self.kind, self.base = "fpu", 1
        elif root in _FPU_MAC:
            self.kind, self.base = "fpu", FP_MAC_CYCLES
        elif root in ("vdiv", "vsqrt"):
            self.kind, self.base = "fpu", FP_DIV_CYCLES
        else:
            self.base = None                            # no entry: an error if it executes

    def __repr__(self):
        return f"{self.addr:#x}: {self.mnemonic} {self.operands}"


def issued(trace, insns: dict[int, Insn]) -> list[tuple[Insn, bool]]:
    """Every instruction the core issued, in order, with whether it executed. The emulator
    reports only executed instructions; an IT-block instruction whose condition failed is
    still issued, so the ones the trace steps over inside an IT block are put back."""
    out = []
    pending: list[int] = []                 # addresses of the open IT block not yet issued
    for addr in trace:
        if pending:
            k = pending.index(addr) if addr in pending else len(pending)
            out.extend((insns[a], False) for a in pending[:k])
            pending = pending[k + 1:]
        ins = insns[addr]
        out.append((ins, True))
        if ins.it_len:
            a = addr + ins.size
            for _ in range(ins.it_len):
                pending.append(a)
                a += insns[a].size
    return out


def price(trace, insns: dict[int, Insn]) -> tuple[Counter, Counter]:
    """(issues, cycles) per instruction address for one executed trace (a list of the
    addresses the emulator executed, in order; the last one returns to the caller)."""
    stream = issued(trace, insns)
    counts, cycles = Counter(), Counter()
    prev, prev_ran = None, False
    for i, (ins, ran) in enumerate(stream):
        counts[ins.addr] += 1
        if not ran:
            cycles[ins.addr] += 1
            prev, prev_ran = ins, False
            continue
        if ins.base is None:
            raise KeyError(f"no cycle cost for '{ins.mnemonic} {ins.operands}' at {ins.addr:#x}")
        c = ins.base
        target = stream[i + 1][0] if i + 1 < len(stream) else None
        taken = target is None or target.addr != ins.addr + ins.size
        if prev_ran and ins.kind in ("load", "store") and not taken:
            if prev.kind == "load" and not prev.refill and not (prev.dests & ins.address_regs):
                c -= 1                                      # pipelined after a load
        if prev_ran and prev.kind == "alu" and prev.dests & ins.address_regs:
            c += 1                                          # address computed just before
        if taken:
            refill = ins.refill or 1
            if target is not None and target.size == 4 and target.addr % 4:
                refill += 1
            c += min(refill, 3)
        cycles[ins.addr] += c
        prev, prev_ran = ins, True
    return counts, cycles
