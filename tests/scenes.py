"""Hand-built scenes for the term tests: a walled 10 m x 10 m room and a way to put robots
and pedestrians exactly where a test wants them."""

import jax
import jax.numpy as jnp

import sgjax
from sgjax.kernels.zone_books import start_zones
from sgjax.maps import parse_map
from sgjax.types import History

ROOM = {
    "name": "room",
    "description": "10 m square room, four nodes on a ring, a 2 m zone in the middle",
    "bounds": [-5.0, -5.0, 5.0, 5.0],
    "walls": [[-5, -5, 5, -5], [5, -5, 5, 5], [5, 5, -5, 5], [-5, 5, -5, -5]],
    "nodes": [{"id": 0, "position": [-4.0, 0.0]}, {"id": 1, "position": [4.0, 0.0]},
              {"id": 2, "position": [0.0, 4.0]}, {"id": 3, "position": [0.0, -4.0]},
              {"id": 4, "position": [0.0, 0.0]}, {"id": 5, "position": [-4.0, 2.0]},
              {"id": 6, "position": [4.0, 2.0]}, {"id": 7, "position": [-4.0, -2.0]},
              {"id": 8, "position": [4.0, -2.0]}],
    "edges": [[0, 4], [1, 4], [2, 4], [3, 4], [5, 0], [7, 0], [6, 1], [8, 1]],
    "groups": [{"starts": [0, 1, 2, 3, 5, 6, 7, 8], "goals": [0, 1, 2, 3, 5, 6, 7, 8]}],
    "zones": [{"name": "middle", "rect": [-1.0, -1.0, 1.0, 1.0]}],
}


def make_room(**overrides):
    """``sgjax.make`` on the room (go/stop actions, 4 robots unless overridden)."""
    return sgjax.make(parse_map(ROOM, source="room"), **overrides)


def place(env, params, xs, ys, headings=None, speeds=None, starts=None, goals=None,
          humans=None, key=0):
    """A state with ``len(xs)`` robots at ``(xs, ys)`` facing ``headings`` (rad) moving forward
    at ``speeds`` (m/s), routes from node ``starts`` to ``goals`` (default 0 -> 1), the rest of
    the slots absent; ``humans = [(x, y, vx, vy), ...]`` are the active pedestrians."""
    n, r = len(xs), env.max_agents
    pad = r - n

    def col(values, fill):
        return jnp.asarray(list(values) + [fill] * pad, jnp.float32)

    starts = list(starts or [0] * n) + [0] * pad
    goals = list(goals or [1] * n) + [1] * pad
    present = jnp.arange(r) < n
    _, state = env.reset_to(jnp.asarray(starts), jnp.asarray(goals), present, params,
                            key=jax.random.key(key))
    headings = col(headings if headings is not None else [0.0] * n, 0.0)
    speeds = col(speeds if speeds is not None else [0.0] * n, 0.0)
    robots = state.robots.replace(
        x=col(xs, 100.0), y=col(ys, 100.0),
        kin=state.robots.kin.replace(heading=headings, v_forward=speeds),
    )
    state = state.replace(robots=robots)
    if humans is not None:
        h = state.humans
        m = h.x.shape[0]
        rows = list(humans) + [(50.0, 50.0, 0.0, 0.0)] * (m - len(humans))
        x, y, vx, vy = (jnp.asarray([row[i] for row in rows], jnp.float32) for i in range(4))
        state = state.replace(humans=h.replace(x=x, y=y, vx=vx, vy=vy,
                                               active=jnp.arange(m) < len(humans)))
    distance = jnp.hypot(state.route.goal_x - robots.x, state.route.goal_y - robots.y)
    zones = start_zones(jax.random.key(key), state.route.x, state.route.y, robots.x, robots.y,
                        params.robots.radius, present,
                        env.config.tracked_zones(params.map.zone_rect))
    history = History.start(env.config.observer.history_length - 1, robots, distance)
    return state.replace(history=history, zones=zones)


def go_run_counting_traces(env, params, steps, seed=1):
    """Every robot on GO for ``steps`` steps through one jitted ``env.step`` (auto-resets
    included). Returns each step's ``(state, info)`` and how many times the step was traced."""
    traces = []

    def counted(key, state, actions, params):
        traces.append(1)
        return env.step(key, state, actions, params)

    step = jax.jit(counted)
    _, state = env.reset(jax.random.key(seed), params)
    visited = []
    for t in range(steps):
        _, state, _, _, _, info = step(jax.random.key(t), state,
                                       jnp.zeros(env.max_agents, jnp.int32), params)
        visited.append((state, info))
    return visited, len(traces)
