"""sgjax as a JaxMARL environment: JaxMARL's base-API checks (its tests/test_envs_implement_
base_api.py and test_jaxmarl_api.py, written again here) on every mini-game in both action modes,
auto-reset to a given state, and an IPPO loop shaped like JaxMARL's baseline scripts (LogWrapper,
batchify / unbatchify, info reshaped to NUM_ACTORS) learning for a few updates."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from flax import linen as nn

from sgjax.adapters.jaxmarl import SocialNavJaxMARL, make_jaxmarl, registered_envs

# jaxmarl itself is imported inside the tests that name its classes: importing it takes about
# 2.6 s, and every xdist worker collects (imports) every test file.

MINI_GAMES = ["doorway", "hallway", "intersection", "roundabout", "open"]


@pytest.mark.parametrize("action_mode", ["go_stop", "continuous"])
@pytest.mark.parametrize("scenario", MINI_GAMES)
def test_base_api(scenario, action_mode):
    from jaxmarl.environments import MultiAgentEnv
    from jaxmarl.environments.spaces import Box, Discrete, Space

    env = make_jaxmarl(f"sgjax_{scenario}", num_agents=3, action_mode=action_mode)
    assert isinstance(env, MultiAgentEnv) and env.name == f"sgjax_{scenario}"
    for agent in env.agents:
        assert env.observation_spaces[agent] == env.observation_space(agent)
        assert env.action_spaces[agent] == env.action_space(agent)
        assert isinstance(env.observation_space(agent), Space)
        assert isinstance(env.action_space(agent), Discrete if action_mode == "go_stop" else Box)
    obs, state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    assert all(bool(env.observation_space(a).contains(obs[a])) for a in env.agents)
    keys = jax.random.split(jax.random.PRNGKey(1), env.num_agents)
    actions = {a: env.action_space(a).sample(keys[i]) for i, a in enumerate(env.agents)}
    result = jax.jit(env.step)(jax.random.PRNGKey(2), state, actions)
    assert isinstance(result, tuple) and len(result) == 5
    next_obs, _, reward, done, info = result
    assert all(bool(env.observation_space(a).contains(next_obs[a])) for a in env.agents)
    assert isinstance(reward, dict) and isinstance(done, dict) and "__all__" in done
    assert isinstance(info, dict)
    assert all(leaf.shape == (env.num_agents,) for leaf in jax.tree.leaves(info))
    avail = env.get_avail_actions(state)
    assert all(v.dtype == jnp.bool_ and bool(v.all()) for v in avail.values())
    assert env.agent_classes == {"robot": env.agents}


def test_auto_reset_to_a_given_state_and_per_agent_action_shapes():
    env = SocialNavJaxMARL("open", num_agents=2, time_limit=1.0)
    _, state1 = env.reset(jax.random.PRNGKey(1))
    _, state2 = env.reset(jax.random.PRNGKey(2))
    step = jax.jit(env.step)
    go = {a: jnp.zeros((1,), jnp.int32) for a in env.agents}  # shape (1,), as unbatchify gives
    _, after, _, dones, _ = step(jax.random.PRNGKey(3), state1, go, state2)
    assert not bool(dones["__all__"])
    assert not np.array_equal(after.robots.x, state2.robots.x)
    last = state1.replace(time=env.params.max_steps - 1)  # the time limit ends this step
    _, after, _, dones, _ = step(jax.random.PRNGKey(4), last, go, state2)
    assert bool(dones["__all__"])
    jax.tree.map(lambda a, b: np.testing.assert_array_equal(a, b), state2, after)
    with pytest.raises(KeyError, match="no action for"):
        env.step(jax.random.PRNGKey(5), state1, {"robot_0": 0})
    assert "sgjax_doorway" in registered_envs()
    with pytest.raises(ValueError, match="registered: sgjax_doorway"):
        make_jaxmarl("doorway")


class ActorCritic(nn.Module):
    """The feed-forward actor-critic of JaxMARL's IPPO script, small."""

    num_actions: int

    @nn.compact
    def __call__(self, x):
        hidden = nn.tanh(nn.Dense(32)(x))
        logits = nn.Dense(self.num_actions)(hidden)
        value = nn.Dense(1)(nn.tanh(nn.Dense(32)(x)))
        return logits, jnp.squeeze(value, -1)


@pytest.mark.slow
def test_an_ippo_loop_shaped_like_jaxmarls_runs_and_learns_under_log_wrapper():
    from jaxmarl.wrappers.baselines import LogWrapper

    num_envs, num_steps, updates = 16, 32, 12
    env = LogWrapper(SocialNavJaxMARL("open", num_agents=2, time_limit=12.0))
    num_actors = env.num_agents * num_envs
    network = ActorCritic(env.action_space(env.agents[0]).n)

    def batchify(x):
        return jnp.stack([x[a] for a in env.agents]).reshape((num_actors, -1))

    def unbatchify(x):
        x = x.reshape((env.num_agents, num_envs, -1))
        return {a: x[i] for i, a in enumerate(env.agents)}

    def train(key):
        key, k_init, k_reset = jax.random.split(key, 3)
        obs_dim = env.observation_space(env.agents[0]).shape[0]
        params = network.init(k_init, jnp.zeros((obs_dim,)))
        tx = optax.chain(optax.clip_by_global_norm(0.5), optax.adam(3e-3))
        opt = tx.init(params)
        obs, state = jax.vmap(env.reset)(jax.random.split(k_reset, num_envs))

        def update(carry, _):
            params, opt, state, obs, key = carry

            def env_step(carry, _):
                state, obs, key = carry
                key, k_act, k_step = jax.random.split(key, 3)
                logits, value = network.apply(params, batchify(obs))
                action = jax.random.categorical(k_act, logits)
                logp = jax.nn.log_softmax(logits)[jnp.arange(num_actors), action]
                env_act = {a: v.squeeze(-1) for a, v in unbatchify(action).items()}
                obs2, state, reward, done, info = jax.vmap(env.step)(
                    jax.random.split(k_step, num_envs), state, env_act)
                info = jax.tree.map(lambda x: x.reshape((num_actors,)), info)
                out = (batchify(obs), action, logp, value, batchify(reward).squeeze(-1),
                       batchify(done).squeeze(-1), info)
                return (state, obs2, key), out

            (state, obs, key), (b_obs, b_act, b_logp, b_val, b_rew, b_done, info) = \
                jax.lax.scan(env_step, (state, obs, key), None, num_steps)
            _, last_val = network.apply(params, batchify(obs))

            def gae(carry, t):
                adv, next_val = carry
                reward, value, done = t
                delta = reward + 0.99 * next_val * (1 - done) - value
                adv = delta + 0.99 * 0.95 * (1 - done) * adv
                return (adv, value), adv

            _, adv = jax.lax.scan(gae, (jnp.zeros(num_actors), last_val),
                                  (b_rew, b_val, b_done), reverse=True)
            targets = adv + b_val

            def loss_fn(p):
                logits, value = network.apply(p, b_obs)
                logp = jax.nn.log_softmax(logits)
                new = jnp.take_along_axis(logp, b_act[..., None], -1)[..., 0]
                ratio = jnp.exp(new - b_logp)
                a = (adv - adv.mean()) / (adv.std() + 1e-8)
                pg = -jnp.minimum(ratio * a, jnp.clip(ratio, 0.8, 1.2) * a).mean()
                return pg + 0.5 * jnp.square(value - targets).mean()

            grads = jax.grad(loss_fn)(params)
            updates_, opt = tx.update(grads, opt)
            params = optax.apply_updates(params, updates_)
            ended = info["returned_episode"]
            mean_return = (info["returned_episode_returns"] * ended).sum() / jnp.maximum(
                ended.sum(), 1)
            return (params, opt, state, obs, key), mean_return

        _, returns = jax.lax.scan(update, (params, opt, state, obs, key), None, updates)
        return returns

    returns = jax.jit(train)(jax.random.PRNGKey(0))
    assert returns.shape == (updates,) and bool(jnp.all(jnp.isfinite(returns)))
    assert float(returns[-4:].mean()) > float(returns[:4].mean()), returns


def test_without_jaxmarl_the_error_names_the_extra():
    import subprocess
    import sys

    program = ("import sys; sys.modules['jaxmarl'] = None\n"
               "import sgjax.adapters.jaxmarl as m\n"
               "builds = (lambda: m.SocialNavJaxMARL('open', 2),\n"
               "          lambda: m.make_jaxmarl('sgjax_open'))\n"
               "for build in builds:\n"
               "    try:\n        build()\n    except ImportError as err:\n        print(err)\n")
    out = subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                         timeout=300, check=True).stdout
    assert out.count("pip install 'sgjax[jaxmarl]'") == 2, out


def test_invalid_actions_raise_outside_jit_and_are_flagged_inside():
    env = SocialNavJaxMARL("open", num_agents=2, action_mode="continuous")
    obs, state = env.reset(jax.random.key(0))
    bad = {"robot_0": jnp.array([jnp.nan, 0.0]), "robot_1": jnp.zeros(2)}
    with pytest.raises(ValueError, match="robot slot 0 has action"):
        env.step(jax.random.key(1), state, bad)
    obs, state, rewards, dones, infos = jax.jit(env.step)(jax.random.key(1), state, bad)
    assert all(bool(jnp.all(jnp.isfinite(o))) for o in obs.values())
