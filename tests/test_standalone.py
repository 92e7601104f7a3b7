"""The repository stands alone: no tracked file refers to a path or a document outside it
(the counter, the notes the code was written from), so a clone on its own builds, tests and
benches. Skipped: binary files, the fuzzers' input corpora (bytes fed to the parsers, some
of them copies of old model files) and this file, which names the patterns."""
import re
import subprocess

from conftest import ROOT

OUTSIDE = [
    r"\.\./shared", r"shared/tools", r"M4COUNT", r"m4count",      # a tool beside the clone
    r"/work/", r"/home/",                                          # absolute paths of one machine
    r"\bSPEC\b", r"DESIGN\.md", r"AX12_FACTS", r"thesis\.txt", r"\breference/",   # notes outside
]


def tracked_texts():
    names = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    for name in filter(None, names.decode().split("\0")):
        path = ROOT / name
        if name == "tests/test_standalone.py" or name.startswith("fuzz/corpus/") or not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data:
            continue
        try:
            yield name, data.decode("utf-8")
        except UnicodeDecodeError:
            continue


def test_no_tracked_file_refers_outside_the_repository():
    pattern = re.compile("|".join(OUTSIDE))
    found = [f"{name}:{n}: {line.strip()}" for name, text in tracked_texts()
             for n, line in enumerate(text.splitlines(), 1) if pattern.search(line)]
    assert not found, "references outside the repository:\n" + "\n".join(found)


def test_the_scan_sees_the_tracked_sources():
    names = {name for name, _ in tracked_texts()}
    assert {"README.md", "uavarm/m4/costs.py", "bench/run.py", ".ci/run"} <= names
