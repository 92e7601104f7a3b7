"""A float32 C printer and the common-subexpression pass that feeds the templates.

SymPy's C99 printer emits `M_PI`, double literals and `pow(x, 3)`; this one prints every
number as the nearest float32 literal with an `f` suffix (folding rationals and pi at
generation time), small integer powers as products, square roots as `sqrtf`, and the
trig the model uses through the generated fast kernels of fastmath.h.
"""
from __future__ import annotations

import numpy as np
import sympy as sp
from sympy.printing.c import C99CodePrinter

FUNCTION_NAMES = {
    "atan2": "fm_atan2f",
    "Abs": "fabsf",
    "Max": "fm_maxf",
    "Min": "fm_minf",
}


def float32_literal(value) -> str:
    """Shortest decimal that reads back as the float32 nearest to `value`."""
    f32 = np.float32(float(sp.sympify(value).evalf(40)))
    if not np.isfinite(f32):
        raise ValueError(f"constant {value} does not fit a float32")
    text = np.format_float_positional(f32, unique=True, trim="0")
    if "e" not in text and len(text.replace("-", "").lstrip("0.")) > 12:
        text = np.format_float_scientific(f32, unique=True, trim="0")
    return text + "f"


class Float32Printer(C99CodePrinter):
    def __init__(self):
        super().__init__({"strict": False})

    def _print_Float(self, expr):
        return float32_literal(expr)

    def _print_Rational(self, expr):
        return float32_literal(expr)

    def _print_Integer(self, expr):
        return float32_literal(expr)

    def _print_NumberSymbol(self, expr):
        return float32_literal(expr)

    _print_Pi = _print_NumberSymbol
    _print_Exp1 = _print_NumberSymbol

    def _print_Pow(self, expr):
        base, exp = expr.as_base_exp()
        b = self.parenthesize(base, sp.printing.precedence.PRECEDENCE["Mul"] + 1)
        if exp == sp.Rational(1, 2):
            return f"sqrtf({self._print(base)})"
        if exp == -sp.Rational(1, 2):
            return f"(1.0f / sqrtf({self._print(base)}))"
        if exp.is_Integer and 1 <= int(exp) <= 4:
            return "*".join([b] * int(exp))
        if exp.is_Integer and -4 <= int(exp) <= -1:
            return f"(1.0f / ({'*'.join([b] * -int(exp))}))"
        return f"powf({self._print(base)}, {self._print(exp)})"

    def _print_Function(self, expr):
        name = type(expr).__name__
        if name in FUNCTION_NAMES:
            return f"{FUNCTION_NAMES[name]}({', '.join(self._print(a) for a in expr.args)})"
        raise ValueError(f"no float32 C kernel for {name}: extend codegen/printer.py")

    _print_Abs = _print_Function
    _print_Max = _print_Function
    _print_Min = _print_Function
    _print_atan2 = _print_Function

    def _print_sin(self, expr):
        raise ValueError("sin/cos must be replaced by fm_sincosf results before printing")

    _print_cos = _print_sin

    def _print_And(self, expr):
        return self._join_bool(expr, " && ")

    def _print_Or(self, expr):
        return self._join_bool(expr, " || ")

    def _join_bool(self, expr, op):
        # parenthesise every compound operand: clear to read, and -Wparentheses stays quiet
        parts = []
        for arg in sorted(expr.args, key=sp.default_sort_key):
            text = self._print(arg)
            parts.append(f"({text})" if isinstance(arg, (sp.And, sp.Or)) else text)
        return op.join(parts)

    def _print_Piecewise(self, expr):
        if expr.args[-1].cond != True:
            raise ValueError("Piecewise needs a final (value, True) branch")
        text = self._print(expr.args[-1].expr)
        for value, cond in reversed(expr.args[:-1]):
            text = f"(({self._print(cond)}) ? {self._print(value)} : {text})"
        return text

    def _print_BooleanTrue(self, expr):
        return "true"

    def _print_BooleanFalse(self, expr):
        return "false"


PRINTER = Float32Printer()


def c(expr) -> str:
    return PRINTER.doprint(expr)


def temp_line(sym, expr) -> str:
    """The C declaration of a CSE temporary: `const bool` for relations, else `const float`."""
    ctype = "bool" if isinstance(expr, (sp.logic.boolalg.Boolean, sp.core.relational.Relational)) else "float"
    return f"const {ctype} {sym} = {c(expr)};"


def cse_lines(outputs, prefix="t"):
    """Run CSE over [(lvalue, expr)] and return (temporaries, assignments) as C text.

    Temporaries are `const float` (or `const bool` for relations) locals named prefix0..N.
    """
    names = [lhs for lhs, _ in outputs]
    exprs = [sp.sympify(e) for _, e in outputs]
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols(prefix), order="canonical")
    temps = [temp_line(sym, expr) for sym, expr in replacements]
    assigns = [f"{lhs} = {c(expr)};" for lhs, expr in zip(names, reduced)]
    return temps, assigns


def op_count(exprs) -> int:
    """Operation count after CSE, for the generated files' headers."""
    replacements, reduced = sp.cse([sp.sympify(e) for e in exprs], order="canonical")
    return int(sum(sp.count_ops(e) for _, e in replacements) + sum(sp.count_ops(e) for e in reduced))
