"""The generated C (generated/*.c) built for the host with the target's flags, via cffi."""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from . import cbuild

GENERATED = cbuild.ROOT / "generated"
# Every generated file's header names the model file and the first 16 hex digits of its SHA-256.
_MODEL_LINE = re.compile(r"^ \* Model: .*\(sha256 ([0-9a-f]{16})\)$", re.M)


class StaleCode(ValueError):
    """The generated code was not generated from the model file in use."""


def check_current(model, folder: Path | None = None) -> None:
    """StaleCode unless every generated file in folder (default generated/) carries the hash
    of `model`'s file: a model edited without `make codegen` would run the old numbers."""
    folder = GENERATED if folder is None else folder
    files = sorted(folder.glob("*.[ch]"))
    if not files:
        raise StaleCode(f"{folder}: no generated code: run `make codegen`")
    for path in files:
        found = _MODEL_LINE.search(path.read_text())
        if found is None or found.group(1) != model.sha256[:16]:
            raise StaleCode(f"{model.path} changed since {path} was generated (model sha256 "
                            f"{model.sha256[:16]}, generated from {found.group(1) if found else 'unknown'}): "
                            f"run `make codegen`")


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
