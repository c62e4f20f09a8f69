"""Map loading: every class of error names file, JSON path and problem; shipped geometry."""

import copy
import json
from pathlib import Path

import jax
import numpy as np
import pytest

import sgjax
from sgjax.maps import MapError, compile_map, import_socialgym, load, parse_map
from sgjax.maps.routing import all_pairs_shortest_paths, path_nodes

GOOD = {
    "name": "tiny",
    "description": "two rooms",
    "bounds": [-5, -5, 5, 5],
    "walls": [[0, 1, 0, 5], [0, -5, 0, -1]],
    "nodes": [{"id": 1, "position": [-3, 0]}, {"id": 2, "position": [0, 0]},
              {"id": 3, "position": [3, 0]}],
    "edges": [[1, 2], [2, 3]],
    "groups": [{"starts": [1], "goals": [3]}],
    "routes": [[3, 2, 1]],
    "zones": [{"name": "door", "rect": [-1, -1, 1, 1]}],
}


def broken(edit):
    data = copy.deepcopy(GOOD)
    edit(data)
    return data


def expect_error(data, path, words):
    with pytest.raises(MapError) as err:
        parse_map(data, source="tiny.json")
    message = str(err.value)
    assert message.startswith("tiny.json: "), message
    assert err.value.path == path, message
    for word in words:
        assert word in message, message


def test_good_map_parses():
    spec = parse_map(GOOD, source="tiny.json")
    assert spec.walls.shape == (2, 4)
    assert spec.num_nodes == 3 and len(spec.groups) == 1 and len(spec.routes) == 1


def test_unknown_key():
    expect_error(broken(lambda d: d.update(colour="red")), "$.colour", ["unknown key", "walls"])


def test_unknown_nested_key():
    expect_error(broken(lambda d: d["nodes"][0].update(pos=[0, 0])), "$.nodes[0].pos",
                 ["unknown key"])


def test_missing_key():
    expect_error(broken(lambda d: d.pop("edges")), "$", ["missing", "edges"])


def test_wrong_type():
    expect_error(broken(lambda d: d["walls"][1].__setitem__(2, "zero")), "$.walls[1][2]",
                 ["number", "str"])
    expect_error(broken(lambda d: d["nodes"][1].__setitem__("id", 2.5)), "$.nodes[1].id",
                 ["integer"])


def test_edge_to_missing_node():
    expect_error(broken(lambda d: d["edges"].append([3, 9])), "$.edges[2][1]", ["9", "not exist"])


def test_route_not_a_path():
    expect_error(broken(lambda d: d.__setitem__("routes", [[1, 3]])), "$.routes[0][1]",
                 ["not a path", "1-3"])


def test_zero_length_wall():
    expect_error(broken(lambda d: d["walls"].append([2, 2, 2, 2])), "$.walls[2]", ["zero-length"])


def test_node_inside_or_near_wall():
    expect_error(broken(lambda d: d["nodes"].append({"id": 4, "position": [0.1, 3]})),
                 "$.nodes[3]", ["node 4", "closer than the robot radius"])


def test_edge_through_wall():
    def edit(d):
        d["nodes"].append({"id": 4, "position": [3, 3]})
        d["nodes"].append({"id": 5, "position": [-3, 3]})
        d["edges"].append([4, 5])
    expect_error(broken(edit), "$.edges[2]", ["crosses wall"])


def test_duplicate_node_and_disconnected_group():
    expect_error(broken(lambda d: d["nodes"].append({"id": 2, "position": [1, 0]})),
                 "$.nodes[3].id", ["duplicate"])
    def edit(d):
        d["nodes"].append({"id": 7, "position": [3, 3]})
        d["groups"] = [{"starts": [1], "goals": [7]}]
    expect_error(broken(edit), "$.groups[0]", ["no path", "7"])


def test_needs_groups_or_routes_and_valid_bounds():
    expect_error(broken(lambda d: (d.pop("groups"), d.pop("routes"))), "$", ["groups"])
    expect_error(broken(lambda d: d.__setitem__("bounds", [1, 0, 0, 1])), "$.bounds", ["xmin"])


def test_file_errors_name_the_file(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    with pytest.raises(MapError, match="bad.json: line 1"):
        load(path)
    path.write_text(json.dumps(broken(lambda d: d.pop("nodes"))))
    with pytest.raises(MapError, match="bad.json: \\$: missing required key 'nodes'"):
        load(path)
    with pytest.raises(KeyError, match="shipped maps are"):
        load("no_such_map")


def test_shortest_paths():
    spec = parse_map(GOOD)
    dist, next_hop = all_pairs_shortest_paths(spec.node_positions, spec.edges)
    assert dist[0, 2] == pytest.approx(6.0)
    assert path_nodes(next_hop, 0, 2) == [0, 1, 2]


# --------------------------------------------------------------------------- shipped maps
def wall_set(spec):
    return {tuple(np.round(w, 3)) for w in spec.walls}


def test_shipped_maps_load_and_compile():
    assert set(sgjax.registered()) >= {"doorway", "hallway", "intersection", "roundabout", "open",
                                       "office"}
    for name in sgjax.registered():
        spec = load(name)
        arrays = compile_map(spec)
        assert np.asarray(arrays.walls).shape == spec.walls.shape
        assert spec.walls.shape[1] == 4


def test_doorway_geometry():
    spec = load("doorway")
    walls = wall_set(spec)
    assert (-0.5, 0.5, 0.5, 0.5) in walls and (-0.5, -0.5, 0.5, -0.5) in walls  # 1 m x 1 m door
    assert len(spec.groups[0][0]) == 21 and len(spec.groups[0][1]) == 21
    ids = spec.node_ids.tolist()
    assert tuple(spec.node_positions[ids.index(20)]) == (-2.0, 0.0)
    starts = spec.node_positions[list(spec.groups[0][0])]
    np.testing.assert_allclose(np.abs(starts[:, 0] + 2) + np.abs(starts[:, 1]), 5.0)


def test_hallway_geometry():
    walls = wall_set(load("hallway"))
    assert (-3, 0.5, 3, 0.5) in walls and (-3, -0.5, 3, -0.5) in walls  # 1 m wide, 6 m long


def test_intersection_and_roundabout_geometry():
    inter, rb = load("intersection"), load("roundabout")
    assert (-2, 2, -2, 8) in wall_set(inter)  # 4 m wide arms up to 8 m
    island = {(0, 1, -1, 0), (-1, 0, 0, -1), (0, -1, 1, 0), (1, 0, 0, 1)}
    assert island <= wall_set(rb) and not island & wall_set(inter)
    rb_edges = {frozenset((int(rb.node_ids[a]), int(rb.node_ids[b]))) for a, b in rb.edges}
    assert frozenset((29, 27)) not in rb_edges and frozenset((26, 28)) not in rb_edges


def test_open_space_diamond():
    spec = load("open")
    assert spec.walls.shape == (0, 4) and spec.num_nodes == 48
    np.testing.assert_allclose(np.abs(spec.node_positions).sum(axis=1), 6.0)
    assert len(spec.edges) == 48 * 47 // 2


def test_office_floor_plan():
    spec = load("office")
    assert spec.walls.shape[0] >= 40
    assert len(spec.groups[0][0]) == 20  # rooms


# --------------------------------------------------------------------------- SocialGym import
def write_socialgym(folder: Path, walls, nodes, edges):
    folder.mkdir()
    (folder / f"{folder.name}.vectormap.txt").write_text(
        "\n".join(", ".join(str(v) for v in w) for w in walls) + "\n")
    (folder / f"{folder.name}.navigation.json").write_text(json.dumps({
        "nodes": [{"id": i, "loc": {"x": x, "y": y}} for i, (x, y) in nodes.items()],
        "edges": [{"s0_id": a, "s1_id": b, "has_door": False, "has_stairs": False,
                   "has_elevator": False, "has_automated_door": False, "max_clearance": 1.0,
                   "max_speed": 2.0} for a, b in edges],
    }))


def test_import_socialgym_files(tmp_path):
    walls = [[-10, -6, -0.5, -6], [-0.5, 0.5, 0.5, 0.5], [-0.5, -0.5, 0.5, -0.5],
             [0.5, -6, 10, -6]]
    nodes = {0: (-7.0, 0.0), 20: (-2.0, 0.0), 21: (2.0, 0.0), 22: (7.0, 0.0)}
    write_socialgym(tmp_path / "door", walls, nodes, [(0, 20), (20, 21), (21, 22)])
    spec = import_socialgym(tmp_path / "door", routes=[[0, 20, 21, 22]])
    np.testing.assert_allclose(spec.walls, walls)
    assert spec.routes and spec.node_ids.tolist() == [0, 20, 21, 22]
    everything = import_socialgym(tmp_path / "door")  # no routes: all nodes are starts and goals
    assert len(everything.groups[0][0]) == 4
    # An imported map drives like a shipped one, directly or after saving it as sgjax JSON.
    env, params = sgjax.make(spec, num_agents=1)
    _, state = env.reset(jax.random.key(0), params)
    assert state.route.start.tolist() == [0] and state.route.goal.tolist() == [3]
    saved = sgjax.maps.save(spec, tmp_path / "door.json")
    again = load(saved)
    np.testing.assert_allclose(again.walls, spec.walls)
    assert again.routes == spec.routes and again.node_ids.tolist() == spec.node_ids.tolist()


def test_import_drops_and_reports_degenerate_walls(tmp_path):
    write_socialgym(tmp_path / "stubs", [[0, 3, 1, 3], [2, 2, 2, 2]],
                    {0: (0.0, 0.0), 1: (1.0, 0.0)}, [(0, 1)])
    spec = import_socialgym(tmp_path / "stubs")
    assert spec.walls.shape == (1, 4) and "dropped 1 zero-length wall" in spec.description


def test_import_reports_bad_line(tmp_path):
    folder = tmp_path / "bad"
    write_socialgym(folder, [[0, 0, 1, 1]], {0: (5.0, 5.0), 1: (6.0, 5.0)}, [(0, 1)])
    (folder / "bad.vectormap.txt").write_text("0, 0, 1, 1\n1, 2, three, 4\n")
    with pytest.raises(MapError, match="bad.vectormap.txt: line 2"):
        import_socialgym(folder)
