"""Compile time of the batched rollout for every shipped map, action mode and loop order.

Prints one row per (map, action mode, loop order): the seconds to trace and lower
(``jit(...).lower``) and the seconds XLA takes to compile, for a rollout of ``--steps`` steps
over ``--num-envs`` environments with ``--robots`` robots (random actions drawn inside the
loop). Loop orders:

- ``scan(vmap)``: ``jit(scan(vmap(step)))``, one loop whose body steps every environment (what
  ``bench/throughput.py``, the evaluator and the trainer's rollout use);
- ``vmap(scan)``: ``jit(vmap(scan(step)))``, one loop per environment, batched afterwards.

The persistent compilation cache is off (every compile is measured afresh); each row compiles
a new program. Run it on a GPU when one is available (the issue's target: every row under 60 s
on a GPU, under 30 s on the CPU).

``--passes N`` also prints, under each row, where XLA spent that compile: the ``N`` longest
of XLA's own trace events (HLO pass pipelines and passes, summed over their runs; the backend;
LLVM code generation), read from a ``jax.profiler`` trace of the compile with XLA:CPU's trace
events on (``--xla_cpu_enable_xprof_traceme=true``, added to ``XLA_FLAGS`` before JAX starts
its backends). Nested events overlap (a pipeline holds its passes), so they do not add up to
the compile. The trace is read with ``jax._src.lib._profile_data``, a private module of
jaxlib: the option says so and stops where a jaxlib lacks it.

    python bench/compile_time.py
    python bench/compile_time.py --maps doorway office --modes go_stop --orders "scan(vmap)"
    python bench/compile_time.py --maps open --modes go_stop --orders "scan(vmap)" --passes 12
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import jax
from compiled import compile_measured

import sgjax
from sgjax.compilation_cache import disable_compilation_cache
from sgjax.evaluation.policies import random_policy

ORDERS = ("scan(vmap)", "vmap(scan)")
MODES = ("go_stop", "continuous")


def rollout(env, params, order: str, num_envs: int, steps: int) -> Callable:
    """A jitted ``(states [E], key) -> states`` running ``steps`` steps in loop order ``order``."""

    policy = random_policy(env)

    def one_step(key, state):
        k_act, k_step = jax.random.split(key)
        return env.step(k_step, state, policy(None, k_act, state, params), params)[1]

    if order == "scan(vmap)":
        def run(states, key):
            def body(states, k):
                return jax.vmap(one_step)(jax.random.split(k, num_envs), states), None

            return jax.lax.scan(body, states, jax.random.split(key, steps))[0]
    else:
        def run(states, key):
            def single(state, k):
                body = lambda s, kk: (one_step(kk, s), None)  # noqa: E731
                return jax.lax.scan(body, state, jax.random.split(k, steps))[0]

            return jax.vmap(single)(states, jax.random.split(key, num_envs))
    return jax.jit(run)


TRACE_EVENTS_FLAG = "--xla_cpu_enable_xprof_traceme=true"


def compile_events(lowered: jax.stages.Lowered) -> tuple[float, Counter[str]]:
    """Compile ``lowered`` under ``jax.profiler``: ``(seconds, {XLA event: seconds summed over
    its runs})``; JAX's own Python events (named ``$file:line function``) are left out."""
    from jax._src.lib import _profile_data  # private: see the module docstring

    with tempfile.TemporaryDirectory(prefix="sgjax-compile-trace-") as folder:
        jax.profiler.start_trace(folder)
        _, seconds, _ = compile_measured(lowered)
        jax.profiler.stop_trace()
        (trace,) = Path(folder).rglob("*.xplane.pb")
        data = _profile_data.ProfileData.from_file(str(trace))
    events: Counter[str] = Counter()
    for plane in data.planes:
        for line in plane.lines:
            for event in line.events:
                if not event.name.startswith("$"):
                    events[event.name] += event.duration_ns / 1e9
    return seconds, events


def measure(scenario: str, mode: str, order: str, robots: int | None, num_envs: int,
            steps: int, passes: int = 0) -> tuple[float, float, int, Counter[str]]:
    """(trace and lower seconds, compile seconds, robot slots, XLA's events when ``passes``)
    of one configuration."""
    counts = {} if robots is None else {"num_agents": robots}
    env, params = sgjax.make(scenario, action_mode=mode, **counts)
    keys = jax.random.split(jax.random.key(0), num_envs)
    _, states = jax.vmap(env.reset, in_axes=(0, None))(keys, params)
    run = rollout(env, params, order, num_envs, steps)
    t0 = time.perf_counter()
    lowered = run.lower(states, jax.random.key(1))
    t1 = time.perf_counter()
    if passes:
        compile_s, events = compile_events(lowered)
        return t1 - t0, compile_s, env.max_agents, events
    _, compile_s, _ = compile_measured(lowered)
    return t1 - t0, compile_s, env.max_agents, Counter()


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python bench/compile_time.py",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", nargs="+", default=list(sgjax.registered()))
    parser.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    parser.add_argument("--orders", nargs="+", default=list(ORDERS), choices=ORDERS)
    parser.add_argument("--robots", type=int, default=None,
                        help="robots per environment (default: each map's default)")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=16)
    parser.add_argument("--passes", type=int, default=0, metavar="N",
                        help="print XLA's N longest compile events under each row (0: none)")
    args = parser.parse_args(argv)
    if args.passes < 0:
        parser.error(f"--passes must be 0 or more, got {args.passes}")
    if args.passes:
        from jax._src import xla_bridge

        try:
            from jax._src.lib import _profile_data  # noqa: F401
        except ImportError:
            parser.error("--passes reads the trace with jax._src.lib._profile_data, which "
                         "this jaxlib lacks")
        if xla_bridge.backends_are_initialized():
            parser.error("--passes: JAX's backends started before XLA_FLAGS could be set")
        os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {TRACE_EVENTS_FLAG}".strip()
    disable_compilation_cache()
    device = jax.devices()[0]
    print(f"jax {jax.__version__} on {device.platform} ({device.device_kind}); "
          f"{args.num_envs} envs x {args.steps} steps")
    print(f"{'map':>14}{'mode':>12}{'order':>12}{'robots':>8}{'lower s':>9}{'compile s':>11}")
    worst = 0.0
    for scenario in args.maps:
        for mode in args.modes:
            for order in args.orders:
                lower_s, compile_s, robots, events = measure(
                    scenario, mode, order, args.robots, args.num_envs, args.steps, args.passes)
                worst = max(worst, lower_s + compile_s)
                print(f"{scenario:>14}{mode:>12}{order:>12}{robots:>8}{lower_s:>9.1f}"
                      f"{compile_s:>11.1f}", flush=True)
                for name, seconds in events.most_common(args.passes):
                    print(f"{'':>14}{seconds:>10.3f} s  {name}")
    print(f"slowest row: {worst:.1f} s (lower + compile)")


if __name__ == "__main__":
    main()
