"""SocialGym 2.0 experiment configs (``config_runner/configs/*.json``, the paper's Listing 1) as
sgjax train configs.

    python -m train.run.socialgym_config door_ao.json --out door_ao.yaml   # the table, the YAML
    python -m train --config door_ao.json                              # converts, then trains

Every key of ``src/config_run.py`` (``../shared/reference/socialgym2.md`` section 4) is read, with
SocialGym's defaults for the keys a file leaves out. The result is the experiment as SocialGym ran
it: its time step (dt 0.025 s), its observation switches, reward weights and episode enders, SB3
PPO's hyperparameters and network (two 64-unit tanh layers over an LSTM of the others, as
``config_run`` always installed), VecNormalize, evaluation of the best checkpoint (its
``ending_eval_with_best``, true by default; false judges the final weights, sgjax's own rule)
with greedy actions. :func:`convert` returns the train config as a dict and a table of every
key: its value and what it became. A key that cannot be honoured (an algorithm other than PPO,
the multiplicative stuck penalty, a penalty for robots that finished, resuming an SB3
checkpoint, ...) or an unknown key is a ``ConfigError`` naming the file and the key.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from sgjax.environment.presets import ZONE_OBSERVATIONS
from sgjax.terms.base import ConfigError
from sgjax.validation import suggest
from train.algorithm.config import config_from_dict

SOCIALGYM_DT = 0.025  # s: UTMRS's delta_t in every shipped template (40 Hz)
SOCIALGYM_MAX_STEPS = 3200  # UTMRS max_steps: the stand-in limit when `timelimit` is off
SB3_PPO = {"learning_rate": 3e-4, "n_steps": 2048, "batch_size": 64, "n_epochs": 10,
           "gamma": 0.99, "gae_lambda": 0.95, "clip_range": 0.2, "ent_coef": 0.0,
           "vf_coef": 0.5, "max_grad_norm": 0.5}
SB3_TO_ALGORITHM = {"learning_rate": "learning_rate", "gamma": "gamma",
                    "gae_lambda": "gae_lambda", "clip_range": "clip_eps", "ent_coef": "ent_coef",
                    "vf_coef": "vf_coef", "max_grad_norm": "max_grad_norm",
                    "n_epochs": "update_epochs"}
NUM_ENVS = 16  # parallel environments; steps per update = n_steps as in SocialGym's one env
SCENARIOS = {"envs_door": "doorway", "envs_hallway": "hallway",
             "envs_intersection": "intersection", "envs_round_about": "roundabout",
             "envs_open": "open"}
RUN_TYPES = {"SACADRL": None, "AO": "any_order", "EO": "enforced_order"}

# config_run.py's defaults (socialgym2.md section 4).
DEFAULTS: dict[str, Any] = {
    "num_agents": 2, "eval_num_agents": None, "train_length": 100000, "eval_frequency": 25000,
    "intermediate_eval_trials": 25, "ending_eval_trials": 100, "ending_eval_with_best": True,
    "device": "cuda:0", "partially_observable": False, "train": True, "eval": True,
    "monitor": True, "local": False, "existence_penalty": 1, "success_reward": 100,
    "collision_penalty": 10, "starting_collision_penalty": 0,
    "collision_penalty_scale_duration": 0, "enforced_order_reward": 25,
    "enforced_order_track_exit": False, "enforced_order_penalty_for_incorrect_order": True,
    "enforced_order_weak_signal_out_of_zone": False, "penalty_for_multiple_agents_entering": True,
    "goal_distance_reward": True, "goal_distance_reward_clip": False, "collision_ender": False,
    "reward_stripper": False, "socialnavAPI": True, "timelimit": False,
    "timelimit_threshold": 2000, "entropy_ender": True, "entropy_max_distance": 0.25,
    "entropy_max_timesteps": 100, "entropy_reward": True, "entropy_constant_penalty": None,
    "entropy_constant_penalty_only_those_that_did_not_finish": True,
    "entropy_reward_multiplier": 100000, "entropy_multiply_negative_rewards_only": False,
    "collision_obs": True, "agent_goal_distance_obs": True, "agent_pose_obs": True,
    "agent_velocity_obs": False, "other_poses_obs": True, "other_velocities_obs": False,
    "agent_pose_ignore_theta": True, "agent_velocity_ignore_theta": True,
    "other_poses_ignore_theta": True, "other_velocities_ignore_theta": True,
    "other_poses_actual_positions": False, "policy_algo_sb3_contrib": False,
    "policy_algo_name": "PPO", "policy_name": "MlpPolicy", "policy_algo_kwargs": None,
    "debug": False, "experiment_names": "envs_open", "run_name": None, "continue_from": None,
    "run_type": "SACADRL",
}
# Other spellings found in SocialGym's files (the paper's Listing 1, old configs).
ALIASES = {"entropy_constant_penalty_only_not_finish":
           "entropy_constant_penalty_only_those_that_did_not_finish",
           "experiment_name": "experiment_names"}


def read_socialgym_config(path: str | Path) -> dict[str, Any]:
    """A SocialGym config file as a dict (JSON, or JSON with ``#`` comments as in the paper)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such config file")
    text = path.read_text()
    try:
        data = json.loads(text)
    except json.JSONDecodeError:
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise ConfigError(f"{path}: neither JSON nor YAML: {err}") from None
    if not isinstance(data, Mapping):
        raise ConfigError(f"{path}: expected an object of SocialGym config keys, got "
                          f"{type(data).__name__}")
    return dict(data)


def is_socialgym_config(data: Mapping[str, Any]) -> bool:
    """True when ``data`` uses SocialGym's keys rather than sgjax's sections."""
    return bool(set(data) & (set(DEFAULTS) | set(ALIASES))) and "env" not in data


def _observations(c: dict[str, Any], most_robots: int) -> list[Any]:
    obs: list[Any] = []
    if c["agent_goal_distance_obs"]:
        obs.append({"goal_distance": {"history": 2}})
    if c["socialnavAPI"]:
        obs.append({"goal": {"frame": "world"}})
    if c["agent_pose_obs"]:
        obs.append({"pose": {"heading": not c["agent_pose_ignore_theta"]}})
    if c["agent_velocity_obs"]:
        obs.append({"velocity": {"frame": "body", "history": 2,
                                 "turn_rate": not c["agent_velocity_ignore_theta"]}})
    if c["collision_obs"]:
        obs.append("collision")
    features = []
    if c["other_poses_obs"]:
        features += ["position"] + ([] if c["other_poses_ignore_theta"] else ["heading"])
    if c["other_velocities_obs"]:
        features.append("velocity")
    if features:
        obs.append({"others": {"k": max(1, most_robots - 1), "features": [*features, "mask"],
                               "line_of_sight": bool(c["partially_observable"]),
                               "relative_velocity": True}})
    if c["run_type"] in ("AO", "EO"):
        obs += ZONE_OBSERVATIONS
    if not obs:
        raise ConfigError("every observation switch is off: a policy needs an observation")
    return obs


def _rewards(c: dict[str, Any], limit_steps: int) -> dict[str, Any]:
    rewards: dict[str, Any] = {}
    if c["existence_penalty"]:
        rewards["existence"] = float(c["existence_penalty"])
    if c["success_reward"]:
        rewards["success"] = float(c["success_reward"])
    if c["collision_penalty_scale_duration"]:  # episodes of one env -> steps of each of ours
        steps = max(1, int(c["collision_penalty_scale_duration"]) * limit_steps // NUM_ENVS)
        rewards["collision"] = {"per_step": True, "weight": {
            "schedule": "linear", "start": float(c["starting_collision_penalty"]),
            "end": float(c["collision_penalty"]), "steps": steps}}
    elif c["collision_penalty"]:  # SocialGym: -1 on every step the collision flag is up
        rewards["collision"] = {"per_step": True, "weight": float(c["collision_penalty"])}
    if c["goal_distance_reward"]:
        rewards["progress"] = ({"weight": 1.0, "clip": [0.0, 1.0]}
                               if c["goal_distance_reward_clip"] else 1.0)
    if c["run_type"] != "SACADRL":  # SACADRL: no zone terms, nothing else (config_run)
        rewards["zone_order"] = {
            "weight": float(c["enforced_order_reward"]), "any_order": c["run_type"] == "AO",
            "incorrect_penalty": (c["run_type"] == "EO"
                                  and bool(c["enforced_order_penalty_for_incorrect_order"])),
            "multiple_entry_penalty": bool(c["penalty_for_multiple_agents_entering"]),
            "continuous": bool(c["enforced_order_weak_signal_out_of_zone"])}
    return rewards


def _enders(c: dict[str, Any], where: str) -> list[Any]:
    enders: list[Any] = ["success", "time_limit"]
    if c["entropy_ender"]:
        stuck: dict[str, Any] = {"distance": float(c["entropy_max_distance"]),
                                 "steps": int(c["entropy_max_timesteps"])}
        if c["entropy_reward"]:
            if c["entropy_constant_penalty"] is None:
                raise ConfigError(
                    f"{where}: entropy_reward with entropy_constant_penalty null asks for the "
                    f"multiplicative stuck penalty (x{c['entropy_reward_multiplier']} on the last "
                    "step's reward), which sgjax does not provide; set "
                    "entropy_constant_penalty (the paper used -100000)")
            if not c["entropy_constant_penalty_only_those_that_did_not_finish"]:
                raise ConfigError(
                    f"{where}: entropy_constant_penalty_only_those_that_did_not_finish false "
                    "would penalise robots that arrived; sgjax's stuck penalty goes to the "
                    "unfinished robots only")
            stuck["penalty"] = float(c["entropy_constant_penalty"])
        enders.append({"stuck": stuck})
    if c["collision_ender"]:
        enders.append({"collision": {"scope": "team"}})
    return enders


def _curriculum(value: Any, steps_per_episode: int, where: str) -> list[list[int]]:
    if isinstance(value, int) and not isinstance(value, bool) and value > 0:
        return [[0, value]]
    if (isinstance(value, list) and value and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, int) for v in p)
            for p in value)):
        return [[episode * steps_per_episode, n] for episode, n in value]
    raise ConfigError(f"{where}: num_agents: expected a robot count or [[episode, count], ...], "
                      f"got {value!r}")


class _Conversion:
    """One SocialGym experiment config being converted: its values (``c``, defaults filled
    in), the keys it gave, and the ``(key, value, what it became)`` rows so far."""

    def __init__(self, data: Mapping[str, Any], source: str):
        self.given: dict[str, Any] = {}
        for key, value in data.items():
            name = ALIASES.get(key, key)
            if name not in DEFAULTS:
                raise ConfigError(f"{source}: {key}: not a SocialGym 2.0 config key"
                                  f"{suggest(str(key), list(DEFAULTS))}")
            self.given[name] = value
        self.c = {**DEFAULTS, **self.given}
        self.where = source
        self.rows: list[tuple[str, str, str]] = []

    def row(self, key: str, became: str) -> None:
        shown = json.dumps(self.c[key]) + ("" if key in self.given else " (default)")
        self.rows.append((key, shown, became))

    def refuse(self, key: str, why: str) -> None:
        raise ConfigError(f"{self.where}: {key}: {json.dumps(self.c[key])} cannot be "
                          f"honoured: {why}")

    def world(self) -> tuple[list[str], int, list, list[int], int]:
        """Where and how long: ``(scenarios, time limit in steps, curriculum, evaluation
        counts, total environment steps)``."""
        c, row, refuse = self.c, self.row, self.refuse
        # Where and how long.
        names = c["experiment_names"]
        names = [names] if isinstance(names, str) else list(names)
        scenarios = []
        for name in names:
            if name not in SCENARIOS:
                refuse("experiment_names", f"{name!r} is not a shipped mini-game "
                       f"({', '.join(SCENARIOS)}); import its map with "
                       "sgjax.maps.import_socialgym and train on the saved .json")
            scenarios.append(SCENARIOS[name])
        row("experiment_names", f"env.scenarios {scenarios} (several: each on an equal share of "
            "the environments at once, where SocialGym cycled them episode by episode)")
        if c["timelimit"]:
            limit_steps = int(c["timelimit_threshold"])
            row("timelimit", f"the time_limit ender ({limit_steps} steps = "
                f"{limit_steps * SOCIALGYM_DT:g} s)")
        else:
            limit_steps = SOCIALGYM_MAX_STEPS
            row("timelimit", f"off: SocialGym had no time limit then (UTMRS's max_steps fed a done "
                f"nobody read); sgjax always has one, so {limit_steps} steps = "
                f"{limit_steps * SOCIALGYM_DT:g} s stands in")
        row("timelimit_threshold", f"env.time_limit {limit_steps * SOCIALGYM_DT:g} s"
            if c["timelimit"] else "unused (timelimit off)")
        curriculum = _curriculum(c["num_agents"], limit_steps, self.where)
        row("num_agents", f"env.curriculum {curriculum} (episode e -> environment step e x "
            f"{limit_steps}: every episode counted at the full time limit)")
        slots = max(n for _, n in curriculum)
        evaluation_counts = c["eval_num_agents"] or [n for _, n in curriculum][-1:]
        row("eval_num_agents", f"evaluation.num_agents {list(evaluation_counts)}")
        total = int(c["train_length"])
        row("train_length", f"algorithm.total_steps {total} (environment steps; SocialGym's "
            f"total_timesteps was this x {slots} robots)")
        return scenarios, limit_steps, curriculum, list(evaluation_counts), total

    def algorithm(self, total: int, slots: int) -> tuple[dict, dict]:
        """The algorithm and network sections (SB3 PPO, VecNormalize, config_run's LSTM over
        the others)."""
        c, row, refuse = self.c, self.row, self.refuse
        # Algorithm and network (SB3 PPO, VecNormalize, config_run's LSTM over the others).
        algo_name, policy_name = c["policy_algo_name"], c["policy_name"]
        recurrent = bool(c["policy_algo_sb3_contrib"])
        if (algo_name, policy_name, recurrent) not in (("PPO", "MlpPolicy", False),
                                                       ("RecurrentPPO", "MlpLstmPolicy", True)):
            refuse("policy_algo_name", f"{algo_name} with {policy_name} (sb3_contrib "
                   f"{recurrent}): sgjax trains PPO (MlpPolicy, or RecurrentPPO's MlpLstmPolicy)")
        kwargs = dict(c["policy_algo_kwargs"] or {})
        unknown = [k for k in kwargs if k not in SB3_PPO]
        if unknown:
            refuse("policy_algo_kwargs", f"no sgjax equivalent for {unknown}; known: "
                   f"{', '.join(SB3_PPO)}")
        ppo = {**SB3_PPO, **kwargs}
        n_steps = int(ppo["n_steps"]) if "n_steps" in kwargs else 512 * slots
        num_steps = max(1, n_steps // NUM_ENVS)
        batch = NUM_ENVS * num_steps * slots  # agent transitions per update
        # sgjax's minibatches are whole agent sequences (NUM_ENVS x slots of them): as many as SB3's
        # batch_size asks for, or the nearest count that splits the sequences evenly below it.
        wanted = max(1, batch // int(ppo["batch_size"]))
        sequences = NUM_ENVS * slots
        minibatches = max(m for m in range(1, min(wanted, sequences) + 1) if sequences % m == 0)
        algorithm: dict[str, Any] = {
            "name": "ippo", "total_steps": total, "num_envs": NUM_ENVS, "num_steps": num_steps,
            "num_minibatches": minibatches,
            "anneal_lr": False, "normalize_observations": True, "normalize_rewards": True,
            "reward_clip": 10.0, **{SB3_TO_ALGORITHM[k]: ppo[k] for k in SB3_TO_ALGORITHM}}
        row("policy_algo_name", "algorithm.name ippo (PPO, one policy shared by the robots as "
            "SocialGym's agents shared one SB3 model)")
        row("policy_algo_sb3_contrib", "network.kind lstm, recurrent_size 256 (RecurrentPPO's "
            "MlpLstmPolicy: an LSTM of 256 over time in the actor and another in the critic, "
            "between the features extractor and the MLP, reset at episode starts)"
            if recurrent else "network.kind mlp")
        row("policy_name", "network: hidden [64, 64] tanh (SB3's MlpPolicy) over an LSTM encoder "
            "of the others (64 units, config_run's LSTMAgentObs), one encoder for the actor and "
            "the critic (SB3's features extractor, shared by default)")
        row("policy_algo_kwargs", f"PPO {json.dumps(ppo)} -> algorithm num_envs {NUM_ENVS} x "
            f"num_steps {num_steps} (= n_steps {n_steps} environment steps per update), "
            f"num_minibatches {minibatches} (batch_size {ppo['batch_size']} asks for {wanted} "
            f"of {batch} transitions; sgjax's minibatches are whole sequences, {sequences} per "
            f"update{'' if minibatches == wanted else ', so fewer and larger ones'}), "
            f"update_epochs {ppo['n_epochs']}; VecNormalize -> normalized observations and "
            "rewards, clip 10")
        network: dict[str, Any] = {"kind": "lstm" if recurrent else "mlp", "hidden": [64, 64],
                                   "activation": "tanh", "others_encoder": "lstm",
                                   "encoder_size": 64, "shared_encoder": True}
        if recurrent:
            network["recurrent_size"] = 256
        return algorithm, network

    def terms(self, slots: int, evaluation_counts: list[int], limit_steps: int
              ) -> tuple[Any, Any, Any]:
        """The observation, reward and ender terms."""
        c, row, refuse = self.c, self.row, self.refuse
        # Terms.
        if c["run_type"] not in RUN_TYPES:
            refuse("run_type", f"expected one of {', '.join(RUN_TYPES)}")
        most = max([slots, *evaluation_counts])
        observations, rewards = _observations(c, most), _rewards(c, limit_steps)
        enders = _enders(c, self.where)
        row("run_type", {"SACADRL": "no zone terms (as config_run; sgjax's cadrl preset adds the "
                                    "paper's CADRL proximity term, this conversion does not)",
                         "AO": "zone_order reward, any order, and the 7 zone observations",
                         "EO": "zone_order reward, enforced order, and the 7 zone observations"}[
            c["run_type"]])
        for key in ("collision_obs", "agent_goal_distance_obs", "agent_pose_obs",
                    "agent_velocity_obs", "other_poses_obs", "agent_pose_ignore_theta",
                    "agent_velocity_ignore_theta", "other_poses_ignore_theta", "socialnavAPI",
                    "partially_observable"):
            row(key, "env.observations (below)")
        row("other_velocities_obs", f"env.observations: others' velocity relative to the robot, "
            f"for the {max(1, most - 1)} others the most robots ({most}) can have")
        row("other_velocities_ignore_theta", "no effect: an other's velocity is its 2-vector in "
            "sgjax (no separate turn rate)")
        row("collision_penalty", "env.rewards.collision, paid on every step in contact as "
            "SocialGym's Collisions term")
        row("collision_penalty_scale_duration", "a linear weight schedule over duration x the time "
            f"limit / {NUM_ENVS} steps of each environment (SocialGym's ramp was hyperbolic, in "
            "episodes)" if c["collision_penalty_scale_duration"] else "0: a constant weight")
        for key in ("existence_penalty", "success_reward", "starting_collision_penalty",
                    "goal_distance_reward", "goal_distance_reward_clip", "enforced_order_reward",
                    "enforced_order_penalty_for_incorrect_order",
                    "enforced_order_weak_signal_out_of_zone",
                    "penalty_for_multiple_agents_entering"):
            row(key, "env.rewards (below)")
        for key in ("entropy_ender", "entropy_max_distance", "entropy_max_timesteps",
                    "entropy_reward", "entropy_constant_penalty",
                    "entropy_constant_penalty_only_those_that_did_not_finish", "collision_ender"):
            row(key, "env.enders (below)")
        unused = ("unused (a constant penalty is set)" if c["entropy_reward"]
                  else "unused (entropy_reward off)")
        row("entropy_reward_multiplier", unused)
        row("entropy_multiply_negative_rewards_only", unused)
        row("reward_stripper", "always: a finished robot's reward is 0")
        row("enforced_order_track_exit", "nothing (SocialGym ignored it too)")
        row("other_poses_actual_positions", "nothing (SocialGym accepted but never used it)")
        return observations, rewards, enders

    def evaluation(self, total: int, evaluation_counts: list[int]) -> tuple[dict, str]:
        """The evaluation section and the run name; refuses what the train command cannot
        honour."""
        c, row, refuse = self.c, self.row, self.refuse
        # Evaluation, logging, the rest.
        if not c["train"]:
            refuse("train", "python -m train trains; evaluate a saved policy with sgjax evaluate")
        if not c["eval"]:
            refuse("eval", "the train command always ends with an evaluation")
        if c["debug"]:
            refuse("debug", "the always-GO debug run is the only_local baseline: sgjax evaluate "
                   "--policy only_local")
        if c["continue_from"]:
            refuse("continue_from", "an SB3 checkpoint cannot be resumed; python -m train "
                   "--resume continues an sgjax run")
        every = int(c["eval_frequency"]) or total
        episodes = int(c["ending_eval_trials"])
        judged = "best" if c["ending_eval_with_best"] else "final"
        evaluation = {"every": every, "episodes": episodes, "num_agents": list(evaluation_counts),
                      "baseline": "only_local", "deterministic": True, "checkpoint": judged}
        row("eval_frequency", f"evaluation.every {every} environment steps"
            + (" (0: only at the end)" if not c["eval_frequency"] else ""))
        row("intermediate_eval_trials", f"periodic evaluations use evaluation.episodes {episodes} "
            "too" if c["eval_frequency"] else "unused (no periodic evaluation)")
        row("ending_eval_trials", f"evaluation.episodes {episodes} (greedy actions, as SB3's "
            "evaluate_policy; beside the only_local baseline)")
        row("ending_eval_with_best", f"evaluation.checkpoint {judged} (the final evaluation "
            + ("judges the best periodic evaluation's weights)" if judged == "best"
               else "judges the weights training ended with)"))
        for key in ("train", "eval", "debug", "continue_from"):
            row(key, "as SocialGym: train, then evaluate")
        run = c["run_name"] or "socialgym"
        row("run_name", f"logging.out runs/{run}")
        row("device", "nothing: JAX uses its default device (GPU when installed)")
        row("monitor", "nothing (no ROS, no RViz); the run ends with a GIF")
        row("local", "nothing (no ROS)")
        return evaluation, run


def convert(data: Mapping[str, Any], source: str = "config") -> tuple[dict[str, Any],
                                                                      list[tuple[str, str, str]]]:
    """``(train config dict, rows)``: the sgjax train config for a SocialGym experiment config
    and one ``(key, value, what it became)`` row per SocialGym key (defaults included)."""
    conversion = _Conversion(data, source)
    scenarios, limit_steps, curriculum, evaluation_counts, total = conversion.world()
    slots = max(n for _, n in curriculum)
    algorithm, network = conversion.algorithm(total, slots)
    observations, rewards, enders = conversion.terms(slots, evaluation_counts, limit_steps)
    evaluation, run = conversion.evaluation(total, evaluation_counts)
    config = {
        "env": {"scenarios": scenarios, "curriculum": curriculum, "dt": SOCIALGYM_DT,
                "time_limit": limit_steps * SOCIALGYM_DT, "robots": "socialgym",
                "action_mode": "go_stop", "arrived": "settle", "observations": observations,
                "rewards": rewards, "enders": enders},
        "algorithm": algorithm, "network": network, "evaluation": evaluation,
        "logging": {"out": f"runs/{run}"},
    }
    config_from_dict(config, f"{source} (converted)")  # the result must validate
    order = {key: i for i, key in enumerate(DEFAULTS)}
    rows = conversion.rows
    rows.sort(key=lambda r: order[r[0]])
    return config, rows


def table(rows: list[tuple[str, str, str]]) -> str:
    """The rows as a markdown table."""
    lines = ["| SocialGym key | value | sgjax |", "|---|---|---|"]
    lines += [f"| `{key}` | `{value}` | {became} |" for key, value, became in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m train.run.socialgym_config",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("config", help="a SocialGym 2.0 experiment config (JSON)")
    parser.add_argument("--out", default=None, help="write the sgjax train config here (YAML)")
    args = parser.parse_args(argv)
    try:
        config, rows = convert(read_socialgym_config(args.config), args.config)
    except ConfigError as err:
        raise SystemExit(f"train.run.socialgym_config: {err}") from err
    print(table(rows))
    text = yaml.safe_dump(config, sort_keys=False)
    if args.out:
        Path(args.out).write_text(f"# converted from {args.config} by "
                                  f"python -m train.run.socialgym_config\n{text}")
        print(f"\nwrote {args.out}")
    else:
        print(f"\n{text}")


if __name__ == "__main__":
    main()
