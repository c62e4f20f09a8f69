"""The worst-case score of a trained run's seeds over a generated family's held-out worlds, as
SFL reports it: every world of the test split (``TEST_SEEDS``) played by each seed's policy
with rollout key A, and the team success of rollout B over the ``ceil(alpha N)`` worlds
rollout A scored lowest, B playing only the worst ``ceil(max alpha N)``
(:func:`sgjax.evaluation.generalisation.play_worst`). One compiled player per seed (a seed's
weights are constants of its policy), so it costs a compile per seed and family."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sgjax.environment.options import MakeOptions
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.generalisation import play_worst
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
        plays = play_worst(env, params, policy, ids, alphas, seed, min(chunk, worlds))
        for alpha in alphas:
            out[f"{alpha:g}"].append(plays.fraction(alpha)[0])
    return out
