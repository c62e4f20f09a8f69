"""Reward and observation ablations trained as one ``vmap`` (the paper's Table 4).

A *variant* switches reward terms off (a multiplier of 0 on ``info["reward_terms"]``) and hides
observation features (a 0 in the observation mask). Reward weights and the mask are arrays in
the runner state, so every variant x seed is one lane of one jitted, vmapped training function
(in one call, or in groups of lanes); only the network architecture (MLP or GRU) needs its own.

    variants = {"baseline": Variant(), "no collision": Variant(rewards_off=("collision",)),
                "no velocities": Variant(hide=("velocity", "others.velocity"))}
    trainer = Trainer(config)
    runner, logs = train_variants(trainer, variants, seeds=3)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from sgjax.observations.others import FEATURES
from sgjax.terms import ConfigError
from train.actor import ActorWeights, lane_evaluator
from train.ppo import Trainer


@dataclasses.dataclass(frozen=True)
class Variant:
    """Reward terms to switch off, and observation features to hide: a term name
    (``"velocity"``), ``"others.<feature>"`` (that feature of every body in the ``others``
    block) or ``"pose.heading"`` (the pose term's cos/sin)."""

    rewards_off: tuple[str, ...] = ()
    hide: tuple[str, ...] = ()


def observation_mask(env: Any, hide: Sequence[str]) -> np.ndarray:
    """``[D]`` ones, with zeros on the hidden features of ``env``'s observation."""
    mask = np.ones(env.observation_size, np.float32)
    slices = env.observation_slices()
    terms = {t.name: t for t in env.config.observer.terms}
    for item in hide:
        term, _, feature = item.partition(".")
        if term not in slices:
            raise ConfigError(f"hide {item!r}: no observation term {term!r}; this "
                              f"observation has {list(slices)}")
        block = slices[term]
        if not feature:
            mask[block] = 0.0
        elif term == "others" and feature in terms["others"].features:
            others = terms["others"]
            start = 0
            for name in others.features:
                if name == feature:
                    break
                start += FEATURES[name]
            for body in range(others.k):
                first = block.start + body * others.width + start
                mask[first:first + FEATURES[feature]] = 0.0
        elif term == "pose" and feature == "heading" and getattr(terms["pose"], "heading",
                                                                  False):
            mask[block.stop - 2:block.stop] = 0.0
        else:
            raise ConfigError(f"hide {item!r}: cannot hide {feature!r} of {term!r} (use a term, "
                              "others.<feature> or pose.heading)")
    return mask


def variant_inputs(trainer: Trainer, variants: Mapping[str, Variant], seeds: int
                   ) -> tuple[jax.Array, dict, jax.Array, list[tuple[str, int]]]:
    """Keys, term weights and masks stacked over lanes (variant x seed), and the lane labels."""
    names = trainer.batch.reward_term_names()
    keys, weights, masks, labels = [], [], [], []
    for label, variant in variants.items():
        for off in variant.rewards_off:
            if off not in names:
                raise ConfigError(f"variant {label!r}: no reward term {off!r}; this "
                                  f"configuration pays {list(names)}")
        mask = observation_mask(trainer.batch.env, variant.hide)
        for seed in range(seeds):
            keys.append(jax.random.PRNGKey(trainer.config.seed + seed))
            weights.append({n: 0.0 if n in variant.rewards_off else 1.0 for n in names})
            masks.append(mask)
            labels.append((label, seed))
    stacked = {n: jnp.asarray([w[n] for w in weights]) for n in names}
    return jnp.stack(keys), stacked, jnp.asarray(np.stack(masks)), labels


def train_variants(trainer: Trainer, variants: Mapping[str, Variant], seeds: int,
                   lanes_per_run: int | None = None) -> tuple[Any, dict, list[tuple[str, int]]]:
    """Train every variant x seed with one jitted ``vmap``: all lanes in one call, or
    ``lanes_per_run`` lanes at a time (the same compiled function for every group, the last
    group padded; for memory). Returns the lane-batched runner, the per-update logs
    ``[lanes, updates]`` and the lane labels ``(variant, seed)``. Wide vmaps used to hang on
    XLA:CPU; the cause is fixed (docs/xla-cpu-deadlock.md)."""
    keys, weights, masks, labels = variant_inputs(trainer, variants, seeds)
    updates = trainer.config.algorithm.num_updates
    count = len(labels)
    width = count if lanes_per_run is None else max(1, min(lanes_per_run, count))

    @jax.jit
    @jax.vmap
    def run(key, weight, mask):
        return trainer.update_chunk(trainer.init(key, weight, mask), updates)

    outputs = []
    for start in range(0, count, width):
        index = np.minimum(np.arange(start, start + width), count - 1)
        pick = lambda x, index=index: x[index]  # noqa: E731
        outputs.append(run(pick(keys), jax.tree.map(pick, weights), pick(masks)))
    runner, logs = jax.tree.map(lambda *xs: jnp.concatenate(xs)[:count], *outputs)
    return runner, logs, labels


def evaluate_lanes(trainer: Trainer, runner: Any, env: Any, env_params: Any, episodes: int,
                   key: jax.Array) -> np.ndarray:
    """Team success of every lane over ``episodes`` episodes of ``env``. Returns ``[lanes]``."""
    values = lane_metrics(trainer, runner, env, env_params, episodes, key)
    return np.mean(values["team_success"], axis=1)


def lane_metrics(trainer: Trainer, runner: Any, env: Any, env_params: Any, episodes: int,
                 key: jax.Array) -> dict[str, np.ndarray]:
    """Every metric's per-episode values for every lane, ``{name: [lanes, episodes]}``: one
    compiled evaluation, ``vmap``-ed over the lanes (seeds or variants), actions sampled."""
    evaluator = lane_evaluator(trainer.config.network, trainer.actor, env, env_params, episodes)
    values, _ = evaluator(ActorWeights.of(runner), key)
    return {name: np.asarray(v) for name, v in values.items()}
