"""Thrust and body rates from acceleration and jerk (paper eqs. 14 and 20)."""

from __future__ import annotations

import numpy as np

from planner.model.flatness import GRAVITY, body_rates, jerk_from_accelerations, thrust


def _attitude(force: np.ndarray) -> np.ndarray:
    """Rotation with body z along `force` and yaw 0 (the same convention, built directly)."""
    z = force / np.linalg.norm(force)
    y = np.cross(z, [1.0, 0.0, 0.0])
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=1)


def test_hover_needs_g_and_no_rotation():
    a = np.zeros((5, 3))
    np.testing.assert_allclose(thrust(a), GRAVITY)
    np.testing.assert_allclose(body_rates(a, jerk_from_accelerations(a, 0.1)), 0.0)


def test_jerk_starts_from_hover():
    a = np.array([[1.0, 0, 0], [1.5, 0, 0], [0.0, 0, 0]])
    np.testing.assert_allclose(jerk_from_accelerations(a, 0.5),
                               [[2.0, 0, 0], [1.0, 0, 0], [-3.0, 0, 0]])


def test_body_rates_match_the_derivative_of_the_attitude():
    # A smooth acceleration profile; body rates from eq. 20 must equal the angular
    # velocity of the attitude itself, R' dR/dt = [w]x, by finite differences.
    t = np.linspace(0.0, 2.0, 2001)
    a = np.stack([np.sin(2 * t), 0.5 * np.cos(3 * t), 0.3 * np.sin(t)], axis=1)
    j = np.stack([2 * np.cos(2 * t), -1.5 * np.sin(3 * t), 0.3 * np.cos(t)], axis=1)
    rates = body_rates(a, j)
    h = t[1] - t[0]
    for n in range(100, 1900, 150):
        R = _attitude(a[n] + [0, 0, GRAVITY])
        dR = (_attitude(a[n + 1] + [0, 0, GRAVITY]) - _attitude(a[n - 1] + [0, 0, GRAVITY])) / (
            2 * h
        )
        skew = R.T @ dR
        w = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
        np.testing.assert_allclose(rates[n, :2], w[:2], atol=1e-5)
    assert np.all(rates[:, 2] == 0.0)


def test_thrust_is_the_norm_of_a_plus_g():
    a = np.array([[3.0, 4.0, -GRAVITY], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(thrust(a), [5.0, GRAVITY + 1.0])


def test_free_fall_and_sideways_thrust_give_finite_rates():
    """At zero thrust (a = -g) the attitude is undefined and with thrust along x the yaw-0
    frame degenerates: the rates stay finite (huge where the vehicle cannot follow), so a
    plan carries numbers, never NaN."""
    a = np.array([[0.0, 0.0, -GRAVITY], [1.0, 0.0, -GRAVITY], [0.0, 0.0, 0.0]])
    with np.errstate(all="raise"):
        rates = body_rates(a, jerk_from_accelerations(a, 0.1))
    assert np.isfinite(rates).all()
