"""Write the shipped maps (``maps/*.json``) from SocialGym 2.0's mini-game geometry.

Geometry and node ids follow ``shared/reference/socialgym2.md`` §3.3. Where SocialGym's graph left
spawn nodes unconnected (its planner projected starts onto the nearest edge), every spawn and goal
node gets an edge to its hub so that routes are graph paths. Run ``python scripts/make_maps.py``.
"""

from __future__ import annotations

import json
from pathlib import Path

OUT = Path(__file__).resolve().parent.parent / "maps"


def half_diamond(cx: float, side: int, first_id_order: list[int]) -> list[dict]:
    """21 nodes on |x - cx| + |y| = 5 on the side of the hub facing away from the door.

    x runs from the far apex (cx + 5 side) toward the hub in 0.5 m steps, both y signs.
    """
    points = [(cx + 5.0 * side, 0.0)]
    for k in range(1, 11):
        x = cx + side * (5.0 - 0.5 * k)
        y = 5.0 - abs(x - cx)
        points += [(x, y), (x, -y)]
    return [{"id": i, "position": [round(p[0], 3), round(p[1], 3)]}
            for i, p in zip(first_id_order, points, strict=True)]


def two_rooms(name: str, description: str, half_gap: float, half_width: float, hub_x: float,
              starts: list[int], goals: list[int], hubs: tuple[int, int], zone: str) -> dict:
    """Two 12 m tall rooms (x out to +-half_width) joined by a 1 m wide channel from -half_gap
    to half_gap; spawns on a half-diamond around the left hub, goals around the right one."""
    g, w = half_gap, half_width
    walls = [[-w, -6, -g, -6], [-w, 6, -g, 6], [-w, -6, -w, 6],
             [-g, 0.5, -g, 6], [-g, -6, -g, -0.5],
             [-g, 0.5, g, 0.5], [-g, -0.5, g, -0.5],
             [g, 0.5, g, 6], [g, -6, g, -0.5],
             [g, -6, w, -6], [g, 6, w, 6], [w, -6, w, 6]]
    nodes = (half_diamond(-hub_x, -1, starts) + half_diamond(hub_x, 1, goals)
             + [{"id": hubs[0], "position": [-hub_x, 0.0]},
                {"id": hubs[1], "position": [hub_x, 0.0]}])
    edges = ([[s, hubs[0]] for s in starts] + [[hubs[0], hubs[1]]]
             + [[hubs[1], t] for t in goals])
    return {
        "name": name,
        "description": description,
        "bounds": [-w - 0.5, -6.5, w + 0.5, 6.5],
        "walls": walls,
        "nodes": sorted(nodes, key=lambda n: n["id"]),
        "edges": edges,
        "groups": [{"starts": starts, "goals": goals}],
        "zones": [{"name": zone, "rect": [-hub_x, -1.0, hub_x, 1.0]}],
    }


def doorway() -> dict:
    return two_rooms(
        "doorway", "SocialGym 2.0 doorway: two 9.5 m x 12 m rooms joined by a 1 m wide, "
        "1 m long door; robots cross left to right.", half_gap=0.5, half_width=10.0, hub_x=2.0,
        starts=[0, 43] + list(range(1, 20)), goals=list(range(22, 43)), hubs=(20, 21), zone="door")


def hallway() -> dict:
    return two_rooms(
        "hallway", "SocialGym 2.0 hallway: two 9 m x 12 m rooms joined by a 1 m wide, 6 m long "
        "corridor; robots cross left to right.", half_gap=3.0, half_width=12.0, hub_x=4.0,
        starts=list(range(0, 21)), goals=list(range(23, 44)), hubs=(21, 22), zone="corridor")


def plus_walls() -> list[list[float]]:
    return [[-2, 2, -2, 8], [2, 2, 2, 8], [-2, -2, -2, -8], [2, -2, 2, -8],
            [-8, 2, -2, 2], [-8, -2, -2, -2], [2, 2, 8, 2], [2, -2, 8, -2],
            [-2, 8, 2, 8], [-2, -8, 2, -8], [-8, -2, -8, 2], [8, -2, 8, 2]]


ROWS = {  # SocialGym ids of the four spawn/goal rows, in the order of increasing offset
    "bottom": [0, 1, 30, 2, 3, 4, 31],  # y = -7.5, x = -1.5 .. 1.5
    "left": [5, 6, 7, 8, 9, 10, 11],  # x = -7.5, y = 1.5 .. -1.5
    "top": [12, 13, 14, 15, 16, 17, 18],  # y = 7.5, x = -1.5 .. 1.5
    "right": [19, 20, 21, 22, 23, 24, 25],  # x = 7.5, y = 1.5 .. -1.5
}
HUBS = {"left": 26, "top": 27, "right": 28, "bottom": 29}


def plus_nodes() -> list[dict]:
    offsets = [-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5]
    nodes = []
    for side, ids in ROWS.items():
        for node_id, off in zip(ids, offsets, strict=True):
            pos = {"bottom": [off, -7.5], "top": [off, 7.5],
                   "left": [-7.5, -off], "right": [7.5, -off]}[side]
            nodes.append({"id": node_id, "position": pos})
    hubs = {26: [-2.0, 0.0], 27: [0.0, 2.0], 28: [2.0, 0.0], 29: [0.0, -2.0]}
    nodes += [{"id": i, "position": p} for i, p in hubs.items()]
    return sorted(nodes, key=lambda n: n["id"])


def plus_row_edges() -> list[list[int]]:
    return [[n, HUBS[side]] for side, ids in ROWS.items() for n in ids]


RING = [[26, 29], [29, 28], [28, 27], [27, 26]]


def intersection() -> dict:
    return {
        "name": "intersection",
        "description": "SocialGym 2.0 intersection: a plus of two 16 m corridors 4 m wide; "
                       "one flow bottom to top, one left to right.",
        "bounds": [-8.5, -8.5, 8.5, 8.5],
        "walls": plus_walls(),
        "nodes": plus_nodes(),
        "edges": plus_row_edges() + [[29, 27], [26, 28]] + RING,
        "groups": [{"starts": ROWS["bottom"], "goals": ROWS["top"]},
                   {"starts": ROWS["left"], "goals": ROWS["right"]}],
        "zones": [{"name": "crossing", "rect": [-2.0, -2.0, 2.0, 2.0]}],
    }


def roundabout() -> dict:
    island = [[0, 1, -1, 0], [-1, 0, 0, -1], [0, -1, 1, 0], [1, 0, 0, 1]]
    return {
        "name": "roundabout",
        "description": "SocialGym 2.0 roundabout: the intersection's plus with a diamond island "
                       "in the middle; traffic goes around the ring.",
        "bounds": [-8.5, -8.5, 8.5, 8.5],
        "walls": plus_walls() + island,
        "nodes": plus_nodes(),
        "edges": plus_row_edges() + RING,
        "groups": [{"starts": ROWS["bottom"], "goals": ROWS["top"] + ROWS["right"] + ROWS["left"]},
                   {"starts": ROWS["left"], "goals": ROWS["top"] + ROWS["right"] + ROWS["bottom"]}],
        "zones": [{"name": "ring", "rect": [-2.0, -2.0, 2.0, 2.0]}],
    }


def open_space() -> dict:
    points = []
    for k in range(13):  # (0, 6) -> (-6, 0)
        points.append((-0.5 * k, 6.0 - 0.5 * k))
    for k in range(1, 13):  # -> (0, -6)
        points.append((-6.0 + 0.5 * k, -0.5 * k))
    for k in range(1, 13):  # -> (6, 0)
        points.append((0.5 * k, -6.0 + 0.5 * k))
    for k in range(1, 12):  # -> back toward (0, 6)
        points.append((6.0 - 0.5 * k, 0.5 * k))
    nodes = [{"id": i, "position": [p[0], p[1]]} for i, p in enumerate(points)]
    ids = [n["id"] for n in nodes]
    edges = [[a, b] for a in ids for b in ids if a < b]
    return {
        "name": "open",
        "description": "SocialGym 2.0 open space: no walls, 48 nodes on the diamond |x| + |y| = 6, "
                       "any node to any other.",
        "bounds": [-7.0, -7.0, 7.0, 7.0],
        "walls": [],
        "nodes": nodes,
        "edges": edges,
        "groups": [{"starts": ids, "goals": ids}],
        "zones": [{"name": "centre", "rect": [-6.0, -6.0, 6.0, 6.0]}],
    }


def office() -> dict:
    """A 30 m x 16 m office floor: 20 rooms (3 m x 7 m) on a 2 m corridor, 1 m doors."""
    walls = [[0, 0, 30, 0], [30, 0, 30, 16], [30, 16, 0, 16], [0, 16, 0, 0]]
    for y in (7.0, 9.0):  # corridor walls, split by a 1 m door into every room
        x = 0.0
        for room in range(10):
            door_lo = 3.0 * room + 1.0
            walls.append([x, y, door_lo, y])
            x = door_lo + 1.0
        walls.append([x, y, 30.0, y])
    for k in range(1, 10):  # room dividers
        walls.append([3.0 * k, 9.0, 3.0 * k, 16.0])
        walls.append([3.0 * k, 0.0, 3.0 * k, 7.0])
    nodes, edges, rooms = [], [], []
    for room in range(10):
        cx = 3.0 * room + 1.5
        corridor, top_door, top_room, bottom_door, bottom_room = (5 * room + k for k in range(5))
        nodes += [{"id": corridor, "position": [cx, 8.0]},
                  {"id": top_door, "position": [cx, 10.5]},
                  {"id": top_room, "position": [cx, 13.5]},
                  {"id": bottom_door, "position": [cx, 5.5]},
                  {"id": bottom_room, "position": [cx, 2.5]}]
        edges += [[corridor, top_door], [top_door, top_room],
                  [corridor, bottom_door], [bottom_door, bottom_room]]
        if room:
            edges.append([corridor - 5, corridor])
        rooms += [top_room, bottom_room]
    return {
        "name": "office",
        "description": "An office floor: 20 rooms of 3 m x 7 m on both sides of a 30 m corridor "
                       "2 m wide, each with a 1 m door; robots go from room to room.",
        "bounds": [-0.5, -0.5, 30.5, 16.5],
        "walls": walls,
        "nodes": nodes,
        "edges": edges,
        "groups": [{"starts": rooms, "goals": rooms}],
        "zones": [{"name": f"door_{side}_{room}",
                   "rect": [3.0 * room + 0.5, y - 1.0, 3.0 * room + 2.5, y + 1.0]}
                  for side, y in (("top", 9.0), ("bottom", 7.0)) for room in range(10)],
    }


def main() -> None:
    OUT.mkdir(exist_ok=True)
    for make in (doorway, hallway, intersection, roundabout, open_space, office):
        data = make()
        path = OUT / f"{data['name']}.json"
        path.write_text(json.dumps(data, indent=1) + "\n")
        print(f"wrote {path} ({len(data['walls'])} walls, {len(data['nodes'])} nodes, "
              f"{len(data['edges'])} edges)")


if __name__ == "__main__":
    main()
