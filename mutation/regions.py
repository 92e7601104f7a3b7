"""Where in a source file mutants may go: the text of named functions (C or Python) or of
a marked span of a template, with comments, strings and template tags blanked out so that
the operators only see code. Blanking keeps every offset, so a position in the masked text
is the same position in the file."""
from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Span:
    start: int
    end: int


def _blank(text: str, pattern: str, flags=0) -> str:
    return re.sub(pattern, lambda m: re.sub(r"[^\n]", " ", m.group(0)), text, flags=flags)


def mask_c(text: str) -> str:
    """Comments, string and character literals and preprocessor lines blanked."""
    text = _blank(text, r"/\*.*?\*/", re.S)
    text = _blank(text, r"//[^\n]*")
    text = _blank(text, r'"(?:\\.|[^"\\\n])*"')
    text = _blank(text, r"'(?:\\.|[^'\\\n])*'")
    return _blank(text, r"^[ \t]*#[^\n]*", re.M)


def mask_template(text: str) -> str:
    """As mask_c, and Jinja2 tags ({{ }}, {% %}, {# #}) blanked too."""
    text = _blank(text, r"\{#.*?#\}|\{%.*?%\}|\{\{.*?\}\}", re.S)
    return mask_c(text)


def mask_python(text: str) -> str:
    """Comments and string literals (docstrings included) blanked."""
    text = _blank(text, r'""".*?"""|\'\'\'.*?\'\'\'', re.S)
    text = _blank(text, r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'')
    return _blank(text, r"#[^\n]*")


def c_function(masked: str, name: str) -> Span:
    """The body (braces included) of C function `name`'s definition."""
    m = re.search(rf"^[A-Za-z_][^\n;]*\b{re.escape(name)}\([^;{{]*?\)\s*\{{", masked, re.M | re.S)
    if m is None:
        raise LookupError(f"no definition of {name}()")
    start = m.end() - 1
    depth = 0
    for i in range(start, len(masked)):
        depth += {"{": 1, "}": -1}.get(masked[i], 0)
        if depth == 0:
            return Span(start, i + 1)
    raise LookupError(f"{name}(): unbalanced braces")


def python_function(masked: str, name: str) -> Span:
    """The body of Python function `name` (up to the next line indented no deeper)."""
    m = re.search(rf"^([ \t]*)def {re.escape(name)}\(", masked, re.M)
    if m is None:
        raise LookupError(f"no def {name}")
    indent = len(m.group(1))
    body = masked.index(":\n", m.end()) + 2
    pos = body
    for line in masked[body:].splitlines(keepends=True):
        if line.strip() and len(line) - len(line.lstrip()) <= indent:
            break
        pos += len(line)
    return Span(body, pos)


def marked(masked_or_raw: str, first: str, last: str) -> Span:
    """From the line matching regex `first` to the end of the line matching `last` after it."""
    a = re.search(first, masked_or_raw, re.M)
    if a is None:
        raise LookupError(f"no line matching {first!r}")
    b = re.compile(last, re.M).search(masked_or_raw, a.end())
    if b is None:
        raise LookupError(f"no line matching {last!r} after {first!r}")
    return Span(masked_or_raw.rfind("\n", 0, a.start()) + 1, masked_or_raw.find("\n", b.end()) + 1)
