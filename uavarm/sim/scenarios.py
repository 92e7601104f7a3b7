"""Drone-motion scenarios of the closed-loop simulator, built in or from a scenario file.

A scenario file is TOML (the built-in ones are the same tables, `uavarm sim NAME --show`
prints them):

    name = "gusty hover"
    kind = "hover"              # bench | hover | manoeuvre | replay
    [motion]                    # the kind's parameters, all optional but `csv`
    gust_mps = 2.0
    [imu]
    profile = "calibrated"      # uavarm.sim.imu_model.PROFILES
    vibration = true            # propeller tones (default: off on the bench, on in flight)
    [link]                      # drone_attitude: the flight controller's roll/pitch, forwarded
    rate_hz = 50.0              # >= 30
    delay_ms = 20.0             # measurement to arrival: the estimator's latency and the link's ...
    jitter_ms = 5.0             # ... +- uniform
    noise_deg = 0.35            # attitude error per axis: white, RMS ...
    slow_deg = 0.35             # ... plus a slowly varying part (first-order Markov), RMS ...
    slow_tau_s = 30.0           # ... with this correlation time
    bias_deg = 0.0              # ... plus a constant, uniform +-
    outages = [[20.0, 50.0]]    # [from, to] s after engage: no message arrives (default none)
    [velocity]                  # drone_velocity: the odometry's velocity, forwarded
    rate_hz = 50.0
    delay_ms = 20.0
    jitter_ms = 5.0
    noise_mps = 0.05            # velocity error per axis: white, RMS ...
    slow_mps = 0.05             # ... plus a slowly varying part (first-order Markov), RMS ...
    slow_tau_s = 30.0           # ... with this correlation time
    outages = []
    [arm]
    target = [60.0, 20.0, -120.0]   # set position, mm, level frame

Motion parameters per kind: bench `max_tilt_deg`; hover `gust_mps`, `mean_wind_mps`;
manoeuvre `speed`, `tilt_deg`, `leg_m`, `pause_s`, `jerk_s`, `gust_mps`; replay `csv`.

`kind = "replay"` plays a flight log: `csv` (relative to the scenario file) with a header
line and columns `t` (s, increasing), `roll`, `pitch` (deg, Z-Y-X Euler), `ax`, `ay`, `az`
(m/s^2: the centre of rotation's acceleration without gravity, in the gravity-aligned,
heading-following frame, z up), e.g. a flight controller's attitude and its position
estimator's acceleration. Rates and angular accelerations are derived from the attitude.
"""
from __future__ import annotations

import csv
import dataclasses
import inspect
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import drone, imu_model
from ..toml_text import toml_value

KINDS = {"bench": drone.bench, "hover": drone.hover, "manoeuvre": drone.manoeuvre}
CSV_COLUMNS = ("t", "roll", "pitch", "ax", "ay", "az")
DEFAULT_TARGET = (60.0, 20.0, -120.0)


class ScenarioError(ValueError):
    """A scenario file or its flight log is unusable; the message names file and key."""


@dataclass(frozen=True)
class LinkParams:
    """The flight controller's attitude as it reaches the arm (defaults: docs/simulator.md)."""
    rate_hz: float = 50.0
    delay_ms: float = 20.0
    jitter_ms: float = 5.0
    noise_deg: float = 0.35
    slow_deg: float = 0.35
    slow_tau_s: float = 30.0
    bias_deg: float = 0.0
    outages: tuple[tuple[float, float], ...] = ()   # (from, to) s after engage: messages lost


@dataclass(frozen=True)
class VelocityParams:
    """The drone's odometry velocity as it reaches the arm (defaults: docs/simulator.md)."""
    rate_hz: float = 50.0
    delay_ms: float = 20.0
    jitter_ms: float = 5.0
    noise_mps: float = 0.05
    slow_mps: float = 0.05
    slow_tau_s: float = 30.0
    outages: tuple[tuple[float, float], ...] = ()   # (from, to) s after engage: messages lost


@dataclass(frozen=True)
class Scenario:
    name: str
    kind: str
    motion: dict = field(default_factory=dict)
    imu_profile: str = "calibrated"
    vibration: bool | None = None
    link: LinkParams = LinkParams()
    velocity: VelocityParams = VelocityParams()
    target: tuple[float, float, float] = DEFAULT_TARGET
    base_dir: Path | None = None            # where a replay's csv is looked up

    @property
    def vibrating(self) -> bool:
        """Propeller tones: on in flight, off on the bench (motors stopped), unless set."""
        return self.kind != "bench" if self.vibration is None else self.vibration

    def imu_errors(self) -> imu_model.ImuErrors:
        errors = imu_model.PROFILES[self.imu_profile]
        return dataclasses.replace(errors, vibration=errors.vibration and self.vibrating)

    def flight(self, seconds: float, rng: np.random.Generator) -> drone.Flight:
        if self.kind == "replay":
            return load_csv(self._csv_path(), seconds)
        return KINDS[self.kind](seconds, rng, **self.motion)

    def _csv_path(self) -> Path:
        p = Path(self.motion["csv"])
        return p if p.is_absolute() or self.base_dir is None else self.base_dir / p


BUILTIN = {
    "bench": "name = \"bench tilting\"\nkind = \"bench\"\n[motion]\nmax_tilt_deg = 20.0\n",
    "hover": "name = \"hover in gusty wind\"\nkind = \"hover\"\n[motion]\ngust_mps = 2.0\nmean_wind_mps = 2.0\n",
    "manoeuvre": ("name = \"lateral manoeuvre\"\nkind = \"manoeuvre\"\n[motion]\nspeed = 2.5\ntilt_deg = 10.0\n"
                  "leg_m = 8.0\npause_s = 2.0\njerk_s = 0.4\ngust_mps = 0.5\n"),
}


def load(name_or_path: str | Path) -> Scenario:
    """A built-in scenario by name, or a scenario file."""
    if str(name_or_path) in BUILTIN:
        return parse(BUILTIN[str(name_or_path)], f"<built-in {name_or_path}>")
    path = Path(name_or_path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(f"{path}: not a built-in scenario ({', '.join(BUILTIN)}) and not a readable "
                            f"file: {exc.strerror}") from None
    return parse(text, str(path), base_dir=path.parent)


def _motion_keys(kind: str) -> set[str]:
    if kind == "replay":
        return {"csv"}
    sig = inspect.signature(KINDS[kind])
    return {p for p in sig.parameters if p not in ("seconds", "rng", "params")}


def parse(text: str, where: str = "<scenario>", base_dir: Path | None = None) -> Scenario:
    def fail(key, msg):
        return ScenarioError(f"{where}: {key}: {msg}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{where}: not valid TOML: {exc}") from None
    unknown = set(data) - {"name", "kind", "motion", "imu", "link", "velocity", "arm"}
    if unknown:
        raise fail(sorted(unknown)[0], "unknown key (expected name, kind, [motion], [imu], [link], [velocity], "
                                       "[arm])")
    kind = data.get("kind")
    if kind not in (*KINDS, "replay"):
        raise fail("kind", f"must be one of {', '.join((*KINDS, 'replay'))}, got {kind!r}")
    name = data.get("name", kind)
    if not isinstance(name, str):
        raise fail("name", f"expected a string, got {name!r}")

    def table(key):
        t = data.get(key, {})
        if not isinstance(t, dict):
            raise fail(key, "expected a table")
        return t

    def number(key, value, lo=None, hi=None):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise fail(key, f"expected a finite number, got {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise fail(key, (f"must be >= {lo}" if hi is None else f"must be within [{lo}, {hi}]") + f", got {value}")
        return float(value)

    motion = dict(table("motion"))
    allowed = _motion_keys(kind)
    for key in motion:
        if key not in allowed:
            raise fail(f"motion.{key}", f"not a parameter of kind {kind} (expected {', '.join(sorted(allowed))})")
    if kind == "replay":
        if not isinstance(motion.get("csv"), str):
            raise fail("motion.csv", "a replay needs the flight log's file name")
    else:
        motion = {k: number(f"motion.{k}", v, lo=0.0) for k, v in motion.items()}

    imu = table("imu")
    for key in imu:
        if key not in ("profile", "vibration"):
            raise fail(f"imu.{key}", "unknown key (expected profile, vibration)")
    profile = imu.get("profile", "calibrated")
    if profile not in imu_model.PROFILES:
        raise fail("imu.profile", f"must be one of {', '.join(imu_model.PROFILES)}, got {profile!r}")
    vibration = imu.get("vibration")
    if vibration is not None and not isinstance(vibration, bool):
        raise fail("imu.vibration", f"expected true or false, got {vibration!r}")

    def stream(key, params_class):
        t = table(key)
        fields = {f.name for f in dataclasses.fields(params_class)}
        for name in t:
            if name not in fields:
                raise fail(f"{key}.{name}", f"unknown key (expected {', '.join(sorted(fields))})")
        outages = t.get("outages", [])
        if not isinstance(outages, list) or not all(isinstance(o, list) and len(o) == 2 for o in outages):
            raise fail(f"{key}.outages", f"expected a list of [from, to] pairs (s after engage), got {outages!r}")
        outages = tuple(tuple(number(f"{key}.outages", v, lo=0.0) for v in o) for o in outages)
        for start, end in outages:
            if not start < end:
                raise fail(f"{key}.outages", f"each [from, to] must end after it starts, got [{start}, {end}]")
        p = params_class(**{k: number(f"{key}.{k}", v, lo=0.0) for k, v in t.items() if k != "outages"},
                         outages=outages)
        if p.rate_hz < 30.0:
            raise fail(f"{key}.rate_hz", f"the drone's messages must come at >= 30 Hz, got {p.rate_hz}")
        if p.jitter_ms > p.delay_ms:
            raise fail(f"{key}.jitter_ms", f"must not exceed delay_ms ({p.delay_ms}), got {p.jitter_ms}")
        if p.slow_tau_s <= 0.0:
            raise fail(f"{key}.slow_tau_s", f"the slow error's correlation time must be positive, got {p.slow_tau_s}")
        return p

    link = stream("link", LinkParams)
    velocity = stream("velocity", VelocityParams)

    arm = table("arm")
    for key in arm:
        if key != "target":
            raise fail(f"arm.{key}", "unknown key (expected target)")
    target = arm.get("target", list(DEFAULT_TARGET))
    if not isinstance(target, list) or len(target) != 3:
        raise fail("arm.target", f"expected [x, y, z] in mm, got {target!r}")
    target = tuple(number(f"arm.target[{i}]", v) for i, v in enumerate(target))
    return Scenario(name, kind, motion, profile, vibration, link, velocity, target, base_dir)


def dump(s: Scenario) -> str:
    """The scenario as a scenario file (parse(dump(s)) == s, base_dir aside)."""
    lines = [f"name = {toml_value(s.name)}", f"kind = {toml_value(s.kind)}", "", "[motion]"]
    lines += [f"{k} = {toml_value(v)}" for k, v in s.motion.items()]
    lines += ["", "[imu]", f"profile = {toml_value(s.imu_profile)}"]
    if s.vibration is not None:
        lines.append(f"vibration = {toml_value(s.vibration)}")
    for key, params in (("link", s.link), ("velocity", s.velocity)):
        lines += ["", f"[{key}]"] + [f"{f.name} = {toml_value(getattr(params, f.name))}"
                                     for f in dataclasses.fields(params)]
    lines += ["", "[arm]", f"target = {toml_value(list(s.target))}", ""]
    return "\n".join(lines)


def write_csv(flight: drone.Flight, path: Path, every: int = 10) -> None:
    """A flight as a replayable log (every `every`-th sample: 100 Hz by default)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for i in range(0, len(flight.t), every):
            w.writerow([f"{flight.t[i]:.6f}", f"{math.degrees(flight.roll[i]):.9g}",
                        f"{math.degrees(flight.pitch[i]):.9g}", *(f"{a:.9g}" for a in flight.acc[i])])


def load_csv(path: Path, seconds: float | None = None) -> drone.Flight:
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the flight log: {exc.strerror}") from None
    if not rows or tuple(c.strip() for c in rows[0]) != CSV_COLUMNS:
        raise ScenarioError(f"{path}: line 1: expected the header {','.join(CSV_COLUMNS)}, "
                            f"got {','.join(rows[0]) if rows else 'an empty file'}")
    values = []
    for n, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            v = [float(c) for c in row]
        except ValueError:
            raise ScenarioError(f"{path}: line {n}: not a number in {row}") from None
        if len(v) != len(CSV_COLUMNS) or not all(map(math.isfinite, v)):
            raise ScenarioError(f"{path}: line {n}: expected {len(CSV_COLUMNS)} finite numbers, got {row}")
        values.append(v)
    if len(values) < 2:
        raise ScenarioError(f"{path}: a flight log needs at least 2 samples, got {len(values)}")
    a = np.array(values)
    t = a[:, 0] - a[0, 0]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ScenarioError(f"{path}: line {bad[0] + 3}: time must increase, got {a[bad[0] + 1, 0]} "
                            f"after {a[bad[0], 0]}")
    if np.any(np.abs(a[:, 1:3]) >= 90):
        raise ScenarioError(f"{path}: roll and pitch must be within (-90, 90) degrees")
    if seconds is not None and t[-1] < seconds:
        raise ScenarioError(f"{path}: the log lasts {t[-1]:.2f} s; the run needs {seconds:.2f} s "
                            f"(ask for fewer --seconds)")
    return drone.resample(t, np.radians(a[:, 1]), np.radians(a[:, 2]), a[:, 3:6], seconds)
