"""Rendering and the main job: frames have the right shape and change; GIFs are readable."""

import jax
import jax.numpy as jnp
import numpy as np
from PIL import Image

import sgjax
from sgjax.render import draw_scenario, render_state, save_gif
from sgjax.rollout import main


def frame_of(spec, state, radius):
    return render_state(spec, state, radius, width_px=200)


def test_frames_change_between_steps_and_gif_is_readable(tmp_path):
    env, params = sgjax.make("hallway", num_agents=2)
    spec = sgjax.maps.load("hallway")
    _, state = env.reset(jax.random.key(0), params)
    radius = np.asarray(params.robots.radius)
    first = frame_of(spec, state, radius)
    for t in range(10):
        _, state, *_ = env.step(jax.random.key(t), state, jnp.zeros(2, jnp.int32), params)
    later = frame_of(spec, state, radius)
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
    assert first.shape == later.shape and not np.array_equal(first, later)
    path = save_gif([first, later], tmp_path / "a.gif")
    with Image.open(path) as gif:
        assert gif.n_frames == 2


def test_scenario_picture():
    image = draw_scenario(sgjax.maps.load("open"), width_px=120)
    assert image.shape[1] == 120 and image.std() > 0


def test_main_job_end_to_end(tmp_path, capsys):
    main(["--scenario", "open", "--num-agents", "2", "--num-envs", "8", "--steps", "800",
          "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert "team success" in out and "agent-steps/s" in out
    with Image.open(tmp_path / "episode.gif") as gif:
        assert gif.n_frames > 5
