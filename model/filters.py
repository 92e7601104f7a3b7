"""Butterworth low-pass stages, designed symbolically.

The analogue Butterworth prototype of order N is split into second-order sections
(s^2 + 2 sin((2k-1) pi / 2N) s + 1, plus s + 1 when N is odd) and each section is mapped
to z by the bilinear transform with the cut-off pre-warped, so the digital filter's -3 dB
point lands exactly on the requested frequency. Every section has unit DC gain.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .config import Filter, Model

zi = sp.Symbol("zi")   # z^-1


@dataclass(frozen=True)
class Section:
    b: tuple   # numerator coefficients of z^0, z^-1, z^-2 (exact SymPy numbers)
    a: tuple   # denominator coefficients, a[0] == 1


def analog_sections(order: int):
    s = sp.Symbol("s")
    polys = [s**2 + 2 * sp.sin((2 * k - 1) * sp.pi / (2 * order)) * s + 1
             for k in range(1, order // 2 + 1)]
    if order % 2:
        polys.append(s + 1)
    return s, polys


def design(f: Filter, sample_rate: float) -> tuple[Section, ...]:
    s, polys = analog_sections(f.order)
    # pre-warped bilinear map of the normalised analogue variable: s -> (1 - z^-1) / (K (1 + z^-1))
    K = sp.tan(sp.pi * sp.nsimplify(f.cutoff, rational=True) / sp.nsimplify(sample_rate, rational=True))
    sections = []
    for poly in polys:
        h = sp.together((1 / poly).subs(s, (1 - zi) / (K * (1 + zi))))
        num, den = sp.fraction(h)
        num = sp.Poly(sp.expand(num), zi).all_coeffs()[::-1]
        den = sp.Poly(sp.expand(den), zi).all_coeffs()[::-1]
        num += [0] * (3 - len(num))
        den += [0] * (3 - len(den))
        a0 = den[0]
        sections.append(Section(b=tuple(sp.simplify(c / a0) for c in num),
                                a=tuple(sp.simplify(c / a0) for c in den)))
    return tuple(sections)


def steady_state(section: Section):
    """Transposed direct-form II state (s1, s2) holding a constant input x0 = 1 at rest."""
    b0, b1, b2 = section.b
    _, a1, a2 = section.a
    return (sp.simplify(1 - b0), sp.simplify(b2 - a2))


def sensor_filters(m: Model) -> dict[str, tuple[Section, ...]]:
    return {"accel": design(m.accel_filter, m.sample_rate),
            "gyro": design(m.gyro_filter, m.sample_rate)}
