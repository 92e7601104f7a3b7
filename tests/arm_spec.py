"""The arm's numbers read straight from the model file with tomllib, not through the code
generator's loader (uavarm.model.config), and the AX-12A's written facts (its e-Manual):
position units 0..1023 span 300 degrees, 512 is the centre. The tests' oracles take their
numbers from here, so a slip in the generator's model-to-number path cannot hide in them.

`spec()` has the attribute names tests/oracles.py's plain geometry expects (L1, L2, L3,
limits[j].min_deg / max_deg, body_z, leg_angles, leg_half_width, leg_distance).
"""
from __future__ import annotations

import math
import tomllib
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

MODEL_FILE = Path(__file__).resolve().parents[1] / "model" / "manipulator.toml"

# AX-12A e-Manual, "Goal Position": 0..1023 (0x3FF) over 0..300 degrees, 512 = 150 degrees.
AX12_UNITS_MAX = 1023
AX12_RANGE_DEG = 300.0
AX12_CENTRE = 512
JOINTS = ("theta1", "theta2", "theta3")


@lru_cache(maxsize=None)
def spec(path: Path = MODEL_FILE) -> SimpleNamespace:
    raw = tomllib.loads(Path(path).read_text())
    geo, col = raw["geometry"], raw["collision"]
    limits = [SimpleNamespace(min_deg=float(raw["joints"][j]["min"]), max_deg=float(raw["joints"][j]["max"]))
              for j in JOINTS]
    servos = [SimpleNamespace(zero=int(raw["servo"][j]["zero"]), direction=int(raw["servo"][j]["direction"]))
              for j in JOINTS]
    return SimpleNamespace(L1=float(geo["L1"]), L2=float(geo["L2"]), L3=float(geo["L3"]), limits=limits,
                           body_z=float(col["body_z"]), leg_angles=[float(a) for a in col["leg_angles"]],
                           leg_half_width=float(col["leg_half_width"]), leg_distance=float(col["leg_distance"]),
                           servos=servos, park_deg=[float(v) for v in raw["park"]["q"]])


def units_exact(joint: int, rad):
    """The servo position (units, unrounded) of a joint angle: the model file's zero and
    direction of that servo, 1023 units over 300 degrees."""
    s = spec().servos[joint]
    return s.zero + s.direction * math.degrees(1.0) * rad * AX12_UNITS_MAX / AX12_RANGE_DEG


def unit_range(joint: int) -> tuple[int, int]:
    """The whole servo positions inside the joint's travel limits."""
    lim = spec().limits[joint]
    ends = sorted(units_exact(joint, math.radians(d)) for d in (lim.min_deg, lim.max_deg))
    return math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9)
