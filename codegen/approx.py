"""Polynomial kernels for sin, cos and atan, fitted at generation time.

newlib's sinf and atan2f cost 57 and ~170 cycles on the Cortex-M4; the kinematics needs
six trig values per FK and six atan2 per IK. These kernels reach float32 accuracy on a
reduced range for a fraction of that. Coefficients are interpolated at Chebyshev nodes in
mpmath (pure Python, so the generated text is the same on every machine); the tests check
the resulting float32 kernels against mpmath, not these fits.
"""
from __future__ import annotations

from dataclasses import dataclass

import mpmath as mp

mp.mp.dps = 40


def _chebyshev_fit(g, w_max, n_coeffs):
    """Coefficients c[0..n-1] of sum c_k w^k interpolating g at Chebyshev nodes of [0, w_max]."""
    nodes = [w_max / 2 * (1 - mp.cos(mp.pi * (2 * k + 1) / (2 * n_coeffs))) for k in range(n_coeffs)]
    A = mp.matrix([[w**k for k in range(n_coeffs)] for w in nodes])
    rhs = mp.matrix([g(w) for w in nodes])
    return [mp.mpf(v) for v in mp.lu_solve(A, rhs)]


@dataclass(frozen=True)
class Kernels:
    sin_poly: list       # sin(r) = r + r^3 * P(r^2), |r| <= pi/4
    cos_poly: list       # cos(r) = 1 - r^2/2 + r^4 * Q(r^2)
    atan_poly: list      # atan(t) = t + t^3 * R(t^2), |t| <= tan(pi/8)
    pio2_parts: list     # pi/2 split in three, the first two short enough to multiply k exactly
    sincos_max: float    # |x| beyond which fm_sincosf returns NaN rather than lose accuracy


def _split_pio2():
    """Cody-Waite split of pi/2: hi and mid carry 12 significant bits, so k * part is
    exact in float32 for |k| < 2^12."""
    parts, rest = [], mp.pi / 2
    for _ in range(2):
        exponent = int(mp.floor(mp.log(abs(rest), 2)))
        step = mp.mpf(2) ** (exponent - 11)
        part = mp.floor(rest / step) * step
        parts.append(part)
        rest -= part
    parts.append(rest)
    return parts


SINCOS_MAX = 2048.0   # fm_sincosf's domain (Kernels.sincos_max)


def fit() -> Kernels:
    r_max2 = (mp.pi / 4) ** 2
    t_max2 = mp.tan(mp.pi / 8) ** 2
    sin_poly = _chebyshev_fit(lambda w: (mp.sin(mp.sqrt(w)) - mp.sqrt(w)) / w ** 1.5, r_max2, 3)
    cos_poly = _chebyshev_fit(lambda w: (mp.cos(mp.sqrt(w)) - 1 + w / 2) / w**2, r_max2, 3)
    atan_poly = _chebyshev_fit(lambda w: (mp.atan(mp.sqrt(w)) - mp.sqrt(w)) / w ** 1.5, t_max2, 4)
    return Kernels(sin_poly, cos_poly, atan_poly, _split_pio2(), sincos_max=SINCOS_MAX)
