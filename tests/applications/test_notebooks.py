"""The notebooks run top to bottom at a small size (``SGJAX_NOTEBOOK_SMALL=1``)."""

import json
import os
from pathlib import Path

import matplotlib
import pytest

ROOT = Path(__file__).resolve().parents[2]


def run_notebook(path: Path) -> dict:
    """Execute every code cell of ``path`` in one namespace; return the namespace."""
    matplotlib.use("Agg")
    cells = json.loads(path.read_text())["cells"]
    namespace: dict = {"__name__": "__notebook__"}
    for i, cell in enumerate(cells):
        if cell["cell_type"] != "code":
            continue
        source = "".join(cell["source"])
        exec(compile(source, f"{path.name}[cell {i}]", "exec"), namespace)  # noqa: S102
    return namespace


@pytest.mark.slow
@pytest.mark.parametrize("name", ["quickstart.ipynb", "ablation.ipynb"])
def test_notebook_runs(name, monkeypatch):
    monkeypatch.setenv("SGJAX_NOTEBOOK_SMALL", "1")
    monkeypatch.chdir(ROOT)
    namespace = run_notebook(ROOT / "notebooks" / name)
    if name == "ablation.ipynb":
        assert len(namespace["scores"]) == (len(namespace["variants"]) + 1) * namespace["SEEDS"]
    else:
        assert len(namespace["values"]) == 2
    assert os.environ["SGJAX_NOTEBOOK_SMALL"] == "1"
