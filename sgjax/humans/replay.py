"""Recorded people as the environment's pedestrians (``make("recorded:FILE",
human_replay=...)``): every episode replays one window of a recording (its people walk where
the recording has them), and robots meet them as bodies.

Three behaviours (``HumanConfig.replay``), after SocNavBench's prerecorded agents and the
hand-over that sim-to-real studies use:

* ``"ghost"``: everyone is where the recording has them at the episode's time, linearly
  interpolated between annotated rows (0.4 s apart in ETH/UCY); nobody reacts to a robot, a
  robot that touches one stops and counts a collision.
* ``"pause"``: as ghost, but a person a robot touches stops for ``HumanParams.pause_seconds``
  and then walks on along their recording from where they stopped (their own clock runs that
  much behind the scene's).
* ``"handover"``: as ghost until a robot comes within ``HumanParams.handover_radius`` of a
  person; from then on that person is simulated by the environment's force model (its
  constants in the params: the calibrated ones for a calibrated crowd) from their recorded
  position and velocity, towards the last position of their track in the window, at their
  recorded mean speed, and leaves when their track would have ended.

Every behaviour books how far people are from where the recording has them at the scene's
time (:class:`ReplayState` ``deviation``, integrated over time): the "log deviation" of
:mod:`sgjax.evaluation.metrics.recorded`, 0 in ghost mode.

Shapes: ``N`` windows, ``L`` rows per window, ``H`` pedestrian slots (the most people any
window holds: one slot per person of the window, for the whole episode)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct
from jax import Array

from sgjax.humans.tracks import TrackWindows
from sgjax.kernels.geometry import safe_norm

REPLAY_MODES = ("ghost", "pause", "handover")
FRACTION_TOLERANCE = 1e-3  # of a row: a time this close past a track's last row still shows it


@struct.dataclass
class Recording:
    """A recording cut into windows (device arrays): ``x, y, valid [N, L, H]`` (m; 0 where not
    valid), ``ids [N, H]`` (each slot's person in the file; -1: an empty slot), ``start [N]``
    (each window's first row in the recording), ``row_seconds`` (s between rows, scalar),
    ``speed [N, H]`` (each person's mean recorded speed in the window, m/s), ``end [N, H]``
    (s: the time of each person's last valid row in the window; -1 for an empty slot),
    ``goal_x, goal_y [N, H]`` (m: its position there)."""

    x: Array
    y: Array
    valid: Array
    ids: Array
    start: Array
    row_seconds: Array
    speed: Array
    end: Array
    goal_x: Array
    goal_y: Array

    @property
    def windows(self) -> int:
        return self.x.shape[0]


def recording(windows: TrackWindows, row_seconds: float) -> Recording:
    """The :class:`Recording` of ``windows`` (:func:`sgjax.humans.tracks.track_windows`, whose
    rows are ``row_seconds`` s apart)."""
    valid = jnp.asarray(windows.valid)
    rows = valid.shape[1]
    index = jnp.arange(rows)[None, :, None]
    last = jnp.max(jnp.where(valid, index, -1), axis=1)  # [N, H]
    seen = last >= 0
    pick = jnp.maximum(last, 0)[:, None, :]
    goal_x = jnp.take_along_axis(windows.x, pick, axis=1)[:, 0]
    goal_y = jnp.take_along_axis(windows.y, pick, axis=1)[:, 0]
    both = valid[:, 1:] & valid[:, :-1]
    step = jnp.hypot(jnp.diff(windows.x, axis=1), jnp.diff(windows.y, axis=1))
    moves = jnp.sum(jnp.where(both, step, 0.0), axis=1)
    count = jnp.sum(both, axis=1)
    speed = jnp.where(count > 0, moves / jnp.maximum(count, 1) / row_seconds, 0.0)
    return Recording(x=jnp.asarray(windows.x, jnp.float32), y=jnp.asarray(windows.y, jnp.float32),
                     valid=valid, ids=jnp.asarray(windows.ids), start=jnp.asarray(windows.start),
                     row_seconds=jnp.asarray(row_seconds, jnp.float32),
                     speed=speed.astype(jnp.float32),
                     end=jnp.where(seen, last * row_seconds, -1.0).astype(jnp.float32),
                     goal_x=jnp.where(seen, goal_x, 0.0).astype(jnp.float32),
                     goal_y=jnp.where(seen, goal_y, 0.0).astype(jnp.float32))


@struct.dataclass
class ReplayState:
    """One episode's replay, ``[H]`` unless noted.

    ``window`` (int32 scalar) the recording's window; ``time`` (s, scalar) the scene's time
    since the window's first row; ``clock`` each person's own time in the recording (the
    scene's time less their pauses); ``pause_left`` (s) how long each still stands;
    ``handed`` simulated by the force model from now on; ``reached`` a robot touched
    (``pause``) or came near (``handover``) them this episode; ``goal_x, goal_y`` (m) the
    last position of their track (where a handed-over person walks); ``deviation`` (m s) the
    time integral of their distance from where the recording has them at the scene's time,
    over ``exposure`` (s) the time they were in the scene and in the recording."""

    window: Array
    time: Array
    clock: Array
    pause_left: Array
    handed: Array
    reached: Array
    goal_x: Array
    goal_y: Array
    deviation: Array
    exposure: Array


def recorded_at(rec: Recording, window: Array, clock: Array
                ) -> tuple[Array, Array, Array, Array, Array]:
    """Where the recording has each person of ``window`` at their ``clock [H]`` (s): ``(x, y,
    vx, vy, present)`` ``[H]``: the linear interpolation between the two rows around the time
    (exactly a row's position at its time), the velocity of that segment (m/s; 0 on a
    person's last row), and whether the recording holds them then."""
    xs, ys, valid = rec.x[window], rec.y[window], rec.valid[window]  # [L, H]
    rows = xs.shape[0]
    at = clock / rec.row_seconds
    row = jnp.clip(jnp.floor(at), 0, rows - 1).astype(jnp.int32)
    after = jnp.minimum(row + 1, rows - 1)
    fraction = jnp.clip(at - row, 0.0, 1.0)
    person = jnp.arange(xs.shape[1])
    x0, y0, v0 = xs[row, person], ys[row, person], valid[row, person]
    x1, y1 = xs[after, person], ys[after, person]
    joined = v0 & valid[after, person] & (after > row)
    inside = (at >= -FRACTION_TOLERANCE) & (at <= rows - 1 + FRACTION_TOLERANCE)
    present = inside & v0 & (joined | (fraction <= FRACTION_TOLERANCE))
    share = jnp.where(joined, fraction, 0.0)
    vx = jnp.where(joined, (x1 - x0) / rec.row_seconds, 0.0)
    vy = jnp.where(joined, (y1 - y0) / rec.row_seconds, 0.0)
    return x0 + share * (x1 - x0), y0 + share * (y1 - y0), vx, vy, present


def start_replay(key: Array, rec: Recording) -> tuple[ReplayState, tuple[Array, ...]]:
    """A random window's replay at its first row, and its people there: ``(state, (x, y, vx,
    vy, present))``."""
    window = jax.random.randint(key, (), 0, rec.windows)
    people = rec.x.shape[2]
    zeros = jnp.zeros(people, jnp.float32)
    no = jnp.zeros(people, bool)
    state = ReplayState(window=window, time=jnp.zeros((), jnp.float32), clock=zeros,
                        pause_left=zeros, handed=no, reached=no, goal_x=rec.goal_x[window],
                        goal_y=rec.goal_y[window], deviation=zeros, exposure=zeros)
    return state, recorded_at(rec, window, zeros)


def deviation_from_recording(rec: Recording, replay: ReplayState, x: Array, y: Array,
                             active: Array) -> tuple[Array, Array]:
    """``(distance, counted) [H]``: each person's distance (m) from where the recording has
    them at the scene's time, and whether it counts (in the scene and in the recording)."""
    scene = jnp.broadcast_to(replay.time, replay.clock.shape)
    rx, ry, _, _, there = recorded_at(rec, replay.window, scene)
    counted = active & there
    return jnp.where(counted, safe_norm(x - rx, y - ry), 0.0), counted


def walking_target(m, humans) -> tuple[Array, Array]:
    """``(x, y) [H]`` (m): where each pedestrian walks: its target node on map ``m``
    (:class:`~sgjax.maps.arrays.MapArrays`), or, for replayed people (``humans.replay`` set),
    the last position of their track (a handed-over person's way)."""
    if humans.replay is not None:
        return humans.replay.goal_x, humans.replay.goal_y
    return m.node_x[humans.target], m.node_y[humans.target]
