"""Shared check of a result file's provenance block (tests/evaluation/test_provenance.py and the
command tests)."""

import subprocess

import jsonschema

from sgjax.evaluation import provenance as prov


def check_block(block: dict) -> None:
    """``block`` follows :data:`PROVENANCE_SCHEMA` and names a commit of this repository."""
    jsonschema.validate(block, prov.PROVENANCE_SCHEMA)
    commit = block["git"]["commit"]
    if (prov.REPOSITORY / ".git").exists():
        assert commit is not None, block["git"]
        subprocess.run(["git", "-C", str(prov.REPOSITORY), "cat-file", "-e",
                        f"{commit}^{{commit}}"], check=True)
