"""Generated worlds in the environment: a family and its ranges as static configuration
(:class:`WorldSource`), and the world an episode plays in (:class:`WorldDraw`, held in
``EnvState.world``).

Each environment of a batch plays its own world: ``reset`` draws one from its key (the same key,
the same world) and keeps it in the episode's state, and ``step`` reads the map from there, so
a batch of environments is a batch of worlds that stays on the device. The state holds the
world (rather than batched params) because the world changes at every reset, inside the step's
auto-reset, where params are fixed for the whole call.

A source with ``levels`` on lets a trainer pick the world of an environment's next episode (a
curriculum: :class:`Level`, written into ``EnvState.next_level``): every world is then a seed
(its build key, ``world_key(seed)``) and parameter values, so a level kept in a replay buffer,
or one with edited values (an ACCEL mutation), is built again exactly."""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.humans.slots import SpawnSlots, slot_grid_shape, world_spawn_slots
from sgjax.maps.arrays import MapArrays
from sgjax.maps.generated.checks import verdict
from sgjax.maps.generated.compiled import world_arrays
from sgjax.maps.generated.export import world_map
from sgjax.maps.generated.families import family
from sgjax.maps.generated.family import Family, generate, range_arrays, world_values
from sgjax.maps.generated.splits import is_excluded, split_hashes, values_hash, world_key
from sgjax.maps.generated.world import Capacity, World

HOLDOUT_TRIES = 4  # value draws a proposal may take to miss a held-out split's worlds


@struct.dataclass
class WorldDraw:
    """The world one episode plays in: its map arrays, whether it passed every check
    (``valid``: False only when all the reset's proposals failed), the parameter values it
    was built from (``{name: float32}``) and its seed (uint32: the build key is
    ``world_key(seed)``; 0 for a world drawn straight from a reset's key, where there is no
    seed)."""

    map: MapArrays
    valid: Array
    values: dict
    seed: Array
    # the world's pedestrian spawn slots and node mask, when the environment has pedestrians
    humans: SpawnSlots | None = None
    # int32: the pedestrians of the episode in this world, -1 for the params' ``num_humans``
    # (a trainer's level may carry its own: an ACCEL edit adds a group)
    pedestrians: Array = dataclasses.field(default_factory=lambda: jnp.int32(-1))

    def params_of(self, params: Any) -> Any:
        """``params`` (``EnvParams``) with this world as the map, and its spawn slots, node
        mask and pedestrian count in the pedestrian params when it has them
        (:func:`sgjax.types.episode_params`)."""
        params = params.replace(map=self.map)
        if self.humans is None:
            return params
        h = self.humans
        count = jnp.where(self.pedestrians >= 0, self.pedestrians,
                          params.humans.num_humans).astype(jnp.int32)
        return params.replace(humans=params.humans.replace(
            spawn_x=h.x, spawn_y=h.y, spawn_nodes=h.nodes, spawn_valid=h.valid,
            node_valid=h.node_valid, num_humans=count))


@struct.dataclass
class Level:
    """The world a trainer picks for an environment's next episode (``EnvState.next_level``):
    a seed (uint32, the build key ``world_key(seed)``), parameter values (``{name: float32}``,
    which need not be the seed's own: an edited level), ``chosen`` (bool: False lets the
    reset draw a fresh seed, as it does without a curriculum) and ``pedestrians`` (int32: the
    episode's active pedestrians, at most the environment's ``max_humans``; -1 for the
    params' ``num_humans``). Leaves gain a leading ``[N]`` in a batch."""

    seed: Array
    values: dict
    chosen: Array
    pedestrians: Array

    @classmethod
    def unset(cls, parameters: Any) -> Level:
        """No level chosen (the next reset draws a fresh world), for a family with these
        ``parameters`` (names)."""
        return cls(seed=jnp.uint32(0),
                   values={name: jnp.float32(jnp.nan) for name in sorted(parameters)},
                   chosen=jnp.asarray(False), pedestrians=jnp.int32(-1))


@dataclasses.dataclass(frozen=True)
class WorldSource:
    """A family of worlds as an environment draws them: its name, the ranges (``(name, low,
    high)`` rows, checked against the family), its capacity (the planner's reach set by
    ``make``), the widest robot's radius (m; passages must fit it), the proposals per reset,
    and whether a draw checks the family's dilemma too (``sgjax maps generate`` does; a reset
    does not: :func:`sgjax.maps.generated.checks.verdict`)."""

    family_name: str
    ranges: tuple[tuple[str, float, float], ...]
    capacity: Capacity
    robot_radius: float
    proposals: int = 1
    check_dilemma: bool = False
    # (first, count): a reset plays one of the worlds with these seeds (a held-out split);
    # None: a fresh world from the reset's key
    seeds: tuple[int, int] | None = None
    # sorted hashes of worlds a draw must not take (a held-out split's: training refuses them)
    exclude: tuple[int, ...] = ()
    # every world a seed and values, and a reset plays the Level the state holds when one is
    # chosen (a trainer's curriculum); False: worlds straight from the reset's key
    levels: bool = False
    # m: the pedestrians' radius, whose spawn slots every world computes (0: no pedestrians)
    human_radius: float = 0.0

    def slots_of(self, world: World) -> SpawnSlots | None:
        """The world's pedestrian spawn slots (:func:`sgjax.humans.slots.world_spawn_slots` on
        the family's slot lattice), or None without pedestrians."""
        if not self.human_radius:
            return None
        shape = slot_grid_shape(self.capacity.extent, self.human_radius)
        return world_spawn_slots(world.walls, world.wall_valid, world.nodes, world.edges,
                                 world.edge_valid, world.bounds, shape, self.human_radius,
                                 world.node_valid)

    @property
    def family(self) -> Family:
        return family(self.family_name)

    def _range_arrays(self) -> dict[str, Array]:
        return range_arrays({name: (low, high) for name, low, high in self.ranges})

    def _excluded(self) -> Array:
        return jnp.asarray(np.asarray(self.exclude, np.uint32))

    def _checked(self, world: World, values: dict, seed: Array) -> WorldDraw:
        """The draw of a built ``world``: its map arrays, checked (``valid``; a world whose
        values a held-out split holds is not valid), its pedestrian slots."""
        capacity = self.capacity
        arrays, dist, overflow, hops = world_arrays(world, capacity, self.family.routes)
        ok = verdict(world, dist, arrays.next_hop, overflow, self.robot_radius,
                     route_nodes=capacity.route_nodes, check_dilemma=self.check_dilemma,
                     hops=hops).valid
        fresh = ~is_excluded(values_hash(values), self._excluded())
        return WorldDraw(map=arrays, valid=ok & fresh, values=values,
                         seed=jnp.asarray(seed, jnp.uint32), humans=self.slots_of(world))

    def _first_fresh(self, candidates: Array, values_of: Any) -> Array:
        """Of ``candidates [T]`` (keys or seeds), the first whose values (``values_of``) no
        held-out split holds, the first when all are held (its check then flags it): only
        values are drawn, a world is built from the one kept."""
        excluded = self._excluded()
        held = jax.vmap(lambda c: is_excluded(values_hash(values_of(c)), excluded))(candidates)
        return candidates[jnp.argmin(held)]

    def chosen(self, key: Array | None, seed: Array | None = None) -> tuple[World, WorldDraw]:
        """The world of ``key`` and its draw: ``proposals`` candidates (fresh worlds from the
        key, or worlds of the split ``seeds`` the key picks), the first valid one kept (the
        first candidate, flagged invalid, when none is); a world whose hash is in ``exclude``
        is not valid. With ``key`` None, world ``seed`` alone (:meth:`of_seed`)."""
        ranges = self._range_arrays()
        own = lambda s: world_values(world_key(s), ranges)  # noqa: E731 (a seed's values)
        if key is None:  # one world by its seed (of_seed)
            return self.built(seed, own(seed))
        if self.seeds is None:
            keys = jax.random.split(key, self.proposals)
            if self.exclude:  # each proposal skips held-out values before building anything
                keys = jax.vmap(lambda k: self._first_fresh(
                    jax.random.split(k, HOLDOUT_TRIES), lambda c: world_values(c, ranges)))(keys)

            def propose(k: Array) -> tuple[World, WorldDraw]:
                world, values = generate(self.family, k, ranges)
                return world, self._checked(world, values, jnp.uint32(0))

            worlds, draws = jax.vmap(propose)(keys)
        else:  # a split's worlds, by their seeds
            first, count = self.seeds
            index = jax.random.randint(key, (self.proposals,), 0, count)
            seeds = jnp.uint32(first) + index.astype(jnp.uint32)
            worlds, draws = jax.vmap(lambda s: self.built(s, own(s)))(seeds)
        best = jnp.argmax(draws.valid)  # the first valid one, else 0
        return jax.tree.map(lambda x: x[best], (worlds, draws))

    def built(self, seed: Array, values: dict) -> tuple[World, WorldDraw]:
        """The world of seed ``seed`` (uint32) built from ``values`` ({name: float32}, the
        seed's own or edited ones) and its draw, checked (``valid``; a world whose values a
        held-out split holds is not valid)."""
        seed = jnp.asarray(seed, jnp.uint32)
        world = self.family.build(values, jax.random.split(world_key(seed))[1])
        return world, self._checked(world, values, seed)

    def level_draw(self, key: Array, level: Level) -> WorldDraw:
        """The world of a reset under a curriculum: ``level`` when it is chosen, else a fresh
        seed from ``key`` with its own values; of ``proposals`` candidates (the chosen level
        first, then fresh seeds, each redrawn up to :data:`HOLDOUT_TRIES` times away from a
        held-out split's values) the first valid one. With one proposal a chosen level that
        fails the checks is played (flagged invalid: a curriculum never records it); with
        more, the next fresh seed replaces it. The draw's ``pedestrians`` is the chosen
        level's where it is played, else -1 (the params' count)."""
        ranges = self._range_arrays()
        own = lambda s: world_values(world_key(s), ranges)  # noqa: E731 (a seed's values)
        tries = HOLDOUT_TRIES if self.exclude else 1
        seeds = jax.random.bits(key, (self.proposals, tries), jnp.uint32)
        seeds = (jax.vmap(lambda row: self._first_fresh(row, own))(seeds) if self.exclude
                 else seeds[:, 0])
        # a chosen level is proposal 0, fresh seeds the others: the fallback when it fails
        chosen = (jnp.arange(self.proposals) == 0) & level.chosen
        seeds = jnp.where(chosen, level.seed, seeds)
        values = {name: jnp.where(chosen, level.values[name], v)
                  for name, v in jax.vmap(own)(seeds).items()}
        _, draws = jax.vmap(self.built)(seeds, values)
        best = jnp.argmax(draws.valid)
        draw = jax.tree.map(lambda x: x[best], draws)
        return draw.replace(pedestrians=jnp.where(chosen[best], level.pedestrians,
                                                  -1).astype(jnp.int32))

    def of_seed(self, seed: Array | int) -> WorldDraw:
        """World ``seed`` (built from ``world_key(seed)``, as a split of seeds plays it) under
        these ranges, checked (``valid``) but never replaced by another proposal."""
        return self.chosen(None, jnp.asarray(seed, jnp.uint32))[1]

    def draw(self, key: Array) -> WorldDraw:
        """The draw of :meth:`chosen` (what ``reset`` keeps in the state)."""
        return self.chosen(key)[1]


def source_for(family_name: str, ranges: dict | None = None, robot_radius: float = 0.25,
               proposals: int = 1, reach: float | None = None, check_dilemma: bool = True,
               seeds: tuple[int, int] | None = None, holdout: tuple[int, int] | None = None,
               levels: bool = False, human_radius: float = 0.0) -> WorldSource:
    """A :class:`WorldSource` of a family by name, with ``ranges`` ({name: (low, high)}) on its
    defaults (checked), for robots up to ``robot_radius`` m (``reach``: the planner's, default
    the family capacity's), checking the dilemma too by default (for files). ``seeds``: play
    the worlds of this split ``(first, count)``; ``holdout``: never draw a world of that split
    (its worlds' hashes excluded, under the same ranges: each proposal redraws held-out values
    before building). ``levels``: a trainer may pick each episode's world
    (:meth:`WorldSource.level_draw`). ``human_radius``: every world computes spawn slots for
    pedestrians of this radius (m; 0: none)."""
    fam = family(family_name)
    checked = fam.ranges(ranges)
    capacity = fam.capacity if reach is None else dataclasses.replace(fam.capacity,
                                                                      reach=float(reach))
    exclude = () if holdout is None else tuple(
        int(h) for h in split_hashes(fam, checked, *holdout))
    return WorldSource(fam.name, tuple((k, lo, hi) for k, (lo, hi) in sorted(checked.items())),
                       capacity, float(robot_radius), int(proposals), bool(check_dilemma),
                       None if seeds is None else (int(seeds[0]), int(seeds[1])), exclude,
                       bool(levels), float(human_radius))


def sample_maps(source: WorldSource, count: int, seed: int) -> list[tuple[dict, bool]]:
    """``count`` worlds of ``source`` from ``seed`` (world ``i`` from the ``i``-th key of
    ``jax.random.split(key(seed), count)``, so the same seed and count give the same files),
    each as ``(map-file dict, valid)``."""
    keys = jax.random.split(jax.random.key(seed), count)
    worlds, draws = jax.jit(jax.vmap(source.chosen))(keys)
    out = []
    for i in range(count):
        world = jax.tree.map(lambda x, i=i: x[i], worlds)
        values = {k: v[i] for k, v in draws.values.items()}
        name = f"{source.family_name}-{seed}-{i:04d}"
        out.append((world_map(world, name, source.family.description, values),
                    bool(draws.valid[i])))
    return out
