"""train.sweep: space files are validated, a lane trains as the config with its values would,
trials run as lanes and groups, pruned lanes are refilled, outputs follow the results schema,
a killed sweep resumes without losing a finished trial, and two processes share a PostgreSQL
study without running a trial twice."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest
import yaml
from postgres import postgres_server
from provenance_checks import check_document

from sgjax.terms.base import ConfigError
from train.algorithm.config import config_from_dict, load_config
from train.algorithm.env_batch import observation_mask
from train.algorithm.lane_settings import LANE_SETTINGS
from train.algorithm.trainer import Trainer
from train.run.search_space import is_lane_key, load_space
from train.sweep import Sweep, open_study, with_values, write_outputs

optuna = pytest.importorskip("optuna", reason="train.sweep needs optuna (the dev extra)")

ROOT = Path(__file__).resolve().parents[2]
TINY = {
    "env": {"scenarios": ["open"], "curriculum": [[0, 2]], "observations": "default",
            "time_limit": 10.0},
    "algorithm": {"num_envs": 8, "num_steps": 8, "total_steps": 8 * 8 * 2, "update_epochs": 1,
                  "num_minibatches": 2},
    "network": {"hidden": [16]},
    "evaluation": {"num_agents": [2], "episodes": 4},
}
SPACE = {
    "objective": {"metric": "team_success", "num_agents": [2], "episodes": 4},
    "trial": {"seeds": 1, "evaluations": 2},
    "sweep": {"trials": 5, "lanes": 2, "sampler": "tpe", "pruner": "none"},
    "params": {
        "algorithm.learning_rate": {"type": "float", "low": 1e-4, "high": 1e-3, "log": True},
        "algorithm.gamma": {"type": "float", "low": 0.9, "high": 0.99},
        "term_weights.collision": {"type": "float", "low": 0.5, "high": 2.0},
        "hide.goal_distance": {"choices": [False, True]},
        "network.hidden": {"choices": [[16], [24]]},
    },
}


def write(path: Path, data: dict) -> Path:
    path.write_text(yaml.safe_dump(data))
    return path


# ---------------------------------------------------------------------- space files
@pytest.mark.parametrize("change, message", [
    ({"objectiv": {}}, "did you mean 'objective'"),
    ({"objective": {"metric": "team_sucess"}}, "did you mean 'team_success'"),
    ({"params": {"algorithm.learning_rat": {"type": "float", "low": 1, "high": 2}}},
     "did you mean 'learning_rate'"),
    ({"params": {"algorithm.gamma": {"type": "float", "low": 0.0, "high": 1.0, "log": True}}},
     "log scale needs low > 0"),
    ({"params": {"algorithm.gamma": {"low": 0.9, "high": 0.99}}}, "give type"),
    ({"params": {"algorithm.gamma": {"type": "float", "low": 0.99, "high": 0.9}}},
     "is above high"),
    ({"params": {"hide.velocity": {"choices": [0, 1]}}}, "true or false"),
    ({"params": {"seed.x": {"choices": [1, 2]}}}, "seeds are the sweep's"),
    ({"params": {"network.kind": {"choices": ["mlp", "gru"]},
                 "network.recurrent_size": {"choices": [64], "when": {"network.knd": "gru"}}}},
     "did you mean 'network.kind'"),
    ({"params": {"network.kind": {"choices": ["mlp", "gru"]},
                 "network.recurrent_size": {"choices": [64], "when": {"network.kind": "lstm"}}}},
     "never takes ['lstm']"),
    ({"sweep": {"sampler": "grid"}}, "grid sampler takes unconditional choices only"),
    ({"sweep": {"lanes": 3}, "trial": {"seeds": 2}}, "multiple of trial.seeds"),
    ({"sweep": {"trials": 0}}, "sweep.trials must be an integer >= 1"),
])
def test_a_bad_space_file_is_an_error_naming_the_file_and_key(tmp_path, change, message):
    data = {**SPACE, **change}
    path = write(tmp_path / "bad.yaml", data)
    with pytest.raises(ConfigError) as err:
        load_space(path)
    assert str(path) in str(err.value) and message in str(err.value), str(err.value)


def test_lane_keys_are_the_runner_state_numbers():
    assert all(is_lane_key(f"algorithm.{name}") for name in LANE_SETTINGS)
    assert is_lane_key("term_weights.collision") and is_lane_key("hide.others.velocity")
    for key in ("algorithm.num_minibatches", "algorithm.max_grad_norm", "network.hidden",
                "env.time_limit"):
        assert not is_lane_key(key)


def test_every_shipped_space_fits_its_config():
    """Each train/configs/sweeps/<name>.yaml parses and every one of its values gives a valid
    config of train/configs/<name>.yaml (choices all, numbers at both ends)."""
    folder = ROOT / "train" / "configs" / "sweeps"
    spaces = sorted(folder.glob("*.yaml"))
    assert {p.stem for p in spaces} >= {"doorway", "hallway", "intersection", "open",
                                        "roundabout"}
    for path in spaces:
        space = load_space(path)
        name = {"paper_table6": "intersection"}.get(path.stem, path.stem)
        base = load_config(ROOT / "train" / "configs" / f"{name}.yaml").to_dict()
        data = with_values(base, dict(space.settings))
        for p in space.params:
            for value in (p.choices if p.kind == "categorical" else (p.low, p.high)):
                config_from_dict(with_values(data, {p.key: value}), f"{path} {p.key}")
        trainer = Trainer(config_from_dict(data))
        names = trainer.batch.reward_term_names()
        for key in space.keys:
            if key.startswith("term_weights."):
                assert key.partition(".")[2] in names, (path, key)
            if key.startswith("hide."):  # a feature of this config's observation
                assert observation_mask(trainer.batch.env, [key.partition(".")[2]]).min() == 0


# ---------------------------------------------------------------------- lanes
@pytest.mark.slow
def test_a_lane_trains_as_the_config_with_its_values_would():
    """Lane settings, reward-term weights and hidden features as runner-state numbers of one
    program give the run that a config holding those values gives."""
    values = {"learning_rate": 1e-3, "ent_coef": 0.03, "vf_coef": 0.7, "clip_eps": 0.3,
              "gamma": 0.95, "gae_lambda": 0.9, "team_reward": 0.5}
    own = config_from_dict(with_values(TINY, {
        **{f"algorithm.{k}": v for k, v in values.items()},
        "term_weights.collision": 2.0, "hide.goal_distance": True}))
    base = Trainer(config_from_dict(TINY), varied=tuple(LANE_SETTINGS))
    alone = Trainer(own)
    key = jax.random.PRNGKey(3)
    mask = alone.observation_mask()
    assert mask.min() == 0.0  # the goal distance is hidden
    lane = base.init(key, {"collision": 2.0}, mask, base.lane_hyper(values))
    lane, _ = jax.jit(lambda r: base.update_chunk(r, 2))(lane)
    reference, _ = jax.jit(lambda r: alone.update_chunk(r, 2))(alone.init(key))
    for a, b in zip(jax.tree.leaves(lane.params), jax.tree.leaves(reference.params),
                    strict=True):
        np.testing.assert_allclose(a, b, rtol=2e-4, atol=2e-6)
    assert not np.allclose(jax.tree.leaves(lane.params)[0],
                           jax.tree.leaves(base.init(key).params)[0])


def tiny_sweep(tmp_path: Path, **changes) -> tuple:
    """The tiny space (with ``changes``) as a sweep in a fresh SQLite study under tmp_path."""
    space = load_space(write(tmp_path / "space.yaml", SPACE))
    space = space.replace(**changes) if changes else space
    out = tmp_path / "out"
    out.mkdir()
    study = open_study(space, f"sqlite:///{out}/study.db", "tiny", 0)
    return space, Sweep(space, TINY, "tiny", study, out, progress=False, log=lambda _: None)


@pytest.mark.slow
def test_trials_run_as_lanes_and_groups_and_write_the_results(tmp_path):
    space, sweep = tiny_sweep(tmp_path)
    sweep.run()
    trials = sweep.study.get_trials()
    assert [t.state.name for t in trials] == ["COMPLETE"] * 5
    assert len({tuple(sorted(t.params.items())) for t in trials}) == 5
    assert all(sorted(t.intermediate_values) == [1, 2] for t in trials)
    programs = {str(t.user_attrs["program"]) for t in trials}
    from sgjax.evaluation.runner import _COMPILED

    def chunks(trainer):  # the trainer's compiled chunk programs (in the shared cache)
        return [k for k in _COMPILED if k[0] in set(trainer._jitted_chunks.values())]

    compiled = [g for g in sweep.groups.values() if chunks(g.trainer)]
    assert len(compiled) == len(programs) == 2  # one compiled program per network width
    assert all(len(chunks(g.trainer)) == 1 for g in compiled)
    document = write_outputs(sweep.study, space, TINY, "tiny", sweep.out, sweep.phases.seconds,
                             log=lambda _: None)
    check_document(document)
    assert document["best"]["number"] in range(5)
    for name in ("trials.md", "trials.csv", "best.yaml", "best_variants.yaml", "history.png",
                 "importance.png"):
        assert (sweep.out / name).is_file(), name
    best = load_config(sweep.out / "best.yaml")
    params = document["best"]["params"]
    assert best.algorithm.learning_rate == pytest.approx(params["algorithm.learning_rate"])
    assert best.algorithm.term_weights["collision"] == pytest.approx(
        params["term_weights.collision"])
    assert ("goal_distance" in best.algorithm.hide) == params["hide.goal_distance"]
    assert list(best.network.hidden) == yaml.safe_load(params["network.hidden"])
    variants = yaml.safe_load((sweep.out / "best_variants.yaml").read_text())
    assert set(variants) == {"baseline", f"tuned (trial {document['best']['number']})"}


def test_a_grid_sweep_runs_its_whole_grid_and_ends(tmp_path):
    """Optuna's grid sampler signals its last point with ``Study.stop()``, which raises outside
    ``Study.optimize``; the sweep ran the paper's Table 6 grid to its last trial and died there
    before writing its outputs. Every point runs once, and the sweep ends normally."""
    # The learning rate's three points; gamma at one value makes the lanes' program the one
    # test_trials_run_as_lanes_and_groups_and_write_the_results compiled for its [16] group
    # (the same lane settings and chunks: read from the compilation cache).
    data = {**SPACE, "sweep": {"trials": 3, "lanes": 2, "sampler": "grid", "pruner": "none"},
            "params": {"algorithm.learning_rate": {"choices": [1e-3, 3e-4, 1e-4]},
                       "algorithm.gamma": {"choices": [0.95]}}}
    space = load_space(write(tmp_path / "space.yaml", data))
    (tmp_path / "out").mkdir()
    study = open_study(space, f"sqlite:///{tmp_path}/out/study.db", "grid", 0)
    sweep = Sweep(space, TINY, "tiny", study, tmp_path / "out", progress=False,
                  log=lambda _: None)
    sweep.run()
    trials = study.get_trials()
    assert [t.state.name for t in trials] == ["COMPLETE"] * 3
    assert sorted(t.params["algorithm.learning_rate"] for t in trials) == [1e-4, 3e-4, 1e-3]


def test_pruned_trials_free_their_lanes_for_the_next(tmp_path):
    """A pruner that stops every trial at its first evaluation: each trial ends pruned after
    one evaluation, and the lanes go on to the next trials until the study has them all."""
    space = load_space(write(tmp_path / "space.yaml", SPACE))
    (tmp_path / "out").mkdir()
    study = optuna.create_study(storage=f"sqlite:///{tmp_path}/out/study.db",
                                direction="maximize",
                                pruner=optuna.pruners.ThresholdPruner(lower=2.0))
    sweep = Sweep(space.replace(trials=4), TINY, "tiny", study, tmp_path / "out",
                  progress=False, log=lambda _: None)
    sweep.run()
    trials = study.get_trials()
    assert [t.state.name for t in trials] == ["PRUNED"] * 4
    assert all(list(t.intermediate_values) == [1] for t in trials)


# ---------------------------------------------------------------------- processes
def sweep_command(config: Path, space: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "train.sweep", "--config", str(config), "--space",
            str(space), "--out", str(out), "--no-progress", *extra]


def finished(study) -> dict[int, float | None]:
    return {t.number: t.value for t in study.get_trials() if t.state.is_finished()}


@pytest.mark.slow
def test_a_killed_sweep_resumes_and_loses_no_finished_trial(tmp_path):
    """kill -9 while trials are in lanes; the same command again: the trials finished before
    keep their values, the running ones go on from the worker's checkpoint, and the study ends
    with the trials asked for."""
    # chunks long enough (a few tenths of a second) to be caught between two evaluations
    slower = {**TINY, "algorithm": {**TINY["algorithm"], "num_envs": 64, "num_steps": 32,
                                    "total_steps": 64 * 32 * 12}}
    config = write(tmp_path / "config.yaml", slower)
    # One network size: one group of lanes, so each run compiles one training and one
    # evaluation program (two sizes made two of each).
    data = {**SPACE, "sweep": {**SPACE["sweep"], "trials": 6},
            "trial": {"seeds": 1, "evaluations": 4}}
    data["params"] = {k: v for k, v in SPACE["params"].items() if k != "network.hidden"}
    space = write(tmp_path / "space.yaml", data)
    out = tmp_path / "out"
    command = sweep_command(config, space, out)
    first = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True)
    storage = f"sqlite:///{out}/study.db"
    deadline = time.time() + 300
    before: dict[int, float | None] = {}
    while time.time() < deadline and first.poll() is None:
        time.sleep(0.1)
        if not (out / "workers" / "0.msgpack").is_file():
            continue
        study = optuna.load_study(study_name="space", storage=storage)
        before = finished(study)
        running = [t for t in study.get_trials() if t.state.name == "RUNNING"
                   and t.intermediate_values]
        if before and running:
            break
    assert first.poll() is None, first.communicate()[0]
    assert before, "no trial finished within the time allowed"
    first.send_signal(signal.SIGKILL)
    first.wait()
    study = optuna.load_study(study_name="space", storage=storage)
    before = finished(study)
    reported = {t.number: dict(t.intermediate_values) for t in study.get_trials()
                if t.state.name == "RUNNING" and t.intermediate_values}
    result = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "resumed worker 0" in result.stdout
    study = optuna.load_study(study_name="space", storage=storage)
    after = finished(study)
    assert {n: after[n] for n in before} == before
    assert len(after) == 6 and all(t.state.name == "COMPLETE" for t in study.get_trials())
    trials = {t.number: t for t in study.get_trials()}
    assert reported  # trials that were between evaluations when killed ...
    for number, values in reported.items():  # ... went on from there: their reports stand
        assert {k: trials[number].intermediate_values[k] for k in values} == values
        assert sorted(trials[number].intermediate_values) == [1, 2, 3, 4]


@pytest.mark.slow
def test_two_processes_share_a_postgresql_study_without_running_a_trial_twice(tmp_path):
    config = write(tmp_path / "config.yaml", TINY)
    data = {**SPACE, "sweep": {**SPACE["sweep"], "trials": 6}}
    data["params"] = {k: v for k, v in SPACE["params"].items() if k != "network.hidden"}
    space = write(tmp_path / "space.yaml", data)
    with postgres_server() as url:
        runs = [subprocess.Popen(
            sweep_command(config, space, tmp_path / f"out{i}", "--storage", url, "--study",
                          "shared", "--worker", str(i)),
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"}) for i in range(2)]
        outputs = [r.communicate(timeout=600)[0] for r in runs]
        for run, output in zip(runs, outputs, strict=True):
            assert run.returncode == 0, output
        study = optuna.load_study(study_name="shared", storage=url)
        trials = [t for t in study.get_trials() if not t.user_attrs.get("surplus")]
    assert len(trials) == 6 and all(t.state.name == "COMPLETE" for t in trials)
    assert len({t.number for t in trials}) == 6
    assert len({tuple(sorted(t.params.items())) for t in trials}) == 6
    workers = [t.user_attrs["worker"] for t in trials]
    assert set(workers) == {0, 1}, workers  # both processes trained trials


def test_init_refuses_a_lane_setting_the_program_would_not_read():
    """A setting given to ``init`` that this Trainer reads from the config (not ``varied``)
    is an error naming it, not a value silently ignored; a varied one is read."""
    config = config_from_dict(TINY)
    fixed = Trainer(config)
    with pytest.raises(ConfigError, match="clip_eps = 0.05 differs from the config"):
        fixed.init(jax.random.PRNGKey(0), hyper={"clip_eps": 0.05})
    same = fixed.init(jax.random.PRNGKey(0), hyper={"clip_eps": config.algorithm.clip_eps})
    assert float(same.hyper["clip_eps"]) == np.float32(config.algorithm.clip_eps)
    varied = Trainer(config, varied=["clip_eps"]).init(jax.random.PRNGKey(0),
                                                       hyper={"clip_eps": 0.05})
    assert float(varied.hyper["clip_eps"]) == np.float32(0.05)
