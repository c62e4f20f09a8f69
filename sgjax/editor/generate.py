"""The editor's "Generate" panel: a world of a generated family drawn by its seed and parameter
ranges (``POST /api/generate``), as a map file the editor then edits and saves.

World ``seed`` is the one ``sgjax maps generate``, the held-out splits and ``sgjax generalise``
name: built from ``world_key(seed)`` with its values drawn from the given ranges (a range with
``low == high`` fixes the value). Each (family, ranges, robot radius) compiles its generator
once (a few seconds; the floor plan's longest), then a world takes milliseconds."""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

from sgjax.editor.session import EditorError
from sgjax.environment.options import WorldOptions
from sgjax.maps.generated.families import FAMILIES, family

SEEDS = 2**32  # world seeds are uint32
ROBOT_RADIUS = 0.25  # m: the passages a drawn world is checked against (sgjax maps generate's)


def families() -> list[dict[str, Any]]:
    """Every family with its parameters (default range, hard limits, unit, meaning), in the
    form the panel fills its fields from."""
    out = []
    for name in FAMILIES:
        fam = family(name)
        out.append({"name": fam.name, "description": fam.description, "parameters": {
            key: {"default": list(p.default), "limits": list(p.limits), "unit": p.unit,
                  "doc": p.doc} for key, p in fam.parameters.items()}})
    return out


def _ranges(name: str, value: Any) -> dict[str, tuple[float, float]]:
    """The request's ``ranges`` ({parameter: [low, high] or a number}) read as ``make``'s
    ``world_ranges`` and checked by the family: a 422 naming the parameter otherwise."""
    try:
        return family(name).ranges(WorldOptions(world_ranges=value or {}).ranges())
    except ValueError as err:
        raise EditorError(422, f"generate: ranges: {err}") from None


@functools.lru_cache(maxsize=16)
def _generator(name: str, ranges: tuple[tuple[str, float, float], ...]) -> Any:
    """The compiled ``seed -> (world, draw)`` of a family under these ranges (the dilemma
    checked too, as for files)."""
    import jax

    from sgjax.environment.worlds import source_for

    source = source_for(name, {k: (lo, hi) for k, lo, hi in ranges}, ROBOT_RADIUS)
    return source, jax.jit(lambda seed: source.chosen(None, seed))


def generate(body: Mapping[str, Any]) -> dict[str, Any]:
    """``{"family": F, "seed": N, "ranges": {...}}`` -> ``{"map": map file, "valid": bool,
    "values": {parameter: value}, "seed": N}``; a bad family, seed or range is a 422 naming
    it."""
    import jax.numpy as jnp

    from sgjax.maps.generated.export import world_map

    name = body.get("family")
    if name not in FAMILIES:
        raise EditorError(422, f"generate: 'family' must be one of {list(FAMILIES)}, got "
                               f"{name!r}")
    seed = body.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < SEEDS:
        raise EditorError(422, f"generate: 'seed' must be an integer in [0, 2**32), got "
                               f"{seed!r}")
    ranges = _ranges(name, body.get("ranges"))
    source, build = _generator(name, tuple((k, lo, hi) for k, (lo, hi) in sorted(ranges.items())))
    world, draw = build(jnp.uint32(seed))
    values = {k: float(v) for k, v in draw.values.items()}
    data = world_map(world, f"{name}-{seed}", source.family.description, draw.values)
    return {"map": data, "valid": bool(draw.valid), "values": values, "seed": seed}
