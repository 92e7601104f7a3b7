"""Generated Butterworth filters against scipy.signal (butter + sosfilt), in float32."""
import numpy as np
import pytest
import scipy.signal as ss
import sympy as sp

from uavarm.model import filters

TOL = 1e-6   # relative to the largest output magnitude


def run_c(gen, name, xs, x0=None):
    ffi, lib = gen
    st = ffi.new(f"filt_{name}_t *")
    if x0 is not None:
        getattr(lib, f"filt_{name}_reset")(st, float(x0))
    step = getattr(lib, f"filt_{name}_step")
    return np.array([step(st, float(x)) for x in xs])


def reference(model, name):
    spec = model.accel_filter if name == "accel" else model.gyro_filter
    return ss.butter(spec.order, spec.cutoff, fs=model.sample_rate, output="sos")


@pytest.mark.parametrize("name", ["accel", "gyro"])
@pytest.mark.parametrize("signal", ["step", "impulse", "noise"])
def test_filter_matches_scipy(model, gen, name, signal):
    rng = np.random.default_rng(7)
    n = 2000
    xs = {"step": np.ones(n), "impulse": np.eye(1, n)[0] * 100.0,
          "noise": rng.normal(0, 9.81, n)}[signal].astype(np.float32)
    want = ss.sosfilt(reference(model, name), xs.astype(np.float64))
    got = run_c(gen, name, xs)
    rel = np.max(np.abs(got - want)) / np.max(np.abs(want))
    print(f"{name} {signal}: max relative error {rel:.2e}")
    assert rel <= TOL


@pytest.mark.parametrize("name", ["accel", "gyro"])
def test_reset_starts_at_rest(model, gen, name):
    """reset(x0) is scipy's steady state: a constant input then passes unchanged."""
    x0 = 9.81
    sos = reference(model, name)
    want, _ = ss.sosfilt(sos, np.full(300, x0), zi=ss.sosfilt_zi(sos) * x0)
    got = run_c(gen, name, np.full(300, x0, dtype=np.float32), x0=x0)
    assert np.max(np.abs(got - want)) <= TOL * x0


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5])
def test_symbolic_design_matches_scipy_for_any_order(model, order):
    from uavarm.model.config import Filter
    sections = filters.design(Filter(cutoff=12.5, order=order), 100.0)
    b, a = np.array([1.0]), np.array([1.0])
    for s in sections:
        b = np.polymul(b, [float(v) for v in s.b])
        a = np.polymul(a, [float(v) for v in s.a])
        assert sp.simplify(sum(s.b) / sum(s.a)) == 1          # unit DC gain, exactly
    bw, aw = ss.butter(order, 12.5, fs=100.0)
    n = max(len(b), len(bw))
    pad = lambda v: np.pad(v, (0, n - len(v)))
    assert np.allclose(pad(np.trim_zeros(b, "b")), pad(bw), atol=1e-13)
    assert np.allclose(pad(np.trim_zeros(a, "b")), pad(aw), atol=1e-13)
