"""Values a user wrote by hand (JSON or TOML), checked against a config field's type hint.

One definition for every hand-editable file that maps onto a dataclass: an evolve run's
``config.json`` (:func:`pac_host.robot.evolve.load_config`) and a sweep's settings
(:mod:`pac_host.experiments.sweep.settings`). Neither format tells a bool from an integer the way
Python
does, so a bool is never a number here; an integer is a float; ``null`` fits only a field whose
type allows ``None``; a tuple field takes a list (or, for strings, a comma-separated string)
and comes back as a JSON-friendly list.

>>> coerce(3, float, "explore")
3.0
>>> coerce("a, b", tuple[str, ...], "effects")
['a', 'b']
>>> coerce(None, int | None, "model_generations") is None
True
>>> coerce(True, int, "interval")
Traceback (most recent call last):
...
pac_host.errors.InputError: interval must be an integer, got True
"""

from __future__ import annotations

import types
import typing
from typing import Any

from pac_host.errors import InputError

_WORDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string",
          dict: "an object", list: "a list", type(None): "null"}


def describe(hint: Any) -> str:
    """What a value of type ``hint`` looks like, in words a user reads in an error."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        return " or ".join(describe(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {_plural(describe(args[0]))}"
        return f"a list of {len(args)} ({', '.join(describe(a) for a in args)})"
    return _WORDS.get(hint) or getattr(hint, "__name__", None) or str(hint)


def _plural(words: str) -> str:
    return {"an integer": "integers", "a number": "numbers", "a string": "strings"}.get(
        words, words)


def coerce(value: Any, hint: Any, what: str) -> Any:
    """``value`` as the type ``hint`` wants, or an :class:`InputError` naming ``what``."""
    try:
        return _coerce(value, hint)
    except _Mismatch:
        raise InputError(f"{what} must be {describe(hint)}, got {value!r}") from None


class _Mismatch(Exception):
    pass


def _coerce(value: Any, hint: Any) -> Any:
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (types.UnionType, typing.Union):
        for a in args:
            try:
                return _coerce(value, a)
            except _Mismatch:
                pass
        raise _Mismatch
    if origin is tuple:
        if isinstance(value, str) and args and args[0] is str:
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, list | tuple):
            raise _Mismatch
        if len(args) == 2 and args[1] is Ellipsis:
            return [_coerce(v, args[0]) for v in value]
        if args and len(args) != len(value):
            raise _Mismatch
        return [_coerce(v, a) for v, a in zip(value, args or [Any] * len(value), strict=True)]
    if hint is Any:
        return value
    if hint is type(None):
        ok = value is None
    elif hint in (int, float):
        ok = isinstance(value, int if hint is int else int | float) and not isinstance(value,
                                                                                       bool)
    elif isinstance(hint, type):
        ok = isinstance(value, hint)
    else:  # a hint this module does not know: never guess that a value fits it
        raise TypeError(f"no check for values of type {hint!r}")
    if not ok:
        raise _Mismatch
    return float(value) if hint is float else value
