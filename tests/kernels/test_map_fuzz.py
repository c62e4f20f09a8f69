"""Corrupted maps never crash the reader: hypothesis mutates a valid map (a leaf replaced by any
JSON value, a key dropped or added, an item duplicated) and every result is a clean map or
``MapError`` naming a JSON path (``parse_map``), and a list of problems with paths
(``check_map``, which the editor calls on every edit); never another exception."""

import copy
import json

from fuzzing import JSON_VALUES, places
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sgjax.maps import MapError, parse_map
from sgjax.maps.check import check_map

VALID = {
    "name": "rooms", "description": "two rooms and a door", "bounds": [-7, -4, 7, 4],
    "walls": [[-6, -3, 6, -3], [6, -3, 6, 3], [6, 3, -6, 3], [-6, 3, -6, -3],
              [0, -3, 0, -0.6], [0, 0.6, 0, 3]],
    "nodes": [{"id": 0, "position": [-4, -1.5]}, {"id": 1, "position": [-4, 1.5]},
              {"id": 2, "position": [0, 0]}, {"id": 3, "position": [4, 0]}],
    "edges": [[0, 2], [1, 2], [2, 3]],
    "groups": [{"starts": [0, 1], "goals": [3]}],
    "routes": [[0, 2, 3]],
    "zones": [{"name": "door", "rect": [-1, -1, 1, 1]}],
    "pedestrian_groups": [{"starts": [0], "goals": [3]}],
}

@st.composite
def corrupted(draw):
    data = copy.deepcopy(VALID)
    for _ in range(draw(st.integers(1, 3))):
        places_ = list(places(data))[1:]
        path, _ = draw(st.sampled_from(places_))
        parent = data
        for step in path[:-1]:
            parent = parent[step]
        action = draw(st.sampled_from(["replace", "drop", "add", "duplicate"]))
        last = path[-1]
        if action == "replace":
            parent[last] = draw(JSON_VALUES)
        elif action == "drop":
            del parent[last]
        elif action == "add" and isinstance(parent, dict):
            parent[draw(st.text(max_size=6))] = draw(JSON_VALUES)
        elif isinstance(parent, list):
            parent.append(copy.deepcopy(parent[last]))
    return data


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(corrupted())
def test_a_corrupted_map_gives_map_errors_with_paths_and_nothing_else(data):
    problems = check_map(data, "fuzz.json")
    for problem in problems:
        assert problem.path.startswith("$") and problem.message, problem
        json.dumps(problem.as_dict())  # the editor sends it as JSON
    errors = [p for p in problems if p.severity == "error"]
    try:
        parse_map(data, "fuzz.json")
    except MapError as err:
        assert err.path.startswith("$") and str(err).startswith("fuzz.json: $")
        assert [e.path for e in err.errors] == [p.path for p in errors]
    else:
        assert not errors, errors


@settings(max_examples=30, deadline=None)
@given(st.one_of(JSON_VALUES, st.lists(JSON_VALUES, max_size=3)))
def test_anything_that_is_not_a_map_is_one_error(data):
    if isinstance(data, dict):
        return  # covered above
    (problem,) = check_map(data, "fuzz.json")
    assert problem.path == "$" and "expected an object" in problem.message
