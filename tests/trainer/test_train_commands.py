"""The training commands end to end: ``python -m train`` then ``sgjax evaluate`` and a resume,
``train.reproduce`` writing the paper's tables, and a sharded run agreeing with an unsharded one
(separate from tests/trainer/test_train.py so that the two files run on different workers)."""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image
from provenance_checks import check_block, check_document
from test_train import TINY

from train.algorithm.config import EVALUATION_SEED_OFFSET, config_from_dict
from train.cli import main as train_main

ROOT = Path(__file__).resolve().parents[2]

SHARDED = """
import jax, numpy as np
from train.algorithm.config import config_from_dict
from train.algorithm.trainer import Trainer, seed_keys
from train.run.sharding import device_mesh, shard_runner
assert jax.device_count() == 2, jax.devices()
config = config_from_dict({"env": {"scenarios": ["open"], "curriculum": [[0, 2]]},
    "algorithm": {"num_envs": 8, "num_steps": 4, "total_steps": 32, "update_epochs": 1,
                  "num_minibatches": 2}, "network": {"hidden": [16]}})
trainer = Trainer(config)
step = jax.jit(lambda r: trainer.update_chunk_lanes(r, 1))
runner = jax.vmap(trainer.init)(seed_keys(config))
plain, _ = step(runner)
sharded_in = shard_runner(runner, device_mesh(), trainer.num_envs)
assert len(sharded_in.obs.sharding.device_set) == 2
sharded, _ = step(sharded_in)
diff = max(float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
           for a, b in zip(jax.tree.leaves(plain.params), jax.tree.leaves(sharded.params)))
print("max difference", diff)
assert diff < 1e-5, diff
"""


@pytest.mark.slow
def test_sharded_and_unsharded_runs_agree_on_one_step():
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=2"
    env = {**os.environ, "XLA_FLAGS": flags.strip(),
           "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(ROOT)}
    result = subprocess.run([sys.executable, "-c", SHARDED], env=env, capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "max difference" in result.stdout


@pytest.mark.slow
def test_train_command_end_to_end_then_evaluate_and_resume(tmp_path, capsys):
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump({
        # the final evaluation's settings of the next test: one compiled program for both
        **TINY, "evaluation": {"every": 64, "episodes": 4, "num_agents": [2, 3]},
        "logging": {"out": str(tmp_path / "run"), "checkpoint_every": 64,
                    "tensorboard": False, "progress": False},
        "env": {**TINY["env"], "time_limit": 10.0}}))
    train_main(["--config", str(config)])
    out = capsys.readouterr().out
    assert "trained (ippo)" in out and "only_local" in out and "team success" in out
    assert "time: compile" in out and "final evaluation" in out and "; total" in out
    run = tmp_path / "run"
    rows = (run / "progress.csv").read_text().splitlines()
    assert rows[0].startswith("steps,") and len(rows) == 4  # header + 3 updates
    with Image.open(run / "eval" / "episode.gif") as gif:
        assert gif.n_frames > 1
    with Image.open(run / "learning_curve.png") as curve:
        assert curve.format == "PNG" and curve.size[0] > 600
    assert (run / "checkpoints" / "best.msgpack").is_file()
    # the final weights are judged (evaluation.checkpoint: final), and the folder stands for them
    assert f"final evaluation of {run / 'checkpoints' / 'latest.msgpack'}" in out
    from train.run.checkpoint import resolve

    assert resolve(run) == run / "checkpoints" / "latest.msgpack"
    made = json.loads((run / "provenance.json").read_text())
    check_block(made)
    assert made["seeds"] == {"training": [0], "validation": [1234], "evaluation": [1000]}
    assert {"train", "final evaluation", "total"} <= set(made["seconds"])
    check_document(json.loads((run / "eval" / "metrics.json").read_text()))
    assert "paired over the same 4 episodes" in out
    from sgjax.command import main as sgjax_main

    sgjax_main(["evaluate", "--scenario", "open", "--policy", str(run), "--num-agents", "2",
                "--episodes", "2", "--out", str(tmp_path / "eval")])
    assert "team success" in capsys.readouterr().out
    # Resume with a larger budget: continues from update 3.
    train_main(["--config", str(config), "--resume", "--set", "algorithm.total_steps=320",
                "--set", "evaluation.baseline=null", "--set", "evaluation.gif=false"])
    out = capsys.readouterr().out
    assert "resumed from" in out and "update 3" in out
    assert len((run / "progress.csv").read_text().splitlines()) == 6


@pytest.mark.slow
def test_final_evaluation_evaluates_like_separate_calls_reports_every_seed_and_records_its_gif(
        tmp_path, capsys):
    """A run of two seeds, the second its best. (1) The final evaluation's one program (the
    best seed and only_local at every count as lanes) gives the results of one ``evaluate``
    call per policy, its GIF is the evaluated episode (the same states as a separate recording
    run of it), and the program compiles once per process. (2) It plays each seed on the same
    episodes as the best seed and the baseline (rows "trained (ippo) seed i", seed i's results
    as its own policy gives them), aggregates them over seeds and prints and tables the spread.
    One test: both properties are of the same final evaluation, which compiles and plays once
    (with the same settings as the previous test's run: one compiled program for both)."""
    import jax
    from test_train import tiny

    from sgjax.evaluation.evaluate import evaluate, policy_environment, run_episodes
    from train.algorithm.trainer import Trainer, seed_keys
    from train.cli import _checkpoint_actor, _evaluate_scenario, final_evaluation
    from train.run.checkpoint import load_checkpoint_policy, save
    from train.tables import main as tables_main

    config = tiny(num_seeds=2, env={"time_limit": 10.0},
                  evaluation={"episodes": 4, "num_agents": [2, 3]})
    trainer = Trainer(config)
    runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
    path = save(tmp_path / "best.msgpack", config, runner, {"best_seed": 1}, trainer.actor)
    summary = final_evaluation(config, tmp_path, path)
    results = summary["results"]
    seed, options = config.seed + EVALUATION_SEED_OFFSET, config.env.options
    # (1) the best seed's and only_local's rows: one evaluate call per policy (the checkpoint's
    # policy is its best seed, played alone)
    separate = (evaluate(["open"], [str(path)], [2, 3], 4, seed=seed, options=options, log=None,
                         policy_names=["trained (ippo)"])
                + evaluate(["open"], ["only_local"], [2, 3], 4, seed=seed, log=None,
                           options=options.replace(action_mode="go_stop")))
    assert [(r.policy, r.num_agents, r.as_dict()["metrics"]) for r in results
            if r.policy in ("trained (ippo)", "only_local")] == [
        (r.policy, r.num_agents, r.as_dict()["metrics"]) for r in separate]
    with Image.open(tmp_path / "eval" / "episode.gif") as gif:
        assert gif.n_frames > 1
    # The GIF's episode: episode 0 of the trained policy at 2 robots (the curriculum's count).
    mine, theirs, (states, length, params), paired, _ = _evaluate_scenario(
        config, _checkpoint_actor(path), "open", 2)
    assert mine[0].compile_seconds == 0.0  # the final evaluation compiled this program
    # The paired difference's mean is the difference of the two means (the same episodes).
    for n, (a, b) in zip((2, 3), zip(mine, theirs, strict=True), strict=True):
        assert paired[n].n == 4 and paired[n].mean == pytest.approx(
            a.metrics["team_success"].mean - b.metrics["team_success"].mean)
    env, by_count = policy_environment("open", [2, 3], None, options)
    replay = run_episodes(env, params, load_checkpoint_policy(path), jax.random.key(seed), 4,
                          record=True)
    assert length == replay.values["episode_length"][0] > 0
    for ours, theirs in zip(jax.tree.leaves(states), jax.tree.leaves(
            jax.tree.map(lambda leaf: leaf[:, 0], replay.states)), strict=True):
        np.testing.assert_array_equal(np.asarray(ours), np.asarray(theirs))
    np.testing.assert_array_equal(states.robots.x[length], replay.states.robots.x[length, 0])
    # (2) every seed's rows, on the same episodes
    assert list(dict.fromkeys(r.policy for r in results)) == [
        "trained (ippo)", "trained (ippo) seed 0", "trained (ippo) seed 1", "only_local"]
    team = {(r.policy, r.num_agents): r.metrics["team_success"].mean for r in results}
    alone = {("trained (ippo) seed 1", r.num_agents): r.metrics["team_success"].mean
             for r in separate if r.policy == "trained (ippo)"}  # the best seed, alone
    seed_0 = run_episodes(env, by_count[2], load_checkpoint_policy(path, seed_index=0),
                          jax.random.key(seed), 4)
    alone["trained (ippo) seed 0", 2] = float(np.mean(seed_0.values["team_success"]))
    for (name, n), value in alone.items():
        assert team[name, n] == pytest.approx(value), (name, n)
    for n in (2, 3):
        assert team["trained (ippo)", n] == team["trained (ippo) seed 1", n]  # the best seed
        cell = summary["seed_spread"]["open"][n]
        assert cell["seeds"] == [team["trained (ippo) seed 0", n],
                                 team["trained (ippo) seed 1", n]]
        assert cell["aggregate"]["mean"] == pytest.approx(np.mean(cell["seeds"]))
        assert len(cell["paired"]) == 2
    cell = summary["seed_spread"]["open"][2]
    document = json.loads((tmp_path / "eval" / "seed_spread.json").read_text())
    check_document(document)
    assert document["scenarios"]["open"]["2"]["team_success"] == cell["seeds"]
    table = (tmp_path / "eval" / "seed_spread.md").read_text()
    assert f"| open | 2 | {cell['seeds'][0]:.3f} {cell['seeds'][1]:.3f} |" in table
    paired = json.loads((tmp_path / "eval" / "paired.json").read_text())
    check_document(paired)
    both = paired["scenarios"]["open"]["2"]
    assert both["policy"]["mean"] == team["trained (ippo)", 2]
    assert both["baseline"]["mean"] == team["only_local", 2]
    assert both["difference"]["mean"] == pytest.approx(team["trained (ippo)", 2]
                                                       - team["only_local", 2])
    assert both["difference"]["n"] == 4
    at_3 = paired["scenarios"]["open"]["3"]["policy"]
    lines = (tmp_path / "eval" / "paired.md").read_text().splitlines()
    assert lines[0].startswith("open: team success on the same 4 episodes per robot count")
    assert lines[2:5] == ["| robots | 2 | 3 |", "|---|---|---|",
                          f"| trained (ippo) | {team['trained (ippo)', 2]:.2f} "
                          f"[{both['policy']['ci_low']:.2f}, {both['policy']['ci_high']:.2f}] | "
                          f"{team['trained (ippo)', 3]:.2f} "
                          f"[{at_3['ci_low']:.2f}, {at_3['ci_high']:.2f}] |"]
    assert lines[6].startswith(f"| trained (ippo) - only_local, paired | "
                               f"{both['difference']['mean']:+.2f} [")
    out = capsys.readouterr().out
    assert "team success of each of the 2 training seeds on the same 4 episodes" in out
    written = {name: (tmp_path / "eval" / name).read_text()
               for name in ("paired.md", "seed_spread.md")}
    for name in written:
        (tmp_path / "eval" / name).unlink()
    assert tables_main([str(tmp_path / "eval")]) == 0  # the tables again, from the JSON files
    assert {name: (tmp_path / "eval" / name).read_text() for name in written} == written
    assert "  2 robots: seeds " in out and "  3 robots: seeds " in out
    assert "above only_local" in out


@pytest.fixture(scope="module")
def whole_cell():
    """A reproduce cell of two seeds trained for 4 updates and never killed: its config,
    trainer and seed-batched runner, trained once for the two tests below (its update program
    serves test_an_ablation_group_killed_midway_resumes_from_its_last_call too, from the
    compilation cache)."""
    from test_train import tiny

    import train.reproduce as reproduce

    config = tiny(num_seeds=2, algorithm={"total_steps": 4 * 8 * 8})  # 4 updates
    assert config.algorithm.num_updates == 4
    trainer, runner, _, _ = reproduce.train_baseline(config)
    return config, trainer, runner


@pytest.mark.slow
def test_a_reproduce_cell_killed_midway_resumes_from_its_last_call(tmp_path, monkeypatch,
                                                                   whole_cell):
    """A cell trains in calls, each ending in a checkpoint; killed after its first call and
    resumed, it ends with the same weights as a cell never killed; a run without resume, or a
    checkpoint of another config, does not continue from a stale file."""
    import jax
    import numpy as np
    from test_train import tiny

    import train.reproduce as reproduce
    from train.run import checkpoint

    config, _, whole = whole_cell
    partial = tmp_path / "partial" / "open-cadrl.msgpack"
    saved = checkpoint.save
    saves = []

    def killed_at_the_second_save(*args, **kwargs):
        saves.append(args[3]["updates"])
        if len(saves) == 2:
            raise KeyboardInterrupt("killed")
        return saved(*args, **kwargs)

    monkeypatch.setattr(checkpoint, "save", killed_at_the_second_save)
    with pytest.raises(KeyboardInterrupt):
        reproduce.train_baseline(config, partial)
    monkeypatch.setattr(checkpoint, "save", saved)
    assert checkpoint.read(partial)[1]["updates"] == 1
    _, resumed, _, _ = reproduce.train_baseline(config, partial, resume=True)
    for a, b in zip(jax.tree.leaves(whole.params), jax.tree.leaves(resumed.params), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert checkpoint.read(partial)[1]["updates"] == 4
    # another cell's config; its seed is an argument of the compiled programs (a learning
    # rate is baked into them: two more compiles)
    other = tiny(num_seeds=2, seed=1, algorithm={"total_steps": 4 * 8 * 8})
    with pytest.raises(ValueError,
                       match="open-cadrl.msgpack: a partly trained cell of other lanes"):
        reproduce.train_baseline(other, partial, resume=True)
    reproduce.train_baseline(other, partial)  # no resume: the stale file is not read


@pytest.mark.slow
def test_a_reproduce_cell_killed_in_its_evaluation_plays_only_the_counts_not_kept(
        tmp_path, monkeypatch, whole_cell):
    """Each robot count's evaluation is kept as it is played: killed after the first count
    and resumed, the cell plays the second alone and ends with the values of an evaluation
    never killed; weights trained again, or a run without resume, do not use the file."""
    import jax

    import train.reproduce as reproduce
    from sgjax.evaluation.trained import TrainedEvaluation

    config, trainer, runner = whole_cell  # any trained cell: the previous test's
    options, kept = config.env.options, tmp_path / "partial" / "open-cadrl.evaluation.json"
    whole = reproduce.evaluate_seeds("open", [2, 3], 3, 0, trainer, runner, options)
    played, killed = [], []
    lanes = TrainedEvaluation.lanes

    def counted(self, weights, key, n):
        played.append(n)
        if played == [2, 3] and not killed:  # the first run dies in its second count
            killed.append(n)
            raise KeyboardInterrupt("killed")
        return lanes(self, weights, key, n)

    monkeypatch.setattr(TrainedEvaluation, "lanes", counted)
    with pytest.raises(KeyboardInterrupt):
        reproduce.evaluate_seeds("open", [2, 3], 3, 0, trainer, runner, options, kept=kept)
    played.clear()
    resumed = reproduce.evaluate_seeds("open", [2, 3], 3, 0, trainer, runner, options,
                                       kept=kept, resume=True)
    assert played == [3] and json.dumps(resumed) == json.dumps(whole)
    played.clear()
    other = jax.tree.map(lambda x: x + 1 if x.dtype.kind == "f" else x, runner)
    reproduce.evaluate_seeds("open", [2, 3], 3, 0, trainer, other, options, kept=kept,
                             resume=True)  # other weights: the kept counts are not theirs
    assert played == [2, 3]
    played.clear()
    reproduce.evaluate_seeds("open", [2, 3], 3, 0, trainer, runner, options, kept=kept)
    assert played == [2, 3]  # no resume: played afresh


@pytest.mark.slow
def test_reproduce_writes_the_papers_two_tables(tmp_path, capsys):
    from train.reproduce import reproduce

    reproduce(["open"], ["cadrl", "only_local"], seeds=2, total_steps=8 * 8 * 2,
              num_envs=8, counts=[2, 3], episodes=2, table_robots=2, out=tmp_path,
              time_limit=10.0, baseline_episodes=3)
    metrics_table = (tmp_path / "metrics_table.md").read_text()
    success_table = (tmp_path / "success_table.md").read_text()
    assert "| open | cadrl |" in metrics_table and "| open | only_local |" in metrics_table
    assert "| 2A | 3A | Avg. |" in success_table
    document = json.loads((tmp_path / "results.json").read_text())
    check_document(document)
    assert document["provenance"]["seeds"] == {"training": [0, 1], "evaluation": [1000]}
    results = document["results"]
    assert len(results["open"]["cadrl"]["2"]["team_success"]) == 2  # one value per seed
    # trained policies play both ways; the tables' metrics are the profile's (sampled) play
    cell = results["open"]["cadrl"]["2"]
    assert cell["team_success_sampled"] == cell["team_success"]
    assert len(cell["team_success_greedy"]) == 2 and "team_success_greedy" not in results[
        "open"]["only_local"]["2"]
    assert "| open | cadrl | 2 |" in (tmp_path / "play_modes.md").read_text()
    # Per-episode team success of every seed, kept for the paired comparison with only_local.
    assert np.shape(results["open"]["cadrl"]["2"]["team_success_by_episode"]) == (2, 2)
    assert np.shape(results["open"]["only_local"]["3"]["team_success_by_episode"]) == (1, 3)
    # The untrained baseline's first 2 of 3 episodes are the 2 that the trained ones played.
    from train.reproduce import evaluate_seeds, only_local_options

    two = evaluate_seeds("open", [3], 2, 0, None, None,
                         only_local_options("sgjax", 10.0), "only_local")[3]
    three = results["open"]["only_local"]["3"]
    assert two["team_success_by_episode"][0] == three["team_success_by_episode"][0][:2]
    comparison = (tmp_path / "comparison_table.md").read_text()
    assert "| open | cadrl | 2 |" in comparison and "| open | cadrl | 3 |" in comparison
    assert "only_local |" not in comparison.split("|---")[1]  # untrained rows are not compared
    from train.reproduce import tables_from_results

    again = tables_from_results(tmp_path / "results.json", tmp_path / "again", table_robots=2)
    assert again["success_table.md"] == success_table  # the tables come from results.json
    assert (tmp_path / "again" / "paper_comparison.md").is_file()
    assert (tmp_path / "performance_profiles.png").is_file()
    assert "| cadrl | 2 | 4 |" in (tmp_path / "across_cells.md").read_text()  # 2 cells x 2 seeds
    marl = json.loads((tmp_path / "marl_eval.json").read_text())["sgjax"]
    assert set(marl["open_2robots"]) == {"cadrl", "only_local"}
    # --resume keeps the finished cells and runs only the missing one (a classical controller,
    # an extra row); other settings refuse.
    kept = dict(results["open"])
    run = dict(seeds=2, total_steps=8 * 8 * 2, num_envs=8, counts=[2, 3], episodes=2,
               table_robots=2, out=tmp_path, time_limit=10.0, resume=True,
               baseline_episodes=3)
    reproduce(["open"], ["cadrl", "only_local", "dwa"], **run)
    assert "kept from" in capsys.readouterr().out
    document = json.loads((tmp_path / "results.json").read_text())
    assert list(document["results"]["open"]) == ["cadrl", "only_local", "dwa"]
    assert {b: document["results"]["open"][b] for b in kept} == kept
    assert document["runs"] == 2 and "open/dwa" in document["cell_seconds"]
    assert len(document["earlier_provenance"]) == 1  # the first run's block is kept
    assert "| open | dwa |" in (tmp_path / "metrics_table.md").read_text()
    marl = json.loads((tmp_path / "marl_eval.json").read_text())["sgjax"]
    assert set(marl["open_2robots"]) == {"cadrl", "only_local", "dwa"}
    with pytest.raises(ValueError, match="results.json: ran with episodes = 2"):
        reproduce(["open"], ["cadrl"], **{**run, "episodes": 3})
    with pytest.raises(ValueError, match="baseline-episodes .1. must be at least"):
        reproduce(["open"], ["cadrl"], **{**run, "baseline_episodes": 1})


@pytest.mark.slow
def test_ablation_command_prints_the_table(tmp_path, capsys):
    from sgjax.terms.base import ConfigError
    from train.ablation import load_variants
    from train.ablation import main as ablation_main

    variants = tmp_path / "variants.yaml"
    variants.write_text("baseline: {}\nno collision penalty: {rewards_off: [collision]}\n"
                        "no headings: {hide: [pose.heading, others.heading]}\n"
                        "team reward: {set: {algorithm.team_reward: 1.0}}\n")
    ablation_main(["--config", str(ROOT / "train/configs/ablation.yaml"),
                   "--set", "algorithm.total_steps=64", "--set", "algorithm.num_envs=8",
                   "--set", "algorithm.num_steps=8", "--set", "env.time_limit=3",
                   "--set", "env.scenarios=[open]", "--variants", str(variants),
                   "--seeds", "2", "--lanes-per-run", "4", "--episodes", "2",
                   "--robots", "2", "3", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert "| no headings |" in out and "Seeds beating the baseline" in out
    assert "Paired vs baseline (points)" in out and "P(improvement)" in out
    assert "with 2 robots" in out and "with 3 robots" in out  # a table per count
    assert "network mlp)" in out and out.count("trained and evaluated") == 2  # set: own group
    saved = json.loads((tmp_path / "out" / "ablation.json").read_text())
    assert {k: len(v) for k, v in saved["team_success"].items()} == {
        "baseline": 2, "no collision penalty": 2, "no headings": 2, "team reward": 2}
    assert set(saved["team_success_by_robots"]) == {"2", "3"}
    assert saved["variants"]["team reward"]["settings"] == [["algorithm.team_reward", 1.0]]
    paired = saved["paired"]["2"]["no headings"]
    values, base = saved["team_success_by_robots"]["2"]["no headings"], saved["team_success"][
        "baseline"]
    assert paired["difference"]["mean"] == pytest.approx(np.mean(values) - np.mean(base))
    assert 0.0 <= paired["probability_of_improvement"] <= 1.0 and "baseline" not in saved[
        "paired"]["2"]
    assert "compile and train" in saved["seconds"]
    check_document(saved)
    variants.write_text("baseline: {}\nwrong: {set: {team_reward: 1.0}}\n")
    with pytest.raises(ConfigError, match="wrong.set: expected a mapping of section.key"):
        load_variants(variants)
    variants.write_text("baseline: {}\nwrong: {set: {algorithm.team_rewards: 1.0}}\n")
    with pytest.raises(SystemExit, match="team_rewards"):
        ablation_main(["--config", str(ROOT / "train/configs/ablation.yaml"),
                       "--variants", str(variants), "--set", "algorithm.total_steps=64"])


@pytest.mark.slow
def test_a_killed_ablation_resumes_its_finished_groups(tmp_path, monkeypatch, capsys):
    """The ablation keeps each finished group of variants in ablation.partial.json; a run
    killed in its second group, resumed with --resume, trains only that group and writes the
    same first-group scores; a partial file of other arguments is refused by name."""
    import train.ablation as ablation

    variants = tmp_path / "variants.yaml"
    variants.write_text("baseline: {}\nteam reward: {set: {algorithm.team_reward: 1.0}}\n")
    out = tmp_path / "out"
    args = ["--config", str(ROOT / "train/configs/ablation.yaml"),
            "--set", "algorithm.total_steps=64", "--set", "algorithm.num_envs=8",
            "--set", "algorithm.num_steps=8", "--set", "env.time_limit=3",
            "--set", "env.scenarios=[open]", "--variants", str(variants),
            "--seeds", "2", "--episodes", "2", "--out", str(out)]
    trained = ablation.train_variants
    calls = []

    def killed_in_the_second_group(trainer, group, *rest, **kwargs):
        calls.append(list(group))
        if len(calls) == 2:
            raise KeyboardInterrupt("killed")
        return trained(trainer, group, *rest, **kwargs)

    monkeypatch.setattr(ablation, "train_variants", killed_in_the_second_group)
    with pytest.raises(KeyboardInterrupt):
        ablation.main(args)
    partial = json.loads((out / ablation.PARTIAL).read_text())
    assert list(partial["groups"]) == ["baseline"]
    first = partial["groups"]["baseline"]["scores"]["4"]["baseline"]
    assert not (out / "ablation.json").exists()

    calls.clear()
    ablation.main([*args, "--resume"])
    assert calls == [["team reward"]]  # the finished group was not trained again
    saved = json.loads((out / "ablation.json").read_text())
    assert saved["team_success"]["baseline"] == first and len(saved["team_success"]) == 2
    assert set(saved["groups"]) == {"baseline", "team reward"}  # each with where it trained
    assert all(len(g["git"]["commit"]) == 40 and g["cpu"] for g in saved["groups"].values())
    assert not (out / ablation.PARTIAL).exists()
    assert "group 1 of 2 (baseline): kept from the partial run" in capsys.readouterr().out

    (out / ablation.PARTIAL).write_text(json.dumps(partial))
    with pytest.raises(SystemExit, match="ablation.partial.json: written by a run with another"):
        ablation.main([*args[:-2], "--seeds", "3", "--out", str(out), "--resume"])
    with pytest.raises(SystemExit, match="ablation.partial.json: written by a run with another"):
        ablation.main([*args, "--variants-per-group", "1", "--resume"])  # grouped otherwise
    (out / ablation.PARTIAL).write_text("{not json")
    with pytest.raises(SystemExit, match="ablation.partial.json: not a partial ablation result"):
        ablation.main([*args, "--resume"])


def test_variants_per_group_cuts_each_network_and_settings_set_in_order():
    from train.ablation import Variant, main, variant_groups

    gru = Variant(network=(("kind", "gru"),))
    variants = {"baseline": Variant(), "a": Variant(rewards_off=("collision",)),
                "memory": gru, "b": Variant(hide=("velocity",)), "c": Variant(hide=("goal",))}
    names = lambda groups: [list(group) for group in groups]  # noqa: E731
    assert names(variant_groups(variants)) == [["baseline", "a", "b", "c"], ["memory"]]
    assert names(variant_groups(variants, 3)) == [["baseline", "a", "b"], ["c"], ["memory"]]
    assert names(variant_groups(variants, 1)) == [["baseline"], ["a"], ["b"], ["c"],
                                                  ["memory"]]
    with pytest.raises(ValueError, match="variants per group must be at least 1, got 0"):
        variant_groups(variants, 0)
    with pytest.raises(SystemExit, match="--variants-per-group must be at least 1"):
        main(["--config", str(ROOT / "train/configs/ablation.yaml"), "--variants-per-group",
              "0"])


@pytest.mark.slow
def test_an_ablation_group_killed_midway_resumes_from_its_last_call(tmp_path, monkeypatch):
    """A group's lanes train in calls, each ending in a checkpoint of every lane call so far;
    killed in its second lane call and resumed, the group ends with the weights and logs of a
    group never killed; a checkpoint of other lanes is refused by name, and a run without
    resume does not read a stale file."""
    import jax
    import numpy as np
    from test_train import tiny

    import train.ablation as ablation
    from train.algorithm.trainer import Trainer
    from train.run import checkpoint

    monkeypatch.setattr(ablation, "SAVES_PER_RUN", 4)  # one update per call
    # two seeds, two lanes a call: the update program of the two-seed reproduce cell above
    # (whole_cell), read from the compilation cache; one lane a call compiles its own
    trainer = Trainer(tiny(algorithm={"total_steps": 4 * 8 * 8}))  # 4 updates
    variants = {"baseline": ablation.Variant(),
                "no collision": ablation.Variant(rewards_off=("collision",))}
    whole, whole_logs, labels = ablation.train_variants(trainer, variants, 2, lanes_per_run=2)
    assert labels == [("baseline", 0), ("baseline", 1), ("no collision", 0),
                      ("no collision", 1)]
    partial = tmp_path / "ablation.partial" / "group-1.msgpack"
    saved = checkpoint.save
    saves = []

    def killed_at_the_sixth_save(*args, **kwargs):
        saves.append((len(args[2]), args[3]["updates"]))
        if len(saves) == 6:
            raise KeyboardInterrupt("killed")
        return saved(*args, **kwargs)

    monkeypatch.setattr(checkpoint, "save", killed_at_the_sixth_save)
    with pytest.raises(KeyboardInterrupt):
        ablation.train_variants(trainer, variants, 2, lanes_per_run=2, partial=partial)
    assert saves[:5] == [(1, 1), (1, 2), (1, 3), (1, 4), (2, 1)]
    assert checkpoint.read(partial)[1]["updates"] == 1  # the second lane call's first update

    def recorded(*args, **kwargs):
        saves.append((len(args[2]), args[3]["updates"]))
        return saved(*args, **kwargs)

    saves.clear()
    monkeypatch.setattr(checkpoint, "save", recorded)
    resumed, logs, _ = ablation.train_variants(trainer, variants, 2, lanes_per_run=2,
                                               partial=partial, resume=True)
    assert saves == [(2, 2), (2, 3), (2, 4)]  # only the updates not yet done
    monkeypatch.setattr(checkpoint, "save", saved)
    for a, b in zip(jax.tree.leaves((whole.params, whole_logs)),
                    jax.tree.leaves((resumed.params, logs)), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert logs["steps"].shape == (4, 4)
    with pytest.raises(ValueError, match="group-1.msgpack: a partly trained group of other"):
        ablation.train_variants(trainer, variants, 2, lanes_per_run=4, partial=partial,
                                resume=True)
    ablation.train_variants(trainer, {"baseline": ablation.Variant()}, 2, partial=partial)
    assert checkpoint.read(partial)[1]["labels"] == [["baseline", 0], ["baseline", 1]]


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _run_two_processes(command: list[str], cwd: Path) -> list[str]:
    """``command`` as processes 0 and 1 of a localhost jax.distributed run; their outputs."""
    command = [*command, "--coordinator", f"127.0.0.1:{_free_port()}", "--num-processes", "2"]
    env = {**os.environ, "JAX_PLATFORMS": "cpu", "PYTHONPATH": str(ROOT)}
    runs = [subprocess.Popen([*command, "--process-id", str(i)], env=env, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, cwd=cwd)
            for i in range(2)]
    try:
        outputs = [run.communicate(timeout=400)[0] for run in runs]
    finally:
        for run in runs:
            run.kill()
    for run, out in zip(runs, outputs, strict=True):
        assert run.returncode == 0, out[-3000:]
    return outputs


@pytest.mark.slow
def test_two_processes_train_two_halves_of_one_sweep_and_gather(tmp_path):
    """jax.distributed on localhost: each process trains its half of the 2 x 2 ablation lanes
    (and of reproduce's seeds); process 0 writes the whole table."""
    variants = tmp_path / "variants.yaml"
    variants.write_text("baseline: {}\nno collision penalty: {rewards_off: [collision]}\n")
    outputs = _run_two_processes(
        [sys.executable, "-m", "train.ablation", "--config",
         str(ROOT / "train/configs/ablation.yaml"), "--set", "algorithm.total_steps=64",
         "--set", "algorithm.num_envs=8", "--set", "algorithm.num_steps=8",
         "--set", "env.time_limit=3", "--set", "env.scenarios=[open]",
         "--variants", str(variants), "--seeds", "2", "--episodes", "2",
         "--out", str(tmp_path / "ablation")], tmp_path)
    assert "process 0 of 2: lanes [0, 1]" in outputs[0]
    assert "process 1 of 2: lanes [2, 3]" in outputs[1]
    assert "| no collision penalty |" in outputs[0] and "process 0 writes" in outputs[1]
    saved = json.loads((tmp_path / "ablation" / "ablation.json").read_text())["team_success"]
    assert {k: len(v) for k, v in saved.items()} == {"baseline": 2, "no collision penalty": 2}
    assert all(0.0 <= x <= 1.0 for v in saved.values() for x in v), saved

    # 2 seeds a process, as test_reproduce_writes_the_papers_two_tables trains in one: process
    # 0 finds that test's programs in the session's compilation cache (a speed-up only)
    outputs = _run_two_processes(
        [sys.executable, "-m", "train.reproduce", "--scenarios", "open", "--baselines", "cadrl",
         "--seeds", "4", "--total-steps", "128", "--num-envs", "8", "--robots", "2", "3",
         "--episodes", "2", "--table-robots", "2", "--time-limit", "10",
         "--out", str(tmp_path / "reproduce")], tmp_path)
    assert "trained 2 seeds" in outputs[0] and "trained 2 seeds" in outputs[1]
    results = json.loads((tmp_path / "reproduce" / "results.json").read_text())["results"]
    per_seed = results["open"]["cadrl"]["3"]["team_success"]
    assert len(per_seed) == 4 and all(0.0 <= x <= 1.0 for x in per_seed), per_seed


def test_a_run_folder_stands_for_the_weights_its_final_evaluation_judged(tmp_path):
    """``resolve(run)``: ``checkpoints/latest.msgpack`` (the final weights) unless the run's
    config.yaml says ``evaluation.checkpoint: best``; also from the checkpoints folder; a
    missing file or an unknown rule is an error naming it."""
    from train.run.checkpoint import resolve

    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    for name in ("latest", "best"):
        (run / "checkpoints" / f"{name}.msgpack").write_bytes(b"")
    assert resolve(run) == run / "checkpoints" / "latest.msgpack"  # no config: final
    (run / "config.yaml").write_text(yaml.safe_dump({"evaluation": {"episodes": 3}}))
    assert resolve(run) == run / "checkpoints" / "latest.msgpack"
    (run / "config.yaml").write_text(yaml.safe_dump({"evaluation": {"checkpoint": "best"}}))
    assert resolve(run) == resolve(run / "checkpoints") == run / "checkpoints" / "best.msgpack"
    (run / "checkpoints" / "best.msgpack").unlink()
    with pytest.raises(ValueError, match="no checkpoints/best.msgpack"):
        resolve(run)
    (run / "config.yaml").write_text(yaml.safe_dump({"evaluation": {"checkpoint": "last"}}))
    with pytest.raises(ValueError, match="config.yaml: evaluation.checkpoint must be one of"):
        resolve(run)
    with pytest.raises(ValueError, match="checkpoint must be one of"):
        config_from_dict({"evaluation": {"checkpoint": "last"}})


def test_lane_shares_cover_every_lane_once():
    from train.run.multiprocess import Processes, gather_lanes, lane_share

    for count in (1, 4, 7):
        for processes in (1, 2, 3):
            shares = [lane_share(count, Processes(p, processes)).tolist()
                      for p in range(processes)]
            assert sum(shares, []) == list(range(count)), (count, processes, shares)
    assert gather_lanes([0.5, 0.25], 2, Processes()).tolist() == [0.5, 0.25]
    from train.run.multiprocess import initialize

    with pytest.raises(ValueError, match="--process-id must be in"):
        initialize("127.0.0.1:1", 2, 2)
    with pytest.raises(ValueError, match="--coordinator must be HOST:PORT"):
        initialize(None, 2, 0)


@pytest.mark.parametrize("text, message", [
    ("baseline: {}\nx: {rewards_of: [collision]}\n", r"x: unknown key 'rewards_of' \(did you"),
    ("baseline: {}\nx: {hide: velocity}\n", r"x\.hide: expected a list of names"),
    ("x: {}\n", "no 'baseline' variant"),
    ("[1, 2]\n", "expected a mapping of variant names"),
])
def test_ablation_variants_file_errors_name_the_file_and_key(tmp_path, text, message):
    from sgjax.terms.base import ConfigError
    from train.ablation import load_variants

    path = tmp_path / "v.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=f"v.yaml: {message}"):
        load_variants(path)


def test_ablation_command_rejects_an_unknown_reward_term(tmp_path):
    from train.ablation import main as ablation_main

    variants = tmp_path / "v.yaml"
    variants.write_text("baseline: {}\nx: {rewards_off: [colision]}\n")
    with pytest.raises(SystemExit, match="no reward term 'colision'"):
        ablation_main(["--config", str(ROOT / "train/configs/ablation.yaml"),
                       "--variants", str(variants)])


def test_ablation_variant_sets_a_mapping_and_a_bad_one_fails_before_training(tmp_path,
                                                                              monkeypatch):
    import train.ablation as ablation
    from train.algorithm.config import load_config

    variants = tmp_path / "v.yaml"
    variants.write_text("baseline: {}\nexistence: {set: {env.rewards: "
                        "{progress: 1.0, success: 100.0, existence: 0.1}}}\n")
    config = load_config(ROOT / "train/configs/doorway.yaml", [])
    changed = ablation._variant_config(config, ablation.load_variants(variants)["existence"], 2)
    assert changed.env.options.terms.rewards == {
        "progress": 1.0, "success": 100.0, "existence": 0.1}
    assert changed.num_seeds == 2 and config.env.options.terms.rewards == "default"

    def no_training(*args, **kwargs):
        raise AssertionError("trained before every variant was checked")

    monkeypatch.setattr(ablation, "train_variants", no_training)
    variants.write_text("baseline: {}\nbad: {set: {env.rewards: {progres: 1.0}}}\n")
    with pytest.raises(SystemExit, match="progres"):
        ablation.main(["--config", str(ROOT / "train/configs/doorway.yaml"),
                       "--variants", str(variants)])


def test_the_papers_printed_averages_are_checked_against_its_rows():
    from train.reproduce import PAPER_TABLE_4, paper_average_slips

    assert paper_average_slips() == [("open", "cadrl", 7, pytest.approx(13.6))]
    assert paper_average_slips({"open": {"x": (10, 20, 30, 40, 50, 30)}}) == []
    assert paper_average_slips({"open": {"x": (1, 2, 3, 4, 5, 4)}}) == [("open", "x", 4, 3.0)]
    assert len(PAPER_TABLE_4) == 5


def test_trained_baselines_are_paired_seed_by_seed_with_cadrl():
    from train.reproduce import baseline_comparison_table

    cell = {"team_success": [0.5, 0.6, 0.7]}
    results = {"doorway": {"cadrl": {3: cell},
                           "any_order": {3: {"team_success": [0.7, 0.7, 0.9]}},
                           "only_local": {3: {"team_success": [0.4]}}},
               "open": {"any_order": {3: cell}}}  # no cadrl row: nothing to pair with
    table = baseline_comparison_table(results, [3], 3)
    rows = [line for line in table.splitlines() if line.startswith("| doorway")]
    # differences 20, 10, 20 points: 16.7 +- 4.303 * 5.77 / sqrt(3); P: 8 of 9 pairs (a tie half)
    assert rows == ["| doorway | any_order | 3 | 77 | 60 | +17 [+2, +31] | 0.89 |"], table
    assert "| open |" not in table and "only_local" not in table.split("|---")[1]


def test_table_4s_rows_share_their_episodes_and_only_local_is_paired_over_seeds_too():
    """Only Local's team success in Table 4 and in the comparison is its value on the trained
    rows' episodes (its first E); the paired interval resamples seeds as well as episodes
    (wider than the episodes-only one where seeds disagree); the across-cells table holds
    every baseline's aggregate and its probability of beating Only Local."""
    from sgjax.evaluation.statistics import paired_difference
    from train.reproduce import EPISODES_KEY, TABLE_METRICS, format_tables

    rng = np.random.default_rng(0)
    # 3 seeds that disagree: one always succeeds, two succeed on half the episodes
    trained = np.stack([np.ones(40), (rng.random(40) < 0.5), (rng.random(40) < 0.5)]).astype(float)
    alone = np.concatenate([np.zeros(40), np.ones(60)])  # 0 on the shared 40, 1 after
    others = {m: [0.0] for m, _ in TABLE_METRICS}
    results = {"doorway": {
        "cadrl": {3: {**others, "team_success": trained.mean(1).tolist(),
                      EPISODES_KEY: trained.tolist()}},
        "only_local": {3: {**others, "team_success": [alone.mean()],
                           EPISODES_KEY: [alone.tolist()]}}}}
    tables = format_tables(results, [3], 3, 3)
    assert "| doorway | only_local | 0 | 0 |" in tables["success_table.md"]  # 0, not 60
    row = next(line for line in tables["comparison_table.md"].splitlines()
               if line.startswith("| doorway | cadrl | 3 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[3] == "0"  # Only Local on the shared episodes
    mean, low, high = (float(v) for v in cells[4].replace("[", "").replace("]", "")
                       .replace(",", "").split())
    assert mean == pytest.approx(100 * trained.mean(), abs=0.5)
    episodes_only = paired_difference(trained.mean(0), alone[:40])
    assert high - low > 100 * (episodes_only.ci_high - episodes_only.ci_low)
    assert "1 paired interval: if no baseline differed" in tables["comparison_table.md"]
    assert "; 1 do." in tables["comparison_table.md"]  # +50 points is no chance
    across = tables["across_cells.md"]
    assert "| cadrl | 1 | 3 |" in across and "| only_local | 1 | 1 |" in across
    assert "P(> only_local)" in across and "P(> cadrl)" in across


def test_a_partial_cell_of_compact_true_resumes_under_auto_on_a_cpu_only():
    """A cell checkpointed when ``algorithm.compact`` defaulted to true is the same computation
    as ``auto`` on a CPU (resumed), not on a GPU (refused, as any other config)."""
    from train.algorithm.config import as_trained, config_from_dict

    auto = config_from_dict(TINY, "test").to_dict()
    old = {**auto, "algorithm": {**auto["algorithm"], "compact": True}}
    assert auto["algorithm"]["compact"] == "auto"
    assert as_trained(old, "cpu") == as_trained(auto, "cpu")
    assert as_trained(old, "gpu") != as_trained(auto, "gpu")
    masked = {**auto, "algorithm": {**auto["algorithm"], "compact": False}}
    assert as_trained(masked, "cpu") != as_trained(auto, "cpu")
