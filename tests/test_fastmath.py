"""The generated sin/cos/atan2 kernels against mpmath."""
import math

import mpmath as mp
import numpy as np

ULP_PI = np.spacing(np.float32(np.pi))     # 2.4e-7: one float32 step near pi


def test_sincos_accuracy(gen):
    ffi, lib = gen
    rng = np.random.default_rng(8)
    xs = np.concatenate([rng.uniform(-2 * np.pi, 2 * np.pi, 50_000),
                         rng.uniform(-2000, 2000, 2_000),
                         np.arange(-16, 17) * np.pi / 4]).astype(np.float32)
    s, c = ffi.new("float *"), ffi.new("float *")
    worst_small = worst_big = 0.0
    for x in xs:
        lib.fm_sincosf_ref(float(x), s, c)
        xm = mp.mpf(float(x))
        err = max(abs(s[0] - float(mp.sin(xm))), abs(c[0] - float(mp.cos(xm))))
        if abs(x) <= 2 * np.pi:
            worst_small = max(worst_small, err)
        else:
            worst_big = max(worst_big, err)
    print(f"sincos max abs error: {worst_small:.2e} (|x| <= 2 pi), {worst_big:.2e} (|x| <= 2000)")
    assert worst_small <= 2.5e-7
    assert worst_big <= 1e-6


def test_sincos_out_of_domain_is_nan(gen):
    ffi, lib = gen
    s, c = ffi.new("float *"), ffi.new("float *")
    for x in (3000.0, -1e30, math.inf, math.nan):
        lib.fm_sincosf_ref(x, s, c)
        assert math.isnan(s[0]) and math.isnan(c[0])


def test_atan2_accuracy_and_range(gen):
    ffi, lib = gen
    rng = np.random.default_rng(9)
    pts = rng.normal(size=(50_000, 2)) * rng.choice([1e-3, 1.0, 1e3], size=(50_000, 1))
    special = [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0), (1.0, 1.0), (-1.0, -1.0),
               (0.0, 0.0), (1e-30, -1.0), (-1e-30, -1.0), (1.0, -1e-30)]
    worst = 0.0
    pi32 = float(np.float32(np.pi))           # the float32 nearest pi is slightly above pi
    for y, x in np.concatenate([pts, special]).astype(np.float32):
        got = lib.fm_atan2f_ref(float(y), float(x))
        want = float(mp.atan2(mp.mpf(float(y)), mp.mpf(float(x))))
        worst = max(worst, abs(got - want))
        assert -pi32 <= got <= pi32
    print(f"atan2 max abs error: {worst:.2e} rad ({worst / ULP_PI:.2f} ulp at pi)")
    assert worst <= 2 * ULP_PI


def test_atan2_conventions(gen):
    ffi, lib = gen
    pi32 = float(np.float32(np.pi))
    assert lib.fm_atan2f_ref(-0.0, -1.0) == pi32      # (-pi, pi]: +pi, not -pi
    assert lib.fm_atan2f_ref(0.0, 0.0) == 0.0
    assert math.isnan(lib.fm_atan2f_ref(math.nan, 1.0))
    assert math.isnan(lib.fm_atan2f_ref(1.0, math.nan))
