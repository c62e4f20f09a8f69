"""Shared checks of a result file and its provenance block (tests/evaluation/test_provenance.py
and the command tests)."""

import subprocess

import jsonschema

from sgjax.evaluation import provenance as prov
from train.reports.result_schemas import schema_for


def check_block(block: dict) -> None:
    """``block`` follows :data:`PROVENANCE_SCHEMA` and names a commit of this repository."""
    jsonschema.validate(block, prov.PROVENANCE_SCHEMA)
    commit = block["git"]["commit"]
    if (prov.REPOSITORY / ".git").exists():
        assert commit is not None, block["git"]
        subprocess.run(["git", "-C", str(prov.REPOSITORY), "cat-file", "-e",
                        f"{commit}^{{commit}}"], check=True)


def check_document(document: dict) -> None:
    """A whole result file follows the schema its ``schema_version`` names, and its provenance
    block names a commit of this repository."""
    jsonschema.validate(document, schema_for(document))
    check_block(document["provenance"])
