"""Build and run the fuzz harnesses; print inputs executed and findings per harness.

    .venv/bin/python fuzz/run.py                       # every harness, 20 s each
    .venv/bin/python fuzz/run.py --time 900 --workers 2 app_link   # both cores on one harness
    .venv/bin/python fuzz/run.py --runs 10000000 llcp_rx dxl_parser dxl2_parser
    .venv/bin/python fuzz/run.py --replay              # each committed seed once

C harnesses (fuzz/<name>.c) are built with clang's libFuzzer, AddressSanitizer and
UndefinedBehaviorSanitizer (every report fatal) and the project's warning flags into
build/fuzz/<name>; the model-file harness runs under atheris. Each harness starts from its
committed seeds (fuzz/corpus/<name>/, read only) and from what earlier runs found
(build/fuzz/corpus/<name>/, where new inputs go). A crash, sanitizer report, leak or
timeout leaves its input in build/fuzz/artifacts/<name>/ and counts as a finding; the
full log is build/fuzz/logs/<name>.log. Exit status 1 if any harness has a finding.

Environment: FUZZ_CC (default clang, else clang-14).
"""
from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from uavarm.build import cbuild, firmware, generated  # noqa: E402

FUZZ = ROOT / "fuzz"
SEEDS = FUZZ / "corpus"
OUT = ROOT / "build" / "fuzz"
APP_SRC = firmware.APP / "Src"
INCLUDE_DIRS = [generated.GENERATED, firmware.APP / "Inc", OUT]   # OUT: arm_spec.h (write_arm_spec)

SANITIZE = ["-g", "-O1", "-fsanitize=fuzzer,address,undefined", "-fno-sanitize-recover=all"]
# The project's warning set (uavarm/build/cbuild.py), and the host build's float32 semantics.
FLAGS = SANITIZE + cbuild.WARNING_FLAGS + ["-ffp-contract=off", "-fno-math-errno"]


def _c_sources(name: str) -> list[Path]:
    if name == "app_link_x":
        return firmware.app_sources(_xseries()[1])
    if name == "llcp_rx":
        return [APP_SRC / "llcp.c", generated.GENERATED / "messages.c"]
    if name == "dxl_parser":
        return [APP_SRC / "dxl_protocol.c"]
    if name == "dxl2_parser":
        return [APP_SRC / "dxl_protocol2.c"]
    if name == "app_link":
        return firmware.app_sources()
    raise KeyError(name)


# app_link_x: fuzz/app_link.c built from the model file made an arm of XM430-W350s
C_HARNESSES = ("llcp_rx", "dxl_parser", "dxl2_parser", "app_link", "app_link_x")
PY_HARNESSES = ("model_loader",)
HARNESSES = C_HARNESSES + PY_HARNESSES
# libFuzzer options per harness: longest input, and how long one input may take.
OPTIONS = {
    "llcp_rx": ["-max_len=1024", "-timeout=10"],
    "dxl_parser": ["-max_len=1024", "-timeout=10"],
    "dxl2_parser": ["-max_len=2048", "-timeout=10"],
    "app_link": ["-max_len=1024", "-timeout=10"],
    "app_link_x": ["-max_len=1024", "-timeout=10"],
    "model_loader": ["-max_len=16384", "-timeout=30", f"-dict={FUZZ / 'model_loader.dict'}"],
}


class FuzzSetupError(RuntimeError):
    """The compiler, libFuzzer or atheris is missing or failed."""


def compiler() -> str | None:
    env = os.environ.get("FUZZ_CC")
    if env:
        return shutil.which(env)
    return shutil.which("clang") or shutil.which("clang-14")


def libfuzzer_available() -> bool:
    """Does the compiler link a libFuzzer + ASan + UBSan program?"""
    cc = compiler()
    if cc is None:
        return False
    OUT.mkdir(parents=True, exist_ok=True)
    probe = OUT / "probe.c"
    probe.write_text("#include <stddef.h>\n#include <stdint.h>\n"
                     "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n);\n"
                     "int LLVMFuzzerTestOneInput(const uint8_t *d, size_t n) { (void)d; (void)n; return 0; }\n")
    proc = subprocess.run([cc, *SANITIZE, str(probe), "-o", str(OUT / "probe")], capture_output=True)
    return proc.returncode == 0


def atheris_available() -> bool:
    proc = subprocess.run([sys.executable, "-c", "import atheris"], capture_output=True)
    return proc.returncode == 0


# Position units per degree, from the servos' e-manuals: the AX-12A's 1023 over 300 degrees,
# the X-series' 4096 a turn.
UNITS_PER_DEG = {"AX-12A": "(1023.0f / 300.0f)", "XL430-W250": "(4096.0f / 360.0f)",
                 "XM430-W350": "(4096.0f / 360.0f)"}


def _xseries() -> tuple[Path, Path]:
    """(model file, generated folder) of the committed model file made an arm of XM430-W350s."""
    from uavarm.build import variants
    _, gen_dir = variants.generate(variants.XM430_EDITS)
    return gen_dir.parent / "manipulator.toml", gen_dir


def _harness_source(name: str) -> Path:
    return FUZZ / ("app_link.c" if name == "app_link_x" else f"{name}.c")


def _include_dirs(name: str) -> list[Path]:
    """The generated code, the application's headers and arm_spec.h of a harness's model."""
    if name == "app_link_x":
        model_file, gen_dir = _xseries()
        write_arm_spec(model_file, OUT / "xm430")
        return [gen_dir, firmware.APP / "Inc", OUT / "xm430"]
    write_arm_spec()
    return INCLUDE_DIRS


def write_arm_spec(model_file: Path = ROOT / "model" / "manipulator.toml", out: Path = OUT) -> None:
    """out/arm_spec.h: the arm's numbers for fuzz/plain_arm.h, read from the model file with
    tomllib (not through the code generator)."""
    raw = tomllib.loads(model_file.read_text())
    joints = [raw["joints"][j] for j in ("theta1", "theta2", "theta3")]
    servos = [raw["servo"][j] for j in ("theta1", "theta2", "theta3")]
    geo, col = raw["geometry"], raw["collision"]

    def floats(values):
        return "{ " + ", ".join(f"{float(v)!r}f" for v in values) + " }"
    text = "\n".join([
        f"/* from {model_file.name} by fuzz/run.py: the fuzzers' plain-geometry judge (plain_arm.h) */",
        *(f"#define ARM_{k} {float(geo[k])!r}f" for k in ("L1", "L2", "L3")),
        f"#define ARM_JOINT_MIN_DEG {floats(j['min'] for j in joints)}",
        f"#define ARM_JOINT_MAX_DEG {floats(j['max'] for j in joints)}",
        f"#define ARM_BODY_Z {float(col['body_z'])!r}f",
        f"#define ARM_LEG_ANGLES_DEG {floats(col['leg_angles'])}",
        f"#define ARM_LEG_HALF_WIDTH_DEG {float(col['leg_half_width'])!r}f",
        f"#define ARM_LEG_DISTANCE {float(col['leg_distance'])!r}f",
        f"#define ARM_SERVO_ZERO {floats(s['zero'] for s in servos)}",
        f"#define ARM_SERVO_DIRECTION {floats(s['direction'] for s in servos)}",
        f"#define ARM_UNITS_PER_DEG {UNITS_PER_DEG[raw['servo'].get('model', 'AX-12A')]}", ""])
    out.mkdir(parents=True, exist_ok=True)
    header = out / "arm_spec.h"
    if not header.exists() or header.read_text() != text:
        header.write_text(text)


def build(name: str) -> Path:
    """build/fuzz/<name>, rebuilt when its sources, headers, flags or compiler change."""
    cc = compiler()
    if cc is None:
        raise FuzzSetupError("clang not found (apt-get install clang libclang-rt-14-dev)")
    include_dirs = _include_dirs(name)
    sources = [_harness_source(name)] + _c_sources(name)
    flags = FLAGS + [f"-I{d}" for d in include_dirs]
    digest = hashlib.sha256(" ".join([cc, *flags]).encode())
    for path in sources + sorted(p for d in include_dirs for p in d.glob("*.h")):
        digest.update(str(path).encode() + b"\0" + path.read_bytes())
    exe = OUT / name
    stamp = OUT / f"{name}.sha256"
    with cbuild.exclusive(OUT / f"{name}.lock"):    # parallel test processes build it once
        if exe.exists() and stamp.exists() and stamp.read_text() == digest.hexdigest():
            return exe
        stamp.unlink(missing_ok=True)
        tmp = OUT / f"{name}.tmp{os.getpid()}"
        cmd = [cc, *flags, *map(str, sources), "-lm", "-o", str(tmp)]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise FuzzSetupError(f"{' '.join(cmd)}\n{proc.stderr}")
        tmp.replace(exe)      # atomic: a harness already running keeps its own file
        stamp.write_text(digest.hexdigest())
    return exe


def command(name: str) -> list[str]:
    if name in PY_HARNESSES:
        return [sys.executable, str(FUZZ / f"{name}.py")]
    return [str(build(name))]


@dataclass
class Result:
    name: str
    inputs: int = 0
    seconds: float = 0.0
    cov: int | None = None          # libFuzzer "cov": covered code edges (atheris: Python + C)
    ft: int | None = None           # libFuzzer "ft": features (edge counters, value profiles)
    corpus: int | None = None
    returncode: int = 0
    artifacts: list[Path] = field(default_factory=list)   # crashes, leaks, timeouts, OOMs
    slow: list[Path] = field(default_factory=list)        # inputs slower than 10 s (not failures)
    log: Path | None = None

    @property
    def findings(self) -> int:
        return len(self.artifacts) or (1 if self.returncode != 0 else 0)

    @property
    def exec_per_s(self) -> float:
        return self.inputs / self.seconds if self.seconds > 0 else 0.0


_STATUS = re.compile(r"^#(\d+)\s+\w+\s+cov: (\d+) ft: (\d+) corp: (\d+)", re.M)
_EXECUTED = re.compile(r"stat::number_of_executed_units: (\d+)")
_DONE = re.compile(r"Done (\d+) runs in")


def _env() -> dict:
    env = dict(os.environ)
    env.setdefault("ASAN_OPTIONS", "detect_leaks=1:abort_on_error=0")
    env.setdefault("UBSAN_OPTIONS", "print_stacktrace=1")
    return env


def fuzz(name: str, *, seconds: float | None = None, runs: int | None = None, workers: int = 1,
         extra: tuple[str, ...] = (), work: Path | None = None) -> Result:
    """Run one harness for `seconds` and/or `runs` inputs (per worker). workers > 1: that
    many fuzzer processes side by side on the same corpus folder (each picks up what the
    others add, libFuzzer -reload); their inputs are added up, coverage is the best one's.
    work: the folder new inputs go to and earlier runs' are read from (default
    build/fuzz/corpus/<name>)."""
    cmd = command(name)
    work = work if work is not None else OUT / "corpus" / name
    artifacts = OUT / "artifacts" / name
    logs = OUT / "logs"
    for d in (work, artifacts, logs):
        d.mkdir(parents=True, exist_ok=True)
    before = set(artifacts.iterdir())
    args = [*OPTIONS[name], f"-artifact_prefix={artifacts}/", "-print_final_stats=1"]
    if seconds is not None:
        args.append(f"-max_total_time={int(seconds)}")
    if runs is not None:
        args.append(f"-runs={runs}")
    log_files = [logs / (f"{name}.log" if i == 0 else f"{name}.{i}.log") for i in range(max(1, workers))]
    start = time.monotonic()
    procs = []
    for log in log_files:
        with open(log, "w") as out:
            procs.append(subprocess.Popen([*cmd, *args, *extra, str(work), str(SEEDS / name)],
                                          stdout=out, stderr=subprocess.STDOUT, env=_env(), cwd=ROOT))
    codes = [p.wait() for p in procs]
    elapsed = time.monotonic() - start
    new = sorted(set(artifacts.iterdir()) - before)
    parts = [_result(name, log.read_text(errors="replace"), code, elapsed, [], [], log)
             for log, code in zip(log_files, codes)]
    r = max(parts, key=lambda p: (p.returncode != 0, p.ft or 0))
    r.inputs = sum(p.inputs for p in parts)
    r.artifacts = [p for p in new if not p.name.startswith("slow-unit-")]
    r.slow = [p for p in new if p.name.startswith("slow-unit-")]
    return r


def _result(name, text, returncode, elapsed, artifacts, slow, log) -> Result:
    r = Result(name, seconds=elapsed, returncode=returncode, artifacts=artifacts, slow=slow, log=log)
    executed = _EXECUTED.findall(text) or _DONE.findall(text)
    statuses = _STATUS.findall(text)
    if executed:
        r.inputs = int(executed[-1])
    elif statuses:
        r.inputs = int(statuses[-1][0])
    if statuses:
        r.cov, r.ft, r.corpus = (int(x) for x in statuses[-1][1:])
    return r


def replay(name: str, inputs: list[Path] | None = None) -> Result:
    """Run each committed seed (or the given files) once."""
    files = inputs if inputs is not None else sorted(p for p in (SEEDS / name).iterdir() if p.is_file())
    cmd = command(name)
    start = time.monotonic()
    proc = subprocess.run([*cmd, *OPTIONS[name], *map(str, files)], capture_output=True, text=True,
                          env=_env(), cwd=ROOT)
    text = proc.stdout + proc.stderr
    r = Result(name, seconds=time.monotonic() - start, returncode=proc.returncode)
    r.inputs = len(re.findall(r"^Executed ", text, re.M))
    if proc.returncode != 0:
        logs = OUT / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        r.log = logs / f"{name}.replay.log"
        r.log.write_text(text)
    return r


_REPLAY_MAIN = """\
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int main(int argc, char **argv)
{
    static uint8_t buf[1 << 16];
    for (int i = 1; i < argc; ++i) {
        FILE *f = fopen(argv[i], "rb");
        if (f == NULL) return 1;
        size_t n = fread(buf, 1, sizeof buf, f);
        fclose(f);
        LLVMFuzzerTestOneInput(buf, n);
    }
    return 0;
}
"""


def coverage(name: str) -> str:
    """Line and branch coverage of the firmware sources reached by a C harness's corpus
    (the committed seeds and what runs added): clang source-based coverage, no sanitizers."""
    cc = compiler()
    tools = {t: shutil.which(t) or shutil.which(f"{t}-14") for t in ("llvm-profdata", "llvm-cov")}
    if cc is None or None in tools.values():
        raise FuzzSetupError("coverage needs clang, llvm-profdata and llvm-cov (Debian llvm-14)")
    include_dirs = _include_dirs(name)
    out = OUT / "coverage" / name
    out.mkdir(parents=True, exist_ok=True)
    (out / "main.c").write_text(_REPLAY_MAIN)
    exe = out / name
    targets = _c_sources(name)
    rel = lambda p: str(p.relative_to(ROOT))
    cmd = [cc, "-O0", "-g", "-fprofile-instr-generate", "-fcoverage-mapping", *cbuild.WARNING_FLAGS,
           *[f"-I{rel(d)}" for d in include_dirs], rel(_harness_source(name)), *map(rel, targets),
           str(out / "main.c"), "-lm", "-o", str(exe)]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise FuzzSetupError(f"{' '.join(cmd)}\n{proc.stderr}")
    files = [p for d in (OUT / "corpus" / name, SEEDS / name) if d.is_dir() for p in sorted(d.iterdir())]
    raw = out / "default.profraw"
    for i in range(0, len(files), 500):
        subprocess.run([str(exe), *map(str, files[i:i + 500])], check=True, capture_output=True, cwd=ROOT,
                       env={**os.environ, "LLVM_PROFILE_FILE": str(out / f"part{i}.profraw")})
    parts = sorted(out.glob("part*.profraw"))
    subprocess.run([tools["llvm-profdata"], "merge", "-o", str(out / "merged.profdata"), *map(str, parts)],
                   check=True)
    for p in parts + [raw]:
        p.unlink(missing_ok=True)
    # the protocol harnesses reach only the receiving functions of their files: per function
    per_function = ["-show-functions"] if name in ("llcp_rx", "dxl_parser", "dxl2_parser") else []
    report = subprocess.run([tools["llvm-cov"], "report", str(exe), f"-instr-profile={out / 'merged.profdata'}",
                             *per_function, *(str(t.relative_to(ROOT)) for t in targets)],
                            check=True, capture_output=True, text=True, cwd=ROOT).stdout
    return f"{name}: {len(files)} inputs\n{report}"


def table(results: list[Result]) -> str:
    rows = [("harness", "inputs", "seconds", "exec/s", "cov", "ft", "corpus", "findings")]
    for r in results:
        rows.append((r.name, f"{r.inputs:,}", f"{r.seconds:.0f}", f"{r.exec_per_s:,.0f}",
                     str(r.cov or "-"), str(r.ft or "-"), str(r.corpus or "-"), str(r.findings)))
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(row, widths)))
             for row in rows]
    for r in results:
        for a in r.artifacts:
            lines.append(f"finding: {r.name}: {a.relative_to(ROOT)} (log {r.log.relative_to(ROOT)})")
        if r.findings and not r.artifacts and r.log:
            lines.append(f"finding: {r.name}: exit status {r.returncode} (log {r.log.relative_to(ROOT)})")
        for a in r.slow:
            lines.append(f"slow input (not a failure): {r.name}: {a.relative_to(ROOT)}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("harness", nargs="*", help=f"default: all of {', '.join(HARNESSES)}")
    ap.add_argument("--time", type=float, help="seconds per harness (default 20 unless --runs)")
    ap.add_argument("--runs", type=int, help="inputs per harness")
    ap.add_argument("--jobs", type=int, default=1, help="harnesses run side by side")
    ap.add_argument("--workers", type=int, default=1, help="fuzzer processes per harness, side by side")
    ap.add_argument("--replay", action="store_true", help="run each committed seed once")
    ap.add_argument("--coverage", action="store_true",
                    help="line/branch coverage of the firmware sources by each C harness's corpus")
    args = ap.parse_args(argv)
    names = args.harness or list(HARNESSES)
    unknown = sorted(set(names) - set(HARNESSES))
    if unknown:
        ap.error(f"unknown harness {', '.join(unknown)}; known: {', '.join(HARNESSES)}")
    if args.time is None and args.runs is None:
        args.time = 20
    for name in names:
        if name in C_HARNESSES:
            build(name)
        elif not atheris_available():
            raise FuzzSetupError("atheris missing: pip install atheris")
    if args.coverage:
        for name in names:
            if name in C_HARNESSES:
                print(coverage(name))
        return 0
    if args.replay:
        results = [replay(n) for n in names]
    else:
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            results = list(pool.map(lambda n: fuzz(n, seconds=args.time, runs=args.runs, workers=args.workers),
                                    names))
    print(table(results))
    return 1 if any(r.findings for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
