"""What a stored record may hold: values that JSON carries both ways and every client can read.

Python's json module reads `NaN`, `Infinity`, `1e999` (as infinity) and `"\\ud800"` (a lone
surrogate, which no UTF-8 text can hold) without complaint; a record holding one is stored, then
cannot be written back as a response. Request bodies are checked with `json_problem` before
anything is queued, and records read from the job database again before they are served.
"""

from __future__ import annotations

import math
from typing import Any

MAX_DEPTH = 32  # objects and lists within each other
MAX_NODES = 20_000  # values in all (a 64 KB body holds fewer)
MAX_STRING = 10_000  # characters of one string or key


def json_problem(value: Any, where: str = "") -> str | None:
    """Why `value` cannot be stored and served as JSON (naming the place, e.g.
    `plan.criteria.max`), or None when it can: finite numbers, strings without lone surrogates,
    string keys, bounded depth, size and string length; no other types. (Whoever reads a number as
    a float checks its size: rig.plan.ring_plan does.)"""
    budget = [MAX_NODES]
    return _problem(value, where, 0, budget)


def _problem(value: Any, where: str, depth: int, budget: list[int]) -> str | None:
    budget[0] -= 1
    if budget[0] < 0:
        return f"{where or 'the body'}: more than {MAX_NODES} values in all"
    here = where or "the body"
    if value is None or isinstance(value, bool | int):  # any integer: JSON and SQLite's text carry it
        return None
    if isinstance(value, float):
        return None if math.isfinite(value) else f"{here}: {value!r} is not a finite number"
    if isinstance(value, str):
        return _string_problem(value, here)
    if depth >= MAX_DEPTH and isinstance(value, dict | list | tuple):
        return f"{here}: nested more than {MAX_DEPTH} levels deep"
    if isinstance(value, dict):
        for key, item in value.items():
            if not isinstance(key, str):
                return f"{here}: key {key!r} is not a string"
            found = _string_problem(key, f"{here}: key") or _problem(item, _join(where, key), depth + 1, budget)
            if found:
                return found
        return None
    if isinstance(value, list | tuple):
        for index, item in enumerate(value):
            found = _problem(item, f"{where}[{index}]" if where else f"[{index}]", depth + 1, budget)
            if found:
                return found
        return None
    return f"{here}: a {type(value).__name__} is not a JSON value"


def _string_problem(text: str, here: str) -> str | None:
    if len(text) > MAX_STRING:
        return f"{here}: a string of {len(text)} characters (at most {MAX_STRING})"
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        code = ord(text[exc.start])
        return f"{here}: holds a lone surrogate (\\u{code:04x}), which UTF-8 text cannot carry"
    return None


def _join(where: str, key: str) -> str:
    shown = key if key.isidentifier() else repr(key)
    return f"{where}.{shown}" if where else shown
