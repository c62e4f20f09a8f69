"""``sgjax edit``'s server and ``sgjax maps check``, without a browser: every problem at once,
the warnings, saves that stay in their folder, the byte-stable round trip, autosave, routes and
play (tests/applications/test_editor_browser.py drives the page in Chromium)."""

import copy
import json
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from dense_maps import packed_room

import sgjax
from sgjax.command import main as sgjax_main
from sgjax.editor.guard import TOKEN_HEADER
from sgjax.editor.server import make_server
from sgjax.editor.session import EditorError, EditorSession
from sgjax.maps import MapError, parse_map
from sgjax.maps.check import check_map

ROOT = Path(__file__).resolve().parents[2]

# Two 6 m x 6 m rooms joined by a 1.2 m door in the wall x = 0, nodes on both sides and in it.
ROOMS = {
    "name": "rooms", "description": "two rooms and a door",
    "bounds": [-7, -4, 7, 4],
    "walls": [[-6, -3, 6, -3], [6, -3, 6, 3], [6, 3, -6, 3], [-6, 3, -6, -3],
              [0, -3, 0, -0.6], [0, 0.6, 0, 3]],
    "nodes": [{"id": 0, "position": [-4, -1.5]}, {"id": 1, "position": [-4, 1.5]},
              {"id": 2, "position": [-2, 0]}, {"id": 3, "position": [0, 0]},
              {"id": 4, "position": [2, 0]}, {"id": 5, "position": [4, -1.5]},
              {"id": 6, "position": [4, 1.5]}],
    "edges": [[0, 2], [1, 2], [2, 3], [3, 4], [4, 5], [4, 6]],
    "groups": [{"starts": [0, 1], "goals": [5, 6]}],
    "zones": [{"name": "door", "rect": [-1, -1, 1, 1]}],
}


def edited(edit):
    data = copy.deepcopy(ROOMS)
    edit(data)
    return data


def kinds(problems, severity):
    return [(p.path, p.message) for p in problems if p.severity == severity]


def test_a_good_map_has_no_problem_and_loads():
    assert check_map(ROOMS) == []
    parse_map(ROOMS)


def test_every_error_is_reported_in_one_pass():
    def three_mistakes(d):
        d["colur"] = "red"  # a misspelt key
        d["walls"][1] = [6, -3, 6]  # a wall with 3 numbers
        d["edges"].append([4, 9])  # an edge to a missing node
    data = edited(three_mistakes)
    errors = kinds(check_map(data, "rooms.json"), "error")
    assert [path for path, _ in errors] == ["$.colur", "$.walls[1]", "$.edges[6][1]"], errors
    with pytest.raises(MapError) as err:
        parse_map(data, "rooms.json")
    assert err.value.path == "$.colur" and len(err.value.errors) == 3
    assert "and 2 more error(s)" in str(err.value) and "$.edges[6][1]" in str(err.value)


def test_misspelt_keys_get_a_suggestion():
    data = edited(lambda d: d.update(zone=d.pop("zones")))
    (path, message), = kinds(check_map(data), "error")
    assert path == "$.zone" and "did you mean 'zones'?" in message


def test_warnings_for_what_loads_but_is_probably_wrong():
    # a node outside the building (and the bounds) joined through a gap in the north wall
    def gap(d):
        d["walls"][2] = [6, 3, -4.5, 3]  # the north wall stops 1.5 m short of the corner
        d["nodes"].append({"id": 7, "position": [-5.2, 4.5]})
        d["edges"].append([7, 1])
        d["groups"].append({"starts": [7], "goals": [6]})
    problems = check_map(edited(gap))
    warnings = kinds(problems, "warning")
    assert not kinds(problems, "error"), problems
    assert any(p == "$.nodes[7]" and "outside the bounds" in m for p, m in warnings), warnings
    assert ("$.nodes[0]", "8 of 8 node(s) (0, 1, 2 ...) are enclosed by no walls: a robot "
            "there can drive off the map (a gap in the walls?)") in warnings, warnings
    closed = edited(lambda d: (d["nodes"].append({"id": 7, "position": [-6.5, 3.5]}),
                               d["edges"].append([7, 7 - 7])))  # outside the closed rooms
    assert ("$.nodes[7]", "1 of 8 node(s) (7) are enclosed by no walls: a robot there can "
            "drive off the map (a gap in the walls?)") in kinds(check_map(closed), "warning")
    # a zone no route crosses
    far = edited(lambda d: d["zones"].append({"name": "corner", "rect": [4.5, 2, 5.5, 2.8]}))
    assert kinds(check_map(far), "warning") == [
        ("$.zones[1]", "zone 'corner': no robot's shortest route crosses it (of 4 start-goal "
                       "pairs)")]
    # a corner that stops 0.2 m short of the other wall, near the graph
    short = edited(lambda d: d["walls"].__setitem__(4, [0, -3, 0, -0.6]) or d["walls"].append(
        [0.2, 0.6, 2, 0.6]))
    assert any("stops 0.20 m short" in m for _, m in kinds(check_map(short), "warning"))
    # two equally short, different ways round a pillar
    pillar = {
        "name": "pillar", "description": "", "bounds": [-4, -3, 4, 3], "walls": [],
        "nodes": [{"id": 0, "position": [-3, 0]}, {"id": 1, "position": [0, 1]},
                  {"id": 2, "position": [0, -1]}, {"id": 3, "position": [3, 0]}],
        "edges": [[0, 1], [1, 3], [0, 2], [2, 3]], "groups": [{"starts": [0], "goals": [3]}]}
    (path, message), = kinds(check_map(pillar), "warning")
    assert path == "$.groups[0]" and "1 of 1 start-goal pair(s) have two equally short" in message
    pillar["nodes"][1]["position"] = [0, 1.1]
    assert check_map(pillar) == []


def test_problems_carry_their_element_and_place():
    data = edited(lambda d: d["nodes"].append({"id": 7, "position": [5.9, 0]}))
    (problem,) = [p for p in check_map(data) if p.severity == "error"]
    assert problem.as_dict() == {
        "severity": "error", "path": "$.nodes[7]", "element": {"kind": "node", "index": 7},
        "point": [5.9, 0.0], "message": problem.message}
    assert "0.100 m from wall $.walls[1]" in problem.message


def test_maps_check_command_reports_every_file(tmp_path, capsys):
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text(json.dumps(ROOMS))
    bad.write_text(json.dumps(edited(lambda d: (d.update(colur=1), d["edges"].append([0, 0])))))
    with pytest.raises(SystemExit) as stop:
        sgjax_main(["maps", "check", str(good), str(bad)])
    assert stop.value.code == 1
    out = capsys.readouterr().out
    assert f"{good}: ok" in out and f"{bad}: error: $.colur" in out
    assert f"{bad}: error: $.edges[6]: edge joins node 0 to itself" in out
    assert "2 file(s): 2 error(s), 0 warning(s)" in out
    sgjax_main(["maps", "check", *(str(p) for p in sorted((ROOT / "maps").glob("*.json")))])


def test_the_documented_example_map_runs_at_the_default_robot_count(tmp_path):
    text = (ROOT / "docs" / "maps.md").read_text()
    example = json.loads(text.split("```json\n", 1)[1].split("```", 1)[0])
    path = tmp_path / f"{example['name']}.json"
    path.write_text(json.dumps(example))
    assert example["name"] not in sgjax.maps.shipped_map_names()
    assert check_map(example) == []
    env, params = sgjax.make(str(path))
    assert int(params.num_agents) == 4
    keys = {row.split("|")[1].strip() for row in text.split("| key | type | meaning |")[1]
            .split("\n\n")[0].splitlines()[2:]}
    documented = {k.strip(" `") for cell in keys for k in cell.split(",")}
    from sgjax.maps.schema import TOP_LEVEL_OPTIONAL, TOP_LEVEL_REQUIRED

    assert documented == set(TOP_LEVEL_REQUIRED + TOP_LEVEL_OPTIONAL)


# --- the session and the server -------------------------------------------------------------


def test_sessions_open_files_folders_and_new_maps(tmp_path):
    path = tmp_path / "rooms.json"
    path.write_text(json.dumps(ROOMS, indent=2))
    session = EditorSession.open(str(path))
    assert session.root == tmp_path.resolve() and session.file == "rooms.json"
    assert session.data == ROOMS
    new = EditorSession.open(None, new="mygame", root=str(tmp_path))
    assert new.file == "mygame.json" and new.data["name"] == "mygame"
    with pytest.raises(EditorError, match="exists; open it instead"):
        EditorSession.open(None, new="rooms", root=str(tmp_path))
    with pytest.raises(EditorError, match="expected a plain name"):
        EditorSession.open(None, new="../up", root=str(tmp_path))
    with pytest.raises(EditorError, match="no such map file"):
        EditorSession.open(str(tmp_path / "missing.json"))
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(EditorError, match="broken.json: line 1 column 2: invalid JSON"):
        EditorSession.open(str(tmp_path / "broken.json"))


def test_saves_stay_in_the_root_never_overwrite_unasked_and_keep_unchanged_bytes(tmp_path):
    text = json.dumps(ROOMS, indent=3, sort_keys=True)  # not the format sgjax writes
    (tmp_path / "rooms.json").write_text(text)
    session = EditorSession.open(str(tmp_path / "rooms.json"))
    for name in ("../evil.json", "/tmp/evil.json", "sub/../../evil.json"):
        with pytest.raises(EditorError, match="outside the folder") as err:
            session.save(ROOMS, name, overwrite=True)
        assert err.value.status == 403
    assert not (tmp_path.parent / "evil.json").exists()
    with pytest.raises(EditorError, match="ending in .json"):
        session.save(ROOMS, "rooms.txt", overwrite=True)
    # the file being edited is saved without a question; any other existing file is asked for
    session.save(ROOMS, "rooms.json", overwrite=False)
    assert (tmp_path / "rooms.json").read_text() == text  # unchanged: the same bytes
    (tmp_path / "other.json").write_text("{}")
    with pytest.raises(EditorError, match="exists; confirm") as err:
        session.save(ROOMS, "other.json", overwrite=False)
    assert err.value.status == 409 and err.value.extra == {"exists": True}
    assert (tmp_path / "other.json").read_text() == "{}"
    session.save(ROOMS, "copy.json", overwrite=False)
    assert (tmp_path / "copy.json").read_text() == text
    assert session.file == "copy.json"  # Save as: now the file being edited
    session.save(ROOMS, "copy.json", overwrite=False)
    with pytest.raises(EditorError, match="exists; confirm"):
        session.save(ROOMS, "rooms.json", overwrite=False)
    changed = edited(lambda d: d.update(name="rooms2"))
    session.save(changed, "sub/rooms2.json", overwrite=False)
    assert json.loads((tmp_path / "sub" / "rooms2.json").read_text()) == changed
    bad = edited(lambda d: d["edges"].append([0, 0]))
    with pytest.raises(EditorError, match="not saved: the map has 1 error") as err:
        session.save(bad, "bad.json", overwrite=False)
    assert err.value.status == 422 and err.value.extra["problems"][0]["path"] == "$.edges[6]"
    assert not (tmp_path / "bad.json").exists()


def test_autosave_is_offered_back_and_cleared_by_a_save(tmp_path):
    (tmp_path / "rooms.json").write_text(json.dumps(ROOMS))
    session = EditorSession.open(str(tmp_path / "rooms.json"))
    assert session.autosaved() is None
    changed = edited(lambda d: d["nodes"][0].update(position=[-4, -1]))
    session.autosave(changed)
    assert (tmp_path / ".rooms.json.autosave").is_file()
    assert EditorSession.open(str(tmp_path / "rooms.json")).autosaved() == changed
    session.save(changed, "rooms.json", overwrite=True)
    assert not (tmp_path / ".rooms.json.autosave").exists()


_TOKENS: dict[str, str] = {}  # base URL of a test server -> its launch token


@pytest.fixture()
def server(tmp_path):
    (tmp_path / "rooms.json").write_text(json.dumps(ROOMS))
    httpd = make_server(EditorSession.open(str(tmp_path / "rooms.json")), port=0)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{httpd.server_address[1]}"
    _TOKENS[url] = httpd.token
    yield url
    httpd.shutdown()
    httpd.server_close()


def call(url, body=None, raw=None, headers=None, token=True):
    """``GET`` (no body) or ``POST`` ``url`` as the editor's page does: the token of the server
    the URL belongs to and a JSON Content-Type, unless ``headers`` or ``token=False`` say
    otherwise. Returns ``(status, body bytes)``."""
    data = raw if raw is not None else (None if body is None else json.dumps(body).encode())
    request = urllib.request.Request(url, data=data, method="GET" if data is None else "POST")
    if token and "/api/" in url:
        request.add_header(TOKEN_HEADER, _TOKENS[url.split("/api/")[0]])
    if data is not None:
        request.add_header("Content-Type", "application/json")
    for name, value in (headers or {}).items():
        request.add_header(name, value)
    try:
        with urllib.request.urlopen(request, timeout=120) as answer:
            return answer.status, answer.read()
    except urllib.error.HTTPError as err:
        return err.code, err.read()


def test_the_api_answers_json_and_errors_as_json(server):
    status, body = call(server + "/api/session")
    session = json.loads(body)
    assert status == 200 and session["map"] == ROOMS and "only_local" in session["policies"]
    status, body = call(server + "/")
    assert status == 200 and b"<html" in body.lower()
    for path in ("/static/../session.py", "/static/nope.js", "/nope"):
        status, body = call(server + path)
        assert status == 404 and "error" in json.loads(body)
    status, body = call(server + "/api/check", raw=b"not json")
    assert status == 400 and "not JSON" in json.loads(body)["error"]
    status, body = call(server + "/api/check", {"nomap": 1})
    assert status == 400 and "needs a 'map'" in json.loads(body)["error"]
    status, body = call(server + "/api/check", {"map": edited(lambda d: d.update(colur=1))})
    assert status == 200 and json.loads(body)["problems"][0]["path"] == "$.colur"
    status, body = call(server + "/api/save", {"map": ROOMS, "file": "../evil.json"})
    assert status == 403 and "outside the folder" in json.loads(body)["error"]
    status, body = call(server + "/api/routes", {"map": ROOMS})
    routes = json.loads(body)
    assert status == 200 and routes["pairs"] == 4 and not routes["truncated"]
    assert routes["routes"][0]["points"][0] == [-4, -1.5] and routes["routes"][0]["tie"] is False
    status, body = call(server + "/api/play", {"map": ROOMS, "robots": 0})
    assert status == 400 and "robots must be an integer" in json.loads(body)["error"]


def test_play_runs_a_batch_and_returns_an_episode(server):
    status, body = call(server + "/api/play", {"map": ROOMS, "policy": "only_local",
                                               "robots": 2, "episodes": 4, "seed": 1})
    answer = json.loads(body)
    assert status == 200, answer
    assert 0.0 <= answer["metrics"]["team_success"]["mean"] <= 1.0
    assert list(answer["metrics"])[0] == "team_success"
    episode = answer["episode"]
    assert len(episode["frames"]) == episode["length"] > 1
    assert len(episode["frames"][0]) == 2 and len(episode["goals"]) == 2
    assert episode["goals"][0] in ([4, -1.5], [4, 1.5])
    status, body = call(server + "/api/play", {"map": ROOMS, "policy": "nope", "robots": 2,
                                               "episodes": 2})
    assert status == 400 and "nope" in json.loads(body)["error"]


def test_unsupported_methods_answer_json_too(server):
    for method in ("PUT", "DELETE", "PATCH"):
        request = urllib.request.Request(server + "/api/save", data=b"{}", method=method)
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(request, timeout=30)
        assert err.value.code == 501 and "error" in json.loads(err.value.read())


# --- who may call the server (docs/editor.md, "Security") -----------------------------------


def _state(folder):
    """Every file under ``folder`` with its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_other_pages_and_forged_hosts_are_refused(server, tmp_path):
    # the open map has an autosave beside it and the session edits rooms.json
    status, _ = call(server + "/api/autosave", {"map": edited(lambda d: d.update(name="x"))})
    assert status == 200
    before = _state(tmp_path)
    port = server.rsplit(":", 1)[1]
    evil = {"map": ROOMS, "file": "evil.json", "overwrite": True}
    # the replay of a page on another origin: fetch(..., {mode: "no-cors"}) with a text/plain
    # body, which a browser sends without asking the server
    no_cors = {"Content-Type": "text/plain", "Origin": "http://127.0.0.1:9"}
    for path in ("/api/save", "/api/autosave", "/api/check", "/api/play"):
        status, body = call(server + path, raw=json.dumps(evil).encode(), headers=no_cors,
                            token=False)
        assert status == 403 and "127.0.0.1:9" in json.loads(body)["error"], (path, body)
        status, body = call(server + path, raw=json.dumps(evil).encode(),
                            headers={"Content-Type": "text/plain"}, token=False)
        assert status == 403 and "X-Sgjax-Token" in json.loads(body)["error"], (path, body)
    # the token is not enough from another origin, or with another Host (DNS rebinding)
    status, body = call(server + "/api/save", evil, headers={"Origin": "http://evil.example"})
    assert status == 403 and "evil.example" in json.loads(body)["error"]
    for host in ("evil.example", f"evil.example:{port}", "127.0.0.1:1"):
        for path in ("/api/save", "/api/session", "/", "/static/editor.js"):
            status, body = call(server + path, None if path[-4:] != "save" else evil,
                                headers={"Host": host})
            assert status == 403 and "is not this editor's address" in json.loads(body)["error"]
    # a write needs a JSON body type even with the token
    status, body = call(server + "/api/save", raw=json.dumps(evil).encode(),
                        headers={"Content-Type": "text/plain"})
    assert status == 415 and "application/json" in json.loads(body)["error"]
    status, body = call(server + "/api/session", token=False)
    assert status == 403
    status, body = call(server + "/api/session", headers={"X-Sgjax-Token": "x" * 32},
                        token=False)
    assert status == 403
    assert _state(tmp_path) == before  # nothing written, deleted or switched
    status, body = call(server + "/api/session")
    assert status == 200 and json.loads(body)["file"] == "rooms.json"
    # the editor's own page, under each loopback name, with the token
    for host in (f"127.0.0.1:{port}", f"localhost:{port}"):
        status, body = call(server + "/api/check", {"map": ROOMS},
                            headers={"Host": host, "Origin": f"http://{host}"})
        assert status == 200 and json.loads(body) == {"problems": []}
    status, _ = call(server + "/?token=" + _TOKENS[server])
    assert status == 200


def test_the_printed_address_carries_a_new_token_each_launch(tmp_path):
    session = EditorSession.open(None, new="x", root=str(tmp_path))
    first, second = make_server(session, port=0), make_server(session, port=0)
    try:
        assert first.token != second.token and len(first.token) >= 32
        assert first.url == (f"http://127.0.0.1:{first.server_address[1]}/?token="
                             f"{first.token}")
    finally:
        first.server_close()
        second.server_close()


def test_oversized_and_dense_maps_get_their_error_and_the_server_answers_on(server, tmp_path):
    """A map past the limits gets its error at once (the 200,000 packed walls within a memory
    bound: tests/applications/test_editor_browser.py, through the page)."""
    from sgjax.maps.size_limits import MAX_WALLS

    too_many = packed_room(MAX_WALLS + 1)
    status, body = call(server + "/api/save", {"map": too_many, "file": "big.json"})
    answer = json.loads(body)
    assert status == 422 and answer["problems"][0]["path"] == "$.walls"
    assert f"at most {MAX_WALLS:,}" in answer["problems"][0]["message"]
    pile = edited(lambda d: d["walls"].extend([[2, 2 + 0.001 * i, 2.3, 2.2] for i in range(300)]))
    status, body = call(server + "/api/check", {"map": pile})
    (problem,) = json.loads(body)["problems"]
    assert problem["path"] == "$.walls" and "walls pass through" in problem["message"]
    status, body = call(server + "/api/routes", {"map": pile})
    assert status == 422 and "walls pass through" in json.loads(body)["error"]
    status, body = call(server + "/api/session")
    assert status == 200
    assert not (tmp_path / "big.json").exists()


@pytest.mark.slow
def test_maps_check_of_50000_packed_walls_ends_within_seconds(tmp_path):
    """``sgjax maps check`` on 50,000 walls packed into one room: every problem, quickly (a
    guard against all-pairs work, which took it past 4 GB before; bench/map_check.py measures
    it: about 2 s on the 2-core CPU)."""
    import subprocess
    import sys
    import time

    path = tmp_path / "packed.json"
    path.write_text(json.dumps(packed_room(50_000)))
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "sgjax.command", "maps", "check", str(path)],
                         capture_output=True, text=True, timeout=120)
    seconds = time.perf_counter() - start
    assert out.returncode == 1, out.stderr[-2000:]  # the edge through the room is an error
    assert "error: $.edges[0]: edge 0-1 crosses wall" in out.stdout
    assert "1 file(s): 2 error(s)" in out.stdout and "warning(s)" in out.stdout
    assert seconds < 60, f"sgjax maps check took {seconds:.0f} s on 50,000 packed walls"


@pytest.mark.slow
def test_generate_draws_a_family_world_by_its_seed_and_refuses_bad_requests_by_name(server):
    from sgjax.environment.worlds import source_for

    status, body = call(server + "/api/session")
    families = {f["name"]: f for f in json.loads(body)["families"]}
    assert set(families) == {"doorway", "hallway", "intersection", "roundabout", "open",
                             "floorplan"}
    assert families["doorway"]["parameters"]["door_width"]["unit"] == "m"
    status, body = call(server + "/api/generate", {"family": "doorway", "seed": 7,
                                                   "ranges": {"door_width": 1.4}})
    answer = json.loads(body)
    assert status == 200 and answer["valid"] and answer["seed"] == 7
    assert answer["values"]["door_width"] == pytest.approx(1.4)
    assert [p for p in check_map(answer["map"]) if p.severity == "error"] == []
    parse_map(answer["map"])
    # world 7 of these ranges, as the held-out splits and sgjax generalise name it
    own = source_for("doorway", {"door_width": (1.4, 1.4)}).of_seed(7).values
    assert {k: pytest.approx(float(v)) for k, v in own.items()} == answer["values"]
    for request, words in (
            ({"family": "maze", "seed": 0}, "'family' must be one of"),
            ({"family": "doorway", "seed": -1}, "'seed' must be an integer"),
            ({"family": "doorway", "seed": 1.5}, "'seed' must be an integer"),
            ({"family": "doorway", "ranges": {"door_width": [9, 10]}}, "door_width range"),
            ({"family": "doorway", "ranges": {"door_wdth": 1.0}}, "no parameter 'door_wdth'"),
            ({"family": "doorway", "ranges": {"door_width": "wide"}}, "'door_width': expected")):
        status, body = call(server + "/api/generate", request)
        assert status == 422 and words in json.loads(body)["error"], (request, body)
