"""The runner's loop kernel (``scan_until_done``) on small carries, and the runner object."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax
from sgjax.evaluation.policies import only_local
from sgjax.evaluation.runner import EpisodeRunner
from sgjax.kernels.chunked_scan import scan_until_done


def counting_step(carry, x):
    """Adds ``x`` to the total until it reaches 10 (then frozen); counts every call."""
    total, calls = carry
    return jnp.where(total < 10, total + x, total), calls + 1


def reached(carry):
    return carry[0] >= 10


def test_it_stops_at_the_chunk_after_done():
    carry, ys, steps = scan_until_done(counting_step, (jnp.int32(0), jnp.int32(0)), reached,
                                       max_steps=100, chunk=4, xs=jnp.full(100, 3, jnp.int32),
                                       record=lambda c: c[0])
    total, calls = carry
    # 3, 6, 9, 12 on the 4th step: done after the first chunk of 4.
    assert int(total) == 12 and int(calls) == 4 and int(steps) == 4
    assert ys.shape == (100,) and ys[:4].tolist() == [3, 6, 9, 12]
    assert (np.asarray(ys[4:]) == 12).all()  # the steps not run read the final carry


def test_early_stop_equals_the_full_scan():
    xs = jax.random.randint(jax.random.key(0), (37,), 0, 3)
    for chunk in (1, 5, 8, 37, 64):
        early = scan_until_done(counting_step, (jnp.int32(0), jnp.int32(0)), reached, 37, chunk,
                                xs=xs, record=lambda c: c[0])
        full = scan_until_done(counting_step, (jnp.int32(0), jnp.int32(0)), reached, 37, chunk,
                               xs=xs, record=lambda c: c[0], stop_early=False)
        assert int(early[0][0]) == int(full[0][0]) == 10
        np.testing.assert_array_equal(early[1], full[1])
        assert int(full[2]) == 37 and int(early[2]) <= 37 and int(early[0][1]) == int(early[2])
        assert int(early[2]) % chunk == 0 or int(early[2]) == 37


@pytest.mark.parametrize("chunk", [3, 4, 10, 16])
def test_it_honours_max_steps(chunk):
    """A run that is never done takes exactly ``max_steps`` steps, whatever the chunk (the
    last chunk is cut short); without ``xs`` each step gets its index."""
    (last, calls), ys, steps = scan_until_done(
        lambda c, t: (t, c[1] + 1), (jnp.int32(-1), jnp.int32(0)), lambda c: jnp.bool_(False),
        max_steps=10, chunk=chunk, record=lambda c: c[0])
    assert int(calls) == 10 and int(steps) == 10 and int(last) == 9
    assert ys.tolist() == list(range(10))


def test_it_runs_under_jit_and_vmap():
    """Batched carries (as the trainer's lane evaluator has) stop when every lane is done."""
    def run(start):
        carry, _, steps = scan_until_done(counting_step, (start, jnp.int32(0)), reached, 50, 4,
                                          xs=jnp.ones(50, jnp.int32))
        return carry[0], carry[1], steps

    totals, calls, steps = jax.jit(jax.vmap(run))(jnp.array([0, 8, 10], jnp.int32))
    assert totals.tolist() == [10, 10, 10]
    assert calls.tolist() == [12, 4, 0] and steps.tolist() == [12, 4, 0]


def test_one_runner_serves_every_robot_count():
    """``EpisodeRunner.run`` takes the params as an argument: one compiled run plays 2 and 3
    robots of a 3-slot environment, and the robots not in an episode read NaN."""
    env, params = sgjax.make("open", num_agents=3, time_limit=3.0)
    runner = EpisodeRunner(env, only_local(env), 2, int(params.max_steps))
    compiled, seconds = runner.compile(jax.random.key(0), params)
    assert seconds > 0
    two = runner.play_compiled(compiled, jax.random.key(0),
                               params.replace(num_agents=jnp.asarray(2, jnp.int32)))
    three = runner.play_compiled(compiled, jax.random.key(0), params)
    assert np.isnan(two.robot["path_length"][:, 2]).all()
    assert np.isfinite(three.robot["path_length"]).all()
    assert set(two.values) == set(three.values)
    with pytest.raises(ValueError, match="at least 1"):
        EpisodeRunner(env, only_local(env), 0, 10)
    with pytest.raises(ValueError, match="runner was built for 30"):
        runner.play_compiled(compiled, jax.random.key(0), sgjax.make("open", time_limit=6.0)[1])
