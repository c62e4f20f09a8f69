"""SocialGym 2.0 experiment configs convert into train configs that train (the paper's Listing 1,
``tests/data/socialgym_listing1.json``, as printed there: comments and a trailing comma)."""

from pathlib import Path

import jax
import numpy as np
import pytest

from sgjax.terms.base import ConfigError
from train.algorithm.config import apply_overrides, config_from_dict
from train.algorithm.trainer import Trainer
from train.run.socialgym_config import DEFAULTS, convert, read_socialgym_config

LISTING = Path(__file__).resolve().parents[1] / "data" / "socialgym_listing1.json"


def test_listing_1_converts_key_by_key():
    config, rows = convert(read_socialgym_config(LISTING), str(LISTING))
    assert sorted(key for key, _, _ in rows) == sorted(DEFAULTS)  # every key, once
    env = config["env"]
    assert env["scenarios"] == ["doorway"] and env["dt"] == 0.025
    assert env["curriculum"] == [[0, 3], [35 * 3200, 4], [70 * 3200, 5]]
    assert config["evaluation"]["num_agents"] == [3, 4, 5, 7, 10]
    assert config["evaluation"]["episodes"] == 25 and config["evaluation"]["deterministic"]
    assert config["algorithm"]["total_steps"] == 250000
    a = config["algorithm"]
    assert a["num_envs"] * a["num_steps"] == 4096 and a["update_epochs"] == 10
    # SB3's batch_size 64 asks for 320 minibatches of the 20480 transitions; sgjax splits whole
    # sequences (16 envs x 5 slots), so 80: a config that trains as it is.
    assert a["ent_coef"] == 0.0 and a["num_minibatches"] == 80
    Trainer(config_from_dict(config))  # raised "num_minibatches must divide" before
    assert env["rewards"]["zone_order"]["any_order"] is True  # run_type AO
    assert {"stuck": {"distance": 0.25, "steps": 100, "penalty": -100000.0}} in env["enders"]
    others = next(o["others"] for o in env["observations"] if isinstance(o, dict) and "others" in o)
    assert others["features"] == ["position", "heading", "velocity", "mask"]
    assert others["k"] == 9 and others["relative_velocity"]  # all others of 10 robots
    assert env["rewards"]["collision"] == {"per_step": True, "weight": 10.0}
    assert "proximity" not in env["rewards"]
    assert "zone_priority" in env["observations"]
    assert config["network"]["others_encoder"] == "lstm"
    assert config["logging"]["out"] == "runs/door/ao"
    became = {key: text for key, _, text in rows}
    assert "nothing" in became["device"] and "unused" in became["intermediate_eval_trials"]
    # SocialGym judged its best model (ending_eval_with_best, true by default); false: the
    # final weights, as every sgjax command does
    assert config["evaluation"]["checkpoint"] == "best"
    assert "best" in became["ending_eval_with_best"]
    final, rows = convert({**read_socialgym_config(LISTING), "ending_eval_with_best": False},
                          str(LISTING))
    assert final["evaluation"]["checkpoint"] == "final"
    assert "ended with" in {key: text for key, _, text in rows}["ending_eval_with_best"]
    assert config_from_dict(final).evaluation.checkpoint == "final"


@pytest.mark.parametrize("edit, message", [
    ({"num_agentz": 3}, r"num_agentz: not a SocialGym 2.0 config key \(did you mean 'num_agents'"),
    ({"entropy_constant_penalty": None}, "multiplicative stuck penalty"),
    ({"policy_algo_name": "DQN"}, "policy_algo_name: \"DQN\" cannot be honoured"),
    ({"experiment_names": ["envs_multi"]}, "import its map with sgjax.maps.import_socialgym"),
    ({"policy_algo_kwargs": {"n_steps": 64, "target_kl": 0.1}},
     r"no sgjax equivalent for \['target_kl'\]"),
])
def test_keys_that_cannot_be_honoured_are_named(edit, message):
    data = {**read_socialgym_config(LISTING), **edit}
    with pytest.raises(ConfigError, match=message):
        convert(data, "exp.json")


@pytest.mark.slow
def test_listing_1_trains(capsys):
    """Converted and shrunk with --set style overrides, it builds a trainer whose updates learn
    something (finite losses, changed weights); ``python -m train --config`` reads it the same
    way, printing the key table first."""
    from train.cli import _socialgym_config

    overrides = ["algorithm.total_steps=256", "algorithm.num_steps=16",
                 "algorithm.num_minibatches=2", "algorithm.update_epochs=1"]
    config = _socialgym_config(str(LISTING), overrides)
    assert "| `run_type` | `\"AO\"` |" in capsys.readouterr().out
    converted, _ = convert(read_socialgym_config(LISTING))
    assert config == config_from_dict(apply_overrides(converted, overrides))
    trainer = Trainer(config)
    runner = trainer.init(jax.random.PRNGKey(0))
    after, logs = jax.jit(lambda r: trainer.update_chunk(r, 1))(runner)
    assert all(np.isfinite(np.asarray(v)).all() for v in logs.values())
    assert any(not np.allclose(a, b) for a, b in zip(jax.tree.leaves(after.params),
                                                     jax.tree.leaves(runner.params),
                                                     strict=True))


@pytest.mark.parametrize("baseline", ["cadrl", "cadrl_lstm", "any_order", "enforced_order"])
def test_reproduce_socialgym_profile_is_listing_1_per_run_type(baseline):
    """train.reproduce --profile socialgym: each baseline as the paper's Listing 1 with its run
    type, on every mini-game; Only Local at SocialGym's step and time limit."""
    from sgjax.evaluation.protocols import PAPER
    from train.reproduce import only_local_options, socialgym_baseline_config

    for scenario in PAPER.scenarios:
        config = socialgym_baseline_config(baseline, scenario, 3, 250_000, 0, PAPER.num_agents,
                                           PAPER.episodes)
        physics = config.env.options.physics
        assert physics.dt == 0.025 and physics.time_limit == 80.0
        assert config.env.scenarios == (scenario,) and config.num_seeds == 3
        assert config.env.curriculum == ((0, 3), (35 * 3200, 4), (70 * 3200, 5))
        assert config.evaluation.deterministic and config.algorithm.total_steps == 250_000
    assert config.network.kind == ("lstm" if baseline == "cadrl_lstm" else "mlp")
    zones = "zone_order" in str(config.env.options.terms.rewards)
    assert zones == (baseline in ("any_order", "enforced_order"))
    settings = only_local_options("socialgym", None).physics
    assert settings.dt == 0.025 and settings.time_limit == 80.0
    with pytest.raises(ValueError, match="not one"):
        socialgym_baseline_config(baseline, "office", 1, 1000, 0, [3], 1)


@pytest.mark.parametrize("profile", ["sgjax", "socialgym"])
def test_only_local_ends_its_episodes_as_the_trained_baselines_do(profile):
    """Only Local runs in the trained baselines' world with their enders (the stuck ender
    included), so its success compares with theirs."""
    import sgjax
    from train.reproduce import (
        BASELINES,
        baseline_config,
        only_local_options,
        socialgym_baseline_config,
    )

    mine, _ = sgjax.make("doorway", options=only_local_options(profile, None))
    assert any(type(t).__name__ == "Stuck" for t in mine.config.enders.terms)
    for name in (b for b, run in BASELINES.items() if run is not None):
        config = (baseline_config(name, "doorway", 1, 1, 1, 0, 75.0) if profile == "sgjax"
                  else socialgym_baseline_config(name, "doorway", 1, 1, 0, [3], 1))
        theirs, _ = sgjax.make("doorway", options=config.env.options)
        assert mine.config.enders == theirs.config.enders, name
        assert mine.config.arrived == theirs.config.arrived
