"""The generated FK/IK run on an emulated Cortex-M4F (uavarm.m4) and agree with the host
build to a few float32 ulps (the scale of an ulp is that of the output's range: positions
~128 mm, angles ~pi). With -std=c99 GCC contracts no a*b+c into vfma, so in practice the
two agree bit for bit; the tolerance leaves room for a compiler that does."""
import numpy as np
import pytest

from conftest import require_arm_toolchain
from uavarm import m4
from uavarm.build import generated, target

N = 120
MAX_ULPS = 8
ULP_MM = float(np.spacing(np.float32(128.0)))     # 7.6e-6 mm
ULP_RAD = float(np.spacing(np.float32(np.pi)))    # 2.4e-7 rad


@pytest.fixture(scope="module")
def m4build():
    require_arm_toolchain()
    return m4.build([str(s) for s in generated.sources()], ["kin_fk_ee", "kin_ik"],
                    cflags=target.M4_CFLAGS + [f"-I{generated.GENERATED}"])


def test_fk_on_target_matches_host(m4build, gen, model):
    ffi, lib = gen
    rng = np.random.default_rng(12)
    worst = 0.0
    for q in rng.uniform(-np.pi, np.pi, size=(N, 3)).astype(np.float32):
        r = m4build.call("kin_fk_ee", [m4.Arr("float", q.tolist()), m4.Arr("float", 3)], ret="void")
        host = ffi.new("float[3]")
        lib.kin_fk_ee(ffi.new("float[3]", q.tolist()), host)
        worst = max(worst, np.max(np.abs(np.array(r.arrays[1]) - np.array(list(host)))) / ULP_MM)
    print(f"FK target vs host: {worst:.1f} ulp")
    assert worst <= MAX_ULPS


def test_ik_on_target_matches_host(m4build, gen, model):
    ffi, lib = gen
    rng = np.random.default_rng(13)
    worst = 0.0
    for _ in range(N):
        d = rng.normal(size=3)
        p = (d / np.linalg.norm(d) * rng.uniform(20.0, 150.0) + [0, 0, -model.L1]).astype(np.float32)
        r = m4build.call("kin_ik", [m4.Arr("float", p.tolist()), m4.Arr("float", 3), m4.Arr("uint32", 14)],
                       ret="int")
        raw = np.array(r.arrays[2], dtype=np.uint32).tobytes()
        q_target = np.frombuffer(raw[:48], dtype=np.float32).reshape(4, 3)
        status_target = list(raw[48:52])
        out = ffi.new("kin_ik_t *")
        sel = lib.kin_ik(ffi.new("float[3]", p.tolist()), ffi.new("float[3]"), out)
        q_host = np.frombuffer(ffi.buffer(out.q), dtype=np.float32).reshape(4, 3)
        assert status_target == list(out.status) and r.ret == sel
        worst = max(worst, np.max(np.abs(q_target - q_host)) / ULP_RAD)
    print(f"IK target vs host: {worst:.1f} ulp")
    assert worst <= MAX_ULPS
