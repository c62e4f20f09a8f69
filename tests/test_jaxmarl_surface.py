"""The JaxMARL-compatible surface, driven the way JaxMARL's IPPO baseline drives environments:
vmapped reset/step over NUM_ENVS, observations batchified to [num_agents * NUM_ENVS, obs_dim],
actions unbatchified back to a dict, the whole rollout inside jit(lax.scan)."""

import jax
import jax.numpy as jnp
import pytest

from sgjax.jaxmarl import Box, Discrete, SocialNavJaxMARL

NUM_ENVS, NUM_STEPS = 8, 64


def batchify(x: dict, agents: list[str], num_actors: int):
    return jnp.stack([x[a] for a in agents]).reshape((num_actors, -1))


def unbatchify(x, agents: list[str], num_envs: int, num_agents: int):
    x = x.reshape((num_agents, num_envs, -1))
    return {a: x[i] for i, a in enumerate(agents)}


@pytest.mark.parametrize("action_mode", ["go_stop", "continuous"])
def test_driven_like_jaxmarl_ippo(action_mode):
    env = SocialNavJaxMARL("open", num_agents=3, action_mode=action_mode, time_limit=3.0)
    num_actors = env.num_agents * NUM_ENVS
    obs_dim = env.observation_space(env.agents[0]).shape[0]
    space = env.action_space(env.agents[0])
    assert isinstance(space, Discrete if action_mode == "go_stop" else Box)

    def rollout(key):
        key, k_reset = jax.random.split(key)
        obsv, env_state = jax.vmap(env.reset)(jax.random.split(k_reset, NUM_ENVS))

        def env_step(carry, _):
            env_state, last_obs, key = carry
            key, k_act, k_step = jax.random.split(key, 3)
            obs_batch = batchify(last_obs, env.agents, num_actors)  # what the network sees
            assert obs_batch.shape == (num_actors, obs_dim)
            action = jax.vmap(space.sample)(jax.random.split(k_act, num_actors))
            env_act = unbatchify(action, env.agents, NUM_ENVS, env.num_agents)
            env_act = {a: v.squeeze(-1) if action_mode == "go_stop" else v
                       for a, v in env_act.items()}
            obsv, env_state, reward, done, info = jax.vmap(env.step)(
                jax.random.split(k_step, NUM_ENVS), env_state, env_act)
            return (env_state, obsv, key), (batchify(reward, env.agents, num_actors),
                                            done["__all__"], info["world_state"])

        _, (rewards, all_done, world) = jax.lax.scan(env_step, (env_state, obsv, key), None,
                                                     NUM_STEPS)
        return rewards, all_done, world

    rewards, all_done, world = jax.jit(rollout)(jax.random.key(0))
    assert rewards.shape == (NUM_STEPS, num_actors, 1)
    assert bool(jnp.all(jnp.isfinite(rewards)))
    assert bool(all_done.any())  # 3 s time limit: episodes end and auto-reset inside the scan
    assert world.shape == (NUM_STEPS, NUM_ENVS, env.num_agents * obs_dim)


@pytest.mark.slow
def test_dones_and_avail_actions():
    env = SocialNavJaxMARL("open", num_agents=2)
    obs, state = env.reset(jax.random.key(0))
    assert set(obs) == {"robot_0", "robot_1"}
    obs, state, rewards, dones, infos = env.step(jax.random.key(1), state,
                                                 {"robot_0": 0, "robot_1": 1})
    assert set(dones) == {"robot_0", "robot_1", "__all__"}
    assert env.get_avail_actions(state)["robot_0"].shape == (2,)
