"""The results file (build/mutate/results.jsonl: one JSON object per mutant run, appended as
each finishes, so an interrupted run resumes where it stopped) and the list of mutants
judged equivalent or accepted (mutation/equivalent.toml, with the reason for each)."""
from __future__ import annotations

import json
import threading
import tomllib
from pathlib import Path

EQUIVALENT = Path(__file__).with_name("equivalent.toml")
FINAL = ("killed", "survived", "timeout", "stillborn", "same_code")


class Results:
    def __init__(self, path: Path):
        self.path = path
        self.lock = threading.Lock()
        self.done: dict[tuple[str, str], dict] = {}
        if path.exists():
            for line in path.read_text().splitlines():
                rec = json.loads(line)
                if rec["status"] in FINAL:
                    self.done[(rec["id"], rec["digest"])] = rec

    def get(self, mutant_id: str, digest: str) -> dict | None:
        return self.done.get((mutant_id, digest))

    def add(self, rec: dict) -> None:
        with self.lock:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            with self.path.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            if rec["status"] in FINAL:
                self.done[(rec["id"], rec["digest"])] = rec


def equivalents() -> dict[str, str]:
    """mutant id -> why it is equivalent (or accepted)."""
    if not EQUIVALENT.exists():
        return {}
    return {e["id"]: e["why"] for e in tomllib.loads(EQUIVALENT.read_text()).get("mutant", [])}
