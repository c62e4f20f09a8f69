"""The JSON Schema of sgjax's own result file, and the pieces result schemas share.

Every result file names its format in ``schema_version``. sgjax writes one:

- ``sgjax.evaluate/1``: ``metrics.json`` of ``sgjax evaluate --out`` and of a training run's
  final evaluation (``RUN/eval/metrics.json``);
- a run's ``provenance.json`` is the provenance block itself (``sgjax.provenance/1``,
  :data:`sgjax.evaluation.provenance.PROVENANCE_SCHEMA`).

The trainer's result files (``train.reproduce``, ``train.ablation``, ``train.sweep``, a run of
several seeds) have their schemas with the trainer (``train.reports.result_schemas``, which
also writes ``docs/results/schema.json``), built from the pieces here: :data:`SUMMARY` (a
metric's mean and interval), :data:`NUMBER_OR_NULL`, :data:`SECONDS` and :data:`COUNT_KEY`.
``RESULT_SCHEMAS`` maps each version to its schema (draft 2020-12); ``schema_for(document)``
picks a document's.
"""

from __future__ import annotations

from typing import Any

from sgjax.evaluation.provenance import PROVENANCE_SCHEMA

EVALUATE = "sgjax.evaluate/1"

NUMBER_OR_NULL = {"type": ["number", "null"]}
SUMMARY = {
    "type": "object", "required": ["mean", "ci_low", "ci_high", "std", "n"],
    "properties": {"mean": NUMBER_OR_NULL, "ci_low": NUMBER_OR_NULL,
                   "ci_high": NUMBER_OR_NULL, "std": NUMBER_OR_NULL,
                   "n": {"type": "integer", "minimum": 0}},
}
SECONDS = {"type": "object", "additionalProperties": {"type": "number"}}
COUNT_KEY = "^[0-9]+$"

EVALUATE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax evaluate metrics.json",
    "type": "object",
    "required": ["schema_version", "sgjax_version", "provenance", "confidence", "interval",
                 "constants", "definitions", "results"],
    "properties": {
        "schema_version": {"const": EVALUATE},
        "sgjax_version": {"type": "string"},
        "provenance": PROVENANCE_SCHEMA,
        "confidence": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 1},
        "interval": {"type": "string"},
        "constants": {"type": "object"},
        "definitions": {"type": "object", "additionalProperties": {
            "type": "object", "required": ["unit", "level", "definition", "source"]}},
        "results": {"type": "array", "items": {
            "type": "object",
            "required": ["scenario", "policy", "num_agents", "episodes", "seed", "metrics"],
            "properties": {
                "scenario": {"type": "string"}, "policy": {"type": "string"},
                "num_agents": {"type": "integer", "minimum": 1},
                "episodes": {"type": "integer", "minimum": 1},
                "seed": {"type": "integer"},
                "metrics": {"type": "object", "additionalProperties": SUMMARY}}}},
    },
}

CROWD_FIT = "sgjax.crowd_fit/1"
_SCORES = {"type": "object", "required": ["ade", "fde", "collisions", "pedestrians"],
           "properties": {"ade": {"type": "number", "minimum": 0},
                          "fde": {"type": "number", "minimum": 0},
                          "collisions": {"type": "number", "minimum": 0, "maximum": 1},
                          "pedestrians": {"type": "integer", "minimum": 0}}}
_DIFFERENCE = {"type": "object", "required": ["mean", "ci_low", "ci_high", "windows"],
               "properties": {"mean": NUMBER_OR_NULL, "ci_low": NUMBER_OR_NULL,
                              "ci_high": NUMBER_OR_NULL,
                              "windows": {"type": "integer", "minimum": 0}}}
CROWD_FIT_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "sgjax crowd fit / crowd loso crowd_fit.json",
    "type": "object",
    "required": ["schema_version", "provenance", "row_seconds", "observe", "predict", "rows"],
    "properties": {
        "schema_version": {"const": CROWD_FIT},
        "provenance": PROVENANCE_SCHEMA,
        "row_seconds": {"type": "number", "exclusiveMinimum": 0},
        "observe": {"type": "integer", "minimum": 2},
        "predict": {"type": "integer", "minimum": 1},
        "rows": {"type": "array", "minItems": 1, "items": {
            "type": "object",
            "required": ["model", "train", "test", "steps", "loss", "constants", "published",
                         "fit_seconds"],
            "properties": {
                "model": {"enum": ["moussaid", "helbing", "hsfm", "orca"]},
                "train": {"type": "array", "items": {"type": "string"}, "minItems": 1},
                "test": {"type": ["string", "null"]},
                "steps": {"type": "integer", "minimum": 1},
                "constants": {"type": "object", "additionalProperties": {"type": "number"}},
                "trajnet": {"type": "object", "additionalProperties": {"type": "number"}},
                "rollout": {"type": "object", "required": ["rows", "steps", "loss"],
                            "properties": {"rows": {"type": "integer", "minimum": 1},
                                           "steps": {"type": "integer", "minimum": 1}}},
                "scores": {"type": "object", "additionalProperties": _SCORES},
                "fitted_minus": {"type": "object", "additionalProperties": _DIFFERENCE}}}},
    },
}

RESULT_SCHEMAS: dict[str, dict[str, Any]] = {EVALUATE: EVALUATE_SCHEMA,
                                             CROWD_FIT: CROWD_FIT_SCHEMA}


def schema_for(document: Any, schemas: dict[str, dict[str, Any]] = RESULT_SCHEMAS
               ) -> dict[str, Any]:
    """The schema of a result document, by its ``schema_version``, among ``schemas``."""
    version = document.get("schema_version") if isinstance(document, dict) else None
    if version not in schemas:
        raise ValueError(f"schema_version {version!r}: not a result file sgjax knows; "
                         f"known versions are {', '.join(schemas)}")
    return schemas[version]
