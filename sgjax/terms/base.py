"""What observation terms, reward terms and episode enders share: a name registry, the one
parser of term specs (:func:`parse_terms`) with errors that list valid names, and
:class:`TermSet`, the base of the Observer, Rewarder and Enders that compose terms."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, ClassVar, TypeVar

import jax

from sgjax.terms.contract import Term, TermInput
from sgjax.validation import freeze, suggest

T = TypeVar("T")


class ConfigError(ValueError):
    """A bad observation, reward or ender configuration: names where and what was expected."""


def unknown_name(where: str, kind: str, name: str, valid: list[str]) -> ConfigError:
    return ConfigError(f"{where}: unknown {kind} {name!r}{suggest(name, valid)}; "
                       f"valid {kind}s are: {', '.join(sorted(valid))}")


class Registry:
    """Term classes of one kind by name. A term class is a frozen dataclass whose fields are its
    options, subclassing ``base`` (the kind's base class)."""

    def __init__(self, kind: str, base: type = Term):
        self.kind = kind
        self.base = base
        self.classes: dict[str, type] = {}

    def register(self, cls: type[T]) -> type[T]:
        """Class decorator: add ``cls`` under its ``name``."""
        name = cls.name  # type: ignore[attr-defined]
        if not (isinstance(cls, type) and issubclass(cls, self.base)):
            raise TypeError(f"{self.kind} {name!r}: a {self.kind} subclasses "
                            f"{self.base.__name__}")
        if name in self.classes:
            raise RuntimeError(f"{self.kind} {name!r} registered twice")
        self.classes[name] = cls
        return cls

    def names(self) -> list[str]:
        return sorted(self.classes)

    def build(self, where: str, name: Any, options: Any) -> Any:
        """Instantiate term ``name`` with ``options`` (a dict; None or True: the defaults),
        checking every key."""
        if not isinstance(name, str):
            raise ConfigError(f"{where}: a {self.kind} name must be a string, got {name!r}")
        if name not in self.classes:
            raise unknown_name(where, self.kind, name, self.names())
        cls = self.classes[name]
        return build_dataclass(f"{where}.{name}", cls, {} if options is True else options or {})


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

    @property
    def needs_key(self) -> bool:
        """Whether any term draws random numbers."""
        return any(t.needs_key for t in self.terms)

    def each(self, inputs: TermInput) -> Iterator[tuple[Any, TermInput]]:
        """Each term with its input: ``inputs`` itself, with a key of the term's own (split
        from ``inputs.key`` in term order) when any term draws random numbers."""
        if not self.needs_key:
            yield from ((term, inputs) for term in self.terms)
            return
        keys = jax.random.split(inputs.key, len(self.terms))
        for term, key in zip(self.terms, keys, strict=True):
            yield term, inputs.replace(key=key)


Entry = Callable[[str, Any], tuple[Any, Any]]


def parse_terms(spec: Any, registry: Registry, where: str, *, lists: bool = True,
                entry: Entry | None = None) -> list[tuple[Any, Any]]:
    """The terms of one section (observations, rewards, enders) from a spec written in YAML,
    JSON or Python, in order, as ``[(term, extra)]``.

    ``spec`` is a mapping ``{name: entry}`` or, with ``lists``, also a list whose items are a
    name, a one-key mapping ``{name: entry}`` or a term instance. Without ``entry`` an entry is
    the term's options (a mapping; None or True for the defaults) and ``extra`` is None;
    ``entry(where, value) -> (options, extra)`` reads other entries (the rewards' weights).
    Errors (:class:`ConfigError`) name the place (``observations[2].velocity``) and list the
    valid names, suggesting the nearest."""
    kinds = f"{registry.kind}s"
    if isinstance(spec, Mapping):
        named = list(spec.items())
        items: list[tuple[str, Any, Any]] = (
            [(f"{where}[{i}]", name, value) for i, (name, value) in enumerate(named)] if lists
            else [(where, name, value) for name, value in named])
    elif lists and isinstance(spec, Sequence) and not isinstance(spec, str):
        items = [_list_item(f"{where}[{i}]", item, registry) for i, item in enumerate(spec)]
    else:
        shape = "a list or mapping" if lists else "a mapping {name: settings}"
        raise ConfigError(f"{where}: expected {shape} of {kinds}, got {spec!r}; valid {kinds} "
                          f"are: {', '.join(registry.names())}")
    out = []
    for at, name, value in items:
        if isinstance(value, registry.base):
            out.append((value, None))
            continue
        options, extra = entry(at, value) if entry is not None else (value, None)
        out.append((registry.build(at, name, options), extra))
    return out


def _list_item(where: str, item: Any, registry: Registry) -> tuple[str, Any, Any]:
    """``(where, name, entry)`` of one list item (a term instance is its own entry)."""
    if isinstance(item, registry.base):
        return where, item.name, item
    if isinstance(item, str):
        return where, item, None
    if isinstance(item, Mapping) and len(item) == 1:
        (name, value), = item.items()
        return where, name, value
    raise ConfigError(f"{where}: expected a name or {{name: options}} of one of the "
                      f"{registry.kind}s, got {item!r}")

