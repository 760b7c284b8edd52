"""The linear functionals of one vehicle-axis trajectory and their compliance.

Every row of a group's QP (a separation row, a box) reads one functional of a vehicle's
trajectory on one axis: its position, velocity, Bernstein middle point, acceleration or jerk
at a step. They are linear in the axis' accelerations a (K values): g = T a, and with M the
inverse Hessian on the feasible set (the boundary conditions fix the rest of the move) the
compliance W = T M T' says how much functional f moves under a unit force on functional g.
W is one (F x F) matrix per (K, dt), shared by every vehicle and axis; the group's dual
(`planner.scp.dual`) builds its Q = C M C' from it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from planner.types import FloatArray, IntArray

__all__ = ["Functionals", "functionals"]


@dataclass(frozen=True)
class Functionals:
    """Indices of the linear functionals of one vehicle-axis trajectory, and W = T M T'."""

    steps: int
    compliance: FloatArray
    """(F, F): W[f, g] = response of functional f to a unit force on functional g."""

    def position(self, k: IntArray | int) -> IntArray:
        return np.asarray(k)

    def velocity(self, k: IntArray | int) -> IntArray:
        return self.steps + 1 + np.asarray(k)

    def middle(self, k: IntArray | int) -> IntArray:
        """p_k + dt/2 v_k, the Bernstein middle point of step k."""
        return 2 * (self.steps + 1) + np.asarray(k)

    def acceleration(self, k: IntArray | int) -> IntArray:
        return 2 * (self.steps + 1) + self.steps + np.asarray(k)

    def jerk(self, k: IntArray | int) -> IntArray:
        """a_k - a_{k-1} (a_{-1} = 0)."""
        return 2 * (self.steps + 1) + 2 * self.steps + np.asarray(k)

    def values(self, p: FloatArray, v: FloatArray, a: FloatArray, dt: float) -> FloatArray:
        """(m, F, 3): every functional of every vehicle and axis of trajectories (p, v, a)."""
        middle = p[:, :-1] + 0.5 * dt * v[:, :-1]
        jerk = np.diff(a, axis=1, prepend=0.0)
        return np.concatenate([p, v, middle, a, jerk], axis=1)


@lru_cache(maxsize=8)
def functionals(steps: int, dt: float) -> Functionals:
    """The functionals' map T from one axis' accelerations a (K) and W = T M T', M = Pi / 2
    (the cost's Hessian is 2 I; Pi projects on the null space of the boundary conditions
    p_K, v_K, a_{K-1}, which fix the rest of the move)."""
    k = np.arange(steps + 1)[:, None]
    j = np.arange(steps)[None, :]
    pos = np.where(j < k, dt * dt * (k - j - 0.5), 0.0)  # p_k - p_0 - k dt v_0 (v_0 = 0)
    vel = np.where(j < k, dt, 0.0)
    middle = pos[:-1] + 0.5 * dt * vel[:-1]
    acc = np.eye(steps)
    jerk = acc - np.eye(steps, k=-1)
    T = np.concatenate([pos, vel, middle, acc, jerk])
    E = np.stack([pos[-1], vel[-1], acc[-1]])
    Pi = np.eye(steps) - E.T @ np.linalg.solve(E @ E.T, E)
    TP = T @ Pi
    return Functionals(steps, 0.5 * TP @ T.T)
