"""The generated C (generated/*.c) built for the host with the target's flags, via cffi."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from . import cbuild

GENERATED = cbuild.ROOT / "generated"


def sources(folder: Path = GENERATED) -> list[Path]:
    return sorted(folder.glob("*.c"))


def headers(folder: Path = GENERATED) -> list[Path]:
    return [h for h in sorted(folder.glob("*.h")) if "cffi:begin" in h.read_text()]


def load(folder: Path = GENERATED):
    """(ffi, lib) for the generated code in `folder`."""
    return cbuild.load("generated", sources(folder), headers(folder), include_dirs=[folder])


@lru_cache(maxsize=None)
def default():
    return load()
