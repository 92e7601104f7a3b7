"""Render the model into float32 C: `python -m uavarm.codegen [--model F] [--out DIR] [--check]`.

Into the default output folder it also writes the model's numbers into the board project
(board_ioc: manipulator.ioc's user constants and main.h), and --check covers them too.

Each model quantity becomes one C function; the SymPy expressions go through CSE and the
float32 printer, then into the Jinja2 templates of templates/. Output is deterministic
(no timestamps): regenerating an unchanged model reproduces generated/ byte for byte.
"""
from __future__ import annotations

import argparse
import difflib
import hashlib
import math
import sys
from pathlib import Path

import jinja2
import sympy as sp

from ..model import (attitude, collision, config, filters, inertia, kinematics, messages, pose_tolerance, quaternion,
                     servo, servo_models, swept, velocity)
from . import approx, board_ioc
from .remember import remembered
from .printer import c, cse_lines, float32_literal, op_count, temp_line

ROOT = Path(__file__).resolve().parents[1]
TEMPLATES = ROOT / "templates"
GENERATED = ROOT / "generated"
GENERATOR_VERSION = "1"
REGENERATE = "make codegen"

Q = [f"q[{i}]" for i in range(3)]


def _trig_free(exprs, angles=kinematics.JOINT_SYMBOLS, c_angles=Q, names=("s1", "c1", "s2", "c2", "s3", "c3"),
               cached=None, bounded=False):
    """Replace sin/cos of the angles by locals filled by fm_sincosf, or, with cached = C
    expressions (sin, cos of each angle), read from there; returns (exprs, C lines).
    bounded: the caller has checked the angles against the joint limits (inside
    fm_sincosf's domain), so two of them may go through fm_sincos2f_bounded."""
    pairs = [(sp.Symbol(names[2 * i]), sp.Symbol(names[2 * i + 1])) for i in range(len(angles))]
    subs = {}
    for a, (si, ci) in zip(angles, pairs):
        subs[sp.sin(a)] = si
        subs[sp.cos(a)] = ci
    expand = lambda e: e.replace(lambda a: isinstance(a, (sp.sin, sp.cos)), sp.expand_trig)
    out = [expand(sp.sympify(e)).subs(subs) for e in exprs]
    used = set().union(*(e.free_symbols for e in out))
    present = [i for i, (si, ci) in enumerate(pairs) if si in used or ci in used]
    if not present:
        return out, []
    if cached is not None:
        return out, [f"const float {pairs[i][0]} = {cached[2 * i]}, {pairs[i][1]} = {cached[2 * i + 1]};"
                     for i in present]
    decl = "float " + ", ".join(f"{pairs[i][0]}, {pairs[i][1]}" for i in present) + ";"
    calls = [f"fm_sincosf({c_angles[i]}, &{pairs[i][0]}, &{pairs[i][1]});" for i in present]
    if bounded and len(present) == 2:   # both at once: their constants loaded once
        (i, j) = present
        calls = [f"fm_sincos2f_bounded({c_angles[i]}, {c_angles[j]}, &{pairs[i][0]}, &{pairs[i][1]}, "
                 f"&{pairs[j][0]}, &{pairs[j][1]});"]
    return out, [decl] + calls


def _bind(exprs, symbols, c_names):
    rename = {s: sp.Symbol(n) for s, n in zip(symbols, c_names)}
    return [sp.sympify(e).xreplace(rename) for e in exprs]


def _function(outputs, symbols, c_names, prefix="t", **trig):
    """Body lines of a C function computing [(lvalue, expr)] from inputs named c_names."""
    lhs = [l for l, _ in outputs]
    exprs, pre = _trig_free([e for _, e in outputs], **trig)
    exprs = _bind(exprs, symbols, c_names)
    temps, assigns = cse_lines(list(zip(lhs, exprs)), prefix)
    return {"lines": pre + temps + assigns, "ops": op_count(exprs)}


@remembered
def kinematics_context(m: config.Model):
    q = kinematics.JOINT_SYMBOLS
    # kin_check_joints' sine and cosine skip fm_sincosf's range test after the limits test
    assert all(max(abs(l.min_rad), abs(l.max_rad)) <= approx.SINCOS_MAX for l in m.limits)
    j3, ee = kinematics.fk_points(m)
    geo = kinematics.fk_geometry(m)
    limits = kinematics.joint_limits_ok(m, q)
    checks = [("body_ok", collision.body_clear(m, geo)),
              ("legs_ok", collision.legs_clear(m, geo))]

    ikm = kinematics.ik(m)
    t = kinematics.TARGET_SYMBOLS
    # each candidate's checks, in kin_check_joints' order: limits, body, legs
    checks_of = [[kinematics.joint_limits_ok(m, cand.q), collision.body_clear(m, cand.geometry),
                  collision.legs_clear(m, cand.geometry)] for cand in ikm.candidates]
    ik_out = [("const bool reachable", ikm.disc >= 0)]
    for i, cand in enumerate(ikm.candidates):
        ik_out += [(f"out->q[{i}][{j}]", cand.q[j]) for j in range(3)]
    for i, (limits_i, body_i, legs_i) in enumerate(checks_of):
        ik_out += [(f"limits_ok[{i}]", limits_i), (f"body_ok[{i}]", body_i), (f"legs_ok[{i}]", legs_i)]
    ik_exprs = _bind([e for _, e in ik_out], t, ["x", "y", "z"])
    temps, assigns = (_finite_atan2(lines) for lines in cse_lines(list(zip([l for l, _ in ik_out], ik_exprs))))
    return {
        "fk_ee": _function([(f"ee[{i}]", ee[i]) for i in range(3)], q, Q),
        "fk_joint3": _function([(f"j3[{i}]", j3[i]) for i in range(3)], q, Q),
        "check_limits": _function([("const bool limits_ok", limits)], q, Q),
        "check": _function([(f"const bool {n}", e) for n, e in checks], q, Q, bounded=True),
        "ik": {"lines": temps + assigns, "ops": op_count(ik_exprs)},
        "nearest": _ik_nearest(m, ikm, checks_of, t),
        "swept": _swept(m),
        "branch": _branch(m),
        "dh": kinematics.dh_rows(m),
        "target_bound": float32_literal(2 * (m.L1 + m.L2 + m.L3)),
        "limits": [(float32_literal(l.min_rad), float32_literal(l.max_rad)) for l in m.limits],
        "pi": float32_literal(sp.pi), "two_pi": float32_literal(2 * sp.pi), "half_pi": float32_literal(sp.pi / 2),
    }


def _swept(m: config.Model):
    """kin_check_swept's body: the box's bounds (model/swept.py) from its centre c[] and
    half-widths h[]; the caller has checked both goals against the limits, so the centre's
    sines and cosines skip fm_sincosf's range test."""
    body, legs = swept.box_clear(m)
    names = [f"c[{i}]" for i in range(3)] + [f"h[{i}]" for i in range(3)]
    return _function([("const bool body_ok", body), ("const bool legs_ok", legs)], swept.CENTRE + swept.HALF, names,
                     angles=swept.CENTRE, c_angles=names[:3], bounded=True)


def _branch(m: config.Model):
    """kin_ik_branch's parts (model/kinematics.py BranchIk): the plane's angle and reach, the
    reach in a given plane, and the elbow's angles for a clamped shoulder distance."""
    b = kinematics.branch_ik(m)
    t = kinematics.TARGET_SYMBOLS
    target = ["x", "y", "z"]
    plane = _function([("const float toward", b.azimuth), ("const float rho", b.rho)], t, target)
    held = _function([("u", b.in_plane)], t + (kinematics.JOINT_SYMBOLS[0],), target + ["q1"],
                     angles=kinematics.JOINT_SYMBOLS[:1], c_angles=["q1"], names=("s1", "c1"))
    elbow = _function([("const float r2", b.r2)], t + (kinematics.U,), target + ["u"], prefix="r")
    angles = _function([("const float q2", b.q2), ("const float q3", b.q3)],
                       t + (kinematics.U, kinematics.ELBOW, kinematics.R2), target + ["u", "elbow", "r2c"], prefix="a")
    return {
        "plane": {"lines": _finite_atan2(plane["lines"])},
        "held": held, "r2": elbow,
        "angles": {"lines": _finite_atan2(angles["lines"])},
        "r2_min": {e: float32_literal(v) for e, v in b.r2_min.items()},
        "r2_max": {e: float32_literal(v) for e, v in b.r2_max.items()},
    }


def _finite_atan2(lines):
    """The IK's C lines with fm_atan2f_finite: its target is refused unless finite and inside
    the reach box, so every atan2 argument is finite."""
    return [line.replace("fm_atan2f(", "fm_atan2f_finite(") for line in lines]


def _ik_nearest(m, ikm, checks_of, target_symbols):
    """kin_ik_nearest: the candidates' angles up front, then each candidate's checks on their
    own, one check after the other, so that the C can test the candidates nearest first and
    stop at the first valid one. One CSE over everything names the shared terms; each
    candidate's block recomputes the terms it needs beyond those of the angles."""
    angles = [ikm.disc >= 0] + [a for cand in ikm.candidates for a in cand.q]
    checks = [c for cand in checks_of for c in cand]
    exprs = _bind(angles + checks, target_symbols, ["x", "y", "z"])
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"), order="canonical")
    defined = dict(replacements)

    def closure(roots, have):
        """Temporaries the expressions roots need beyond have, in definition order."""
        need, todo = set(), [s for e in roots for s in e.free_symbols if s in defined]
        while todo:
            sym = todo.pop()
            if sym in need or sym in have:
                continue
            need.add(sym)
            todo += [s for s in defined[sym].free_symbols if s in defined]
        return [(sym, e) for sym, e in replacements if sym in need]

    def lines(temps):
        return [temp_line(sym, e) for sym, e in temps]

    n_angles = len(angles)
    upfront = closure(reduced[:n_angles], set())
    have_upfront = {sym for sym, _ in upfront}
    candidates = []
    for i in range(len(ikm.candidates)):
        have, steps = set(have_upfront), []
        for k, why in enumerate(("KIN_JOINT_LIMIT", "KIN_BODY", "KIN_LEG")):   # checks_of's order
            cond = reduced[n_angles + 3 * i + k]
            if k == 0:   # the limits again on the named angles: |t| <= L for a symmetric one
                cond = kinematics.joint_limits_ok(m, reduced[1 + 3 * i: 4 + 3 * i])
            temps = closure([cond], have)
            have |= {sym for sym, _ in temps}
            steps.append({"lines": lines(temps), "ok": c(cond), "why": why})
        candidates.append(steps)
    return {
        "lines": _finite_atan2(lines(upfront)),
        "reachable": c(reduced[0]),
        "q": [[c(reduced[1 + 3 * i + j]) for j in range(3)] for i in range(len(ikm.candidates))],
        "candidates": candidates,
    }


@remembered
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
            # constants folded at generation time: one multiply-add, no division by pi
            "to_units": c(sp.expand(servo.joint_to_units(m, j, angle)).evalf(40)),
            "to_angle": c(sp.expand(servo.units_to_joint(m, j, units)).evalf(40)),
            "units_min": lo, "units_max": hi,
        })
    q = kinematics.JOINT_SYMBOLS
    return {"joints": joints,
            "check_limits": _function([("const bool limits_ok", kinematics.joint_limits_ok(m, q))], q, Q)}


def _split_step(m: config.Model):
    """The split's Kalman filter, one axis: predict, gain, update (three parts, so that the
    update stays in Joseph form and the gain's division is done once)."""
    numeric = lambda exprs: [sp.N(e, 40) for e in exprs]
    pred_c, k_c = [str(v) for v in velocity.SPLIT_PRED], [str(v) for v in velocity.SPLIT_K]
    inputs = velocity.SPLIT_P + (velocity.SPLIT_H, velocity.SPLIT_ERR, velocity.SPLIT_FC)
    names = [f"p[{i}]" for i in range(3)] + ["h", "err", "fc"]
    predict = _function([(f"const float {n}", v) for n, v in zip(pred_c, numeric(velocity.split_predict(m)))],
                        inputs, names, prefix="sp")
    gain = _function([(f"const float {n}", v) for n, v in zip(k_c, numeric(velocity.split_gain(m)))],
                     velocity.SPLIT_PRED, pred_c, prefix="sg")
    update = _function(list(zip(["*turn", "*learn", "p[0]", "p[1]", "p[2]"], numeric(velocity.split_update(m)))),
                       velocity.SPLIT_PRED + velocity.SPLIT_K + inputs, pred_c + k_c + names, prefix="su")
    fades = velocity.SPLIT_FC in sp.sympify(velocity.split_update(m)[1]).free_symbols
    return {"lines": ([] if fades else ["(void)fc;   /* fc_error never fades */"])
            + predict["lines"] + gain["lines"] + update["lines"],
            "ops": predict["ops"] + gain["ops"] + update["ops"]}


@remembered
def estimator_context(m: config.Model):
    acc, gyro, p = (attitude.ACC, attitude.GYRO, attitude.P_LEVEL)
    acc_c = [f"acc[{i}]" for i in range(3)]
    gyro_c = [f"gyro[{i}]" for i in range(3)]
    p_c = [f"p_level[{i}]" for i in range(3)]
    tilt = attitude.tilt_from_accel(m)
    step = attitude.complementary_step(m)
    rot = attitude.level_to_base(attitude.roll, attitude.pitch) * sp.Matrix(p)
    # sin and cos of the attitude are kept with it (est_set), so no step computes them twice
    angles = dict(angles=(attitude.roll, attitude.pitch), c_angles=("e->roll", "e->pitch"),
                  names=("sr", "cr", "sp", "cp"),
                  cached=("e->sin_roll", "e->cos_roll", "e->sin_pitch", "e->cos_pitch"))
    Q, QH, B, U, W = quaternion.Q, quaternion.QH, quaternion.BIAS, quaternion.UP, quaternion.RATE
    q_c, qh_c, b_c = [f"e->q[{i}]" for i in range(4)], [f"q_hist[{i}]" for i in range(4)], [f"e->bias[{i}]" for i in range(3)]
    # the step in three parts, so that its normalisation is 1 / |q_raw|^2 once, then a square
    # root of that (SymPy would print 1 / sqrt(|q_raw|^2) and 1 / |q_raw|^2: two divisions)
    q_raw, b_next, rate = quaternion.step_unnormalised(m)
    r, inv2 = sp.symbols("r0:4", real=True), sp.Symbol("inv2", positive=True)
    r_c = [str(v) for v in r]
    raw_step = _function([(f"const float {r_c[i]}", q_raw[i]) for i in range(4)]
                         + [(f"const float b{i}", b_next[i]) for i in range(3)]
                         + [(f"e->rate[{i}]", rate[i]) for i in range(3)],
                         Q + B + acc + gyro + (quaternion.K_P, quaternion.K_I, quaternion.GATE, attitude.DT),
                         q_c + b_c + acc_c + gyro_c + ["k_p", "k_i", "gate", "dt"])
    norm = _function([("const float inv2", 1 / sum(v * v for v in r))], r, r_c, prefix="n")
    q_next, up_next = quaternion.normalised_step(r, inv2)
    unit = _function([(f"const float q{i}", q_next[i]) for i in range(4)] + [(f"up[{i}]", up_next[i]) for i in range(3)],
                     r + (inv2,), r_c + ["inv2"], prefix="u")
    quat_step = {"lines": raw_step["lines"] + norm["lines"] + unit["lines"],
                 "ops": raw_step["ops"] + norm["ops"] + unit["ops"]}
    q_gyro, rate_gyro = quaternion.propagate_unnormalised(m)
    raw_gyro = _function([(f"const float {r_c[i]}", q_gyro[i]) for i in range(4)]
                         + [(f"e->rate[{i}]", rate_gyro[i]) for i in range(3)],
                         Q + B + gyro + (attitude.DT,), q_c + b_c + gyro_c + ["dt"])
    quat_propagate = {"lines": raw_gyro["lines"] + norm["lines"] + unit["lines"],
                      "ops": raw_gyro["ops"] + norm["ops"] + unit["ops"]}
    quat_gate = _function([("const float gate", quaternion.accel_gate(m))], Q + acc + (quaternion.INNOVATION,),
                          q_c + acc_c + ["innovation_scale"], prefix="g")
    corr, err = quaternion.link_error()
    link = _function([(f"c[{i}]", corr[i]) for i in range(4)] + [(f"err[{i}]", err[i]) for i in range(3)],
                     QH + (quaternion.LINK_SR, quaternion.LINK_CR, quaternion.LINK_SP, quaternion.LINK_CP)
                     + quaternion.FC_ERROR + (quaternion.LINK_K,),
                     qh_c + ["sr", "cr", "sp", "cp"] + [f"fc_error[{i}]" for i in range(3)] + ["k_link"])
    vec = lambda name: [f"{name}[{i}]" for i in range(3)]
    vel_predict = _function([(f"const float n{i}", v) for i, v in enumerate(velocity.predict(m))],
                            velocity.VEL + velocity.ACC_BIAS + acc + U + W + (attitude.DT,),
                            vec("e->v") + vec("e->accel_bias") + acc_c + vec("up") + vec("rate") + ["dt"], prefix="p")
    innov_e, innov_turn = velocity.innovation(m)
    vel_innovation = _function([(f"e[{i}]", v) for i, v in enumerate(innov_e)]
                               + [(f"turn[{i}]", v) for i, v in enumerate(innov_turn)],
                               QH + velocity.V_LEVEL + W + velocity.VEL_H,
                               qh_c + vec("v_level") + vec("rate") + vec("v_hist"), prefix="i")
    vel_along = _function([(f"r[{i}]", v) for i, v in enumerate(velocity.along_up())], QH + velocity.INNOV,
                          qh_c + vec("e"), prefix="a")
    tilt_bias = _function([(f"r[{i}]", v) for i, v in enumerate(velocity.tilt_as_bias())], QH + quaternion.ERR,
                          qh_c + vec("err"), prefix="b")
    accel_bias_up = _function([(f"bias[{i}]", v) for i, v in enumerate(velocity.accel_bias_update(m))],
                              velocity.ACC_BIAS + velocity.ALONG + (velocity.K_A,), vec("bias") + vec("r") + ["k_a"])
    quat_turn = _function([(f"const float r{i}", v) for i, v in enumerate(velocity.turned())], Q + velocity.TURN,
                          [f"q[{i}]" for i in range(4)] + vec("turn"), prefix="t")
    split = _split_step(m)
    q_arg = [f"q[{i}]" for i in range(4)]
    left = _function([(f"const float r{i}", v) for i, v in enumerate(quaternion.rotate_left())], Q + quaternion.CORR,
                     q_arg + [f"c[{i}]" for i in range(4)])
    bias_up = _function([(f"bias[{i}]", v) for i, v in enumerate(quaternion.bias_update(m))],
                        B + quaternion.ERR + (quaternion.LINK_KB,),
                        [f"bias[{i}]" for i in range(3)] + [f"err[{i}]" for i in range(3)] + ["k_bias"])
    up_acc = quaternion.from_up(attitude.mounting(m) * sp.Matrix(acc))
    point = quaternion.command_point(m)
    est_rate = quaternion.rate_of(m)
    return {
        "quat_step": quat_step,
        "quat_propagate": quat_propagate,
        "quat_gate": quat_gate,
        "quat_link": link,
        "quat_left": left,
        "vel_predict": vel_predict,
        "vel_innovation": vel_innovation,
        "vel_along": vel_along,
        "vel_tilt_bias": tilt_bias,
        "accel_bias_update": accel_bias_up,
        "quat_turn": quat_turn,
        "split_step": split,
        "bias_update": bias_up,
        "quat_from_acc": _function([(f"q[{i}]", up_acc[i]) for i in range(4)], acc, acc_c),
        "quat_up": _function([(f"up[{i}]", v) for i, v in enumerate(quaternion.up_of(Q))], Q, [f"q[{i}]" for i in range(4)]),
        "rate": _function([(f"rate[{i}]", est_rate[i]) for i in range(3)], gyro + B,
                          gyro_c + [f"bias[{i}]" for i in range(3)]),
        "point": _function([(f"p_base[{i}]", point[i]) for i in range(3)], U + W + p,
                           [f"up[{i}]" for i in range(3)] + [f"rate[{i}]" for i in range(3)] + p_c),
        "tilt": _function([("*roll", tilt[0]), ("*pitch", tilt[1])], acc, acc_c),
        "step": _function([("const float next_roll", step[0]), ("const float next_pitch", step[1])],
                          (attitude.roll, attitude.pitch) + acc + gyro + (attitude.DT,),
                          ["e->roll", "e->pitch"] + acc_c + gyro_c + ["dt"],
                          **angles),
        "to_base": _function([(f"p_base[{i}]", rot[i]) for i in range(3)], p, p_c, **angles),
        "mounting": [[float(v) for v in row] for row in attitude.mounting(m).tolist()],
    }


def urdf_context(m: config.Model):
    """The arm as a URDF chain (metres, radians): joint 1 about the base's -z at the base
    origin, joints 2 and 3 about -y (the arm's plane x-z at joint 1 = 0), each L below the last."""
    metres = lambda mm: f"{mm / 1000:.6g}"
    names = ("arm_joint1", "arm_joint2", "arm_joint3")
    links = ("arm_turret", "upper_arm", "forearm")
    parents = ("arm_base",) + links[:2]
    drops, lengths = (0.0, m.L1, m.L2), (m.L1, m.L2, m.L3)
    joints = [{"name": n, "parent": p, "child": c, "drop": metres(d), "axis": "0 0 -1" if k == 0 else "0 -1 0",
               "lower": f"{math.radians(lim.min_deg):.9g}", "upper": f"{math.radians(lim.max_deg):.9g}",
               "length": metres(length) if k else "", "half_length": metres(length / 2)}
              for k, (n, p, c, d, lim, length) in enumerate(zip(names, parents, links, drops, m.limits,
                                                                (0.0, m.L2, m.L3)))]
    xyz = lambda v: " ".join(f"{c:.6g}" for c in v)
    bodies = {name: {"mass": f"{b.kg:.6g}", "centre": xyz(b.centre),
                     **{f"i{a}{b_}": f"{b.inertia[i][j]:.6g}" for i, a in enumerate("xyz")
                        for j, b_ in enumerate("xyz") if j >= i},
                     "shapes": [{"centre": xyz(p.centre), "geometry": p.geometry} for p in parts]}
              for (name, b), parts in zip(inertia.link_bodies(m).items(), inertia.link_parts(m).values())}
    return {"joints": joints, "bodies": bodies, "offset": [metres(v) for v in m.mount_offset], "l1": metres(m.L1),
            "half_l1": metres(-m.L1 / 2), "l3": metres(m.L3),
            "velocity": f"{float(servo.rad_per_s(servo.speed_units(m.working_speed_rpm, m.servo_model), m.servo_model)):.6g}"}


def params_context(m: config.Model):
    """Model numbers the application uses as they are (units, register values, ms)."""
    ms = lambda s: round(s * 1000)
    lsb_per_g = config.accel_lsb_per_g(m.accel_range_g)
    gyro_rad_per_lsb = sp.pi * sp.Rational(m.gyro_range_dps, 32768) / 180      # gyro_dps_per_lsb
    cal = m.imu_calibration
    gyro_k = [gyro_rad_per_lsb / sp.nsimplify(sc, rational=True) for sc in cal.gyro_scale]
    undo_cross = (sp.eye(3) + sp.Matrix(3, 3, lambda i, j: sp.nsimplify(cal.gyro_cross_axis[i][j],
                                                                       rational=True))).inv()
    return {
        "park": [float32_literal(sp.rad(sp.nsimplify(d, rational=True))) for d in m.park_deg],
        "tuck": [float32_literal(sp.rad(sp.nsimplify(d, rational=True))) for d in tuck(m)],
        "leg_planes": [float32_literal(a) for a in collision.leg_planes(m)],
        "leg_half_width": float32_literal(sp.rad(sp.nsimplify(m.leg_half_width, rational=True))),
        "leg_distance": float32_literal(m.leg_distance),
        "lengths": [float32_literal(v) for v in (m.L1, m.L2, m.L3)],
        "park_speed": servo.speed_units(m.park_speed_rpm, m.servo_model),
        "transit_speed": servo.speed_units(m.transit_speed_rpm, m.servo_model),
        "working_speed": servo.speed_units(m.working_speed_rpm, m.servo_model),
        "bench_torque_limit": servo.bench_torque_limit(m),
        # how far the goals move per tick at each speed (the Moving Speed the register holds)
        "steps": {name: float32_literal(servo.rad_per_s(servo.speed_units(rpm, m.servo_model), m.servo_model)
                                       / sp.nsimplify(m.sample_rate, rational=True))
                  for name, rpm in (("park", m.park_speed_rpm), ("transit", m.transit_speed_rpm),
                                    ("working", m.working_speed_rpm))},
        "axis_hold": float32_literal(m.motion.axis_hold_radius),
        "axis_release": float32_literal(m.motion.axis_release_radius),
        "follow_window": float32_literal(sp.rad(sp.nsimplify(m.motion.follow_window_deg, rational=True))),
        "units_per_s_per_speed": float32_literal(servo.units_per_s_per_speed_unit(m)),
        "rad_per_unit": float32_literal(1 / servo.units_per_rad(m)),
        "step_per_decivolt": float32_literal(servo.supply_step_per_decivolt(m)),
        "gap_max": servo.gap_max_units(m),
        "track_tolerance": servo.track_tolerance_units(m),
        "angle_limits": [servo.unit_range(m, j) for j in range(3)],
        "baud_register": servo_models.baud_register(m.servo_model, m.servo_baud),
        "return_delay": m.servo_return_delay_us // 2,
        "boot_ms": ms(m.servo_boot_time),
        "silence_ms": ms(m.link_silence_timeout),
        "heartbeat_ms": ms(m.heartbeat_period),
        "frame_gap_ms": ms(m.link_frame_gap),
        "tick_us": round(1e6 / m.sample_rate),
        "smplrt_div": round(1000 / m.sample_rate) - 1,
        "dlpf_cfg": config.DLPF_BANDWIDTHS[m.dlpf_bandwidth],
        "accel_fs_sel": config.ACCEL_RANGES_G[m.accel_range_g],
        "gyro_fs_sel": config.GYRO_RANGES_DPS[m.gyro_range_dps],
        "accel_g_per_lsb": float32_literal(sp.Rational(1, lsb_per_g)),
        # calibrated: (counts / lsb_per_g - bias) / scale = counts * k + c, per IMU axis
        "accel_k": [float32_literal(1 / (lsb_per_g * sp.nsimplify(sc, rational=True)))
                    for sc in m.imu_calibration.accel_scale],
        "accel_c": [float32_literal(-sp.nsimplify(b, rational=True) / sp.nsimplify(sc, rational=True))
                    for b, sc in zip(m.imu_calibration.accel_bias, m.imu_calibration.accel_scale)],
        # calibrated: counts * rad_per_lsb / scale, per IMU axis (the offset is the estimator's)
        "gyro_k": [float32_literal(k) for k in gyro_k],
        # ... and the cross-axis sensitivity undone: rad/s = (I + C)^-1 diag(gyro_k) counts
        "gyro_cross": any(c != 0 for row in cal.gyro_cross_axis for c in row),
        "gyro_w": [[float32_literal(w) for w in undo_cross.row(i) * sp.diag(*gyro_k)] for i in range(3)],
        # the estimator's starting gyro bias, base axes, rad/s: the offset as the calibrated rate reads it
        "gyro_bias0": [float32_literal(v) for v in attitude.mounting(m) * undo_cross * sp.Matrix(
            [sp.pi * sp.nsimplify(d, rational=True) / (180 * sp.nsimplify(sc, rational=True))
             for d, sc in zip(cal.gyro_bias_dps, cal.gyro_scale)])],
        "est": estimator_params(m),
    }


def gate_params(e: config.Estimator) -> dict:
    """The drone messages' gate (stabiliser.c): the expected spreads times gate_sigmas, in
    radians and m/s, and its times in microseconds."""
    n = sp.nsimplify(e.gate_sigmas, rational=True)
    rad = lambda deg: sp.rad(sp.nsimplify(deg, rational=True))
    return {
        "gate_sigmas": float32_literal(n),
        "gate_attitude": float32_literal(n * rad(e.drone_attitude_noise_deg)),
        "gate_velocity": float32_literal(n * sp.nsimplify(e.drone_velocity_noise, rational=True)),
        # the IMU's velocity error per radian of tilt: g over the velocity correction's k_v
        "gate_velocity_per_rad": float32_literal(velocity.G / velocity.gains(e.velocity_bandwidth)["k_v"]),
        "gate_drift_per_us": float32_literal(n * rad(e.drift_dps) / 10 ** 6),
        "gate_drift_max": float32_literal(n * rad(e.drift_max_deg)),
        "reject_after_us": round(e.reject_after * 1e6),
        "retake_after_us": round(e.retake_after * 1e6),
        "correction_max_sin": float32_literal(sp.sin(rad(e.correction_max_deg))),
    }


def estimator_params(m: config.Model):
    e = m.estimator
    us = lambda s: round(s * 1e6)
    return {
        "quaternion": int(e.kind == "quaternion"),
        "drone_attitude": int(e.drone_attitude),
        "accel_gain": float32_literal(e.accel_gain),
        "bias_gain": float32_literal(e.bias_gain),
        "align_accel_gain": float32_literal(e.align_accel_gain),
        "align_bias_gain": float32_literal(e.align_bias_gain),
        "innovation_scale": float32_literal(1 / sp.sin(sp.rad(sp.nsimplify(e.accel_reject_deg, rational=True))) ** 2),
        "link_gain": float32_literal(e.link_gain),
        "link_bias_gain": float32_literal(e.link_bias_gain),
        "link_delay_min_us": us(e.link_delay_min),
        "link_delay_max_us": us(e.link_delay_max),
        "link_timeout_us": us(e.link_timeout),
        # ticks of history: the longest accepted delay, one more to interpolate, one spare
        "history": int(sp.ceiling(sp.nsimplify(e.link_delay_max, rational=True) * sp.nsimplify(m.sample_rate, rational=True))) + 2,
        "lead_time": float32_literal(e.lead_time),
        "drone_velocity": int(e.drone_velocity),
        "vel": {k: float32_literal(v) for k, v in {**velocity.gains(e.velocity_bandwidth),
                                                   **velocity.accel_bias_gains(e.accel_bias_bandwidth)}.items()},
        "accel_bias": int(e.accel_bias_bandwidth > 0),
        "link_gain_with_velocity": float32_literal(e.link_gain_with_velocity),
        "link_bias_gain_with_velocity": float32_literal(e.link_bias_gain_with_velocity),
        "fc_error_gain": float32_literal(e.fc_error_gain),
        "fc_error_max": float32_literal(sp.rad(sp.nsimplify(e.fc_error_max_deg, rational=True))),
        "fc_error_fade": float32_literal(velocity.split_noises(m)["fade"]),
        "accel_bias_attitude_gain": float32_literal(e.accel_bias_attitude_gain),
        # the split's Kalman filter: variances in rad^2 (a bias of b g tilts the estimate by b rad)
        "split_bias_var": float32_literal(velocity.split_noises(m)["bias_var"]),
        "split_fc_var": float32_literal(velocity.split_noises(m)["fc_var"]),
        "split_settle": float32_literal(velocity.settle_s(e.velocity_bandwidth)),
        **gate_params(e),
        # one time constant of the alignment, at most 1 s (the attitude at rest, the gyro's offset begun)
        "settle_samples": int(sp.ceiling(sp.nsimplify(m.sample_rate, rational=True)
                                         / sp.nsimplify(max(e.align_accel_gain, 1.0), rational=True))),
    }


def check_park(m: config.Model) -> None:
    """The parked pose must pass the same checks the firmware applies to every command."""
    # the pose at 40 digits: the checks decide by numbers, not by exact trigonometry
    q = [sp.rad(sp.nsimplify(d, rational=True)).evalf(40) for d in m.park_deg]
    geo = kinematics.fk_geometry(m, at=q)
    for what, cond in (("outside the joint limits", kinematics.joint_limits_ok(m, q)),
                       ("not below the body", collision.body_clear(m, geo)),
                       ("in a landing leg", collision.legs_clear(m, geo))):
        if not bool(cond):
            raise config.ModelError(f"{m.path}: park.q: the parked pose {list(m.park_deg)} deg is {what}")


def tuck(m: config.Model) -> tuple[float, float]:
    """Joints 2 and 3 (deg) of the pose in which the arm turns joint 1 to go round a leg: the
    park pose's if they keep the end effector and joint 3 inside the leg distance (and below
    the body) at every joint 1 angle with every joint off by up to the servos' zero tolerance,
    else hanging straight down (the loader refuses a model where neither does)."""
    q23 = pose_tolerance.tuck_deg(m, m.servo_zero_tolerance_deg)
    if q23 is None:
        raise config.ModelError(f"{m.path}: park.q: no pose to turn joint 1 past a leg in")
    return q23


def fastmath_context():
    k = approx.fit()
    lit = lambda vals: [float32_literal(v) for v in vals]
    return {"sin": lit(k.sin_poly), "cos": lit(k.cos_poly), "atan": lit(k.atan_poly),
            "pio2": lit(k.pio2_parts), "sincos_max": float32_literal(k.sincos_max),
            "two_over_pi": float32_literal(2 / sp.pi), "pi": float32_literal(sp.pi),
            "pi_2": float32_literal(sp.pi / 2), "pi_4": float32_literal(sp.pi / 4),
            "tan_pi_8": float32_literal(sp.tan(sp.pi / 8))}


URDF = "uavarm_arm.urdf"
MESSAGE_TABLE = "message_table.py"
ARM_STATUS = "ArmStatus.msg"
# the ROS package carries these too, so it builds and runs in any catkin workspace
ROS_COPIES = {URDF: Path("ros/uavarm_ros/urdf"), MESSAGE_TABLE: Path("ros/uavarm_ros/src/uavarm_link"),
              ARM_STATUS: Path("ros/uavarm_ros/msg")}

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
    "estimator.h": "estimator.h.j2",
    "estimator.c": "estimator.c.j2",
    "messages.h": "messages.h.j2",
    "messages.c": "messages.c.j2",
    URDF: "arm.urdf.j2",
    MESSAGE_TABLE: "message_table.py.j2",
    ARM_STATUS: "ArmStatus.msg.j2",
}


def render(model_path: Path = config.DEFAULT_MODEL) -> dict[str, str]:
    m = config.load(model_path)
    check_park(m)
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
        "est": estimator_context(m),
        "params": params_context(m),
        "urdf": urdf_context(m),
        "lit": float32_literal,
        "pi": sp.pi,
        "messages": messages.MESSAGES,
        "faults": messages.FAULTS,
        "sources": messages.SOURCES,
        "states": messages.STATES,
        "refusals": messages.REFUSALS,
        "reset_causes": messages.RESET_CAUSES,
        "types": messages.TYPES,
        "tx_max_payload": messages.TX_MAX_PAYLOAD,
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


def main(argv=None, prog: str = "python -m uavarm.codegen") -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0].replace(
        "python -m uavarm.codegen", prog))
    ap.add_argument("--model", type=Path, default=config.DEFAULT_MODEL,
                    help="model file, TOML (default: model/manipulator.toml)")
    ap.add_argument("--out", type=Path, default=GENERATED, help="output folder (default: generated/)")
    ap.add_argument("--check", action="store_true", help="write nothing; fail if the output is stale")
    ap.add_argument("--board", type=Path, default=None,
                    help="board project whose .ioc and main.h get the model's user constants "
                         "(default: firmware_stm32/ when --out is the default folder)")
    args = ap.parse_args(argv)
    default_out = args.out.resolve() == GENERATED.resolve()
    board = args.board or (board_ioc.BOARD if default_out else None)
    try:
        files = render(args.model)
        board_files = board_ioc.render(args.model, board) if board else {}
    except config.ModelError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    copies = ROS_COPIES if default_out else {}
    if args.check:
        d = diff(files, args.out) + (diff(board_files, board) if board else "")
        d += "".join(diff({name: files[name]}, ROOT / folder) for name, folder in copies.items())
        if d:
            sys.stdout.write(d)
            print(f"\n{args.out} is stale: run `{REGENERATE}`", file=sys.stderr)
            return 1
        print(f"{args.out} is up to date")
        return 0
    changed = write(files, args.out) + (board_ioc.write(board_files, board) if board else [])
    for name, folder in copies.items():
        path = ROOT / folder / name
        if not path.exists() or path.read_text() != files[name]:
            path.write_text(files[name])
            changed.append(str(folder / name))
    print(f"{args.out}: {len(files)} files, {len(changed)} changed" + (f" ({', '.join(changed)})" if changed else ""))
    return 0
