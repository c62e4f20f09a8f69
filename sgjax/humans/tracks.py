"""Recorded pedestrian tracks: the ``frame id x y`` text files of ETH/UCY (and of sgjax's own
rollouts, so a simulated crowd is a track file too), read with errors naming the file and line,
held as padded arrays (time x pedestrians with a validity mask) and cut into windows that
``vmap`` turns into a batch of episodes.

The format: one observation per line, ``frame pedestrian_id x y`` separated by tabs or spaces
(floats; frame numbers and ids whole), positions in metres in the scene's world frame, rows in
order of frame. The annotated frames of ETH/UCY are 10 frame numbers (0.4 s) apart, with a few
longer gaps; each pedestrian appears for a contiguous run of annotated frames. The project
never downloads the data: a user points :func:`read_tracks` at their own copy.

The time axis of :class:`Tracks` is the regular grid of the file's usual frame step (its most
common difference between annotated frames): a row of the grid with no annotation (a longer
gap) holds no valid position, so a window that needs a pedestrian across it sees the hole."""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from pathlib import Path

import jax.numpy as jnp
import numpy as np
from flax import struct
from jax import Array

from sgjax.files import write_atomic

DEFAULT_STEP_SECONDS = 0.4  # s between annotated frames in ETH/UCY (10 frame numbers at 25 Hz)


class TrackFileError(ValueError):
    """A track file that cannot be read as tracks; the message names the file and line."""


@dataclasses.dataclass(frozen=True)
class Tracks:
    """One recording on a regular time grid (host arrays).

    ``frames [T]`` the frame number of each row (``first + t * frame_step``); ``ids [P]`` the
    pedestrians' ids in order of first appearance; ``x, y [T, P]`` positions (m, NaN where not
    annotated) and ``valid [T, P]``; ``dt`` seconds per row; ``source`` the file."""

    frames: np.ndarray
    ids: np.ndarray
    x: np.ndarray
    y: np.ndarray
    valid: np.ndarray
    dt: float
    source: str

    @property
    def frame_step(self) -> int:
        return int(self.frames[1] - self.frames[0]) if self.frames.shape[0] > 1 else 1


def _numbers(path: Path) -> np.ndarray:
    """``[N, 5]`` float64: each row's line number and its four numbers; a TrackFileError names
    the first bad line."""
    rows = []
    with open(path, encoding="utf-8") as lines:
        for number, line in enumerate(lines, 1):
            fields = line.split()
            if not fields:
                continue
            if len(fields) != 4:
                raise TrackFileError(f"{path}:{number}: {len(fields)} fields, expected 4 "
                                     f"(frame pedestrian_id x y): {line.strip()!r}")
            try:
                row = [float(f) for f in fields]
            except ValueError:
                bad = next(f for f in fields if not _is_float(f))
                raise TrackFileError(f"{path}:{number}: {bad!r} is not a number "
                                     "(frame pedestrian_id x y)") from None
            if not all(math.isfinite(v) for v in row):
                raise TrackFileError(f"{path}:{number}: a field is not finite: {line.strip()!r}")
            for name, value in (("frame", row[0]), ("pedestrian_id", row[1])):
                if value != round(value):
                    raise TrackFileError(f"{path}:{number}: {name} {value:g} is not a whole "
                                         "number")
            rows.append((number, *row))
    if not rows:
        raise TrackFileError(f"{path}: no observations")
    return np.asarray(rows, np.float64)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _check_order(path: Path, rows: np.ndarray) -> None:
    """Frames never decrease, no (frame, id) twice, and every pedestrian's annotated frames
    are contiguous among the file's annotated frames."""
    line, frame, ident = rows[:, 0].astype(int), rows[:, 1].astype(int), rows[:, 2].astype(int)
    back = np.flatnonzero(np.diff(frame) < 0)
    if back.size:
        i = back[0] + 1
        raise TrackFileError(f"{path}:{line[i]}: frame {frame[i]} after frame {frame[i - 1]} "
                             "(rows must be in order of frame)")
    seen: dict[tuple[int, int], int] = {}
    for i in range(rows.shape[0]):
        key = (frame[i], ident[i])
        if key in seen:
            raise TrackFileError(f"{path}:{line[i]}: pedestrian {ident[i]} at frame {frame[i]} "
                                 f"again (first on line {seen[key]})")
        seen[key] = line[i]
    annotated = np.unique(frame)
    place = np.searchsorted(annotated, frame)
    last: dict[int, tuple[int, int]] = {}  # id -> (place of its last frame, its line)
    for i in range(rows.shape[0]):
        before = last.get(ident[i])
        if before is not None and place[i] != before[0] + 1:
            raise TrackFileError(
                f"{path}:{line[i]}: pedestrian {ident[i]} reappears at frame {frame[i]} after "
                f"leaving at frame {annotated[before[0]]} (line {before[1]}); a pedestrian's "
                "frames must be contiguous")
        last[ident[i]] = (place[i], line[i])


def read_tracks(path: str | Path, step_seconds: float = DEFAULT_STEP_SECONDS) -> Tracks:
    """The tracks of a ``frame id x y`` file (module doc). ``step_seconds``: the time between
    two annotated frames of the file's usual step (ETH/UCY: 0.4 s). A TrackFileError names
    the file and line of a row that is not four numbers, a frame number or id that is not
    whole, a frame before the one above it, a pedestrian twice in one frame, or a pedestrian
    that reappears after leaving; a frame off the file's grid is named too."""
    path = Path(path)
    if not path.is_file():
        raise TrackFileError(f"{path}: no such track file")
    if not step_seconds > 0.0:
        raise ValueError(f"step_seconds must be > 0 s, got {step_seconds}")
    rows = _numbers(path)
    _check_order(path, rows)
    line, frame, ident = rows[:, 0].astype(int), rows[:, 1].astype(int), rows[:, 2].astype(int)
    annotated = np.unique(frame)
    gaps = np.diff(annotated)
    step = Counter(gaps.tolist()).most_common(1)[0][0] if gaps.size else 1
    off_grid = np.flatnonzero((frame - annotated[0]) % step)
    if off_grid.size:
        i = off_grid[0]
        raise TrackFileError(f"{path}:{line[i]}: frame {frame[i]} is off the file's grid of "
                             f"{step} frames from frame {annotated[0]}")
    order = list(dict.fromkeys(ident.tolist()))  # first appearance
    column = {pid: c for c, pid in enumerate(order)}
    count = (annotated[-1] - annotated[0]) // step + 1
    x = np.full((count, len(order)), np.nan, np.float32)
    y = np.full((count, len(order)), np.nan, np.float32)
    t = (frame - annotated[0]) // step
    cols = np.asarray([column[i] for i in ident.tolist()])
    x[t, cols], y[t, cols] = rows[:, 3], rows[:, 4]
    return Tracks(frames=annotated[0] + step * np.arange(count), ids=np.asarray(order),
                  x=x, y=y, valid=~np.isnan(x), dt=float(step_seconds), source=str(path))


def tracks_text(frames: np.ndarray, ids: np.ndarray, x: np.ndarray, y: np.ndarray,
                valid: np.ndarray) -> str:
    """The ``frame id x y`` text of positions ``x, y [T, P]`` (m) where ``valid [T, P]``, at
    frame numbers ``frames [T]`` for pedestrians ``ids [P]`` (tab-separated, in order of
    frame, as ETH/UCY write them)."""
    lines = []
    for t in range(frames.shape[0]):
        for p in np.flatnonzero(valid[t]):
            lines.append(f"{int(frames[t])}\t{int(ids[p])}\t{float(x[t, p]):.4f}\t"
                         f"{float(y[t, p]):.4f}")
    return "\n".join(lines) + "\n"


def write_rollout_tracks(path: str | Path, x: np.ndarray, y: np.ndarray, active: np.ndarray,
                         frame_step: int = 10) -> Path:
    """A rollout's pedestrians as a track file (:func:`read_tracks` reads it back): positions
    ``x, y [T, H]`` (m) of every step, ``active [T, H]`` where a pedestrian is in the scene;
    row ``t`` is frame ``t * frame_step``, pedestrian ``h`` id ``h``. A pedestrian that leaves
    and comes back (an episode's respawn) would break the format's contiguity: a ValueError
    names it."""
    x, y, active = np.asarray(x), np.asarray(y), np.asarray(active, bool)
    if not x.shape == y.shape == active.shape or x.ndim != 2:
        raise ValueError(f"x, y and active must share a [T, H] shape, got {x.shape}, "
                         f"{y.shape}, {active.shape}")
    starts = np.sum(np.diff(active.astype(np.int8), axis=0) == 1, axis=0) + active[0]
    back = np.flatnonzero(starts > 1)
    if back.size:
        raise ValueError(f"pedestrian {back[0]} enters the rollout {int(starts[back[0]])} times; "
                         "a track file holds one contiguous run per id")
    frames = frame_step * np.arange(x.shape[0])
    return write_atomic(path, tracks_text(frames, np.arange(x.shape[1]), x, y, active))


@struct.dataclass
class TrackWindows:
    """Windows of ``L`` rows cut from tracks (device arrays, ``N`` windows): ``x, y [N, L,
    Pw]`` (m, 0 where not valid), ``valid [N, L, Pw]``, ``ids [N, Pw]`` (-1 for padding),
    ``start [N]`` the first row of each window in the recording. ``Pw`` is the most
    pedestrians any window holds (static: every window padded to it)."""

    x: Array
    y: Array
    valid: Array
    ids: Array
    start: Array


def track_windows(tracks: Tracks, length: int, stride: int = 1,
                  whole: bool = False) -> TrackWindows:
    """Every window of ``length`` rows starting every ``stride`` rows, with the pedestrians
    seen in it (in order of first appearance); ``whole`` keeps only the pedestrians present in
    every row of the window (the forecasting protocol's fully observed tracks, e.g. 8 observed
    + 12 predicted = 20 rows). Windows with no pedestrian are left out."""
    if length < 1 or stride < 1:
        raise ValueError(f"length and stride must be >= 1, got {length} and {stride}")
    rows = tracks.valid.shape[0]
    if length > rows:
        raise ValueError(f"{tracks.source}: windows of {length} rows, the recording has {rows}")
    picked = []
    for start in range(0, rows - length + 1, stride):
        block = tracks.valid[start:start + length]
        keep = np.flatnonzero(block.all(axis=0) if whole else block.any(axis=0))
        if keep.size:
            picked.append((start, keep))
    if not picked:
        raise ValueError(f"{tracks.source}: no window of {length} rows holds a pedestrian"
                         + (" in every row" if whole else ""))
    width = max(keep.size for _, keep in picked)
    count = len(picked)
    x = np.zeros((count, length, width), np.float32)
    y = np.zeros((count, length, width), np.float32)
    valid = np.zeros((count, length, width), bool)
    ids = np.full((count, width), -1, np.int32)
    for n, (start, keep) in enumerate(picked):
        block = slice(start, start + length)
        v = tracks.valid[block][:, keep]
        valid[n, :, :keep.size] = v
        x[n, :, :keep.size] = np.where(v, tracks.x[block][:, keep], 0.0)
        y[n, :, :keep.size] = np.where(v, tracks.y[block][:, keep], 0.0)
        ids[n, :keep.size] = tracks.ids[keep]
    return TrackWindows(x=jnp.asarray(x), y=jnp.asarray(y), valid=jnp.asarray(valid),
                        ids=jnp.asarray(ids), start=jnp.asarray([s for s, _ in picked],
                                                                jnp.int32))
