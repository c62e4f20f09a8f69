"""The README's test command is the one CI runs; shipped pictures exist for every scenario."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```bash\n(.+?)\n```", text, flags=re.S)


def test_readme_has_exactly_two_setup_commands():
    commands = readme_commands()
    assert len(commands) == 2
    assert "python -m train --config train/configs/doorway.yaml" in commands[0]
    assert "pytest" in commands[1]


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    assert readme_commands()[1] in ci


def test_every_shipped_map_has_a_picture():
    """The README's table of shipped maps (the generated crowd scenarios are described in
    text)."""
    from sgjax.maps.io import shipped_map_names

    for name in shipped_map_names():
        assert (ROOT / "docs" / "img" / f"{name}.png").exists(), name


@pytest.mark.slow
def test_readme_quick_start_runs():
    code = re.findall(r"```python\n(.+?)\n```", (ROOT / "README.md").read_text(), flags=re.S)[0]
    namespace: dict = {}
    exec(compile(code, "README.md quick start", "exec"), namespace)  # noqa: S102
    assert namespace["obs"].shape == (1024, 10, 10)
