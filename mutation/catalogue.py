"""The mutants of each target, from its file as it stands."""
from __future__ import annotations

import hashlib
from pathlib import Path

from . import regions
from .operators import Mutant, mutants
from .targets import Target

ROOT = Path(__file__).resolve().parents[1]


def file_digest(path: str) -> str:
    return hashlib.sha256((ROOT / path).read_bytes()).hexdigest()[:16]


def target_mutants(target: Target) -> list[Mutant]:
    text = (ROOT / target.path).read_text()
    python = target.path.endswith(".py")
    masked = (regions.mask_python(text) if python else
              regions.mask_template(text) if target.path.endswith(".j2") else regions.mask_c(text))
    spans = []
    for kind, *args in target.spans:
        if kind == "c":
            spans.append(regions.c_function(masked, *args))
        elif kind == "py":
            spans.append(regions.python_function(masked, *args))
        else:
            spans.append(regions.marked(masked, *args))
    return mutants(target.path, text, masked, spans, python)
