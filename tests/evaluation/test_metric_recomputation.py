"""Metrics recomputed in plain numpy from recorded episode states, from docs/metrics.md's
definitions, agree with the evaluator's: several scenarios, policies and action modes.

Covered here: success, clean_success, timeout, time_to_goal, path_length, path_irregularity,
path_irregularity_per_m, the collision counts (rising edges of the recorded contact flags) and
collision_episode, stop_time, freezes, deadlock, velocity_change_sum and _max,
turn_rate_change_sum, acceleration_mean and _max, jerk_mean and _max, min_distance_robot and
_human, the intimate/personal/social space fractions (robots and pedestrians), min_ttc,
ttc_below_threshold, team_success, episode_length, aggregated_time and makespan. (The
counterfactual metrics have their own brute-force test in test_counterfactual.py; order
violations and flow rate, which need the zone books' priorities, and spl, which needs the
route's graph length, are checked on hand-built cases in test_metrics.py.)
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

import sgjax
from sgjax.evaluation.evaluate import run_episodes
from sgjax.evaluation.metrics import DEFAULT_CONSTANTS, SPACE_NAMES
from sgjax.evaluation.metrics.ttc import TOUCHING

CASES = [  # scenario, policy, make options, metrics that must occur (not all 0 or NaN)
    ("doorway", "only_local", {"num_agents": 4, "num_humans": 3, "time_limit": 20.0},
     ("collisions_robot", "stop_time", "clean_success", "timeout")),
    ("intersection", "random", {"num_agents": 3, "action_mode": "continuous",
                                "time_limit": 12.0}, ("collisions_wall", "min_ttc")),
    # waiting in a corridor among pedestrians: freezes, a deadlock, pedestrian contacts, and
    # one team success (makespan)
    ("hallway", "stop_when_blocked", {"num_agents": 4, "num_humans": 6, "time_limit": 40.0},
     ("collisions_human", "freezes", "deadlock", "makespan", "jerk_max")),
]


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def _ttc(dp: np.ndarray, dv: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Smallest tau >= 0 with |dp + tau dv| = reach; 0 within reach + TOUCHING; inf never."""
    a = np.sum(dv * dv, -1)
    b = 2 * np.sum(dp * dv, -1)
    dist2 = np.sum(dp * dp, -1)
    c = dist2 - reach**2
    disc = b * b - 4 * a * c
    closing = (b < 0) & (disc >= 0) & (a > 1e-12)
    with np.errstate(invalid="ignore", divide="ignore"):
        root = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * np.where(closing, a, 1))
    return np.where(dist2 <= (reach + TOUCHING) ** 2, 0.0, np.where(closing, root, np.inf))


def recompute(states, params, episode: int) -> dict[str, np.ndarray]:
    """Robot-level ``[R]`` and episode-level values of one recorded episode, in numpy."""
    get = lambda leaf: np.asarray(leaf)[:, episode]  # noqa: E731
    r, h = jax.tree.map(get, states.robots), jax.tree.map(get, states.humans)
    dt, c = float(params.dt), DEFAULT_CONSTANTS
    radius = np.asarray(params.robots.radius, float)
    human_radius = float(params.humans.radius)
    active = np.asarray(r.present & ~(r.succeeded | r.ended))  # [T + 1, R]
    in_world = np.asarray(r.in_world)
    present = np.asarray(r.present[0])
    finished = ~active[:, present].any(axis=1)
    max_steps = active.shape[0] - 1
    length = int(np.argmax(finished)) if finished.any() else max_steps
    steps = np.arange(max_steps)
    was_active = active[:-1] & (steps < length)[:, None]  # [T, R]: the counted steps
    pos = np.stack([np.asarray(r.x), np.asarray(r.y)], -1).astype(float)  # [T + 1, R, 2]
    vel = np.asarray(jax.vmap(lambda rr: rr.velocity)(r), float)  # [T + 1, R, 2] world
    body_vel = np.asarray(jax.vmap(lambda rr: rr.body_velocity)(r), float)  # parked at rest
    heading = np.asarray(r.heading, float)
    moved = np.linalg.norm(pos[1:] - pos[:-1], axis=-1)
    dv = np.linalg.norm(vel[1:] - vel[:-1], axis=-1)
    num = pos.shape[1]
    # Other bodies after each step: robots in the world during it, active pedestrians.
    other = in_world[:-1, None, :] & ~np.eye(num, dtype=bool)[None]  # [T, R, R]
    gap_robot = (np.linalg.norm(pos[1:, :, None] - pos[1:, None, :], axis=-1)
                 - radius[:, None] - radius[None, :])
    gap_robot = np.where(other, gap_robot, np.inf)
    hp = np.stack([np.asarray(h.x), np.asarray(h.y)], -1).astype(float)  # [T + 1, H, 2]
    hv = np.stack([np.asarray(h.vx), np.asarray(h.vy)], -1).astype(float)
    h_active = np.asarray(h.active)[1:]  # [T, H]
    gap_human = np.linalg.norm(pos[1:, :, None] - hp[1:, None, :], axis=-1) - radius[:, None] \
        - human_radius
    gap_human = np.where(h_active[:, None, :], gap_human, np.inf)
    ttc_robot = _ttc(pos[1:, None, :] - pos[1:, :, None],
                     body_vel[1:, None, :] - vel[1:, :, None],
                     radius[:, None] + radius[None, :])
    ttc_human = _ttc(hp[1:, None, :] - pos[1:, :, None], hv[1:, None, :] - vel[1:, :, None],
                     radius[:, None] + human_radius)
    ttc = np.minimum(np.where(other, ttc_robot, np.inf).min(-1, initial=np.inf),
                     np.where(h_active[:, None, :], ttc_human, np.inf).min(-1, initial=np.inf))
    ttc = np.minimum(ttc, c.ttc_cap)
    counted = np.maximum(was_active.sum(0), 1)

    def fraction_below(values: np.ndarray, threshold: float, eps: float) -> np.ndarray:
        """``[R, 2]``: the fraction of counted steps with ``values < threshold``, as bounds:
        a value within ``eps`` of the threshold may fall either way in float32 (positions and
        velocities are float32 in the step; this recomputation is float64)."""
        low = (was_active & (values < threshold - eps)).sum(0) / counted
        high = (was_active & (values < threshold + eps)).sum(0) / counted
        return np.stack([low, high], -1)

    def over_active(values: np.ndarray, reduce, empty: float) -> np.ndarray:
        return np.array([reduce(values[was_active[:, i], i]) if was_active[:, i].any()
                         else empty for i in range(num)])

    # Stops (after each counted step: unfinished, speed and turn rate below the thresholds).
    omega = np.asarray(r.kin.omega, float)
    running = (steps < length)[:, None]
    still = active[1:] & running  # [T, R]
    stopped = still & (np.linalg.norm(vel[1:], axis=-1) < c.stop_speed) & (
        np.abs(omega[1:]) < c.stop_turn_rate)
    freeze_steps = max(int(np.ceil(c.freeze_time / dt - 1e-6)), 1)
    deadlock_steps = max(int(np.ceil(c.deadlock_time / dt - 1e-6)), 1)
    run_length = np.zeros(num, int)
    freezes = np.zeros(num)
    stall, deadlock = 0, False
    for t in range(max_steps):
        run_length = np.where(stopped[t], run_length + 1, 0)
        freezes += was_active[t] & stopped[t] & (run_length == freeze_steps)
        stalled = still[t].sum() >= 2 and np.all(stopped[t] | ~still[t])
        stall = stall + 1 if stalled else 0
        deadlock |= t < length and stall >= deadlock_steps
    # Smoothness: accelerations per step, jerk between consecutive counted steps.
    accel = (vel[1:] - vel[:-1]) / dt  # [T, R, 2]
    accel_norm = np.linalg.norm(accel, axis=-1)
    jerk = np.linalg.norm(accel[1:] - accel[:-1], axis=-1) / dt  # [T - 1, R]
    jerk_ok = was_active[1:] & was_active[:-1]
    jerk_counted = jerk_ok.sum(0)
    # Collisions: onsets (rising edges) of the recorded contact flags, while counted.
    onsets = {}
    for kind in ("robot", "wall", "human"):
        touching = np.asarray(getattr(states, f"touching_{kind}"))[:, episode]  # [T + 1, R]
        onsets[kind] = (touching[1:] & ~touching[:-1] & was_active).sum(0)
    any_onset = onsets["robot"] + onsets["wall"] + onsets["human"]

    succeeded = np.asarray(r.succeeded[-1]) & present
    arrival = np.argmax(np.asarray(r.succeeded), axis=0)  # first step it is set
    nearest_robot = gap_robot.min(-1, initial=np.inf)
    nearest_human = gap_human.min(-1, initial=np.inf)
    out = {
        "success": succeeded.astype(float),
        "time_to_goal": np.where(succeeded, arrival * dt, np.nan),
        "path_length": np.where(was_active, moved, 0).sum(0),
        "path_irregularity": np.where(was_active, np.abs(_wrap(heading[1:] - heading[:-1])),
                                      0).sum(0),
        "velocity_change_sum": np.where(was_active, dv, 0).sum(0),
        "velocity_change_max": over_active(dv, np.max, 0.0),
        "min_distance_robot": over_active(nearest_robot, np.min, np.inf),
        "min_distance_human": over_active(nearest_human, np.min, np.inf),
        "min_ttc": over_active(ttc, np.min, c.ttc_cap),
        "ttc_below_threshold": fraction_below(ttc, c.ttc_threshold, 1e-4),
        "team_success": float(succeeded[present].all()),
        "episode_length": float(length),
        "timeout": (present & ~succeeded & ~np.asarray(r.ended[-1])).astype(float),
        "stop_time": (was_active & stopped).sum(0) * dt,
        "freezes": freezes,
        "deadlock": float(deadlock),
        "turn_rate_change_sum": np.where(was_active, np.abs(omega[1:] - omega[:-1]), 0).sum(0),
        "acceleration_mean": np.where(was_active, accel_norm, 0).sum(0) / counted,
        "acceleration_max": over_active(accel_norm, np.max, 0.0),
        "jerk_mean": np.where(jerk_counted > 0, np.where(jerk_ok, jerk, 0).sum(0)
                              / np.maximum(jerk_counted, 1), np.nan),
        "jerk_max": np.where(jerk_counted > 0, np.where(jerk_ok, jerk, 0).max(0, initial=0.0),
                             np.nan),
        "collisions": any_onset.astype(float),
        "collisions_robot": onsets["robot"].astype(float),
        "collisions_wall": onsets["wall"].astype(float),
        "collisions_human": onsets["human"].astype(float),
        "collision_episode": float(any_onset[present].sum() > 0),
    }
    team = bool(succeeded[present].all())
    out["aggregated_time"] = out["makespan"] = (
        float(arrival[present].max() * dt) if team else np.nan)
    path = out["path_length"]
    out["path_irregularity_per_m"] = np.where(path > 1e-3, out["path_irregularity"]
                                              / np.maximum(path, 1e-3), np.nan)
    # Clean success: arrived with no onset in the steps it started unfinished (arrival
    # step included).
    out["clean_success"] = (succeeded & (any_onset == 0)).astype(float)
    for k, space in enumerate(SPACE_NAMES):
        near = c.space_radii[k]
        out[f"{space}_space_robot"] = fraction_below(nearest_robot, near, 1e-5)
        out[f"{space}_space_human"] = fraction_below(nearest_human, near, 1e-5)
    for name in ("min_distance_robot", "min_distance_human"):  # never met anyone: NaN
        out[name] = np.where(np.isfinite(out[name]), out[name], np.nan)
    saw_robot = np.isfinite(np.where(was_active, nearest_robot, np.inf)).any(0)
    saw_human = np.isfinite(np.where(was_active, nearest_human, np.inf)).any(0)
    for space in SPACE_NAMES:
        out[f"{space}_space_robot"] = np.where(saw_robot[:, None], out[f"{space}_space_robot"],
                                               np.nan)
        out[f"{space}_space_human"] = np.where(saw_human[:, None], out[f"{space}_space_human"],
                                               np.nan)
    for name, value in out.items():  # robots not in the episode: NaN
        if np.ndim(value):
            out[name] = np.where(present.reshape((-1,) + (1,) * (np.ndim(value) - 1)), value,
                                 np.nan)
    return out


@pytest.mark.slow
@pytest.mark.parametrize(("scenario", "policy", "options", "occurring"), CASES)
def test_metrics_recomputed_from_recorded_states(scenario, policy, options, occurring):
    env, params = sgjax.make(scenario, **options)
    episodes = 6
    out = run_episodes(env, params, policy, jax.random.key(11), episodes, record=True)
    for name in occurring:  # the comparison below is not of zeros only
        values = np.asarray(out.robot[name] if name in out.robot else out.values[name], float)
        assert np.nansum(np.abs(values)) > 0, f"{scenario}: {name} never occurs"
    for e in range(episodes):
        mine = recompute(out.states, params, e)
        for name, value in mine.items():
            where = f"{scenario} {policy} episode {e}: {name}"
            theirs = np.asarray(out.robot[name] if np.ndim(value) else out.values[name])[e]
            if np.ndim(value) == 2:  # a fraction as [R, 2] bounds (see fraction_below)
                low, high = value[:, 0], value[:, 1]
                assert np.array_equal(np.isnan(theirs), np.isnan(low)), where
                known = ~np.isnan(low)
                assert np.all(theirs[known] >= low[known] - 1e-6), (where, theirs, low)
                assert np.all(theirs[known] <= high[known] + 1e-6), (where, theirs, high)
            else:
                np.testing.assert_allclose(theirs, value, rtol=1e-5, atol=1e-5,
                                           equal_nan=True, err_msg=where)
