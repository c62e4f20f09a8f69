"""The maps' segment grid (``sgjax.maps.segment_grid``) against brute force over all pairs:
its candidates hold every near segment, its nearest segment is the brute force's (distance and
lowest index), its crossing test is the scalar one, and the map limits refuse before work."""

import numpy as np
import pytest

from sgjax.kernels.geometry import segments_intersect, segments_intersect_pairs
from sgjax.maps import MapError, parse_map
from sgjax.maps.check import check_map
from sgjax.maps.schema import point_segment_distances
from sgjax.maps.segment_grid import SegmentGrid
from sgjax.maps.size_limits import MAX_NODES, MAX_WALLS, MAX_WALLS_PER_CELL


def random_segments(rng, count, spread=10.0):
    """``count`` segments of mixed lengths (a few cm to tens of m) around the origin, some
    sharing ends, some axis-aligned."""
    a = rng.uniform(-spread, spread, (count, 2))
    b = a + rng.normal(0, rng.choice([0.05, 0.5, 4.0, 20.0], (count, 1)), (count, 2))
    axis = rng.random(count) < 0.3
    b[axis, 1] = a[axis, 1]
    shared = rng.random(count) < 0.2
    a[shared] = b[np.roll(np.arange(count), 1)][shared]
    return np.concatenate([a, b], 1).round(2)


@pytest.mark.parametrize("seed", range(12))
def test_near_points_and_nearest_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    segments = random_segments(rng, int(rng.integers(1, 400)))
    points = rng.uniform(-14, 14, (300, 2)).round(2)
    points[:20] = segments[:20, :2] if len(segments) >= 20 else points[:20]  # on wall ends
    cell = float(rng.choice([0.25, 0.5, 1.0]))
    grid = SegmentGrid(segments, cell)
    dist = point_segment_distances(points, segments)
    for radius in (0.05, 0.25, 0.5, 1.5, 3.0):
        found = set()
        for point, segment in grid.near_points(points, radius):
            found.update(zip(point.tolist(), segment.tolist(), strict=True))
        assert set(zip(*map(np.ndarray.tolist, np.nonzero(dist <= radius)), strict=True)) <= found
        skip = rng.integers(0, len(segments), len(points))
        best, nearest = grid.nearest(points, radius, skip=skip)
        masked = dist.copy()
        masked[np.arange(len(points)), skip] = np.inf
        want = masked.min(1)
        near = want <= radius
        np.testing.assert_array_equal(best[near], want[near])
        np.testing.assert_array_equal(nearest[near], np.argmin(masked, 1)[near])
        assert np.all(np.isinf(best[~near]))


@pytest.mark.parametrize("seed", range(8))
def test_near_segments_hold_every_crossing(seed):
    rng = np.random.default_rng(100 + seed)
    walls = random_segments(rng, int(rng.integers(1, 300)))
    queries = random_segments(rng, 120, spread=12.0)
    grid = SegmentGrid(walls, 0.5)
    crossing = {(q, w) for q in range(len(queries)) for w in range(len(walls))
                if segments_intersect(tuple(queries[q, :2]), tuple(queries[q, 2:]),
                                      tuple(walls[w, :2]), tuple(walls[w, 2:]))}
    found = set()
    for query, wall in grid.near_segments(queries):
        found.update(zip(query.tolist(), wall.tolist(), strict=True))
    assert crossing <= found
    q, w = np.array(sorted(found)).T
    vectorised = segments_intersect_pairs(queries[q], walls[w])
    scalar = [segments_intersect(tuple(queries[i, :2]), tuple(queries[i, 2:]),
                                 tuple(walls[j, :2]), tuple(walls[j, 2:]))
              for i, j in zip(q, w, strict=True)]
    np.testing.assert_array_equal(vectorised, scalar)


def test_candidates_come_in_bounded_chunks(monkeypatch):
    import sgjax.maps.segment_grid as segment_grid

    monkeypatch.setattr(segment_grid, "CHUNK_PAIRS", 500)
    rng = np.random.default_rng(7)
    segments = random_segments(rng, 2000, spread=3.0)
    points = rng.uniform(-3, 3, (400, 2))
    grid = SegmentGrid(segments, 0.5)
    sizes = [len(p) for p, _ in grid.near_points(points, 0.5)]
    per_point = max(np.bincount(p, minlength=len(points)).max()
                    for p, _ in grid.near_points(points, 0.5))
    assert len(sizes) > 10 and max(sizes) <= 500 + per_point
    best, _ = grid.nearest(points, 0.5)
    want = point_segment_distances(points, segments).min(1)
    np.testing.assert_array_equal(best[want <= 0.5], want[want <= 0.5])


def _map(walls, nodes=((0.0, 0.0), (1.0, 0.0)), edges=((0, 1),)):
    return {"name": "limits", "description": "", "bounds": [-50, -50, 50, 50], "walls": walls,
            "nodes": [{"id": i, "position": list(p)} for i, p in enumerate(nodes)],
            "edges": [list(e) for e in edges], "groups": [{"starts": [0], "goals": [1]}]}


def test_limits_refuse_before_any_other_work():
    too_many = _map([[0, 5, 1, 5]] * (MAX_WALLS + 1))
    problems = check_map(too_many, "big.json")
    assert [(p.severity, p.path) for p in problems] == [("error", "$.walls")]
    assert f"{MAX_WALLS + 1:,} walls; a map has at most {MAX_WALLS:,}" in problems[0].message
    nodes = [(float(i), 3.0) for i in range(MAX_NODES + 1)]
    with pytest.raises(MapError, match=f"at most {MAX_NODES:,}") as err:
        parse_map(_map([], nodes=nodes), "nodes.json")
    assert err.value.path == "$.nodes"
    # a pile of walls at one spot: refused, with where it is
    pile = [[10.0 + 0.001 * i, 10.0, 10.2, 10.3] for i in range(MAX_WALLS_PER_CELL + 1)]
    (problem,) = check_map(_map(pile + [[-5, -5, 5, -5]]), "pile.json")
    assert problem.path == "$.walls" and f"{MAX_WALLS_PER_CELL + 1} walls pass" in problem.message
    assert "around (10." in problem.message
    check_map(_map(pile[:MAX_WALLS_PER_CELL] + [[-5, -5, 5, -5]]))  # at the limit: checked
