"""sgjax's Moussaid force law against PySocialForce (pip pysocialforce, a test-only dependency).

The scene: pedestrians in two counter-flowing groups inside a walled corridor, groups off,
PySocialForce's default constants, a 0.1 s step. Differences in formulation reconciled here
(docs/humans.md lists them):

* PySocialForce walks toward ``max_speed = 1.3 x`` each pedestrian's *initial* speed and caps at
  the same value; sgjax relaxes toward a desired speed and caps at ``max_speed_factor`` x it. The
  test sets sgjax's desired speed to 1.3 x the initial speed and the factor to 1.
* PySocialForce sums its obstacle term over points sampled along the walls (10 per metre);
  sgjax does that with ``human_walls="points"`` (the default sums over each wall's nearest point).
* PySocialForce's angle ``theta`` is the raw difference of two ``arctan2`` values, not
  wrapped to (-pi, pi] as in the paper and in sgjax. Wherever the raw value falls outside
  [-pi, pi] (a pair straddling the +x direction; hundreds of pair-steps in this scene) its
  interaction all but vanishes. The comparison runs sgjax with ``pysocialforce_angle=True``,
  which reproduces that; :func:`test_wrapped_angle_differs_only_where_pysocialforce_unwraps`
  checks that this flag changes nothing else, and
  :func:`test_pysocialforce_unwrapped_angle_drops_the_interaction` shows a case where the two
  conventions differ.
"""

from __future__ import annotations

import logging
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from sgjax.humans.forces import (
    SocialForceParams,
    cap_speed,
    desired_force,
    exponential_wall_force,
    moussaid_interaction,
)
from sgjax.humans.slots import wall_sample_points

psf = pytest.importorskip("pysocialforce")
toml = pytest.importorskip("toml")
logging.getLogger().setLevel(logging.WARNING)  # pysocialforce switches the root logger to DEBUG

DT = 0.1
RADIUS = 0.35  # PySocialForce's agent_radius (used by its obstacle term)
WALLS = np.array([[-2.0, -12.0, -2.0, 12.0], [2.0, -12.0, 2.0, 12.0], [0.8, -1.0, 1.6, -1.0]])
FORCE_TOL = 1e-3  # m/s^2, per component, from identical states (float32 against float64)
POSITION_TOL = 1e-4  # m after STEPS independent steps of both simulators (measured 2.4e-6)
STEPS = 60


def _scene() -> np.ndarray:
    """``[N, 6]`` rows ``(x, y, vx, vy, goal_x, goal_y)``: 4 walking up, 4 walking down."""
    up = [(-1.1, -7.0), (0.05, -8.0), (1.2, -6.6), (-0.5, -9.3)]
    down = [(-1.3, 7.4), (-0.2, 6.1), (0.9, 8.2), (0.35, 9.6)]
    speeds = [1.0, 1.1, 0.9, 1.2]
    rows = [(x, y, 0.02 * i, v, x * 0.5, 40.0)
            for i, ((x, y), v) in enumerate(zip(up, speeds, strict=True))]
    rows += [(x, y, -0.02 * i, -v, x * 0.5, -40.0)
             for i, ((x, y), v) in enumerate(zip(down, speeds, strict=True))]
    return np.array(rows, dtype=np.float64)


def _simulator(state: np.ndarray, tmp_path: Path):
    config = toml.load(Path(psf.__file__).parent / "config" / "default.toml")
    config["scene"]["enable_group"] = False
    # PedState reads step_width (and tau, agent_radius, max_speed_multiplier) from the top level
    # of the config, not from [scene], so [scene].step_width alone leaves it at 0.4 s.
    config["step_width"] = DT
    path = tmp_path / "psf.toml"
    path.write_text(toml.dumps(config))
    obstacles = [[x1, x2, y1, y2] for x1, y1, x2, y2 in WALLS]  # its (x1, x2, y1, y2) order
    return psf.Simulator(state.copy(), groups=None, obstacles=obstacles, config_file=str(path))


def _sgjax_forces(state, desired_speed, points, p: SocialForceParams, psf_angle=True):
    x, y, vx, vy, gx, gy = (jnp.asarray(state[:, i], jnp.float32) for i in range(6))
    n = x.shape[0]
    fx, fy = desired_force(x, y, vx, vy, gx, gy, desired_speed, p.tau)
    weight = 1.0 - jnp.eye(n)
    sx, sy = moussaid_interaction(x, y, vx, vy, x, y, vx, vy, weight, p,
                                  pysocialforce_angle=psf_angle)
    px, py = jnp.asarray(points[:, 0], jnp.float32), jnp.asarray(points[:, 1], jnp.float32)
    wx, wy = exponential_wall_force(x[:, None] - px[None, :], y[:, None] - py[None, :],
                                    jnp.ones(px.shape, bool), jnp.full(n, RADIUS), p)
    return np.stack([fx + sx + wx, fy + sy + wy], axis=-1)


def _unwrapped_theta(state: np.ndarray) -> np.ndarray:
    """PySocialForce's theta for every ordered pair (its formula, not its code)."""
    pos, vel = state[:, :2], state[:, 2:4]
    diff = pos[:, None] - pos[None, :]  # self - other
    e = diff / np.linalg.norm(diff, axis=-1, keepdims=True).clip(1e-12)
    inter = 2.0 * (vel[None, :] - vel[:, None]) + e
    mask = ~np.eye(len(state), dtype=bool)
    return (np.arctan2(inter[..., 1], inter[..., 0]) - np.arctan2(e[..., 1], e[..., 0]))[mask]


@pytest.mark.slow
def test_moussaid_matches_pysocialforce(tmp_path):
    state0 = _scene()
    sim = _simulator(state0, tmp_path)
    p = SocialForceParams()
    desired_speed = jnp.asarray(1.3 * np.linalg.norm(state0[:, 2:4], axis=1), jnp.float32)
    points = wall_sample_points(WALLS, 10.0)
    ours = state0.copy()
    worst_force, crossings = 0.0, 0
    for _ in range(STEPS):
        theirs = sim.peds.state[:, :6].copy()
        crossings += int(np.sum(np.abs(_unwrapped_theta(theirs)) > np.pi))
        reference = sim.compute_forces()
        mine = _sgjax_forces(theirs, desired_speed, points, p)
        worst_force = max(worst_force, float(np.max(np.abs(mine - reference))))
        # Advance sgjax on its own trajectory (semi-implicit Euler with the speed cap).
        f = _sgjax_forces(ours, desired_speed, points, p)
        vx, vy = cap_speed(jnp.asarray(ours[:, 2] + DT * f[:, 0], jnp.float32),
                           jnp.asarray(ours[:, 3] + DT * f[:, 1], jnp.float32), desired_speed)
        ours[:, 2], ours[:, 3] = np.asarray(vx), np.asarray(vy)
        ours[:, :2] += DT * ours[:, 2:4]
        sim.step_once()
    print(f"worst force gap {worst_force:.2e} m/s^2; pair-steps with PySocialForce's theta "
          f"outside [-pi, pi]: {crossings}")
    assert worst_force < FORCE_TOL
    gap = np.max(np.linalg.norm(ours[:, :2] - sim.peds.state[:, :2], axis=1))
    print(f"largest position gap after {STEPS} steps: {gap:.2e} m")
    assert gap < POSITION_TOL
    # The scene is not trivial: the groups met and were deflected sideways.
    assert np.max(np.abs(sim.peds.state[:, 0] - state0[:, 0])) > 0.2


def test_pysocialforce_unwrapped_angle_drops_the_interaction():
    """Pedestrian 1 stands just ahead of pedestrian 0 on its +x path, slightly to the left:
    the true angle is small, so both laws should brake hard; PySocialForce's unwrapped
    difference is near 2 pi and its interaction all but vanishes. sgjax keeps it."""
    state = np.array([[0.0, 0.0, 1.0, 0.0, 10.0, 0.0], [1.0, 0.05, 0.0, 0.3, 1.0, 10.0]])
    theta = _unwrapped_theta(state)
    assert abs(theta[0]) > np.pi  # PySocialForce's value for pedestrian 0
    x, y, vx, vy = (jnp.asarray(state[:, i], jnp.float32) for i in range(4))
    fx, _ = moussaid_interaction(x, y, vx, vy, x, y, vx, vy, 1.0 - jnp.eye(2),
                                 SocialForceParams())
    assert float(fx[0]) < -0.5  # sgjax brakes pedestrian 0


def test_wrapped_angle_differs_only_where_pysocialforce_unwraps():
    """On the scene's first state, the two angle conventions give the same interaction for
    every pedestrian none of whose pairs straddles the cut."""
    state = _scene()
    state[:, 0] += np.linspace(-0.3, 0.3, len(state))  # break the symmetry a little
    state[:, 1] *= 0.3  # bring the groups close, so that some pairs straddle the cut
    p = SocialForceParams()
    speed = jnp.ones(len(state))
    points = np.zeros((0, 2))
    wrapped = _sgjax_forces(state, speed, points, p, psf_angle=False)
    raw = _sgjax_forces(state, speed, points, p, psf_angle=True)
    n = len(state)
    straddles = np.zeros((n, n), bool)
    straddles[~np.eye(n, dtype=bool)] = np.abs(_unwrapped_theta(state)) > np.pi
    clean = ~straddles.any(axis=1)
    assert clean.any() and (~clean).any()
    np.testing.assert_allclose(wrapped[clean], raw[clean], atol=1e-5)
