"""Worlds made inside ``jit``: generators of social mini-games, each world drawn from ranges of
parameters into static capacities with masks, compiled to the same
:class:`~sgjax.maps.arrays.MapArrays` as a loaded map (``docs/generated.md``)."""
