"""Draw one moment of an sgjax episode MCAP file from the file's own contents, top-down, as
Foxglove's 3D panel shows it from above: walls, graph and conflict zones (``/map``), robots
with heading and remaining route (``/robots``), pedestrians (``/pedestrians``) and every
robot's lidar returns placed by ``/tf`` (``/robot_i/scan``).

    python examples/mcap_picture.py episode.mcap --time 6.0 --out picture.png

Reads with ``mcap``'s reader and ``mcap_protobuf``'s decoder (pip install -e ".[robotics]");
nothing of sgjax is imported, so the picture shows what any MCAP reader finds in the file."""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any


def read(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """``{topic: [(log time ns, decoded message)]}``."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    factory, out = DecoderFactory(), defaultdict(list)
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            value = (json.loads(message.data) if channel.message_encoding == "json"
                     else factory.decoder_for(channel.message_encoding, schema)(message.data))
            out[channel.topic].append((message.log_time, value))
    return out


def at(messages: list[tuple[int, Any]], nanos: int) -> Any:
    """The last message logged at or before ``nanos``."""
    before = [m for t, m in messages if t <= nanos]
    return before[-1] if before else messages[0][1]


def rgba(color: Any) -> tuple[float, float, float, float]:
    return color.r, color.g, color.b, color.a


def yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def draw(topics: dict[str, list[tuple[int, Any]]], seconds: float, title: str) -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, FancyArrow, Rectangle

    nanos = round(seconds * 1e9)
    fig, ax = plt.subplots(figsize=(8, 6), dpi=110)
    ax.set_facecolor("#1f2430")
    for entity in at(topics["/map"], 0).entities:
        for line in entity.lines:
            xs, ys = [p.x for p in line.points], [p.y for p in line.points]
            for k in range(0, len(xs) - 1, 2):
                ax.plot(xs[k:k + 2], ys[k:k + 2], color="#e8e8e8" if entity.id == "walls"
                        else "#6c7a96", lw=2.0 if entity.id == "walls" else 0.6)
        for cube in entity.cubes:
            p, s = cube.pose.position, cube.size
            ax.add_patch(Rectangle((p.x - s.x / 2, p.y - s.y / 2), s.x, s.y,
                                   color=rgba(cube.color)))
    transforms = {f.child_frame_id: f for f in at(topics["/tf"], nanos).transforms}
    for topic in sorted(t for t in topics if t.endswith("/scan")):
        scan = at(topics[topic], nanos)
        frame = transforms.get(scan.frame_id)
        if frame is None:
            continue
        heading = yaw(frame.rotation)
        step = (scan.end_angle - scan.start_angle) / max(len(scan.ranges) - 1, 1)
        points = [(frame.translation.x + r * math.cos(heading + scan.start_angle + k * step),
                   frame.translation.y + r * math.sin(heading + scan.start_angle + k * step))
                  for k, r in enumerate(scan.ranges) if r < 9.99]
        if points:
            ax.scatter(*zip(*points, strict=True), s=3, color="#ff9f43", zorder=3)
    for entity in at(topics["/pedestrians"], nanos).entities:
        for c in entity.cylinders:
            ax.add_patch(Circle((c.pose.position.x, c.pose.position.y), c.size.x / 2,
                                color="#b8bcc8", zorder=4))
    for entity in at(topics["/robots"], nanos).entities:
        for line in entity.lines:
            ax.plot([p.x for p in line.points], [p.y for p in line.points], color="#5b8def",
                    lw=1.0, ls="--", zorder=2)
        body, goal = entity.cylinders[0], entity.cylinders[1]
        ax.add_patch(Circle((goal.pose.position.x, goal.pose.position.y), 0.15,
                            color="#5b8def", zorder=2))
        ax.add_patch(Circle((body.pose.position.x, body.pose.position.y), body.size.x / 2,
                            color=rgba(body.color), zorder=5))
        for arrow in entity.arrows:
            h = yaw(arrow.pose.orientation)
            ax.add_patch(FancyArrow(arrow.pose.position.x, arrow.pose.position.y,
                                    arrow.shaft_length * math.cos(h),
                                    arrow.shaft_length * math.sin(h), width=0.04,
                                    color="#111111", zorder=6))
    step = at(topics["/step"], nanos)
    rewards = step.get("reward")
    ax.set_title(f"{title}  t = {step['time']:.1f} s" + (
        "  rewards " + ", ".join(f"{r:+.2f}" for r in rewards) if rewards else ""), fontsize=9)
    ax.set_aspect("equal")
    ax.autoscale_view()
    fig.tight_layout()
    return fig


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mcap", type=Path)
    parser.add_argument("--time", type=float, default=None,
                        help="simulation time to draw (s; default the episode's middle)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    topics = read(args.mcap)
    last = topics["/step"][-1][0] / 1e9
    seconds = last / 2 if args.time is None else args.time
    fig = draw(topics, seconds, args.mcap.name)
    fig.savefig(args.out)
    print(f"wrote {args.out} ({args.mcap.name} at {seconds:.1f} s of {last:.1f} s)")


if __name__ == "__main__":
    main()
