"""Differentiability with continuous actions: gradients of positions and rewards with respect to
the actions are finite and match central finite differences away from contacts and limits."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sgjax

jax.config.update("jax_enable_x64", False)
STEPS = 12


def make_rollout(robots="socialgym", **overrides):
    env, params = sgjax.make("open", num_agents=2, action_mode="continuous", robots=robots,
                             **overrides)
    spec = sgjax.maps.load("open")
    start = jnp.array([spec.index_of(12), spec.index_of(36)])  # (-6, 0) and (6, 0), 12 m apart
    _, state0 = env.reset_to(start, start[::-1], jnp.array([True, True]), params)

    def rollout(actions, with_obs=False):  # actions [STEPS, 2, d] -> (positions, reward)
        def body(state, a):
            obs, state, reward, *_ = env.step_env(jax.random.key(0), state, a, params)
            return state, (reward.sum(), obs)

        state, (rewards, obs) = jax.lax.scan(body, state0, actions)
        if with_obs:
            return state.robots.position, rewards.sum(), obs[-1]
        return state.robots.position, rewards.sum()

    return env, rollout


def smooth_actions(dim, key):
    # Small commands (well inside the speed, acceleration and yaw limits) keep every step on
    # the smooth side of the clips, far from any contact.
    base = jnp.zeros((STEPS, 2, dim)).at[..., 0].set(0.15)
    return base + 0.05 * jax.random.uniform(key, base.shape, minval=-1, maxval=1)


@pytest.mark.slow
@pytest.mark.parametrize("robots", ["socialgym", "cobot", "automata"])
def test_gradient_matches_finite_differences(robots):
    env, rollout = make_rollout(robots)
    actions = smooth_actions(env.config.action_dim, jax.random.key(1))

    def objective(a):
        position, reward = rollout(a)
        return position[0, 0] + 0.5 * position[0, 1] - position[1, 1] + reward

    assert_matches_finite_differences(objective, actions, seed=0, directions=6, abs_tol=2e-3)


def assert_matches_finite_differences(objective, actions, seed, directions, abs_tol):
    """jax.grad is finite, not all zero, and matches central differences along random
    directions (eps 1e-2, 5% relative)."""
    grad = jax.jit(jax.grad(objective))(actions)
    assert bool(jnp.all(jnp.isfinite(grad)))
    assert float(jnp.abs(grad).max()) > 0.0
    f = jax.jit(objective)
    rng = np.random.default_rng(seed)
    eps = 1e-2
    for _ in range(directions):
        direction = jnp.asarray(rng.normal(size=actions.shape), jnp.float32)
        direction = direction / jnp.linalg.norm(direction)
        numeric = (f(actions + eps * direction) - f(actions - eps * direction)) / (2 * eps)
        analytic = jnp.vdot(grad, direction)
        assert float(analytic) == pytest.approx(float(numeric), rel=0.05, abs=abs_tol)


def test_jacobian_of_positions_is_finite_and_causal():
    env, rollout = make_rollout()
    actions = smooth_actions(env.config.action_dim, jax.random.key(2))
    jac = jax.jit(jax.jacrev(lambda a: rollout(a)[0]))(actions)  # [2, 2, STEPS, 2, d]
    assert bool(jnp.all(jnp.isfinite(jac)))
    # Robot 0's position depends on its own actions, not on robot 1's (no contact here).
    assert float(jnp.abs(jac[0, :, :, 0]).max()) > 0.0
    assert float(jnp.abs(jac[0, :, :, 1]).max()) == 0.0


@pytest.mark.slow
def test_grad_through_vmap_and_jit():
    env, rollout = make_rollout()
    actions = jnp.stack([smooth_actions(env.config.action_dim, k)
                         for k in jax.random.split(jax.random.key(3), 4)])
    grads = jax.jit(jax.vmap(jax.grad(lambda a: rollout(a)[1])))(actions)
    assert grads.shape == actions.shape and bool(jnp.all(jnp.isfinite(grads)))


SMOOTH_TERMS = {
    "observations": ["pose", {"velocity": {"history": 2, "frame": "world"}}, "goal",
                     {"goal_distance": {"history": 2}}, "waypoint", {"others": {"k": 1}},
                     {"lidar": {"beams": 8, "range": 20.0}}],
    "rewards": {"progress": 1.0, "goal_distance": 0.1, "velocity_change": 1.0,
                "preferred_velocity": 0.1, "existence": 1.0, "proximity": 1.0},
}


@pytest.mark.slow
def test_gradient_through_smooth_terms_matches_finite_differences():
    """Rewards and observations made of terms stay differentiable in the actions."""
    env, rollout = make_rollout(terms=SMOOTH_TERMS)
    actions = smooth_actions(env.config.action_dim, jax.random.key(2))

    def objective(a):
        _, reward, obs = rollout(a, with_obs=True)
        return reward + 0.1 * jnp.sum(obs)

    assert_matches_finite_differences(objective, actions, seed=1, directions=4, abs_tol=5e-3)
