"""Hyper-parameter search: an Optuna study whose trials train side by side as lanes.

    python -m train.sweep --config train/configs/doorway.yaml \\
        --space train/configs/sweeps/doorway.yaml [--trials 32] [--lanes 8] \\
        [--storage sqlite:///runs/sweep/study.db | postgresql://...] [--study NAME] \\
        [--out runs/sweep/doorway] [--set algorithm.total_steps=5e5] [--worker 0]

The space file (``train.run.search_space``) lists the parameters, the objective and the study's
settings. Trials are asked from Optuna (ask-and-tell) and placed in **lanes** of one compiled
training call (``Trainer.update_chunk_lanes``): trials that differ only in lane values
(learning rate, entropy and value coefficients, clip range, gamma, GAE lambda, team reward,
reward-term weights, hidden observation features) share one program; trials that change the
program (network sizes, minibatch count, environments) are grouped by those values and each
group compiles once. A trial with ``trial.seeds`` seeds takes that many lanes (the seeds are
``config.seed + i`` for every trial: trials are compared on the same seeds and the same
validation episodes).

Every ``1 / trial.evaluations`` of a trial's updates, each lane is evaluated by the project's
evaluation (``sgjax.evaluation.trained.TrainedEvaluation``, one compiled program per group)
on the validation episodes (``train.algorithm.config.VALIDATION_SEED``, never the final
evaluation's), the trial's mean is reported to Optuna, and the pruner may stop it. A finished
or pruned trial's lanes are refilled with the next trial at once (a lane in a fixed-width
``vmap`` costs the same whether it works or idles, so stopping a lane saves nothing; refilling
it is the gain).

Storage: an SQLite file in the run folder by default; any SQLAlchemy URL (PostgreSQL) lets
several processes or hosts share one study: start the same command on each with its own
``--worker`` number (a sampler seed and a checkpoint file of its own); the storage hands every
trial to one process, and each process stops when the study has ``sweep.trials`` trials.

After every training call a worker writes its lanes (``<out>/workers/<worker>.msgpack``,
atomically): killed (``kill -9``) and started again with the same ``--out`` and ``--worker``,
it continues its running trials from there; finished trials live in the storage and are never
run again.

Outputs in ``--out``: ``trials.md``/``trials.csv`` (every trial), ``best.yaml`` (the best
trial as a config: ``python -m train --config best.yaml`` trains it), ``best_variants.yaml``
(the shipped config against the tuned one for ``train.ablation --variants``: paired seeds),
``history.png`` and ``importance.png`` (Optuna's plots), and ``sweep.json`` (every trial,
with provenance; schema ``sgjax.sweep/1``). ``optuna-dashboard <storage URL>`` browses the
study live.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import yaml

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.evaluation.provenance import provenance
from sgjax.evaluation.report import markdown_table
from sgjax.evaluation.trained import TrainedEvaluation
from sgjax.files import write_atomic
from sgjax.terms.base import ConfigError
from sgjax.validation import freeze, thaw
from train.algorithm.actor import ActorWeights
from train.algorithm.config import VALIDATION_SEED, TrainConfig, config_from_dict, load_config
from train.algorithm.env_batch import observation_mask
from train.algorithm.lane_settings import LANE_SETTINGS
from train.algorithm.trainer import Trainer
from train.reports.result_schemas import SWEEP
from train.run import checkpoint
from train.run.loop import Call, train_in_calls
from train.run.phases import Phases
from train.run.search_space import (
    PRUNERS,
    SearchSpace,
    grid,
    is_lane_key,
    load_space,
    split_values,
    suggest_values,
    trial_values,
)

CHECKPOINT_FORMAT = "sgjax.sweep-worker/1"


def _optuna():
    """Optuna, imported on first use (``pip install -e .[sweep]``)."""
    try:
        import optuna
    except ImportError as err:
        raise ConfigError("train.sweep needs Optuna: pip install -e '.[sweep]' (optuna; "
                          "psycopg2-binary for a PostgreSQL storage)") from err
    return optuna


# ---------------------------------------------------------------------- configs of trials
def with_values(data: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """A copy of config data with ``{section.key: value}`` set; ``term_weights.<term>`` goes
    to ``algorithm.term_weights`` and a true ``hide.<feature>`` to ``algorithm.hide``."""
    data = {k: dict(v) if isinstance(v, Mapping) else v for k, v in data.items()}
    for key, value in values.items():
        section, _, field = key.partition(".")
        algorithm = data.setdefault("algorithm", {})
        if section == "term_weights":
            algorithm["term_weights"] = {**thaw(algorithm.get("term_weights") or {}),
                                         field: thaw(value)}
        elif section == "hide":
            hidden = [h for h in thaw(algorithm.get("hide") or []) if h != field]
            algorithm["hide"] = hidden + [field] if value else hidden
        else:
            data[section] = {**data.get(section, {}), field: thaw(value)}
    return data


def group_key(program: Mapping[str, Any]) -> tuple:
    """A hashable key of a trial's program settings (trials with equal keys share lanes)."""
    return tuple(sorted((k, freeze(v)) for k, v in program.items()))


@dataclasses.dataclass
class Running:
    """A trial in lanes: its Optuna trial, values, lanes, evaluations done, scores so far."""

    trial: Any
    values: dict[str, Any]
    lanes: tuple[int, ...]
    evaluations: int = 0
    scores: list[float] = dataclasses.field(default_factory=list)
    # evaluations the storage holds already (a trial run again from the start: Optuna keeps
    # the first report of each)
    reported: frozenset[int] = frozenset()

    @property
    def number(self) -> int:
        return self.trial.number


class Group:
    """One compiled program: the trials sharing every program setting, as ``lanes`` lanes
    (``lanes / seeds`` trial slots of ``seeds`` lanes)."""

    def __init__(self, data: Mapping[str, Any], program: Mapping[str, Any],
                 space: SearchSpace, lanes: int, source: str):
        self.program = dict(program)
        self.space = space
        self.lanes = lanes
        where = f"{source} with {dict(program)}" if program else source
        self.config: TrainConfig = config_from_dict(with_values(data, program), where)
        varied = {k.partition(".")[2] for k in space.keys if k.startswith("algorithm.")
                  and k.partition(".")[2] in LANE_SETTINGS}
        self.trainer = Trainer(self.config, varied=tuple(varied))
        a = self.config.algorithm
        self.per_chunk = math.ceil(a.num_updates / space.evaluations)
        self.updates = self.per_chunk * space.evaluations
        self.steps = self.updates * a.steps_per_update  # environment steps per trial
        trainer = self.trainer
        self._init = jax.jit(jax.vmap(trainer.init))
        self._place = jax.jit(lambda runners, index, fresh: jax.tree.map(
            lambda a, b: a.at[index].set(b), runners, fresh), donate_argnums=0)
        self._evaluation: TrainedEvaluation | None = None

    # ------------------------------------------------------------------ lanes
    def lane_inputs(self, values: Sequence[Mapping[str, Any]]) -> tuple:
        """``init``'s inputs for lanes with these values (one mapping per lane, each lane's
        seed its index within its trial's lanes is given by ``values[i]["_seed"]``)."""
        trainer = self.trainer
        base_hide = tuple(self.config.algorithm.hide)
        configured = {n: float(w) for n, w in trainer.term_weights().items()}
        keys, weights, masks, hypers = [], [], [], []
        for v in values:
            keys.append(jax.random.PRNGKey(self.config.seed + int(v.get("_seed", 0))))
            w = dict(configured)
            hide = list(base_hide)
            hyper = {}
            for key, value in v.items():
                section, _, field = key.partition(".")
                if section == "term_weights":
                    if field not in w:
                        raise ConfigError(f"{self.space.source}: params: {key}: no reward term "
                                          f"{field!r}; this configuration pays {list(w)}")
                    w[field] = float(value)
                elif section == "hide":
                    hide = [h for h in hide if h != field] + ([field] if value else [])
                elif section == "algorithm" and field in LANE_SETTINGS:
                    hyper[field] = value
            try:
                masks.append(observation_mask(trainer.batch.env, hide))
            except ConfigError as err:
                raise ConfigError(f"{self.space.source}: params: hide: {err}") from None
            weights.append(w)
            hypers.append(trainer.lane_hyper(hyper))
        stack = lambda rows: {k: jnp.asarray(np.stack([r[k] for r in rows])) for k in rows[0]}  # noqa: E731
        return (jnp.stack(keys), stack(weights), jnp.asarray(np.stack(masks)), stack(hypers))

    def start(self) -> Any:
        """Every lane at the config's values (lanes wait in this state until a trial fills
        them; they compute like the others): one trial's worth of lanes, initialised by the
        program :meth:`fill` uses too, repeated."""
        return self._repeated(*self._waiting_inputs())

    def _waiting_inputs(self) -> tuple:
        return self.lane_inputs([{"_seed": i} for i in range(self.space.seeds)])

    def _repeated(self, *inputs: Any) -> Any:
        copies = self.lanes // self.space.seeds
        return jax.tree.map(lambda x: jnp.concatenate([x] * copies), self._init(*inputs))

    def fill(self, runners: Any, lanes: Sequence[int], values: Mapping[str, Any]) -> Any:
        """``runners`` with ``lanes`` (one trial's seeds) started afresh at ``values``."""
        fresh = self._init(*self.lane_inputs([{**values, "_seed": i}
                                              for i in range(len(lanes))]))
        return self._place(runners, jnp.asarray(lanes), fresh)

    def score(self, runners: Any) -> np.ndarray:
        """The objective of every lane ``[lanes]``: the metric's mean over the validation
        episodes, averaged over the objective's robot counts (one compiled evaluation,
        :class:`sgjax.evaluation.trained.TrainedEvaluation`)."""
        o = self.space.objective
        if self._evaluation is None:
            counts = list(o.num_agents)
            self._evaluation = TrainedEvaluation(
                self.trainer.trained_actor, self.config.env.scenarios[0], counts, o.episodes,
                self.config.env.options, max_agents=max(*counts, self.trainer.slots))
        scores = self._evaluation.scores(ActorWeights.of(runners),
                                         jax.random.PRNGKey(VALIDATION_SEED), o.metric)
        return np.mean(scores, axis=0)

    # ------------------------------------------------------------------ checkpoints
    def template(self) -> Any:
        """The shapes of :meth:`start`'s runners (to read a checkpoint into)."""
        return jax.eval_shape(self._repeated, *self._waiting_inputs())


# ---------------------------------------------------------------------- the study
def open_study(space: SearchSpace, storage: str, name: str, worker: int) -> Any:
    """The study (created or loaded), with the space's sampler and pruner; ``worker`` offsets
    the sampler's seed so that processes sharing a study draw different trials."""
    optuna = _optuna()
    # Each worker draws its own sequence, and a study continued (a restarted worker, a second
    # run of the command) does not replay the draws of its first trials.
    kwargs = {"connect_args": {"timeout": 60}} if storage.startswith("sqlite") else {}
    rdb = _storage(storage, kwargs)
    try:
        existing = len(rdb.get_all_trials(rdb.get_study_id_from_name(name), deepcopy=False))
    except KeyError:
        existing = 0
    seed = space.sampler_seed + 1000 * worker + existing
    if space.sampler == "grid":
        sampler = optuna.samplers.GridSampler(grid(space), seed=seed)
    elif space.sampler == "random":
        sampler = optuna.samplers.RandomSampler(seed=seed)
    else:
        sampler = optuna.samplers.TPESampler(seed=seed, constant_liar=True)
    if space.pruner == "median":
        pruner = optuna.pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=0)
    elif space.pruner == "hyperband":
        pruner = optuna.pruners.HyperbandPruner(min_resource=1,
                                                max_resource=space.evaluations)
    else:
        pruner = optuna.pruners.NopPruner()
    return optuna.create_study(storage=rdb, study_name=name, sampler=sampler, pruner=pruner,
                               direction=space.objective.direction, load_if_exists=True)


def _storage(url: str, engine_kwargs: dict, attempts: int = 5) -> Any:
    """Optuna's RDB storage at ``url``. Processes started together on a fresh database race to
    create Optuna's tables (PostgreSQL: a unique-key violation in its catalogue); the loser
    tries again once the tables exist."""
    import sqlalchemy.exc

    optuna = _optuna()
    for attempt in range(attempts):
        try:
            return optuna.storages.RDBStorage(url, engine_kwargs=engine_kwargs)
        except sqlalchemy.exc.DBAPIError:
            if attempt == attempts - 1:
                raise
            time.sleep(0.5 * (attempt + 1))
    raise AssertionError("unreachable")


def tell(study: Any, trial: Any, value: float | None = None, **state: Any) -> None:
    """``study.tell``, where a grid sampler's signal that its grid is done is not an error.
    Optuna's ``GridSampler.after_trial`` calls ``Study.stop()`` once every grid point has been
    asked, and outside ``Study.optimize`` (ask-and-tell, as here) ``stop`` raises
    ``RuntimeError``; the trial's state and value are stored all the same (a ``finally`` in
    Optuna's tell), and the sweep ends by counting its trials, so the signal is dropped."""
    try:
        study.tell(trial, value, **state)
    except RuntimeError as err:
        if "Study.stop" not in str(err):
            raise


def counted(trials: Sequence[Any]) -> list[Any]:
    """The trials that count toward the study's size (not the surplus ones a process asked
    while another took the last place)."""
    return [t for t in trials if not t.user_attrs.get("surplus")]


def grid_size(space: SearchSpace) -> int:
    return int(np.prod([len(p.choices) for p in space.params]))


class Sweep:
    """One worker of a sweep: asks trials, trains them in lanes, reports, checkpoints."""

    def __init__(self, space: SearchSpace, data: Mapping[str, Any], source: str, study: Any,
                 out: Path, worker: int = 0, log: Callable[[str], None] = print,
                 progress: bool = True):
        self.space, self.data, self.source = space, dict(data), source
        self.study, self.out, self.worker, self.log = study, out, worker, log
        self.trials = (min(space.trials, grid_size(space)) if space.sampler == "grid"
                       else space.trials)
        self.groups: dict[tuple, Group] = {}
        self.pending: dict[tuple, list[tuple[Any, dict]]] = {}
        self.reported: dict[int, frozenset[int]] = {}
        self.phases = Phases("compile", "start lanes", "train", "evaluate", "storage",
                             "checkpoint")
        self.checkpoint = out / "workers" / f"{worker}.msgpack"
        # what a worker's checkpoint must agree with (the study's size may change between
        # runs: more trials continue it)
        fixed = space.to_dict()
        fixed["sweep"].pop("trials")
        self.space_hash = hashlib.sha256(json.dumps(
            [fixed, thaw(self.data)], sort_keys=True, default=str).encode()).hexdigest()
        self.bar = None
        if progress:
            from tqdm.auto import tqdm
            self.bar = tqdm(total=self.trials, unit="trial", desc=f"sweep {study.study_name}",
                            dynamic_ncols=True)

    # ------------------------------------------------------------------ trials
    def _left(self) -> int:
        return self.trials - len(counted(self.study.get_trials(deepcopy=False)))

    def ask(self) -> tuple[Any, dict] | None:
        """A new trial and its values, or None when the study has all its trials."""
        optuna = _optuna()
        with self.phases.timing("storage"):
            if self._left() <= 0:
                return None
            trial = self.study.ask()
            values = suggest_values(trial, self.space)
            trial.set_user_attr("worker", self.worker)
            trial.set_user_attr("seeds", self.space.seeds)
            before = [t for t in counted(self.study.get_trials(deepcopy=False))
                      if t.number < trial.number]
            if len(before) >= self.trials:  # another process took the last place meanwhile
                trial.set_user_attr("surplus", True)
                tell(self.study, trial, state=optuna.trial.TrialState.FAIL)
                return None
            return trial, values

    def group(self, key: tuple) -> Group:
        if key not in self.groups:
            program = {k: thaw(v) for k, v in key}
            self.groups[key] = Group(self.data, program, self.space, self.space.lanes,
                                     self.source)
        return self.groups[key]

    def check_lane_keys(self) -> None:
        """Every ``term_weights``/``hide`` parameter names a term or feature of this
        configuration (before anything trains)."""
        group = self.group(group_key({}))
        probe = {p.key: (True if p.key.startswith("hide.") else 1.0)
                 for p in self.space.params if p.key.startswith(("term_weights.", "hide."))}
        if probe:
            group.lane_inputs([probe])

    # ------------------------------------------------------------------ run
    def run(self) -> None:
        """Work until the study has all its trials and this worker's are finished."""
        self.check_lane_keys()
        resumed = self._resume()
        while True:
            if resumed is not None:
                key, runners, slots = resumed
                resumed = None
            else:
                key = max(self.pending, key=lambda k: len(self.pending[k]), default=None)
                if key is not None and not self.pending[key]:
                    key = None
                if key is None:
                    asked = self.ask()
                    if asked is None:
                        break
                    key = group_key(split_values(asked[1])[1])
                    self.pending.setdefault(key, []).append(asked)
                runners, slots = None, None
            self._run_group(key, runners, slots)
        self._progress()
        if self.bar is not None:
            self.bar.close()

    def _next_for(self, key: tuple) -> tuple[Any, dict] | None:
        """The next trial for group ``key``: a waiting one, else newly asked ones until one
        belongs to it (others wait for their group, at most ``lanes`` of them)."""
        if self.pending.get(key):
            return self.pending[key].pop(0)
        waiting = sum(len(v) for v in self.pending.values())
        while waiting < self.space.lanes:
            asked = self.ask()
            if asked is None:
                return None
            other = group_key(split_values(asked[1])[1])
            if other == key:
                return asked
            self.pending.setdefault(other, []).append(asked)
            waiting += 1
        return None

    def _run_group(self, key: tuple, runners: Any = None,
                   slots: list[Running | None] | None = None) -> None:
        """Train group ``key``'s trials in its lanes until none is left to run
        (:func:`train.run.loop.train_in_calls`): after each call every trial is evaluated and
        reported; finished and pruned trials' lanes take the next trials."""
        group = self.group(key)
        if runners is None or slots is None:
            with self.phases.timing("start lanes"):
                runners = group.start()
            slots = [None] * (self.space.lanes // self.space.seeds)
        runners = self._fill(group, key, runners, slots)
        if not any(slots):
            return

        def between(call: Call) -> None:
            with self.phases.timing("evaluate"):
                scores = group.score(call.runner)
            with self.phases.timing("storage"):
                self._report(group, slots, scores)
            call.runner = self._fill(group, key, call.runner, slots)
            with self.phases.timing("checkpoint"):
                self._save(key, call.runner, slots)
            self._progress()
            call.stop = not any(slots)

        train_in_calls(group.trainer, runners, group.per_chunk, None, donate=True,
                       phases=self.phases, after_call=between)

    def _report(self, group: Group, slots: list[Running | None], scores: np.ndarray) -> None:
        """Every running trial's evaluation (``scores [lanes]``) reported to the study; a
        trial that has all its evaluations is told, a pruned one stopped (its slot freed)."""
        optuna = _optuna()
        steps_per_evaluation = group.per_chunk * group.config.algorithm.steps_per_update
        for i, slot in enumerate(slots):
            if slot is None:
                continue
            slot.evaluations += 1
            value = float(np.mean(scores[list(slot.lanes)]))
            slot.scores.append(value)
            if slot.evaluations not in slot.reported:  # a trial run again reports anew
                slot.trial.report(value, slot.evaluations)
            slot.trial.set_user_attr("steps", slot.evaluations * steps_per_evaluation)
            # each seed's score at the latest evaluation (intervals over seeds)
            slot.trial.set_user_attr("seed_scores", [float(scores[j]) for j in slot.lanes])
            if slot.evaluations >= self.space.evaluations:
                if math.isfinite(value):
                    tell(self.study, slot.trial, value)
                else:
                    slot.trial.set_user_attr("error", f"objective {value}")
                    tell(self.study, slot.trial, state=optuna.trial.TrialState.FAIL)
                slots[i] = None
            elif not math.isfinite(value) or slot.trial.should_prune():
                tell(self.study, slot.trial, state=optuna.trial.TrialState.PRUNED)
                slots[i] = None

    def _fill(self, group: Group, key: tuple, runners: Any, slots: list[Running | None]
              ) -> Any:
        """``runners`` with every free slot given the group's next trial (while there is
        one); ``slots`` is updated in place."""
        seeds = self.space.seeds
        for i, slot in enumerate(slots):
            if slot is not None:
                continue
            asked = self._next_for(key)
            if asked is None:
                break
            trial, values = asked
            lanes = tuple(range(i * seeds, (i + 1) * seeds))
            trial.set_user_attr("lanes", list(lanes))
            trial.set_user_attr("program", thaw(group.program))
            with self.phases.timing("start lanes"):
                runners = group.fill(runners, lanes, values)
            slots[i] = Running(trial, values, lanes,
                               reported=self.reported.pop(trial.number, frozenset()))
        return runners

    def _progress(self) -> None:
        if self.bar is None:
            return
        trials = counted(self.study.get_trials(deepcopy=False))
        finished = [t for t in trials if t.state.is_finished()]
        complete = [t for t in finished if t.value is not None]
        self.bar.n = len(finished)
        if complete:
            best = (max if self.space.objective.direction == "maximize" else min)(
                complete, key=lambda t: t.value)
            self.bar.set_postfix_str(f"best {best.value:.3f} (trial {best.number}), "
                                     f"{len(trials) - len(finished)} running")
        self.bar.refresh()

    # ------------------------------------------------------------------ checkpoints
    def _save(self, key: tuple, runners: Any, slots: list[Running | None]) -> None:
        from flax import serialization

        state = {"format": CHECKPOINT_FORMAT, "space": self.space_hash,
                 "program": [[k, thaw(v)] for k, v in key],
                 "slots": [None if s is None else {"trial": s.number, "evaluations":
                                                   s.evaluations, "scores": s.scores}
                           for s in slots],
                 "pending": [t.number for waiting in self.pending.values()
                             for t, _ in waiting]}
        payload = {"state": json.dumps(state),
                   "runners": serialization.to_state_dict(jax.device_get(runners))}
        self.checkpoint.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(self.checkpoint, serialization.msgpack_serialize(payload))

    def _resume(self) -> tuple[tuple, Any, list] | None:
        """This worker's lanes from its checkpoint, if it has one: the running trials go on
        from their last evaluation, its waiting trials wait again; trials the storage holds
        as finished are not run again. Trials this worker had asked and the checkpoint does
        not hold (killed before writing it) are run again from the start."""
        optuna = _optuna()
        resumed = self._resume_lanes() if self.checkpoint.is_file() else None
        held = {s.number for s in (resumed[2] if resumed else []) if s is not None}
        held |= {t.number for waiting in self.pending.values() for t, _ in waiting}
        lost = [t for t in self.study.get_trials(deepcopy=False)
                if t.state == optuna.trial.TrialState.RUNNING and t.number not in held
                and t.user_attrs.get("worker") == self.worker]
        for frozen in lost:
            self.reported[frozen.number] = frozenset(frozen.intermediate_values)
            values = trial_values(self.space, frozen.params)
            self.pending.setdefault(group_key(split_values(values)[1]), []).append(
                (optuna.trial.Trial(self.study, frozen._trial_id), values))
        if lost:
            self.log(f"worker {self.worker}: trial(s) {[t.number for t in lost]} were running "
                     "here with no checkpoint of their lanes; they run again from the start")
        return resumed

    def _resume_lanes(self) -> tuple[tuple, Any, list]:
        from flax import serialization

        optuna = _optuna()
        try:
            payload = serialization.msgpack_restore(self.checkpoint.read_bytes())
            state = json.loads(payload["state"])
        except Exception as err:  # noqa: BLE001 (any unreadable file: say which)
            raise ConfigError(f"{self.checkpoint}: not a readable sweep checkpoint ({err}); "
                              "delete it to start this worker's lanes afresh") from None
        if state.get("format") != CHECKPOINT_FORMAT or state.get("space") != self.space_hash:
            raise ConfigError(f"{self.checkpoint}: written for another space or config (or "
                              "by another version); use another --out or --study, or delete "
                              "the file")
        by_number = {t.number: t for t in self.study.get_trials(deepcopy=False)}
        running = optuna.trial.TrialState.RUNNING

        def live(number: int) -> Any:
            frozen = by_number.get(number)
            if frozen is None or frozen.state != running:
                return None
            return (optuna.trial.Trial(self.study, frozen._trial_id),
                    trial_values(self.space, frozen.params))

        for number in state["pending"]:
            got = live(number)
            if got is not None:
                self.pending.setdefault(group_key(split_values(got[1])[1]), []).append(got)
        key = tuple((k, freeze(v)) for k, v in state["program"])
        group = self.group(key)
        runners = checkpoint.state_from_raw(group.template(), payload["runners"])
        runners = jax.tree.map(jnp.asarray, runners)
        seeds = self.space.seeds
        slots: list[Running | None] = []
        resumed = 0
        for i, entry in enumerate(state["slots"]):
            got = None if entry is None else live(entry["trial"])
            if got is None:
                slots.append(None)
                continue
            slots.append(Running(got[0], got[1], tuple(range(i * seeds, (i + 1) * seeds)),
                                 entry["evaluations"], list(entry["scores"])))
            resumed += 1
        self.log(f"resumed worker {self.worker} from {self.checkpoint}: {resumed} running "
                 f"trial(s) continue from their last evaluation, "
                 f"{sum(len(v) for v in self.pending.values())} waiting")
        return key, runners, slots


# ---------------------------------------------------------------------- outputs
def trial_rows(study: Any, space: SearchSpace) -> tuple[list[str], list[list[Any]]]:
    """The trials table: number, state, objective, each parameter, steps, seconds."""
    header = ["trial", "state", space.objective.metric, *space.keys, "env steps", "seconds"]
    rows = []
    for t in counted(study.get_trials(deepcopy=False)):
        seconds = ((t.datetime_complete - t.datetime_start).total_seconds()
                   if t.datetime_complete and t.datetime_start else None)
        rows.append([t.number, t.state.name.lower(),
                     None if t.value is None else round(float(t.value), 4),
                     *[_short(trial_values(space, t.params).get(k)) for k in space.keys],
                     t.user_attrs.get("steps"),
                     None if seconds is None else round(seconds, 1)])
    return header, rows


def best_trial(study: Any) -> Any | None:
    complete = [t for t in counted(study.get_trials(deepcopy=False))
                if t.state.name == "COMPLETE"]
    if not complete:
        return None
    pick = max if study.direction.name == "MAXIMIZE" else min
    return pick(complete, key=lambda t: t.value)


def best_config(data: Mapping[str, Any], space: SearchSpace, trial: Any, steps: int | None
                ) -> dict[str, Any]:
    """The config data of a trial (its values on the sweep's config), trained for the steps
    the trial trained."""
    out = with_values(data, trial_values(space, trial.params))
    if steps:
        out["algorithm"] = {**out.get("algorithm", {}), "total_steps": int(steps)}
    return out


def write_outputs(study: Any, space: SearchSpace, data: Mapping[str, Any], source: str,
                  out: Path, seconds: Mapping[str, float], log: Callable[[str], None] = print
                  ) -> dict[str, Any]:
    """The trials table, best config, plots and ``sweep.json``; returns the JSON document."""
    out.mkdir(parents=True, exist_ok=True)
    header, rows = trial_rows(study, space)
    buffer = io.StringIO()
    csv.writer(buffer).writerows([header, *rows])
    write_atomic(out / "trials.csv", buffer.getvalue())
    shown = [["" if v is None else v for v in row] for row in rows]
    write_atomic(out / "trials.md", "\n".join(markdown_table(header, shown)) + "\n")
    best = best_trial(study)
    config = None
    if best is not None:
        config = config_from_dict(best_config(data, space, best, best.user_attrs.get("steps")),
                                  f"best trial {best.number}")
        write_atomic(out / "best.yaml", yaml.safe_dump(config.to_dict(), sort_keys=False))
        tuned = {k: v for k, v in best_config({}, space, best, None).items() if v}
        settings = {f"{section}.{field}": value for section, fields in tuned.items()
                    for field, value in fields.items()}
        write_atomic(out / "best_variants.yaml", yaml.safe_dump(
            {"baseline": {}, f"tuned (trial {best.number})": {"set": settings}},
            sort_keys=False))
    plots = _plots(study, out, log)
    trials = []
    for t in study.get_trials(deepcopy=False):
        trials.append({"number": t.number, "state": t.state.name.lower(),
                       "value": t.value, "params": thaw(t.params),
                       "intermediate": {str(k): v for k, v in t.intermediate_values.items()},
                       "user_attrs": thaw(t.user_attrs),
                       "started": t.datetime_start.isoformat() if t.datetime_start else None,
                       "finished": (t.datetime_complete.isoformat()
                                    if t.datetime_complete else None)})
    document = {
        "schema_version": SWEEP,
        "provenance": provenance(config_from_dict(data, source).to_dict(),
                                 seeds={"training": [int(data.get("seed", 0)) + i
                                                     for i in range(space.seeds)],
                                        "validation": [VALIDATION_SEED]},
                                 episodes_per_cell=space.objective.episodes,
                                 seconds=dict(seconds)),
        "study": study.study_name, "space": space.to_dict(),
        "direction": study.direction.name.lower(),
        "best": None if best is None else {"number": best.number, "value": best.value,
                                           "params": thaw(best.params)},
        "trials": trials, "plots": plots,
    }
    write_atomic(out / "sweep.json", json.dumps(document, indent=1, default=str) + "\n")
    return document


def _plots(study: Any, out: Path, log: Callable[[str], None]) -> list[str]:
    """Optuna's history and parameter-importance plots as PNG (a plot that cannot be drawn
    yet, e.g. importances before two trials finished, is skipped with the reason)."""
    import matplotlib

    matplotlib.use("Agg")
    import warnings

    import matplotlib.pyplot as plt
    import optuna
    from optuna.visualization import matplotlib as plots

    written = []
    for name, draw in (("history.png", plots.plot_optimization_history),
                       ("importance.png", plots.plot_param_importances)):
        try:
            with warnings.catch_warnings():
                # "experimental" (the matplotlib backend's label since Optuna 2.2), and
                # PED-ANOVA's note when too few trials differ for importances to differ
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                warnings.filterwarnings("ignore", "Target and region quantiles")
                axes = draw(study)
            figure = axes.figure if hasattr(axes, "figure") else axes.flat[0].figure
            figure.set_size_inches(8, 5)
            figure.tight_layout()
            figure.savefig(out / name, dpi=100)
            plt.close(figure)
            written.append(name)
        except (ValueError, RuntimeError, ZeroDivisionError) as err:
            log(f"{name}: not drawn ({err})")
    return written


def print_summary(document: Mapping[str, Any], space: SearchSpace, out: Path,
                  storage: str, log: Callable[[str], None] = print, top: int = 10) -> None:
    trials = [t for t in document["trials"] if not t["user_attrs"].get("surplus")]
    states: dict[str, int] = {}
    for t in trials:
        states[t["state"]] = states.get(t["state"], 0) + 1
    log(f"\nstudy {document['study']}: {len(trials)} trials ("
        + ", ".join(f"{n} {s}" for s, n in sorted(states.items())) + ")")
    done = [t for t in trials if t["state"] == "complete"]
    done.sort(key=lambda t: t["value"], reverse=document["direction"] == "maximize")
    if done:
        rows = [[t["number"], f"{t['value']:.3f}",
                 *[_short(t["params"].get(k)) for k in space.keys]] for t in done[:top]]
        log("\n".join(markdown_table(["trial", space.objective.metric, *space.keys], rows)))
        log(f"best: trial {document['best']['number']} -> {out / 'best.yaml'} "
            f"(python -m train --config {out / 'best.yaml'})")
    log(f"wrote {out / 'trials.md'}, {out / 'sweep.json'}"
        + "".join(f", {out / p}" for p in document["plots"])
        + f"\nbrowse the study: optuna-dashboard {storage}")


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return "" if value is None else str(value)


def redacted(url: str) -> str:
    """A storage URL without its password."""
    head, sep, tail = url.partition("://")
    if "@" in tail and ":" in tail.split("@", 1)[0]:
        user = tail.split("@", 1)[0].split(":", 1)[0]
        return f"{head}{sep}{user}:***@{tail.split('@', 1)[1]}"
    return url


# ---------------------------------------------------------------------- command line
def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m train.sweep",
        description="Tune a training config with Optuna: trials train as lanes of one "
                    "compiled call, pruned on validation evaluations.")
    parser.add_argument("--config", required=True, help="training config (YAML)")
    parser.add_argument("--space", required=True,
                        help="search space file (train/configs/sweeps/*.yaml)")
    parser.add_argument("--trials", type=int, default=None,
                        help="trials in the study (default: the space's sweep.trials)")
    parser.add_argument("--lanes", type=int, default=None,
                        help="lanes per compiled call (default: the space's sweep.lanes; 1 "
                             "with trial.seeds 1 runs one trial at a time)")
    parser.add_argument("--pruner", choices=PRUNERS, default=None,
                        help="the pruner (default: the space's sweep.pruner)")
    parser.add_argument("--storage", default=None,
                        help="SQLAlchemy URL (default: sqlite:///<out>/study.db); "
                             "postgresql://user@host/db shares a study between processes")
    parser.add_argument("--study", default=None, help="study name (default: the space file's "
                                                      "name)")
    parser.add_argument("--out", default=None, help="run folder (default: runs/sweep/<study>)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                        help="override one config key for every trial (repeatable)")
    parser.add_argument("--worker", type=int, default=0,
                        help="this process's number among those sharing the study (its "
                             "sampler seed and checkpoint; restart a killed worker with the "
                             "same number)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_cache_arguments(parser)
    args = parser.parse_args(argv)
    try:
        cache_from_arguments(args)
        space = load_space(args.space)
        changes = {}
        if args.trials is not None:
            changes["trials"] = args.trials
        if args.lanes is not None:
            changes["lanes"] = args.lanes
        for name, value in changes.items():
            if value < 1:
                raise ConfigError(f"--{name} must be at least 1, got {value}")
        if args.pruner is not None:
            changes["pruner"] = args.pruner
        space = space.replace(**changes) if changes else space
        if args.worker < 0:
            raise ConfigError(f"--worker must be >= 0, got {args.worker}")
        base = load_config(args.config, args.set)  # validates the config and --set
        data = with_values(base.to_dict(), dict(space.settings))
        source = f"{args.config} with the space's set" if space.settings else args.config
        config_from_dict(data, source)
        name = args.study or Path(args.space).stem
        out = Path(args.out or f"runs/sweep/{name}").resolve()
        out.mkdir(parents=True, exist_ok=True)
        storage = args.storage or f"sqlite:///{out / 'study.db'}"
        _quiet_optuna()
        study = open_study(space, storage, name, args.worker)
        print(f"sweep {name}: {space.trials} trials over {len(space.params)} parameters ("
              f"{sum(is_lane_key(k) for k in space.keys)} lane values), {space.lanes} lanes "
              f"of {space.seeds} seed(s) per trial, {space.evaluations} evaluations per trial, "
              f"{space.sampler} sampler, {space.pruner} pruner; storage {redacted(storage)}; "
              f"worker {args.worker}")
        sweep = Sweep(space, data, source, study, out, args.worker,
                      progress=not args.no_progress)
        sweep.run()
        with sweep.phases.timing("write"):
            document = write_outputs(study, space, data, source, out,
                                     {**sweep.phases.seconds, "total": sweep.phases.elapsed()})
        print_summary(document, space, out, redacted(storage))
        print(sweep.phases.line())
    except (ConfigError, ValueError) as err:
        raise SystemExit(f"sweep: {err}") from err


def _quiet_optuna() -> None:
    optuna = _optuna()
    optuna.logging.set_verbosity(optuna.logging.WARNING)


if __name__ == "__main__":
    main()
