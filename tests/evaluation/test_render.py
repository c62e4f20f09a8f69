"""Rendering: frames have the right shape and change; GIFs are readable; drawing leaves
matplotlib's global backend alone."""

import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image

import sgjax
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.render import (
    MapCanvas,
    draw_scenario,
    episode_frames,
    render_frame,
    render_state,
    save_gif,
)

ROOT = Path(__file__).resolve().parents[2]


def frame_of(spec, state, radius):
    return render_state(spec, state, radius, width_px=200)


@pytest.mark.slow
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


def test_frames_on_one_map_canvas_equal_frames_drawn_alone():
    """episode_frames draws every frame over one MapCanvas (the map drawn once): each frame is
    the picture render_state draws on a figure of its own, pixel for pixel, so nothing of one
    frame is left on the next."""
    env, params = sgjax.make("doorway", num_agents=3, num_humans=2)
    spec = sgjax.maps.load("doorway")
    out = run_episodes(env, params, "only_local", jax.random.key(1), 1, record=True)
    states = jax.tree.map(lambda leaf: np.asarray(leaf)[:40, 0], out.states)
    frames, stride = episode_frames(spec, states, params, 39, title="x", width_px=160,
                                    max_frames=4)
    radius = np.asarray(params.robots.radius)
    assert stride == 10 and len(frames) == 4
    positions = np.stack([states.robots.x, states.robots.y], axis=-1)
    for k, t in enumerate(range(0, 40, stride)):
        alone = render_state(spec, jax.tree.map(lambda leaf, t=t: leaf[t], states), radius,
                             trail=positions[max(0, t - 15):t + 1],
                             title=f"x  t = {t * float(params.dt):.1f} s", width_px=160,
                             human_radius=float(params.humans.radius))
        np.testing.assert_array_equal(frames[k], alone, err_msg=f"frame {k}")
    canvas = MapCanvas(spec, 160)
    blank = render_frame(spec, np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, bool),
                         np.zeros(0, bool), np.zeros((0, 2)), canvas=canvas)
    assert len(canvas.ax.get_children()) == len(MapCanvas(spec, 160).ax.get_children())
    assert blank.shape == frames[0].shape


def test_scenario_picture():
    image = draw_scenario(sgjax.maps.load("open"), width_px=120)
    assert image.shape[1] == 120 and image.std() > 0


BACKEND_CHECK = """
import matplotlib, sys
import sgjax.adapters.pettingzoo, sgjax.evaluation.report, sgjax.evaluation.render
import sgjax.evaluation.evaluate, sgjax.command
assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
env = sgjax.adapters.pettingzoo.parallel_env("open", num_agents=2, render_mode="rgb_array")
env.reset(seed=0)
frame = env.render()
assert frame.ndim == 3 and frame.shape[2] == 3 and frame.std() > 0
import pathlib, tempfile, numpy as np
from sgjax.evaluation.metrics import DEFAULT_CONSTANTS, METRICS
from sgjax.evaluation.statistics import ConfigResult, summarize_metrics
values = {name: np.random.default_rng(0).random(4) for name in METRICS.names()}
result = ConfigResult("open", "p", 2, 4, 0, 0.1, 10, summarize_metrics(values), 1.0)
out = pathlib.Path(tempfile.mkdtemp())
sgjax.evaluation.report.write_all([result], out, DEFAULT_CONSTANTS)
assert (out / "success_by_robots.png").stat().st_size > 0
assert matplotlib.get_backend() == "svg", matplotlib.get_backend()
assert "matplotlib.pyplot" not in sys.modules, "pyplot was imported"
print("backend kept")
"""


@pytest.mark.slow
def test_importing_and_drawing_keep_the_plotting_backend():
    """A notebook's matplotlib backend survives importing and using the adapters and report."""
    env = {**os.environ, "MPLBACKEND": "svg", "JAX_PLATFORMS": "cpu",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    result = subprocess.run([sys.executable, "-c", BACKEND_CHECK], env=env, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    assert "backend kept" in result.stdout
