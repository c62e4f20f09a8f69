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
