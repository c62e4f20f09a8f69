"""Host-side rendering with matplotlib (Agg, headless): map pictures, frames and GIFs.

Nothing here runs inside ``jit``; pass states (or slices of a stacked rollout) as arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402
from PIL import Image  # noqa: E402

from sgjax.maps.arrays import spawn_groups  # noqa: E402
from sgjax.maps.schema import MapSpec  # noqa: E402

ROBOT_COLOURS = plt.get_cmap("tab10").colors


def _figure(spec: MapSpec, width_px: int) -> tuple[plt.Figure, plt.Axes]:
    xmin, ymin, xmax, ymax = spec.bounds
    aspect = (ymax - ymin) / (xmax - xmin)
    dpi = 100
    fig = plt.figure(figsize=(width_px / dpi, max(2.0, width_px * aspect / dpi)), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.axis("off")
    return fig, ax


def _draw_map(ax: plt.Axes, spec: MapSpec, graph: bool, zones: bool) -> None:
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


def _to_rgb(fig: plt.Figure) -> np.ndarray:
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return rgb


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
) -> np.ndarray:
    """One top-down frame as an ``H x W x 3`` uint8 array.

    ``position [R, 2]``, ``heading [R]``, ``radius [R]``, ``present``/``succeeded [R]`` bool,
    ``goal [R, 2]``; ``trail [T, R, 2]`` optional recent positions. Robots are coloured by id;
    finished robots are drawn hollow at their goal. ``humans [H, 2]`` (active pedestrians only)
    are grey discs of ``human_radius`` m, with a 0.5 s velocity tick from ``human_velocity``.
    """
    fig, ax = _figure(spec, width_px)
    _draw_map(ax, spec, graph=True, zones=True)
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
        ax.add_patch(Circle(tuple(position[i]), float(radius[i]), facecolor="none" if done
                            else colour, edgecolor=colour, lw=1.5, zorder=5))
        tip = position[i] + float(radius[i]) * np.array([np.cos(heading[i]), np.sin(heading[i])])
        ax.plot([position[i, 0], tip[0]], [position[i, 1], tip[1]], color="white" if not done
                else colour, lw=1.2, zorder=6)
        ax.text(position[i, 0], position[i, 1] + float(radius[i]) * 1.4, str(i), fontsize=7,
                ha="center", zorder=6)
    if title:
        ax.text(0.01, 0.99, title, transform=ax.transAxes, va="top", fontsize=9)
    return _to_rgb(fig)


def render_state(
    spec: MapSpec, state, radius: np.ndarray, trail: np.ndarray | None = None, title: str = "",
    width_px: int = 480, human_radius: float = 0.25,
) -> np.ndarray:
    """:func:`render_frame` of one (unbatched) ``EnvState`` with its active pedestrians;
    ``radius [R]`` from ``params.robots.radius``, ``human_radius`` (m) from
    ``params.humans.radius``."""
    robots = state.robots
    goal = np.stack([np.asarray(state.route.goal_x), np.asarray(state.route.goal_y)], -1)
    active = np.asarray(state.humans.active)
    return render_frame(spec, np.asarray(robots.position), np.asarray(robots.heading),
                        np.asarray(radius), np.asarray(robots.present),
                        np.asarray(robots.succeeded), goal, trail=trail, title=title,
                        width_px=width_px, humans=np.asarray(state.humans.position)[active],
                        human_velocity=np.asarray(state.humans.velocity)[active],
                        human_radius=float(human_radius))


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
