"""Reading traced programs in tests: every equation of a jaxpr, and where it was traced."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from jax._src import source_info_util


def equations(jaxpr: Any) -> Iterator[Any]:
    """Every equation of ``jaxpr`` and of the jaxprs inside it (scan, while, cond, pjit,
    custom rules...), depth first."""
    for eqn in jaxpr.eqns:
        yield eqn
        for param in eqn.params.values():
            for sub in param if isinstance(param, (list, tuple)) else [param]:
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    yield from equations(inner)


def traced_in(eqn: Any) -> tuple[str, str] | None:
    """``(file, function)`` of the user code that traced ``eqn`` (None for JAX's own)."""
    frame = source_info_util.user_frame(eqn.source_info.traceback)
    return None if frame is None else (frame.file_name, frame.function_name)
