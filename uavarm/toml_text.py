"""TOML text of a value, for the files the simulator writes (edited model files, scenario
dumps): tomllib reads TOML but the standard library has no writer."""
from __future__ import annotations


def toml_value(v) -> str:
    """bool, str, int, float (numpy scalars too) or lists of them; TypeError otherwise."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, int):
        return str(int(v))
    if isinstance(v, float):
        return repr(float(v))   # numpy 2's repr of its own floats is not TOML
    raise TypeError(f"no TOML form for {v!r}")
