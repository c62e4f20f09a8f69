"""A curriculum over generated worlds as pure functions: a replay buffer of levels per
scenario (prioritised level replay, PLR), edited levels (ACCEL) and learnability scores (SFL).

A level is a world's seed and parameter values (:class:`sgjax.environment.worlds.Level`: the
environment builds it again exactly). Before every rollout, :func:`next_levels` picks the world
of each environment's next episode: a level replayed from the buffer with probability
``replay_prob`` once the buffer is ``min_fill`` full (sampled by rank of score and by
staleness, as PLR does), under ``accel`` an edit of the replayed level with probability
``mutate_prob`` (a few parameters moved within their ranges: a door widened or narrowed or
moved, an arm turned; or, where the environment has room for pedestrians, a group of them
added), and otherwise a fresh world. After the rollout, :func:`episode_scores`
scores every episode that ended and :func:`record` keeps the best-scoring levels.

Scores (``LevelsConfig.method``):

* ``plr`` and ``accel``: the positive value loss, the mean over the episode's steps of the
  acting robots' mean positive GAE advantage (JaxUED's ``pvl``; the latest episode's score
  replaces a replayed level's);
* ``learnability``: ``p (1 - p)``, ``p`` the level's mean robot success over its plays (SFL's
  learnability: highest where the policy succeeds half the time).

Shapes: ``N`` buffer slots, ``E`` environments of the scenario, ``T`` rollout steps. Times are
environment steps of the whole batch (``RunnerState.steps``)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.environment.worlds import Level

NEVER = -float("inf")  # an empty slot's score


@struct.dataclass
class LevelBuffer:
    """One scenario's levels (``[N]`` slots) and the running scores of its environments'
    current episodes (``[E]``)."""

    seed: Array  # [N] uint32
    values: dict  # {parameter: [N] float32}
    pedestrians: Array  # [N] int32 the level's active pedestrians (-1: the environment's)
    score: Array  # [N] float32, -inf where empty
    plays: Array  # [N] float32 episodes played on the level
    success: Array  # [N] float32 mean robot success over those episodes
    last_played: Array  # [N] int32 environment steps when it was last played
    filled: Array  # [N] bool
    episode_score: Array  # [E] float32 sum of the current episode's step scores so far
    episode_steps: Array  # [E] float32 steps of it with an acting robot

    @classmethod
    def empty(cls, parameters: tuple[str, ...], size: int, num_envs: int) -> LevelBuffer:
        """An empty buffer of ``size`` levels of a family with these ``parameters``, for
        ``num_envs`` environments."""
        zeros = jnp.zeros(size, jnp.float32)
        return cls(seed=jnp.zeros(size, jnp.uint32),
                   values={name: zeros for name in sorted(parameters)},
                   pedestrians=jnp.full(size, -1, jnp.int32),
                   score=jnp.full(size, NEVER, jnp.float32), plays=zeros, success=zeros,
                   last_played=jnp.zeros(size, jnp.int32), filled=jnp.zeros(size, bool),
                   episode_score=jnp.zeros(num_envs, jnp.float32),
                   episode_steps=jnp.zeros(num_envs, jnp.float32))

    @property
    def fill(self) -> Array:
        """Share of slots holding a level (float32)."""
        return jnp.mean(self.filled.astype(jnp.float32))


def replay_weights(buffer: LevelBuffer, now: Array, temperature: float,
                   staleness: float) -> Array:
    """PLR's replay distribution ``[N]`` over the filled slots: ``(1 - staleness) x`` rank
    prioritisation (weight ``(1 / rank) ^ (1 / temperature)``, rank 1 the highest score) plus
    ``staleness x`` the steps since each level was last played, each normalised."""
    order = jnp.argsort(jnp.where(buffer.filled, -buffer.score, jnp.inf))
    rank = jnp.empty_like(order).at[order].set(jnp.arange(1, order.size + 1))
    by_score = jnp.where(buffer.filled, (1.0 / rank) ** (1.0 / temperature), 0.0)
    age = jnp.where(buffer.filled, (now - buffer.last_played).astype(jnp.float32), 0.0)
    by_age = age / jnp.maximum(jnp.sum(age), 1e-9)
    by_score = by_score / jnp.maximum(jnp.sum(by_score), 1e-30)
    stale = jnp.where(jnp.sum(age) > 0, staleness, 0.0)
    return (1.0 - stale) * by_score + stale * by_age


@dataclasses.dataclass(frozen=True)
class Crowd:
    """What an edit may do to a level's pedestrians: add ``group`` of them (0: never) to its
    count (``base``, the environment's ``num_humans``, where the level has none of its own),
    up to the environment's ``capacity`` (``max_humans``)."""

    group: int = 0
    base: int = 0
    capacity: int = 0

    @property
    def can_grow(self) -> bool:
        return self.group > 0 and self.capacity > self.base


NO_CROWD = Crowd()


def edit(key: Array, values: dict, pedestrians: Array, ranges: dict[str, tuple[float, float]],
         edits: int, scale: float, crowd: Crowd = NO_CROWD) -> tuple[dict, Array]:
    """ACCEL's mutation of one level: ``edits`` changes (drawn with repeats allowed), each a
    parameter (fixed ones, ``low == high``, never move) moved by up to ``scale`` of its
    range's width either way and clipped to the range, or, where ``crowd`` can grow, a group
    of pedestrians added (one more choice beside the parameters, while the level is below
    capacity). Returns the values and the pedestrian count (int32; -1, the environment's,
    where no group was added)."""
    names = sorted(values)
    low = jnp.asarray([ranges[n][0] for n in names], jnp.float32)
    high = jnp.asarray([ranges[n][1] for n in names], jnp.float32)
    vector = jnp.stack([values[n] for n in names])
    k_which, k_step = jax.random.split(key)
    count = jnp.where(pedestrians >= 0, pedestrians, crowd.base)
    grows = jnp.asarray(crowd.can_grow) & (count < crowd.capacity)
    choices = jnp.concatenate([(high > low).astype(jnp.float32),
                               grows.astype(jnp.float32)[None]])
    which = jax.random.choice(k_which, len(names) + 1, (edits,),
                              p=choices / jnp.maximum(jnp.sum(choices), 1))
    step = jax.random.uniform(k_step, (edits,), jnp.float32, -scale, scale)
    which = jnp.where(jnp.sum(choices) > 0, which, -1)  # nothing can change: no edit at all
    moved = (which >= 0) & (which < len(names))
    at = jnp.where(moved, which, 0)
    vector = vector.at[at].add(jnp.where(moved, step * (high - low)[at], 0.0))
    vector = jnp.clip(vector, low, high)
    groups = jnp.sum(which == len(names))
    pedestrians = jnp.where(groups > 0, jnp.minimum(count + groups * crowd.group,
                                                    crowd.capacity), pedestrians)
    return {n: vector[i] for i, n in enumerate(names)}, pedestrians.astype(jnp.int32)


def next_levels(key: Array, buffer: LevelBuffer, now: Array, ranges: dict, *,
                replay_prob: Array | float, min_fill: float, temperature: float,
                staleness: float, mutate_prob: Array | float, edits: int, edit_scale: float,
                crowd: Crowd = NO_CROWD) -> Level:
    """The level of each environment's next episode ``[E]`` (chosen, or unset for a fresh
    world; see the module doc). ``replay_prob`` 0: never a replay (domain randomisation);
    ``mutate_prob`` 0: no edits (PLR). Both may be traced (a lane's numbers). ``crowd``: the
    pedestrian groups an edit may add. A level's last-played time is set when its episode
    ends (:func:`record`), not here: a pick may wait several rollouts for its environment's
    episode to end."""
    num_envs = buffer.episode_score.shape[0]
    k_replay, k_pick, k_mutate, k_edit = jax.random.split(key, 4)
    ready = (buffer.fill >= min_fill) & jnp.any(buffer.filled)
    replay = ready & (jax.random.uniform(k_replay, (num_envs,)) < replay_prob)
    weights = replay_weights(buffer, now, temperature, staleness)
    pick = jax.random.choice(k_pick, weights.size, (num_envs,), p=weights)
    values = {name: v[pick] for name, v in buffer.values.items()}
    pedestrians = buffer.pedestrians[pick]
    mutate = replay & (jax.random.uniform(k_mutate, (num_envs,)) < mutate_prob)
    edited, more = jax.vmap(lambda k, v, p: edit(k, v, p, ranges, edits, edit_scale, crowd))(
        jax.random.split(k_edit, num_envs), values, pedestrians)
    values = {name: jnp.where(mutate, edited[name], v) for name, v in values.items()}
    pedestrians = jnp.where(mutate, more, pedestrians)
    return Level(seed=buffer.seed[pick], values=values, chosen=replay,
                 pedestrians=jnp.where(replay, pedestrians, -1).astype(jnp.int32))


def step_scores(advantages: Array, active: Array, num_envs: int) -> tuple[Array, Array]:
    """Each environment's positive value loss per step ``[T, E]`` (the mean over its acting
    robots of ``max(advantage, 0)``) and whether any robot acted ``[T, E]``, from
    ``advantages`` and ``active [T, E x R]``."""
    steps = advantages.shape[0]
    adv = advantages.reshape(steps, num_envs, -1)
    acting = active.reshape(steps, num_envs, -1).astype(jnp.float32)
    count = jnp.sum(acting, axis=2)
    mean = jnp.sum(jnp.maximum(adv, 0.0) * acting, axis=2) / jnp.maximum(count, 1.0)
    return mean, count > 0


def episode_scores(buffer: LevelBuffer, scores: Array, stepped: Array, done: Array
                   ) -> tuple[Array, LevelBuffer]:
    """The score of every episode that ended in the rollout ``[T, E]`` (the mean of its step
    ``scores [T, E]`` over the steps where a robot acted, ``stepped``, this rollout's and the
    earlier ones'; 0 elsewhere) and the buffer with the running sums of the episodes still
    going. ``done [T, E]``: the episode ended at that step."""

    def one(carry: tuple, x: tuple) -> tuple:
        total, count = carry
        score, acted, ended = x
        total = total + jnp.where(acted, score, 0.0)
        count = count + acted
        out = jnp.where(ended, total / jnp.maximum(count, 1.0), 0.0)
        return (jnp.where(ended, 0.0, total), jnp.where(ended, 0.0, count)), out

    (total, count), out = jax.lax.scan(one, (buffer.episode_score, buffer.episode_steps),
                                       (scores, stepped.astype(jnp.float32), done))
    return out, buffer.replace(episode_score=total, episode_steps=count)


def record(buffer: LevelBuffer, now: Array, seed: Array, values: dict, pedestrians: Array,
           valid: Array, done: Array, score: Array, success: Array,
           learnability: Array | bool, candidates: int) -> tuple[LevelBuffer, Array, Array]:
    """The buffer after the episodes that ended in a rollout (``[T, E]`` each: the seed,
    values and pedestrian count of the level played, whether it was valid, ``done``, the
    episode's PVL ``score`` and its robots' ``success`` share): at most ``candidates`` of
    them (the first to end) are recorded. A level already held gets its new score (under
    ``learnability``, its success mean updated first); new valid levels replace the lowest
    scores when they score higher. Levels are equal when their seeds, pedestrian counts and
    every value are; a level that ended several
    episodes in the rollout counts them all (a held one's newest score is its last
    candidate's; a new one's the mean of its episodes). ``learnability`` (a bool, or a lane's
    traced one) scores by learnability instead of PVL. Returns the buffer, the episodes
    recorded and how many of them replayed a held level (float32)."""
    flat = lambda x: x.reshape(-1)  # noqa: E731
    ended = flat(done) & flat(valid)
    order = jnp.argsort(~ended, stable=True)[:candidates]
    keep = ended[order]
    c_seed = flat(seed)[order]
    c_pedestrians = flat(pedestrians)[order]
    c_values = {n: flat(v)[order] for n, v in values.items()}
    c_success = flat(success)[order]
    c_score = flat(score)[order]

    def same(a: tuple[Array, Array, dict], b: tuple[Array, Array, dict]) -> Array:
        eq = (a[0][:, None] == b[0][None, :]) & (a[1][:, None] == b[1][None, :])
        for n in a[2]:
            eq = eq & (a[2][n][:, None] == b[2][n][None, :])
        return eq

    candidate = (c_seed, c_pedestrians, c_values)
    held = (same(candidate, (buffer.seed, buffer.pedestrians, buffer.values))
            & buffer.filled[None, :] & keep[:, None])
    known = jnp.any(held, axis=1)
    slot = jnp.where(known, jnp.argmax(held, axis=1), buffer.seed.size)

    # Replayed levels: their success mean and score updated (the last candidate's PVL).
    size = buffer.seed.size
    plays = buffer.plays.at[slot].add(1.0, mode="drop")
    success_sum = (buffer.success * buffer.plays).at[slot].add(c_success, mode="drop")
    success = success_sum / jnp.maximum(plays, 1.0)
    last_candidate = jnp.full(size, -1).at[slot].max(jnp.arange(slot.size), mode="drop")
    newest = jnp.where(last_candidate >= 0, c_score[jnp.maximum(last_candidate, 0)],
                       buffer.score)
    learnability = jnp.asarray(learnability, bool)  # may be a lane's (traced) choice
    score = jnp.where(learnability,
                      jnp.where(plays > buffer.plays, success * (1.0 - success), buffer.score),
                      newest)
    last = buffer.last_played.at[slot].set(now, mode="drop")
    buffer = buffer.replace(plays=plays, success=success, score=score, last_played=last)

    # New levels: the first of each kind among the candidates (its twins' episodes pooled),
    # competing for the slots.
    twin = same(candidate, candidate) & keep[None, :] & keep[:, None]
    earlier = jnp.tril(twin, k=-1)
    new = keep & ~known & ~jnp.any(earlier, axis=1)
    count = jnp.maximum(jnp.sum(twin, axis=1), 1).astype(jnp.float32)
    c_success = jnp.sum(twin * c_success[None, :], axis=1) / count
    c_score = jnp.sum(twin * c_score[None, :], axis=1) / count
    new_score = jnp.where(learnability, c_success * (1.0 - c_success), c_score)
    pool = jnp.concatenate([jnp.where(buffer.filled, buffer.score, NEVER),
                            jnp.where(new, new_score, NEVER)])
    top = jax.lax.top_k(pool, buffer.seed.size)[1]  # empty slots (-inf) rank last
    join = lambda a, b: jnp.concatenate([a, b])[top]  # noqa: E731
    buffer = buffer.replace(
        seed=join(buffer.seed, c_seed),
        values={n: join(buffer.values[n], c_values[n]) for n in buffer.values},
        pedestrians=join(buffer.pedestrians, c_pedestrians),
        score=pool[top],
        plays=join(buffer.plays, count),
        success=join(buffer.success, c_success),
        last_played=join(buffer.last_played, jnp.full(c_score.shape, now, jnp.int32)),
        filled=join(buffer.filled, new))
    return buffer, jnp.sum(keep).astype(jnp.float32), jnp.sum(known).astype(jnp.float32)
