"""Build project C sources for the host with the target's strict flags and load them with cffi.

The C is compiled by the system compiler exactly like the firmware (C99, warnings as
errors, -Wdouble-promotion) into a shared library, and opened in cffi's ABI mode, so the
Python side calls the very functions the STM32 runs; no cffi wrapper C is compiled.

The cffi declarations come from the headers themselves: each header marks the part cffi
must see between the lines `/* cffi:begin */` and `/* cffi:end */` (types, #define'd
integer constants and prototypes only), so nothing is declared twice.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import re
import subprocess
from pathlib import Path

import cffi

ROOT = Path(__file__).resolve().parents[2]
BUILD_DIR = ROOT / "build" / "host"

# The warning set every C file of the project must pass, on the host and on the target.
WARNING_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-Wshadow"]
# -fno-math-errno lets sqrtf be one instruction; it changes no result.
COMMON_FLAGS = WARNING_FLAGS + ["-O2", "-fno-math-errno"]
# Host only: no fused multiply-add, so host results are plain IEEE float32 arithmetic.
HOST_FLAGS = COMMON_FLAGS + ["-ffp-contract=off", "-fPIC"]
TARGET_FLAGS = COMMON_FLAGS + ["-mcpu=cortex-m4", "-mthumb", "-mfpu=fpv4-sp-d16", "-mfloat-abi=hard"]

_CDEF_BLOCK = re.compile(r"/\* cffi:begin \*/\n(.*?)/\* cffi:end \*/", re.S)


class CBuildError(RuntimeError):
    """The C compiler rejected a source; the message carries its output."""


def cdef_of(headers) -> str:
    parts = []
    for header in headers:
        blocks = _CDEF_BLOCK.findall(Path(header).read_text())
        if not blocks:
            raise CBuildError(f"{header}: no /* cffi:begin */ ... /* cffi:end */ block")
        parts.extend(blocks)
    return "\n".join(parts)


@contextlib.contextmanager
def exclusive(lock_path: Path):
    """Holds an exclusive lock on lock_path (created if need be) while the block runs: the
    processes of a parallel test run that need the same build wait for one to make it."""
    lock_path.parent.mkdir(parents=True, exist_ok=True)
    with open(lock_path, "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        yield


def build_shared(name: str, sources, include_dirs=(), extra_flags=(), cc: str | None = None) -> Path:
    """Compile `sources` into build/host/<name>-<hash>.so; reuse it while nothing changed."""
    cc = cc or os.environ.get("CC", "cc")
    sources = [Path(s) for s in sources]
    include_dirs = [Path(d) for d in include_dirs]
    flags = HOST_FLAGS + list(extra_flags) + [f"-I{d}" for d in include_dirs]
    digest = hashlib.sha256(" ".join([cc] + flags).encode())
    for path in sorted(sources) + sorted(p for d in include_dirs for p in d.glob("*.h")):
        digest.update(str(path).encode())
        digest.update(path.read_bytes())
    out = BUILD_DIR / f"{name}-{digest.hexdigest()[:16]}.so"
    if out.exists():
        return out
    with exclusive(out.with_suffix(".lock")):   # parallel test processes compile it once
        if out.exists():
            return out
        tmp = out.with_suffix(f".tmp{os.getpid()}")
        cmd = [cc, *flags, "-shared", "-o", str(tmp), *map(str, sources), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise CBuildError(f"{' '.join(cmd)}\n{proc.stderr}")
        tmp.replace(out)  # atomic: a process that did not wait never loads a half-written file
    return out


def load(name: str, sources, headers, include_dirs=(), extra_flags=()):
    """Build (if needed) and open the library; returns (ffi, lib)."""
    so = build_shared(name, sources, include_dirs, extra_flags)
    ffi = cffi.FFI()
    ffi.cdef(cdef_of(headers))
    return ffi, ffi.dlopen(str(so))
