"""Result files carry their provenance: the commit (which exists), versions, machine, command,
seeds; the block follows its JSON schema."""

import json
import math

import jsonschema
import pytest
from provenance_checks import check_block, check_document

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
    monkeypatch.delenv(prov.COMMIT_VARIABLE, raising=False)
    state = prov.git_state()
    assert state["commit"] is None and state["dirty"] is None
    assert "not a git checkout" in state["error"] and prov.COMMIT_VARIABLE in state["error"]
    jsonschema.validate(prov.provenance(), prov.PROVENANCE_SCHEMA)


def test_an_installed_sgjax_takes_the_commit_from_the_environment(tmp_path, monkeypatch):
    checkout = prov.REPOSITORY
    monkeypatch.setattr(prov, "REPOSITORY", tmp_path)
    commit = "0123456789abcdef0123456789abcdef01234567"
    monkeypatch.setenv(prov.COMMIT_VARIABLE, commit)
    assert prov.git_state() == {"commit": commit, "dirty": None,
                                "source": prov.COMMIT_VARIABLE}
    jsonschema.validate(prov.provenance(), prov.PROVENANCE_SCHEMA)
    for bad in ("55d7da2", commit.upper(), commit + "0", ""):
        monkeypatch.setenv(prov.COMMIT_VARIABLE, bad)
        with pytest.raises(ValueError, match=prov.COMMIT_VARIABLE):
            prov.git_state()
    # A checkout's own commit wins over the variable.
    monkeypatch.setenv(prov.COMMIT_VARIABLE, commit)
    monkeypatch.setattr(prov, "REPOSITORY", checkout)
    state = prov.git_state()
    assert state["commit"] == prov._git("rev-parse", "HEAD") and "source" not in state


def test_a_checkout_that_moves_during_a_run_keeps_its_starting_commit_and_says_so(monkeypatch):
    """A long run's result names the commit its process started from (the module's import),
    not the one the checkout holds when the result is written; where they differ the block is
    dirty and names the later commit."""
    now = prov.git_state()
    monkeypatch.setattr(prov, "_AT_IMPORT", dict(now))  # nothing moved: the state as it is
    assert prov.run_git_state() == now and "now" not in prov.provenance()["git"]
    started = {"commit": "0123456789abcdef0123456789abcdef01234567", "dirty": False}
    monkeypatch.setattr(prov, "_AT_IMPORT", started)
    block = prov.provenance()
    assert block["git"] == {"commit": started["commit"], "dirty": True,
                            "now": now["commit"]}
    jsonschema.validate(block, prov.PROVENANCE_SCHEMA)


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
    document = json.loads((tmp_path / "metrics.json").read_text())
    check_document(document)
    block = document["provenance"]
    assert block["seeds"] == {"evaluation": [3]} and block["episodes_per_cell"] == 2


def test_result_schemas_reject_what_they_should_and_docs_hold_them(tmp_path):
    from sgjax.evaluation.result_schema import EVALUATE_SCHEMA
    from train.reports.result_schemas import all_schemas, schema_for

    with pytest.raises(ValueError, match="schema_version 'nope/1': not a result file"):
        schema_for({"schema_version": "nope/1"})
    good = {"schema_version": "sgjax.evaluate/1", "sgjax_version": "0.1.0",
            "provenance": prov.provenance({"a": 1}), "confidence": 0.95, "interval": "t",
            "constants": {}, "definitions": {}, "results": [
                {"scenario": "open", "policy": "only_local", "num_agents": 2, "episodes": 2,
                 "seed": 0, "metrics": {"success": {"mean": 0.5, "ci_low": 0.1,
                                                    "ci_high": 0.9, "std": 0.5, "n": 2}}}]}
    jsonschema.validate(good, EVALUATE_SCHEMA)
    for broken in ({**good, "schema_version": "sgjax.evaluate/2"},
                   {k: v for k, v in good.items() if k != "provenance"},
                   {**good, "results": [{**good["results"][0], "num_agents": 0}]},
                   {**good, "results": [{**good["results"][0],
                                         "metrics": {"success": {"mean": "high"}}}]}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, EVALUATE_SCHEMA)
    shipped = json.loads((prov.REPOSITORY / "docs" / "results" / "schema.json").read_text())
    assert shipped == json.loads(json.dumps(all_schemas())), (
        "docs/results/schema.json is stale: python -m train.reports.result_schemas "
        "--write docs/results/schema.json")


def test_probability_of_improvement_counts_pairs_and_ties_half():
    from sgjax.evaluation.statistics import probability_of_improvement

    assert probability_of_improvement([1, 2], [0, 0]) == 1.0
    assert probability_of_improvement([0, 0], [1, 2]) == 0.0
    assert probability_of_improvement([1, 3], [1, 2]) == pytest.approx((0.5 + 0 + 1 + 1) / 4)
    assert probability_of_improvement([float("nan"), 1], [0]) == 1.0
    assert math.isnan(probability_of_improvement([], [1]))


# Published before result files carried a schema and provenance (issue 39); to be replaced by
# the protocol's rerun. Every other result file in docs/results must validate.
LEGACY_RESULTS = {"results.json", "baselines/metrics.json"}


def test_every_published_result_file_follows_its_schema():
    folder = prov.REPOSITORY / "docs" / "results"
    found = sorted(p for p in folder.rglob("*.json") if p.name != "schema.json")
    checked = []
    for path in found:
        name = path.relative_to(folder).as_posix()
        if name in LEGACY_RESULTS or path.name == "marl_eval.json":
            continue  # marl_eval.json: the results.json beside it in marl-eval's layout
        if path.name == "provenance.json":  # a training run's own block, beside its results
            check_block(json.loads(path.read_text()))
        else:
            check_document(json.loads(path.read_text()))
        checked.append(name)
    assert "sweeps/doorway/sweep.json" in checked and "tuned_doorway/ablation.json" in checked
    assert "release-0.5.0/shipped/doorway/seed_spread.json" in checked
    assert "reproduce-protocol/results.json" in checked and "table5/ablation.json" in checked
    assert {p.relative_to(folder).as_posix() for p in found} >= LEGACY_RESULTS
