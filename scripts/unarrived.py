"""Where the robots that did not arrive ended, and whether a parked robot sat by their goal.

    python scripts/unarrived.py --scenario intersection --num-agents 7 \
        --policy runs/intersection only_local

For each policy, plays ``--episodes`` episodes at exactly ``--num-agents`` robots (in the
settings a checkpoint was trained with, as ``sgjax evaluate`` builds them) and reports, over
the robots that were present and did not reach their goal: how many episodes had one, how far
from their goal they ended (m), and how near the nearest parked robot was to that goal (m). A
failure with the robot a metre from a goal that a parked robot occupies is one no GO/STOP
decision along the way can undo at that moment.
"""

from __future__ import annotations

import argparse

import jax
import numpy as np

from sgjax.evaluation.evaluate import policy_environment, run_episodes
from sgjax.evaluation.policies import load_policy

CHUNK = 64  # episodes recorded per batched call (each keeps every step's state)


def unarrived(spec: str, scenario: str, num_agents: int, episodes: int, seed: int
              ) -> tuple[int, np.ndarray, np.ndarray]:
    """Failed episodes, and per unarrived robot ``[N]``: its final distance to its goal and
    the distance from its goal to the nearest parked robot (inf if none), both in m."""
    env, by_count = policy_environment(scenario, [num_agents], spec)
    params = by_count[num_agents]
    policy = load_policy(spec, env)
    failed_teams, ended, blocker = 0, [], []
    for start in range(0, episodes, CHUNK):
        count = min(CHUNK, episodes - start)
        batch = run_episodes(env, params, policy, jax.random.fold_in(jax.random.key(seed), start),
                             count, record=True)
        last = jax.tree.map(lambda leaf: np.asarray(leaf[-1]), batch.states)  # [E, ...]
        goal_x, goal_y = last.route.x[..., -1], last.route.y[..., -1]  # [E, R]
        x, y = last.robots.x, last.robots.y
        failed = last.robots.present & ~last.robots.succeeded
        failed_teams += int(failed.any(axis=1).sum())
        for e, r in zip(*np.nonzero(failed), strict=True):
            ended.append(np.hypot(x[e, r] - goal_x[e, r], y[e, r] - goal_y[e, r]))
            others = ((last.robots.parked[e] | last.robots.settling[e])  # arrived, still there
                      & (np.arange(x.shape[1]) != r))
            gaps = np.hypot(x[e, others] - goal_x[e, r], y[e, others] - goal_y[e, r])
            blocker.append(gaps.min() if gaps.size else np.inf)
    return failed_teams, np.array(ended), np.array(blocker)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenario", default="intersection")
    parser.add_argument("--policy", nargs="+", default=["only_local"],
                        help="baselines or trainer checkpoints (run folders, .msgpack files)")
    parser.add_argument("--num-agents", type=int, default=7)
    parser.add_argument("--episodes", type=int, default=192)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for spec in args.policy:
        teams, ended, blocker = unarrived(spec, args.scenario, args.num_agents, args.episodes,
                                          args.seed)
        if not ended.size:
            print(f"{spec}: every robot arrived in all {args.episodes} episodes")
            continue
        print(f"{spec}: {teams} of {args.episodes} episodes failed, {ended.size} robots did not "
              f"arrive; ended within 1 m of their goal: {np.sum(ended < 1.0)} (median "
              f"{np.median(ended):.2f} m); a parked robot within 0.5 m of their goal: "
              f"{np.sum(blocker < 0.5)}, within 0.8 m: {np.sum(blocker < 0.8)}")


if __name__ == "__main__":
    main()
