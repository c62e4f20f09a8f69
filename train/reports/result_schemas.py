"""JSON Schemas of the trainer's result files, one per ``schema_version``, and of every result
file at once (``docs/results/schema.json``).

- ``sgjax.reproduce/1``: ``results.json`` of ``python -m train.reproduce`` (the paper's Tables
  3-4: per-seed values of every metric per mini-game, baseline and robot count, and per-episode
  team success for the paired comparisons);
- ``sgjax.ablation/1``: ``ablation.json`` of ``python -m train.ablation`` (Table 5);
- ``sgjax.sweep/1``: ``results.json`` of ``python -m train.sweep``;
- ``sgjax.seed_spread/1``: ``RUN/eval/seed_spread.json`` of a training run of several seeds
  (every seed's team success on the final evaluation's episodes, the aggregate over seeds and
  each seed's paired difference against the baseline);
- ``sgjax.paired/1``: ``RUN/eval/paired.json`` of a training run with a baseline (the
  evaluated policy's and the baseline's team success on the same episodes per robot count, and
  their paired difference);
- ``sgjax.transfer/1``: ``transfer.json`` of ``python -m train.transfer`` (trained runs on
  held-out worlds: every seed's team success per episode on every map beside Only Local's, the
  paired comparisons);
- and sgjax's own ``sgjax.evaluate/1`` (:mod:`sgjax.evaluation.result_schema`).

``RESULT_SCHEMAS`` maps every version to its schema (draft 2020-12); ``schema_for(document)``
picks a document's. The tests validate every command's output against them with
``jsonschema`` (a test dependency), and ``docs/results/schema.json`` is ``all_schemas()``,
written by ``python -m train.reports.result_schemas --write FILE``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from sgjax.evaluation import result_schema as evaluate_schema
from sgjax.evaluation.provenance import PROVENANCE_SCHEMA
from sgjax.evaluation.result_schema import COUNT_KEY, NUMBER_OR_NULL, SECONDS, SUMMARY

REPRODUCE = "sgjax.reproduce/1"
ABLATION = "sgjax.ablation/1"
SWEEP = "sgjax.sweep/1"
SEED_SPREAD = "sgjax.seed_spread/1"
PAIRED = "sgjax.paired/1"
TRANSFER = "sgjax.transfer/1"

_PER_SEED_METRICS = {
    "type": "object",
    "properties": {"team_success_by_episode": {
        "type": "array", "items": {"type": "array", "items": {"type": "number"}}}},
    "additionalProperties": {"type": "array", "items": NUMBER_OR_NULL},
}

REPRODUCE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax train.reproduce results.json",
    "type": "object",
    "required": ["schema_version", "provenance", "profile", "seeds", "total_steps", "num_envs",
                 "episodes", "baseline_episodes", "counts", "seed", "results", "seconds",
                 "runs"],
    "properties": {
        "schema_version": {"const": REPRODUCE},
        "provenance": PROVENANCE_SCHEMA,
        "earlier_provenance": {"type": "array", "items": PROVENANCE_SCHEMA},
        "profile": {"enum": ["sgjax", "socialgym"]},
        "seeds": {"type": "integer", "minimum": 1},
        "total_steps": {"type": ["integer", "null"]},
        "num_envs": {"type": "integer", "minimum": 1},
        "episodes": {"type": "integer", "minimum": 1},
        "baseline_episodes": {"type": "integer", "minimum": 1},
        "counts": {"type": "array", "items": {"type": "integer", "minimum": 1}},
        "seed": {"type": "integer"},
        "time_limit": NUMBER_OR_NULL,
        "train_seconds": {"type": "object"},
        "cell_seconds": {"type": "object", "additionalProperties": SECONDS},
        "seconds": SECONDS,
        "runs": {"type": "integer", "minimum": 1},
        # mini-game -> baseline -> robot count -> metric -> one value per training seed
        "results": {"type": "object", "additionalProperties": {
            "type": "object", "additionalProperties": {
                "type": "object", "patternProperties": {COUNT_KEY: _PER_SEED_METRICS},
                "additionalProperties": False}}},
    },
}

ABLATION_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax train.ablation ablation.json",
    "type": "object",
    "required": ["schema_version", "provenance", "config", "seeds", "episodes", "robots",
                 "team_success", "team_success_by_robots", "variants", "seconds"],
    "properties": {
        "schema_version": {"const": ABLATION},
        "provenance": PROVENANCE_SCHEMA,
        "config": {"type": "object"},
        "seeds": {"type": "integer", "minimum": 1},
        "episodes": {"type": "integer", "minimum": 1},
        "robots": {"type": "integer", "minimum": 1},
        # variant -> one team success per training seed (at ``robots``)
        "team_success": {"type": "object", "additionalProperties": {
            "type": "array", "items": {"type": "number"}}},
        "team_success_by_robots": {"type": "object", "patternProperties": {
            COUNT_KEY: {"type": "object"}}, "additionalProperties": False},
        "paired": {"type": "object"},
        "variants": {"type": "object"},
        # group of variants -> where and how long it trained (a resumed run's groups may
        # come from other commits or machines)
        "groups": {"type": "object", "additionalProperties": {
            "type": "object", "properties": {
                "git": {"type": "object"}, "cpu": {"type": "string"}, "seconds": SECONDS}}},
        "seconds": SECONDS,
    },
}

SWEEP_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax train.sweep sweep.json",
    "type": "object",
    "required": ["schema_version", "provenance", "study", "space", "direction", "best",
                 "trials"],
    "properties": {
        "schema_version": {"const": SWEEP},
        "provenance": PROVENANCE_SCHEMA,
        "study": {"type": "string"},
        "space": {"type": "object", "required": ["objective", "trial", "sweep", "params"]},
        "direction": {"enum": ["maximize", "minimize"]},
        "best": {"type": ["object", "null"], "required": ["number", "value", "params"]},
        "trials": {"type": "array", "items": {
            "type": "object",
            "required": ["number", "state", "value", "params", "intermediate", "user_attrs"],
            "properties": {
                "number": {"type": "integer", "minimum": 0},
                "state": {"enum": ["running", "waiting", "complete", "pruned", "fail"]},
                "value": NUMBER_OR_NULL,
                "params": {"type": "object"},
                # evaluation index (1, 2, ...) -> the objective at that evaluation
                "intermediate": {"type": "object", "patternProperties": {
                    COUNT_KEY: {"type": "number"}}, "additionalProperties": False},
                "user_attrs": {"type": "object"}}}},
        "plots": {"type": "array", "items": {"type": "string"}},
    },
}

_BOUNDED = {"type": "object", "required": ["mean", "mean_low", "mean_high", "iqm", "iqm_low",
                                             "iqm_high", "seeds"]}
def _run_eval_schema(version: str, file: str, baseline: dict[str, Any],
                     cell: dict[str, Any]) -> dict[str, Any]:
    """The schema of a training run's ``eval/<file>``: the evaluated policy, its baseline
    (``baseline``: its JSON type), the episodes and ``scenario -> robot count -> cell``."""
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": f"sgjax training run eval/{file}",
        "type": "object",
        "required": ["schema_version", "provenance", "policy", "baseline", "episodes",
                     "scenarios"],
        "properties": {
            "schema_version": {"const": version},
            "provenance": PROVENANCE_SCHEMA,
            "policy": {"type": "string"},
            "baseline": baseline,
            "episodes": {"type": "integer", "minimum": 1},
            "scenarios": {"type": "object", "additionalProperties": {
                "type": "object", "patternProperties": {COUNT_KEY: cell},
                "additionalProperties": False}},
        },
    }


# each seed's team success, the aggregate over seeds and each seed's paired difference
SEED_SPREAD_SCHEMA = _run_eval_schema(
    SEED_SPREAD, "seed_spread.json", {"type": ["string", "null"]},
    {"type": "object", "required": ["team_success", "aggregate"], "properties": {
        "team_success": {"type": "array", "items": {"type": "number"}, "minItems": 2},
        "aggregate": _BOUNDED,
        "paired": {"type": "array", "items": SUMMARY}}})
# both policies' team success and their paired difference
PAIRED_SCHEMA = _run_eval_schema(
    PAIRED, "paired.json", {"type": "string"},
    {"type": "object", "required": ["policy", "baseline", "difference"], "properties": {
        "policy": SUMMARY, "baseline": SUMMARY, "difference": SUMMARY}})

_EPISODES = {"type": "array", "items": NUMBER_OR_NULL}
_PER_EPISODE = {"type": "object", "required": ["team_success", "collisions", "makespan"],
                "additionalProperties": _EPISODES}
_SEEDS_BY_EPISODE = {"type": "array", "items": _EPISODES, "minItems": 1}
_RUNS = {"type": "object", "additionalProperties": {
    "type": "object", "required": ["checkpoint", "sha256", "seeds", "trained_on",
                                   "deterministic", "options"]}}
TRANSFER_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax train.transfer transfer.json",
    "type": "object",
    "required": ["schema_version", "provenance", "arms", "reference", "margin", "robots",
                 "episodes", "seed", "sets", "maps"],
    "properties": {
        "schema_version": {"const": TRANSFER},
        "provenance": PROVENANCE_SCHEMA,
        "arms": _RUNS,
        # own specialists that are no arm, each played on its own shipped map only
        "specialists": _RUNS,
        "reference": {"type": ["string", "null"]},
        "margin": {"type": "number", "exclusiveMinimum": 0},
        "robots": {"type": "integer", "minimum": 1},
        "episodes": {"type": "integer", "minimum": 1},
        "seed": {"type": "integer"},
        "sets": {"type": "array", "items": {"type": "string"}},
        "fingerprint": {"type": "string"},  # a resume key of the first files, since unused
        "pending": {"type": "array", "items": {"type": "string"}},  # maps still to play
        # maps some arm has not played yet (or of other sets), kept for a later --resume
        "unfinished": {"type": "object"},
        # the worst alpha% per arm and generated family: {alpha: [one value per seed]};
        # "protocol" "sfl": rollout B played only the worst worlds; its own provenance (it
        # may be played by later code than the maps)
        "worst": {"type": "object", "required": ["worlds", "alphas", "protocol", "arms"],
                  "properties": {
            "worlds": {"type": "integer", "minimum": 1},
            "alphas": {"type": "array", "items": {"type": "string"}},
            "protocol": {"enum": ["sfl"]},
            "provenance": PROVENANCE_SCHEMA,
            "pending": {"type": "array", "items": {"type": "string"}},
            "arms": {"type": "object", "additionalProperties": {
                "type": "object", "required": ["sha256", "families"]}}}},
        # "<set>/<map>" -> the map's episodes: Only Local's [E], every arm's [S, E] per metric
        "maps": {"type": "object", "additionalProperties": {
            "type": "object",
            "required": ["set", "name", "scenario", "worlds", "robots", "only_local", "arms",
                         "paired"],
            "properties": {
                "robots": {"type": "integer", "minimum": 1},
                "only_local": _PER_EPISODE,
                "arms": {"type": "object", "additionalProperties": {
                    "type": "object", "required": ["team_success", "collisions", "makespan"],
                    "additionalProperties": _SEEDS_BY_EPISODE}},
                "checkpoints": {"type": "object", "additionalProperties": {"type": "string"}},
                # the arm or specialist trained on this map alone; its values under arms
                "own_specialist": {"type": "string"},
                "paired": {"type": "object", "additionalProperties": SUMMARY}}}},
    },
}


RESULT_SCHEMAS: dict[str, dict[str, Any]] = {
    **evaluate_schema.RESULT_SCHEMAS, REPRODUCE: REPRODUCE_SCHEMA, ABLATION: ABLATION_SCHEMA,
    SWEEP: SWEEP_SCHEMA, SEED_SPREAD: SEED_SPREAD_SCHEMA, PAIRED: PAIRED_SCHEMA,
    TRANSFER: TRANSFER_SCHEMA}


def schema_for(document: Any) -> dict[str, Any]:
    """The schema of any result document, sgjax's or the trainer's, by its ``schema_version``."""
    return evaluate_schema.schema_for(document, RESULT_SCHEMAS)


def all_schemas() -> dict[str, Any]:
    """Every result file's schema and the provenance block's, as one JSON document."""
    return {"provenance": PROVENANCE_SCHEMA, "results": RESULT_SCHEMAS}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="Write the result files' JSON Schemas")
    parser.add_argument("--write", required=True, metavar="FILE")
    args = parser.parse_args(argv)
    Path(args.write).write_text(json.dumps(all_schemas(), indent=1) + "\n")
    print(f"wrote {args.write}")


if __name__ == "__main__":
    main()
