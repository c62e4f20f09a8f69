"""The intersection family: two to four corridors (arms) meeting at a junction, an L, a T or an
X, each arm with its own width, length and angle; robots start at the end of one arm and go to
the end of another, so flows cross or meet in the junction (SocialGym 2.0's intersection is a
plus of two 16 m corridors 4 m wide).

The walls are each arm's two sides, from where they meet the neighbouring arm's side (the
intersection of the two side lines) to the arm's end, and the end. Where two neighbouring arms
are nearly opposite (a T's flat side), their side lines meet far away or never: a short wall
joins the two sides beside the junction instead."""

from __future__ import annotations

from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.maps.generated.family import Family, Parameter
from sgjax.maps.generated.world import Capacity, World, padded_walls

ARMS = 4
ALONG, ACROSS = 4, 2  # spawn lattice of an arm's end, in the arm's frame
SPAWNS = ALONG * ACROSS
NODES = 1 + ARMS + ARMS * SPAWNS  # the junction's centre, each arm's approach node, spawns
EDGES = ARMS + ARMS * SPAWNS
WALLS = 4 * ARMS + 1  # per arm two sides and its end, per gap a joining wall; padding
STRAIGHT = np.deg2rad(25.0)  # neighbours within this of opposite are joined by a short wall
MARGIN = 0.5  # m: spawns keep this far from an arm's walls
SPAWN_DEPTH = 3.0  # m: the spawn lattice fills this much of each arm's end

PARAMETERS = {
    "arms": Parameter((2.0, 4.999), (2.0, 4.999), "", "the arms (the integer part: an L, a T, "
                      "an X)"),
    "arm_width": Parameter((2.0, 4.0), (1.6, 5.0), "m", "each arm's width (drawn per arm)"),
    "arm_length": Parameter((6.0, 9.0), (5.0, 10.0), "m", "each arm's length from the centre "
                            "(drawn per arm)"),
    "angle_jitter": Parameter((0.0, 10.0), (0.0, 20.0), "deg", "how far each arm may turn from "
                              "its right angle"),
    "rotation": Parameter((0.0, 360.0), (0.0, 360.0), "deg", "the whole junction's turn"),
}
CAPACITY = Capacity(walls=WALLS, nodes=NODES, edges=EDGES, hubs=1 + ARMS, groups=ARMS, zones=1,
                    route_nodes=5, extent=(-13.5, -13.5, 13.5, 13.5), cell_walls=WALLS - 1)


def _meet(p: Array, d: Array, q: Array, e: Array) -> tuple[Array, Array]:
    """Where lines ``p + t d`` and ``q + u e`` meet: ``(t, parallel)`` (``t`` 0 where they are
    parallel)."""
    det = d[0] * (-e[1]) - d[1] * (-e[0])
    r = q - p
    t = (r[0] * (-e[1]) - r[1] * (-e[0])) / jnp.where(jnp.abs(det) < 1e-9, 1.0, det)
    return jnp.where(jnp.abs(det) < 1e-9, 0.0, t), jnp.abs(det) < 1e-9


@struct.dataclass
class Arms:
    """The arms of a junction: ``present [A]``, unit vectors ``d [A, 2]`` along each arm and
    ``n [A, 2]`` to its left, half widths and lengths ``[A]`` (m), each arm's next present arm
    counter-clockwise ``nxt [A]`` and whether that neighbour is nearly opposite (``straight``),
    and where each arm's left and right sides begin (``t_left``, ``t_right [A]``, m along it)."""

    count: Array
    present: Array
    d: Array
    n: Array
    half: Array
    length: Array
    nxt: Array
    straight: Array
    t_left: Array
    t_right: Array


def draw_arms(values: Mapping[str, Array], key: Array) -> Arms:
    """The arms of the parameter ``values``: an L is arms 0 and 1, a T arms 0, 1 and 2 (0 and 2
    opposite), an X all four; each arm's width and length the drawn value spread by 10%, its
    angle a right angle turned by up to ``angle_jitter`` (``key`` draws them)."""
    count = jnp.floor(values["arms"]).astype(jnp.int32)
    k_width, k_length, k_angle = jax.random.split(key, 3)
    base = jnp.deg2rad(jnp.asarray([0.0, 90.0, 180.0, 270.0]))
    turn = jax.random.uniform(k_angle, (ARMS,), jnp.float32, -1.0, 1.0)
    theta = base + jnp.deg2rad(values["rotation"] + turn * values["angle_jitter"])
    present = jnp.arange(ARMS) < count
    half = values["arm_width"] / 2 * jax.random.uniform(k_width, (ARMS,), jnp.float32, 0.9, 1.1)
    length = values["arm_length"] * jax.random.uniform(k_length, (ARMS,), jnp.float32, 0.9,
                                                       1.1)
    d = jnp.stack([jnp.cos(theta), jnp.sin(theta)], -1)
    n = jnp.stack([-d[:, 1], d[:, 0]], -1)
    nxt = jnp.asarray([(k + 1) % ARMS for k in range(ARMS)])
    nxt = jnp.where(present[nxt], nxt, 0)  # the last present arm's next is arm 0
    straight = jnp.abs(jnp.mod(theta[nxt] - theta, 2 * np.pi) - np.pi) <= STRAIGHT

    def corner(k: Array) -> tuple[Array, Array]:
        """Where arm k's left side meets its next arm's right side: (t on k, u on next)."""
        j = nxt[k]
        t, parallel = _meet(half[k] * n[k], d[k], -half[j] * n[j], d[j])
        u, _ = _meet(-half[j] * n[j], d[j], half[k] * n[k], d[k])
        flat = straight[k] | parallel
        return jnp.where(flat, 0.0, t), jnp.where(flat, 0.0, u)

    t_left, u_next = jax.vmap(corner)(jnp.arange(ARMS))
    prev = jnp.asarray([(k - 1) % ARMS for k in range(ARMS)])
    prev = jnp.where(present[prev], prev, count - 1)
    return Arms(count=count, present=present, d=d, n=n, half=half, length=length, nxt=nxt,
                straight=straight, t_left=t_left, t_right=u_next[prev])


def arm_walls(arms: Arms) -> tuple[Array, Array]:
    """``(walls [4 A, 4], valid [4 A])``: each arm's right and left sides and end, and the
    short walls joining nearly opposite neighbours."""
    a = arms
    left_start = a.half[:, None] * a.n + a.t_left[:, None] * a.d
    right_start = -a.half[:, None] * a.n + a.t_right[:, None] * a.d
    left_end = a.half[:, None] * a.n + a.length[:, None] * a.d
    right_end = -a.half[:, None] * a.n + a.length[:, None] * a.d
    joins = jnp.concatenate([left_start, right_start[a.nxt]], -1)
    walls = jnp.concatenate([jnp.concatenate([right_start, right_end], -1),
                             jnp.concatenate([left_start, left_end], -1),
                             jnp.concatenate([right_end, left_end], -1), joins])
    joined = a.straight & a.present & (
        jnp.linalg.norm(joins[:, :2] - joins[:, 2:], axis=-1) > 1e-4)
    return walls, jnp.concatenate([a.present, a.present, a.present, joined])


def arm_spawns(arms: Arms, key: Array, reach: Array) -> tuple[Array, Array]:
    """``(spawns [A, S, 2], room)``: each arm's spawn lattice at its end, past ``reach [A]`` (m
    along it), and whether every present arm has room for one (>= 0.4 m of it)."""
    a = arms
    start = jnp.maximum(a.length - SPAWN_DEPTH, reach + 0.6)
    keys = jax.random.split(key, ARMS)
    iy, ix = np.meshgrid(np.arange(ACROSS), np.arange(ALONG), indexing="ij")

    def spawns(k: Array) -> Array:
        jitter = jax.random.uniform(keys[k], (SPAWNS, 2), jnp.float32, -0.3, 0.3)
        along = start[k] + (ix.ravel() + 0.5 + jitter[:, 0]) / ALONG * (
            a.length[k] - MARGIN - start[k])
        across = (-a.half[k] + MARGIN + (iy.ravel() + 0.5 + jitter[:, 1]) / ACROSS
                  * (2 * a.half[k] - 2 * MARGIN))
        return along[:, None] * a.d[k] + across[:, None] * a.n[k]

    room = jnp.all(~a.present | (a.length - MARGIN - start >= 0.4))
    return jax.vmap(spawns)(jnp.arange(ARMS)), room


def arm_groups(arms: Arms, hubs: int = 1 + ARMS) -> tuple[Array, Array, Array]:
    """``(arm_of [N], group_starts [A, N], group_goals [A, N])`` over a junction's node layout
    (``hubs`` hub nodes first, then each arm's spawns): each arm's spawns go to every other
    arm's."""
    arm_of = jnp.concatenate([jnp.full(hubs, -1), jnp.repeat(jnp.arange(ARMS), SPAWNS)])
    mine = arm_of[None, :] == jnp.arange(ARMS)[:, None]
    spawned = arm_of[None, :] >= 0
    return (arm_of, mine & arms.present[:, None],
            spawned & ~mine & arms.present[:, None])


def build(values: Mapping[str, Array], key: Array) -> World:
    """An intersection world of the parameter ``values``; ``key`` draws each arm's width,
    length and turn within the ranges' spread and jitters the spawn lattices."""
    k_arms, k_spawn = jax.random.split(key)
    arms = draw_arms(values, k_arms)
    sides, built = arm_walls(arms)
    walls, valid = padded_walls(sides, CAPACITY.walls, built)
    # approach nodes on each arm's centre line, past both its corners
    reach = jnp.maximum(jnp.maximum(arms.t_left, arms.t_right),
                        jnp.max(arms.half * arms.present)) + 1.0
    spawn, room = arm_spawns(arms, k_spawn, reach)
    nodes = jnp.concatenate([jnp.zeros((1, 2)), reach[:, None] * arms.d, spawn.reshape(-1, 2)])
    arm_of, starts, goals = arm_groups(arms)
    node_valid = jnp.concatenate([jnp.ones(1, bool), arms.present,
                                  jnp.repeat(arms.present, SPAWNS)])
    spawn_rows = 1 + ARMS + jnp.arange(ARMS * SPAWNS)
    pairs = jnp.concatenate([
        jnp.stack([jnp.zeros(ARMS, jnp.int32), 1 + jnp.arange(ARMS, dtype=jnp.int32)], 1),
        jnp.stack([1 + arm_of[spawn_rows].astype(jnp.int32), spawn_rows.astype(jnp.int32)], 1)])
    r = jnp.max(arms.half * arms.present) + 0.5
    return World(
        walls=walls, wall_valid=valid, nodes=nodes, node_valid=node_valid, edges=pairs,
        edge_valid=node_valid[pairs[:, 0]] & node_valid[pairs[:, 1]], group_starts=starts,
        group_goals=goals, zones=jnp.stack([-r, -r, r, r])[None],
        zone_width=(2 * jnp.min(jnp.where(arms.present, arms.half, jnp.inf)))[None],
        zone_valid=jnp.ones(1, bool),
        bounds=jnp.asarray([-13.5, -13.5, 13.5, 13.5]), made=room, dilemma=jnp.asarray(True))


INTERSECTION = Family("intersection", "two to four corridors meeting at a junction (L, T, X); "
                      "robots go from one arm's end to another's", PARAMETERS, CAPACITY, build)
