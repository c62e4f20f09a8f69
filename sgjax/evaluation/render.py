"""Host-side rendering with matplotlib: map pictures, frames, animations (GIF with pillow, MP4
with ffmpeg when it is installed) and trajectory plots. Every figure is drawn by its own Agg
canvas (headless), so importing this module neither needs pyplot nor changes matplotlib's
backend.

Nothing here runs inside ``jit``; pass states (or slices of a stacked rollout) as arrays.
Robots are coloured by id; their outline says their status: white while driving, red while in
contact (a collision), hollow once arrived, grey with a cross once ended by an ender.
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import jax
import matplotlib
import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle
from PIL import Image

from sgjax.maps.arrays import FAR, spawn_groups
from sgjax.maps.schema import MapSpec, Zone

ROBOT_COLOURS = matplotlib.colormaps["tab10"].colors
CONTACT_COLOUR = "#e31a1c"
ENDED_COLOUR = "#7f7f7f"


def _figure(spec: MapSpec, width_px: int) -> tuple[Figure, Axes]:
    xmin, ymin, xmax, ymax = spec.bounds
    aspect = (ymax - ymin) / (xmax - xmin)
    dpi = 100
    fig = Figure(figsize=(width_px / dpi, max(2.0, width_px * aspect / dpi)), dpi=dpi)
    FigureCanvasAgg(fig)  # its own canvas: no pyplot, no global backend
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.axis("off")
    return fig, ax


def _draw_map(ax: Axes, spec: MapSpec, graph: bool, zones: bool) -> None:
    if zones:
        for zone in spec.zones:
            x0, y0, x1, y1 = zone.rect
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, color="#ffe9a8", zorder=0))
    if graph and len(spec.edges):
        pos = spec.node_positions
        segments = np.stack([pos[spec.edges[:, 0]], pos[spec.edges[:, 1]]], axis=1)
        ax.add_collection(LineCollection(segments, colors="#c9d6e8", linewidths=0.6, zorder=1))
        ax.scatter(pos[:, 0], pos[:, 1], s=4, color="#9fb3cf", zorder=1)
    if len(spec.walls):
        walls = spec.walls.reshape(-1, 2, 2)
        ax.add_collection(LineCollection(walls, colors="black", linewidths=2.0, zorder=3))


class MapCanvas:
    """A figure with ``spec``'s map drawn (zones, walls and, with ``graph``, the navigation
    graph), for drawing many frames over it: :func:`render_frame` with ``canvas=`` adds a
    frame's robots and pedestrians, rasterises, and removes them again. Drawing the map and
    making the figure once per episode instead of once per frame makes a GIF several times
    faster to draw."""

    def __init__(self, spec: MapSpec, width_px: int = 480, graph: bool = True):
        self.spec = spec
        self.fig, self.ax = _figure(spec, width_px)
        _draw_map(self.ax, spec, graph=graph, zones=True)
        self.fig.canvas.draw()
        self.background = self.fig.canvas.copy_from_bbox(self.fig.bbox)

    def rasterise(self, artists: Sequence[Artist]) -> np.ndarray:
        """The map with ``artists`` (added to :attr:`ax` after the map) drawn over it in
        z-order, as a full redraw would draw them (blitted: only they are drawn), as an
        ``H x W x 3`` uint8 array."""
        canvas = self.fig.canvas
        canvas.restore_region(self.background)
        for artist in sorted(artists, key=lambda a: a.get_zorder()):
            self.ax.draw_artist(artist)
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _to_rgb(fig: Figure) -> np.ndarray:
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def draw_scenario(spec: MapSpec, width_px: int = 480) -> np.ndarray:
    """Picture of a map: walls, navigation graph, conflict zones, starts (green) and goals (red).
    Returns an ``H x W x 3`` uint8 array."""
    fig, ax = _figure(spec, width_px)
    _draw_map(ax, spec, graph=True, zones=True)
    starts = sorted({s for group, _ in spawn_groups(spec) for s in group})
    goals = sorted({g for _, group in spawn_groups(spec) for g in group})
    pos = spec.node_positions
    ax.scatter(pos[goals, 0], pos[goals, 1], s=22, marker="x", color="#d62728", zorder=4)
    ax.scatter(pos[starts, 0], pos[starts, 1], s=14, color="#2ca02c", zorder=5)
    ax.text(0.01, 0.99, spec.name, transform=ax.transAxes, va="top", fontsize=10)
    return _to_rgb(fig)


def render_frame(
    spec: MapSpec,
    position: np.ndarray,
    heading: np.ndarray,
    radius: np.ndarray,
    present: np.ndarray,
    succeeded: np.ndarray,
    goal: np.ndarray,
    trail: np.ndarray | None = None,
    title: str = "",
    width_px: int = 480,
    humans: np.ndarray | None = None,
    human_velocity: np.ndarray | None = None,
    human_radius: float = 0.25,
    touching: np.ndarray | None = None,
    ended: np.ndarray | None = None,
    graph: bool = True,
    canvas: MapCanvas | None = None,
) -> np.ndarray:
    """One top-down frame as an ``H x W x 3`` uint8 array.

    ``position [R, 2]``, ``heading [R]``, ``radius [R]``, ``present``/``succeeded [R]`` bool,
    ``goal [R, 2]``; ``trail [T, R, 2]`` optional recent positions; ``touching [R]`` (in contact
    now) and ``ended [R]`` (ended without arriving) bool, optional. Robots are coloured by id
    (status in the outline, see the module doc). ``humans [H, 2]`` (active pedestrians only)
    are grey discs of ``human_radius`` m, with a 0.5 s velocity tick from ``human_velocity``.
    ``graph`` draws the navigation graph. ``canvas``: a :class:`MapCanvas` of ``spec`` to draw
    on (its map drawn once for many frames; ``width_px`` and ``graph`` are then its own).
    """
    own = canvas is None
    canvas = MapCanvas(spec, width_px, graph) if own else canvas
    ax = canvas.ax
    before = set(ax.get_children())
    if humans is not None:
        for k, centre in enumerate(humans):
            ax.add_patch(Circle(tuple(centre), human_radius, facecolor="#9e9e9e",
                                edgecolor="#505050", lw=0.6, zorder=3))
            if human_velocity is not None:
                tip = centre + 0.5 * human_velocity[k]
                ax.plot([centre[0], tip[0]], [centre[1], tip[1]], color="#505050", lw=0.8,
                        zorder=3)
    for i in np.flatnonzero(present):
        colour = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
        if trail is not None:
            ax.plot(trail[:, i, 0], trail[:, i, 1], color=colour, alpha=0.5, lw=1.0, zorder=4)
        ax.scatter([goal[i, 0]], [goal[i, 1]], marker="x", s=40, color=colour, zorder=4)
        done = bool(succeeded[i])
        stopped = ended is not None and bool(ended[i])
        contact = touching is not None and bool(touching[i]) and not done
        face = "none" if done else (ENDED_COLOUR if stopped else colour)
        edge = CONTACT_COLOUR if contact else colour
        ax.add_patch(Circle(tuple(position[i]), float(radius[i]), facecolor=face,
                            edgecolor=edge, lw=2.5 if contact else 1.5, zorder=5))
        tip = position[i] + float(radius[i]) * np.array([np.cos(heading[i]), np.sin(heading[i])])
        ax.plot([position[i, 0], tip[0]], [position[i, 1], tip[1]], color="white" if not done
                else colour, lw=1.2, zorder=6)
        if stopped:
            ax.scatter([position[i, 0]], [position[i, 1]], marker="x", s=30, color="black",
                       zorder=6)
        ax.text(position[i, 0], position[i, 1] + float(radius[i]) * 1.4, str(i), fontsize=7,
                ha="center", zorder=6)
    if title:
        ax.text(0.01, 0.99, title, transform=ax.transAxes, va="top", fontsize=9)
    if own:
        return _to_rgb(canvas.fig)
    added = [a for a in ax.get_children() if a not in before]
    frame = canvas.rasterise(added)
    for artist in added:  # leave the map for the next frame
        artist.remove()
    return frame


def render_state(
    spec: MapSpec, state, radius: np.ndarray, trail: np.ndarray | None = None, title: str = "",
    width_px: int = 480, human_radius: float = 0.25, graph: bool = True,
    canvas: MapCanvas | None = None,
) -> np.ndarray:
    """:func:`render_frame` of one (unbatched) ``EnvState`` with its active pedestrians;
    ``radius [R]`` from ``params.robots.radius``, ``human_radius`` (m) from
    ``params.humans.radius``; ``canvas`` as there."""
    robots = state.robots
    touching = (np.asarray(state.touching_robot) | np.asarray(state.touching_wall)
                | np.asarray(state.touching_human))
    goal = np.stack([np.asarray(state.route.goal_x), np.asarray(state.route.goal_y)], -1)
    active = np.asarray(state.humans.active)
    return render_frame(spec, np.asarray(robots.position), np.asarray(robots.heading),
                        np.asarray(radius), np.asarray(robots.present),
                        np.asarray(robots.succeeded), goal, trail=trail, title=title,
                        width_px=width_px, humans=np.asarray(state.humans.position)[active],
                        human_velocity=np.asarray(state.humans.velocity)[active],
                        human_radius=float(human_radius), touching=touching,
                        ended=np.asarray(robots.ended), graph=graph, canvas=canvas)


def save_gif(frames: Sequence[np.ndarray], path: str | Path, fps: int = 10) -> Path:
    """Write frames (``H x W x 3`` uint8) to an animated GIF with pillow."""
    if not frames:
        raise ValueError("save_gif: no frames to write")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    images = [Image.fromarray(np.asarray(f)) for f in frames]
    images[0].save(path, save_all=True, append_images=images[1:], duration=int(1000 / fps),
                   loop=0, optimize=False)
    return path


def save_mp4(frames: Sequence[np.ndarray], path: str | Path, fps: int = 10) -> Path:
    """Write frames (``H x W x 3`` uint8) to an H.264 MP4 by piping them to ``ffmpeg``."""
    if not frames:
        raise ValueError("save_mp4: no frames to write")
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is None:
        raise RuntimeError(f"save_mp4: writing {path} needs ffmpeg on the PATH, which was not "
                           "found; install ffmpeg or write a .gif instead")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    height, width = frames[0].shape[:2]
    command = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
               "-s", f"{width}x{height}", "-r", str(fps), "-i", "-",
               "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-pix_fmt", "yuv420p", str(path)]
    data = b"".join(np.ascontiguousarray(f, np.uint8).tobytes() for f in frames)
    result = subprocess.run(command, input=data, capture_output=True, check=False)
    if result.returncode != 0:
        raise RuntimeError(f"save_mp4: ffmpeg failed writing {path}: "
                           f"{result.stderr.decode(errors='replace').strip()}")
    return path


def save_animation(frames: Sequence[np.ndarray], path: str | Path, fps: int = 10) -> Path:
    """Write frames to ``path``: ``.gif`` (pillow) or ``.mp4`` (ffmpeg)."""
    suffix = Path(path).suffix.lower()
    if suffix == ".gif":
        return save_gif(frames, path, fps)
    if suffix == ".mp4":
        return save_mp4(frames, path, fps)
    raise ValueError(f"animation path {str(path)!r}: the file name must end in .gif or .mp4")


def episode_frames(
    spec: MapSpec, states, params, length: int, title: str = "", width_px: int = 480,
    max_frames: int = 300, trail_steps: int = 15,
) -> tuple[list[np.ndarray], int]:
    """Frames of one recorded episode: ``states`` stacked ``[T, ...]`` (one environment, step
    0 first) of which the first ``length + 1`` are drawn, every ``stride``-th so that at most
    ``max_frames`` remain. Returns ``(frames, stride)``."""
    count = min(length + 1, int(np.shape(states.time)[0]))
    stride = max(1, -(-count // max_frames))
    positions = np.stack([np.asarray(states.robots.x[:count]),
                          np.asarray(states.robots.y[:count])], axis=-1)  # [T, R, 2]
    radius = np.asarray(params.robots.radius)
    dt = float(params.dt)
    canvas = MapCanvas(spec, width_px)
    frames = []
    for t in range(0, count, stride):
        state = _index(states, t)
        label = f"{title}  t = {t * dt:.1f} s" if title else f"t = {t * dt:.1f} s"
        frames.append(render_state(spec, state, radius,
                                   trail=positions[max(0, t - trail_steps):t + 1], title=label,
                                   human_radius=float(np.asarray(params.humans.radius)),
                                   canvas=canvas))
    return frames, stride


def plot_trajectories(
    spec: MapSpec, states, params, length: int, title: str = "", width_px: int = 640,
) -> np.ndarray:
    """A picture of a whole recorded episode (``states`` as in :func:`episode_frames`): each
    robot's path from its start (dot) to where it ended (its disc: hollow if it arrived, grey
    with a cross if ended), its goal (x), and the pedestrians' paths in grey. RGB uint8."""
    count = min(length + 1, int(np.shape(states.time)[0]))
    x, y = np.asarray(states.robots.x[:count]), np.asarray(states.robots.y[:count])
    last = _index(states, count - 1)
    robots = last.robots
    present = np.asarray(robots.present)
    radius = np.asarray(params.robots.radius)
    goal = np.stack([np.asarray(last.route.goal_x), np.asarray(last.route.goal_y)], -1)
    fig, ax = _figure(spec, width_px)
    _draw_map(ax, spec, graph=False, zones=True)
    humans_active = np.asarray(states.humans.active[:count])
    if humans_active.size:
        hx, hy = np.asarray(states.humans.x[:count]), np.asarray(states.humans.y[:count])
        for k in np.flatnonzero(humans_active.any(axis=0)):
            seen = humans_active[:, k]
            ax.plot(hx[seen, k], hy[seen, k], color="#9e9e9e", lw=0.8, alpha=0.7, zorder=2)
    for i in np.flatnonzero(present):
        colour = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
        ax.plot(x[:, i], y[:, i], color=colour, lw=1.6, zorder=4)
        ax.scatter([x[0, i]], [y[0, i]], s=18, color=colour, zorder=5)
        ax.scatter([goal[i, 0]], [goal[i, 1]], marker="x", s=40, color=colour, zorder=4)
        arrived, ended = bool(robots.succeeded[i]), bool(robots.ended[i])
        face = "none" if arrived else (ENDED_COLOUR if ended else colour)
        ax.add_patch(Circle((x[-1, i], y[-1, i]), float(radius[i]), facecolor=face,
                            edgecolor=colour, lw=1.5, zorder=5))
        ax.text(x[0, i], y[0, i] + float(radius[i]) * 1.4, str(i), fontsize=7, ha="center",
                zorder=6)
    label = f"{title}  {count - 1} steps" if title else f"{count - 1} steps"
    ax.text(0.01, 0.99, label, transform=ax.transAxes, va="top", fontsize=9)
    return _to_rgb(fig)


def save_png(image: np.ndarray, path: str | Path) -> Path:
    """Write an ``H x W x 3`` uint8 image as PNG (pillow)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.asarray(image, np.uint8)).save(path)
    return path


def _index(tree, t: int):
    """Step ``t`` of a stacked pytree."""
    return jax.tree.map(lambda leaf: leaf[t], tree)


def drawing_of_arrays(arrays: Any, name: str) -> MapSpec:
    """A map to draw from one episode's map arrays (a generated world's, say: ``state.world.map``
    of one episode, host or device): its valid walls, the graph's edges (node pairs one hop
    apart on some route), the groups and the zones within reach; bounds around the walls. For
    drawing only: nothing is validated."""
    a = jax.tree.map(np.asarray, arrays)
    walls = np.stack([a.wall_x1, a.wall_y1, a.wall_x2, a.wall_y2], -1)[a.wall_valid]
    nodes = np.stack([a.node_x, a.node_y], -1)
    count = len(nodes)
    hop = a.next_hop
    rows = np.arange(count)
    direct = (hop == rows[None, :]) & (rows[:, None] != rows[None, :])
    i, j = np.nonzero(np.triu(direct | direct.T, 1))
    xy = walls.reshape(-1, 2)
    lo, hi = xy.min(axis=0) - 0.5, xy.max(axis=0) + 0.5
    zones = tuple(Zone(f"zone {k}", tuple(float(v) for v in r))
                  for k, r in enumerate(a.zone_rect) if np.all(np.abs(r) < FAR / 2))
    groups = tuple((tuple(np.flatnonzero(s).tolist()), tuple(np.flatnonzero(g).tolist()))
                   for s, g in zip(a.group_starts, a.group_goals, strict=True) if s.any())
    return MapSpec(name=name, description="", bounds=(float(lo[0]), float(lo[1]),
                                                      float(hi[0]), float(hi[1])),
                   walls=walls, node_ids=rows, node_positions=nodes,
                   edges=np.stack([i, j], 1).astype(int), groups=groups,
                   routes=(), zones=zones)


def recorded_map(scenario: Any, states: Any) -> MapSpec:
    """The map one recorded episode (``states [T + 1, ...]``) played on: a generated world's
    (from its first state), a recording's open space (``recorded:FILE``) or the scenario's map
    file."""
    from sgjax.humans.recorded_scene import PREFIX as RECORDED
    from sgjax.humans.recorded_scene import read_scene
    from sgjax.maps.io import load

    world = getattr(states, "world", None)
    if world is not None:
        first = jax.tree.map(lambda leaf: leaf[0], world.map)
        return drawing_of_arrays(first, str(scenario))
    if isinstance(scenario, str) and scenario.startswith(RECORDED):
        return read_scene(scenario[len(RECORDED):])[1]
    return load(scenario)
