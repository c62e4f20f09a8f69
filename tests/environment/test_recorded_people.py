"""Recorded people as the environment's pedestrians (``make("recorded:FILE")``,
``sgjax.humans.replay``): replayed positions equal the recording at its rows and its linear
interpolation between them; pause and hand-over change only the people a robot reached; ghosts
are never pushed and leave no log deviation; the step is deterministic, ``jit`` equals eager and
``vmap`` equals a loop; bad input is refused by name; and the ETH/UCY scenes run."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from shared_data import SHARED, require

import sgjax
from sgjax.humans.replay import recorded_at
from sgjax.humans.replay_step import meet_robots, move_replayed
from sgjax.humans.tracks import TrackFileError

ROW = 0.4  # s between the file's rows (frames 10 apart)


def scene_text(rows: int = 80) -> str:
    """Five people: 1 walks east at 0.5 m/s, 2 walks west at 0.4 m/s, 3 stands, 4 walks north
    from row 20 to row 70, 5 walks a curve from row 40 on."""
    lines = []
    for r in range(rows):
        t = r * ROW
        lines.append(f"{10 * r} 1 {-8.0 + 0.5 * t:.4f} 0.0")
        lines.append(f"{10 * r} 2 {6.0 - 0.4 * t:.4f} 1.5")
        lines.append(f"{10 * r} 3 2.0 -3.0")
        if 20 <= r <= 70:
            lines.append(f"{10 * r} 4 -2.0 {-5.0 + 0.5 * (t - 8.0):.4f}")
        if r >= 40:
            lines.append(f"{10 * r} 5 {3.0 * np.cos(0.1 * t):.4f} {3.0 * np.sin(0.1 * t):.4f}")
    return "\n".join(sorted(lines, key=lambda line: int(line.split()[0]))) + "\n"


def recorded_positions(text: str, person: int, time: float) -> tuple[float, float] | None:
    """Where ``person`` is at ``time`` s by the file (linear between rows), None if absent."""
    rows = [line.split() for line in text.splitlines()]
    mine = np.asarray([[float(r[0]) / 10 * ROW, float(r[2]), float(r[3])]
                       for r in rows if int(r[1]) == person])
    if time < mine[0, 0] - 1e-4 or time > mine[-1, 0] + 1e-4:
        return None
    return float(np.interp(time, mine[:, 0], mine[:, 1])), float(np.interp(time, mine[:, 0],
                                                                          mine[:, 2]))


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("recorded") / "scene.txt"
    text = scene_text()
    path.write_text(text)
    return path, text


def env_of(scene, mode="ghost", **keywords):
    path, _ = scene
    return sgjax.make(f"recorded:{path}", num_agents=keywords.pop("num_agents", 2),
                      time_limit=keywords.pop("time_limit", 12.0), human_replay=mode,
                      **keywords)


def rollout(env, params, key, steps):
    """States after each of ``steps`` steps of all-GO actions (jitted)."""
    step = jax.jit(env.step)
    _, state = jax.jit(env.reset)(key, params)
    states = [state]
    go = jnp.ones(env.config.max_agents, jnp.int32)
    for _ in range(steps):
        key, k = jax.random.split(key)
        state = step(k, state, go, params)[1]
        states.append(state)
    return states


def test_ghosts_are_where_the_recording_has_them(scene):
    env, params = env_of(scene)
    rec = params.humans.recording
    _, text = scene
    checked = 0
    for seed in range(3):
        states = rollout(env, params, jax.random.key(seed), 60)
        window = int(states[0].humans.replay.window)
        start = int(rec.start[window]) * ROW
        ids = np.asarray(rec.ids[window])
        for n, state in enumerate(states):
            if int(state.humans.replay.time * 10 + 0.5) != n:  # an auto-reset began anew
                break
            h = state.humans
            for slot, person in enumerate(ids):
                if person < 0:
                    assert not bool(h.active[slot])
                    continue
                expected = recorded_positions(text, int(person), start + n * 0.1)
                if expected is None:
                    assert not bool(h.active[slot]), (seed, n, person)
                    continue
                if not bool(h.active[slot]):  # within the float tolerance of a track's end
                    continue
                np.testing.assert_allclose([float(h.x[slot]), float(h.y[slot])], expected,
                                           atol=2e-4, err_msg=f"person {person} at step {n}")
                checked += 1
    assert checked > 300


def test_recorded_rows_are_exact_and_interpolation_is_linear(scene):
    _, params = env_of(scene)
    rec = params.humans.recording
    window = jnp.asarray(1)
    people = rec.x.shape[2]
    for row in range(0, 25):
        x, y, _, _, present = recorded_at(rec, window, jnp.full(people, row * ROW))
        valid = np.asarray(rec.valid[1, row])
        np.testing.assert_array_equal(np.asarray(present), valid)
        np.testing.assert_allclose(np.asarray(x)[valid], np.asarray(rec.x[1, row])[valid],
                                   atol=1e-5)
        np.testing.assert_allclose(np.asarray(y)[valid], np.asarray(rec.y[1, row])[valid],
                                   atol=1e-5)
    x0, y0, *_ = recorded_at(rec, window, jnp.full(people, 4 * ROW))
    x1, y1, *_ = recorded_at(rec, window, jnp.full(people, 5 * ROW))
    xm, ym, vx, _, _ = recorded_at(rec, window, jnp.full(people, 4.25 * ROW))
    both = np.asarray(rec.valid[1, 4] & rec.valid[1, 5])
    np.testing.assert_allclose(np.asarray(xm)[both], (0.75 * x0 + 0.25 * x1)[both], atol=1e-5)
    np.testing.assert_allclose(np.asarray(ym)[both], (0.75 * y0 + 0.25 * y1)[both], atol=1e-5)
    np.testing.assert_allclose(np.asarray(vx)[both], ((x1 - x0) / ROW)[both], atol=1e-4)


def test_ghosts_are_not_pushed_and_leave_no_log_deviation(scene):
    env, params = env_of(scene, num_agents=4)
    from sgjax.evaluation.evaluate import run_episodes  # noqa: PLC0415 - heavy import

    values = run_episodes(env, params, "only_local", jax.random.key(0), 4).values
    assert np.all(values["log_deviation"] < 1e-5)
    assert np.all(values["people_reached"] == 0.0)
    humans = _people(env, params, jax.random.key(1))
    first = int(np.flatnonzero(np.asarray(humans.active))[0])
    robot_x, robot_y = humans.x[first] + 0.1, humans.y[first]  # on that person
    met_people, met = meet_robots(env.config.humans, params.humans, params.map, humans,
                                  jnp.stack([robot_x, robot_x + 50.0]),
                                  jnp.stack([robot_y, robot_y]), jnp.full(2, 0.3),
                                  jnp.ones(2, bool))
    assert met.tolist() == [True, False]  # the robot touched a ghost (a collision)...
    np.testing.assert_array_equal(np.asarray(met_people.x), np.asarray(humans.x))  # not pushed
    assert not bool(jnp.any(met_people.replay.reached))


def _people(env, params, key):
    _, state = jax.jit(env.reset)(key, params)
    return state.humans


def test_pause_stops_only_the_person_touched_and_delays_their_walk(scene):
    env, params = env_of(scene, "pause")
    hp = params.humans.replace(pause_seconds=jnp.asarray(0.8, jnp.float32))
    cfg, m = env.config.humans, params.map
    humans = _people(env, params, jax.random.key(3))
    rec, window = hp.recording, humans.replay.window
    walking = np.flatnonzero(np.asarray(humans.active & (jnp.abs(humans.vx) > 0.3)))
    touched = int(walking[0])
    # a robot on that person, another far from everybody
    rx = jnp.asarray([float(humans.x[touched]), 40.0])
    ry = jnp.asarray([float(humans.y[touched]), 40.0])
    radius = jnp.asarray([0.3, 0.3])
    in_world = jnp.asarray([True, True])
    humans, met = meet_robots(cfg, hp, m, humans, rx, ry, radius, in_world)
    assert met.tolist() == [True, False]
    assert np.flatnonzero(np.asarray(humans.replay.reached)).tolist() == [touched]
    dt = jnp.asarray(0.1, jnp.float32)
    still = (float(humans.x[touched]), float(humans.y[touched]))
    zero = jnp.zeros(2)
    for n in range(1, 21):
        humans, _ = move_replayed(cfg, hp, m, humans, rx + 100.0, ry, zero, zero, in_world,
                                  in_world, radius, dt)
        clock = np.full(humans.x.shape, n * 0.1, np.float32)
        x, y, _, _, present = recorded_at(rec, window, jnp.asarray(clock))
        others = np.asarray(present) & (np.arange(clock.size) != touched)
        np.testing.assert_allclose(np.asarray(humans.x)[others], np.asarray(x)[others],
                                   atol=1e-4)
        if n <= 8:  # standing for 0.8 s
            assert (float(humans.x[touched]), float(humans.y[touched])) == pytest.approx(still)
            assert float(humans.vx[touched]) == 0.0
        else:  # walking on 0.8 s behind the recording
            late, late_y, *_ = recorded_at(rec, window, jnp.full(clock.shape, n * 0.1 - 0.8))
            assert float(humans.x[touched]) == pytest.approx(float(late[touched]), abs=1e-4)
            assert float(humans.y[touched]) == pytest.approx(float(late_y[touched]), abs=1e-4)
    assert float(humans.replay.deviation[touched]) > 0.0
    assert float(jnp.sum(humans.replay.deviation)) == pytest.approx(
        float(humans.replay.deviation[touched]))


def test_handover_hands_over_only_the_people_a_robot_came_near(scene):
    env, params = env_of(scene, "handover")
    hp = params.humans
    cfg, m = env.config.humans, params.map
    humans = _people(env, params, jax.random.key(3))
    rec, window = hp.recording, humans.replay.window
    active = np.flatnonzero(np.asarray(humans.active))
    near = int(active[0])
    # 1.0 m body gap from that person (within handover_radius 1.5), far from the others?
    rx = jnp.asarray([float(humans.x[near]), 40.0])
    ry = jnp.asarray([float(humans.y[near]) + 1.0 + 0.25 + 0.3, 40.0])
    gaps = np.hypot(np.asarray(humans.x) - float(rx[0]), np.asarray(humans.y) - float(ry[0]))
    expected = np.asarray(humans.active) & (gaps - 0.25 - 0.3 < 1.5)
    radius = jnp.asarray([0.3, 0.3])
    in_world = jnp.asarray([True, True])
    humans, met = meet_robots(cfg, hp, m, humans, rx, ry, radius, in_world)
    assert not bool(jnp.any(met))
    np.testing.assert_array_equal(np.asarray(humans.replay.handed), expected)
    handed = np.flatnonzero(expected)
    dt = jnp.asarray(0.1, jnp.float32)
    zero = jnp.zeros(2)
    moved = False
    for n in range(1, 16):
        humans, _ = move_replayed(cfg, hp, m, humans, rx, ry, zero, zero, in_world, in_world,
                                  radius, dt)
        x, y, _, _, present = recorded_at(rec, window, jnp.full(humans.x.shape, n * 0.1))
        others = np.asarray(present) & ~expected
        np.testing.assert_allclose(np.asarray(humans.x)[others], np.asarray(x)[others],
                                   atol=1e-4)
        np.testing.assert_allclose(np.asarray(humans.y)[others], np.asarray(y)[others],
                                   atol=1e-4)
        moved |= bool(np.any(np.abs(np.asarray(humans.x)[handed] - np.asarray(x)[handed])
                             + np.abs(np.asarray(humans.y)[handed] - np.asarray(y)[handed])
                             > 1e-3))
    assert moved, "the handed-over people walk under the force model, off their recording"
    deviation = np.asarray(humans.replay.deviation)
    assert np.all(deviation[~expected] < 1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["pause", "handover"])
def test_replay_is_deterministic_and_jit_equals_eager_and_vmap_a_loop(scene, mode):
    env, params = env_of(scene, mode, num_agents=3)
    keys = jax.random.split(jax.random.key(7), 3)
    go = jnp.ones(3, jnp.int32)

    def play(key):
        _, state = env.reset(key, params)
        for _ in range(4):
            key, k = jax.random.split(key)
            state = env.step(k, state, go, params)[1]
        return state.humans

    jitted = jax.jit(play)
    batched = jax.jit(jax.vmap(play))(keys)
    for i, key in enumerate(keys):
        one = jitted(key)
        again = jitted(key)
        with jax.disable_jit():
            eager = play(key)
        for a, b, c, d in zip(jax.tree.leaves(one), jax.tree.leaves(again),
                              jax.tree.leaves(eager),
                              jax.tree.leaves(jax.tree.map(lambda v, i=i: v[i], batched)),
                              strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
            np.testing.assert_allclose(np.asarray(a), np.asarray(c), atol=1e-4)
            np.testing.assert_allclose(np.asarray(a), np.asarray(d), atol=1e-5)


def test_resets_draw_different_windows(scene):
    env, params = env_of(scene)
    windows = {int(_people(env, params, jax.random.key(k)).replay.window) for k in range(12)}
    assert len(windows) > 3


def test_bad_input_is_refused_by_name(scene, tmp_path):
    path, _ = scene
    with pytest.raises(TrackFileError, match="no such track file"):
        sgjax.make(f"recorded:{tmp_path / 'missing.txt'}", num_agents=2)
    broken = tmp_path / "broken.txt"
    broken.write_text("0 1 1.0 2.0\n10 1 abc 2.0\n")
    with pytest.raises(TrackFileError, match=r"broken.txt:2: 'abc' is not a number"):
        sgjax.make(f"recorded:{broken}", num_agents=2)
    with pytest.raises(ValueError, match="num_humans and max_humans come from the recording"):
        sgjax.make(f"recorded:{path}", num_agents=2, num_humans=3)
    with pytest.raises(ValueError, match="human_replay='pause' replays a recording"):
        sgjax.make("doorway", num_agents=2, human_replay="pause")
    with pytest.raises(ValueError, match="human_replay"):
        sgjax.make(f"recorded:{path}", num_agents=2, human_replay="ghosts")
    with pytest.raises(ValueError, match="windows of 376 rows, the recording has 80"):
        sgjax.make(f"recorded:{path}", num_agents=2, time_limit=150.0)


ETH_UCY = SHARED / "pedestrians" / "eth_ucy"


def test_an_eth_ucy_scene_replays_its_recording():
    path = require(ETH_UCY / "crowds_zara01.txt", "the ETH/UCY recordings")
    env, params = sgjax.make(f"recorded:{path}", num_agents=3, time_limit=20.0)
    rec = params.humans.recording
    states = rollout(env, params, jax.random.key(0), 30)
    window = states[0].humans.replay.window
    for n, state in enumerate(states):
        x, y, _, _, present = recorded_at(rec, window, jnp.full(rec.x.shape[2], n * 0.1))
        np.testing.assert_array_equal(np.asarray(state.humans.active), np.asarray(present))
        np.testing.assert_allclose(np.asarray(state.humans.x), np.asarray(x), atol=1e-4)
    assert int(jnp.sum(states[0].humans.active)) > 3


def test_replay_off_puts_simulated_pedestrians_in_the_recordings_space(scene):
    path, _ = scene
    env, params = sgjax.make(f"recorded:{path}", num_agents=2, human_replay="off",
                             num_humans=6, time_limit=12.0)
    replayed_env, replayed = env_of(scene)
    assert env.config.humans.replay is None and params.humans.recording is None
    assert env.config.humans.max_humans == 6
    np.testing.assert_array_equal(np.asarray(params.map.node_x),
                                  np.asarray(replayed.map.node_x))  # the same space
    humans = _people(env, params, jax.random.key(0))
    assert humans.replay is None and int(jnp.sum(humans.active)) == 6
