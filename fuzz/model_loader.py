"""atheris harness: the model-file loader (model/config.py) on arbitrary bytes.

    .venv/bin/python fuzz/model_loader.py [libFuzzer options] [corpus folders]

Two kinds of input:
  - any bytes: they are the model file;
  - a first byte 0x01: the rest drives up to three edits of the default model
    (model/manipulator.toml) before it is written back as TOML: a value, list element or
    whole table replaced by a number from the edges of float64 (subnormals, 1e300, inf,
    nan), an integer of up to 16,000 bits (decimal or hexadecimal), a string, a list, an
    array nested up to 1,500 deep, an inline table or a date, or deleted. Byte mutations of
    a TOML text rarely produce such values; this reaches the validation behind the parser.

The bytes go through uavarm.model.config.parse() (what load() does after reading the
file). The property: the loader either returns a model or raises config.ModelError (naming
the file and the key); no other exception escapes, whatever the bytes. A model that loads
then goes through the code generator's park check (codegen check_park), which must pass or
raise ModelError as well. check_park is a pure function of the park pose, geometry, limits
and collision numbers and costs ~15 ms of SymPy, so its verdict is remembered per value of
those (PARK_FIELDS, checked at start-up to cover what it reads): edits of the filters, the
estimator or the servo settings reuse it.

Only the loader (uavarm.model.config) is instrumented for coverage. tomllib, CPython's TOML
parser (tomli, fuzzed upstream), runs on every input but uninstrumented: instrumenting it
made each input 3.4x slower (2.5 -> 0.75 ms) and its coverage says nothing about what the
loader does with the document. SymPy is not instrumented either.
"""
from __future__ import annotations

import copy
import json
import math
import re
import sys
from pathlib import Path

import atheris

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import tomllib  # noqa: E402

with atheris.instrument_imports(include=["uavarm.model.config"]):
    from uavarm.model import config

from uavarm.codegen import generate  # noqa: E402

_PATH = Path("fuzz-input.toml")    # names the input in errors; nothing is written
_PARK: dict = {}
# The model fields codegen check_park reads (geometry, limits, collision, park pose; path only
# names the file, always _PATH here). Its verdict is remembered per value of these fields.
PARK_FIELDS = ("path", "L1", "L2", "L3", "limits", "body_z", "leg_angles", "leg_half_width",
               "leg_distance", "park_deg")


class _ParkFieldsOnly:
    """A model that lets check_park read PARK_FIELDS only: proves at start-up that the
    cache key covers everything the check depends on."""

    def __init__(self, model):
        self._model = model

    def __getattr__(self, name):
        if name not in PARK_FIELDS:
            raise AssertionError(f"codegen check_park reads model.{name}: add it to PARK_FIELDS")
        return getattr(self._model, name)


generate.check_park(_ParkFieldsOnly(config.load(config.DEFAULT_MODEL)))


def check_park(model: config.Model) -> None:
    key = tuple(getattr(model, name) for name in PARK_FIELDS)
    if key not in _PARK:
        if len(_PARK) > 4096:
            _PARK.clear()
        try:
            generate.check_park(model)
            _PARK[key] = None
        except config.ModelError as exc:
            _PARK[key] = exc
    if _PARK[key] is not None:
        raise _PARK[key]


# ------------------------------------------------------------------ edited models

with open(config.DEFAULT_MODEL, "rb") as _f:
    BASE = tomllib.load(_f)

SPECIAL_FLOATS = [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1e-300, 1e-17, 1e-9, 0.5, 1.0,
                  -1.0, 179.99999999999997, 180.0, 360.0, 1e17, 1e300, 1.7976931348623157e308,
                  -1.7976931348623157e308, math.inf, -math.inf, math.nan]


_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


class Raw(str):
    """TOML text written as is (deeply nested arrays, dates)."""


def _value(fdp, old, depth: int = 0):
    kind = fdp.ConsumeIntInRange(0, 10)
    if kind == 0:
        return fdp.PickValueInList(SPECIAL_FLOATS)
    if kind == 1:
        return fdp.ConsumeRegularFloat()
    if kind == 2:   # near the old value
        base = old if isinstance(old, float) or (type(old) is int and abs(old) < 2**64) else 1.0
        return base * fdp.ConsumeFloatInRange(-2.0, 2.0)
    if kind == 3:
        return fdp.ConsumeIntInRange(-70000, 70000)
    if kind == 4:
        return fdp.ConsumeInt(fdp.ConsumeIntInRange(8, 2000))      # up to 16,000 bits
    if kind == 5:
        return fdp.ConsumeBool()
    if kind == 6:
        return fdp.ConsumeUnicodeNoSurrogates(fdp.ConsumeIntInRange(0, 40))
    if kind == 7 and depth < 3:
        return [_value(fdp, old, depth + 1) for _ in range(fdp.ConsumeIntInRange(0, 5))]
    if kind == 8:
        d = fdp.ConsumeIntInRange(1, 1500)
        return Raw("[" * d + "0" + "]" * d)
    if kind == 9 and depth < 3:
        return {fdp.ConsumeUnicodeNoSurrogates(8): _value(fdp, old, depth + 1)
                for _ in range(fdp.ConsumeIntInRange(0, 3))}
    return Raw("1979-05-27T07:32:00Z")


def _toml(v) -> str:
    if isinstance(v, Raw):
        return str(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        if v.bit_length() > 14000 or (v > 0 and v.bit_length() > 64 and v % 2):
            return f"0x{abs(v):x}"    # (Python prints at most 4,300 decimal digits)
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return "{" + ", ".join(f"{_key(k)} = {_toml(x)}" for k, x in v.items()) + "}"


def _key(k: str) -> str:
    """A bare key where TOML allows one (cheaper to parse), else a quoted one."""
    return k if _BARE_KEY.fullmatch(k) else json.dumps(k, ensure_ascii=False)


def _dump(doc: dict, prefix: str = "") -> list[str]:
    lines = []
    for k, v in doc.items():
        key = prefix + _key(k)
        if isinstance(v, dict) and v and not isinstance(v, Raw):
            lines += _dump(v, key + ".")
        else:
            lines.append(f"{key} = {_toml(v)}")
    return lines


def _paths(node, prefix=()):
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from _paths(v, prefix + (k,))


def edited_model(data: bytes) -> bytes:
    fdp = atheris.FuzzedDataProvider(data)
    doc = copy.deepcopy(BASE)
    for _ in range(fdp.ConsumeIntInRange(1, 3)):
        paths = list(_paths(doc))
        if not paths:
            break
        path = fdp.PickValueInList(paths)
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if fdp.ConsumeIntInRange(0, 9) == 0:
            del parent[path[-1]]
        else:
            parent[path[-1]] = _value(fdp, parent[path[-1]])
    return ("\n".join(_dump(doc)) + "\n").encode()


# ------------------------------------------------------------------ the property

def test_one_input(data: bytes) -> None:
    raw = edited_model(data[1:]) if data[:1] == b"\x01" else data
    try:
        model = config.parse(raw, _PATH)
    except config.ModelError:
        return
    try:
        check_park(model)
    except config.ModelError:
        return


def main() -> None:
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
