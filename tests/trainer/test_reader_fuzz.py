"""The trainer's readers never crash on bad input: hypothesis corrupts a valid training config
(any key's value replaced by any YAML value, a key added), ``--set`` overrides, sweep space
files and checkpoint files (truncated, or foreign bytes), and every result is a valid object or
a ``ConfigError`` / ``ValueError`` naming the source (the file, or the override); never another
exception."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from fuzzing import JSON_VALUES, places, replaced
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sgjax.terms.base import ConfigError
from train.algorithm.config import config_from_dict, load_config
from train.run import checkpoint
from train.run.search_space import space_from_dict

ROOT = Path(__file__).resolve().parents[2]
BASE = load_config(ROOT / "train" / "configs" / "doorway.yaml").to_dict()
SPACE = yaml.safe_load((ROOT / "train" / "configs" / "sweeps" / "intersection.yaml").read_text())

FAST = settings(max_examples=60, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@FAST
@given(data=st.data(), new=JSON_VALUES)
def test_a_corrupted_train_config_is_a_config_error_naming_the_source(data, new):
    path, _ = data.draw(st.sampled_from(list(places(BASE))))
    corrupted = replaced(BASE, path, new)
    try:
        config = config_from_dict(corrupted, "fuzzed.yaml")
    except ConfigError as err:
        assert "fuzzed.yaml" in str(err), str(err)
    else:
        assert config.to_dict()  # a valid config survives its own round trip
        config_from_dict(config.to_dict(), "round trip")


@FAST
@given(key=st.text(min_size=1, max_size=12), value=st.text(max_size=12))
def test_any_set_override_is_applied_or_named(key, value):
    override = f"{key}={value}"
    try:
        load_config(ROOT / "train" / "configs" / "doorway.yaml", [override])
    except ConfigError as err:
        text = str(err)
        assert "doorway.yaml" in text or "--set" in text, text


@FAST
@given(data=st.data(), new=JSON_VALUES)
def test_a_corrupted_space_file_is_a_config_error_naming_the_file(data, new):
    path, _ = data.draw(st.sampled_from(list(places(SPACE))))
    corrupted = replaced(SPACE, path, new)
    try:
        space_from_dict(corrupted, "fuzzed-space.yaml")
    except ConfigError as err:
        assert "fuzzed-space.yaml" in str(err), str(err)


@pytest.fixture(scope="module")
def saved_checkpoint(tmp_path_factory) -> bytes:
    """A real checkpoint file's bytes (a tiny config's fresh runner)."""
    import jax

    from train.algorithm.trainer import Trainer, seed_keys

    config = config_from_dict({
        "env": {"scenarios": ["open"], "curriculum": [[0, 2]], "observations": "default"},
        "algorithm": {"num_envs": 2, "num_steps": 4, "total_steps": 8, "num_minibatches": 2},
        "network": {"hidden": [8]}})
    trainer = Trainer(config)
    runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
    path = tmp_path_factory.mktemp("checkpoint") / "latest.msgpack"
    checkpoint.save(path, config, runner, {"steps": 0, "updates": 0}, trainer.actor)
    assert checkpoint.read(path)[0] == config
    return path.read_bytes()


@settings(max_examples=40, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_a_truncated_or_foreign_checkpoint_is_an_error_naming_the_file(
        data, saved_checkpoint, tmp_path):
    kind = data.draw(st.sampled_from(["truncated", "foreign", "flipped"]))
    if kind == "truncated":
        cut = data.draw(st.integers(0, len(saved_checkpoint) - 1))
        content = saved_checkpoint[:cut]
    elif kind == "foreign":
        content = data.draw(st.binary(max_size=200))
    else:
        at = data.draw(st.integers(0, 400))
        content = bytearray(saved_checkpoint)
        content[at] ^= 0xFF
        content = bytes(content)
    path = tmp_path / "broken.msgpack"
    path.write_bytes(content)
    try:
        checkpoint.read(path)
    except ValueError as err:
        assert str(path) in str(err), str(err)
