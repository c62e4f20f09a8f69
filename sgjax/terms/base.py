"""What observation terms, reward terms and episode enders share: a name registry and the
parsing of their options from plain dicts (YAML or JSON), with errors that list valid names."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar, TypeVar

from sgjax.validation import freeze, suggest

T = TypeVar("T")


class ConfigError(ValueError):
    """A bad observation, reward or ender configuration: names where and what was expected."""


def unknown_name(where: str, kind: str, name: str, valid: list[str]) -> ConfigError:
    return ConfigError(f"{where}: unknown {kind} {name!r}{suggest(name, valid)}; "
                       f"valid {kind}s are: {', '.join(sorted(valid))}")


class Registry:
    """Term classes by name. A term class is a frozen dataclass whose fields are its options."""

    def __init__(self, kind: str):
        self.kind = kind
        self.classes: dict[str, type] = {}

    def register(self, cls: type[T]) -> type[T]:
        name = cls.name  # type: ignore[attr-defined]
        if name in self.classes:
            raise RuntimeError(f"{self.kind} {name!r} registered twice")
        self.classes[name] = cls
        return cls

    def names(self) -> list[str]:
        return sorted(self.classes)

    def build(self, where: str, name: Any, options: Any) -> Any:
        """Instantiate term ``name`` with ``options`` (a dict or None), checking every key."""
        if not isinstance(name, str):
            raise ConfigError(f"{where}: a {self.kind} name must be a string, got {name!r}")
        if name not in self.classes:
            raise unknown_name(where, self.kind, name, self.names())
        cls = self.classes[name]
        return build_dataclass(f"{where}.{name}", cls, options or {})


def option_names(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls) if f.init]


def build_dataclass(where: str, cls: type[T], options: Any) -> T:
    """``cls(**options)`` with an error naming ``where`` for unknown keys or bad values."""
    if not isinstance(options, Mapping):
        raise ConfigError(f"{where}: options must be a mapping of "
                          f"{', '.join(option_names(cls)) or 'nothing'}, got {options!r}")
    valid = option_names(cls)
    for key in options:
        if key not in valid:
            raise ConfigError(f"{where}: unknown option {key!r}{suggest(str(key), valid)}; "
                              f"valid options are: {', '.join(valid) or 'none'}")
    try:
        # frozen (lists to tuples): terms stay hashable, as static jit arguments
        return cls(**{k: freeze(v) for k, v in options.items()})
    except (TypeError, ValueError) as err:
        raise ConfigError(f"{where}: {err}") from None


def check_unique(section: str, names: list[str]) -> None:
    """Raise if a term name appears more than once in a section."""
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"{section}: each term may appear once; repeated: {repeated}")


@dataclasses.dataclass(frozen=True)
class TermSet:
    """An ordered tuple of terms with distinct names (base of Observer, Rewarder, Enders)."""

    terms: tuple
    section: ClassVar[str] = ""

    def __post_init__(self) -> None:
        check_unique(self.section, list(self.names))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)
