"""Calibration results into the model file, keeping its comments and layout (tomlkit): the
new text is parsed by the model loader before anything is written, so a result the loader
would refuse never reaches the file."""
from __future__ import annotations

import difflib
from pathlib import Path

import tomlkit

from ..model import config


def edited(path: Path, values: dict[str, object]) -> tuple[str, str]:
    """(old text, new text) of the model file with each dotted key set to its value;
    ModelError if the result is not a valid model."""
    old = path.read_text()
    doc = tomlkit.parse(old)
    for key, value in values.items():
        *tables, name = key.split(".")
        node = doc
        for table in tables:
            node = node[table]
        node[name] = value
    new = tomlkit.dumps(doc)
    config.parse(new.encode(), path)
    return old, new


def diff(path: Path, old: str, new: str) -> str:
    return "".join(difflib.unified_diff(old.splitlines(True), new.splitlines(True), str(path), str(path)))


def write(path: Path, values: dict[str, object], confirm) -> bool:
    """Shows the diff, asks confirm(question) and writes; False (nothing written) if declined
    or if nothing changes."""
    old, new = edited(path, values)
    if old == new:
        print(f"{path}: unchanged")
        return False
    print(diff(path, old, new), end="")
    if not confirm(f"write these changes to {path}?"):
        print(f"{path}: left as it was")
        return False
    path.write_text(new)
    print(f"wrote {path}: run `make codegen`, then rebuild and flash the firmware")
    return True
