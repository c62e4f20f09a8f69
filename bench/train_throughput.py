"""Training throughput: environment plus learning, in agent-steps per second.

Times whole PPO updates (rollout with auto-reset, GAE, epochs of minibatches) of
``train.algorithm.trainer.Trainer`` on the doorway for several batch sizes, robot counts and
numbers of seeds, and prints agent-steps/s, env-steps/s (over all seeds), compile time, peak memory
(XLA's memory analysis of the compiled chunk of updates) and, for several seeds, the cost of
one seed lane against a run of one seed (``lane cost`` 1.00x: lanes of one call are as cheap
per seed as separate runs; 2.00x: each lane costs twice a separate run), for each
``algorithm.lanes`` mode asked for (batched: one ``vmap``; sequential: batched rollouts, the
learning phases one lane after another).

    python bench/train_throughput.py --num-envs 64 256 1024 --robots 4 10
    python bench/train_throughput.py --num-envs 256 --robots 4 --seeds 1 3 6
    python bench/train_throughput.py --num-envs 256 --robots 4 --seeds 1 3 \\
        --lanes batched sequential
    python bench/train_throughput.py --num-envs 256 --robots 5 --compact off on

``--scenario`` takes several (a fixed map beside generated worlds, at the same shapes) and
``--levels`` the curricula over generated worlds to time on the generated ones (``dr``: a
fresh world every episode; ``plr``, ``accel``, ``learnability``: the trainer picks the worlds
from a level buffer)::

    python bench/train_throughput.py --num-envs 256 --robots 5 \
        --scenario doorway generated:doorway --levels dr accel

``--compact`` times the learning phase with ``algorithm.compact`` off (every robot slot
computed, the inactive ones masked) and on (only the transitions that can learn), back to
back.
"""

from __future__ import annotations

import argparse
import itertools
import time

import jax
from compiled import compile_measured

from sgjax.evaluation.provenance import cpu_model
from sgjax.maps.generated.families import PREFIX as GENERATED
from train.algorithm.config import CURRICULA, LANE_MODES, NETWORK_KINDS, config_from_dict
from train.algorithm.trainer import Trainer, seed_keys


def time_updates(config: dict, seeds: int, updates: int) -> tuple[float, float, float]:
    """Seconds per ``updates`` updates of ``seeds`` lanes (best of two), compile s, peak MB."""
    config = dict(config, seed=0, num_seeds=seeds)
    trainer = Trainer(config_from_dict(config))
    runner = jax.jit(jax.vmap(trainer.init))(seed_keys(trainer.config))
    chunk = trainer.jitted_chunk_lanes(updates)
    compiled, compile_s, peak_bytes = compile_measured(chunk.lower(runner))
    runner, _ = compiled(runner)  # warm
    jax.block_until_ready(runner.params)
    best = float("inf")
    for _ in range(2):
        t0 = time.perf_counter()
        runner, _ = compiled(runner)
        jax.block_until_ready(runner.params)
        best = min(best, time.perf_counter() - t0)
    return best, compile_s, peak_bytes / 2**20


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", nargs="+", default=["doorway"])
    parser.add_argument("--levels", nargs="+", default=["dr"], choices=list(CURRICULA),
                        help="curricula timed on the generated scenarios")
    parser.add_argument("--num-envs", nargs="+", type=int, default=[64, 256, 1024])
    parser.add_argument("--robots", nargs="+", type=int, default=[4, 10])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1],
                        help="numbers of seeds trained as lanes of one call")
    parser.add_argument("--updates", type=int, default=4, help="updates per timed call")
    parser.add_argument("--network", nargs="+", default=["mlp"], choices=list(NETWORK_KINDS),
                        help="network.kind (lstm: LSTM-PPO, the reproduce benchmark's CADRL(L))")
    parser.add_argument("--recurrent-size", type=int, default=128,
                        help="network.recurrent_size of gru and lstm (256: CADRL(L))")
    parser.add_argument("--others", default="none", choices=["none", "attention", "lstm"],
                        help="others encoder (lstm: an LSTM over the others, SocialGym's)")
    parser.add_argument("--compact", nargs="+", default=["off"], choices=["off", "on"],
                        help="algorithm.compact: compute only the transitions that can learn")
    parser.add_argument("--lanes", nargs="+", default=["auto"],
                        choices=list(LANE_MODES),
                        help="algorithm.lanes: how the seed lanes run the learning phase")
    args = parser.parse_args()
    print(f"jax {jax.__version__} on {jax.devices()[0].platform} ({cpu_model()}), IPPO "
          f"others encoder {args.others}, recurrent size {args.recurrent_size}, 64 steps x 4 "
          "epochs x 4 minibatches per update")
    print(f"{'scenario':>20}{'levels':>13}{'network':>8}{'compact':>8}{'lanes':>11}{'robots':>7}{'envs':>7}"
          f"{'seeds':>6}{'agent-steps/s':>15}{'env-steps/s':>13}{'compile s':>11}"
          f"{'peak MB':>9}{'lane cost':>11}")
    runs = [(scenario, method) for scenario in args.scenario
            for method in (args.levels if scenario.startswith(GENERATED) else ["-"])]
    for (scenario, method), network, robots, envs, lanes, compact in itertools.product(
            runs, args.network, args.robots, args.num_envs, args.lanes, args.compact):
        one_seed = None
        for seeds in args.seeds:
            config = {
                "env": {"scenarios": [scenario], "curriculum": [[0, robots]]},
                "algorithm": {"num_envs": envs, "num_steps": 64, "total_steps": 10**8,
                              "lanes": lanes, "compact": compact == "on"},
                "network": {"kind": network, "others_encoder": args.others,
                            "recurrent_size": args.recurrent_size}}
            if method != "-":
                config["levels"] = {"method": method}
            seconds, compile_s, peak = time_updates(config, seeds, args.updates)
            if seeds == 1:
                one_seed = seconds
            lane = ("" if one_seed is None or seeds == 1
                    else f"{seconds / (seeds * one_seed):.2f}x")
            env_rate = seeds * args.updates * 64 * envs / seconds
            print(f"{scenario:>20}{method:>13}{network:>8}{compact:>8}{lanes:>11}{robots:>7}{envs:>7}"
                  f"{seeds:>6}"
                  f"{env_rate * robots:>15,.0f}{env_rate:>13,.0f}{compile_s:>11.1f}"
                  f"{peak:>9.1f}{lane:>11}", flush=True)


if __name__ == "__main__":
    main()
