"""The worst-case score of a trained run's seeds over a generated family's held-out worlds, as
SFL reports it: every world of the test split (``TEST_SEEDS``) played twice by each seed's
policy (:func:`sgjax.evaluation.generalisation.play_worlds`: rollout keys A and B), and the
team success of rollout B over the ``ceil(alpha N)`` worlds rollout A scored lowest
(:func:`~sgjax.evaluation.generalisation.worst_fraction`). One compiled player per seed (a
seed's weights are constants of its policy), so it costs a compile per seed and family."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.generalisation import RANKED, play_worlds, worst_fraction
from sgjax.maps.generated.families import PREFIX
from sgjax.maps.generated.splits import TEST_SEEDS
from train.run.checkpoint import load_checkpoint_policy


def worst_of_seeds(path: str | Path, seeds: int, deterministic: bool, options: MakeOptions,
                   family: str, robots: int, worlds: int, alphas: Sequence[float],
                   seed: int, chunk: int = 500) -> dict[str, list[float]]:
    """``{alpha: [S]}`` (alpha as ``f"{alpha:g}"``): each of the checkpoint's ``seeds``
    seeds' worst-alpha team success over the first ``worlds`` worlds of ``family``'s test
    split at ``robots`` robots, in ``options`` (the run's own, with no world keywords: the
    family's default ranges), rollout keys from ``seed``; NaN where no world was valid."""
    env, by_count = params_by_count(PREFIX + family, [robots], options=options)
    params = by_count[robots]
    ids = TEST_SEEDS[0] + np.arange(worlds, dtype=np.int64)
    out: dict[str, list[float]] = {f"{a:g}": [] for a in alphas}
    for index in range(seeds):
        policy = load_checkpoint_policy(path, env, seed_index=index,
                                        deterministic=deterministic)
        plays = play_worlds(env, params, policy, ids, seed, min(chunk, worlds))
        for alpha in alphas:
            out[f"{alpha:g}"].append(worst_fraction(plays.a[RANKED], plays.b[RANKED], alpha)[0])
    return out
