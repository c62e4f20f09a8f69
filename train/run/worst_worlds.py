"""The worst-case score of a trained run's seeds over a generated family's held-out worlds, as
SFL reports it: every world of the test split (``TEST_SEEDS``) played by each seed's policy
with rollout key A, and the team success of rollout B over the ``ceil(alpha N)`` worlds
rollout A scored lowest, B playing only the worst ``ceil(max alpha N)``
(:func:`sgjax.evaluation.generalisation.play_worst`). The seed's weights are an argument of
the compiled player (:func:`sgjax.evaluation.generalisation.actor_world_players`), so one
program serves every seed of every run of the same actor spec, options and play mode: a
:class:`WorstPlayers` keeps it for the family."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.generalisation import actor_world_players, play_worst
from sgjax.evaluation.trained import ActorSpec
from sgjax.maps.generated.families import PREFIX
from sgjax.maps.generated.splits import TEST_SEEDS
from train.algorithm.actor import ActorWeights


class WorstPlayers:
    """The compiled players of the worst case, one per (family, robots, options, actor spec,
    play mode, chunk), kept while those stay the same (a judge plays every arm of a family
    before the next family, so it compiles once per family)."""

    def __init__(self) -> None:
        self._key: tuple | None = None
        self._made: tuple[Any, Any, Any] | None = None

    def get(self, family: str, robots: int, options: MakeOptions, actor: ActorSpec,
            deterministic: bool, chunk: int) -> tuple[Any, Any, Any]:
        """``(params, runner, draw)`` for these settings, built when they changed."""
        key = (family, robots, options, actor, bool(deterministic), chunk)
        if key != self._key or self._made is None:
            env, by_count = params_by_count(PREFIX + family, [robots], options=options)
            params = by_count[robots]
            self._made = (params, *actor_world_players(env, params, actor, deterministic,
                                                       chunk))
            self._key = key
        return self._made


def worst_of_seeds(actor: ActorSpec, weights: ActorWeights, deterministic: bool,
                   options: MakeOptions, family: str, robots: int, worlds: int,
                   alphas: Sequence[float], seed: int, chunk: int = 500,
                   players: WorstPlayers | None = None) -> dict[str, list[float]]:
    """``{alpha: [S]}`` (alpha as ``f"{alpha:g}"``): each of the seed-batched ``weights``'
    ``S`` seeds' worst-alpha team success over the first ``worlds`` worlds of ``family``'s
    test split at ``robots`` robots, in ``options`` (the run's own, with no world keywords:
    the family's default ranges), rollout keys from ``seed``; NaN where no world was valid.
    ``players``: compiled players kept from an earlier call (a fresh one by default)."""
    players = WorstPlayers() if players is None else players
    chunk = min(chunk, worlds)
    params, runner, draw = players.get(family, robots, options, actor, deterministic, chunk)
    ids = TEST_SEEDS[0] + np.arange(worlds, dtype=np.int64)
    out: dict[str, list[float]] = {f"{a:g}": [] for a in alphas}
    for index in range(weights.lanes):
        plays = play_worst(runner.env, params, None, ids, alphas, seed, chunk,
                           compiled=(runner, draw), args=(weights.seed(index),))
        for alpha in alphas:
            out[f"{alpha:g}"].append(plays.fraction(alpha)[0])
    return out
