"""Episode enders: composable terminated / truncated terms.

An ender is called with the one term input, ``ender(inputs: TermInput) -> Outcome``, on the
state after the motion (``inputs.state``; arrivals are marked, absorbing robots not yet) and
the state before the step (``inputs.prev``). Its :class:`Outcome` says which robots it
terminates (they leave the world, or stay parked with ``make(ended="park")``; arrived robots
settle on their goals by default), which it truncates (the episode ends for them without a
terminal state) and a reward adjustment (for example the stuck penalty).
``success`` (a robot at its goal terminates) is always on: it is what success means here.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any, ClassVar

import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.terms.base import ConfigError, Registry, TermSet, parse_terms
from sgjax.terms.contract import Term, TermInput
from sgjax.terms.queries import collided
from sgjax.validation import check_bool, check_choice, check_int, check_positive

if TYPE_CHECKING:
    from sgjax.types import EnvState


@struct.dataclass
class Outcome:
    """What an ender (or all of them together) decides for one step, per robot slot ``[R]``:

    * ``terminated`` (bool): the robot's episode ends in a terminal state (success, a fatal
      collision); it is absorbing from the next state on (``state.robots.ended``);
    * ``truncated`` (bool): its episode ends without a terminal state (time limit, stuck);
    * ``reward`` (float32, natural sign): added to the step's reward of robots that were
      active at ``prev`` (the stuck penalty), and reported under the ender's name in
      ``info["reward_terms"]`` when the ender ``pays``.

    Enders combine by ``or`` on the flags and ``+`` on the reward."""

    terminated: Array  # [R] bool
    truncated: Array  # [R] bool
    reward: Array  # [R] float32 added to the step's reward


@dataclasses.dataclass(frozen=True)
class Ender(Term):
    """Base class of episode enders: subclasses set ``name`` and implement
    ``__call__(inputs) -> Outcome``. ``window``: steps of per-robot movement the ender reads
    from ``state.moved`` (the environment keeps the longest any ender asks for); ``pays``: the
    ender adjusts rewards (its ``Outcome.reward`` is reported in ``info["reward_terms"]``)."""

    window: ClassVar[int] = 0  # steps of movement history the ender reads
    pays: ClassVar[bool] = False  # adjusts rewards (reported in info["reward_terms"])

    def __call__(self, inputs: TermInput) -> Outcome:
        raise NotImplementedError


ENDERS = Registry("episode ender", Ender)


def _nothing(state: EnvState) -> Outcome:
    no = jnp.zeros(state.robots.x.shape, bool)
    return Outcome(no, no, jnp.zeros(state.robots.x.shape, jnp.float32))


@ENDERS.register
@dataclasses.dataclass(frozen=True)
class SuccessEnder(Ender):
    """A robot within ``params.goal_tolerance`` of its goal terminates (always on)."""

    name = "success"

    def __call__(self, inputs: TermInput) -> Outcome:
        prev, state = inputs.prev, inputs.state
        out = _nothing(state)
        return out.replace(terminated=state.robots.succeeded & ~prev.robots.succeeded)


@ENDERS.register
@dataclasses.dataclass(frozen=True)
class TimeLimit(Ender):
    """Every unfinished robot is truncated once ``params.max_steps`` steps have passed (set by
    ``make(time_limit=seconds)``)."""

    name = "time_limit"

    def __call__(self, inputs: TermInput) -> Outcome:
        state, params = inputs.state, inputs.params
        out = _nothing(state)
        late = state.time >= params.max_steps
        return out.replace(truncated=jnp.broadcast_to(late, out.truncated.shape))


@ENDERS.register
@dataclasses.dataclass(frozen=True)
class Stuck(Ender):
    """SocialGym's stuck detector ("entropy ender"): when every robot still on its way has
    travelled less than ``distance`` (m) over the last ``steps`` steps, the episode is truncated
    for all and each unfinished robot receives ``penalty`` (SocialGym's configs: -100000).
    Robots that finished inside the window do not count."""

    name = "stuck"
    pays = True
    distance: float = 0.5
    steps: int = 100
    penalty: float = 0.0

    def __post_init__(self) -> None:
        check_positive("distance", self.distance)
        check_int("steps", self.steps)
        if isinstance(self.penalty, bool) or not isinstance(self.penalty, int | float):
            raise ValueError(f"penalty must be a number, got {self.penalty!r}")

    @property
    def window(self) -> int:  # type: ignore[override]
        return self.steps

    def __call__(self, inputs: TermInput) -> Outcome:
        prev, state = inputs.prev, inputs.state
        out = _nothing(state)
        travelled = jnp.sum(state.moved[: self.steps], axis=0)  # [R] over the window
        still_active = prev.robots.active & ~state.robots.succeeded
        stuck = ((state.time >= self.steps) & jnp.any(still_active)
                 & jnp.all(~still_active | (travelled < self.distance)))
        hit = still_active & stuck
        return Outcome(terminated=out.terminated, truncated=hit,
                       reward=jnp.where(hit, jnp.float32(self.penalty), 0.0))


@ENDERS.register
@dataclasses.dataclass(frozen=True)
class CollisionEnder(Ender):
    """On a collision onset of the chosen kinds, ``scope="team"`` terminates every robot still
    on its way (SocialGym's ``CollisionEpisodeEnder``), ``"robot"`` only the robots that
    collided (they leave the world, or stay parked where they stopped with
    ``make(ended="park")``)."""

    name = "collision"
    scope: str = "team"
    robots: bool = True
    walls: bool = True
    humans: bool = True

    def __post_init__(self) -> None:
        check_choice("scope", self.scope, ("team", "robot"))
        for field in ("robots", "walls", "humans"):
            check_bool(field, getattr(self, field))

    def __call__(self, inputs: TermInput) -> Outcome:
        prev, state = inputs.prev, inputs.state
        out = _nothing(state)
        hit = collided(prev, state, self.robots, self.walls, self.humans, per_step=False)
        hit = hit & prev.robots.active
        still_active = prev.robots.active & ~state.robots.succeeded
        ended = still_active & jnp.any(hit) if self.scope == "team" else hit & still_active
        return out.replace(terminated=ended)


@dataclasses.dataclass(frozen=True)
class Enders(TermSet):
    """The episode's enders (``success`` always among them)."""

    terms: tuple[Ender, ...]
    section = "enders"

    def __post_init__(self) -> None:
        super().__post_init__()
        if "success" not in self.names:
            raise ConfigError("enders: 'success' is required (a robot at its goal leaves the "
                              f"world); got {list(self.names)}")

    @property
    def window(self) -> int:
        """Steps of per-robot movement the enders need to remember."""
        return max([0] + [int(t.window) for t in self.terms])

    @classmethod
    def parse(cls, spec: Any, where: str = "enders") -> Enders:
        """From a list of names / ``{name: options}`` items or a mapping ``{name: options}``
        (see :func:`sgjax.terms.base.parse_terms`); ``success`` is added when missing. Enders
        are returned as they are."""
        if isinstance(spec, Enders):
            return spec
        terms = [term for term, _ in parse_terms(spec, ENDERS, where)]
        if "success" not in [t.name for t in terms]:
            terms.insert(0, SuccessEnder())
        return cls(tuple(terms))

    def __call__(self, inputs: TermInput) -> tuple[Outcome, dict[str, Array]]:
        """Combined outcome and each paying ender's reward adjustment by name."""
        total = _nothing(inputs.state)
        rewards = {}
        for term, term_inputs in self.each(inputs):
            out = term(term_inputs)
            total = Outcome(total.terminated | out.terminated, total.truncated | out.truncated,
                            total.reward + out.reward)
            if term.pays:
                rewards[term.name] = out.reward
        return total, rewards

