"""The fuzz harnesses (fuzz/, docs/fuzzing.md): every harness builds with libFuzzer,
AddressSanitizer and UndefinedBehaviorSanitizer, replays its committed seeds without a
finding, and survives a short run bounded by a number of inputs (-runs), not by time: from
its committed seeds only, with libFuzzer's random seed fixed, so every machine, idle or
busy, runs the same inputs and the verdict is "no finding" whatever the speed. The long run
is `make fuzz-long`.

Needs clang with libFuzzer (Debian: clang libclang-rt-14-dev) and atheris (pip): skipped on
a developer machine without them, a failure in CI.
"""
from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import pytest

from conftest import ROOT, require_clang_fuzzer
from uavarm.link.messages import FAULTS

# Inputs per harness in the short run (libFuzzer -runs, with -seed=SEED), two harnesses at a
# time. What they cover (the edges, `cov`) is printed with the run's table; MIN_COV is well
# below what these exact inputs reach, so a harness that stopped exercising its target (a
# build that links nothing, a harness that returns early) fails. These runs reach 76, 78,
# 1,428 and 231 edges in 26 s of CPU; two to four times as many (200,000, 60,000, 20,000 and
# 6,000) reach 76, 78, 1,464 and 235 in 66 s. app_link_x's 10,000 reach 1,458 (app_link's
# 1,437 in the same run, its harness since shared with the X-series). The long runs are
# `make fuzz-long`'s.
SHORT_RUNS = {"llcp_rx": 50_000, "dxl_parser": 20_000, "dxl2_parser": 20_000, "app_link": 10_000, "app_link_x": 10_000,
              "model_loader": 3_000}
SEED = 1
MIN_COV = {"llcp_rx": 60, "dxl_parser": 60, "dxl2_parser": 60, "app_link": 900, "app_link_x": 900, "model_loader": 120}


def _load_runner():
    """fuzz/run.py (not a package) as the module uavarm_fuzz_run."""
    if "uavarm_fuzz_run" not in sys.modules:
        spec = importlib.util.spec_from_file_location("uavarm_fuzz_run", ROOT / "fuzz" / "run.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module   # (its dataclasses look their module up)
        spec.loader.exec_module(module)
    return sys.modules["uavarm_fuzz_run"]


@pytest.fixture(scope="module")
def runner():
    require_clang_fuzzer()
    return _load_runner()


def test_every_harness_listed_and_seeded():
    run = _load_runner()
    assert set(run.HARNESSES) == set(SHORT_RUNS) == set(MIN_COV)
    for name in run.HARNESSES:
        assert (run._harness_source(name) if name in run.C_HARNESSES else ROOT / "fuzz" / f"{name}.py").is_file()
        seeds = [p for p in (run.SEEDS / name).iterdir() if p.is_file()]
        assert 3 <= len(seeds) <= 20, name
        max_len = int(next(f for f in run.OPTIONS[name] if f.startswith("-max_len=")).split("=")[1])
        assert all(0 < p.stat().st_size <= max_len for p in seeds), name


@pytest.mark.parametrize("name", ["llcp_rx", "dxl_parser", "dxl2_parser", "app_link", "app_link_x", "model_loader"])
def test_seed_corpus_replays_clean(runner, name):
    result = runner.replay(name)
    n_seeds = sum(1 for p in (runner.SEEDS / name).iterdir() if p.is_file())
    assert result.returncode == 0, f"{name}: seed replay failed, see {result.log}"
    assert result.inputs == n_seeds


@pytest.mark.parametrize("name", ["app_link", "app_link_x"])
def test_app_link_seeds_reach_every_state(runner, name):
    """The seeds drive the application through configuration into the engaged, stabilising
    state, through disable, link loss, IMU faults (absent, asleep, full scale) and servo
    faults (errors, configuration, a stuck shaft, a brown-out): the fuzzer starts deep. On the
    X-series (app_link_x) the brown-out is seen through the lost status map."""
    exe = runner.build(name)
    seeds = sorted(p for p in (runner.SEEDS / name).iterdir() if p.is_file())
    proc = subprocess.run([str(exe), *map(str, seeds)], capture_output=True, text=True,
                          env={**os.environ, "APP_LINK_TRACE": "1"}, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = [dict(re.findall(r"(\w+) (0x[0-9a-f]+|\d+)", line))
             for line in proc.stderr.splitlines() if line.startswith("app_link:")]
    # one line per seed; libFuzzer has been seen to add a run (an extra line) right after a
    # rebuild, which changes nothing below: every state must still be reached
    assert len(lines) >= len(seeds)
    assert any(int(s["engaged_sync_writes"]) >= 10 for s in lines)
    assert any(int(s["heartbeats"]) >= 2 for s in lines)
    faults = 0
    for s in lines:
        faults |= int(s["faults"], 16)
    # servo_error, servo_config, imu, link_lost, imu_saturated, servo_tracking, servo_reset: each reached
    names = ("servo_error", "servo_config", "imu", "link_lost", "imu_saturated", "servo_tracking", "servo_reset")
    want = sum(1 << i for i, (name, _) in enumerate(FAULTS) if name in names)
    assert faults & want == want, hex(faults)
    assert any(int(s["resets"]) >= 1 for s in lines)
    if name == "app_link_x":
        assert any(int(s["remaps"]) >= 1 for s in lines)


def test_short_fuzz_run_finds_nothing(runner, tmp_path):
    """Every harness fuzzed for its SHORT_RUNS inputs, two at a time, each from its
    committed seeds alone (new inputs go to a fresh folder, not build/fuzz/corpus): no
    finding, every input run, at least MIN_COV edges each. One test, not one per harness:
    the run happens once per test run, not once in each process that gets one of them."""
    for name in runner.C_HARNESSES:
        runner.build(name)

    def run(name):
        return runner.fuzz(name, runs=SHORT_RUNS[name], extra=(f"-seed={SEED}",), work=tmp_path / name)
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(run, ["app_link", "app_link_x", "model_loader", "dxl_parser", "dxl2_parser", "llcp_rx"]))
    print("\n" + runner.table(results))
    failed = []
    for r in results:
        name = r.name
        if r.findings != 0:
            failed.append(f"{name}: {[str(a) for a in r.artifacts]} exit {r.returncode}, see {r.log}")
        if r.inputs < SHORT_RUNS[name]:
            failed.append(f"{name}: stopped after {r.inputs} inputs, see {r.log}")
        if r.cov is None or r.cov < MIN_COV[name]:
            failed.append(f"{name}: covered {r.cov} edges, see {r.log}")
    assert not failed, "\n".join(failed)
