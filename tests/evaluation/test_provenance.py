"""Result files carry their provenance: the commit (which exists), versions, machine, command,
seeds; the block follows its JSON schema."""

import json

import jsonschema
import pytest
from provenance_checks import check_block

from sgjax.evaluation import provenance as prov


def test_block_names_this_checkout_versions_machine_and_seeds():
    block = prov.provenance({"b": 1, "a": [1, 2]}, seeds={"training": [0, 1], "evaluation": [7]},
                            episodes_per_cell=100, seconds={"train": 1.23456})
    check_block(block)
    assert block["versions"]["jax"] and block["versions"]["numpy"]
    assert block["machine"]["cpu"] and block["machine"]["cpu_count"] >= 1
    assert block["machine"]["jax_backend"] in ("cpu", "gpu", "tpu")
    assert block["seeds"] == {"training": [0, 1], "evaluation": [7]}
    assert block["seconds"] == {"train": 1.235} and block["episodes_per_cell"] == 100
    assert "pytest" in block["command"] or "python" in block["command"]
    # The hash is of the resolved configuration, whatever the key order.
    assert block["config_sha256"] == prov.config_hash({"a": [1, 2], "b": 1})
    assert prov.config_hash({"a": [1, 2], "b": 2}) != block["config_sha256"]


def test_outside_a_checkout_the_commit_is_none_and_says_why(tmp_path, monkeypatch):
    monkeypatch.setattr(prov, "REPOSITORY", tmp_path)
    state = prov.git_state()
    assert state["commit"] is None and state["dirty"] is None
    assert "not a git checkout" in state["error"]
    jsonschema.validate(prov.provenance(), prov.PROVENANCE_SCHEMA)


def test_a_block_that_breaks_the_schema_is_caught():
    block = prov.provenance()
    for broken in ({**block, "git": {"commit": "abc", "dirty": False}},  # not 40 hex digits
                   {k: v for k, v in block.items() if k != "machine"},
                   {**block, "schema": "something else"}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, prov.PROVENANCE_SCHEMA)


def test_evaluate_writes_provenance_into_metrics_json(tmp_path):
    from sgjax.environment.options import MakeOptions
    from sgjax.evaluation.evaluate import evaluate

    evaluate(["open"], ["only_local"], num_agents=[2], episodes=2, seed=3, out=tmp_path,
             options=MakeOptions.from_keywords(time_limit=3.0), log=None)
    block = json.loads((tmp_path / "metrics.json").read_text())["provenance"]
    check_block(block)
    assert block["seeds"] == {"evaluation": [3]} and block["episodes_per_cell"] == 2
