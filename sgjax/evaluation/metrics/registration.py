"""The metric registry: :func:`register_metric` (a class decorator, as Waymax's
``register_metric``), :func:`unregister_metric`, and :data:`METRICS`, the catalogue derived
from it.

The catalogue lists every registered metric in registration order (family by family, each
family's metrics in its own order); evaluation outputs, statistics, reports and the tables of
docs/metrics.md are all read from it, so a metric registered from outside sgjax::

    from sgjax.evaluation.metrics import Metric, register_metric, robot_metric

    @register_metric
    class Honks(Metric):
        infos = (robot_metric("honks", "count", "steps stopped next to someone", "mine"),)
        ...

appears in ``run_episodes`` and ``evaluate`` outputs like a built-in one.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TypeVar

from sgjax.evaluation.metrics.base import Metric, MetricInfo

M = TypeVar("M", bound=type[Metric])


class MetricRegistry:
    """Registered metric families, and the catalogue of their metrics (iterating yields every
    :class:`MetricInfo`; ``METRICS[name]`` is one; ``name in METRICS``; ``len(METRICS)``)."""

    def __init__(self) -> None:
        self._families: dict[str, Metric] = {}

    def register(self, family: Metric) -> None:
        """Add an instance of a :class:`Metric` subclass; its family key and metric names must
        be new, and each entry complete (:meth:`MetricInfo.check`)."""
        if not isinstance(family, Metric):
            raise TypeError(f"register_metric: {family!r} is not a Metric")
        if not family.infos:
            raise ValueError(f"register_metric: {family.key} declares no metrics (infos)")
        if family.key in self._families:
            raise ValueError(f"register_metric: a metric family {family.key!r} is already "
                             "registered (unregister_metric it first)")
        names = family.names
        for info in family.infos:
            info.check()
        taken = sorted(set(names) & set(self.names()))
        repeated = sorted({n for n in names if names.count(n) > 1})
        if taken or repeated:
            raise ValueError(f"register_metric: {family.key} repeats metric names "
                             f"{taken + repeated}")
        self._families[family.key] = family

    def unregister(self, key: str) -> Metric:
        """Remove the family ``key`` (its class name) or the family that gives metric ``key``;
        returns it."""
        if key not in self._families:
            owners = [k for k, f in self._families.items() if key in f.names]
            if not owners:
                raise KeyError(f"unregister_metric: no metric or family {key!r}")
            key = owners[0]
        return self._families.pop(key)

    def families(self) -> tuple[Metric, ...]:
        """The registered families, in registration order."""
        return tuple(self._families.values())

    def names(self) -> tuple[str, ...]:
        return tuple(info.name for info in self)

    def family_of(self, name: str) -> Metric:
        """The family that gives metric ``name``."""
        for family in self._families.values():
            if name in family.names:
                return family
        raise KeyError(f"no metric {name!r}; registered: {', '.join(self.names())}")

    def __iter__(self) -> Iterator[MetricInfo]:
        for family in self._families.values():
            yield from family.infos

    def __len__(self) -> int:
        return sum(len(f.infos) for f in self._families.values())

    def __contains__(self, name: object) -> bool:
        return any(name in f.names for f in self._families.values())

    def __getitem__(self, name: str) -> MetricInfo:
        family = self.family_of(name)
        return family.infos[family.names.index(name)]


METRICS = MetricRegistry()


def register_metric(cls: M) -> M:
    """Class decorator: register a :class:`Metric` subclass (instantiated without arguments)
    so that every evaluation computes its metrics. Returns the class."""
    if not (isinstance(cls, type) and issubclass(cls, Metric)):
        raise TypeError(f"register_metric decorates a Metric subclass, got {cls!r}")
    METRICS.register(cls())
    return cls


def unregister_metric(key: str | type[Metric]) -> None:
    """Remove a registered family: by class, class name, or the name of one of its metrics."""
    METRICS.unregister(key.__name__ if isinstance(key, type) else key)
