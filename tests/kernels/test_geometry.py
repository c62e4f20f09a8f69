"""Swept disc-vs-segment contact times and ray casts against hand-worked answers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sgjax.kernels.geometry import (
    point_segment_distance,
    segments_intersect,
    swept_disc_segment_toi,
    wrap_angle,
)

WALL = (0.0, -1.0, 0.0, 1.0)  # vertical wall on x = 0, y in [-1, 1]


def toi(px, py, dx, dy, r=0.2, wall=WALL):
    return float(swept_disc_segment_toi(px, py, dx, dy, r, *wall))


def test_head_on_hits_side_at_radius():
    # Centre starts 1 m left of the wall and moves 2 m right: contact when the centre is 0.2 m
    # from the wall, i.e. after 0.8 m of 2 m.
    assert toi(-1.0, 0.0, 2.0, 0.0) == pytest.approx(0.4)


def test_fast_motion_cannot_tunnel():
    # 100 m in one step still reports the contact.
    assert toi(-1.0, 0.0, 100.0, 0.0) == pytest.approx(0.8 / 100.0)


def test_miss_and_parallel_motion():
    assert np.isinf(toi(-1.0, 0.0, 0.5, 0.0))  # stops short
    assert np.isinf(toi(-1.0, 0.0, 0.0, 3.0))  # parallel
    assert np.isinf(toi(-1.0, 2.0, 2.0, 0.0))  # passes above the end cap (2 > 1 + 0.2)


def test_end_cap_contact():
    # Moving right at y = 1.1: contact with the rounded end at (0, 1): x = -sqrt(0.04 - 0.01).
    expected = (1.0 - np.sqrt(0.2**2 - 0.1**2)) / 2.0
    assert toi(-1.0, 1.1, 2.0, 0.0) == pytest.approx(expected, rel=1e-5)


def test_inside_moving_in_is_zero_and_moving_out_is_free():
    assert toi(-0.1, 0.0, 0.5, 0.0) == 0.0
    assert np.isinf(toi(-0.1, 0.0, -0.5, 0.0))


def test_point_segment_distance():
    d = point_segment_distance(jnp.array([-3.0, 0.5, 0.0]), jnp.array([0.0, 3.0, 0.0]), *WALL)
    np.testing.assert_allclose(d, [3.0, np.hypot(0.5, 2.0), 0.0], rtol=1e-6)


def test_segments_intersect():
    assert segments_intersect((0, 0), (2, 2), (0, 2), (2, 0))
    assert not segments_intersect((0, 0), (1, 0), (0, 1), (1, 1))
    assert segments_intersect((0, 0), (1, 0), (1, 0), (2, 5))  # touching end


def test_wrap_angle_range():
    a = wrap_angle(jnp.linspace(-20.0, 20.0, 1001))
    assert float(a.min()) > -np.pi and float(a.max()) <= np.pi
    assert float(wrap_angle(jnp.float32(-np.pi))) == pytest.approx(np.pi)


def test_toi_gradient_finite_away_from_contact():
    g = jax.grad(lambda x: swept_disc_segment_toi(x, 0.0, 2.0, 0.0, 0.2, *WALL))(-1.0)
    assert np.isfinite(g) and g == pytest.approx(-0.5)  # d/dx of (-x - 0.2) / 2 for x < 0
