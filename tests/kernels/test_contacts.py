"""Property tests of the contact routines on random geometry (hypothesis)."""

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from sgjax.kernels.contacts import CONTACT_GAP, WALL_SKIN, clamp_to_walls, separate_robots
from sgjax.kernels.geometry import point_segment_distance
from sgjax.maps import compile_map, parse_map

coord = st.floats(-5.0, 5.0, allow_nan=False)
motion = st.floats(-50.0, 50.0, allow_nan=False)


def one_wall_map(x1, y1, x2, y2):
    data = {"name": "w", "description": "", "bounds": [-60, -60, 60, 60],
            "walls": [[x1, y1, x2, y2]],
            "nodes": [{"id": 0, "position": [-55, -55]}, {"id": 1, "position": [55, -55]}],
            "edges": [[0, 1]], "groups": [{"starts": [0], "goals": [1]}]}
    return compile_map(parse_map(data, clearance=0.5))


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(wall=st.tuples(coord, coord, coord, coord), start=st.tuples(coord, coord),
       move=st.tuples(motion, motion), radius=st.floats(0.05, 0.5))
def test_clamped_motion_never_ends_inside_or_crosses_a_wall(wall, start, move, radius):
    x1, y1, x2, y2 = wall
    if np.hypot(x2 - x1, y2 - y1) < 1e-3:
        return
    d0 = float(point_segment_distance(start[0], start[1], x1, y1, x2, y2))
    if d0 < radius + WALL_SKIN:  # the disc must start outside the wall
        return
    m = one_wall_map(x1, y1, x2, y2)
    x, y = jnp.array([start[0]], jnp.float32), jnp.array([start[1]], jnp.float32)
    dx, dy, _ = clamp_to_walls(x, y, jnp.array([move[0]]), jnp.array([move[1]]),
                               jnp.array([radius]), m)
    # Sample the travelled path: no point of it may come within the radius of the wall.
    t = np.linspace(0.0, 1.0, 201)
    px, py = start[0] + t * float(dx[0]), start[1] + t * float(dy[0])
    d = np.asarray(point_segment_distance(px, py, x1, y1, x2, y2))
    assert d.min() >= radius - 1e-4


@settings(max_examples=100, deadline=None)
@given(points=st.lists(st.tuples(coord, coord), min_size=2, max_size=6),
       radius=st.floats(0.1, 0.5))
@example(points=[(0.0, 0.5), (0.0, 0.3)], radius=0.1)  # tangent in float64, 1e-8 apart in float32
@example(points=[(0.0, 0.0), (0.0, 0.200005)], radius=0.1)  # 5 um apart: in contact, no push
@example(points=[(0.0, 0.0), (0.0, 0.20002)], radius=0.1)  # 20 um apart: not in contact
def test_separation_of_a_pair_is_exact_and_symmetric(points, radius):
    (ax, ay), (bx, by) = points[:2]
    x, y = jnp.array([ax, bx], jnp.float32), jnp.array([ay, by], jnp.float32)
    r = jnp.array([radius, radius])
    px, py, touching = separate_robots(x, y, r, jnp.array([True, True]))
    gap_before = float(np.hypot(ax - bx, ay - by))
    gap_after = float(np.hypot(ax + px[0] - bx - px[1], ay + py[0] - by - py[1]))
    np.testing.assert_allclose([px[0] + px[1], py[0] + py[1]], [0.0, 0.0], atol=1e-5)
    # Positions are float32 and this oracle float64: a pair within float32 rounding of
    # tangency (for example 0.5 - 0.3 against 2 x 0.1) may be pushed or not, by no more than
    # that rounding; a pair apart by at most CONTACT_GAP is in contact without a push.
    rounding = 1e-6
    if gap_before < 2 * radius - rounding:
        assert bool(touching.all()) and abs(gap_after - 2 * radius) < 1e-4
    else:
        assert float(jnp.hypot(px, py).max()) < rounding
        if gap_before < 2 * radius + CONTACT_GAP - rounding:
            assert bool(touching.all())
        elif gap_before > 2 * radius + CONTACT_GAP + rounding:
            assert not bool(touching.any()) and float(jnp.abs(px).max()) == 0.0
