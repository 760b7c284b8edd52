"""The double integrator and its exact interpolation against step-by-step integration."""

from __future__ import annotations

import numpy as np

from planner.model.dynamics import integrate, interpolate


def _step_by_step(p0, v0, accelerations, dt, substeps):
    """Integrate each constant-acceleration step in `substeps` sub-steps, one at a time."""
    h = dt / substeps
    p, v = np.array(p0, float), np.array(v0, float)
    positions, velocities, times = [p.copy()], [v.copy()], [0.0]
    t = 0.0
    for a in accelerations:
        for _ in range(substeps):
            p = p + h * v + 0.5 * h * h * a
            v = v + h * a
            t += h
            positions.append(p.copy())
            velocities.append(v.copy())
            times.append(t)
    return np.array(times), np.array(positions), np.array(velocities)


def test_integrate_matches_the_recurrence():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(40, 3))
    p, v = integrate([1.0, 2.0, 3.0], [0.5, 0.0, -0.5], a, 0.2)
    _, ref_p, ref_v = _step_by_step([1.0, 2.0, 3.0], [0.5, 0.0, -0.5], a, 0.2, 1)
    np.testing.assert_allclose(p, ref_p, atol=1e-12)
    np.testing.assert_allclose(v, ref_v, atol=1e-12)


def test_integrate_broadcasts_over_vehicles():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(5, 30, 3))
    starts = rng.normal(size=(5, 3))
    p, v = integrate(starts, np.zeros((5, 3)), a, 0.1)
    for n in range(5):
        one_p, one_v = integrate(starts[n], np.zeros(3), a[n], 0.1)
        np.testing.assert_allclose(p[n], one_p)
        np.testing.assert_allclose(v[n], one_v)


def test_interpolation_is_the_exact_motion_between_steps():
    rng = np.random.default_rng(3)
    dt = 0.2
    a = rng.normal(size=(25, 3))
    p, v = integrate([0, 0, 1], [0, 0, 0], a, dt)
    times, ref_p, ref_v = _step_by_step([0, 0, 1], [0, 0, 0], a, dt, 8)
    sample = interpolate(p, v, a, dt, times)
    np.testing.assert_allclose(sample.position, ref_p, atol=1e-12)
    np.testing.assert_allclose(sample.velocity, ref_v, atol=1e-12)
    # Inside each step (away from the boundaries, where either side is right) the
    # acceleration is that step's.
    middles = (np.arange(25) + 0.5) * dt
    np.testing.assert_allclose(interpolate(p, v, a, dt, middles).acceleration, a)


def test_interpolation_holds_start_and_goal_outside_the_horizon():
    a = np.zeros((10, 3))
    a[2] = [1.0, 0, 0]
    a[5] = [-1.0, 0, 0]
    p, v = integrate([0, 0, 0], [0, 0, 0], a, 0.5)
    sample = interpolate(p, v, a, 0.5, [-1.0, 100.0])
    np.testing.assert_allclose(sample.position[0], p[0])
    np.testing.assert_allclose(sample.position[1], p[-1])
    np.testing.assert_allclose(sample.velocity[1], v[-1])
    np.testing.assert_allclose(sample.acceleration, 0.0)


def test_a_step_boundary_belongs_to_the_step_it_starts():
    # 0.6 / 0.2 is 2.9999999999999996 in floating point; t = 0.6 starts step 3.
    dt = 0.2
    a = np.arange(10.0)[:, None] * np.ones(3)
    p, v = integrate(np.zeros(3), np.zeros(3), a, dt)
    times = np.array([0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8])  # as typed
    np.testing.assert_array_equal(interpolate(p, v, a, dt, times).acceleration, a)
