"""The multi-robot mini-game metrics (sgjax.evaluation.counterfactual, makespan, flow rate) against
the
same quantities worked out by brute force from separately played episodes, and the evaluation
protocol."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.command import main as cli_main
from sgjax.evaluation import metrics
from sgjax.evaluation.evaluate import params_by_count
from sgjax.evaluation.policies import load_policy
from sgjax.evaluation.protocols import PAPER, load_protocol
from sgjax.evaluation.runner import EpisodeRunner, with_zone_books
from sgjax.maps import parse_map
from sgjax.maps.arrays import zone_widths

EPISODES, TIME_LIMIT = 2, 15.0


def test_zone_widths_are_the_free_gaps_of_the_shipped_mini_games():
    widths = {name: float(sgjax.make(name)[1].map.zone_width[0])
              for name in ("doorway", "hallway", "intersection", "roundabout", "open")}
    assert widths["doorway"] == pytest.approx(1.0)  # the door
    assert widths["hallway"] == pytest.approx(1.0)  # the corridor
    assert widths["intersection"] == pytest.approx(4.0)  # the roads
    assert widths["roundabout"] == pytest.approx(1.5 * np.sqrt(2.0), abs=1e-5)  # island-corner
    assert widths["open"] == pytest.approx(12.0)  # no walls: the zone's shorter side
    # A 0.8 m gap between two separate wall pieces; the walls that meet at a corner count once.
    spec = parse_map({"name": "gap", "description": "a gap", "bounds": [-5, -5, 5, 5],
                      "walls": [[-3, 0.4, -1, 0.4], [-1, 0.4, -1, 2], [-3, -0.4, 3, -0.4]],
                      "nodes": [{"id": 0, "position": [-4, 0]}, {"id": 1, "position": [4, 0]}],
                      "edges": [[0, 1]], "routes": [[0, 1]],
                      "zones": [{"name": "gap", "rect": [-2, -1, 2, 1]}]})
    np.testing.assert_allclose(zone_widths(spec), [0.8])


def _play_lane(env, params, policy, reset_key, step_keys, episode, keep):
    """One lane played as ``EpisodeRunner`` plays it: its episode's keys (``episode`` may be
    traced), frozen once done. Returns per-step records (the start first) of robots,
    pedestrians and zones, and whether the episode ran at each step ``[T]``."""
    obs, state = env.reset_subset(reset_key, params, keep)

    def body(carry, key):
        obs, state, running = carry
        k_act, k_step = jax.random.split(key)
        actions = policy(obs, jax.random.split(k_act, EPISODES)[episode], state, params)
        nobs, nstate, _, term, trunc, _ = env.step_env(
            jax.random.split(k_step, EPISODES)[episode], state, actions, params)
        done = metrics.episode_done(nstate, term, trunc)
        kept = jax.tree.map(lambda new, old: jnp.where(running, new, old), nstate, state)
        nobs = jnp.where(running, nobs, obs)
        return (nobs, kept, running & ~done), (kept, running)

    (_, _, _), (states, running) = jax.lax.scan(body, (obs, state, jnp.asarray(True)), step_keys)
    states = jax.tree.map(lambda a, rest: jnp.concatenate([a[None], rest]), state, states)
    return states, running


def _polyline_distance(points, line):
    """Distance from ``points [P, 2]`` to the polyline through ``line [Q, 2]`` (numpy)."""
    a, b = line[:-1][None], line[1:][None]
    p = points[:, None]
    e = b - a
    t = np.clip(np.sum((p - a) * e, -1) / np.maximum(np.sum(e * e, -1), 1e-12), 0.0, 1.0)
    return np.min(np.linalg.norm(p - (a + t[..., None] * e), axis=-1), axis=1)


@pytest.fixture(scope="module")
def doorway():
    """Doorway with room for 3 robots and 4 pedestrians, its params at 1 and 3 robots, and one
    counterfactual runner of ``only_local`` for the module: the robot counts are params
    values, so the tests share its compiled program (the protocol's evaluation below plays
    the same environment, so it finds that program in the compilation cache)."""
    env, by_count = params_by_count("doorway", [1, 3], time_limit=TIME_LIMIT, num_humans=4)
    env = with_zone_books(env)
    policy = load_policy("only_local", env)
    runner = EpisodeRunner(env, policy, EPISODES, int(by_count[3].max_steps),
                           counterfactual=True)
    return env, by_count, policy, runner


@pytest.mark.slow
def test_counterfactual_metrics_equal_brute_force_from_separate_episodes(doorway):
    """Doorway, 3 robots, 4 pedestrians: every counterfactual metric of the batched runner
    equals the value computed in numpy from the episode, each robot's episode alone and the
    episode without each robot, played one by one; the ordinary metrics are unchanged by the
    extra lanes; makespan and flow rate match their definitions."""
    env, by_count, policy, counterfactual = doorway
    params = by_count[3]
    key = jax.random.key(5)
    steps = int(params.max_steps)
    plain = EpisodeRunner(env, policy, EPISODES, steps).run(key, params)[0]
    values, robot, *_ = counterfactual.run(key, params)
    for name in metrics.METRICS.names():
        if name not in metrics.counterfactuals.COUNTERFACTUAL_NAMES:
            np.testing.assert_array_equal(np.asarray(values[name]), np.asarray(plain[name]),
                                          err_msg=name)
    assert np.all(np.isnan(np.asarray(plain["hausdorff"])))

    k_reset, k_steps = jax.random.split(key)
    reset_keys = jax.random.split(k_reset, EPISODES)
    step_keys = jax.random.split(k_steps, int(params.max_steps))
    num = env.max_agents
    dt = float(params.dt)
    checked = flows = 0
    # one program for every lane played below (the episode and the robots kept are arguments)
    play = jax.jit(lambda reset_key, episode, keep: _play_lane(
        env, params, policy, reset_key, step_keys, episode, keep))
    for e in range(EPISODES):
        def lane(keep, e=e):
            states, running = play(reset_keys[e], jnp.int32(e), jnp.asarray(keep))
            return jax.device_get(states), np.asarray(running)

        full, running = lane(np.ones(num, bool))
        xy = np.stack([full.robots.x, full.robots.y], -1)  # [T + 1, R, 2]
        present = full.robots.present[0]
        active_before = full.robots.active[:-1] & running[:, None]  # [T, R]
        solo_arrival = []
        for i in range(num):
            if not present[i]:
                continue
            alone, _ = lane(np.arange(num) == i)
            solo = np.stack([alone.robots.x[:, i], alone.robots.y[:, i]], -1)
            arrived = np.flatnonzero(alone.robots.succeeded[:, i])
            solo_arrival.append(arrived[0] if arrived.size else 0)
            steps = np.flatnonzero(active_before[:, i])
            dev = _polyline_distance(xy[steps + 1, i], solo)
            path = xy[: steps[-1] + 2, i] if steps.size else xy[:1, i]
            hausdorff = max(dev.max(initial=0.0), _polyline_distance(solo, path).max())
            np.testing.assert_allclose(robot["path_deviation_mean"][e, i], dev.mean(),
                                       atol=2e-4)
            np.testing.assert_allclose(robot["path_deviation_max"][e, i], dev.max(), atol=2e-4)
            np.testing.assert_allclose(robot["hausdorff"][e, i], hausdorff, atol=2e-4)

            without, running_w = lane(np.arange(num) != i)
            compared = running | running_w  # [T]
            others = present & (np.arange(num) != i)
            gap = np.hypot(full.robots.x[1:] - without.robots.x[1:],
                           full.robots.y[1:] - without.robots.y[1:])[:, others]
            hgap = np.hypot(full.humans.x[1:] - without.humans.x[1:],
                            full.humans.y[1:] - without.humans.y[1:])
            hgap = hgap[:, full.humans.active[0]]
            np.testing.assert_allclose(robot["invasiveness_robots"][e, i],
                                       gap.mean(axis=1)[compared].mean(), atol=2e-4)
            np.testing.assert_allclose(robot["invasiveness_humans"][e, i],
                                       hgap.mean(axis=1)[compared].mean(), atol=2e-4)
            checked += 1
        team = bool(np.all(full.robots.succeeded[-1] | ~present))
        if team:
            last = np.flatnonzero(np.all(full.robots.succeeded | ~present, axis=1))[0]
            np.testing.assert_allclose(values["makespan"][e], last * dt, rtol=1e-6)
            if all(solo_arrival):
                np.testing.assert_allclose(values["makespan_ratio"][e],
                                           last / max(solo_arrival), rtol=1e-5)
        else:
            assert np.isnan(values["makespan"][e]) and np.isnan(values["makespan_ratio"][e])
        # Flow rate: robots out of the door zone per metre (1 m door) per second.
        phase = full.zones.phase[:, :, 0]  # [T + 1, R]
        entries = np.flatnonzero(np.any((phase[:-1] == 0) & (phase[1:] != 0), axis=1))
        exits = (phase[:-1] != 2) & (phase[1:] == 2)
        exit_steps = np.flatnonzero(np.any(exits, axis=1))
        if exit_steps.size and entries.size and exit_steps[-1] > entries[0]:
            expected = exits.sum() / (1.0 * (exit_steps[-1] - entries[0]) * dt)
            np.testing.assert_allclose(values["flow_rate"][e], expected, rtol=1e-5)
            flows += 1
    assert checked >= 4 and flows >= 1


def test_a_robot_alone_deviates_from_nothing_and_invades_nobody(doorway):
    """One robot (of room for 3) among 4 pedestrians: its episode is its solo episode, so path
    deviation and Hausdorff are 0, the makespan ratio 1, and invasiveness undefined (nobody
    else)."""
    _, by_count, _, runner = doorway
    values, robot, *_ = runner.run(jax.random.key(1), by_count[1])
    np.testing.assert_allclose(np.asarray(robot["hausdorff"][:, 0]), 0.0, atol=1e-5)
    np.testing.assert_allclose(np.asarray(robot["path_deviation_max"][:, 0]), 0.0, atol=1e-5)
    np.testing.assert_allclose(np.asarray(values["makespan_ratio"]), 1.0)
    assert np.all(np.isnan(np.asarray(values["invasiveness_robots"])))


def test_protocols_pin_the_evaluation_and_reject_clashes(tmp_path):
    assert PAPER.num_agents == (3, 4, 5, 7, 10) and PAPER.episodes == 25
    assert load_protocol("paper") is PAPER
    with pytest.raises(SystemExit, match="--protocol paper fixes --scenario"):
        cli_main(["evaluate", "--protocol", "paper", "--scenario", "doorway"])
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nscenarios: [doorway]\nnum_agents: [2]\nepisodes: 1\nseed: 0\n"
                   "counterfactual: yes please\nrobots: 3\n")
    with pytest.raises(ValueError, match=r"bad.yaml: unknown keys \['robots'\]"):
        load_protocol(bad)
    with pytest.raises(FileNotFoundError, match="neither a built-in protocol"):
        load_protocol(tmp_path / "missing.yaml")
    good = tmp_path / "small.yaml"
    # the environment and episodes of the module's counterfactual runner: the same program,
    # found in the compilation cache once the tests above compiled it
    good.write_text(f"name: small\nscenarios: [doorway]\nnum_agents: [3]\nepisodes: {EPISODES}\n"
                    f"seed: 3\ncounterfactual: true\ntime_limit: {TIME_LIMIT}\n")
    cli_main(["evaluate", "--protocol", str(good), "--policy", "only_local", "--num-humans", "4",
              "--out", str(tmp_path / "out")])
    table = (tmp_path / "out" / "table.md").read_text()
    assert "Hausdorff (m)" in table and "seed 3" in table
