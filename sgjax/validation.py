"""One vocabulary for checking options: types, choices, ranges, unknown keys.

Every check takes the field's path (``"num_agents"``, ``"algorithm.gamma"``,
``"env.curriculum[1][0]"``) and the value, and raises ``ValueError`` naming both::

    num_agents must be a positive integer, got 0
    human_model must be one of ('moussaid', 'helbing', 'orca', 'hsfm'), got 'orka' (did you ...)
    algorithm.gamma must be in [0, 1], got 1.5

Callers put where the value came from in front (a file, ``make('doorway')``, a term's
section). The module also holds the one :func:`freeze` / :func:`thaw` pair that turns plain
YAML / JSON data into hashable values (static configuration) and back. It is a leaf: it imports
nothing from ``sgjax``.
"""

from __future__ import annotations

import difflib
import math
import numbers
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

__all__ = [
    "FrozenDict", "check_bool", "check_choice", "check_int", "check_keys", "check_positive",
    "check_range", "check_type", "describe_type", "freeze", "suggest", "thaw",
]


def suggest(name: str, valid: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the closest valid name, or ``""``."""
    close = difflib.get_close_matches(name, list(valid), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def check_keys(path: str, keys: Iterable[Any], valid: Sequence[str], kind: str = "key",
               error: type[Exception] = ValueError) -> None:
    """Raise ``error`` for the first of ``keys`` not in ``valid``: ``"<path>: unknown <kind>
    'x' (did you mean 'y'?); valid <kind>s are: a, b"``."""
    for key in keys:
        if key not in valid:
            raise error(f"{path}: unknown {kind} {key!r}{suggest(str(key), valid)}; valid "
                        f"{kind}s are: {', '.join(valid) or 'none'}")


def check_choice(path: str, value: Any, choices: Sequence[Any]) -> None:
    """``value`` is one of ``choices`` (a near miss of a string choice is named)."""
    if value not in choices:
        strings = [c for c in choices if isinstance(c, str)]
        hint = suggest(value, strings) if isinstance(value, str) else ""
        raise ValueError(f"{path} must be one of {tuple(choices)}, got {value!r}{hint}")


def check_bool(path: str, value: Any) -> None:
    """``value`` is ``True`` or ``False`` (not 0, 1 or a string)."""
    if not isinstance(value, bool):
        raise ValueError(f"{path} must be True or False, got {value!r}")


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_int(path: str, value: Any, low: int = 1) -> None:
    """``value`` is an integer (a Python or NumPy one, not a bool) of at least ``low``."""
    if not _is_int(value) or value < low:
        what = {1: "a positive integer", 0: "a non-negative integer"}.get(
            low, f"an integer >= {low}")
        raise ValueError(f"{path} must be {what}, got {value!r}")


def check_positive(path: str, value: Any, allow_zero: bool = False) -> None:
    """``value`` is a finite number above zero (or at least zero with ``allow_zero``)."""
    if not _is_number(value) or not math.isfinite(value) or (
            value < 0 if allow_zero else value <= 0):
        raise ValueError(f"{path} must be a {'non-negative' if allow_zero else 'positive'} "
                         f"number, got {value!r}")


def check_range(path: str, value: Any, low: float, high: float) -> None:
    """``value`` is a number in ``[low, high]``."""
    if not _is_number(value) or not low <= value <= high:
        raise ValueError(f"{path} must be in [{low:g}, {high:g}], got {value!r}")


def describe_type(hint: Any) -> str:
    """A type annotation in words: ``int | None`` is ``"an integer or null"``."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return " or ".join(describe_type(a) for a in typing.get_args(hint))
    if typing.get_origin(hint) is tuple:
        return "a list"
    names = {type(None): "null", bool: "True or False", int: "an integer", float: "a number",
             str: "a string"}
    return names.get(hint, getattr(hint, "__name__", str(hint)))


def check_type(path: str, value: Any, hint: Any) -> None:
    """``value`` (plain YAML / JSON data) fits the annotation ``hint``: ``bool``, ``int``,
    ``float`` (an int will do), ``str``, ``None``, unions of them and ``tuple[X, ...]`` or
    ``tuple[X, Y]`` (a list); ``Any`` and other annotations pass."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        for option in typing.get_args(hint):
            try:
                check_type(path, value, option)
                return
            except ValueError:
                pass
        raise ValueError(f"{path} must be {describe_type(hint)}, got {value!r}")
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ValueError(f"{path} must be a list, got {value!r}")
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            args = (args[0],) * len(value)
        elif len(value) != len(args):
            raise ValueError(f"{path} must be a list of {len(args)} items, got {value!r}")
        for i, (item, arg) in enumerate(zip(value, args, strict=True)):
            check_type(f"{path}[{i}]", item, arg)
        return
    checks = {type(None): lambda v: v is None, bool: lambda v: isinstance(v, bool),
              int: _is_int, float: _is_number, str: lambda v: isinstance(v, str)}
    check = checks.get(hint)
    if check is not None and not check(value):
        raise ValueError(f"{path} must be {describe_type(hint)}, got {value!r}")


class FrozenDict(dict):
    """A read-only, hashable ``dict`` (a frozen YAML / JSON mapping); equal to the ``dict`` of
    the same items."""

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(frozenset(self.items()))

    def _read_only(self, *args: Any, **kwargs: Any) -> None:
        raise TypeError("a frozen mapping cannot be changed; thaw() it for a mutable copy")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _read_only
    __ior__ = _read_only  # type: ignore[assignment]

    def __reduce__(self) -> tuple:
        return FrozenDict, (dict(self),)

    def __repr__(self) -> str:
        return f"FrozenDict({dict.__repr__(self)})"


def freeze(value: Any) -> Any:
    """Plain data made hashable: lists and tuples become tuples, mappings
    :class:`FrozenDict`, all the way down (other values stay as they are)."""
    if isinstance(value, list | tuple):
        return tuple(freeze(v) for v in value)
    if isinstance(value, Mapping):
        return FrozenDict((k, freeze(v)) for k, v in value.items())
    return value


def thaw(value: Any) -> Any:
    """Frozen (or any) data back in plain YAML / JSON form: tuples and lists become lists,
    mappings ``dict``, all the way down."""
    if isinstance(value, list | tuple):
        return [thaw(v) for v in value]
    if isinstance(value, Mapping):
        return {k: thaw(v) for k, v in value.items()}
    return value
