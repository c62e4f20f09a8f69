"""SocialGym 2.0's map files and evaluation protocol files never crash their readers: hypothesis
corrupts a real SocialGym map folder (a navigation.json value replaced by any JSON value, lines
of the vectormap dropped, garbled or cut) and protocol files, and every result is a map, or a
``MapError`` / ``ValueError`` naming the file; never another exception."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from fuzzing import JSON_VALUES, places, replaced
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shared_data import SG2MAPS, require

from sgjax.evaluation.protocols import load_protocol
from sgjax.maps import MapError
from sgjax.maps.socialgym import import_socialgym

DOOR = SG2MAPS / "door"

FAST = settings(max_examples=50, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.fixture(autouse=True)
def _socialgym_maps():
    require(DOOR, "SocialGym 2.0's maps")


def _folder(tmp_path: Path) -> Path:
    folder = tmp_path / "door"
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(DOOR, folder)
    for path in folder.iterdir():
        path.chmod(0o644)
    return folder


def _imports_or_names(folder: Path) -> None:
    try:
        import_socialgym(folder)
    except (MapError, ValueError, FileNotFoundError) as err:
        assert str(folder) in str(err), str(err)


@FAST
@given(data=st.data(), new=JSON_VALUES)
def test_a_corrupted_navigation_file_is_a_map_error_naming_it(tmp_path, data, new):
    folder = _folder(tmp_path)
    nav = folder / "door.navigation.json"
    graph = json.loads(nav.read_text())
    path, _ = data.draw(st.sampled_from(list(places(graph, items=3))))
    nav.write_text(json.dumps(replaced(graph, path, new)))
    _imports_or_names(folder)


@FAST
@given(data=st.data())
def test_a_corrupted_vectormap_is_a_map_error_naming_it(tmp_path, data):
    folder = _folder(tmp_path)
    kind = data.draw(st.sampled_from(["txt", "json", "bytes"]))
    if kind == "txt":
        walls = folder / "door.vectormap.txt"
        lines = walls.read_text().splitlines()
        index = data.draw(st.integers(0, len(lines) - 1))
        lines[index] = data.draw(st.text(max_size=20))
        walls.write_text("\n".join(lines))
    elif kind == "json":
        (folder / "door.vectormap.txt").unlink()
        walls = folder / "door.vectormap.json"
        lines = json.loads(walls.read_text())
        path, _ = data.draw(st.sampled_from(list(places(lines, items=3))))
        walls.write_text(json.dumps(replaced(lines, path, data.draw(JSON_VALUES))))
    else:
        walls = folder / data.draw(st.sampled_from(["door.vectormap.txt",
                                                    "door.navigation.json"]))
        content = walls.read_bytes()
        walls.write_bytes(content[:data.draw(st.integers(0, len(content)))])
    _imports_or_names(folder)


PROTOCOL = {"name": "mine", "scenarios": ["doorway", "hallway"], "num_agents": [3, 4],
            "episodes": 25, "seed": 0, "counterfactual": True, "time_limit": 75.0}


@settings(max_examples=80, deadline=None, suppress_health_check=[
    HealthCheck.function_scoped_fixture])
@given(data=st.data(), new=JSON_VALUES)
def test_a_corrupted_protocol_file_is_an_error_naming_it(tmp_path, data, new):
    path, _ = data.draw(st.sampled_from(list(places(PROTOCOL))))
    file = tmp_path / "protocol.yaml"
    text = json.dumps(replaced(PROTOCOL, path, new))
    if data.draw(st.booleans()):
        text = text[:data.draw(st.integers(0, len(text)))]
    file.write_text(text)
    try:
        load_protocol(file)
    except ValueError as err:
        assert str(file) in str(err), str(err)


@pytest.mark.parametrize("value", ["1e300", "nan", "-inf", "200000"])
def test_a_coordinate_beyond_the_float32_range_is_a_map_error_without_a_warning(tmp_path,
                                                                                 value):
    """A wall or node coordinate that is not finite or beyond +-1e5 m stops the import at the
    file and line or node that holds it, before any geometry (no numpy overflow warning)."""
    import re
    import warnings

    for target in ("vectormap", "navigation"):
        folder = _folder(tmp_path)
        if target == "vectormap":
            path = folder / "door.vectormap.txt"
            lines = path.read_text().splitlines()
            lines[1] = f"{value}, 0.0, 1.0, 1.0"
            path.write_text("\n".join(lines) + "\n")
            where = "line 2"
        else:
            path = folder / "door.navigation.json"
            graph = json.loads(path.read_text())
            graph["nodes"][0]["loc"]["x"] = value  # SocialGym writes numbers as strings too
            path.write_text(json.dumps(graph))
            where = "$.nodes[0].loc"
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(MapError, match=re.escape(path.name) + ".*" + re.escape(where)):
                import_socialgym(folder)
