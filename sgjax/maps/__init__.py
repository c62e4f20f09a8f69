"""Maps: the JSON format, loading and validation, routing, and SocialGym 2.0 import."""

from sgjax.maps.arrays import MapArrays, compile_map
from sgjax.maps.io import load, save, shipped_map_names
from sgjax.maps.schema import MapError, MapSpec, Zone, parse_map
from sgjax.maps.socialgym import import_socialgym

__all__ = [
    "MapArrays",
    "MapError",
    "MapSpec",
    "Zone",
    "compile_map",
    "import_socialgym",
    "load",
    "parse_map",
    "save",
    "shipped_map_names",
]
