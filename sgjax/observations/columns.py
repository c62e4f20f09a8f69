"""Column layouts: what each column of an observation holds.

Every observation term publishes its :class:`Columns` (``term.columns(layout)``), and the
Observer the layout of the whole vector (:class:`ObservationColumns`,
``observer.columns(layout)``), so that networks, observation masks and saved policies read
positions and feature names from the layout instead of from the terms' internals::

    columns = env.config.observer.columns(env.config.layout)
    columns.span("others")                # slice(10, 30): the term's columns in obs [..., D]
    columns["others"].shape               # (4, 5): K blocks (bodies) x F features
    columns["others"].offset("mask")      # 4: the mask feature's column inside a block
    columns.indices("others.velocity")    # every body's velocity columns in obs [..., D]
    columns.names[:4]                     # ('pose.x', 'pose.y', 'pose.cos_heading', ...)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import numpy as np


@dataclasses.dataclass(frozen=True)
class Columns:
    """The columns of one observation term: ``repeat`` blocks of the same features, one after
    the other (``size = repeat x width``).

    A block is one neighbour (``others``: ``K`` bodies, nearest first), one step of a history
    (latest first), one lidar beam or one conflict zone; terms without blocks have
    ``repeat = 1``. A feature is a named group of adjacent columns of a block, hidden or read
    as one (``pose``'s ``heading`` is ``cos_heading, sin_heading``).

    ``features``: ``((feature, (column, ...)), ...)`` in column order (column names are unique
    within a block). ``filled``: the most blocks that can hold a value in the environment the
    layout was taken from; the blocks after them are always zero (``None``: every block can).
    """

    features: tuple[tuple[str, tuple[str, ...]], ...]
    repeat: int = 1
    filled: int | None = None

    def __post_init__(self) -> None:
        names = self.block_names
        if len(set(names)) != len(names) or len({f for f, _ in self.features}) != len(
                self.features):
            raise ValueError(f"column and feature names must be unique, got {self.features}")
        if self.repeat < 0:
            raise ValueError(f"repeat must be >= 0, got {self.repeat}")

    @classmethod
    def grouped(cls, features: Mapping[str, Sequence[str]], repeat: int = 1,
                filled: int | None = None) -> Columns:
        """From ``{feature: [column, ...]}`` in order."""
        return cls(tuple((f, tuple(c)) for f, c in features.items()), repeat, filled)

    @classmethod
    def plain(cls, *names: str, repeat: int = 1) -> Columns:
        """Columns that are each a feature of their own name."""
        return cls(tuple((n, (n,)) for n in names), repeat)

    @property
    def block_names(self) -> tuple[str, ...]:
        """The names of one block's ``F`` columns."""
        return tuple(c for _, columns in self.features for c in columns)

    @property
    def width(self) -> int:
        """``F``: columns per block."""
        return len(self.block_names)

    @property
    def shape(self) -> tuple[int, int]:
        """``(repeat, width)``: the term's columns as blocks x features."""
        return self.repeat, self.width

    @property
    def size(self) -> int:
        return self.repeat * self.width

    def __len__(self) -> int:
        return self.size

    @property
    def names(self) -> tuple[str, ...]:
        """All column names in order; ``name[i]`` for block ``i`` when the term has blocks."""
        if self.repeat == 1:
            return self.block_names
        return tuple(f"{n}[{i}]" for i in range(self.repeat) for n in self.block_names)

    @property
    def feature_names(self) -> tuple[str, ...]:
        return tuple(f for f, _ in self.features)

    def feature_slice(self, feature: str) -> slice:
        """The feature's columns inside one block."""
        start = 0
        for name, columns in self.features:
            if name == feature:
                return slice(start, start + len(columns))
            start += len(columns)
        raise ValueError(f"no feature {feature!r}; the features are: "
                         f"{', '.join(self.feature_names) or 'none'}")

    def offset(self, feature: str) -> int:
        """The first column of ``feature`` inside a block."""
        return self.feature_slice(feature).start

    def indices(self, feature: str | None = None) -> np.ndarray:
        """The term's columns (0 .. size - 1) that hold ``feature`` in every block (all
        columns with None), ascending."""
        if feature is None:
            return np.arange(self.size)
        inside = np.arange(self.width)[self.feature_slice(feature)]
        return (np.arange(self.repeat)[:, None] * self.width + inside[None, :]).ravel()


@dataclasses.dataclass(frozen=True)
class ObservationColumns:
    """The layout of a whole observation vector ``[D]``: its terms in order, each with its
    first column and its :class:`Columns`."""

    terms: tuple[tuple[str, int, Columns], ...]  # (term name, start, columns)

    @classmethod
    def of(cls, columns: Sequence[tuple[str, Columns]]) -> ObservationColumns:
        """From ``[(term name, columns)]`` in observation order."""
        out, start = [], 0
        for name, c in columns:
            out.append((name, start, c))
            start += c.size
        return cls(tuple(out))

    @property
    def size(self) -> int:
        """``D``."""
        return sum(c.size for _, _, c in self.terms)

    def __contains__(self, term: object) -> bool:
        return any(name == term for name, _, _ in self.terms)

    def __getitem__(self, term: str) -> Columns:
        return self._find(term)[1]

    def _find(self, term: str) -> tuple[int, Columns]:
        for name, start, columns in self.terms:
            if name == term:
                return start, columns
        raise KeyError(f"no observation term {term!r}; this observation has "
                       f"{[name for name, _, _ in self.terms]}")

    def span(self, term: str) -> slice:
        """The term's columns in the observation vector."""
        start, columns = self._find(term)
        return slice(start, start + columns.size)

    @property
    def slices(self) -> dict[str, slice]:
        """``{term name: slice}`` in order."""
        return {name: slice(start, start + c.size) for name, start, c in self.terms}

    @property
    def names(self) -> tuple[str, ...]:
        """``D`` column names ``term.column`` (``others.dx[0]``: block 0's ``dx``)."""
        return tuple(f"{name}.{column}" for name, _, c in self.terms for column in c.names)

    def indices(self, item: str) -> np.ndarray:
        """Columns of the observation vector holding ``item``: a term (``"velocity"``) or one
        feature of a term in every block (``"others.velocity"``, ``"pose.heading"``). Raises
        ``KeyError`` for an unknown term, ``ValueError`` for an unknown feature."""
        term, _, feature = item.partition(".")
        start, columns = self._find(term)
        try:
            return start + columns.indices(feature or None)
        except ValueError as err:
            raise ValueError(f"{term}: {err}") from None

    def describe(self) -> str:
        """One line per term: ``name [start:stop] size`` and its blocks and features."""
        lines = []
        for name, start, c in self.terms:
            blocks = f" = {c.repeat} x {c.width}" if c.repeat != 1 else ""
            lines.append(f"{name:<24} [{start}:{start + c.size}] size {c.size}{blocks}: "
                         + ", ".join(c.block_names))
        return "\n".join(lines)
