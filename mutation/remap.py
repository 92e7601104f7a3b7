"""Keeps mutation/equivalent.toml naming the code as it is: a mutant's id carries its line
number, so an edit above it moves it. `stale()` lists the judged ids the catalogue no longer
makes; `remap(rev)` moves each to the one line of the working tree identical to the line it
named at git revision `rev` (the column and the change stay), and leaves the others for a
developer to judge again."""
from __future__ import annotations

import subprocess

from .catalogue import ROOT, target_mutants
from .results import EQUIVALENT, equivalents
from .targets import TARGETS


def stale() -> list[str]:
    current = {mu.id for t in TARGETS for mu in target_mutants(t)}
    return [i for i in equivalents() if i not in current]


def _lines_at(root, rev: str, path: str) -> list[str] | None:
    out = subprocess.run(["git", "show", f"{rev}:{path}"], cwd=root, capture_output=True, text=True)
    return out.stdout.split("\n") if out.returncode == 0 else None


def remap(rev: str = "HEAD", ids=None, root=ROOT, listing=EQUIVALENT) -> tuple[list[tuple[str, str]], list[str]]:
    """Rewrites the listing (equivalent.toml) for `ids` (the stale ones); returns (moved:
    (old id, new id), left: ids not placed)."""
    text = listing.read_text()
    moved, left = [], []
    for old in stale() if ids is None else ids:
        path, line, rest = old.split(":", 2)
        then = _lines_at(root, rev, path)
        now = (root / path).read_text().split("\n") if (root / path).exists() else []
        hits = [k + 1 for k, x in enumerate(now) if then and int(line) <= len(then) and x == then[int(line) - 1]]
        if len(hits) != 1:
            left.append(old)
            continue
        new = f"{path}:{hits[0]}:{rest}"
        text = text.replace(f'id = "{old}"', f'id = "{new}"')
        moved.append((old, new))
    listing.write_text(text)
    return moved, left
