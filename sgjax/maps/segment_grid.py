"""A uniform grid over segments, on the host (numpy): which segments may be near a point or a
segment, so that a map's checks cost what is near each element, not all pairs.

Each segment is recorded in the cells of points sampled along it at most half a cell apart,
so every point of a segment lies within a quarter cell of a sample and within one cell of a
recorded cell. A query for everything within ``radius`` of a point therefore looks
``ceil(radius / cell) + 1`` cells around the point's cell, and one for segments that may cross
a query segment looks two cells around each of the query's own recorded cells. Candidates come
in chunks of at most :data:`CHUNK_PAIRS` pairs, so memory stays bounded however dense the map;
the caller computes exact distances on them.

Used by :mod:`sgjax.maps.schema` (node clearance, edges through walls, the wall density limit)
and :mod:`sgjax.maps.check` (open wall ends, and :func:`points_along` in bounded runs for the
enclosure raster).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

BIAS = 1 << 30  # added to cell coordinates in keys, so that cells left of the origin sort too
CHUNK_PAIRS = 1 << 20  # candidate pairs handed out at once (about 50 MB of work arrays)
MAX_RECORDS = 1 << 24  # (segment, cell) records at most: longer walls get larger cells


def bounded_runs(sizes: np.ndarray, limit: int) -> Iterator[tuple[int, int]]:
    """Consecutive ``(first, last)`` runs of items (``[first, last)``) whose ``sizes`` add up to
    at most ``limit``; an item larger than ``limit`` is a run of its own."""
    total = np.cumsum(sizes)
    first = 0
    while first < len(total):
        done = total[first - 1] if first else 0
        last = max(first + 1, int(np.searchsorted(total, done + limit, "right")))
        yield first, last
        first = last


def points_along(segments: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``counts[s]`` (at least 2) evenly spaced points along each of ``segments [S, 4]``, both
    ends included (``numpy.linspace``'s points): ``(owner [K], points [K, 2])``."""
    counts = np.asarray(counts, np.int64)
    owner = np.repeat(np.arange(len(segments)), counts)
    step = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    last = counts[owner] - 1
    t = np.where(step == last, 1.0, step * (1.0 / np.maximum(last, 1)))
    a, b = segments[owner, :2], segments[owner, 2:]
    return owner, a + t[:, None] * (b - a)


class SegmentGrid:
    """``segments [S, 4]`` (x1, y1, x2, y2, m) in square cells of ``cell`` m (larger when the
    segments are so long that they would fill more than :data:`MAX_RECORDS` cells)."""

    def __init__(self, segments: np.ndarray, cell: float):
        self.segments = np.asarray(segments, np.float64).reshape(-1, 4)
        lengths = np.hypot(*(self.segments[:, 2:] - self.segments[:, :2]).T)
        self.cell = max(cell, 2.0 * float(lengths.sum()) / MAX_RECORDS)
        points = self.segments.reshape(-1, 2)
        self.origin = (points.min(0) if len(points) else np.zeros(2)) - 4 * self.cell
        owner, cells = self.sample_cells(self.segments)
        # sorted by cell, one record per (cell, segment)
        self.cell_keys, self.owners = unique_pairs(self.key(cells), owner)

    @staticmethod
    def key(cells: np.ndarray) -> np.ndarray:
        """``[..., 2]`` integer cell coordinates -> ``[...]`` int64 keys, in x then y order."""
        return ((cells[..., 0].astype(np.int64) + BIAS) << 32) + cells[..., 1] + BIAS

    @staticmethod
    def cell_of_key(keys: np.ndarray) -> np.ndarray:
        """:meth:`key`'s inverse: ``[...]`` keys -> ``[..., 2]`` cell coordinates."""
        return np.stack([(keys >> 32) - BIAS, (keys & 0xFFFFFFFF) - BIAS], -1)

    def cell_of(self, points: np.ndarray) -> np.ndarray:
        """``[P, 2]`` points (m) -> ``[P, 2]`` int64 cell coordinates."""
        return np.floor((np.asarray(points, np.float64) - self.origin) / self.cell).astype(
            np.int64)

    def sample_cells(self, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cells of points sampled at most half a cell apart along each of ``segments
        [S, 4]``: ``(owner [K], cells [K, 2])``, repeats included."""
        lengths = np.hypot(*(segments[:, 2:] - segments[:, :2]).T)
        owner, points = points_along(segments, np.ceil(lengths / (self.cell / 2)) + 1)
        return owner, self.cell_of(points)

    def most_in_one_cell(self) -> tuple[int, np.ndarray]:
        """``(count, centre [2] m)``: the largest number of segments recorded in one cell, and
        that cell's centre."""
        if len(self.cell_keys) == 0:
            return 0, self.origin
        starts = np.flatnonzero(np.r_[True, self.cell_keys[1:] != self.cell_keys[:-1]])
        counts = np.diff(np.r_[starts, len(self.cell_keys)])
        cell = self.cell_of_key(self.cell_keys[starts[np.argmax(counts)]])
        return int(counts.max()), self.origin + (cell + 0.5) * self.cell

    def _ranges(self, cells: np.ndarray, reach: int) -> tuple[np.ndarray, np.ndarray]:
        """For query cells ``[Q, 2]`` and every offset within ``reach`` cells: where their
        records start and how many there are, ``([Q, O], [Q, O])``."""
        span = np.arange(-reach, reach + 1)
        offsets = np.stack(np.meshgrid(span, span, indexing="ij"), -1).reshape(-1, 2)
        keys = self.key(cells[:, None, :] + offsets[None])
        start = np.searchsorted(self.cell_keys, keys, "left")
        return start, np.searchsorted(self.cell_keys, keys, "right") - start

    def candidates(self, owner: np.ndarray, cells: np.ndarray, reach: int
                   ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Pairs ``(query owner [K], segment [K])`` of every segment recorded within ``reach``
        cells of a query cell (``owner [Q]``, ``cells [Q, 2]``), in chunks of about
        :data:`CHUNK_PAIRS`; a pair may come more than once (a segment in several of the
        cells looked at)."""
        block = max(1, CHUNK_PAIRS // (2 * reach + 1) ** 2)
        for lo in range(0, len(cells), block):  # the ranges themselves in bounded blocks
            start, count = self._ranges(cells[lo:lo + block], reach)
            for first, last in bounded_runs(count.sum(1), CHUNK_PAIRS):
                yield self._expand(owner[lo + first:lo + last], start[first:last],
                                   count[first:last])

    def _expand(self, owner: np.ndarray, start: np.ndarray, count: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        flat_count = count.ravel()
        rows = np.repeat(np.repeat(owner, count.shape[1]), flat_count)
        first = np.repeat(start.ravel(), flat_count)
        within = np.arange(flat_count.sum()) - np.repeat(np.cumsum(flat_count) - flat_count,
                                                         flat_count)
        return rows, self.owners[first + within]

    def near_points(self, points: np.ndarray, radius: float
                    ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Pairs ``(point [K], segment [K])`` that include every segment within ``radius`` m of
        each of ``points [P, 2]`` (and some farther ones), in bounded chunks."""
        reach = int(np.ceil(radius / self.cell)) + 1
        yield from self.candidates(np.arange(len(points)), self.cell_of(points), reach)

    def nearest(self, points: np.ndarray, radius: float, skip: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """For ``points [P, 2]``: the distance (m) to the nearest segment when it is within
        ``radius`` (inf otherwise) and that segment (the lowest-numbered of equally near ones;
        0 when none is near), leaving out segment ``skip[p]`` for point ``p``: ``([P], [P])``."""
        best = np.full(len(points), np.inf)
        nearest = np.full(len(points), len(self.segments), np.int64)
        for point, segment in self.near_points(points, radius):
            if skip is not None:
                kept = segment != skip[point]
                point, segment = point[kept], segment[kept]
            dist = pair_distances(points[point], self.segments[segment])
            low = np.full(len(points), np.inf)
            np.minimum.at(low, point, dist)
            lowest = np.full(len(points), len(self.segments))
            at_low = dist == low[point]
            np.minimum.at(lowest, point[at_low], segment[at_low])
            closer = low < best  # an earlier chunk's equal distance keeps its segment
            tie = (low == best) & (lowest < nearest)
            best[closer], nearest[closer | tie] = low[closer], lowest[closer | tie]
        near = best <= radius
        return np.where(near, best, np.inf), np.where(near, nearest, 0)

    def near_segments(self, segments: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Pairs ``(query [K], segment [K])`` that include every segment touching or crossing
        each of ``segments [Q, 4]``, in bounded chunks (a query recorded in several cells may
        meet a segment more than once)."""
        owner, cells = self.sample_cells(np.asarray(segments, np.float64).reshape(-1, 4))
        owner, keys = unique_pairs(owner, self.key(cells))
        yield from self.candidates(owner, self.cell_of_key(keys), 2)


def unique_pairs(first: np.ndarray, second: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct pairs of two ``[K]`` integer arrays, sorted by ``first`` then ``second``."""
    order = np.lexsort((second, first))
    first, second = first[order], second[order]
    keep = np.ones(len(first), bool)
    keep[1:] = (first[1:] != first[:-1]) | (second[1:] != second[:-1])
    return first[keep], second[keep]


def pair_distances(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances (m) from ``points [..., 2]`` to segments ``[..., 4]`` (x1, y1, x2, y2), pair by
    pair with broadcasting: ``[...]``."""
    a, b = segments[..., :2], segments[..., 2:]
    e = b - a
    t = np.clip(np.sum((points - a) * e, -1) / np.maximum(np.sum(e * e, -1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[..., None] * e), axis=-1)
