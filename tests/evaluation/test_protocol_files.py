"""Protocol files that fix a crowd (``num_humans``, ``human_range``), the shipped building
protocol over SocialGym 2.0's floors, and map folders as scenarios."""

from __future__ import annotations

from pathlib import Path

import pytest
from shared_data import SG2MAPS, require

from sgjax.command import main as cli_main
from sgjax.environment.options import MakeOptions
from sgjax.evaluation.protocols import PAPER, load_protocol
from sgjax.maps.io import load

ROOT = Path(__file__).resolve().parents[2]


def test_a_protocol_may_fix_the_crowd_and_then_the_command_line_may_not(tmp_path):
    path = tmp_path / "crowd.yaml"
    path.write_text("name: crowd\nscenarios: [open]\nnum_agents: [2]\nepisodes: 1\nseed: 0\n"
                    "counterfactual: false\nnum_humans: 30\nhuman_range: 3\n")
    protocol = load_protocol(path)
    assert protocol.num_humans == 30 and protocol.human_range == 3.0
    options = protocol.options(MakeOptions())
    assert options.humans.num_humans == 30 and options.humans.human_range == 3.0
    assert PAPER.options(MakeOptions()) == MakeOptions()  # the paper fixes no crowd
    with pytest.raises(SystemExit, match="fixes --num-humans"):
        cli_main(["evaluate", "--protocol", str(path), "--num-humans", "5"])
    bad = tmp_path / "bad.yaml"
    bad.write_text(path.read_text().replace("num_humans: 30", "num_humans: -1"))
    with pytest.raises(ValueError, match=r"bad.yaml: .*num_humans"):
        load_protocol(bad)


def test_the_building_protocol_reads_socialgym_floors_among_hundreds_of_people():
    protocol = load_protocol(ROOT / "protocols" / "building.yaml")
    assert protocol.num_humans >= 100 and protocol.human_range is not None
    require(SG2MAPS, "SocialGym 2.0's maps")
    for scenario in protocol.scenarios:
        folder = (ROOT / scenario).resolve()
        spec = load(folder)  # a map folder: imported
        assert len(spec.walls) > 1000 and spec.source
    with pytest.raises(FileNotFoundError, match="map file not found"):
        load(ROOT / "no_such_map.json")
