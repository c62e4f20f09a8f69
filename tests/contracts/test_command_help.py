"""Every command's ``--help`` prints its usage and exits 0 (an argparse help string with a bare
``%`` crashes ``--help`` with "ValueError: incomplete format", as train.reports.sweep_table's
did)."""

import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODULES = ["train.cli", "train.ablation", "train.reports.curves", "train.reports.marl_eval",
           "train.reproduce", "train.run.socialgym_config", "train.sweep", "train.tables",
           "train.transfer",
           "train.reports.sweep_table", "sgjax.command",
           "sgjax.evaluation.metrics.catalogue", "train.reports.result_schemas"]
# bench/ and scripts/ files that read arguments (make_maps and make_pictures take none).
FILES = sorted(str(p.relative_to(ROOT)) for folder in ("bench", "scripts")
               for p in (ROOT / folder).glob("*.py") if "argparse" in p.read_text())


def load_file(relative: str):
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location(f"_help_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(path.parent))  # bench files import their siblings
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(path.parent))
    return module


@pytest.mark.parametrize("name", MODULES + FILES)
def test_help_prints_usage(name, monkeypatch, capsys):
    if name.endswith(".py"):
        if "torch" in (ROOT / name).read_text():
            pytest.importorskip("torch", reason="the file imports torch (pip install torch)")
        module = load_file(name)
    else:
        module = importlib.import_module(name)
    monkeypatch.setattr(sys, "argv", [name, "--help"])
    with pytest.raises(SystemExit) as exited:
        module.main()
    assert exited.value.code in (0, None)
    assert "usage:" in capsys.readouterr().out
