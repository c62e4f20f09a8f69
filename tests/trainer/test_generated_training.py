"""The trainer on generated worlds: ``env.scenarios: [generated:doorway]`` trains with a world
per environment, a new one at every episode, and checkpoints keep the ranges."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_train import tiny

from train.algorithm.level_buffer import Crowd
from train.algorithm.trainer import Trainer, seed_keys
from train.algorithm.world_curriculum import crowds


@pytest.fixture(scope="module")
def generated_run():
    """A tiny run on generated doorways (door widths 1.0 to 1.6 m, 1 s episodes): its config,
    trainer and fresh runners (one seed), built and compiled once for the tests below."""
    config = tiny(env={"scenarios": ["generated:doorway"], "curriculum": [[0, 2]],
                       "time_limit": 1.0, "world_ranges": {"door_width": [1.0, 1.6]}})
    trainer = Trainer(config)
    return config, trainer, jax.jit(jax.vmap(trainer.init))(seed_keys(config))


@pytest.mark.slow
def test_a_run_on_generated_worlds_trains_on_a_world_per_environment(generated_run):
    config, trainer, runners = generated_run
    assert config.env.options.worlds.ranges() == {"door_width": (1.0, 1.6)}
    widths = np.asarray(runners.env_states[0].world.values["door_width"])  # [seeds, envs]
    assert widths.shape == (1, trainer.num_envs) and len(set(widths[0].round(5))) > 1
    assert np.all((widths >= 1.0) & (widths <= 1.6))
    runners, logs = jax.jit(lambda r: trainer.update_chunk_lanes(r, 2))(runners)
    assert all(np.all(np.isfinite(np.asarray(v))) for v in logs.values())
    after = np.asarray(runners.env_states[0].world.values["door_width"])
    assert not np.array_equal(after, widths)  # 1 s episodes ended: new worlds drawn


@pytest.mark.slow
@pytest.mark.parametrize("method", ["plr", "accel", "learnability"])
def test_a_curriculum_keeps_a_buffer_per_lane_and_replays_its_levels(method):
    """Every lane its own buffer of valid levels, replayed; with room for pedestrians (1 of
    5), ``accel``'s edits also add groups of 2, which the worlds play, and ``plr``'s and
    ``learnability``'s levels keep the environment's count. (The three methods differ only
    in the lanes' curriculum numbers: they run one compiled update. Without room for
    pedestrians an edit adds none: test_curricula_train_as_lanes_of_one_program.)"""
    edits = method == "accel"
    config = tiny(env={"scenarios": ["generated:doorway", "doorway"], "curriculum": [[0, 2]],
                       "time_limit": 1.0, "num_humans": 1, "max_humans": 5},
                  levels={"method": method, "buffer_size": 8, "min_fill": 0.25,
                          "replay_prob": 1.0, "mutate_prob": 0.5, "pedestrian_group": 2},
                  num_seeds=2)
    trainer = Trainer(config)
    assert trainer.batch.level_sources[1] is None  # the shipped doorway keeps its map
    runners = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
    assert runners.levels[1] is None and not np.asarray(runners.levels[0].filled).any()
    update = jax.jit(lambda r: trainer.update_chunk_lanes(r, 2))
    seen = set()
    for _ in range(3):
        runners, logs = update(runners)
        assert all(np.all(np.isfinite(np.asarray(v))) for v in logs.values())
        states = runners.env_states[0]
        count = np.asarray(states.world.pedestrians)
        active = np.asarray(states.humans.active).sum(axis=-1)
        np.testing.assert_array_equal(active, np.where(count >= 0, count, 1))
        seen |= set(count.ravel().tolist())
        held = np.asarray(runners.levels[0].pedestrians)[np.asarray(runners.levels[0].filled)]
        # 1 and whole groups of 2, capped at 5; without edits the environment's count
        assert set(held.tolist()) <= ({-1, 3, 5} if edits else {-1})
    # the edits may add groups of 2 on top of 1, up to 5 (whether one was drawn in these few
    # updates is chance: tests/trainer/test_level_buffer.py draws them); replays without
    # edits play the environment's count
    assert crowds(trainer.batch, config.levels)[0] == Crowd(group=2, base=1, capacity=5)
    assert seen <= {-1, 3, 5} if edits else seen == {-1}
    buffers = runners.levels[0]
    filled = np.asarray(buffers.filled)  # [seeds, slots]
    assert filled.any(axis=1).all()
    # each lane its own levels, each one played in a valid world of its own seed
    assert not np.array_equal(np.asarray(buffers.seed)[0][filled[0]],
                              np.asarray(buffers.seed)[1][filled[1]])
    assert np.asarray(logs["levels_fill"])[:, -1].min() > 0
    replayed = np.asarray(logs["levels_replayed"])  # share of ended episodes on held levels
    assert ((replayed >= 0) & (replayed <= 1)).all() and replayed[:, -3:].max() > 0
    states = runners.env_states[0]
    chosen = np.asarray(states.next_level.chosen)
    if chosen.any():
        held = {(lane, int(s)) for lane in range(2)
                for s in np.asarray(buffers.seed)[lane][filled[lane]]}
        for lane, env in zip(*np.nonzero(chosen), strict=True):
            assert (lane, int(states.next_level.seed[lane, env])) in held


def test_a_curriculum_needs_a_generated_scenario_and_valid_settings():
    from sgjax.terms.base import ConfigError
    with pytest.raises(ConfigError, match="levels.method 'plr' picks generated worlds"):
        Trainer(tiny(levels={"method": "plr"}))
    with pytest.raises(ConfigError, match="levels: method must be one of .*did you mean .plr."):
        tiny(levels={"method": "plrr"})
    with pytest.raises(ConfigError, match="levels: replay_prob must be in"):
        tiny(levels={"method": "plr", "replay_prob": 1.5})


@pytest.mark.slow
def test_curricula_train_as_lanes_of_one_program():
    """DR, PLR and ACCEL lanes of one vmap: the DR lane never replays, the PLR lane replays
    levels as they are, the ACCEL lane plays edits too; without room for pedestrians its
    edits add none."""
    config = tiny(env={"scenarios": ["generated:doorway"], "curriculum": [[0, 2]],
                       "time_limit": 1.0},
                  levels={"method": "plr", "buffer_size": 8, "min_fill": 0.25,
                          "replay_prob": 1.0, "mutate_prob": 1.0})
    trainer = Trainer(config)
    methods = ["dr", "plr", "accel"]
    lanes = [trainer.curriculum_values(m) for m in methods]
    assert [float(c["mutate_prob"]) for c in lanes] == [0.0, 0.0, 1.0]
    curricula = {n: jnp.stack([c[n] for c in lanes]) for n in lanes[0]}
    keys = jnp.stack([jax.random.PRNGKey(0)] * 3)
    runners = jax.jit(jax.vmap(lambda k, c: trainer.init(k, curriculum=c)))(keys, curricula)
    runners, logs = jax.jit(lambda r: trainer.update_chunk_lanes(r, 6))(runners)
    replayed = np.asarray(logs["levels_replayed"])  # [lanes, updates]
    assert replayed[0].max() == 0 and replayed[1].max() > 0.5  # DR never, PLR mostly
    buffers, nxt = runners.levels[0], runners.env_states[0].next_level
    def levels(tree, lane, rows):
        names = sorted(tree.values)
        return {(int(tree.seed[lane, i]), *(float(tree.values[n][lane, i]) for n in names))
                for i in rows}

    for lane, edits in ((1, False), (2, True)):
        held = levels(buffers, lane, np.flatnonzero(np.asarray(buffers.filled[lane])))
        picked = levels(nxt, lane, range(trainer.num_envs))
        assert np.asarray(nxt.chosen[lane]).all()
        if edits:  # ACCEL: edited levels keep their parent's seed, not its values
            assert {p[0] for p in picked} <= {h[0] for h in held}
            assert len(picked - held) >= len(picked) // 2  # an edit clipped at a bound stays
        else:
            assert picked <= held
    # no pedestrian slots: an edit never adds a group, every level keeps the environment's
    # count (-1)
    assert crowds(trainer.batch, config.levels) == (Crowd(group=2, base=0, capacity=0),)
    assert (np.asarray(buffers.pedestrians) == -1).all()
    assert (np.asarray(nxt.pedestrians) == -1).all()


def test_a_lane_curriculum_needs_a_curriculum_config():
    from sgjax.terms.base import ConfigError
    trainer = Trainer(tiny())
    assert trainer.curriculum_values() == {}
    with pytest.raises(ConfigError, match="levels.method 'plr' for a lane"):
        trainer.curriculum_values("plr")


def test_a_curriculum_variant_needs_a_curriculum_config_and_a_known_method(tmp_path):
    from sgjax.terms.base import ConfigError
    from train.ablation import Variant, load_variants, variant_inputs
    with pytest.raises(ConfigError, match="variant 'plr': levels.method 'plr' for a lane"):
        variant_inputs(Trainer(tiny()), {"plr": Variant(levels="plr")}, 1)
    bad = tmp_path / "v.yaml"
    bad.write_text("baseline: {levels: dr}\nfancy: {levels: plrr}\n")
    with pytest.raises(ConfigError, match=r"fancy.levels: expected one of"):
        load_variants(bad)


@pytest.mark.slow
def test_a_checkpoint_saved_before_curricula_restores_and_other_gaps_still_fail(
        generated_run, tmp_path, monkeypatch):
    from train.run import checkpoint

    config, trainer, runner = generated_run
    path = checkpoint.save(tmp_path / "c.msgpack", config, runner, {"steps": 0})
    cfg, meta, raw = checkpoint.read(path)
    old = {k: v for k, v in raw.items() if k not in ("levels", "curriculum")}
    old["env_states"] = {i: {**{f: v for f, v in s.items() if f != "next_level"},
                             "world": {f: v for f, v in s["world"].items()
                                       if f not in ("seed", "humans")}}
                         for i, s in raw["env_states"].items()}
    monkeypatch.setattr(checkpoint, "read", lambda p: (cfg, meta, old))
    restored, _ = checkpoint.restore(path, trainer)
    for a, b in zip(jax.tree.leaves(restored), jax.tree.leaves(runner), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    broken = {k: v for k, v in old.items() if k != "returns"}
    monkeypatch.setattr(checkpoint, "read", lambda p: (cfg, meta, broken))
    with pytest.raises(ValueError, match="does not fit this configuration.*returns"):
        checkpoint.restore(path, trainer)
