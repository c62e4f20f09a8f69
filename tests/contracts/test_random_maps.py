"""The step on maps nobody drew: hypothesis generates rooms with random inner walls, a
navigation grid kept clear of them, random robot teams within their presets' limits and random
actions, and over at least 100,000 robot-steps per map nothing becomes non-finite and no robot
ends a step inside a wall."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import sgjax
from sgjax.kernels.geometry import point_segment_distance
from sgjax.maps import MapError, parse_map
from sgjax.maps.schema import point_segment_distances

PRESETS = ["socialgym", "jackal", "turtlebot3", "cobot", "automata"]
NUM_ENVS, STEPS, HOLD = 64, 400, 8  # 64 x 4 robots x 400 = 102,400 robot-steps per map
SPACING, CLEAR = 1.5, 0.6  # m: grid of nodes, and their distance from every wall


def _crosses(a: np.ndarray, b: np.ndarray, walls: np.ndarray) -> bool:
    """Whether the segment ``a``-``b`` passes within CLEAR / 2 of a wall (sampled)."""
    points = a + np.linspace(0.0, 1.0, 16)[:, None] * (b - a)
    return bool(np.min(point_segment_distances(points, walls)) < CLEAR / 2)


@st.composite
def rooms(draw) -> dict:
    """A rectangular room with up to four inner walls (each leaving a gap), a grid of nodes
    clear of the walls joined to its neighbours where no wall is in the way, and one group
    whose starts and goals are the largest connected part of the grid."""
    width = draw(st.floats(6.0, 14.0))
    height = draw(st.floats(6.0, 12.0))
    walls = [[0, 0, width, 0], [width, 0, width, height], [width, height, 0, height],
             [0, height, 0, 0]]
    for _ in range(draw(st.integers(0, 4))):
        if draw(st.booleans()):
            x = draw(st.floats(1.5, width - 1.5))
            y0, y1 = sorted(draw(st.tuples(st.floats(0.0, height), st.floats(0.0, height))))
            walls.append([x, y0, x, max(y1, y0 + 0.5)])
        else:
            y = draw(st.floats(1.5, height - 1.5))
            x0, x1 = sorted(draw(st.tuples(st.floats(0.0, width), st.floats(0.0, width))))
            walls.append([x0, y, max(x1, x0 + 0.5), y])
    segments = np.asarray(walls, float)
    grid = {}
    for i, x in enumerate(np.arange(SPACING / 2, width - 0.3, SPACING)):
        for j, y in enumerate(np.arange(SPACING / 2, height - 0.3, SPACING)):
            point = np.array([[x, y]])
            if np.min(point_segment_distances(point, segments)) >= CLEAR:
                grid[(i, j)] = point[0]
    edges = [(a, b) for a in grid for b in ((a[0] + 1, a[1]), (a[0], a[1] + 1))
             if b in grid and not _crosses(grid[a], grid[b], segments)]
    parts, seen = [], set()
    for start in grid:  # connected parts of the grid
        if start in seen:
            continue
        part, todo = [], [start]
        seen.add(start)
        while todo:
            node = todo.pop()
            part.append(node)
            for a, b in edges:
                other = b if a == node else a if b == node else None
                if other is not None and other not in seen:
                    seen.add(other)
                    todo.append(other)
        parts.append(part)
    part = max(parts, key=len, default=[])
    ids = {node: k for k, node in enumerate(part)}
    return {"name": "random_room", "description": "a generated room",
            "bounds": [-1, -1, width + 1, height + 1], "walls": walls,
            "nodes": [{"id": ids[n], "position": grid[n].tolist()} for n in part],
            "edges": [[ids[a], ids[b]] for a, b in edges if a in ids and b in ids],
            "groups": [{"starts": list(ids.values()), "goals": list(ids.values())}]}


@pytest.mark.slow
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                HealthCheck.filter_too_much])
@given(room=rooms(), team=st.lists(st.sampled_from(PRESETS), min_size=4, max_size=4),
       seed=st.integers(0, 2**16))
def test_random_maps_robots_and_actions_keep_every_body_out_of_walls(room, team, seed):
    assume(len(room["nodes"]) >= 8)  # room for four distinct starts and goals
    try:
        spec = parse_map(room, "random room", clearance=0.35)
    except MapError as err:  # the generator keeps clear of what the loader checks
        pytest.fail(f"generated map rejected: {err}")
    env, params = sgjax.make(spec, num_agents=4, action_mode="continuous", robots=team,
                             time_limit=20.0)
    m, rp = params.map, params.robots
    step = jax.vmap(env.step, in_axes=(0, 0, 0, None))

    def one(state, inputs):
        t, key = inputs
        held = jax.random.fold_in(jax.random.key(seed), t // HOLD)
        actions = jax.random.uniform(held, (NUM_ENVS, 4, env.config.action_dim), minval=-1.0)
        _, state, _, _, _, info = step(jax.random.split(key, NUM_ENVS), state, actions, params)
        after = info["final_robots"]
        finite = jnp.all(jnp.isfinite(jnp.stack([after.x, after.y, after.kin.v_forward,
                                                  after.kin.omega])))
        d = point_segment_distance(after.x[..., None], after.y[..., None], m.wall_x1,
                                   m.wall_y1, m.wall_x2, m.wall_y2)
        d = jnp.min(jnp.where(m.wall_valid, d, jnp.inf), axis=-1)
        inside = jnp.max(jnp.where(after.present, rp.radius - d, -1.0))
        return state, (finite, inside)

    @jax.jit
    def run(key):
        _, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key, NUM_ENVS),
                                                          params)
        _, out = jax.lax.scan(one, state, (jnp.arange(STEPS), jax.random.split(key, STEPS)))
        return out

    finite, inside = jax.device_get(run(jax.random.key(seed)))
    assert finite.all(), "a non-finite robot state"
    assert inside.max() <= 1e-4, f"a robot {inside.max():.4f} m inside a wall"
