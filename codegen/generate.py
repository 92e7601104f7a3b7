"""Render the model into float32 C: `python -m uavarm.codegen [--model F] [--out DIR] [--check]`.

Each model quantity becomes one C function; the SymPy expressions go through CSE and the
float32 printer, then into the Jinja2 templates of templates/. Output is deterministic
(no timestamps): regenerating an unchanged model reproduces generated/ byte for byte.
"""
from __future__ import annotations

import argparse
import difflib
import hashlib
import sys
from pathlib import Path

import jinja2
import sympy as sp

from ..model import collision, config, filters, kinematics, messages, servo
from . import approx
from .printer import c, cse_lines, float32_literal, op_count

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
GENERATED = ROOT / "generated"
GENERATOR_VERSION = "1"
REGENERATE = "make codegen"

Q = [f"q[{i}]" for i in range(3)]


def _trig_free(exprs):
    """Replace sin(q_i)/cos(q_i) by locals filled by fm_sincosf; returns (exprs, C lines)."""
    pairs = [(sp.Symbol(f"s{i + 1}"), sp.Symbol(f"c{i + 1}")) for i in range(3)]
    subs = {}
    for qi, (si, ci) in zip(kinematics.JOINT_SYMBOLS, pairs):
        subs[sp.sin(qi)] = si
        subs[sp.cos(qi)] = ci
    expand = lambda e: e.replace(lambda a: isinstance(a, (sp.sin, sp.cos)), sp.expand_trig)
    out = [expand(sp.sympify(e)).subs(subs) for e in exprs]
    used = set().union(*(e.free_symbols for e in out))
    joints = [i for i, (si, ci) in enumerate(pairs) if si in used or ci in used]
    if not joints:
        return out, []
    decl = "float " + ", ".join(f"{pairs[i][0]}, {pairs[i][1]}" for i in joints) + ";"
    return out, [decl] + [f"fm_sincosf(q[{i}], &{pairs[i][0]}, &{pairs[i][1]});" for i in joints]


def _bind(exprs, symbols, c_names):
    return [sp.sympify(e).subs({s: sp.Symbol(n) for s, n in zip(symbols, c_names)}) for e in exprs]


def _function(outputs, symbols, c_names, prefix="t"):
    """Body lines of a C function computing [(lvalue, expr)] from inputs named c_names."""
    lhs = [l for l, _ in outputs]
    exprs, pre = _trig_free([e for _, e in outputs])
    exprs = _bind(exprs, symbols, c_names)
    temps, assigns = cse_lines(list(zip(lhs, exprs)), prefix)
    return {"lines": pre + temps + assigns, "ops": op_count(exprs)}


def kinematics_context(m: config.Model):
    q = kinematics.JOINT_SYMBOLS
    j3, ee = kinematics.fk_points(m)
    geo = kinematics.fk_geometry(m)
    checks = [("limits_ok", kinematics.joint_limits_ok(m, q)),
              ("body_ok", collision.body_clear(m, geo)),
              ("legs_ok", collision.legs_clear(m, geo))]

    ikm = kinematics.ik(m)
    t = kinematics.TARGET_SYMBOLS
    ik_out = [("const bool reachable", ikm.disc >= 0)]
    for i, cand in enumerate(ikm.candidates):
        ik_out += [(f"out->q[{i}][{j}]", cand.q[j]) for j in range(3)]
    for i, cand in enumerate(ikm.candidates):
        ik_out += [(f"limits_ok[{i}]", kinematics.joint_limits_ok(m, cand.q)),
                   (f"body_ok[{i}]", collision.body_clear(m, cand.geometry)),
                   (f"legs_ok[{i}]", collision.legs_clear(m, cand.geometry))]
    ik_exprs = _bind([e for _, e in ik_out], t, ["x", "y", "z"])
    temps, assigns = cse_lines(list(zip([l for l, _ in ik_out], ik_exprs)))
    return {
        "fk_ee": _function([(f"ee[{i}]", ee[i]) for i in range(3)], q, Q),
        "fk_joint3": _function([(f"j3[{i}]", j3[i]) for i in range(3)], q, Q),
        "check": _function([(f"const bool {n}", e) for n, e in checks], q, Q),
        "ik": {"lines": temps + assigns, "ops": op_count(ik_exprs)},
        "dh": kinematics.dh_rows(m),
        "target_bound": float32_literal(2 * (m.L1 + m.L2 + m.L3)),
        "limits": [(float32_literal(l.min_rad), float32_literal(l.max_rad)) for l in m.limits],
    }


def filters_context(m: config.Model):
    out = {}
    for name, sections in filters.sensor_filters(m).items():
        spec = m.accel_filter if name == "accel" else m.gyro_filter
        out[name] = {
            "cutoff": spec.cutoff, "order": spec.order,
            "sections": [{"b": [float32_literal(v) for v in s.b], "a": [float32_literal(v) for v in s.a[1:]],
                          "neg_a": [float32_literal(-v) for v in s.a[1:]],
                          "rest": [float32_literal(v) for v in filters.steady_state(s)]} for s in sections],
        }
    return out


def servo_context(m: config.Model):
    angle, units = sp.symbols("angle u")
    joints = []
    for j in range(3):
        lo, hi = servo.unit_range(m, j)
        joints.append({
            "to_units": c(servo.joint_to_units(m, j, angle)),
            "to_angle": c(servo.units_to_joint(m, j, units)),
            "units_min": lo, "units_max": hi,
        })
    return {"joints": joints}


def fastmath_context():
    k = approx.fit()
    lit = lambda vals: [float32_literal(v) for v in vals]
    return {"sin": lit(k.sin_poly), "cos": lit(k.cos_poly), "atan": lit(k.atan_poly),
            "pio2": lit(k.pio2_parts), "sincos_max": float32_literal(k.sincos_max),
            "two_over_pi": float32_literal(2 / sp.pi), "pi": float32_literal(sp.pi),
            "pi_2": float32_literal(sp.pi / 2), "pi_4": float32_literal(sp.pi / 4),
            "tan_pi_8": float32_literal(sp.tan(sp.pi / 8))}


OUTPUTS = {
    "fastmath.h": "fastmath.h.j2",
    "fastmath.c": "fastmath.c.j2",
    "kinematics.h": "kinematics.h.j2",
    "kinematics.c": "kinematics.c.j2",
    "filters.h": "filters.h.j2",
    "filters.c": "filters.c.j2",
    "servo_map.h": "servo_map.h.j2",
    "servo_map.c": "servo_map.c.j2",
    "model_params.h": "model_params.h.j2",
    "messages.h": "messages.h.j2",
    "messages.c": "messages.c.j2",
}


def render(model_path: Path = config.DEFAULT_MODEL) -> dict[str, str]:
    m = config.load(model_path)
    messages.check()
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES), undefined=jinja2.StrictUndefined,
                             keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True)
    try:
        shown_path = m.path.resolve().relative_to(ROOT)
    except ValueError:
        shown_path = m.path
    ctx = {
        "m": m,
        "model_file": shown_path,
        "model_sha": m.sha256[:16],
        "generator_version": GENERATOR_VERSION,
        "template_sha": _templates_digest(),
        "regenerate": REGENERATE,
        "kin": kinematics_context(m),
        "filt": filters_context(m),
        "servo": servo_context(m),
        "fm": fastmath_context(),
        "lit": float32_literal,
        "messages": messages.MESSAGES,
        "types": messages.TYPES,
        "wire_types": messages.wire_types(),
    }
    return {name: env.get_template(tpl).render(ctx, file_name=name) for name, tpl in OUTPUTS.items()}


def _templates_digest() -> str:
    h = hashlib.sha256()
    for path in sorted(TEMPLATES.glob("*.j2")) + sorted((ROOT / "codegen").glob("*.py")) + \
            sorted((ROOT / "model").glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def write(files: dict[str, str], out_dir: Path) -> list[str]:
    out_dir.mkdir(parents=True, exist_ok=True)
    changed = []
    for name, text in files.items():
        path = out_dir / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)
            changed.append(name)
    stale = sorted(p.name for p in out_dir.iterdir() if p.is_file() and p.name not in files)
    for name in stale:
        (out_dir / name).unlink()
    return changed + stale


def diff(files: dict[str, str], out_dir: Path) -> str:
    lines = []
    for name, text in files.items():
        path = out_dir / name
        old = path.read_text() if path.exists() else ""
        if old != text:
            lines += difflib.unified_diff(old.splitlines(True), text.splitlines(True),
                                          f"{out_dir.name}/{name}", f"regenerated/{name}")
    return "".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m uavarm.codegen", description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, default=config.DEFAULT_MODEL, help="model file (TOML)")
    ap.add_argument("--out", type=Path, default=GENERATED, help="output folder")
    ap.add_argument("--check", action="store_true", help="write nothing; fail if the output is stale")
    args = ap.parse_args(argv)
    try:
        files = render(args.model)
    except config.ModelError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.check:
        d = diff(files, args.out)
        if d:
            sys.stdout.write(d)
            print(f"\n{args.out} is stale: run `{REGENERATE}`", file=sys.stderr)
            return 1
        print(f"{args.out} is up to date")
        return 0
    changed = write(files, args.out)
    print(f"{args.out}: {len(files)} files, {len(changed)} changed" + (f" ({', '.join(changed)})" if changed else ""))
    return 0
