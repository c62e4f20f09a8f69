"""``sgjax maps generate``: worlds of a family as map files that ``sgjax maps check`` accepts
and ``sgjax evaluate`` plays; bad ranges are refused by name."""

from __future__ import annotations

import json

import pytest

from sgjax.command import main


def test_generated_files_pass_the_checker_and_the_same_seed_gives_the_same_files(tmp_path,
                                                                                capsys):
    main(["maps", "generate", "--family", "intersection", "--count", "3", "--seed", "4",
          "--out", str(tmp_path / "a"), "--set", "arms=4"])
    main(["maps", "generate", "--family", "intersection", "--count", "3", "--seed", "4",
          "--out", str(tmp_path / "b"), "--set", "arms=4"])
    files = sorted((tmp_path / "a").glob("*.json"))
    assert [f.name for f in files] == [f"intersection-4-000{i}.json" for i in range(3)]
    for f in files:
        assert f.read_text() == (tmp_path / "b" / f.name).read_text()
        assert len(json.loads(f.read_text())["groups"]) == 4  # an X: four arms
    main(["maps", "check", *map(str, files)])  # exits 1 on an error
    assert "3 file(s): 0 error(s)" in capsys.readouterr().out


def test_bad_generate_arguments_are_refused_by_name(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["maps", "generate", "--family", "doorway", "--out", str(tmp_path),
              "--set", "door_width"])
    assert "expected NAME=LOW,HIGH" in capsys.readouterr().err
    with pytest.raises(SystemExit, match="door_width range \\[9, 9\\] must lie within"):
        main(["maps", "generate", "--family", "doorway", "--out", str(tmp_path),
              "--set", "door_width=9"])
