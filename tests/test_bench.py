"""The whole-tick benchmark (bench/tick_bench.c) still measures what it says: it runs on the
emulated Cortex-M4F and reports a run complete only if the arm stayed engaged and every tick
had its SYNC_WRITE and its status reading. No cycle threshold is asserted (figures come from
`make bench`): a tick costs something, its counts are the same run to run, and a parked run
is refused. (tests/test_m4.py checks the counter's cycles against the manual.)"""
import importlib.util

import pytest

from conftest import ROOT, require_arm_toolchain
from uavarm import m4
from uavarm.build import firmware
from uavarm.model import config

_spec = importlib.util.spec_from_file_location("bench_run_py", ROOT / "bench" / "run.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

N = 3


@pytest.fixture(scope="module")
def tick_build():
    """The tick bench linked as the firmware's Makefile links it (link-time optimisation)."""
    require_arm_toolchain()
    return bench.tick_bench_build()


def run(tick_build, raw, ticks, n=N):
    return tick_build.call("bench_run", [m4.Arr("int32", raw), m4.U32(n), m4.U32(ticks)], ret="int")


def test_ticks_run_engaged_with_all_their_bus_traffic(tick_build):
    raw = bench.tilting_imu(config.load(), N + 1)
    idle, ticks = run(tick_build, raw, 0), run(tick_build, raw, 1)
    assert idle.ret == 1 and ticks.ret == 1
    per_tick = (ticks.cycles - idle.cycles) / N
    print(f"\n{per_tick:.0f} est. cycles per tick over {N} ticks (make bench: the mean over {bench.N_TICKS})")
    assert per_tick > 0
    again = run(tick_build, raw, 1)
    assert (again.insns, again.cycles, again.cycles_by_function, again.stack_bytes) == \
        (ticks.insns, ticks.cycles, ticks.cycles_by_function, ticks.stack_bytes)
    # the stabilising path's own functions ran in the ticks (told apart with each file built on
    # its own: link-time optimisation inlines them into app_poll)
    per_file = bench.tick_bench_build(build="per_file")
    idle, ticks = run(per_file, raw, 0), run(per_file, raw, 1)
    assert idle.ret == 1 and ticks.ret == 1
    assert {"kin_ik_branch", "stab_sample", "sbus_poll"} <= set(ticks.cycles_by_function)


def test_a_run_that_parked_is_refused(tick_build):
    """Samples at full scale are unusable (saturated): after APP_IMU_STALE_TICKS of them the
    arm parks, and the bench must not report those ticks as the stabilising path."""
    _, lib = firmware.default()
    n = lib.APP_IMU_STALE_TICKS + 1
    raw = bench.tilting_imu(config.load(), n + 1)
    saturated = raw[:6] + [32767] * (6 * n)
    assert run(tick_build, raw, 1, n).ret == 1
    assert run(tick_build, saturated, 1, n).ret == 0


def test_the_main_loop_passes_measured_do_their_work(tick_build):
    """bench_pass (make bench's set_position and heartbeat figures): the pass with the work
    does it (the set position taken engaged; one heartbeat more), the one without does not,
    and the work costs something."""
    raw = bench.tilting_imu(config.load(), N + 1)
    for what in (1, 2):
        without, with_ = (tick_build.call("bench_pass", [m4.Arr("int32", raw), m4.U32(N), m4.U32(what), m4.U32(w)],
                                          ret="int") for w in (0, 1))
        assert without.ret == 1 and with_.ret == 1
        assert with_.cycles > without.cycles
    print(f"\nheartbeat: {with_.cycles - without.cycles} est. cycles")


def test_the_xseries_bus_bench_takes_every_reading(capsys):
    """bench/sbus2_bench.c on the emulated Cortex-M4F: every command sends its SYNC_WRITE and
    takes its status reading (xseries_bus stops otherwise); no cycle figure is asserted."""
    require_arm_toolchain()
    bench.xseries_bus(n=2)
    assert "est. cycles" in capsys.readouterr().out


def test_the_xseries_tick_bench_runs_engaged_with_all_its_bus_traffic(capsys):
    """The whole tick of the model file made an XM430-W350 arm, built from that variant's own
    generated code (its servo map, not the AX-12A's): engaged and following, every tick with
    its SYNC_WRITE and its status reading (xseries_tick stops otherwise)."""
    require_arm_toolchain()
    bench.xseries_tick()
    assert "XM430-W350 servos" in capsys.readouterr().out


def test_without_the_arm_toolchain_make_bench_says_what_to_install(tmp_path):
    """No arm-none-eabi-gcc on PATH: a line naming the toolchain and its Debian packages, exit
    status 1, no Python traceback."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, str(ROOT / "bench" / "run.py")], capture_output=True, text=True,
                          env={"PATH": str(tmp_path), "HOME": str(tmp_path)}, cwd=ROOT)
    assert proc.returncode == 1
    assert "arm-none-eabi-gcc not found" in proc.stderr and "gcc-arm-none-eabi" in proc.stderr
    assert "Traceback" not in proc.stderr
