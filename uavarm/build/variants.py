"""Firmware variants for the simulator: the model file with some keys edited, generated and
built into its own host library, cached under build/sim/<hash>/.

    lib = variants.build(variants.edits("link", ["estimator.lead_time=0.02"]))

An edit names a key that must already exist in the model file (`estimator.kind`,
`mount.offset`, ...): a key the model does not have stops with an error instead of being
ignored by the loader, so a preset never silently measures the wrong firmware.
"""
from __future__ import annotations

import dataclasses
import hashlib
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from . import cbuild, firmware
from ..model import config
from ..toml_text import toml_value

SIM_BUILD = cbuild.ROOT / "build" / "sim"

# Estimator presets of `uavarm sim --estimator`: the model keys each one sets.
PRESETS: dict[str, dict[str, object]] = {
    "complementary": {"estimator.kind": "complementary", "estimator.drone_attitude": False,
                      "estimator.drone_velocity": False},
    "quaternion": {"estimator.kind": "quaternion", "estimator.drone_attitude": False, "estimator.drone_velocity": False},
    "link": {"estimator.kind": "quaternion", "estimator.drone_attitude": True, "estimator.drone_velocity": False},
    "link-velocity": {"estimator.kind": "quaternion", "estimator.drone_attitude": True, "estimator.drone_velocity": True},
    "imu-velocity": {"estimator.kind": "quaternion", "estimator.drone_attitude": False, "estimator.drone_velocity": True},
}


# Model keys only one estimator reads (firmware_stm32/App/Src/stabiliser.c): the complementary
# filter on the filtered gyro; the quaternion estimator on the raw gyro, with its gains, gates
# and bias clamp; the drone's attitude over the link only when it is fused.
COMPLEMENTARY_ONLY = ("estimator.complementary_gyro_weight", "filters.gyro.cutoff", "filters.gyro.order")
QUATERNION_ONLY = ("estimator.accel_gain", "estimator.bias_gain", "estimator.align_accel_gain",
                   "estimator.align_bias_gain", "estimator.accel_reject_g", "estimator.accel_reject_deg",
                   "estimator.gyro_bias_max_dps")
LINK_ONLY = ("estimator.link_gain", "estimator.link_bias_gain")
STREAMS_ONLY = ("estimator.link_delay_min", "estimator.link_delay_max", "estimator.link_timeout")
VELOCITY_ONLY = ("estimator.velocity_bandwidth", "estimator.accel_bias_bandwidth", "estimator.accel_bias_max_g")
LINK_AND_VELOCITY_ONLY = ("estimator.link_gain_with_velocity", "estimator.link_bias_gain_with_velocity",
                          "estimator.fc_error_gain", "estimator.fc_error_max_deg", "estimator.fc_error_tau",
                          "estimator.fc_error_deg", "estimator.drone_attitude_white_deg", "estimator.accel_bias_prior_g",
                          "estimator.accel_bias_walk_g",
                          "estimator.accel_bias_attitude_gain")


class VariantError(ValueError):
    """An edit the model file cannot take."""


def unused(keys, estimator: config.Estimator) -> list[str]:
    """Why each of `keys` changes nothing in the firmware of this estimator (none: all count)."""
    out = []
    for key in keys:
        if key in COMPLEMENTARY_ONLY and estimator.kind != "complementary":
            out.append(f"{key}: not used by the {estimator.kind} estimator (only by the complementary one: "
                       f"--estimator complementary)")
        elif key in QUATERNION_ONLY and estimator.kind != "quaternion":
            out.append(f"{key}: not used by the {estimator.kind} estimator (only by the quaternion one: "
                       f"--estimator quaternion or link)")
        elif key in LINK_ONLY and not estimator.drone_attitude:
            out.append(f"{key}: not used without the drone's attitude over the link (--estimator link)")
        elif key in STREAMS_ONLY and not (estimator.drone_attitude or estimator.drone_velocity):
            out.append(f"{key}: not used without the drone's attitude or velocity over the link "
                       f"(--estimator link, link-velocity or imu-velocity)")
        elif key in VELOCITY_ONLY and not estimator.drone_velocity:
            out.append(f"{key}: not used without the drone's velocity over the link (--estimator imu-velocity)")
        elif key in LINK_AND_VELOCITY_ONLY and not (estimator.drone_attitude and estimator.drone_velocity):
            out.append(f"{key}: used only with both the drone's attitude and velocity over the link "
                       f"(--estimator link-velocity)")
    return out


def parse_value(text: str):
    """A --set value as TOML (numbers, true/false, arrays, "strings"); a bare word is a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_\-]*", text):
            return text
        raise VariantError(f"not a TOML value: {text!r}") from None


def edits(preset: str | None = None, sets=()) -> dict[str, object]:
    """The key edits of a preset followed by KEY=VALUE strings (later ones win)."""
    out: dict[str, object] = {}
    if preset is not None:
        if preset not in PRESETS:
            raise VariantError(f"unknown estimator preset {preset!r} (choose from {', '.join(PRESETS)})")
        out.update(PRESETS[preset])
    for item in sets:
        key, eq, value = item.partition("=")
        if not eq or not key.strip():
            raise VariantError(f"--set takes KEY=VALUE, got {item!r}")
        out[key.strip()] = parse_value(value.strip())
    return out


def _toml_value(v) -> str:
    try:
        return toml_value(v)
    except TypeError as exc:
        raise VariantError(f"cannot write {v!r} into the model file") from exc


_HEADER = re.compile(r"^\s*\[([A-Za-z0-9_.\-]+)\]\s*(#.*)?$")
_ASSIGN = re.compile(r"^(\s*)([A-Za-z0-9_\-]+)(\s*=\s*)")


def edit_text(text: str, key: str, value, where: str = "model") -> str:
    """The model file's text with `key` (dotted: table.key) set to value; comments kept."""
    table, _, name = key.rpartition(".")
    data = tomllib.loads(text)
    node = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise VariantError(f"{where}: {key}: no such key in the model file; this firmware does not "
                               f"know it (a preset of another branch, or a typo?)")
        node = node[part]
    lines = text.splitlines(keepends=True)
    current = ""
    for i, line in enumerate(lines):
        h = _HEADER.match(line)
        if h:
            current = h.group(1)
            continue
        m = _ASSIGN.match(line)
        if m and current == table and m.group(2) == name:
            if "\n" not in line or line.rstrip().endswith("["):
                raise VariantError(f"{where}: {key}: multi-line values cannot be edited")
            lines[i] = f"{m.group(1)}{name}{m.group(3)}{_toml_value(value)}   # edited by uavarm sim\n"
            new = "".join(lines)
            got = tomllib.loads(new)
            for part in key.split("."):
                got = got[part]
            if got != value:
                raise VariantError(f"{where}: {key}: edit did not take ({got!r} != {value!r})")
            return new
    raise VariantError(f"{where}: {key}: not written as `{name} = ...` under [{table}]; cannot edit it")


@dataclass(frozen=True)
class Variant:
    model: config.Model
    ffi: object
    lib: object
    edits: dict
    gen_dir: Path


# The committed model file made an arm of XM430-W350s (Protocol 2.0, 4096 units a turn, every
# zero at the centre, 1 Mbit/s): the X-series variant the benches, the fuzzer and tests build.
XM430_EDITS = {"servo.model": "XM430-W350", "servo.units_max": 4095, "servo.range_deg": 359.912109375,
               "servo.baud": 1_000_000, **{f"servo.theta{j}.zero": 2048 for j in (1, 2, 3)}}


def edited_text(changes: dict[str, object], base: Path = config.DEFAULT_MODEL) -> str:
    text = Path(base).read_text()
    for key, value in changes.items():
        text = edit_text(text, key, value, str(base))
    return text


def model_of(changes: dict[str, object], base: Path = config.DEFAULT_MODEL) -> config.Model:
    """The edited model as the loader reads it, without generating or building anything."""
    try:
        model = config.parse(edited_text(changes, base).encode(), Path(base))
    except config.ModelError as exc:
        raise VariantError(str(exc)) from None
    return model


def _values(model: config.Model) -> str:
    """What a model says, apart from its file's path and text (comments, the order edits were
    made in): models with the same values generate the same code."""
    return repr(dataclasses.replace(model, path=None, sha256=None))


def build(changes: dict[str, object], base: Path = config.DEFAULT_MODEL) -> Variant:
    """Generate and build the firmware of the edited model, cached by its values: edits that
    leave the committed model's values as they are take the committed build (generated/)."""
    model, gen_dir = generate(changes, base)
    if gen_dir == firmware.generated.GENERATED:
        ffi, lib = firmware.default()
    else:
        ffi, lib = firmware.load(gen_dir)
    return Variant(model, ffi, lib, dict(changes), gen_dir)


def generate(changes: dict[str, object], base: Path = config.DEFAULT_MODEL) -> tuple[config.Model, Path]:
    """(the edited model, the folder of its generated code), generated once for its values
    (generated/ itself for the committed model's)."""
    if Path(base) == config.DEFAULT_MODEL and (not changes or _values(model_of(changes)) == _values(config.load())):
        model = config.load(base)
        firmware.generated.check_current(model)     # generated/ is this model's (make codegen)
        return model, firmware.generated.GENERATED
    text = edited_text(changes, base)
    from ..codegen import generate as codegen   # imports SymPy: only when a variant is really built
    digest = hashlib.sha256((_values(model_of(changes, base)) + codegen._templates_digest()).encode()).hexdigest()[:16]
    out = SIM_BUILD / digest
    model_path = out / "manipulator.toml"
    gen_dir = out / "generated"
    stamp = out / "done"
    with cbuild.exclusive(SIM_BUILD / f"{digest}.lock"):   # parallel runs build a variant once
        if not stamp.exists():
            out.mkdir(parents=True, exist_ok=True)
            model_path.write_text(text)
            try:
                files = codegen.render(model_path)
            except config.ModelError as exc:
                raise VariantError(str(exc)) from None
            codegen.write(files, gen_dir)
            stamp.write_text("".join(f"{k} = {_toml_value(v)}\n" for k, v in changes.items()))
    return config.load(model_path), gen_dir
