"""The typed options of ``make`` and the one vocabulary of checks (``sgjax.validation``): every
error names the field and the value; options travel as one ``MakeOptions`` (nested form for
files); pedestrian defaults live on their dataclasses."""

import dataclasses
import pickle

import numpy as np
import pytest

import sgjax
from sgjax.environment.env import EnvConfig
from sgjax.environment.options import MakeOptions
from sgjax.environment.registry import HUMAN_TOP_SPEED
from sgjax.humans.groups import GroupParams
from sgjax.humans.map_params import human_params
from sgjax.humans.orca_model import OrcaParams
from sgjax.humans.pedestrians import HumanConfig, HumanParams
from sgjax.maps.io import load
from sgjax.validation import (
    FrozenDict,
    check_bool,
    check_choice,
    check_int,
    check_keys,
    check_positive,
    check_range,
    check_type,
    freeze,
    suggest,
    thaw,
)


@pytest.mark.parametrize("check, args, message", [
    (check_int, ("a.k", 0), "a.k must be a positive integer, got 0"),
    (check_int, ("k", True), "k must be a positive integer, got True"),
    (check_int, ("k", 1.0), "k must be a positive integer, got 1.0"),
    (check_int, ("n", -1, 0), "n must be a non-negative integer, got -1"),
    (check_int, ("n", 2, 3), "n must be an integer >= 3, got 2"),
    (check_positive, ("dt", 0.0), "dt must be a positive number, got 0.0"),
    (check_positive, ("dt", float("inf")), "dt must be a positive number, got inf"),
    (check_positive, ("dt", "1"), "dt must be a positive number, got '1'"),
    (check_positive, ("noise", -0.1, True), "noise must be a non-negative number, got -0.1"),
    (check_range, ("gamma", 1.5, 0.0, 1.0), r"gamma must be in \[0, 1\], got 1.5"),
    (check_bool, ("flag", 1), "flag must be True or False, got 1"),
    (check_choice, ("mode", "continous", ("go_stop", "continuous")),
     r"mode must be one of \('go_stop', 'continuous'\), got 'continous' \(did you mean "
     r"'continuous'\?\)"),
    (check_type, ("c[1]", [1, 2.5], tuple[int, ...]), r"c\[1\]\[1\] must be an integer, got 2.5"),
    (check_type, ("b", 3, str | None), "b must be a string or null, got 3"),
    (check_type, ("p", [1], tuple[int, int]), r"p must be a list of 2 items, got \[1\]"),
    (check_keys, ("env", ["num_arcz"], ["num_arcs", "dt"]),
     r"env: unknown key 'num_arcz' \(did you mean 'num_arcs'\?\); valid keys are: num_arcs, dt"),
])
def test_each_check_names_the_field_and_the_value(check, args, message):
    with pytest.raises(ValueError, match=message):
        check(*args)


def test_checks_pass_good_values_numpy_ones_included():
    check_int("k", np.int32(3))
    check_positive("dt", np.float32(0.1))
    check_positive("noise", 0, allow_zero=True)
    check_range("gamma", 1, 0.0, 1.0)
    check_type("x", 3, float)  # an int is a number
    check_type("c", [[0, 1], (2, 3)], tuple[tuple[int, int], ...])
    assert suggest("doorwya", ["doorway", "hallway"]) == " (did you mean 'doorway'?)"
    assert suggest("zzz", ["doorway"]) == ""
    with pytest.raises(TypeError, match="unknown option"):
        check_keys("make", ["x"], ["y"], "option", TypeError)


def test_freeze_and_thaw_are_one_pair():
    data = {"rewards": {"progress": 1.0, "weights": [1, [2, 3]]}, "list": [{"a": 1}]}
    frozen = freeze(data)
    assert isinstance(frozen, FrozenDict) and frozen == {"rewards": {
        "progress": 1.0, "weights": (1, (2, 3))}, "list": ({"a": 1},)}
    assert frozen["rewards"]["weights"] == (1, (2, 3)) and isinstance(frozen["list"][0], dict)
    assert hash(frozen) == hash(freeze({"list": [{"a": 1}], "rewards": {
        "weights": [1, [2, 3]], "progress": 1.0}}))  # order does not matter
    with pytest.raises(TypeError, match="frozen mapping"):
        frozen["x"] = 1
    thawed = thaw(frozen)
    assert thawed == data and type(thawed["rewards"]) is dict
    assert type(thawed["rewards"]["weights"][1]) is list
    assert pickle.loads(pickle.dumps(frozen)) == frozen


def test_make_options_round_trip_through_their_nested_form():
    options = MakeOptions.from_keywords(num_agents=3, human_groups=[2], num_humans=4,
                                        observations="navigation", dt=0.05, arrived="park",
                                        world_ranges={"door_width": [1, 1.5]})
    nested = options.to_dict()
    assert set(nested) == {"robots", "humans", "terms", "physics", "worlds"}
    assert nested["worlds"]["world_ranges"] == [["door_width", 1.0, 1.5]]
    assert nested["humans"]["human_groups"] == [2] and nested["robots"]["arrived"] == "park"
    assert MakeOptions.from_dict(nested) == options
    assert MakeOptions.from_dict({"physics": {"dt": 0.05}}) == MakeOptions.from_keywords(dt=0.05)
    with pytest.raises(ValueError, match=r"opts: unknown group 'physic' \(did you mean"):
        MakeOptions.from_dict({"physic": {}}, "opts")
    with pytest.raises(ValueError, match=r"options.robots: unknown option 'dt'.*valid options "
                                         r"are: num_agents"):
        MakeOptions.from_dict({"robots": {"dt": 0.1}})
    with pytest.raises(ValueError, match="options.terms must be a mapping"):
        MakeOptions.from_dict({"terms": "default"})


def test_make_takes_options_whole_and_flat_keywords_on_top():
    options = MakeOptions.from_keywords(num_agents=2, time_limit=5.0)
    env, params = sgjax.make("open", options=options, num_agents=3)
    assert env.max_agents == 3 and int(params.max_steps) == 50
    same, _ = sgjax.make("open", num_agents=3, time_limit=5.0)
    assert same == env


@pytest.mark.parametrize("keywords, message", [
    ({"action_mode": "velocity"}, "action_mode must be one of"),
    ({"arrived": "stay"}, "arrived must be one of"),
    ({"ended": "settle"}, "ended must be one of"),
    ({"decision_period": 0}, "decision_period must be a positive integer, got 0"),
    ({"humans_see_robots": "yes"}, "humans_see_robots must be True or False, got 'yes'"),
    ({"num_humans": -1}, "num_humans must be a non-negative integer, got -1"),
    ({"goal_tolerance": float("nan")}, "goal_tolerance must be a positive number, got nan"),
])
def test_the_static_settings_are_checked_once_with_clear_errors(keywords, message):
    """``action_mode``, ``arrived``, ``ended`` and ``decision_period`` are checked by the
    options (``EnvConfig`` takes them as given): a bad value is an error naming it."""
    with pytest.raises(ValueError, match=message):
        sgjax.make("open", num_agents=2, **keywords)
    fields = {f.name for f in dataclasses.fields(EnvConfig)}
    assert {"action_mode", "arrived", "ended", "decision_period"} <= fields


def test_pedestrian_defaults_live_on_their_dataclasses():
    """``human_params`` fills in the map's slots and routes; every constant is its dataclass's
    default, as a float32 array."""
    spec = load("doorway")
    hp = human_params(spec, HumanConfig(max_humans=4), 4, 0.3, groups=(2,))
    defaults = {f.name: f.default for f in dataclasses.fields(HumanParams)
                if f.default is not dataclasses.MISSING}
    for name in ("speed_mean", "speed_std", "speed_min", "speed_max", "max_speed_factor",
                 "waypoint_radius", "robot_weight"):
        assert getattr(hp, name).dtype == np.float32
        assert float(getattr(hp, name)) == pytest.approx(defaults[name]), name
    assert float(hp.orca.time_horizon) == OrcaParams().time_horizon
    assert float(hp.groups.coherence) == GroupParams(leader=None).coherence
    assert hp.groups.leader.tolist() == [0, 0, 2, 3]
    assert HUMAN_TOP_SPEED == 2.6  # m/s: 2.0 x the 1.3 cap
    blind = human_params(spec, HumanConfig(max_humans=4), 4, 0.3, see_robots=False)
    assert float(blind.robot_weight) == 0.0 and float(blind.orca.robot_share) == 0.0
