"""A context function of the model remembered by what it read of it.

The SymPy behind the kinematics, the filters and the estimator takes seconds each, and each
reads a few of the model's values (the kinematics the lengths, limits, body and legs; the
filters their cutoffs and the sample rate). A process that renders several models (a test
run's firmware variants, a sweep) edits a few keys between them: a context whose values are
all as they were is taken from the last time instead of worked out again.

`remembered(fn)` runs fn(m) on a stand-in for m that notes every attribute fn takes, through
nested dataclasses and tuples of them, with its value; a later m with the same value at every
one of those gets the same result. fn must be a pure function of m (what it reads of m and
constants of the generator's own modules); a result that keeps hold of the stand-in is not
remembered.
"""
from __future__ import annotations

import dataclasses
import functools


class _Reader:
    """Stands in for a dataclass instance; notes (path, value) of every attribute read."""

    def __init__(self, obj, path: tuple, notes: list):
        object.__setattr__(self, "_obj", obj)
        object.__setattr__(self, "_path", path)
        object.__setattr__(self, "_notes", notes)

    def __getattr__(self, name):
        value = getattr(self._obj, name)
        path = self._path + (name,)
        if dataclasses.is_dataclass(value):
            return _Reader(value, path, self._notes)
        if isinstance(value, tuple) and any(dataclasses.is_dataclass(v) for v in value):
            return tuple(_Reader(v, path + (i,), self._notes) if dataclasses.is_dataclass(v) else v
                         for i, v in enumerate(value))
        self._notes.append((path, value))
        return value

    def __setattr__(self, name, value):
        raise AttributeError("the model is read only")


def _value_at(obj, path: tuple):
    for step in path:
        obj = obj[step] if isinstance(step, int) else getattr(obj, step)
    return obj


def _same(a, b) -> bool:
    """Equal and of the same type, element by element (5 and 5.0 may print apart)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


def _holds_reader(value) -> bool:
    if isinstance(value, _Reader):
        return True
    if isinstance(value, dict):
        return any(_holds_reader(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return any(_holds_reader(v) for v in value)
    return False


def remembered(fn):
    memory: list[tuple[list, object]] = []     # (notes, result), newest first

    @functools.wraps(fn)
    def wrapper(m):
        for notes, result in memory:
            if all(_same(_value_at(m, path), value) for path, value in notes):
                return result
        notes: list = []
        result = fn(_Reader(m, (), notes))
        if not _holds_reader(result):
            memory.insert(0, (notes, result))
            del memory[8:]
        return result
    return wrapper
