"""The mutation operators: each finds places in the masked code of a span and proposes a
replacement text there.

| operator | what |
|---|---|
| relational | `<` `<=` `>` `>=` swapped with their strict/non-strict twin, `==` / `!=` negated |
| logic | `&&` / `||` (`and` / `or`) swapped; a `!` (`not`) removed |
| constant | an integer one up and one down; a decimal constant 1 % up and down (not indices) |
| sign | a binary `+` / `-` swapped (also `+=` / `-=`); a unary minus removed |
| condition | an `if`'s condition replaced by always-false and always-true |
| statement | a C statement line removed (an `if (...) return ...;` guard with it) |
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from .regions import Span


@dataclass(frozen=True)
class Mutant:
    path: str          # relative to the tree
    start: int
    end: int
    replacement: str
    operator: str
    original: str
    line: int
    column: int

    @property
    def id(self) -> str:
        """path:line:column:operator:original->replacement (readable, stable while the file is)."""
        return (f"{self.path}:{self.line}:{self.column}:{self.operator}:"
                f"{' '.join(self.original.split())}->{' '.join(self.replacement.split())}")

    def apply(self, text: str) -> str:
        return text[:self.start] + self.replacement + text[self.end:]


_REL = {"<": "<=", "<=": "<", ">": ">=", ">=": ">", "==": "!=", "!=": "=="}
_REL_TOKEN = re.compile(r"<<=|>>=|<<|>>|->|<=|>=|==|!=|<|>")
_NUMBER = re.compile(r"(?<![\w.])(0[xX][0-9a-fA-F]+|\d+\.\d*(?:[eE][-+]?\d+)?|\d+(?:[eE][-+]?\d+)?)([fFuU]?)(?![\w.])")
_BINARY_SIGN = re.compile(r"(?<=[\w)\]]) ([+-])(=?) (?=[\w(])")
_UNARY_MINUS = re.compile(r"(?:(?<=[(,=?:])|(?<=return)|(?<=[(,=?:] ))-(?=[\w(])")


def _line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _column(text: str, pos: int) -> int:
    return pos - text.rfind("\n", 0, pos)


def relational(masked: str, span: Span):
    for m in _REL_TOKEN.finditer(masked, span.start, span.end):
        tok = m.group(0)
        if tok in _REL:
            yield m.start(), m.end(), _REL[tok], "relational"


def logic(masked: str, span: Span, python: bool):
    pairs = {"and": "or", "or": "and"} if python else {"&&": "||", "||": "&&"}
    pattern = r"\b(and|or)\b" if python else r"&&|\|\|"
    for m in re.finditer(pattern, masked[:span.end]):
        if m.start() >= span.start:
            yield m.start(), m.end(), pairs[m.group(0)], "logic"
    pattern = r"\bnot\s+" if python else r"!(?!=)\s*"
    for m in re.finditer(pattern, masked[:span.end]):
        if m.start() >= span.start:
            yield m.start(), m.end(), "", "logic"


def _scaled(number: str, factor: float) -> str:
    v = float(number) * factor
    return repr(v) if "e" not in repr(v) else f"{v:.9g}"


def constant(masked: str, span: Span):
    for m in _NUMBER.finditer(masked, span.start, span.end):
        number, suffix = m.group(1), m.group(2)
        if masked[m.start() - 1] == "[" and masked[m.end()] == "]":
            continue   # an index or an array's size, not a limit or threshold
        if number.lower().startswith("0x"):
            n = int(number, 16)
            yield m.start(), m.end(), f"{hex(n + 1)}{suffix}", "constant"
            if n > 0:
                yield m.start(), m.end(), f"{hex(n - 1)}{suffix}", "constant"
        elif re.fullmatch(r"\d+", number) and suffix.lower() != "f":
            n = int(number)
            yield m.start(), m.end(), f"{n + 1}{suffix}", "constant"
            if n > 0:
                yield m.start(), m.end(), f"{n - 1}{suffix}", "constant"
        elif float(number) != 0.0:
            for factor in (1.01, 0.99):
                yield m.start(), m.end(), _scaled(number, factor) + suffix, "constant"


def sign(masked: str, span: Span):
    for m in _BINARY_SIGN.finditer(masked, span.start, span.end):
        swapped = "-" if m.group(1) == "+" else "+"
        yield m.start(1), m.start(1) + 1, swapped, "sign"
    for m in _UNARY_MINUS.finditer(masked, span.start, span.end):
        yield m.start(), m.end(), "", "sign"


def _closing(masked: str, open_at: int) -> int:
    depth = 0
    for i in range(open_at, len(masked)):
        depth += {"(": 1, ")": -1}.get(masked[i], 0)
        if depth == 0:
            return i
    return -1


def condition(masked: str, span: Span, python: bool):
    if python:
        for m in re.finditer(r"\b(if|elif|while)\s+(.+?):[ \t]*(\n|$)", masked[:span.end], re.M):
            if m.start() >= span.start and "lambda" not in m.group(2):
                for value in ("False", "True"):
                    yield m.start(2), m.end(2), value, "condition"
        return
    for m in re.finditer(r"\bif\s*\(", masked[:span.end]):
        if m.start() < span.start:
            continue
        close = _closing(masked, m.end() - 1)
        if close > 0:
            for value in ("0", "1"):
                yield m.end(), close, value, "condition"


_DECLARATION = re.compile(r"^\s*(const\s+|static\s+)*(float|int|bool|unsigned|uint\d+_t|int\d+_t|size_t|char|"
                          r"double|[a-z_]+_t)\b[^=(]*[=;]")


def statement(masked: str, span: Span):
    pos = span.start
    for line in masked[span.start:span.end].splitlines(keepends=True):
        code = line.strip()
        simple = code.endswith(";") and "{" not in code and "}" not in code
        if simple and not _DECLARATION.match(line) and not code.startswith(("return", "for", "while", "do", "else")):
            yield pos, pos + len(line), "\n", "statement"
        pos += len(line)


def mutants(rel_path: str, text: str, masked: str, spans, python: bool):
    """Every mutant of the spans, in file order, each place and replacement once."""
    seen, out = set(), []
    for span in spans:
        gens = [relational(masked, span), logic(masked, span, python), constant(masked, span), sign(masked, span),
                condition(masked, span, python)]
        if not python:
            gens.append(statement(masked, span))
        for gen in gens:
            for start, end, replacement, op in gen:
                key = (start, end, replacement)
                if key in seen or text[start:end] == replacement:
                    continue
                seen.add(key)
                out.append(Mutant(rel_path, start, end, replacement, op, text[start:end], _line(text, start),
                                  _column(text, start)))
    return sorted(out, key=lambda mu: (mu.start, mu.operator, mu.replacement))
