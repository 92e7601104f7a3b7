"""`make bench`: Cortex-M4 instruction counts and estimated cycles of the generated code,
side by side with the plain reference (bench/reference.c) in the same run.

Counts come from ../shared/tools/m4count.py (unicorn emulation, deterministic); cycles
are its estimate at zero flash wait states. Each row is the mean and the worst case over
the same fixed set of inputs for both sides. Host timings are not figures of merit.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from uavarm import generated, target
from uavarm.model import config

BENCH = Path(__file__).resolve().parent
N_INPUTS = 50


def inputs(m):
    rng = np.random.default_rng(2024)
    qs = [[float(rng.uniform(l.min_rad, l.max_rad)) for l in m.limits] for _ in range(N_INPUTS)]
    # reachable targets in front of and below the arm, and a few unreachable ones
    targets = []
    while len(targets) < N_INPUTS:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        r = rng.uniform(80.0, m.L2 + m.L3 - 1.0) if len(targets) % 10 else m.L2 + m.L3 + 20.0
        p = d * r + [0.0, 0.0, -m.L1]
        if p[2] < -m.L1:
            targets.append([float(v) for v in p])
    samples = [float(v) for v in rng.normal(0.0, 9.81, N_INPUTS)]
    return qs, targets, samples


def measure(build, func, arg_sets, ret):
    m4 = target.m4count()
    results = [build.call(func, [m4.Arr(*a) if isinstance(a, tuple) else a for a in args], ret=ret)
               for args in arg_sets]
    cycles = [r.cycles for r in results]
    insns = [r.insns for r in results]
    return {"insns": float(np.mean(insns)), "cycles": float(np.mean(cycles)), "cycles_max": max(cycles),
            "bytes": results[0].reached_bytes, "stack": max(r.stack_bytes for r in results)}


def main() -> int:
    m = config.load()
    m4 = target.m4count()
    gen_dir = generated.GENERATED
    gen = m4.build([str(s) for s in generated.sources()],
                   ["kin_fk_ee", "kin_ik", "filt_accel_step", "filt_gyro_step"],
                   cflags=target.M4_CFLAGS + [f"-I{gen_dir}"])
    ref = m4.build([str(BENCH / "reference.c")], ["ref_fk", "ref_ik", "ref_biquad_step"],
                   cflags=target.M4_CFLAGS + target.reference_defines(m))
    qs, targets, samples = inputs(m)
    zero_q = ("float", [0.0, 0.0, 0.0])

    rows = [
        ("FK (end effector)",
         measure(gen, "kin_fk_ee", [[("float", q), ("float", 3)] for q in qs], "void"),
         measure(ref, "ref_fk", [[("float", q), ("float", 3)] for q in qs], "void")),
        ("IK: 4 candidates + checks + select",
         measure(gen, "kin_ik", [[("float", p), zero_q, ("uint32", 14)] for p in targets], "int"),
         measure(ref, "ref_ik", [[("float", p), zero_q, ("float", 3)] for p in targets], "int")),
        ("accel filter step (1 axis)",
         measure(gen, "filt_accel_step", [[("float", 2), x] for x in samples], "float"),
         measure(ref, "ref_biquad_step", [[("float", 4), x] for x in samples], "float")),
        ("gyro filter step (1 axis)",
         measure(gen, "filt_gyro_step", [[("float", 2), x] for x in samples], "float"),
         measure(ref, "ref_biquad_step", [[("float", 4), x] for x in samples], "float")),
    ]

    print(f"Cortex-M4F (m4count, -O2, FPv4-SP), mean / worst over {N_INPUTS} inputs; "
          "est. cycles at 0 wait states\n")
    print("| function | generated insns | generated cycles (worst) | bytes | "
          "reference insns | reference cycles (worst) | bytes | cycles ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, g, r in rows:
        print(f"| {name} | {g['insns']:.0f} | {g['cycles']:.0f} ({g['cycles_max']}) | {g['bytes']} | "
              f"{r['insns']:.0f} | {r['cycles']:.0f} ({r['cycles_max']}) | {r['bytes']} | "
              f"{r['cycles'] / g['cycles']:.1f}x |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
