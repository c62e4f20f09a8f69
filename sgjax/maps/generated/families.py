"""The registered world families, by name (``sgjax.make("generated:<name>")``, ``sgjax maps
generate --family <name>``)."""

from __future__ import annotations

from sgjax.maps.generated.doorway import DOORWAY
from sgjax.maps.generated.family import Family
from sgjax.maps.generated.floorplan import FLOORPLAN
from sgjax.maps.generated.hallway import HALLWAY
from sgjax.maps.generated.intersection import INTERSECTION
from sgjax.maps.generated.open_space import OPEN
from sgjax.maps.generated.roundabout import ROUNDABOUT
from sgjax.validation import suggest

FAMILIES: dict[str, Family] = {f.name: f for f in (DOORWAY, HALLWAY, INTERSECTION, ROUNDABOUT,
                                                  OPEN, FLOORPLAN)}
PREFIX = "generated:"  # a scenario name that names a family


def family(name: str) -> Family:
    """The family called ``name`` (with or without :data:`PREFIX`); a ValueError lists them."""
    bare = name[len(PREFIX):] if name.startswith(PREFIX) else name
    if bare not in FAMILIES:
        raise ValueError(f"no world family {bare!r}{suggest(bare, list(FAMILIES))}; the "
                         f"families are {', '.join(FAMILIES)}")
    return FAMILIES[bare]
