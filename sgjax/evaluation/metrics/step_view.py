"""The quantities that several metrics read, computed once per step (:class:`StepView`) and
once at the end of an episode (:class:`EpisodeEnd`).

Both are plain classes built inside the jitted step: each quantity is a cached property,
computed the first time a metric family reads it and shared by every other family (XLA drops
the ones nobody reads). Shapes: ``R`` robot slots, ``H`` pedestrians, ``B = R + H`` bodies
(robots first); distances in m, speeds in m/s, times in steps unless noted.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
from jax import Array

from sgjax.evaluation.metrics.constants import MetricConstants
from sgjax.kernels.geometry import safe_norm
from sgjax.terms.queries import Bodies, body_gaps, gather_bodies
from sgjax.types import EnvParams, EnvState, Layout, RobotState


class StepView:
    """One step ``prev -> state`` of one environment, as the metrics see it.

    ``info`` is ``env.step_env``'s (``was_active``, ``arrived``); ``done`` (bool scalar) says
    the episode ended with this step; ``running`` (bool scalar) that it had not ended before
    it (an ended episode is frozen: its steps must change no accumulator)."""

    def __init__(self, prev: EnvState, state: EnvState, info: dict, done: Array,
                 params: EnvParams, constants: MetricConstants, running: Array):
        self.prev, self.state, self.info, self.done = prev, state, info, done
        self.params, self.constants, self.running = params, constants, running
        self.dt = params.dt  # s

    @functools.cached_property
    def was_active(self) -> Array:
        """``[R]`` bool: active before the step, in a running episode (the steps counted)."""
        return self.info["was_active"] & self.running

    @functools.cached_property
    def still_active(self) -> Array:
        """``[R]`` bool: still unfinished after the step, in a running episode."""
        return self.state.robots.active & self.running

    @functools.cached_property
    def arrived(self) -> Array:
        """``[R]`` bool: arrived with this step."""
        return self.info["arrived"] & self.running

    @functools.cached_property
    def moved(self) -> Array:
        """``[R]`` m: distance each robot moved in the step."""
        r0, r1 = self.prev.robots, self.state.robots
        return safe_norm(r1.x - r0.x, r1.y - r0.y)

    @functools.cached_property
    def stopped(self) -> Array:
        """``[R]`` bool: unfinished and stopped after the step: speed below ``stop_speed`` and
        turn rate below ``stop_turn_rate``."""
        r1, c = self.state.robots, self.constants
        v1 = r1.velocity
        slow = ((safe_norm(v1[:, 0], v1[:, 1]) < c.stop_speed)
                & (jnp.abs(r1.kin.omega) < c.stop_turn_rate))
        return self.still_active & slow

    @functools.cached_property
    def velocity_change(self) -> Array:
        """``[R, 2]`` m/s: change of the world velocity vector over the step."""
        return self.state.robots.velocity - self.prev.robots.velocity

    @functools.cached_property
    def velocity_change_norm(self) -> Array:
        """``[R]`` m/s: its length."""
        dv = self.velocity_change
        return safe_norm(dv[:, 0], dv[:, 1])

    @functools.cached_property
    def bodies(self) -> Bodies:
        """Every body after the step (robots first, then pedestrians; ``[B]`` each): where they
        are and how fast they move (parked robots at rest)."""
        return gather_bodies(self.state, self.params)

    @functools.cached_property
    def others(self) -> Array:
        """``[R, B]`` bool: the bodies each robot meets in this step: the other robots that were
        in the world during it (active, settling or parked before it) and the active
        pedestrians."""
        robots, humans = self.prev.robots, self.state.humans
        num = robots.x.shape[0]
        other_robot = robots.in_world[None, :] & ~jnp.eye(num, dtype=bool)
        other_human = jnp.broadcast_to(humans.active[None, :], (num, humans.x.shape[0]))
        return jnp.concatenate([other_robot, other_human], axis=1)

    @functools.cached_property
    def gaps(self) -> Array:
        """``[R, B]`` m: body gaps after the step (centre distance - both radii,
        :func:`sgjax.terms.queries.body_gaps`) to :attr:`others`; inf elsewhere."""
        r0, r1 = self.prev.robots, self.state.robots
        # Where the robots are now, in the world as they were during the step.
        during = self.state.replace(robots=_with_flags(r1, r0))
        gaps = body_gaps(during, self.params, Layout(max_agents=r1.x.shape[0]))
        return jnp.where(self.others, gaps, jnp.inf)

    @functools.cached_property
    def nearest_robot(self) -> Array:
        """``[R]`` m: gap to the nearest other robot (inf: none)."""
        num = self.state.robots.x.shape[0]
        return jnp.min(self.gaps[:, :num], axis=1, initial=jnp.inf)

    @functools.cached_property
    def nearest_human(self) -> Array:
        """``[R]`` m: gap to the nearest pedestrian (inf: none)."""
        num = self.state.robots.x.shape[0]
        return jnp.min(self.gaps[:, num:], axis=1, initial=jnp.inf)

    def add(self, total: Array, value: Array | int, mask: Array | None = None) -> Array:
        """``total + value`` where ``mask`` (default :attr:`was_active`), in ``total``'s
        dtype."""
        mask = self.was_active if mask is None else mask
        return total + jnp.where(mask, value, 0).astype(total.dtype)

    def most(self, best: Array, value: Array, mask: Array | None = None) -> Array:
        """Running maximum over the steps where ``mask`` (default :attr:`was_active`)."""
        mask = self.was_active if mask is None else mask
        return jnp.where(mask, jnp.maximum(best, value), best)

    def least(self, best: Array, value: Array) -> Array:
        """Running minimum over the active steps."""
        return jnp.where(self.was_active, jnp.minimum(best, value), best)


def collision_onsets(state: EnvState) -> Array:
    """``[R]`` int32: collision onsets of any kind (robot, wall, pedestrian) so far."""
    c = state.collisions
    return c.robot + c.wall + c.human


def _with_flags(robots: RobotState, flags: RobotState) -> RobotState:
    """``robots`` with the episode flags (present, finished, parked, settling) of ``flags``."""
    return robots.replace(present=flags.present, succeeded=flags.succeeded, ended=flags.ended,
                          parked=flags.parked, settle_steps=flags.settle_steps)


class EpisodeEnd:
    """The end of one episode, as the metrics' finalisation sees it: its final ``state``, its
    ``params``, ``length`` (int32 scalar, steps it ran) and ``active_steps`` (``[R]`` int32,
    steps each robot was active)."""

    def __init__(self, state: EnvState, params: EnvParams, length: Array, active_steps: Array):
        self.state, self.params = state, params
        self.length, self.active_steps = length, active_steps
        self.robots = state.robots
        self.dt = params.dt  # s

    @functools.cached_property
    def present(self) -> Array:
        """``[R]`` bool: robots in the episode."""
        return self.robots.present

    @functools.cached_property
    def success(self) -> Array:
        """``[R]`` bool: in the episode and arrived."""
        return self.robots.present & self.robots.succeeded

    @functools.cached_property
    def collisions(self) -> Array:
        """``[R]`` int32: collision onsets of any kind."""
        return collision_onsets(self.state)

    @functools.cached_property
    def steps(self) -> Array:
        """``[R]`` float32: active steps, at least 1 (the denominator of per-step means)."""
        return jnp.maximum(self.active_steps, 1).astype(jnp.float32)

    @property
    def has_zones(self) -> bool:
        """Whether conflict-zone books were kept (static)."""
        return self.state.zones.phase.shape[1] > 0
