"""The ``sgjax`` command: ``sgjax evaluate ...``, ``sgjax render ...``, ``sgjax maps show ...``,
``sgjax maps check ...``, ``sgjax maps generate ...``, ``sgjax crowd fit ...``, ``sgjax crowd
loso ...`` and ``sgjax edit ...``.

Examples::

    sgjax evaluate --scenario doorway --policy only_local --num-agents 3 4 --episodes 8 \\
        --out runs/eval
    sgjax render --scenario doorway --policy only_local --out episode.gif
    sgjax maps show doorway --out doorway.png
    sgjax maps show path/to/SocialGym2/door --socialgym-scenario envs_door
    sgjax maps check mygame.json other.json
    sgjax crowd fit --model moussaid --data ../shared/pedestrians/eth_ucy --test ZARA1 \\
        --out runs/crowd_fit
    sgjax edit --new mygame
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import jax

from sgjax.compilation_cache import add_cache_arguments, cache_from_arguments
from sgjax.environment.options import MakeOptions
from sgjax.environment.registry import registered
from sgjax.evaluation.calibration import FITTED_BY_MODEL
from sgjax.evaluation.evaluate import evaluate, policy_environment, run_episodes
from sgjax.evaluation.policies import BASELINES, load_policy, policy_options
from sgjax.evaluation.protocols import PAPER, PROTOCOLS, load_protocol
from sgjax.humans.calibrated import CONSTANT_SETS
from sgjax.humans.pedestrians import FORCE_MODELS
from sgjax.humans.replay import REPLAY_MODES
from sgjax.maps.generated.families import FAMILIES
from sgjax.maps.io import load as load_map
from sgjax.types import ACTION_MODES, ARRIVED_SEMANTICS
from sgjax.version import __version__


def _add_environment_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--num-humans", type=int, default=None,
                        help="pedestrians per episode (default: the scenario's)")
    parser.add_argument("--human-range", type=float, default=None,
                        help="m: bodies farther than this do not act on a pedestrian (on a "
                        "building floor its walls and neighbours then come from cell lists; "
                        "default: every body acts)")
    parser.add_argument("--human-model", default=None, choices=FORCE_MODELS,
                        help="the pedestrians' force model (default: the policy's, else "
                        "moussaid); with --human-replay handover, the handed-over people's")
    parser.add_argument("--human-constants", default=None, choices=CONSTANT_SETS,
                        help="the pedestrian law's constants: published (the default) or a "
                        "preset fitted to recorded people (eth_ucy; docs/humans.md)")
    parser.add_argument("--human-replay", default=None, choices=(*REPLAY_MODES, "off"),
                        help="recorded:FILE scenarios: replayed people as ghosts, pausing "
                        "when a robot touches them, or handed over to the force model when "
                        "a robot comes near (default ghost), or off: --num-humans simulated "
                        "pedestrians in the recording's space (docs/humans.md)")
    parser.add_argument("--time-limit", type=float, default=None,
                        help="seconds before truncation (default 75)")
    parser.add_argument("--action-mode", default=None, choices=ACTION_MODES)
    parser.add_argument("--arrived", default=None, choices=ARRIVED_SEMANTICS,
                        help="what an arrived robot does: drive on to its goal point and park "
                        "(settle), park where it arrived, or leave the world (default: the "
                        "checkpoint's, else settle)")
    parser.add_argument("--observation-preset", default=None,
                        help="observation preset the policy expects (docs/terms.md)")
    parser.add_argument("--world-range", dest="world_ranges", action="append", default=None,
                        metavar="NAME=LOW,HIGH", type=_world_range,
                        help="generated scenarios: a parameter's range (or NAME=VALUE), "
                             "repeatable (docs/generated.md)")
    parser.add_argument("--world-seeds", type=int, nargs=2, default=None,
                        metavar=("FIRST", "COUNT"),
                        help="generated scenarios: play only the worlds of this seed split")
    add_cache_arguments(parser)


def _world_range(text: str) -> tuple[str, float, float]:
    """``NAME=LOW,HIGH`` or ``NAME=VALUE`` -> a ``(name, low, high)`` row."""
    name, _, values = text.partition("=")
    try:
        pair = [float(v) for v in values.split(",")]
    except ValueError:
        pair = []
    if not name or len(pair) not in (1, 2):
        raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=LOW,HIGH or NAME=VALUE")
    return (name, pair[0], pair[-1])


def _add_action_choice(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_mutually_exclusive_group()
    actions.add_argument("--greedy", dest="deterministic", action="store_const", const=True,
                         default=None, help="trained checkpoints take their most likely action "
                         "every step (default: as their run's evaluation.deterministic says)")
    actions.add_argument("--sampled", dest="deterministic", action="store_const", const=False,
                         help="trained checkpoints sample their actions")


RENDER_FORMATS = ("gif", "mp4", "mcap", "rosbag2")
ENVIRONMENT_FLAGS = ("num_humans", "human_range", "human_model", "human_constants",
                     "human_replay", "time_limit",
                     "action_mode", "arrived", "observation_preset", "world_ranges",
                     "world_seeds")


def _options(args: argparse.Namespace, policy: Any) -> MakeOptions:
    """The options ``policy`` acts in (``policy_options``: a checkpoint's from training), with
    the environment flags given on the command line on top."""
    flags = {name: getattr(args, name) for name in ENVIRONMENT_FLAGS
             if getattr(args, name) is not None}
    return policy_options(policy).replace(where=f"sgjax {args.command}", **flags)


def _policy_help() -> str:
    return (f"a baseline ({', '.join(BASELINES)}), 'package.module:function' naming a "
            "jittable function (obs [R, D], key) -> actions, or a trainer checkpoint (a "
            ".msgpack file or a run folder; built with the settings it was trained with)")


PROTOCOL_FIXED = {"scenario": "scenarios", "num_agents": "num_agents", "episodes": "episodes",
                  "seed": "seed", "counterfactual": "counterfactual", "time_limit": "time_limit",
                  "num_humans": "num_humans", "human_range": "human_range"}
PROTOCOL_OPTIONAL = ("num_humans", "human_range")  # fixed only where a protocol names them
# Without --protocol: the paper's scenarios, robot counts, episodes and seed, without the
# counterfactual lanes.
EVALUATE_DEFAULTS = {"scenario": list(PAPER.scenarios), "num_agents": list(PAPER.num_agents),
                     "episodes": PAPER.episodes, "seed": PAPER.seed, "counterfactual": False}


def _apply_protocol(args: argparse.Namespace) -> None:
    """Fill in what ``--protocol`` fixes (an error if the command line sets it too), else the
    defaults."""
    if args.protocol is None:
        for name, value in EVALUATE_DEFAULTS.items():
            if getattr(args, name) is None:
                setattr(args, name, value)
        return
    protocol = load_protocol(args.protocol)
    # the crowd is fixed only by a protocol that names one; the rest always
    fixed = [name for name in PROTOCOL_FIXED
             if name not in PROTOCOL_OPTIONAL or getattr(protocol, PROTOCOL_FIXED[name])
             is not None]
    clash = [f"--{name.replace('_', '-')}" for name in fixed
             if getattr(args, name) not in (None, False)]
    if clash:
        raise ValueError(f"--protocol {protocol.name} fixes {', '.join(clash)}; leave "
                         f"{'it' if len(clash) == 1 else 'them'} out (or write a protocol file)")
    for name in fixed:
        value = getattr(protocol, PROTOCOL_FIXED[name])
        setattr(args, name, list(value) if isinstance(value, tuple) else value)


def run_evaluate(args: argparse.Namespace) -> None:
    _apply_protocol(args)
    print(f"sgjax {__version__}, jax {jax.__version__} on {jax.devices()[0].platform}: "
          f"{len(args.scenario)} scenario(s) x {len(args.policy)} policy(ies) x robot counts "
          f"{args.num_agents} x {args.episodes} episodes, seed {args.seed}"
          + (f", protocol {args.protocol}" if args.protocol else "")
          + (", counterfactual lanes on" if args.counterfactual else ""))
    evaluate(args.scenario, args.policy, num_agents=args.num_agents, episodes=args.episodes,
             seed=args.seed, out=args.out,
             options=[_options(args, policy) for policy in args.policy],
             counterfactual=args.counterfactual, deterministic=args.deterministic,
             record=args.record_mcap)
    print(f"table: {Path(args.out) / 'table.md'}")


def run_render(args: argparse.Namespace) -> None:
    from sgjax.evaluation.render import (
        episode_frames,
        plot_trajectories,
        recorded_map,
        save_animation,
        save_png,
    )

    out = Path(args.out)
    kind = args.format or out.suffix.lower().lstrip(".")
    if kind not in RENDER_FORMATS:
        raise SystemExit(f"sgjax render: --out {args.out!r} must end in .gif, .mp4 or .mcap "
                         "(or give --format, rosbag2 for a ROS 2 bag folder)")
    # exactly --num-agents robots in the settings the policy needs, as sgjax evaluate plays
    env, by_count = policy_environment(args.scenario, [args.num_agents], args.policy,
                                       _options(args, args.policy))
    params = by_count[args.num_agents]
    policy = load_policy(args.policy, env, args.deterministic)
    batch = run_episodes(env, params, policy, jax.random.key(args.seed), 1, record=True)
    states = jax.tree.map(lambda leaf: leaf[:, 0], batch.states)
    length = int(batch.values["episode_length"][0])
    spec = recorded_map(args.scenario, states)
    if args.live:
        from sgjax.evaluation.episode_log import serve_episode

        served = serve_episode(spec, states, params, env.config.layout, length, host=args.host,
                               port=args.port, speed=args.speed, wait_for_client=600.0,
                               rewards=batch.rewards[:, 0],
                               started=lambda port: print(
                                   f"serving {spec.name} to Foxglove at ws://{args.host}:{port} "
                                   "(open connection, Foxglove WebSocket); it plays once a "
                                   "client subscribes", flush=True))
        print(f"served {served} steps")
        return
    if kind in ("mcap", "rosbag2"):
        from sgjax.evaluation.episode_bag import write_rosbag2
        from sgjax.evaluation.episode_log import write_mcap

        metrics = {name: float(values[0]) for name, values in batch.values.items()}
        rewards = batch.rewards[:, 0]  # [T, R]
        if kind == "mcap":
            write_mcap(out, spec, states, params, env.config.layout, length, rewards=rewards,
                       metrics=metrics)
        else:
            write_rosbag2(out, spec, states, params, env.config.layout, length,
                          rewards=rewards)
        print(f"{spec.name}, {args.num_agents} robots, policy {args.policy}: {length} steps "
              f"({length * float(params.dt):.1f} s); wrote {out} ("
              + ("open it in Foxglove)" if kind == "mcap" else "ros2 bag play it)"))
        return
    title = f"{spec.name} / {args.policy}"
    frames, stride = episode_frames(spec, states, params, length, title=title,
                                    width_px=args.width, max_frames=args.max_frames)
    fps = max(1, round(1.0 / (float(params.dt) * stride)))
    save_animation(frames, out, fps=fps)
    trajectory = Path(args.trajectory) if args.trajectory else out.with_suffix(".png")
    save_png(plot_trajectories(spec, states, params, length, title=title,
                               width_px=args.width), trajectory)
    arrived = int(batch.robot["success"][0].sum())
    print(f"{spec.name}, {args.num_agents} robots, policy {args.policy}: {arrived} of "
          f"{args.num_agents} arrived in {length} steps ({length * float(params.dt):.1f} s)")
    print(f"wrote {out} ({len(frames)} frames at {fps} fps) and {trajectory}")


def _map_summary(spec: Any, robots: str) -> list[str]:
    """Lines describing a map: its parts, groups, zones and how many robots fit."""
    import numpy as np

    from sgjax.environment.registry import robots_that_fit
    from sgjax.maps.arrays import spawn_groups
    from sgjax.maps.routing import connected_components

    parts = connected_components(spec.num_nodes, spec.edges)
    sizes = sorted(np.bincount(parts)[np.unique(parts)].tolist(), reverse=True)
    groups = spawn_groups(spec)
    xmin, ymin, xmax, ymax = spec.bounds
    lines = [
        f"{spec.name}: {spec.description}",
        f"  source      {spec.source}",
        f"  bounds      x {xmin:.2f} .. {xmax:.2f} m, y {ymin:.2f} .. {ymax:.2f} m",
        f"  walls       {len(spec.walls)}",
        f"  graph       {spec.num_nodes} nodes, {len(spec.edges)} edges, {len(sizes)} connected "
        f"part(s) of {', '.join(str(s) for s in sizes[:8])}{' ...' if len(sizes) > 8 else ''} "
        "nodes",
        f"  placement   {len(spec.groups)} group(s) and {len(spec.routes)} route(s) -> "
        f"{len(groups)} spawn group(s): " + "; ".join(
            f"{len(starts)} starts x {len(goals)} goals" for starts, goals in groups[:6])
        + (" ..." if len(groups) > 6 else ""),
    ]
    for zone in spec.zones:
        x0, y0, x1, y1 = zone.rect
        lines.append(f"  zone        {zone.name}: x {x0:.2f} .. {x1:.2f} m, y {y0:.2f} .. "
                     f"{y1:.2f} m")
    lines.append(f"  robots fit  {robots_that_fit(spec, robots)} {robots} robots in every "
                 "draw (distinct starts and goals, bodies apart)")
    return lines


def run_maps_show(args: argparse.Namespace) -> None:
    from sgjax.dynamics.limits import resolve_robots
    from sgjax.maps.socialgym import import_socialgym

    target = Path(args.map)
    if target.is_dir():
        reports: list = []
        radius = max(preset.radius for _, preset in resolve_robots(args.robots, 1))
        spec = import_socialgym(target, scenario=args.socialgym_scenario, clearance=radius,
                                report=reports.append)
        for report in reports:
            print(report)
    else:
        if args.socialgym_scenario:
            raise ValueError("--socialgym-scenario needs a SocialGym map folder, got "
                             f"{args.map!r}")
        spec = load_map(args.map)
    print("\n".join(_map_summary(spec, args.robots)))
    if args.out:
        from sgjax.evaluation.render import draw_scenario, save_png

        print(f"wrote {save_png(draw_scenario(spec, width_px=args.width), Path(args.out))}")


def run_maps_check(args: argparse.Namespace) -> None:
    from sgjax.maps.check import check_file

    errors = warnings = 0
    for name in args.files:
        problems = check_file(name, clearance=args.clearance)
        for problem in problems:
            print(problem)
        found = sum(p.severity == "error" for p in problems)
        errors, warnings = errors + found, warnings + len(problems) - found
        if not problems:
            print(f"{name}: ok")
    print(f"{len(args.files)} file(s): {errors} error(s), {warnings} warning(s)")
    if errors:
        raise SystemExit(1)


def run_generalise(args: argparse.Namespace) -> None:
    import json

    from sgjax.evaluation import generalisation
    from sgjax.evaluation.provenance import provenance
    from sgjax.files import write_atomic

    print(f"sgjax {__version__}, jax {jax.__version__} on {jax.devices()[0].platform}: "
          f"{len(args.policy)} policy(ies) x {len(args.family)} family(ies) x "
          f"{args.worlds} worlds per split x 2 rollouts, {args.num_agents} robots")
    result = generalisation.report(args.policy, args.family, args.num_agents, args.worlds,
                                   args.alpha, args.seed, lambda p: _options(args, p),
                                   chunk=args.chunk)
    result["provenance"] = provenance(seeds={"evaluation": [args.seed]},
                                      episodes_per_cell=2 * args.worlds)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "generalisation.json", json.dumps(result, indent=1) + "\n")
    table = generalisation.table_markdown(result)
    write_atomic(out / "generalisation.md", table)
    print(table)
    print(f"wrote {out / 'generalisation.json'}, {out / 'generalisation.md'}")


def _add_generalise_command(commands: Any) -> None:
    gen = commands.add_parser(
        "generalise", help="a policy on worlds it never saw: train and held-out splits of "
        "generated families, the worst alpha%% and the gap",
        description="Plays every world of each split (train: world seeds 0.., test: the "
                    "held-out seeds) twice, with two rollout seeds; reports team success, "
                    "collisions and makespan per family and split, the worst alpha%% (the "
                    "second rollout's score on the worlds the first scored lowest) and the "
                    "gap (train less test). Writes generalisation.json and generalisation.md.")
    gen.add_argument("--policy", nargs="+", default=["only_local"],
                     help="baselines or trainer checkpoints, as sgjax evaluate takes them")
    gen.add_argument("--family", nargs="+", choices=list(FAMILIES), default=list(FAMILIES))
    gen.add_argument("--num-agents", type=int, default=4)
    gen.add_argument("--worlds", type=int, default=1000, help="worlds per split")
    gen.add_argument("--alpha", type=float, nargs="+", default=[0.1],
                     help="the worst fractions of worlds reported")
    gen.add_argument("--seed", type=int, default=0)
    gen.add_argument("--chunk", type=int, default=1000, help="worlds per compiled call")
    gen.add_argument("--out", default="generalisation")
    _add_environment_options(gen)
    gen.set_defaults(run=run_generalise)


def run_maps_generate(args: argparse.Namespace) -> None:
    import json

    from sgjax.environment.worlds import sample_maps, source_for
    from sgjax.files import write_atomic

    ranges = {name: (low, high) for name, low, high in args.set}
    source = source_for(args.family, ranges, robot_radius=args.clearance)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = 0
    for data, valid in sample_maps(source, args.count, args.seed):
        if not valid:
            print(f"{data['name']}: no valid world in {source.proposals} proposals; not written")
            continue
        path = write_atomic(out / f"{data['name']}.json", json.dumps(data, indent=1) + "\n")
        written += 1
        print(f"wrote {path}")
    print(f"{written} of {args.count} world(s) of family {args.family!r} in {out}")


def run_edit(args: argparse.Namespace) -> None:
    from sgjax.editor.guard import LOOPBACK_HOSTS
    from sgjax.editor.server import serve
    from sgjax.editor.session import EditorError, EditorSession

    if args.host not in LOOPBACK_HOSTS:
        print(f"sgjax edit: warning: serving on {args.host}: anyone who reaches this machine "
              "and has the printed address (its token) can read the map and save inside its "
              "folder")
    try:
        session = EditorSession.open(args.map, new=args.new, root=args.root)
    except EditorError as err:
        raise ValueError(str(err)) from None
    for line in session.import_report:
        print(line)
    serve(session, args.host, args.port, browser=not args.no_browser)


def _add_maps_commands(commands: Any) -> None:
    """``sgjax maps show`` and ``sgjax maps check``."""
    maps = commands.add_parser("maps", help="inspect maps").add_subparsers(
        dest="maps_command", required=True)
    show = maps.add_parser(
        "show", help="what a map offers (walls, graph, groups, zones, robots that fit), drawn",
        description="Describe a shipped map, a map .json file or a SocialGym 2.0 map folder "
                    "(imported as sgjax.maps.import_socialgym does, with its import report)")
    show.add_argument("map", help=f"a shipped id ({', '.join(registered())}), a .json map or "
                                  "a SocialGym 2.0 folder")
    show.add_argument("--socialgym-scenario", default=None,
                      help="for a SocialGym folder: one of its own scenarios (e.g. envs_door) "
                           "whose robot paths and zone to use (default: one group per "
                           "connected part)")
    show.add_argument("--robots", default="socialgym",
                      help="robot preset for the clearance and capacity count")
    show.add_argument("--out", default=None, help="PNG picture of the map")
    show.add_argument("--width", type=int, default=640, help="picture width in pixels")
    add_cache_arguments(show)
    show.set_defaults(run=run_maps_show)
    check = maps.add_parser(
        "check", help="every error and warning of map files, in one pass",
        description="Check map .json files: every error (what loading refuses) and warning "
                    "(what loads but is probably wrong), each with its JSON path; exit status "
                    "1 if any file has an error")
    check.add_argument("files", nargs="+", help="map .json files")
    check.add_argument("--clearance", type=float, default=0.25,
                       help="the largest robot radius every node must keep from walls (m)")
    add_cache_arguments(check)
    check.set_defaults(run=run_maps_check)
    generate = maps.add_parser(
        "generate", help="worlds of a generated family as map files",
        description="Draw worlds of a family (docs/generated.md) and write each as a map .json "
                    "file that sgjax maps check, sgjax evaluate --scenario, the trainer and "
                    "the editor load")
    generate.add_argument("--family", required=True, choices=list(FAMILIES))
    generate.add_argument("--count", type=int, default=8)
    generate.add_argument("--seed", type=int, default=0)
    generate.add_argument("--out", required=True, help="folder for the .json files")
    generate.add_argument("--set", action="append", default=[], metavar="NAME=LOW,HIGH",
                          type=_world_range,
                          help="a parameter's range (or NAME=VALUE), repeatable")
    generate.add_argument("--clearance", type=float, default=0.25,
                          help="the largest robot radius passages and nodes must fit (m)")
    add_cache_arguments(generate)
    generate.set_defaults(run=run_maps_generate)



def _add_crowd_commands(commands: Any) -> None:
    """``sgjax crowd fit`` and ``sgjax crowd loso``."""
    crowd = commands.add_parser(
        "crowd", help="calibrate the pedestrian models to recorded people").add_subparsers(
        dest="crowd_command", required=True)
    fit = crowd.add_parser(
        "fit", help="fit a pedestrian model to recorded scenes, score it on a held-out one",
        description="Fit a model's constants by gradient on the training scenes' tracks (the "
                    "one-row loss, then optionally short rollouts) and forecast the held-out "
                    "scene (observe 8 rows, predict 12: ADE, FDE, predicted collisions) beside "
                    "constant velocity, the published and TrajNet++'s constants; writes "
                    "crowd_fit.json (with provenance) and crowd_fit.md")
    loso = crowd.add_parser(
        "loso", help="leave each of ETH, HOTEL, UNIV, ZARA1, ZARA2 out once",
        description="crowd fit five times, each standard ETH/UCY scene held out once; one "
                    "result file. Each finished scene is kept in the folder "
                    "(crowd_fit.partial.json): the same command continues after them")
    for command in (fit, loso):
        command.add_argument("--model", default="moussaid", choices=list(FITTED_BY_MODEL))
        command.add_argument("--data", required=True, type=Path,
                             help="the folder of track files (frame id x y), e.g. "
                                  "../shared/pedestrians/eth_ucy")
        command.add_argument("--steps", type=int, default=100,
                             help="Adam steps on the one-row loss")
        command.add_argument("--rollout-steps", type=int, default=0,
                             help="then Adam steps on short rollouts (0: none)")
        command.add_argument("--rollout-rows", type=int, default=4,
                             help="rows (0.4 s each) per short rollout")
        command.add_argument("--max-seconds", type=float, default=None,
                             help="stop each phase of a fit after this long (compile "
                                  "included)")
        command.add_argument("--out", required=True, type=Path, help="result folder")
        add_cache_arguments(command)
    fit.add_argument("--test", default=None,
                     help="the held-out scene (ZARA1, a file stem such as crowds_zara01, or a "
                          "file name); without it, fit only")
    fit.add_argument("--train", nargs="+", default=None,
                     help="training scenes (default: the standard five but --test)")
    fit.set_defaults(run=run_crowd_fit)
    loso.set_defaults(run=run_crowd_loso)


def run_crowd_fit(args: argparse.Namespace) -> None:
    from sgjax.evaluation.crowd_fit import fit_scene, write_result

    began = time.perf_counter()
    row = fit_scene(args.model, args.data, args.test, args.train, args.steps, args.max_seconds,
                    args.rollout_steps, args.rollout_rows)
    path = write_result(args.out, [row], {"fit": time.perf_counter() - began})
    print(f"{args.model} fitted on {', '.join(row['train'])} in {row['fit_seconds']} s "
          f"({row['steps']} steps): " + ", ".join(f"{k} {v:.4g}"
                                                  for k, v in row["constants"].items()))
    print(f"wrote {path}")
    if row["test"] is not None:
        print((args.out / "crowd_fit.md").read_text())


def run_crowd_loso(args: argparse.Namespace) -> None:
    from sgjax.evaluation.crowd_fit import PARTIAL, loso, write_result

    began = time.perf_counter()
    rows = loso(args.model, args.data, args.steps, args.max_seconds,
                log=lambda line: print(line, flush=True), rollout_steps=args.rollout_steps,
                rollout_rows=args.rollout_rows, out=args.out)
    path = write_result(args.out, rows, {"loso": time.perf_counter() - began})
    (args.out / PARTIAL).unlink(missing_ok=True)
    print(f"wrote {path}\n" + (args.out / "crowd_fit.md").read_text())


def _add_edit_command(commands: Any) -> None:
    """``sgjax edit``."""
    edit = commands.add_parser(
        "edit", help="draw and edit a map in the browser, check it, play it, save it",
        description="Start the map editor (a local web page; docs/editor.md)")
    edit.add_argument("map", nargs="?", default=None,
                      help="a map .json file or a SocialGym 2.0 map folder to open")
    edit.add_argument("--new", default=None, metavar="NAME",
                      help="start an empty map saved as NAME.json")
    edit.add_argument("--root", default=None,
                      help="the folder saves may go to (default: the map's folder, or the "
                           "current folder with --new)")
    edit.add_argument("--host", default="127.0.0.1",
                      help="address to serve on (default 127.0.0.1: this machine only)")
    edit.add_argument("--port", type=int, default=8765,
                      help="port (the next free one if taken; default 8765)")
    edit.add_argument("--no-browser", action="store_true", help="do not open a browser")
    add_cache_arguments(edit)
    edit.set_defaults(run=run_edit)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="sgjax", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)

    ev = commands.add_parser("evaluate", help="metrics of policies x scenarios x robot counts",
                             description="Evaluate policies; writes metrics.json, metrics.csv, "
                                         "table.md and PNG charts")
    ev.add_argument("--scenario", nargs="+", default=None,
                    help=f"scenario ids, map files or recorded:TRACK_FILE (default: the five "
                         f"mini-games); shipped: {', '.join(registered())}")
    ev.add_argument("--policy", nargs="+", default=["only_local"], help=_policy_help())
    ev.add_argument("--num-agents", nargs="+", type=int, default=None,
                    help=f"robot counts (default: {' '.join(map(str, PAPER.num_agents))})")
    ev.add_argument("--episodes", type=int, default=None,
                    help=f"episodes per configuration (default {PAPER.episodes})")
    ev.add_argument("--seed", type=int, default=None,
                    help=f"evaluation seed (default {PAPER.seed})")
    ev.add_argument("--counterfactual", action="store_true",
                    help="also play each episode with each robot alone and without each robot "
                         "(1 + 2R times the work) for path deviation, Hausdorff distance, "
                         "makespan ratio and invasiveness")
    ev.add_argument("--protocol", default=None,
                    help=f"a built-in protocol ({', '.join(PROTOCOLS)}) or a protocol YAML "
                         "file fixing scenarios, robot counts, episodes, seed, time limit and "
                         "counterfactual lanes (sgjax.evaluation.protocols)")
    _add_action_choice(ev)
    ev.add_argument("--record-mcap", default=None, metavar="DIR",
                    help="also write each configuration's first episode as an MCAP file for "
                         "Foxglove into DIR (docs/interop.md)")
    ev.add_argument("--out", default="runs/eval",
                    help="output folder (its files written atomically when the evaluation "
                         "ends; a killed evaluation does not resume: run it again)")
    _add_environment_options(ev)
    ev.set_defaults(run=run_evaluate)

    rd = commands.add_parser("render", help="animate one episode (GIF or MP4) and plot its "
                                            "trajectories")
    rd.add_argument("--scenario", default="doorway")
    rd.add_argument("--policy", default="only_local", help=_policy_help())
    rd.add_argument("--num-agents", type=int, default=4)
    rd.add_argument("--seed", type=int, default=0)
    rd.add_argument("--out", default="episode.gif",
                    help=".gif (pillow), .mp4 (ffmpeg), .mcap (Foxglove's schemas) or, "
                         "with --format rosbag2, a ROS 2 bag folder (docs/interop.md)")
    rd.add_argument("--format", default=None, choices=RENDER_FORMATS,
                    help="what to write (default: --out's suffix)")
    rd.add_argument("--live", action="store_true",
                    help="serve the episode to Foxglove over its WebSocket protocol instead "
                         "of writing a file (docs/interop.md)")
    rd.add_argument("--host", default="127.0.0.1",
                    help="--live: the address to serve on (default loopback: this machine)")
    rd.add_argument("--port", type=int, default=8765, help="--live: the port")
    rd.add_argument("--speed", type=float, default=1.0,
                    help="--live: times the simulation clock")
    rd.add_argument("--trajectory", default=None,
                    help="trajectory plot PNG (default: --out with .png)")
    rd.add_argument("--width", type=int, default=480, help="frame width in pixels")
    rd.add_argument("--max-frames", type=int, default=300)
    _add_action_choice(rd)
    _add_environment_options(rd)
    rd.set_defaults(run=run_render)

    _add_maps_commands(commands)
    _add_generalise_command(commands)
    _add_crowd_commands(commands)
    _add_edit_command(commands)
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        cache_from_arguments(args)
        args.run(args)
    except (ValueError, KeyError, TypeError, RuntimeError, FileNotFoundError) as err:
        raise SystemExit(f"sgjax {args.command}: {err}") from err


if __name__ == "__main__":
    main()
