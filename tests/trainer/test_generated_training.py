"""The trainer on generated worlds: ``env.scenarios: [generated:doorway]`` trains with a world
per environment, a new one at every episode, and checkpoints keep the ranges."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from test_train import tiny

from train.algorithm.trainer import Trainer, seed_keys


@pytest.mark.slow
def test_a_run_on_generated_worlds_trains_on_a_world_per_environment():
    config = tiny(env={"scenarios": ["generated:doorway"], "curriculum": [[0, 2]],
                       "time_limit": 1.0, "world_ranges": {"door_width": [1.0, 1.6]}})
    assert config.env.options.worlds.ranges() == {"door_width": (1.0, 1.6)}
    trainer = Trainer(config)
    runners = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
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
    config = tiny(env={"scenarios": ["generated:doorway", "doorway"], "curriculum": [[0, 2]],
                       "time_limit": 1.0},
                  levels={"method": method, "buffer_size": 8, "min_fill": 0.25,
                          "replay_prob": 1.0, "mutate_prob": 0.5},
                  num_seeds=2)
    trainer = Trainer(config)
    assert trainer.batch.level_sources[1] is None  # the shipped doorway keeps its map
    runners = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
    assert runners.levels[1] is None and not np.asarray(runners.levels[0].filled).any()
    runners, logs = jax.jit(lambda r: trainer.update_chunk_lanes(r, 6))(runners)
    assert all(np.all(np.isfinite(np.asarray(v))) for v in logs.values())
    buffers = runners.levels[0]
    filled = np.asarray(buffers.filled)  # [seeds, slots]
    assert filled.any(axis=1).all()
    # each lane its own levels, each one played in a valid world of its own seed
    assert not np.array_equal(np.asarray(buffers.seed)[0][filled[0]],
                              np.asarray(buffers.seed)[1][filled[1]])
    assert np.asarray(logs["levels_fill"])[:, -1].min() > 0
    # once the buffer is filled enough every next episode is a chosen level (replay_prob 1)
    ready = np.asarray(logs["levels_fill"]) >= 0.25
    assert (np.asarray(logs["levels_replayed"])[:, 1:][ready[:, :-1]] == 1.0).all()
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
