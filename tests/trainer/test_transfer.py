"""``python -m train.transfer``: trained runs judged on held-out maps beside Only Local, every
arm's seeds on the same episodes, the result file and the tables generated from it."""

import dataclasses
import json
from pathlib import Path

import jax
import numpy as np
import pytest
from provenance_checks import check_document
from shared_data import SG2MAPS, require
from test_train import tiny

from sgjax.evaluation.evaluate import params_by_count, run_episodes
from sgjax.evaluation.generalisation import REPORTED, play_rollout, play_worst, world_players
from sgjax.maps.generated.families import family
from train import transfer
from train.algorithm.trainer import Trainer, seed_keys
from train.run.checkpoint import load_checkpoint_policy, save
from train.run.worst_worlds import WorstPlayers, worst_of_seeds

OPEN = transfer.HeldOutMap("minigames", "open", "open", 2)


def tiny_run(folder: Path, seed: int = 0, num_seeds: int = 2, **env):
    """A run folder holding an untrained checkpoint of ``num_seeds`` seeds of the open map."""
    config = tiny(seed=seed, num_seeds=num_seeds, env={"time_limit": 20.0, **env})
    trainer = Trainer(config)
    runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))
    save(folder / "checkpoints" / "latest.msgpack", config, runner, {}, trainer.actor)
    return folder


@pytest.fixture(scope="module")
def arms(tmp_path_factory):
    root = tmp_path_factory.mktemp("arms")
    return [transfer.load_arm("a", tiny_run(root / "a", seed=0)),
            transfer.load_arm("b", tiny_run(root / "b", seed=7))]


@pytest.mark.slow
def test_every_seed_of_every_arm_and_only_local_play_the_keyed_episodes(arms):
    """Lane ``i`` of an arm on a map is the checkpoint's seed ``i`` played alone with the map's
    key, and Only Local's row is Only Local played alone with it: the differences pair."""
    result = transfer.judge_map(arms, OPEN, episodes=4, seed=3)
    assert result["robots"] == 2
    key = transfer.map_key(3, OPEN)
    env, by_count = params_by_count("open", [2], options=transfer.map_options(arms[0], OPEN))
    for arm in arms:
        values = np.asarray(result["arms"][arm.name]["team_success"])
        assert values.shape == (2, 4)
        for index in range(2):
            alone = run_episodes(env, by_count[2], load_checkpoint_policy(
                arm.path, env, seed_index=index, deterministic=arm.deterministic), key, 4)
            np.testing.assert_array_equal(values[index], alone.values["team_success"])
            np.testing.assert_allclose(result["arms"][arm.name]["makespan"][index],
                                       alone.values["makespan"], equal_nan=True)
    local = run_episodes(env, by_count[2], "only_local", key, 4)
    np.testing.assert_array_equal(result["only_local"]["team_success"],
                                  local.values["team_success"])


def test_a_maps_key_depends_on_the_map_alone():
    other = transfer.HeldOutMap("minigames", "doorway", "doorway", 2)
    same = jax.random.key_data(transfer.map_key(0, OPEN))
    assert np.array_equal(same, jax.random.key_data(transfer.map_key(0, OPEN)))
    assert not np.array_equal(same, jax.random.key_data(transfer.map_key(0, other)))
    assert not np.array_equal(same, jax.random.key_data(transfer.map_key(1, OPEN)))


def test_arms_trained_in_other_worlds_settings_are_refused(tmp_path, arms):
    other = transfer.load_arm("slow", tiny_run(tmp_path / "slow", time_limit=30.0))
    with pytest.raises(ValueError, match=r"'a' and 'slow'.*physics.time_limit"):
        transfer.check_same_episodes([arms[0], other])
    transfer.check_same_episodes(arms)  # their terms alone may differ


def test_the_sets_hold_their_maps_and_extrapolate_beyond_the_training_ranges():
    maps = transfer.held_out_maps(["minigames", "office", "generated_test", "generated_train",
                                   "extrapolation"], robots=4)
    keys = [m.key for m in maps]
    assert len(keys) == len(set(keys))
    assert [m.name for m in maps if m.set == "minigames"] == list(transfer.MINIGAMES)
    test = {m.name: dict(m.worlds) for m in maps if m.set == "generated_test"}
    assert set(test) == set(transfer.FAMILIES)
    assert all(w["world_seeds"][0] == transfer.TEST_SEEDS[0] for w in test.values())
    assert all(dict(m.worlds)["world_seeds"][0] == 0 for m in maps
               if m.set == "generated_train")
    for m in maps:
        if m.set != "extrapolation":
            continue
        ranges = dict(m.worlds).get("world_ranges", {})
        generator = family(m.scenario.split(":", 1)[1])
        generator.ranges(ranges)  # within the family's limits
        for name, (low, high) in ranges.items():
            default_low, default_high = generator.parameters[name].default
            assert high <= default_low or low >= default_high, (m.name, name)
    assert any(m.robots > 5 for m in maps if m.set == "extrapolation")
    with pytest.raises(ValueError, match="unknown set"):
        transfer.held_out_maps(["minigame"], robots=4)
    with pytest.raises(ValueError, match="--sg2maps: /nowhere"):
        transfer.held_out_maps(["sg2maps"], robots=4, sg2maps=Path("/nowhere"))


def test_a_socialgym_map_without_room_plays_the_most_robots_it_places(arms):
    folder = require(SG2MAPS / "tmp_test4", "SocialGym 2.0's maps")
    held = transfer.HeldOutMap("sg2maps", "tmp_test4", str(folder), 4, socialgym_folder=True)
    assert transfer.fitted_robots(held, arms[0], transfer.scenario_of(held)) == 2


def fake_document(seeds_b: int = 2) -> dict:
    """A document of two arms on two maps with known per-episode values."""
    rng = np.random.default_rng(0)
    maps = {}
    for set_name, name in (("generated_train", "doorway"), ("generated_test", "doorway")):
        result = {"set": set_name, "name": name, "scenario": "generated:doorway",
                  "worlds": {}, "robots": 4,
                  "only_local": {"team_success": [0.0] * 40, "collisions": [1.0] * 40,
                                 "makespan": [30.0] * 40},
                  "arms": {"a": {m: rng.integers(0, 2, (2, 40)).astype(float).tolist()
                                 for m in transfer.METRICS},
                           "b": {m: np.ones((seeds_b, 40)).tolist()
                                 for m in transfer.METRICS}}}
        maps[f"{set_name}/{name}"] = result
    return maps


def test_the_paired_comparisons_and_the_summary_follow_the_episodes():
    maps = fake_document()
    paired = transfer.comparisons(maps["generated_test/doorway"], reference="a")
    assert set(paired) == {"a - only_local", "b - only_local", "b - a"}
    assert paired["b - only_local"]["mean"] == 1.0  # every episode 1 against 0
    a = np.asarray(maps["generated_test/doorway"]["arms"]["a"]["team_success"])
    assert paired["b - a"]["mean"] == pytest.approx(1.0 - a.mean())
    assert paired["b - a"]["ci_low"] <= 1.0 - a.mean() <= paired["b - a"]["ci_high"]
    with pytest.raises(ValueError, match="as many seeds"):
        transfer.comparisons(fake_document(seeds_b=3)["generated_test/doorway"], "a")


def test_the_result_file_follows_its_schema_and_its_tables_are_generated_from_it(
        tmp_path, arms):
    made = transfer.document(arms, fake_document(), ["generated_train", "generated_test"], 4,
                             40, 0, "a", 0.05, seconds=1.0)
    check_document(made)
    text = transfer.tables(made)
    assert "| doorway | 0.00 | " in text and "## Generalisation gap" in text
    row = next(line for line in text.splitlines() if line.startswith("| generated_test | b |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2:4] == ["1.00 [1.00, 1.00]"] * 2  # every run of b succeeded
    a_seeds = np.nanmean(np.asarray(made["maps"]["generated_test/doorway"]["arms"]["a"][
        "team_success"]), axis=1)
    assert cells[4].startswith(f"{np.mean(a_seeds < 1.0):.2f} [")  # P(b > a) on the map
    assert cells[5:] == ["1 of 1", "1 of 1", ""]  # no map has its own specialist
    source = tmp_path / "transfer.json"
    source.write_text(json.dumps(made))
    transfer.main(["--from-results", str(source)])
    assert (tmp_path / "transfer.md").read_text() == text


@pytest.mark.slow
def test_a_maps_own_specialist_plays_there_alone_and_every_arm_is_compared_with_it(
        tmp_path, arms):
    """A run trained on one shipped map alone is that map's own specialist: played there
    beside the arms on the same episodes, compared with every arm, tabled in its own column
    and counted in the summary; an arm can be one; a run for no judged map, or two for one
    map, are refused."""
    own = transfer.load_arm("open specialist", tiny_run(tmp_path / "own", seed=3))
    elsewhere = transfer.HeldOutMap("generated_test", "open", "generated:open", 2)
    mapping = transfer.own_specialists([own], [OPEN, elsewhere])
    assert list(mapping) == [OPEN.key] and mapping[OPEN.key] is own  # shipped maps only
    result = transfer.judge(arms, [OPEN], 4, 0, log=print, own=mapping)[OPEN.key]
    assert result["own_specialist"] == "open specialist"
    assert result["checkpoints"] == {"a": arms[0].sha256, "b": arms[1].sha256,
                                     "open specialist": own.sha256}
    alone = transfer.judge_map([own], OPEN, 4, 0)
    assert result["arms"]["open specialist"] == alone["arms"]["open specialist"]
    assert result["only_local"] == alone["only_local"]
    paired = transfer.comparisons(result, "a")
    a, o = (np.asarray(result["arms"][n]["team_success"], float) for n in ("a", "open specialist"))
    assert paired["a - own specialist"]["mean"] == pytest.approx(np.nanmean(a - o))
    # an arm as its map's own specialist: nothing played again, no comparison with itself
    plain = transfer.judge(arms, [OPEN], 4, 0, log=print)[OPEN.key]
    marked = {**plain, "only_local": {m: [-1.0] * 4 for m in transfer.METRICS}}
    as_arm = transfer.judge(arms, [OPEN], 4, 0, done={OPEN.key: marked}, log=print,
                            own={OPEN.key: arms[0]})[OPEN.key]
    assert as_arm["only_local"] == marked["only_local"]  # kept, not played again
    assert as_arm["arms"] == plain["arms"] and as_arm["own_specialist"] == "a"
    assert set(transfer.comparisons(as_arm, "a")) == {
        "a - only_local", "b - only_local", "b - a", "b - own specialist"}
    made = transfer.document(arms, {OPEN.key: result}, ["minigames"], 2, 4, 0, "a", 0.05,
                             seconds=1.0, specialists=[own])
    check_document(made)
    assert made["specialists"]["open specialist"]["sha256"] == own.sha256
    text = transfer.tables(made)
    header = next(line for line in text.splitlines() if line.startswith("| map |"))
    assert header.endswith("| own specialist | a - own specialist | b - own specialist |")
    row = next(line for line in text.splitlines() if line.startswith("| minigames | b |"))
    assert row.rstrip(" |").endswith("of 1")  # b within the margin of the own specialist?
    with pytest.raises(ValueError, match="both trained on open alone"):
        transfer.own_specialists([own, arms[0]], [OPEN])
    doorway_family = dataclasses.replace(own, trained_on=("generated:doorway",))
    with pytest.raises(ValueError, match="not on one shipped map"):
        transfer.own_specialists([doorway_family], [OPEN])


@pytest.mark.slow
def test_a_resumed_run_plays_only_the_arms_added_or_retrained_since(tmp_path, arms):
    first = transfer.judge(arms[:1], [OPEN], 4, 0, log=print)
    both = transfer.judge(arms, [OPEN], 4, 0, log=print)
    later = transfer.judge(arms, [OPEN], 4, 0, done=first, log=print)
    assert later[OPEN.key] == both[OPEN.key]
    assert later[OPEN.key]["checkpoints"] == {"a": arms[0].sha256, "b": arms[1].sha256}
    assert transfer.judge(arms, [OPEN], 4, 0, done=later, log=None) == later  # nothing to play
    marked = {**first[OPEN.key], "only_local": {m: [-1.0] * 4 for m in transfer.METRICS}}
    kept = transfer.judge(arms[:1], [OPEN], 4, 0, done={OPEN.key: marked}, log=None)
    assert kept[OPEN.key] == marked  # an unchanged arm and Only Local are not played again
    retrained = {**marked, "checkpoints": {"a": "an older checkpoint"}}
    again = transfer.judge(arms[:1], [OPEN], 4, 0, done={OPEN.key: retrained}, log=print)
    assert again[OPEN.key]["arms"] == first[OPEN.key]["arms"]
    assert again[OPEN.key]["only_local"] == marked["only_local"]


def test_a_resume_needs_the_same_settings_and_the_arms_as_many_seeds(tmp_path, arms):
    wanted = transfer.settings(arms, 4, 0, 2)
    assert transfer.read_earlier(tmp_path, wanted) == {}  # nothing yet
    made = transfer.document(arms, {}, ["minigames"], 2, 4, 0, "a", 0.05, seconds=1.0)
    (tmp_path / "transfer.json").write_text(json.dumps(
        {**made, "unfinished": {"x/y": {"robots": 1}}}))
    assert transfer.read_earlier(tmp_path, wanted) == {"x/y": {"robots": 1}}
    for changed, name in ((transfer.settings(arms, 4, 0, 3), "robots"),
                          (transfer.settings(arms, 5, 1, 2), "episodes, seed")):
        with pytest.raises(ValueError, match=f"made with other {name}"):
            transfer.read_earlier(tmp_path, changed)
    # the first arm's own worlds keywords (training's holdout) do not count
    held = dataclasses.replace(arms[0], options=arms[0].options.replace(world_holdout=None))
    assert transfer.settings([held], 4, 0, 2) == wanted
    three = tiny_run(tmp_path / "three", num_seeds=3)
    with pytest.raises(SystemExit, match="has 3 seeds and the reference a 2"):
        transfer.main(["--arm", f"a={arms[0].path}", "--arm", f"c={three}"])


@pytest.mark.parametrize("argv, message", [
    ([], "at least one --arm"),
    (["--arm", "a"], "expected NAME=RUN"),
    (["--arm", "only_local=x"], "is taken"),
    (["--arm", "a=/nowhere"], "no checkpoint at /nowhere"),
    (["--arm", "a=/x", "--reference", "b"], "--reference 'b' is not one of the arms"),
])
def test_bad_arguments_name_what_is_wrong(argv, message):
    with pytest.raises(SystemExit, match=message):
        transfer.main(argv)


@pytest.mark.slow
def test_the_command_writes_its_files_after_every_map_and_adds_an_arm_on_resume(
        tmp_path, arms, monkeypatch, capsys):
    other = transfer.HeldOutMap("office", "open", "open", 2)  # another key, the same program
    monkeypatch.setattr(transfer, "held_out_maps",
                        lambda sets, robots, sg2maps, recordings: [OPEN, other])
    written = []
    real = transfer.tables
    monkeypatch.setattr(transfer, "tables", lambda d: written.append(list(d["pending"]))
                        or real(d))
    out = tmp_path / "out"
    first = ["--arm", f"a={arms[0].path}", "--episodes", "4", "--out", str(out)]
    transfer.main(first)
    assert written[0] == [other.key] and written[-1] == []  # after each map, then at the end
    document = json.loads((out / "transfer.json").read_text())
    check_document(document)
    assert list(document["maps"]) == [OPEN.key, other.key] and document["pending"] == []
    assert (out / "transfer.md").read_text() == real(document)
    judge_map = transfer.judge_map

    def killed_at_the_second(arms_, held, *a):
        if held.key == other.key:
            raise KeyboardInterrupt
        return judge_map(arms_, held, *a)

    monkeypatch.setattr(transfer, "judge_map", killed_at_the_second)
    with pytest.raises(KeyboardInterrupt):  # b added, killed before its second map
        transfer.main([*first, "--arm", f"b={arms[1].path}", "--resume"])
    halfway = json.loads((out / "transfer.json").read_text())
    assert list(halfway["maps"]) == [OPEN.key] and halfway["pending"] == [other.key]
    assert halfway["unfinished"][other.key] == document["maps"][other.key] | {
        "paired": halfway["unfinished"][other.key]["paired"]}  # a's values kept, not lost
    monkeypatch.setattr(transfer, "judge_map", judge_map)
    transfer.main([*first, "--arm", f"b={arms[1].path}", "--resume"])
    again = json.loads((out / "transfer.json").read_text())
    assert set(again["maps"][OPEN.key]["arms"]) == {"a", "b"}
    for key in (OPEN.key, other.key):  # a's values and Only Local's kept, b's added
        assert again["maps"][key]["arms"]["a"] == document["maps"][key]["arms"]["a"]
        assert again["maps"][key]["only_local"] == document["maps"][key]["only_local"]
    assert "b - a" in again["maps"][OPEN.key]["paired"]
    assert "resuming" in capsys.readouterr().out
    # an arm named as both maps' own specialist (they play "open"): nothing played again
    transfer.main([*first, "--arm", f"b={arms[1].path}", "--own-specialist", "a", "--resume"])
    owned = json.loads((out / "transfer.json").read_text())
    assert [r["own_specialist"] for r in owned["maps"].values()] == ["a", "a"]
    assert owned["maps"][OPEN.key]["arms"] == again["maps"][OPEN.key]["arms"]
    assert "b - own specialist" in owned["maps"][OPEN.key]["paired"]
    # the worst case added to a finished judge (later code may play it): the maps keep the
    # provenance of the run that played them, the worst case carries its own
    monkeypatch.setattr(transfer, "FAMILIES", ("open",))
    monkeypatch.setattr(transfer, "worst_of_seeds", lambda actor, weights, *rest, **kw: {
        "0.1": [0.5] * weights.lanes})
    transfer.main([*first, "--arm", f"b={arms[1].path}", "--own-specialist", "a", "--resume",
                   "--worst-worlds", "10", "--alpha", "0.1"])
    worst = json.loads((out / "transfer.json").read_text())
    check_document(worst)
    assert worst["provenance"] == owned["provenance"] and worst["maps"] == owned["maps"]
    assert worst["worst"]["pending"] == [] and set(worst["worst"]["arms"]) == {"a", "b"}
    assert worst["worst"]["provenance"]["created"] >= owned["provenance"]["created"]


@pytest.mark.slow
def test_every_seed_of_every_arm_plays_its_worst_case_on_one_compiled_player(arms):
    """The weights are the worst-case player's argument: a seed's rollouts equal those of its
    checkpoint's policy (its weights constants of the program) on the same worlds and keys,
    metric by metric, and every seed of both arms plays on one compiled program."""
    held = transfer.HeldOutMap("generated_test", "open", "generated:open", 2)
    options = transfer.map_options(arms[0], held)
    players = WorstPlayers()
    results = [worst_of_seeds(arm.actor, arm.weights, arm.deterministic, options, "open", 2, 6,
                              [0.5, 1.0], 3, chunk=4, players=players) for arm in arms]
    params, runner, draw = players.get("open", 2, options, arms[0].actor, arms[0].deterministic,
                                       4)
    assert len(runner._executables) == 1  # one program for 2 arms x 2 seeds
    env, by_count = params_by_count("generated:open", [2], options=options)
    ids = transfer.TEST_SEEDS[0] + np.arange(6)
    key = jax.random.key(11)
    for arm, result in zip(arms, results, strict=True):
        for index in range(arm.seeds):
            policy = load_checkpoint_policy(arm.path, env, seed_index=index,
                                            deterministic=arm.deterministic)
            constants = world_players(env, params, policy, 4)
            _, alone = play_rollout(*constants, params, ids, key)
            _, argued = play_rollout(runner, draw, params, ids, key, arm.weights.seed(index))
            for name in REPORTED:
                np.testing.assert_array_equal(argued[name], alone[name])
            worst = play_worst(env, params, policy, ids, [0.5, 1.0], 3, 4, compiled=constants)
            assert [result[k][index] for k in ("0.5", "1")] == [
                worst.fraction(a)[0] for a in (0.5, 1.0)]
    assert len(runner._executables) == 1
    assert len({np.asarray(x).tobytes() for x in jax.tree.leaves(arms[1].weights.seed(0))}
               - {np.asarray(x).tobytes() for x in jax.tree.leaves(arms[0].weights.seed(0))})


@pytest.mark.slow
def test_the_worst_case_per_seed_is_kept_on_resume_and_tabled(arms, monkeypatch):
    monkeypatch.setattr(transfer, "FAMILIES", ("open",))
    worst = transfer.judge_worst(arms[:1], 2, 4, [0.5, 1.0], 0, log=print)
    values = worst["arms"]["a"]["families"]["open"]
    assert worst["alphas"] == ["0.5", "1"] and set(values) == {"0.5", "1"}
    assert all(len(v) == 2 and all(0.0 <= x <= 1.0 for x in v) for v in values.values())
    assert all(lo <= hi for lo, hi in zip(values["0.5"], values["1"], strict=True))  # worst first

    def never(*args, **kwargs):
        raise AssertionError("an unchanged arm is not played again")

    assert worst["protocol"] == "sfl" and worst["pending"] == []
    assert worst["provenance"]["seconds"]["worst"] > 0

    monkeypatch.setattr(transfer, "worst_of_seeds", never)
    again = transfer.judge_worst(arms[:1], 2, 4, [0.5, 1.0], 0, earlier=worst)
    assert again["arms"] == worst["arms"]
    with pytest.raises(AssertionError, match="not played again"):  # other worlds: played
        transfer.judge_worst(arms[:1], 2, 8, [0.5, 1.0], 0, earlier=worst)
    for changed in ({"protocol": None}, {"provenance": {**worst["provenance"], "git": {}}}):
        with pytest.raises(AssertionError, match="not played again"):  # other code: played
            transfer.judge_worst(arms[:1], 2, 4, [0.5, 1.0], 0, earlier=worst | changed)
    # a stopped run keeps its finished families: a second family is played, the first lent,
    # and every finished family is handed on as it ends
    monkeypatch.setattr(transfer, "FAMILIES", ("open", "hallway"))
    played, handed = [], []

    def fake(actor, weights, deterministic, options, family, *rest, **kwargs):
        played.append(family)
        return {"0.5": [0.25] * weights.lanes, "1": [0.5] * weights.lanes}

    monkeypatch.setattr(transfer, "worst_of_seeds", fake)
    grown = transfer.judge_worst(arms[:1], 2, 4, [0.5, 1.0], 0, earlier=worst,
                                 on_family=lambda b: handed.append(json.loads(json.dumps(b))))
    assert played == ["hallway"] and [b["pending"] for b in handed] == [[]]
    assert grown["arms"]["a"]["families"]["open"] == values
    assert grown["arms"]["a"]["families"]["hallway"] == {"0.5": [0.25] * 2, "1": [0.5] * 2}
    played.clear()
    handed.clear()
    transfer.judge_worst(arms[:1], 2, 4, [0.5, 1.0], 0,
                         on_family=lambda b: handed.append(json.loads(json.dumps(b))))
    assert played == ["open", "hallway"]
    assert [b["pending"] for b in handed] == [["a/hallway"], []]
    made = transfer.document(arms[:1], {}, ["generated_test"], 2, 4, 0, "a", 0.05, 1.0)
    made["worst"] = worst
    check_document(made)
    text = transfer.tables(made)
    assert "## Worst case over 4 held-out worlds per family" in text
    assert "| family | a worst 50% | a worst 100% |" in text
    # an arm still to play a family: its cells read "pending", the family's row stays
    partial = {**worst, "arms": {**worst["arms"], "z": {"sha256": "", "families": {}}}}
    rows = [line for line in transfer.worst_section(partial) if line.startswith("| open |")]
    assert len(rows) == 1 and rows[0].endswith("| pending | pending |")


RECORDINGS = SG2MAPS.parent / "pedestrians" / "eth_ucy"


def test_the_recorded_set_holds_each_scene_as_ghosts_and_handed_over(tmp_path):
    """Ten maps: the five standard scenes, each with ghosts and with hand-overs to the
    fitted constants (the same for every arm), keeping the people metrics; a missing track
    file is named; the default sets leave the recorded people out."""
    maps = transfer.held_out_maps(["recorded"], 3, recordings=require(
        RECORDINGS, "the ETH/UCY recordings"))
    assert [m.name for m in maps[:2]] == ["ETH, ghost", "ETH, handover"] and len(maps) == 10
    for held in maps:
        assert held.scenario.startswith("recorded:") and held.robots == 3
        assert dict(held.keywords)["human_constants"] == "eth_ucy"
        assert set(transfer.RECORDED_METRICS) <= set(held.metrics)
    with pytest.raises(ValueError, match="no biwi_eth.txt"):
        transfer.held_out_maps(["recorded"], 3, recordings=tmp_path)
    default_sets = transfer.parser().parse_args(["--arm", "a=x"]).sets
    assert "recorded" not in default_sets and "simulated_crowds" not in default_sets


def test_the_simulated_crowds_set_holds_each_scene_with_both_constants(tmp_path):
    """The same five scenes with simulated people (no replay), once with the published and
    once with the fitted constants, the same for every arm; the people metrics a simulated
    crowd has (no log deviation: nothing recorded to deviate from)."""
    maps = transfer.held_out_maps(["simulated_crowds"], 3, recordings=require(
        RECORDINGS, "the ETH/UCY recordings"))
    assert [m.name for m in maps[:2]] == ["ETH, published constants", "ETH, fitted constants"]
    assert len(maps) == 10 and {m.set for m in maps} == {"simulated_crowds"}
    recorded = transfer.held_out_maps(["recorded"], 3, recordings=RECORDINGS)
    assert {m.scenario for m in maps} == {m.scenario for m in recorded}
    for held, constants in zip(maps, ["published", "eth_ucy"] * 5, strict=True):
        keywords = dict(held.keywords)
        assert keywords["human_replay"] == "off" and keywords["human_constants"] == constants
        assert keywords["num_humans"] == transfer.SIMULATED_PEOPLE
        assert "log_deviation" not in held.metrics
        assert set(transfer.SIMULATED_METRICS) <= set(held.metrics)
    with pytest.raises(ValueError, match="no biwi_eth.txt"):
        transfer.held_out_maps(["simulated_crowds"], 3, recordings=tmp_path)


@pytest.mark.slow
def test_arms_trained_among_other_crowds_are_judged_among_the_same_recorded_people(tmp_path):
    """Two arms whose training crowds differ (published and fitted constants) play the same
    episodes among recorded people, whose hand-overs the map sets: allowed there, refused on
    a map that keeps the arms' own crowds; every seed keeps the people metrics beside team
    success, paired with the reference, and the tables show them."""
    recordings = require(RECORDINGS, "the ETH/UCY recordings")
    arms = [transfer.load_arm(name, tiny_run(tmp_path / name, seed=seed,
                                             human_constants=constants))
            for name, seed, constants in (("published", 0, "published"),
                                          ("calibrated", 7, "eth_ucy"))]
    with pytest.raises(ValueError, match=r"'published' and 'calibrated'.*human_constants"):
        transfer.check_same_episodes(arms, [OPEN])
    held = next(m for m in transfer.held_out_maps(["recorded"], 2, recordings=recordings)
                if m.name == "ZARA1, handover")
    transfer.check_same_episodes(arms, [held])
    result = {"set": held.set, "name": held.name, "scenario": held.scenario, "worlds": {},
              **transfer.judge_map(arms, held, episodes=3, seed=0)}
    for name in ("published", "calibrated"):
        values = result["arms"][name]
        assert set(transfer.RECORDED_METRICS) <= set(values)
        assert np.asarray(values["people_reached"]).shape == (2, 3)
    assert np.all(np.isfinite(result["only_local"]["log_deviation"]))
    made = transfer.document(arms, {held.key: result}, ["recorded"], 2, 3, 0, "published",
                             0.05, seconds=1.0)
    check_document(made)
    paired = made["maps"][held.key]["paired"]
    assert "calibrated - published: log_deviation" in paired
    text = transfer.tables(made)
    assert "Log deviation (m):" in text and "| ZARA1, handover |" in text
    # the same scene with simulated people, constants set by the map: both arms play it too
    simulated = next(m for m in transfer.held_out_maps(["simulated_crowds"], 2,
                                                       recordings=recordings)
                     if m.name == "ZARA1, fitted constants")
    transfer.check_same_episodes(arms, [simulated])
    played = {"set": simulated.set, "name": simulated.name, "scenario": simulated.scenario,
              "worlds": {}, **transfer.judge_map(arms, simulated, episodes=3, seed=0)}
    assert "log_deviation" not in played["arms"]["published"]
    assert np.asarray(played["arms"]["calibrated"]["collisions_human"]).shape == (2, 3)
    both = transfer.document(arms, {held.key: result, simulated.key: played},
                             ["recorded", "simulated_crowds"], 2, 3, 0, "published", 0.05,
                             seconds=1.0)
    check_document(both)
    text = transfer.tables(both)
    assert "## simulated_crowds" in text and "| ZARA1, fitted constants |" in text
