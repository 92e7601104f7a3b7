"""`make bench`: Cortex-M4 instruction counts and estimated cycles of the generated code,
side by side with the plain reference (bench/reference.c) in the same run.

Counts come from uavarm/m4 (unicorn emulation, deterministic); cycles are its estimate
from the Cortex-M4 manual's timings at zero flash wait states. Each row is the mean and
the worst case over the same fixed set of inputs for both sides. Host timings are not
figures of merit.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

from uavarm import m4
from uavarm.build import cbuild, firmware, generated, target
from uavarm.model import config
from uavarm.sim.board import SimBoard

sys.path.insert(0, str(Path(__file__).resolve().parent))
import motion  # noqa: E402  (bench/motion.py)

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
    results = [build.call(func, [m4.Arr(*a) if isinstance(a, tuple) else a for a in args], ret=ret)
               for args in arg_sets]
    cycles = [r.cycles for r in results]
    insns = [r.insns for r in results]
    return {"insns": float(np.mean(insns)), "cycles": float(np.mean(cycles)), "cycles_max": max(cycles),
            "bytes": results[0].reached_bytes, "stack": max(r.stack_bytes for r in results)}


def main() -> int:
    m = config.load()
    gen_dir = generated.GENERATED
    gen = m4.build([str(s) for s in generated.sources()],
                   ["kin_fk_ee", "kin_ik", "kin_ik_nearest", "kin_ik_branch", "filt_accel_step", "filt_gyro_step"],
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
        ("IK for a new set position: nearest candidate first, stop at the first valid",
         measure(gen, "kin_ik_nearest", [[("float", p), zero_q, ("float", 3)] for p in targets], "int"),
         measure(ref, "ref_ik", [[("float", p), zero_q, ("float", 3)] for p in targets], "int")),
        ("IK as every tick runs it: the followed branch (the reference solves and checks all four)",
         measure(gen, "kin_ik_branch", [[("float", p), ("float", [0.3, 1.0, -1.0]), -1.0, 0, ("float", 3),
                                          ("float", 3)] for p in targets], "int"),
         measure(ref, "ref_ik", [[("float", p), zero_q, ("float", 3)] for p in targets], "int")),
        ("accel filter step (1 axis)",
         measure(gen, "filt_accel_step", [[("float", 2), x] for x in samples], "float"),
         measure(ref, "ref_biquad_step", [[("float", 4), x] for x in samples], "float")),
        ("gyro filter step (1 axis)",
         measure(gen, "filt_gyro_step", [[("float", 2), x] for x in samples], "float"),
         measure(ref, "ref_biquad_step", [[("float", 4), x] for x in samples], "float")),
    ]

    print(f"Cortex-M4F (uavarm.m4, -O2, FPv4-SP), mean / worst over {N_INPUTS} inputs; "
          "est. cycles at 0 wait states\n")
    print("| function | generated insns | generated cycles (worst) | bytes | "
          "reference insns | reference cycles (worst) | bytes | cycles ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, g, r in rows:
        print(f"| {name} | {g['insns']:.0f} | {g['cycles']:.0f} ({g['cycles_max']}) | {g['bytes']} | "
              f"{r['insns']:.0f} | {r['cycles']:.0f} ({r['cycles_max']}) | {r['bytes']} | "
              f"{r['cycles'] / g['cycles']:.1f}x |")
    whole_tick(m)
    target_size()
    bus_traffic(m)
    xseries_bus()
    xseries_tick()
    motion.report(m)
    return 0


N_TICKS = 20


def tilting_imu(m, n=N_TICKS):
    """Raw MPU-6050 counts of a board rocking +-20 deg in roll at 1 Hz (ideal sensor)."""
    lsb_g = 32768 / m.accel_range_g
    lsb_rad = 32768 / np.radians(m.gyro_range_dps)
    raw = []
    for k in range(n):
        t = k / m.sample_rate
        roll = np.radians(20) * np.sin(2 * np.pi * t)
        rate = np.radians(20) * 2 * np.pi * np.cos(2 * np.pi * t)
        raw += [0, round(np.sin(roll) * lsb_g), round(np.cos(roll) * lsb_g), round(rate * lsb_rad), 0, 0]
    return raw


# How the firmware is built: as its Makefile links it (-O2, link-time optimisation: what the
# target is for), each file compiled and linked on its own (whose cycles can be told by
# function: link-time optimisation inlines most of the tick into app_poll), and as the
# STM32CubeIDE project's Release configuration builds it (-Os, each file on its own).
BUILDS = {"makefile": target.FIRMWARE_LTO, "per_file": [], "cubeide_release": ["-Os"]}


def tick_bench_build(gen_dir=generated.GENERATED, build="makefile"):
    """bench/tick_bench.c with every application and generated source, for the M4 counter,
    built as BUILDS[build] says."""
    sources = [str(s) for s in firmware.app_sources(gen_dir)] + [str(BENCH / "tick_bench.c")]
    incs = [f"-I{d}" for d in (gen_dir, firmware.APP / "Inc")]
    return m4.build(sources, ["bench_run", "bench_message", "bench_pass"],
                    cflags=target.M4_CFLAGS + BUILDS[build] + incs)


def tick_cycles(gen_dir, raw):
    """({build: whole tick}, the per-file build's cycles by function), est. cycles per tick."""
    tick = {}
    for build in BUILDS:
        idle, run = tick_runs(tick_bench_build(gen_dir, build), raw)
        if not (idle.ret and run.ret):
            raise SystemExit("tick bench: a run did not complete (engaged, all commands sent)")
        tick[build] = (run.cycles - idle.cycles) / N_TICKS
        if build == "per_file":
            by_func = {k: (v - idle.cycles_by_function.get(k, 0)) / N_TICKS for k, v in run.cycles_by_function.items()}
    return tick, by_func


def whole_tick(m):
    """The firmware's whole tick (bench/tick_bench.c) against the plain reference tick."""
    gen = tick_bench_build()
    ref = m4.build([str(BENCH / "reference.c")], ["ref_run"], cflags=target.M4_CFLAGS + target.reference_defines(m))
    raw = tilting_imu(m, N_TICKS + 1)   # the firmware's warm-up tick on the first sample, then N_TICKS
    idle, run = tick_runs(gen, raw)
    base = ref.call("ref_run", [m4.Arr("int32", raw[6:]), m4.U32(N_TICKS), m4.Arr("float", [60.0, 20.0, -120.0]),
                                m4.Arr("uint32", 3)], ret="int")
    if not (idle.ret and run.ret and base.ret):
        raise SystemExit("tick bench: a run did not complete (engaged, all commands sent)")
    ticks, by_func = tick_cycles(generated.GENERATED, raw)
    tick = ticks["makefile"]
    # (told by function in the build without link-time optimisation: its calls cost more, so
    # the ratio below is the smaller one)
    arithmetic = sum(v for k, v in by_func.items()
                     if k.startswith(("kin_", "est_", "filt_", "stab_", "fm_", "servo_joints_to_units", "mpu_sample")))
    tick_insns = (run.insns - idle.insns) / N_TICKS
    ref_tick = base.cycles / N_TICKS
    print(f"\nWhole 100 Hz tick, mean over {N_TICKS} ticks of a board rocking +-20 deg. Firmware "
          "(bench/tick_bench.c): what a tick adds to the main loop's idle passes: the IMU burst, "
          "filters, attitude, level-to-base, the followed branch's IK, the move's swept check, servo units, the SYNC_WRITE, "
          "the status READ and the parse of its 18-byte reply. Reference (bench/reference.c "
          "ref_tick): the same arithmetic written plainly with libm, no I/O.\n")
    print("| | insns | est. cycles | us at 96 MHz | stack bytes |")
    print("|---|---:|---:|---:|---:|")
    print(f"| firmware: whole tick with bus I/O, linked as the Makefile links it (link-time optimisation) | "
          f"{tick_insns:.0f} | {tick:.0f} | {tick / 96:.1f} | {run.stack_bytes} |")
    for build, what in (("per_file", "the same, each file compiled and linked on its own"),
                        ("cubeide_release", "the same as STM32CubeIDE's Release configuration builds it (-Os)")):
        print(f"| {what} | | {ticks[build]:.0f} | {ticks[build] / 96:.1f} | |")
    print(f"| of which the arithmetic (generated code, stabiliser, IMU decoding and scaling) | | {arithmetic:.0f} | "
          f"{arithmetic / 96:.1f} | |")
    print(f"| plain reference tick: the arithmetic only, no I/O | {base.insns / N_TICKS:.0f} | {ref_tick:.0f} | "
          f"{ref_tick / 96:.1f} | {base.stack_bytes} |")
    print(f"| ratio reference / firmware arithmetic | | {ref_tick / arithmetic:.1f}x | | |")
    print("\nLargest shares of the firmware tick, each file on its own (est. cycles, exclusive):",
          ", ".join(f"{k} {v:.0f}" for k, v in sorted(by_func.items(), key=lambda kv: -kv[1])[:14]))
    print(f"\nWith the gyro's cross-axis sensitivity calibrated (imu.gyro_cross_axis not zero: a 3x3 product "
          f"per sample instead of three scales): whole tick {cross_axis_tick(raw):.0f} est. cycles.")
    messages = []
    for which, name, fused in ((1, "drone_attitude", m.estimator.drone_attitude),
                               (2, "drone_velocity", m.estimator.drone_velocity)):
        if not fused:
            continue
        runs = [gen.call("bench_message", [m4.Arr("int32", raw), m4.U32(N_TICKS), m4.U32(which), m4.U32(second)],
                         ret="int") for second in (0, 1)]
        if not all(r.ret for r in runs):
            raise SystemExit(f"tick bench: a {name} message was refused")
        messages.append(f"{name} {runs[1].cycles - runs[0].cycles}")
    if messages:
        print("\nOne drone message fused by the stabiliser (main loop, between ticks; est. cycles): "
              + ", ".join(messages) + ". Both streams are fresh in the ticks above, as in flight.")
    passes = []
    for what, name in ((1, "a new set_position received and handled, engaged (route checked)"),
                       (2, "a heartbeat packed, framed and written")):
        runs = [gen.call("bench_pass", [m4.Arr("int32", raw), m4.U32(N_TICKS), m4.U32(what), m4.U32(with_)],
                         ret="int") for with_ in (0, 1)]
        if not all(r.ret for r in runs):
            raise SystemExit(f"tick bench: the pass with {name} did not do it")
        passes.append(f"{name} {runs[1].cycles - runs[0].cycles}")
    print("\nOne main-loop pass's extra work, outside the tick (est. cycles): " + "; ".join(passes) + ".")


def tick_runs(gen, raw):
    """The tick bench without ticks (the main loop's idle passes) and with them."""
    return [gen.call("bench_run", [m4.Arr("int32", raw), m4.U32(N_TICKS), m4.U32(ticks)], ret="int")
            for ticks in (0, 1)]


def cross_axis_tick(raw) -> float:
    """The whole tick of the model file with a calibrated cross-axis sensitivity (+-2 %)."""
    from uavarm.build import variants
    cross = [[0.0, 0.015, -0.02], [0.012, 0.0, 0.008], [-0.018, 0.019, 0.0]]
    idle, run = tick_runs(tick_bench_build(variants.build({"imu.gyro_cross_axis": cross}).gen_dir), raw)
    if not (idle.ret and run.ret):
        raise SystemExit("tick bench: the run with the cross-axis calibrated did not complete")
    return (run.cycles - idle.cycles) / N_TICKS


def target_size():
    """Flash and static RAM of the portable application and generated code on the M4."""
    ffi, _ = firmware.default()
    sizes = target.cross_compile(firmware.app_sources(), [generated.GENERATED, firmware.APP / "Inc"],
                                 cbuild.ROOT / "build" / "m4")
    text = sum(s[0] for s in sizes.values())
    data = sum(s[1] for s in sizes.values())
    bss = sum(s[2] for s in sizes.values())
    print(f"\nCortex-M4F objects ({len(sizes)} files, -O2, -Werror): flash {text + data} bytes "
          f"(text {text}, data {data}), static RAM {data + bss} bytes; the application state "
          f"app_t is {ffi.sizeof('app_t')} bytes (a static in main.c).")


def bus_traffic(m, seconds=1.0):
    """Servo-bus bytes and wire time per tick, engaged, from the simulated board."""
    board = SimBoard(m)
    board.send("enable", on=1)
    board.run(1.0)
    board.send("engage", on=1)
    board.run(0.2)
    tx0, rx0, t0 = len(board.servo_tx), board.servo_rx_bytes, board.time
    board.run(seconds)
    ticks = round((board.time - t0) * m.sample_rate)
    tx = (len(board.servo_tx) - tx0) / ticks
    rx = (board.servo_rx_bytes - rx0) / ticks
    byte_us = 10e6 / m.servo_baud
    wire = (tx + rx) * byte_us + m.servo_return_delay_us
    print(f"\nServo bus at {m.servo_baud} baud, engaged: {tx:.0f} bytes out + {rx:.0f} bytes back per tick "
          f"(SYNC_WRITE of 3 servos + one status READ), {wire:.0f} us of wire time per "
          f"{1e6 / m.sample_rate:.0f} us tick ({wire * m.sample_rate / 1e4:.0f} % of the bus).")


# The model file as an XM430-W350 arm: the servo model, its travel, a baud it runs at, zeros at its centre.


def xseries_reply_bytes() -> int:
    """The X-series status reply's length: the status packet's 11 bytes around the driver's
    SBUS2_STATUS_LEN parameters."""
    text = (firmware.APP / "Inc" / "servo_bus.h").read_text()
    return 11 + int(re.search(r"#define SBUS2_STATUS_LEN (\d+)", text).group(1))


def xseries_bus(n=9):
    """The X-series bus driver's work per command (bench/sbus2_bench.c), built from the model
    file edited into an XM430-W350 arm."""
    import tempfile

    from uavarm.build import variants
    from uavarm.codegen import generate
    with tempfile.TemporaryDirectory(prefix="uavarm-xm430-") as tmp:
        model_path, gen_dir = Path(tmp) / "arm.toml", Path(tmp) / "generated"
        model_path.write_text(variants.edited_text(variants.XM430_EDITS))
        generate.write(generate.render(model_path), gen_dir)
        sources = [str(firmware.APP / "Src" / f) for f in ("servo_bus2.c", "dxl_protocol2.c")]
        build = m4.build(sources + [str(BENCH / "sbus2_bench.c")], ["bench_sbus2"],
                         cflags=target.M4_CFLAGS + [f"-I{gen_dir}", f"-I{firmware.APP / 'Inc'}"])
    idle = build.call("bench_sbus2", [m4.U32(n), m4.U32(0)], ret="int")
    run = build.call("bench_sbus2", [m4.U32(n), m4.U32(1)], ret="int")
    if not (idle.ret and run.ret):
        raise SystemExit("X-series bus bench: a command went without its SYNC_WRITE or status reading")
    print(f"\nX-series bus driver (servo_bus2.c, XM430-W350 model), per command: SYNC_WRITE built and sent, "
          f"status READ sent, its {xseries_reply_bytes()}-byte reply checked and taken: {(run.insns - idle.insns) / n:.0f} insns, "
          f"{(run.cycles - idle.cycles) / n:.0f} est. cycles, {run.stack_bytes} bytes of stack.")


def xseries_tick():
    """The whole tick (bench/tick_bench.c) of the model file edited into an XM430-W350 arm."""
    from uavarm.build import variants
    m = config.load()
    raw = tilting_imu(m, N_TICKS + 1)
    ticks, by_func = tick_cycles(variants.build(variants.XM430_EDITS).gen_dir, raw)
    print(f"\nWhole tick of the same arm on XM430-W350 servos (bench/tick_bench.c, as above): "
          f"{ticks['makefile']:.0f} est. cycles as the Makefile links it, {ticks['per_file']:.0f} with each file "
          f"on its own, {ticks['cubeide_release']:.0f} as CubeIDE's Release builds it (-Os); largest shares, each "
          "file on its own: " + ", ".join(f"{k} {v:.0f}" for k, v in sorted(by_func.items(), key=lambda kv: -kv[1])[:8])
          + ".")


if __name__ == "__main__":
    try:
        sys.exit(main())
    except m4.ToolError as e:
        sys.exit(f"make bench: {e}")
