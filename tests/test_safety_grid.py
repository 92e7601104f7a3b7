"""Exhaustive safety (issue "Robustness", item 3): over a dense grid of targets, inside and
outside the reachable region, and of drone tilts up to +-30 deg, the solution the firmware
would command never violates a joint limit, the body or a leg; checked by plain geometry,
for the firmware's C path and for the SymPy model."""
import math

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

from conftest import ROOT
from oracles import check_pose
from uavarm import cbuild, firmware, generated
from uavarm.model import collision, config, kinematics, servo

HARNESS = ROOT / "tests" / "csrc"
TILTS_DEG = np.arange(-30.0, 30.1, 10.0)
MARGIN = 1e-4            # mm / rad: closer to a boundary, float32 may decide either way


def grid(m):
    reach = m.L2 + m.L3 + m.L1
    xs = np.arange(-reach - 20.0, reach + 20.1, 8.0)
    zs = np.arange(-reach - 60.0, m.body_z + 40.1, 8.0)
    x, y, z = np.meshgrid(xs, xs, zs, indexing="ij")
    targets = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    r, p = np.meshgrid(np.radians(TILTS_DEG), np.radians(TILTS_DEG), indexing="ij")
    tilts = np.stack([r.ravel(), p.ravel()], axis=1)
    return targets, tilts


@pytest.fixture(scope="module")
def harness():
    sources = firmware.app_sources() + [HARNESS / "safety_grid.c"]
    return cbuild.load("safety_grid", sources, [HARNESS / "safety_grid.h"],
                       include_dirs=[generated.GENERATED, firmware.APP / "Inc", HARNESS])


def assert_safe(m, q, what):
    status, clear = check_pose(m, q, margin=MARGIN)
    bad = (status != 0) & clear
    assert not bad.any(), f"{what}: {bad.sum()} unsafe commands, e.g. {np.degrees(q[bad][:3])} deg"
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    assert np.all((q >= lo - 1e-6) & (q <= hi + 1e-6)), f"{what}: a joint past its limit"
    return int((~clear).sum())


def test_firmware_path_never_commands_an_unsafe_pose(harness):
    ffi, lib = harness
    m = config.load()
    targets, tilts = grid(m)
    t32 = np.ascontiguousarray(targets, dtype=np.float32)
    a32 = np.ascontiguousarray(tilts, dtype=np.float32)
    n = len(targets) * len(tilts)
    q = np.empty((n, 3), dtype=np.float32)
    units = np.zeros((n, 3), dtype=np.uint16)
    commands = lib.safety_grid(ffi.from_buffer("float[]", t32), len(targets), ffi.from_buffer("float[]", a32),
                               len(tilts), ffi.from_buffer("float[]", q), ffi.from_buffer("uint16_t[]", units))
    valid = ~np.isnan(q[:, 0])
    assert valid.sum() == commands and 0 < commands < n
    near = assert_safe(m, q[valid].astype(np.float64), "firmware")
    # and the servo positions sent are those of the checked joints, inside the joint limits
    for j in range(3):
        lo, hi = servo.unit_range(m, j)
        assert units[valid, j].min() >= lo and units[valid, j].max() <= hi
    print(f"\nfirmware path: {len(targets)} targets x {len(tilts)} tilts = {n} solves, {commands} commands, "
          f"0 unsafe ({near} within {MARGIN} of a boundary, checked against the limits only)")


def model_solutions(m, p_base, q_now):
    """The SymPy model's IK (lambdified, float64) with its checks and nearest-valid selection."""
    ikm = kinematics.ik(m)
    xyz = kinematics.TARGET_SYMBOLS
    exprs = [ikm.disc >= 0]
    for cand in ikm.candidates:
        exprs += list(cand.q) + [kinematics.joint_limits_ok(m, cand.q), collision.body_clear(m, cand.geometry),
                                 collision.legs_clear(m, cand.geometry)]
    f = sp.lambdify(xyz, exprs, modules="numpy")
    out = f(p_base[:, 0], p_base[:, 1], p_base[:, 2])
    reach = np.broadcast_to(out[0], len(p_base))
    best = np.full((len(p_base), 3), np.nan)
    best_d = np.full(len(p_base), np.inf)
    for k in range(4):
        q = np.stack([np.broadcast_to(v, len(p_base)) for v in out[1 + 6 * k:4 + 6 * k]], axis=1).astype(float)
        ok = reach & np.all([np.broadcast_to(v, len(p_base)) for v in out[4 + 6 * k:7 + 6 * k]], axis=0)
        d = np.sum((q - q_now) ** 2, axis=1)
        take = ok & (d < best_d)
        best[take], best_d[take] = q[take], d[take]
    return best


def test_model_never_selects_an_unsafe_pose():
    m = config.load()
    targets, tilts = grid(m)
    targets = targets[::3]          # the lambdified model is slower; every third target
    park = np.radians(m.park_deg)
    chosen, near = 0, 0
    for roll, pitch in tilts:
        # p_base = (Ry(pitch) Rx(roll))^T (o + p_level) - o, from scipy (o: the mount offset)
        r_wb = Rotation.from_euler("YX", [pitch, roll]).as_matrix()
        o = np.array(m.mount_offset)
        q = model_solutions(m, (targets + o) @ r_wb - o, park)
        valid = ~np.isnan(q[:, 0])
        chosen += int(valid.sum())
        near += assert_safe(m, q[valid], f"model at roll {math.degrees(roll):.0f}, pitch {math.degrees(pitch):.0f}")
    print(f"\nmodel: {len(targets)} targets x {len(tilts)} tilts, {chosen} selected, 0 unsafe "
          f"({near} within {MARGIN} of a boundary)")
