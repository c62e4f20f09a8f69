"""The kinematic models on hand-worked cases: each limit bites where it should."""

import jax.numpy as jnp
import numpy as np
import pytest

from sgjax.dynamics import PRESETS, Kinematics, decode_continuous, integrate, robot_params


def rest(n=1, heading=0.0):
    z = jnp.zeros(n)
    return Kinematics(heading=z + heading, v_forward=z, v_lateral=z, omega=z, steering=z)


def step(preset, kin, forward, lateral, turn, dt=0.1):
    p = robot_params([PRESETS[preset]] * kin.heading.shape[0])
    arr = [jnp.atleast_1d(jnp.asarray(v, jnp.float32)) for v in (forward, lateral, turn)]
    return integrate(kin, *arr, p, jnp.float32(dt))


def test_diff_drive_acceleration_limit_and_straight_motion():
    kin, dx, dy = step("socialgym", rest(), 1.5, 0.0, 0.0)
    assert float(kin.v_forward[0]) == pytest.approx(0.5)  # 5 m/s^2 x 0.1 s
    assert float(dx[0]) == pytest.approx(0.05) and float(dy[0]) == pytest.approx(0.0)


def test_diff_drive_ignores_lateral_and_clips_reverse():
    kin, dx, dy = step("socialgym", rest(), -1.0, 1.0, 0.0)
    assert float(kin.v_forward[0]) == 0.0  # socialgym preset has no reverse
    assert float(kin.v_lateral[0]) == 0.0 and float(dy[0]) == 0.0


def test_yaw_rate_and_angular_acceleration_limits():
    kin = rest()
    for _ in range(20):
        kin, _, _ = step("socialgym", kin, 0.0, 0.0, 10.0)
    assert float(kin.omega[0]) == pytest.approx(3.0)  # max_omega
    kin2, _, _ = step("socialgym", rest(), 0.0, 0.0, 10.0)
    assert float(kin2.omega[0]) == pytest.approx(0.5)  # max_alpha x dt


def test_omni_moves_sideways_with_a_vector_speed_limit():
    kin = rest()
    for _ in range(30):
        kin, dx, dy = step("cobot", kin, 5.0, 5.0, 0.0)
    speed = np.hypot(float(kin.v_forward[0]), float(kin.v_lateral[0]))
    assert speed == pytest.approx(1.2, rel=1e-5)
    assert float(dy[0]) > 0.0 and float(dx[0]) == pytest.approx(float(dy[0]), rel=1e-5)


def test_ackermann_turning_radius_and_no_turn_in_place():
    kin = rest()
    for _ in range(40):
        kin, _, _ = step("automata", kin, 1.2, 0.0, 10.0)
    radius = float(kin.v_forward[0] / kin.omega[0])
    assert radius == pytest.approx(0.98, rel=1e-4)
    stopped, dx, _ = step("automata", rest(), 0.0, 0.0, 10.0)
    assert float(stopped.omega[0]) == 0.0 and float(dx[0]) == 0.0


def test_heterogeneous_team_in_one_call():
    presets = [PRESETS[n] for n in ("socialgym", "cobot", "automata")]
    p = robot_params(presets)
    forward, lateral, turn = decode_continuous(jnp.ones((3, 3)), p, 3)
    np.testing.assert_allclose(forward, [1.5, 1.2, 1.2])
    np.testing.assert_allclose(lateral, [0.0, 1.2, 0.0])  # only the omni robot strafes
    np.testing.assert_allclose(turn, [3.0, np.pi, np.arctan(0.324 / 0.98)], rtol=1e-6)
    kin, dx, dy = integrate(rest(3), forward, lateral, turn, p, jnp.float32(0.1))
    assert kin.v_lateral.tolist()[0] == 0.0 and kin.v_lateral.tolist()[2] == 0.0
    assert float(kin.steering[2]) > 0.0 and float(kin.steering[0]) == 0.0
