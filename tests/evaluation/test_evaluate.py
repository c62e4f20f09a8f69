"""The evaluation runner, its outputs, the baselines, policy loaders, ``sgjax render`` end to
end, and the evaluation layer's imports."""

import csv
import json
import math
import shutil
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image
from scenes import make_room, place

import sgjax
import sgjax.evaluation.runner
from sgjax import command as cli
from sgjax.command import main
from sgjax.environment.options import MakeOptions
from sgjax.evaluation import metrics, policies
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.policies import GO, STOP, load_policy, stop_when_blocked
from sgjax.evaluation.render import save_animation

ROOT = Path(__file__).resolve().parents[2]


def go_everywhere(obs, key):
    """A policy from observations, imported by the tests below as ``test_evaluate:...``."""
    return jnp.zeros(obs.shape[0], jnp.int32)


@pytest.mark.slow
def test_evaluate_command_end_to_end(tmp_path, capsys):
    main(["evaluate", "--scenario", "open", "--policy", "only_local", "stop_when_blocked",
          "--num-agents", "2", "3", "--episodes", "3", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "team success" in out and "agent-steps/s" in out  # throughput, once compiled
    document = json.loads((tmp_path / "metrics.json").read_text())
    assert document["constants"]["space_radii"] == [0.45, 1.2, 3.6]
    assert set(document["definitions"]) == set(metrics.METRICS.names())
    results = document["results"]
    assert [(r["policy"], r["num_agents"]) for r in results] == [
        ("only_local", 2), ("only_local", 3), ("stop_when_blocked", 2),
        ("stop_when_blocked", 3)]
    for r in results:  # one compilation per policy serves both robot counts
        assert (r["compile_seconds"] > 0) == (r["num_agents"] == 2) and r["run_seconds"] > 0
        s = r["metrics"]["success"]
        assert s["n"] == 3 and 0.0 <= s["ci_low"] <= s["mean"] <= s["ci_high"] <= 1.0
        assert r["metrics"]["min_distance_human"]["mean"] is None  # no pedestrians
    with (tmp_path / "metrics.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4 * len(metrics.METRICS)
    table = (tmp_path / "table.md").read_text()
    assert "| open | only_local | 2 |" in table and "Team success (%) by robot count" in table
    for png in ("success_by_robots.png", "metrics_by_robots.png"):
        with Image.open(tmp_path / png) as image:
            assert image.size[0] > 100


@pytest.mark.slow
def test_runner_agrees_with_a_manual_loop():
    """The batched, frozen-after-the-end runner against eager step_env calls."""
    env, params = sgjax.make("hallway", num_agents=2)
    batch = run_episodes(env, params, "only_local", jax.random.key(3), 2, record=True)
    states = batch.states
    step = jax.jit(env.step_env)
    for e in range(2):
        state = jax.tree.map(lambda leaf, e=e: leaf[0, e], states)
        steps = 0
        for t in range(int(params.max_steps)):
            _, state, _, term, trunc, _ = step(
                jax.random.key(t), state, jnp.zeros(2, jnp.int32), params)
            steps += 1
            if bool(metrics.episode_done(state, term, trunc)):
                break
        assert batch.values["episode_length"][e] == steps
        recorded = jax.tree.map(lambda leaf, e=e: leaf[-1, e], states)
        assert np.allclose(recorded.robots.x, state.robots.x, atol=1e-4)
        assert batch.robot["success"][e].tolist() == np.asarray(
            state.robots.succeeded, float).tolist()


@pytest.mark.slow
def test_stopping_once_every_episode_ended_changes_no_result():
    """The runner plays chunks of steps until every episode has ended (``record`` plays every
    step of the time limit): both give the same value of every metric, for episodes that end
    early and late, with a time limit that is no multiple of the chunk."""
    for scenario, policy in (("doorway", "stop_when_blocked"), ("open", "only_local")):
        env, params = sgjax.make(scenario, num_agents=3, time_limit=33.3)
        assert int(params.max_steps) % sgjax.evaluation.runner.STEP_CHUNK
        early = run_episodes(env, params, policy, jax.random.key(4), 3)
        full = run_episodes(env, params, policy, jax.random.key(4), 3, record=True)
        for name, value in early.values.items():
            np.testing.assert_array_equal(value, full.values[name], err_msg=f"{policy} {name}")
    assert early.values["episode_length"].max() < 200  # open: all ended long before the limit


def test_every_robot_count_is_evaluated_by_one_compilation():
    """Robot counts are params: evaluating three counts traces (so compiles) the run once."""
    traces = []

    def counted(obs, key, state, params):
        traces.append(1)
        return jnp.zeros(obs.shape[0], jnp.int32)  # GO

    results = sgjax.evaluation.evaluate.evaluate(["open"], [counted], num_agents=[2, 3, 4],
                                                 episodes=2,
                                                 options=MakeOptions.from_keywords(
                                                     time_limit=3.0), log=None)
    assert len(traces) == 1
    assert [r.num_agents for r in results] == [2, 3, 4]
    assert all(r.metrics["success"].n == 2 for r in results)
    with pytest.raises(ValueError, match="here: .* the runner was built for 30"):
        sgjax.evaluation.runner.check_steps(sgjax.make("open", time_limit=6.0)[1], 30, "here")


def test_a_named_baseline_compiles_its_run_once_per_process():
    """``run_episodes`` of a baseline by name at a second robot count plays the program the
    first call compiled, with the results of a runner built afresh for that count."""
    env, by_count = sgjax.evaluation.evaluate.params_by_count(
        "open", [2, 3], options=MakeOptions.from_keywords(time_limit=4.0))
    key = jax.random.key(11)
    first = run_episodes(env, by_count[2], "stop_when_blocked", key, 3)
    second = run_episodes(env, by_count[3], "stop_when_blocked", key, 3)
    assert first.compile_seconds > 0 and second.compile_seconds == 0.0
    fresh = sgjax.evaluation.runner.EpisodeRunner(
        env, load_policy("stop_when_blocked", env), 3, int(by_count[3].max_steps))(
        key, by_count[3])
    assert fresh.compile_seconds > 0
    for name, value in fresh.values.items():
        np.testing.assert_array_equal(second.values[name], value, err_msg=name)
    assert not np.array_equal(first.values["path_length"], second.values["path_length"])


def test_policy_specs_and_errors():
    env, params = sgjax.make("open", num_agents=2)
    obs, state = env.reset(jax.random.key(0), params)
    fn = load_policy("test_evaluate:go_everywhere", env)
    assert fn(obs, jax.random.key(0), state, params).tolist() == [GO, GO]
    with pytest.raises(ValueError, match="not known"):
        load_policy("only_locl", env)
    with pytest.raises(ValueError, match="no function"):
        load_policy("test_evaluate:missing", env)
    continuous, _ = sgjax.make("open", num_agents=2, action_mode="continuous")
    with pytest.raises(ValueError, match="go_stop"):
        load_policy("only_local", continuous)
    assert load_policy("random", continuous)(obs, jax.random.key(1), state, params).shape == (
        2, continuous.config.action_dim)


def test_stop_when_blocked_yields_to_the_lower_index():
    env, params = make_room(num_agents=2)
    # Robot 1 faces robot 0, 0.8 m ahead: it yields; robot 0 has priority and goes.
    state = place(env, params, [0.0, -0.8 - 2 * float(params.robots.radius[0])], [0.0, 0.0],
                  headings=[0.0, 0.0])
    actions = stop_when_blocked(env)(None, jax.random.key(0), state, params)
    assert actions.tolist() == [GO, STOP]
    far = place(env, params, [0.0, -3.0], [0.0, 0.0])
    assert stop_when_blocked(env)(None, jax.random.key(0), far, params).tolist() == [GO, GO]


@pytest.mark.slow
def test_render_command_writes_animation_and_trajectory(tmp_path, capsys):
    gif = tmp_path / "episode.gif"
    main(["render", "--scenario", "open", "--num-agents", "2", "--width", "160",
          "--max-frames", "12", "--out", str(gif)])
    assert "arrived" in capsys.readouterr().out
    with Image.open(gif) as animation:
        assert 2 <= animation.n_frames <= 12
        first = np.asarray(animation.convert("RGB"))
        animation.seek(animation.n_frames - 1)
        last = np.asarray(animation.convert("RGB"))
    assert first.shape[1] == 160 and not np.array_equal(first, last)
    with Image.open(tmp_path / "episode.png") as picture:
        assert picture.size[0] == 160


def test_render_draws_the_generated_world_the_episode_played():
    """A generated scenario's episode is drawn on its own world (from the recorded state), with
    the world's valid walls and zones only."""
    import jax

    import sgjax
    from sgjax.evaluation.render import recorded_map

    env, params = sgjax.make("generated:floorplan", num_agents=2)
    _, state = env.reset(jax.random.key(4), params)
    states = jax.tree.map(lambda leaf: leaf[None], state)
    spec = recorded_map("generated:floorplan", states)
    m = state.world.map
    assert len(spec.walls) == int(m.wall_valid.sum())
    assert 0 < len(spec.zones) < m.zone_rect.shape[0]  # the doors, not the padding
    xmin, ymin, xmax, ymax = spec.bounds
    assert xmax - xmin < 60 and ymax - ymin < 60
    assert recorded_map("doorway", object()).name == "doorway"  # a map file's own


@pytest.mark.slow
def test_render_builds_the_environment_the_policy_needs(tmp_path, capsys):
    """``sgjax render`` applies a policy's make settings as ``sgjax evaluate`` does: ``orca``
    drives continuous actions (in a GO/STOP environment it is an error)."""
    main(["render", "--scenario", "open", "--num-agents", "2", "--policy", "orca", "--width",
          "120", "--max-frames", "4", "--time-limit", "3", "--out", str(tmp_path / "o.gif")])
    assert "policy orca" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="render: policy 'orca'.*continuous"):
        main(["render", "--scenario", "open", "--num-agents", "2", "--policy", "orca",
              "--action-mode", "go_stop", "--out", str(tmp_path / "p.gif")])


@pytest.mark.slow
def test_render_plays_exactly_the_robots_asked_for(tmp_path, capsys, monkeypatch,
                                                   fresh_loaders):
    """A checkpoint trained on a range of robot counts (its make settings carry
    ``min_agents``) is rendered with exactly ``--num-agents`` robots, as it is evaluated."""
    policies.register_loader("ranged", matches=lambda spec: spec.endswith(".ranged"),
                             load=lambda spec, env: policies.only_local(env),
                             options=lambda spec: MakeOptions.from_keywords(
                                 min_agents=1))
    played = []

    def recording(env, params, *args, **kwargs):
        played.append(params)
        return run_episodes(env, params, *args, **kwargs)

    monkeypatch.setattr(cli, "run_episodes", recording)
    main(["render", "--scenario", "open", "--num-agents", "4", "--policy", "run.ranged",
          "--width", "120", "--max-frames", "4", "--time-limit", "3",
          "--out", str(tmp_path / "r.gif")])
    assert " of 4 arrived" in capsys.readouterr().out
    (params,) = played
    assert int(params.num_agents) == 4 and int(params.min_agents) == 0


def test_mp4_needs_ffmpeg_or_is_written(tmp_path):
    frames = [np.full((30, 41, 3), v, np.uint8) for v in (0, 128, 255)]
    if shutil.which("ffmpeg") is None:
        with pytest.raises(RuntimeError, match="ffmpeg"):
            save_animation(frames, tmp_path / "a.mp4")
    else:
        assert (save_animation(frames, tmp_path / "a.mp4")).stat().st_size > 0
    with pytest.raises(ValueError, match=".gif or .mp4"):
        save_animation(frames, tmp_path / "a.avi")


def test_bad_render_output_name_is_an_error():
    with pytest.raises(SystemExit, match=r"must end in \.gif, \.mp4 or \.mcap"):
        main(["render", "--out", "episode.webm"])


@pytest.mark.slow
def test_metrics_are_finite_where_defined():
    env, params = sgjax.make("doorway", num_agents=3)
    batch = run_episodes(env, params, "random", jax.random.key(0), 4, counterfactual=True)
    undefined_without_success = ("time_to_goal", "aggregated_time", "makespan", "makespan_ratio")
    recorded = ("log_deviation", "log_deviation_max", "people_reached")  # NaN: no recording
    for name, values in batch.values.items():
        info = metrics.METRICS[name]
        if name in recorded:
            assert np.isnan(values).all(), name
            continue
        if name in undefined_without_success or "human" in name:
            continue
        assert np.isfinite(values).all(), name
        assert (values >= 0).all(), name
        if info.unit == "fraction":
            assert (values <= 1).all(), name
    assert not math.isnan(batch.values["order_violations_entry"][0])  # zone books were kept


@pytest.fixture
def fresh_loaders(monkeypatch):
    """An empty loader registry whose entry points are read again at first use."""
    monkeypatch.setattr(policies, "_LOADERS", {})
    monkeypatch.setattr(policies, "_discovery", None)


FAKE_LOADER = """
import jax.numpy as jnp
from sgjax.environment.options import MakeOptions
from sgjax.evaluation.policies import PolicyLoader

def load(spec, env):
    return lambda obs, key, state, params: jnp.ones(obs.shape[0], jnp.int32)

LOADER = PolicyLoader("fake", matches=lambda spec: spec.endswith(".fake"), load=load,
                      options=lambda spec: MakeOptions.from_keywords(time_limit=3.0))
"""


def test_policy_loaders_come_from_the_entry_point_group(tmp_path, monkeypatch, fresh_loaders):
    (tmp_path / "fake_sgjax_loader.py").write_text(FAKE_LOADER)
    info = tmp_path / "fake_sgjax_loader-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-sgjax-loader\n"
                                   "Version: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sgjax.policy_loaders]\nfake = fake_sgjax_loader:LOADER\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    env, params = sgjax.make("open", num_agents=2)
    obs, state = env.reset(jax.random.key(0), params)
    assert load_policy("only_local", env) is not None and policies._discovery is None  # lazy
    policy = load_policy("run.fake", env)
    assert policy(obs, jax.random.key(0), state, params).tolist() == [STOP, STOP]
    assert policies.policy_options("run.fake") == MakeOptions.from_keywords(time_limit=3.0)
    assert policies.policy_options("only_local") == MakeOptions()
    assert "fake" in policies.registered_loaders()
    sys.modules.pop("fake_sgjax_loader", None)


def test_a_checkpoint_without_a_loader_is_a_clear_error(tmp_path, monkeypatch, fresh_loaders):
    monkeypatch.setattr(policies.metadata, "entry_points", lambda group: [])
    env, _ = sgjax.make("open", num_agents=2)
    with pytest.raises(ValueError, match=r"no installed policy loader.*sgjax\[train\]"):
        load_policy(str(tmp_path / "best.msgpack"), env)
    with pytest.raises(ValueError, match="looks like a trainer checkpoint"):
        load_policy(str(tmp_path), env)  # an existing folder
    seen = []
    policies.register_loader("folders", matches=lambda spec: spec == str(tmp_path),
                             load=lambda spec, env: seen.append(spec) or policies.only_local(env))
    load_policy(str(tmp_path), env)
    assert seen == [str(tmp_path)]


def test_greedy_or_sampled_reaches_loaders_that_take_it(fresh_loaders):
    """``load_policy(..., deterministic=)`` (``sgjax evaluate --greedy/--sampled``) goes to a
    loader that declares ``greedy``; one that does not is an error naming it; baselines ignore
    it."""
    asked = []
    policies.register_loader(
        "chooser", matches=lambda spec: spec.endswith(".choose"), greedy=True,
        load=lambda spec, env, deterministic=None: asked.append(deterministic)
        or policies.only_local(env))
    policies.register_loader("plain", matches=lambda spec: spec.endswith(".plain"),
                             load=lambda spec, env: policies.only_local(env))
    env, _ = sgjax.make("open", num_agents=2)
    load_policy("run.choose", env)
    load_policy("run.choose", env, deterministic=True)
    load_policy("run.choose", env, deterministic=False)
    assert asked == [None, True, False]
    load_policy("run.plain", env)
    with pytest.raises(ValueError, match=r"run\.plain.*loader 'plain' cannot choose"):
        load_policy("run.plain", env, deterministic=True)
    assert load_policy("only_local", env, deterministic=True) is not None


def test_evaluate_command_passes_greedy_and_sampled(monkeypatch):
    seen = []
    monkeypatch.setattr(cli, "evaluate", lambda *a, **k: seen.append(k["deterministic"]))
    for flags, expected in (([], None), (["--greedy"], True), (["--sampled"], False)):
        cli.main(["evaluate", "--scenario", "open", "--episodes", "1", *flags])
        assert seen.pop() is expected
    with pytest.raises(SystemExit):
        cli.main(["evaluate", "--greedy", "--sampled"])


def test_evaluate_command_passes_the_arrived_world(monkeypatch):
    seen = []
    monkeypatch.setattr(cli, "evaluate", lambda *a, **k: seen.append(k["options"]))
    cli.main(["evaluate", "--scenario", "open", "--episodes", "1"])
    assert seen.pop() == [MakeOptions()]  # the policy's own (a checkpoint's), else make's
    for world in ("settle", "park", "leave"):
        cli.main(["evaluate", "--scenario", "open", "--episodes", "1", "--arrived", world])
        assert [o.robots.arrived for o in seen.pop()] == [world]
    with pytest.raises(SystemExit):
        cli.main(["evaluate", "--arrived", "stay"])

