"""Shared pieces of the readers' property-based tests: any JSON value, every place in a JSON
tree, and a tree with one place replaced."""

from __future__ import annotations

import copy
from collections.abc import Iterator
from typing import Any

from hypothesis import strategies as st

JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**6, 10**6)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner,
                                                                max_size=3),
    max_leaves=6)


def places(value: Any, path: tuple = (), items: int | None = None) -> Iterator[tuple]:
    """Every ``(path, value)`` in a JSON tree, the root first (``items``: only the first that
    many items of each list)."""
    yield path, value
    if isinstance(value, dict):
        for key, item in value.items():
            yield from places(item, (*path, key), items)
    elif isinstance(value, list):
        for i, item in enumerate(value[:items]):
            yield from places(item, (*path, i), items)


def replaced(tree: Any, path: tuple, new: Any) -> Any:
    """A copy of ``tree`` with the value at ``path`` replaced by ``new`` (``()``: the root)."""
    if not path:
        return new
    tree = copy.deepcopy(tree)
    target = tree
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = new
    return tree
