"""Running statistics for observation and reward normalisation (as SB3's ``VecNormalize``,
which the SocialGym 2.0 paper found essential)."""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

EPS = 1e-8


@struct.dataclass
class RunningStats:
    """Mean and variance of a stream of ``[..., F]`` samples (parallel Welford update)."""

    mean: Array  # [F]
    var: Array  # [F]
    count: Array  # scalar float

    @classmethod
    def start(cls, size: int) -> RunningStats:
        """No samples yet (a count of 1e-4 keeps the first update's division finite). The count
        is a strongly typed float32, as every update returns it: a weakly typed Python-float
        start made the first training call trace and compile the update a second time."""
        return cls(mean=jnp.zeros(size), var=jnp.ones(size), count=jnp.asarray(1e-4, jnp.float32))

    def update(self, x: Array, mask: Array) -> RunningStats:
        """Fold in the rows of ``x [N, F]`` where ``mask [N]``.

        The masked sums over the rows are matrix-vector products ``w @ x``: XLA:CPU reduces
        a ``[N, F]`` array over its major axis slowly, and the observation statistics run on
        every rollout step (``bench/learner_roofline.py`` times them)."""
        w = mask.astype(jnp.float32)
        n = jnp.sum(w)
        safe_n = jnp.maximum(n, 1.0)
        # float32 products at full precision (a GPU's default may round them to TF32)
        weighted_sum = functools.partial(jnp.dot, w, precision=jax.lax.Precision.HIGHEST)
        batch_mean = weighted_sum(x) / safe_n
        batch_var = weighted_sum(jnp.square(x - batch_mean)) / safe_n
        total = self.count + n
        delta = batch_mean - self.mean
        mean = self.mean + delta * n / total
        m2 = self.var * self.count + batch_var * n + jnp.square(delta) * self.count * n / total
        updated = RunningStats(mean=mean, var=m2 / total, count=total)
        return self.where(n > 0, updated)

    def where(self, condition: Array, other: RunningStats) -> RunningStats:
        return RunningStats(mean=jnp.where(condition, other.mean, self.mean),
                            var=jnp.where(condition, other.var, self.var),
                            count=jnp.where(condition, other.count, self.count))

    def normalize(self, x: Array, clip: float = 10.0) -> Array:
        return jnp.clip((x - self.mean) / jnp.sqrt(self.var + EPS), -clip, clip)

    def scale(self, x: Array, clip: float) -> Array:
        """Divide by the standard deviation only (reward scaling by the return's spread)."""
        return jnp.clip(x / jnp.sqrt(self.var + EPS), -clip, clip)
