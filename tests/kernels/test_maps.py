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


def test_route_ends_must_be_joined_but_its_waypoints_need_no_edges():
    spec = parse_map(broken(lambda d: d.__setitem__("routes", [[1, 3], [3, 1, 2]])))
    assert spec.routes == ((0, 2), (2, 0, 1))  # kept as written (SocialGym's scenario paths)

    def edit(d):
        d["nodes"].append({"id": 7, "position": [3, 3]})
        d["routes"] = [[1, 2, 7]]
    expect_error(broken(edit), "$.routes[0]", ["no path", "start 1 to goal 7"])
    expect_error(broken(lambda d: d.__setitem__("routes", [[1, 2, 1]])), "$.routes[0]",
                 ["other than its start"])


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


def write_socialgym_door(folder: Path) -> dict:
    """A small SocialGym-style doorway: two rooms joined by a 1 m door, the hubs 20 and 21 the
    only edge, spawn nodes without edges (as SocialGym's real door and hallway ship them)."""
    walls = [[-6, -4, -0.5, -4], [-6, 4, -0.5, 4], [-6, -4, -6, 4], [-0.5, -4, -0.5, -0.5],
             [-0.5, 0.5, -0.5, 4], [0.5, -4, 0.5, -0.5], [0.5, 0.5, 0.5, 4], [0.5, -4, 6, -4],
             [0.5, 4, 6, 4], [6, -4, 6, 4], [-0.5, -0.5, 0.5, -0.5], [-0.5, 0.5, 0.5, 0.5],
             [3, 3, 3, 3]]  # one zero-length stub, as SocialGym's files have
    nodes = {20: (-5.0, 0.0), 21: (4.0, 0.0), 22: (3.5, 1.5), 23: (5.0, -1.5)}
    nodes.update({i: (-3.0 - 0.5 * i, -2.5 + 1.25 * i) for i in range(5)})  # spawns, no edges
    nodes[5] = (-5.9, 2.0)  # 0.1 m from the back wall: moved clear on import
    write_socialgym(folder, walls, nodes, [(20, 21)])
    return nodes


def test_socialgym_scenario_paths_and_edgeless_spawns_import_as_socialgym_ran_them(tmp_path):
    """SocialGym's own [start, hub, hub, goal] paths load as given; edgeless spawn nodes are
    joined to the nearest visible edge (split there), the report says what changed, and robots
    placed on them drive through the door to their goals."""
    nodes = write_socialgym_door(tmp_path / "door")
    routes = [[s, 20, 21, g] for s in range(6) for g in (22, 23)]
    reports = []
    spec = import_socialgym(tmp_path / "door", routes=routes, report=reports.append)
    report = reports[0]
    assert report.dropped_walls == 1 and [n for n, _ in report.moved] == [5]
    assert {node for node, _, _ in report.attached} == {0, 1, 2, 3, 4, 5, 22, 23}
    assert sorted(report.added_nodes) == [24, 25, 26, 27]  # ids above the file's
    assert (2, None, 0.0) in report.attached  # on the edge already: the edge runs through it
    assert "max_speed (2.0 on 1 edge(s))" in str(report)
    assert "attached 8 edgeless node(s)" in spec.description
    moved = spec.node_positions[spec.index_of(5)]
    assert moved[0] >= -6 + 0.25 - 1e-6 and moved[1] == pytest.approx(nodes[5][1])
    # Each attachment is the nearest point of the hubs' edge (y = 0, x from -5 to 4).
    for node, target, distance in report.attached:
        x, y = spec.node_positions[spec.index_of(node if target is None else target)]
        own = spec.node_positions[spec.index_of(node)]
        assert abs(y) < 1e-9 and x == pytest.approx(np.clip(own[0], -5, 4))
        assert distance == pytest.approx(np.hypot(*(own - (x, y))))
    assert len(spec.edges) == 6 + 7  # the hubs' edge in 6 pieces, and 7 joins
    assert spec.routes[0] == tuple(spec.index_of(i) for i in routes[0])  # kept as written
    env, params = sgjax.make(spec, num_agents=2, time_limit=40.0)
    keys = jax.random.split(jax.random.key(0), 4)
    _, state = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    step = jax.jit(jax.vmap(env.step_env, in_axes=(0, 0, 0, None)))
    for _ in range(int(params.max_steps)):
        _, state, *_ = step(keys, state, jax.numpy.zeros((4, 2), jax.numpy.int32), params)
    arrived = np.asarray(state.robots.succeeded)
    assert arrived.sum(axis=1).min() >= 1, arrived  # every episode: someone came through


def test_socialgym_default_groups_follow_connected_parts_and_unseen_nodes_stay_apart(tmp_path):
    walls = [[-1, -3, -1, 3], [1, -3, 1, 3], [4, -1, 6, -1], [4, 1, 6, 1], [4, -1, 4, 1],
             [6, -1, 6, 1]]  # a closed box around node 9: it sees no edge
    nodes = {0: (-3.0, 0.0), 1: (-3.0, 2.0), 2: (-2.0, -2.0), 3: (3.0, 0.0), 4: (3.0, 2.0),
             9: (5.0, 0.0)}
    write_socialgym(tmp_path / "two", walls, nodes, [(0, 1), (3, 4)])
    reports = []
    spec = import_socialgym(tmp_path / "two", report=reports.append)
    ids = spec.node_ids.tolist()
    groups = [sorted(ids[n] for n in starts) for starts, _ in spec.groups]
    assert sorted(groups) == [[0, 1, 2], [3, 4]]  # node 2 joined its part; 9 stays out
    assert reports[0].unattached == [9] and "see no edge" in str(reports[0])
    assert "2 group(s), one per connected part" in spec.description
    reports.clear()
    import_socialgym(tmp_path / "two", scenario="envs_multi", report=reports.append)
    assert "written for SocialGym's multienv map file(s), not two" in str(reports[0])


def test_socialgym_errors_print_plain_numbers_and_name_unknown_scenarios(tmp_path):
    walls = [[-1, 0.1, 1, 0.1], [-1, -0.1, 1, -0.1]]  # a 0.2 m slot: no room to move node 1 out
    write_socialgym(tmp_path / "slot", walls, {0: (-3.0, 0.0), 1: (0.0, 0.0)}, [(0, 1)])
    with pytest.raises(MapError) as err:
        import_socialgym(tmp_path / "slot")
    assert "node 1 at (0.000, 0.000) is 0.100 m from wall" in str(err.value)
    assert "np.float64" not in str(err.value)
    with pytest.raises(ValueError, match="did you mean 'envs_door'"):
        import_socialgym(tmp_path / "slot", scenario="envs_dor")
    with pytest.raises(MapError, match="conflict zone needs nodes 20 and 21; this map has no "
                                       "node 20"):
        import_socialgym(tmp_path / "slot", scenario="envs_door")
    write_socialgym(tmp_path / "apart", [], {0: (0.0, 0.0), 1: (2.0, 0.0)}, [])
    with pytest.raises(MapError, match="no two nodes are joined by the graph"):
        import_socialgym(tmp_path / "apart")


def test_socialgym_json_vectormap_beside_an_empty_txt(tmp_path):
    """SocialGym's open map ships an empty .vectormap.txt beside its .vectormap.json."""
    folder = tmp_path / "box"
    write_socialgym(folder, [], {0: (0.0, 0.0), 1: (2.0, 0.0)}, [(0, 1)])
    (folder / "box.vectormap.json").write_text(json.dumps(
        [{"p0": {"x": "-1", "y": "-1"}, "p1": {"x": "3", "y": "-1"}}]))
    assert import_socialgym(folder).walls.tolist() == [[-1.0, -1.0, 3.0, -1.0]]


@pytest.mark.parametrize("pairs", [
    [(s, g) for s in range(6) for g in range(6) if s != g],  # SocialGym's open: every pair
    [(s, g) for s in range(3) for g in (7, 8, 9)],  # door: starts x goals
    [(0, 1), (1, 0), (1, 2)],  # multienv
    [(0, 5), (0, 6), (1, 5), (2, 7), (3, 7), (4, 0)],
])
def test_routes_fold_into_groups_allowing_exactly_their_pairs(pairs):
    from sgjax.maps.arrays import spawn_groups

    data = {"name": "g", "description": "", "bounds": [-1, -1, 11, 1], "walls": [],
            "nodes": [{"id": i, "position": [float(i), 0.0]} for i in range(10)],
            "edges": [[i, i + 1] for i in range(9)], "routes": [list(p) for p in pairs]}
    groups = spawn_groups(parse_map(data))
    allowed = {(s, g) for starts, goals in groups for s in starts for g in goals if s != g}
    assert allowed == set(pairs)
    assert len(groups) <= len({s for s, _ in pairs})
    starts = [s for group, _ in groups for s in group]
    assert len(starts) == len(set(starts))  # a start in one group only: no pair drawn twice


def test_maps_show_describes_and_draws(tmp_path, capsys):
    from sgjax.command import main

    write_socialgym_door(tmp_path / "door")
    main(["maps", "show", str(tmp_path / "door"), "--out", str(tmp_path / "door.png")])
    out = capsys.readouterr().out
    assert "attached 8 edgeless node(s)" in out and "1 connected part(s)" in out
    assert "robots fit" in out and (tmp_path / "door.png").stat().st_size > 0
    main(["maps", "show", "doorway"])
    assert "zone        door" in capsys.readouterr().out
    with pytest.raises(SystemExit, match="no_such"):
        main(["maps", "show", "no_such_map"])
