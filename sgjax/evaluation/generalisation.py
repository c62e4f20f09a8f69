"""Whether a policy works in worlds it never saw: a family's worlds played one by one, each
twice (two rollout seeds), summarised per split, with the worst-case score SFL reports.

A **split** is a range of world seeds (:mod:`sgjax.maps.generated.splits`): ``train`` is seeds
``0 ..`` under the ranges given (the distribution training draws from), ``test`` the held-out
seeds ``TEST_SEEDS`` (a run made with ``world_holdout=TEST_SEEDS`` never drew them), each world
built from its seed by :meth:`~sgjax.environment.worlds.WorldSource.of_seed`. Every world is
played with rollout seed A and again with rollout seed B (other spawns, goals and robot count
draws, other action noise). The **worst alpha%** is the mean of rollout B over the
``ceil(alpha N)`` worlds rollout A scored lowest (ranking and scoring on one rollout would
select worlds for their bad luck, not their difficulty). The **gap** is the train split's mean
less the test split's."""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array

from sgjax.environment.env import SocialNavEnv
from sgjax.environment.worlds import WorldDraw
from sgjax.evaluation.evaluate import policy_environment
from sgjax.evaluation.policies import Policy, RecurrentPolicy, load_policy
from sgjax.evaluation.report import markdown_table
from sgjax.evaluation.runner import EpisodeRunner
from sgjax.evaluation.statistics import summarize
from sgjax.evaluation.trained import ActorSpec, check_observation_size
from sgjax.maps.generated.families import PREFIX
from sgjax.maps.generated.splits import TEST_SEEDS
from sgjax.types import EnvParams, EnvState

REPORTED = ("team_success", "collisions", "makespan")  # per family and split
RANKED = "team_success"  # the score the worst alpha% ranks worlds by
SPLITS = {"train": 0, "test": TEST_SEEDS[0]}  # each split's first world seed


class WorldRunner(EpisodeRunner):
    """An :class:`EpisodeRunner` whose episode ``e`` plays world ``worlds[e]`` (a batch of
    :class:`WorldDraw`, an argument of :attr:`run`) instead of the world its reset key
    draws."""

    def reset_batch(self, keys: Array, params: EnvParams, worlds: WorldDraw
                    ) -> tuple[Array, EnvState]:
        return jax.vmap(self.env.reset_in_world, in_axes=(0, None, 0))(keys, params, worlds)


class ActorWorldRunner(WorldRunner):
    """A :class:`WorldRunner` of a trained actor whose weights are an argument of :attr:`run`
    (``run(key, params, worlds, weights)``, ``weights`` one seed's): one compiled program
    plays every seed of a run, and every run of the same actor spec, instead of a program per
    set of weights (weights closed over are constants of the program)."""

    def __init__(self, env: SocialNavEnv, actor: ActorSpec, deterministic: bool,
                 num_episodes: int, max_steps: int):
        super().__init__(env, None, num_episodes, max_steps)
        self.actor, self.deterministic = actor, bool(deterministic)

    def episodes(self, key: Array, params: EnvParams, worlds: WorldDraw, weights: Any
                 ) -> tuple:
        """:meth:`WorldRunner.episodes` under the actor's policy with ``weights`` (traced)."""
        acting = copy.copy(self)  # this trace's runner: the policy of these weights
        acting.policy = self.actor.policy(weights, self.deterministic)
        return WorldRunner.episodes(acting, key, params, worlds)


@dataclasses.dataclass(frozen=True)
class WorldPlays:
    """Worlds ``seeds [N]`` played twice: ``valid [N]`` (worlds that failed the family's
    checks are played with the rest but their rows read NaN), and each rollout's per-world metrics
    ``a``, ``b`` (``{name: [N]}``)."""

    seeds: np.ndarray
    valid: np.ndarray
    a: dict[str, np.ndarray]
    b: dict[str, np.ndarray]


def play_rollout(runner: WorldRunner, draw: Any, params: EnvParams, seeds: np.ndarray,
                 key: Array, *args: Any) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """One rollout of every world of ``seeds [N]`` (``runner.num_episodes`` worlds a call,
    call ``i`` keyed ``fold_in(key, i)``, the last call padded with its last world):
    ``(valid [N], {name: [N]})``, each :data:`REPORTED` metric NaN where the world failed the
    family's checks. ``args``: the runner's further arguments (an :class:`ActorWorldRunner`'s
    weights)."""
    seeds = np.asarray(seeds, np.uint32)
    size = runner.num_episodes
    valid, values = [], {k: [] for k in REPORTED}
    for i, start in enumerate(range(0, len(seeds), size)):
        part = seeds[start:start + size]
        padded = np.concatenate([part, np.repeat(part[-1:], size - len(part))])
        worlds = draw(jnp.asarray(padded))
        ok = np.asarray(worlds.valid)[:len(part)]
        valid.append(ok)
        played = runner(jax.random.fold_in(key, i), params, worlds, *args)
        for name in REPORTED:
            value = np.asarray(played.values[name], np.float64)[:len(part)]
            values[name].append(np.where(ok, value, np.nan))
    if not valid:
        return np.zeros(0, bool), {k: np.zeros(0) for k in REPORTED}
    return np.concatenate(valid), {k: np.concatenate(v) for k, v in values.items()}


def rollout_keys(seed: int) -> tuple[Array, Array]:
    """The keys of rollouts A and B of every play seeded ``seed``."""
    key_a, key_b = jax.random.split(jax.random.key(seed))
    return key_a, key_b


def play_worlds(env: SocialNavEnv, params: EnvParams, policy: Policy | RecurrentPolicy | str,
                seeds: np.ndarray, seed: int = 0, chunk: int = 1000,
                compiled: tuple[WorldRunner, Any] | None = None) -> WorldPlays:
    """Play every world of ``seeds`` once with rollout key A and once with B (both from
    ``seed``), ``chunk`` worlds per compiled call (the worlds' map arrays of a chunk are held
    at once). ``compiled``: the :func:`world_players` of an earlier call, to play more splits
    without compiling again."""
    seeds = np.asarray(seeds, np.uint32)
    runner, draw = compiled or world_players(env, params, policy, min(chunk, len(seeds)))
    key_a, key_b = rollout_keys(seed)
    valid, a = play_rollout(runner, draw, params, seeds, key_a)
    _, b = play_rollout(runner, draw, params, seeds, key_b)
    return WorldPlays(seeds=seeds, valid=valid, a=a, b=b)


@dataclasses.dataclass(frozen=True)
class WorstPlays:
    """SFL's worst case, played as SFL plays it: ``ranked [N]`` is rollout A's
    :data:`RANKED` score of every world of ``seeds [N]`` (NaN where invalid), ``worst [K]`` the
    indices into ``seeds`` of the ``K = ceil(max alpha x valid)`` worlds rollout A scored
    lowest (lowest first, ties in world order), and ``second [K]`` rollout B's score on
    them: rollout B plays those worlds alone."""

    seeds: np.ndarray
    ranked: np.ndarray
    worst: np.ndarray
    second: np.ndarray

    @property
    def scored(self) -> int:
        """How many worlds were valid and ranked."""
        return int(np.isfinite(self.ranked).sum())

    def fraction(self, alpha: float) -> tuple[float, int]:
        """``(mean, count)``: rollout B's mean over the ``ceil(alpha x valid)`` worlds rollout
        A scored lowest (NaN, 0 where no world was valid); ``alpha`` may not exceed the
        largest alpha played."""
        count = worst_count(alpha, self.scored)
        if not self.scored:
            return math.nan, 0
        if count > len(self.worst):
            raise ValueError(f"alpha {alpha:g} needs the worst {count} worlds; rollout B "
                             f"played the worst {len(self.worst)} only")
        return float(np.mean(self.second[:count])), count


def play_worst(env: SocialNavEnv, params: EnvParams, policy: Policy | RecurrentPolicy | str | None,
               seeds: np.ndarray, alphas: Sequence[float], seed: int = 0, chunk: int = 1000,
               compiled: tuple[WorldRunner, Any] | None = None, args: tuple = ()
               ) -> WorstPlays:
    """SFL's worst alpha% of every ``alphas`` at the cost SFL pays: rollout A (the key
    :func:`play_worlds` gives it, so its scores equal that function's ``a``) plays every world
    of ``seeds``, rollout B only the ``ceil(max(alphas) x valid)`` worlds A scored lowest
    (about ``1 + max(alphas)`` rollouts a world instead of two). With ``compiled`` the
    ``policy`` is the players' (None will do), and ``args`` their runner's further arguments
    (the weights of :func:`actor_world_players`)."""
    if not alphas or not all(0.0 < a <= 1.0 for a in alphas):
        raise ValueError(f"play_worst: every alpha must lie in (0, 1], got {list(alphas)}")
    seeds = np.asarray(seeds, np.uint32)
    runner, draw = compiled or world_players(env, params, policy, min(chunk, len(seeds)))
    key_a, key_b = rollout_keys(seed)
    _, first = play_rollout(runner, draw, params, seeds, key_a, *args)
    ranked = first[RANKED]
    scored = np.flatnonzero(np.isfinite(ranked))
    count = worst_count(max(alphas), len(scored)) if len(scored) else 0
    worst = scored[np.argsort(ranked[scored], kind="stable")[:count]]
    _, second = play_rollout(runner, draw, params, seeds[worst], key_b, *args)
    return WorstPlays(seeds=seeds, ranked=ranked, worst=worst, second=second[RANKED])


def world_players(env: SocialNavEnv, params: EnvParams, policy: Any, chunk: int
                  ) -> tuple[WorldRunner, Any]:
    """``(runner, draw)``: a :class:`WorldRunner` of ``chunk`` episodes under ``policy`` and
    the jitted ``vmap`` of the family's ``of_seed``, made once for every split."""
    source = _world_source(env)
    runner = WorldRunner(env, load_policy(policy, env), chunk, int(params.max_steps))
    return runner, jax.jit(jax.vmap(source.of_seed))


def actor_world_players(env: SocialNavEnv, params: EnvParams, actor: ActorSpec,
                        deterministic: bool, chunk: int) -> tuple[ActorWorldRunner, Any]:
    """:func:`world_players` of a trained actor whose weights are the runner's last argument
    (:class:`ActorWorldRunner`): pass ``args=(weights,)`` to :func:`play_worst`."""
    source = _world_source(env)
    check_observation_size(actor, env, str(env.config.scenario))
    runner = ActorWorldRunner(env, actor, deterministic, chunk, int(params.max_steps))
    return runner, jax.jit(jax.vmap(source.of_seed))


def _world_source(env: SocialNavEnv) -> Any:
    """The generated family ``env`` draws its worlds from (an error for a fixed map)."""
    if env.config.world is None:
        raise ValueError(f"play_worlds: {env.config.scenario!r} is a fixed map; give a "
                         "generated family (generated:<family>)")
    return env.config.world


def worst_count(alpha: float, scored: int) -> int:
    """How many of ``scored`` worlds the worst ``alpha`` share holds: ``ceil(alpha N)``, at
    least one; an error for an alpha outside (0, 1]."""
    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha must lie in (0, 1], got {alpha}")
    return max(1, math.ceil(alpha * scored))


def worst_fraction(first: np.ndarray, second: np.ndarray, alpha: float) -> tuple[float, int]:
    """``(mean, count)``: the mean of ``second`` over the ``ceil(alpha N)`` worlds ``first``
    scored lowest (``N`` the worlds with both scores; ties in world order)."""
    worst_count(alpha, 1)  # an alpha outside (0, 1] is an error even with no world
    keep = np.isfinite(first) & np.isfinite(second)
    first, second = first[keep], second[keep]
    if not len(first):
        return math.nan, 0
    count = worst_count(alpha, len(first))
    worst = np.argsort(first, kind="stable")[:count]
    return float(np.mean(second[worst])), count


def split_summary(plays: WorldPlays, alphas: Sequence[float]) -> dict[str, Any]:
    """A split's row: every reported metric over both rollouts of every valid world (mean and
    95% interval over the worlds' two-rollout means), the worst alpha% of each ``alphas``, and
    the worlds played."""
    row: dict[str, Any] = {"worlds": int(len(plays.seeds)), "valid": int(plays.valid.sum())}
    for name in REPORTED:
        pair = np.stack([plays.a[name], plays.b[name]])
        seen = np.isfinite(pair)
        both = np.where(seen.any(axis=0), np.where(seen, pair, 0.0).sum(axis=0)
                        / np.maximum(seen.sum(axis=0), 1), np.nan)
        row[name] = summarize(both, binary=False, fraction=name == "team_success").as_dict()
    for alpha in alphas:
        mean, count = worst_fraction(plays.a[RANKED], plays.b[RANKED], alpha)
        row[f"worst_{alpha:g}"] = {"mean": mean, "worlds": count}
    return row


def family_report(env: SocialNavEnv, params: EnvParams, policy: Any, worlds: int,
                  alphas: Sequence[float] = (0.1,), seed: int = 0, chunk: int = 1000,
                  splits: Mapping[str, int] | None = None) -> dict[str, Any]:
    """Every split's row (:func:`split_summary`) for ``worlds`` worlds of each, and the gap
    (train less test) of every reported metric's mean."""
    splits = dict(SPLITS if splits is None else splits)
    players = world_players(env, params, policy, min(chunk, worlds))
    rows = {}
    for name, first in splits.items():
        seeds = first + np.arange(worlds, dtype=np.int64)
        rows[name] = split_summary(play_worlds(env, params, policy, seeds, seed, chunk,
                                               players), alphas)
    report: dict[str, Any] = {"splits": rows}
    if {"train", "test"} <= set(rows):
        report["gap"] = {k: _difference(rows["train"][k]["mean"], rows["test"][k]["mean"])
                         for k in REPORTED}
    return report


def _difference(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None else float(a - b)


def report(policies: Sequence[Any], families: Sequence[str], num_agents: int, worlds: int,
           alphas: Sequence[float], seed: int, options_for: Any, chunk: int = 1000,
           progress: Any = print) -> dict[str, Any]:
    """:func:`family_report` of every policy on every family (``generated:<family>``, made
    with ``options_for(policy)``: a checkpoint's training options, with evaluation's on top)
    at exactly ``num_agents`` robots: ``{"rows": [{policy, family, ...}], ...}``."""
    rows = []
    for policy in policies:
        for family in families:
            scenario = family if family.startswith(PREFIX) else PREFIX + family
            env, by_count = policy_environment(scenario, [num_agents], policy,
                                               options_for(policy))
            params = by_count[num_agents]
            row = {"policy": str(policy), "family": family,
                   **family_report(env, params, policy, worlds, alphas, seed, chunk)}
            rows.append(row)
            if progress is not None:
                progress(_progress_line(row, alphas))
    return {"num_agents": int(num_agents), "worlds_per_split": int(worlds),
            "alphas": [float(a) for a in alphas], "seed": int(seed), "rows": rows}


def _progress_line(row: Mapping[str, Any], alphas: Sequence[float]) -> str:
    parts = []
    for split, values in row["splits"].items():
        worst = ", ".join(f"worst {a:g}: {values[f'worst_{a:g}']['mean']:.2f}" for a in alphas)
        parts.append(f"{split} {values['team_success']['mean']:.2f} ({worst})")
    return f"{row['family']:>22} {row['policy']:>14}: team success " + "; ".join(parts)


def table_markdown(result: Mapping[str, Any]) -> str:
    """The markdown table of a :func:`report` result: per policy, family and split, team
    success with its interval, collisions, makespan, each worst alpha%, and the gap."""
    alphas = result["alphas"]
    header = (["family", "policy", "split", "worlds", "team success [95% CI]", "collisions",
               "makespan (s)"] + [f"worst {100 * a:g}%" for a in alphas])

    def number(v: float | None, digits: int = 2) -> str:
        return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.{digits}f}"

    rows = []
    for row in result["rows"]:
        for split, v in row["splits"].items():
            ts = v["team_success"]
            rows.append([row["family"], row["policy"], split, f"{v['valid']}/{v['worlds']}",
                         f"{number(ts['mean'])} [{number(ts['ci_low'])}, "
                         f"{number(ts['ci_high'])}]",
                         number(v["collisions"]["mean"]), number(v["makespan"]["mean"], 1)]
                        + [number(v[f"worst_{a:g}"]["mean"]) for a in alphas])
        if "gap" in row:
            gap = row["gap"]
            rows.append([row["family"], row["policy"], "gap (train - test)", "",
                         number(gap["team_success"]), number(gap["collisions"]),
                         number(gap["makespan"], 1)] + [""] * len(alphas))
    lines = markdown_table(header, rows)
    return "\n".join(lines) + "\n"
