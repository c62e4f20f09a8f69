"""Play a batch of episodes of the map being edited: the evaluator's metrics over the batch and
episode 0 as frames for the page to animate.

A batch plays in parts of at most :data:`PART_EPISODES` episodes (equal sizes: one compiled
program), so that the page's Stop (``POST /api/play/cancel``) ends it after the part under way.
Part ``k`` of a batch of several draws its episodes from ``fold_in(key(seed), k)``; a batch of
one part plays ``key(seed)`` itself, as ``sgjax evaluate`` would."""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import jax
import numpy as np

from sgjax.editor.session import EditorError
from sgjax.evaluation.evaluate import policy_environment, run_episodes, summarize_episodes
from sgjax.evaluation.policies import BASELINES, load_policy
from sgjax.maps.schema import MapError, parse_map

# The metrics the page shows first (any other metric of the evaluator follows).
HEADLINE = ("team_success", "success", "collisions", "robot_collisions", "deadlock",
            "episode_length", "time_to_goal")
MAX_EPISODES = 1024
MAX_ROBOTS = 32
PART_EPISODES = 64  # episodes per part of a batch: Stop takes effect after the current part
_running = threading.Lock()
_cancelled = threading.Event()


def _integer(request: dict[str, Any], field: str, default: int, low: int, high: int) -> int:
    value = request.get(field, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise EditorError(400, f"play: {field} must be an integer in [{low}, {high}], got "
                               f"{value!r}")
    return value


def play(request: dict[str, Any]) -> dict[str, Any]:
    """``request``: ``{"map", "policy", "robots", "episodes", "seed"}`` (docs/editor.md).
    Returns ``{"metrics", "episode", "seconds"}``; one play at a time."""
    policy = request.get("policy", "only_local")
    if not isinstance(policy, str) or not policy:
        raise EditorError(400, f"play: policy must be a name or a checkpoint path, got "
                               f"{policy!r}; baselines: {', '.join(BASELINES)}")
    robots = _integer(request, "robots", 4, 1, MAX_ROBOTS)
    episodes = _integer(request, "episodes", 64, 1, MAX_EPISODES)
    seed = _integer(request, "seed", 0, 0, 2**31 - 1)
    try:
        spec = parse_map(request.get("map"), source="the edited map")
    except MapError as err:
        raise EditorError(422, f"play: {err}") from None
    if not _running.acquire(blocking=False):
        raise EditorError(409, "play: another batch is running; wait for it or stop it")
    _cancelled.clear()
    try:
        return _play(spec, policy, robots, episodes, seed)
    except (ValueError, KeyError, TypeError, FileNotFoundError) as err:
        raise EditorError(400, f"play: {err}") from None
    finally:
        _running.release()


def cancel() -> bool:
    """Ask the batch under way to stop after its current part; whether one was running."""
    running = _running.locked()
    if running:
        _cancelled.set()
    return running


def part_sizes(episodes: int) -> tuple[int, int]:
    """``(parts, episodes per part)``: the fewest equal parts of at most
    :data:`PART_EPISODES` that hold ``episodes`` (the last part's extra episodes are dropped)."""
    parts = -(-episodes // PART_EPISODES)
    return parts, -(-episodes // parts)


def _play(spec: Any, policy: str, robots: int, episodes: int, seed: int) -> dict[str, Any]:
    env, by_count = policy_environment(spec, [robots], policy)
    params = by_count[robots]
    loaded = load_policy(policy, env, True)
    parts, size = part_sizes(episodes)
    key = jax.random.key(seed)
    start = time.perf_counter()
    played = []
    for part in range(parts):
        if _cancelled.is_set():
            raise EditorError(409, f"play: stopped after {part} of {parts} part(s) "
                                   f"({part * size} of {episodes} episodes)", cancelled=True)
        played.append(run_episodes(env, params, loaded,
                                   key if parts == 1 else jax.random.fold_in(key, part),
                                   size, record=True))
    seconds = time.perf_counter() - start
    batch = dataclasses.replace(
        played[0], values={name: np.concatenate([p.values[name] for p in played])[:episodes]
                           for name in played[0].values},
        compile_seconds=sum(p.compile_seconds or 0.0 for p in played))
    summary = {name: s.as_dict() for name, s in summarize_episodes(batch).items()}
    ordered = {name: summary[name] for name in HEADLINE if name in summary}
    ordered.update({name: value for name, value in summary.items() if name not in ordered})
    compile_seconds = batch.compile_seconds or 0.0
    return {"metrics": ordered, "episode": episode_frames(batch, params),
            "seconds": {"compile": compile_seconds, "run": max(seconds - compile_seconds, 0.0)}}


def episode_frames(batch: Any, params: Any) -> dict[str, Any]:
    """Episode 0 of a recorded batch as plain lists (docs/editor.md's ``EPISODE``)."""
    states = jax.tree.map(lambda leaf: np.asarray(leaf[:, 0]), batch.states)
    length = int(batch.values["episode_length"][0]) + 1  # the start and every step
    robots, humans, route = states.robots, states.humans, states.route
    frames = np.stack([robots.x[:length], robots.y[:length], robots.heading[:length]], -1)
    active = humans.active[:length]
    people = np.stack([humans.x[:length], humans.y[:length]], -1)
    last = length - 1
    return {
        "dt": float(params.dt),
        "length": length,
        "radius": np.asarray(params.robots.radius).round(4).tolist(),
        "goals": np.stack([route.x[0][:, -1], route.y[0][:, -1]], -1).round(4).tolist(),
        "present": robots.present[0].tolist(),
        "arrived": robots.succeeded[last].tolist(),
        "frames": frames.round(4).tolist(),
        "humans": [people[t][active[t]].round(4).tolist() for t in range(length)],
        "human_radius": float(np.asarray(params.humans.radius)),
    }
