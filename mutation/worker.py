"""A worker's copy of the tree under build/mutate/, where one mutant at a time is applied,
built (regenerating generated/ where the target asks), tested and undone.

The copy holds the files git knows of (tracked and new, not ignored) and imports as the
`uavarm` package from itself (PYTHONPATH, with `uavarm/model` and `uavarm/codegen` linked to
their folders as the editable install maps them), so the tests run against its files."""
from __future__ import annotations

import fcntl
import itertools
import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .operators import Mutant
from .targets import FRESHNESS_TESTS, Target

ROOT = Path(__file__).resolve().parents[1]
BUILD_CHECK = ("from uavarm.build import firmware, generated; generated.load(); firmware.load()")


@dataclass
class Outcome:
    status: str        # killed | survived | timeout | stillborn | same_code
    seconds: float
    detail: str = ""


# A mutant's tests may take this many times the unmutated run's before they count as hung.
TIMEOUT_FACTOR = 10
TIMEOUT_MIN_S = 60.0


class TestsFail(RuntimeError):
    """A target's tests fail on the unmutated tree: no mutant of it can be judged."""


def tree_files(root: Path = ROOT) -> list[str]:
    out = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"], cwd=root,
                         capture_output=True, check=True).stdout.decode()
    return [p for p in out.split("\0") if p and (root / p).is_file()]


class Worker:
    """Takes the first of base/w0, w1, ... that no other worker (of this run or another)
    holds, and holds it while it lives."""

    def __init__(self, base: Path, timeout: float | None):
        for k in itertools.count():
            self.dir = base / f"w{k}"
            self.dir.mkdir(parents=True, exist_ok=True)
            self._lock = (self.dir / ".lock").open("w")
            try:
                fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                self._lock.close()
        self.timeout = timeout          # None: TIMEOUT_FACTOR x each target's unmutated run
        self._timeouts: dict[str, float] = {}
        self.env = dict(os.environ, PYTHONPATH=str(self.dir), PYTHONDONTWRITEBYTECODE="1")
        self.env.pop("CI", None)

    def prepare(self) -> None:
        """A fresh copy of the tree (its build folder kept: the host builds are cached by
        content)."""
        for path in tree_files():
            dst = self.dir / path
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / path, dst)
        for pkg in ("model", "codegen"):
            link = self.dir / "uavarm" / pkg
            if not link.is_symlink():
                link.symlink_to(Path("..") / pkg)
        self._generated = {p.name: p.read_bytes() for p in (self.dir / "generated").iterdir()}

    def _run(self, args, timeout):
        return subprocess.run([sys.executable, *args], cwd=self.dir, env=self.env, capture_output=True, text=True,
                              timeout=timeout)

    def _restore_generated(self) -> None:
        gen = self.dir / "generated"
        for p in gen.iterdir():
            if p.name not in self._generated:
                p.unlink()
        for name, data in self._generated.items():
            if (gen / name).read_bytes() != data:
                (gen / name).write_bytes(data)

    def _same_code(self) -> bool:
        """The regenerated files equal the committed ones but for the header's hashes."""
        def body(data: bytes) -> list[bytes]:
            return [ln for ln in data.splitlines() if b"sha256" not in ln]
        gen = self.dir / "generated"
        return all(body((gen / n).read_bytes()) == body(d) for n, d in self._generated.items())

    def _test_args(self, target: Target) -> list[str]:
        args = ["-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", *target.tests]
        return args + [f"--deselect={t}" for t in FRESHNESS_TESTS]

    def timeout_for(self, target: Target) -> float:
        """The seconds a mutant's test run may take: the fixed --timeout, or TIMEOUT_FACTOR
        times the target's tests on the unmutated copy (run once per worker and target,
        when the machine is as busy as it is for the mutants), at least TIMEOUT_MIN_S."""
        if self.timeout is not None:
            return self.timeout
        if target.name not in self._timeouts:
            t0 = time.monotonic()
            res = self._run(self._test_args(target), None)
            took = time.monotonic() - t0
            if res.returncode != 0:
                raise TestsFail(f"{target.name}: the tests fail without a mutant:\n{res.stdout[-2000:]}")
            self._timeouts[target.name] = max(TIMEOUT_MIN_S, TIMEOUT_FACTOR * took)
            print(f"{target.name}: unmutated tests {took:.0f} s, a mutant's may take "
                  f"{self._timeouts[target.name]:.0f} s", flush=True)
        return self._timeouts[target.name]

    def run(self, target: Target, mutant: Mutant) -> Outcome:
        timeout = self.timeout_for(target)      # (on the unmutated copy: before the mutant is made)
        path = self.dir / mutant.path
        original = path.read_text()
        t0 = time.monotonic()
        try:
            path.write_text(mutant.apply(original))
            if target.regenerate:
                gen = self._run(["-m", "uavarm.codegen"], 600)
                if gen.returncode != 0:
                    broken = any(e in gen.stderr for e in ("SyntaxError", "IndentationError", "NameError",
                                                          "TemplateSyntaxError"))
                    return Outcome("stillborn" if broken else "killed", time.monotonic() - t0,
                                   "generator: " + (gen.stderr.strip().splitlines() or ["?"])[-1])
                if self._same_code():
                    return Outcome("same_code", time.monotonic() - t0)
            build = self._run(["-c", BUILD_CHECK], 600)
            if build.returncode != 0:
                return Outcome("stillborn", time.monotonic() - t0, "does not compile")
            try:
                res = self._run(self._test_args(target), timeout)
            except subprocess.TimeoutExpired:
                # a hang the suite would show only as a run that never ends: not counted as killed
                return Outcome("timeout", time.monotonic() - t0, f"tests still running after {timeout:.0f} s")
            if res.returncode == 0:
                return Outcome("survived", time.monotonic() - t0)
            if res.returncode == 1:
                failed = [ln for ln in res.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))]
                return Outcome("killed", time.monotonic() - t0, (failed or ["?"])[0][:200])
            if res.returncode < 0:
                return Outcome("killed", time.monotonic() - t0, f"the tests crashed (signal {-res.returncode})")
            return Outcome("error", time.monotonic() - t0, res.stdout[-300:])
        finally:
            path.write_text(original)
            if target.regenerate:
                self._restore_generated()
