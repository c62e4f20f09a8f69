"""A recording as a scenario (``sgjax.make("recorded:FILE", num_agents=3)``): the open space its
people walked, robots that cross it, and the recording's windows as the episodes' people
(:mod:`sgjax.humans.replay`).

The map: the rectangle the recorded people cover (every valid position), with robot start and
goal nodes on a ring :data:`NODE_MARGIN` m outside it, :data:`NODE_SPACING` m apart, each
joined to every node of the opposite side (robots cross in straight lines), and walls
:data:`WALL_MARGIN` m beyond the nodes. Four route groups send robots across the scene: west
side to east, east to west, south to north, north to south, so every robot crosses the
people's space. No obstacle of the scene is in the map: ETH/UCY annotate people, not the
buildings, benches and cars they walk around (a limitation a reader of the results must keep
in mind: a robot may cross where the people could not).

The episodes: windows of ``time_limit`` s cut from the recording every
:data:`WINDOW_STRIDE` s; a reset draws one at random, and every person of it has a slot for the
episode."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sgjax.humans.replay import Recording, recording
from sgjax.humans.tracks import Tracks, read_tracks, track_windows
from sgjax.maps.schema import MapSpec, parse_map

PREFIX = "recorded:"
NODE_MARGIN = 1.0  # m: robot starts and goals lie this far outside the recorded people's extent
NODE_SPACING = 3.0  # m between two start/goal nodes on a side
WALL_MARGIN = 1.5  # m: the scene's walls lie this far beyond the nodes
WINDOW_STRIDE = 4.0  # s between the starts of two windows


def scene_map(tracks: Tracks, name: str) -> MapSpec:
    """The open-space map of ``tracks`` (module doc), named ``name``."""
    x0, x1 = float(np.nanmin(tracks.x)), float(np.nanmax(tracks.x))
    y0, y1 = float(np.nanmin(tracks.y)), float(np.nanmax(tracks.y))
    x0, x1, y0, y1 = x0 - NODE_MARGIN, x1 + NODE_MARGIN, y0 - NODE_MARGIN, y1 + NODE_MARGIN

    def side(a: float, b: float) -> np.ndarray:
        count = max(2, int(math.floor((b - a) / NODE_SPACING)) + 1)
        return np.linspace(a, b, count + 2)[1:-1]  # corners left out: no start in two sides

    sides = {"west": [(x0, y) for y in side(y0, y1)], "east": [(x1, y) for y in side(y0, y1)],
             "south": [(x, y0) for x in side(x0, x1)], "north": [(x, y1) for x in side(x0, x1)]}
    points, rows = [], {}
    for key, where in sides.items():
        rows[key] = list(range(len(points), len(points) + len(where)))
        points.extend(where)
    wall = (x0 - WALL_MARGIN, y0 - WALL_MARGIN, x1 + WALL_MARGIN, y1 + WALL_MARGIN)
    walls = [[wall[0], wall[1], wall[2], wall[1]], [wall[2], wall[1], wall[2], wall[3]],
             [wall[2], wall[3], wall[0], wall[3]], [wall[0], wall[3], wall[0], wall[1]]]
    data = {
        "name": name,
        "description": f"recorded people of {tracks.source}: an open space of "
                       f"{x1 - x0:.1f} x {y1 - y0:.1f} m (its obstacles not annotated), robots "
                       "crossing it from side to side",
        "bounds": [wall[0] - 0.5, wall[1] - 0.5, wall[2] + 0.5, wall[3] + 0.5],
        "walls": [[round(v, 4) for v in w] for w in walls],
        "nodes": [{"id": i, "position": [round(x, 4), round(y, 4)]}
                  for i, (x, y) in enumerate(points)],
        "edges": [[a, b] for one, other in (("west", "east"), ("south", "north"))
                  for a in rows[one] for b in rows[other]],
        "groups": [{"starts": rows[a], "goals": rows[b]}
                   for a, b in (("west", "east"), ("east", "west"), ("south", "north"),
                                ("north", "south"))],
    }
    return parse_map(data, source=f"{PREFIX}{tracks.source}")


def scene_recording(tracks: Tracks, time_limit: float) -> Recording:
    """The recording's episodes: windows of ``time_limit`` s (and the row after, so the last
    step still has a row to interpolate to) every :data:`WINDOW_STRIDE` s."""
    rows = int(math.ceil(time_limit / tracks.dt)) + 1
    stride = max(1, int(round(WINDOW_STRIDE / tracks.dt)))
    return recording(track_windows(tracks, rows, stride), tracks.dt)


def read_scene(path: str | Path) -> tuple[Tracks, MapSpec]:
    """The tracks of the file ``path`` (:func:`sgjax.humans.tracks.read_tracks`: errors name
    the file and line) and its scene's map, named ``recorded:<file stem>``."""
    tracks = read_tracks(path)
    return tracks, scene_map(tracks, f"{PREFIX}{Path(path).stem}")
