"""Pair geometry for the separation constraint ||S (p_i - p_j)|| >= R, S = diag(1/scale).

- `step_distances`: every pair's distance at every step (chunked over pairs to bound memory).
- `linearised_rows`: the half-space u'S(p_i - p_j) >= R with u the unit direction at the
  linearisation point (paper eqs. 29-31) for chosen pair-instants.
- `row_values`: u'S(p_i - p_j) of the current iterate for rows, to find violated ones.
- `interval_minima`: the exact minimum distance of a pair over [t_k, t_k+1], where both move
  on their exact quadratics; the continuous-time check of a plan.

Every function is vectorised over pairs and steps; chunks bound memory for large fleets.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "PairSteps",
    "all_pairs",
    "interval_lower_bounds",
    "interval_minima",
    "linearised_coefficients",
    "min_step_distance",
    "step_distances",
    "violated_linearised",
    "worst_per_run",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Pair-steps handled at once (bounds temporary memory to a few tens of MB).
CHUNK = 1 << 20


@dataclass(frozen=True)
class PairSteps:
    """A set of (i, j, k): vehicle pair i < j (scenario indices) at step/interval k."""

    i: IntArray
    j: IntArray
    k: IntArray

    def __len__(self) -> int:
        return len(self.i)

    def select(self, mask: NDArray[np.bool_] | IntArray) -> PairSteps:
        return PairSteps(self.i[mask], self.j[mask], self.k[mask])

    def keys(self, vehicles: int, stages: int) -> NDArray[np.int64]:
        """A unique integer per (i, j, k), for set operations."""
        return (self.i.astype(np.int64) * vehicles + self.j) * stages + self.k

    @staticmethod
    def from_keys(keys: NDArray[np.int64], vehicles: int, stages: int) -> PairSteps:
        k = keys % stages
        ij = keys // stages
        return PairSteps((ij // vehicles).astype(np.intp), (ij % vehicles).astype(np.intp),
                         k.astype(np.intp))


def all_pairs(vehicles: int) -> tuple[IntArray, IntArray]:
    """Indices (i, j), i < j, of every pair."""
    i, j = np.triu_indices(vehicles, k=1)
    return i.astype(np.intp), j.astype(np.intp)


def _pair_chunks(vehicles: int, stages: int) -> Iterator[tuple[IntArray, IntArray]]:
    i, j = all_pairs(vehicles)
    per_chunk = max(1, CHUNK // max(stages, 1))
    for lo in range(0, len(i), per_chunk):
        yield i[lo:lo + per_chunk], j[lo:lo + per_chunk]


def step_distances(positions: FloatArray, scale: FloatArray, below: float) -> tuple[PairSteps,
                                                                                  FloatArray]:
    """Every pair-step whose scaled distance is below `below`, with that distance.

    positions: (N, K+1, 3). Returns (pair-steps, distances) for the close ones only.
    """
    n, stages = positions.shape[0], positions.shape[1]
    scaled = positions / scale
    found_i, found_j, found_k, found_d = [], [], [], []
    for i, j in _pair_chunks(n, stages):
        d = np.linalg.norm(scaled[i] - scaled[j], axis=-1)  # (pairs, stages)
        pi, kk = np.nonzero(d < below)
        found_i.append(i[pi])
        found_j.append(j[pi])
        found_k.append(kk)
        found_d.append(d[pi, kk])
    cat = np.concatenate
    return PairSteps(cat(found_i), cat(found_j), cat(found_k).astype(np.intp)), cat(found_d)


def min_step_distance(positions: FloatArray, scale: FloatArray) -> tuple[float, int, int, int]:
    """The smallest scaled pair distance at the steps: (distance, i, j, k)."""
    n, stages = positions.shape[0], positions.shape[1]
    if n < 2:
        return float("inf"), -1, -1, -1
    scaled = positions / scale
    best = (float("inf"), -1, -1, -1)
    for i, j in _pair_chunks(n, stages):
        d = np.linalg.norm(scaled[i] - scaled[j], axis=-1)
        flat = int(np.argmin(d))
        p, k = divmod(flat, stages)
        if d[p, k] < best[0]:
            best = (float(d[p, k]), int(i[p]), int(j[p]), int(k))
    return best


def linearised_coefficients(positions: FloatArray, scale: FloatArray, rows: PairSteps
                            ) -> FloatArray:
    """(rows, 3) coefficients c = S u of u'S(p_i - p_j) >= R at the linearisation point.

    u is the unit direction of S(p_i - p_j) at step k of `positions` (the previous iterate).
    Coincident points (zero distance) get an arbitrary but fixed direction (up), so the row
    still pushes the pair apart.
    """
    d = (positions[rows.i, rows.k] - positions[rows.j, rows.k]) / scale
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    tiny = norm[:, 0] < 1e-12
    if tiny.any():
        d[tiny] = np.array([0.0, 0.0, 1.0])
        norm[tiny] = 1.0
    return d / norm / scale


def violated_linearised(lin_positions: FloatArray, positions: FloatArray,
                        velocities: FloatArray, dt: float, scale: FloatArray,
                        separation: float, tolerance: float, continuous: bool
                        ) -> list[tuple[PairSteps, FloatArray]]:
    """Every linearised row (about `lin_positions`) that the iterate violates, by kind.

    Kind 0: u_k'S(p_i - p_j)[k] at step k. With `continuous`, also the interval rows of
    [k, k+1] along the same direction u_k: kind 1 at the Bernstein middle point
    (p + dt/2 v)[k], kind 2 at step k+1. Returns, per kind, the violated (i, j, k) with
    their values (< separation - tolerance). This is the all-pairs check that makes lazily
    generated rows give the optimum of the QP with every row.
    """
    n, stages = positions.shape[0], positions.shape[1]
    lin = lin_positions / scale
    cur = positions / scale
    mid = (positions + 0.5 * dt * velocities) / scale
    kinds = 3 if continuous else 1
    out: list[tuple[list[IntArray], list[IntArray], list[IntArray], list[FloatArray]]] = [
        ([], [], [], []) for _ in range(kinds)
    ]
    for i, j in _pair_chunks(n, stages):
        d_lin = lin[i] - lin[j]
        norm = np.linalg.norm(d_lin, axis=-1)
        coincident = norm < 1e-12
        if coincident.any():  # same fallback direction as `linearised_coefficients`
            d_lin[coincident] = np.array([0.0, 0.0, 1.0])
            norm[coincident] = 1.0
        u = d_lin / norm[..., None]
        values = [np.einsum("psc,psc->ps", u, cur[i] - cur[j])]
        if continuous:
            values.append(np.einsum("psc,psc->ps", u[:, :-1], (mid[i] - mid[j])[:, :-1]))
            values.append(np.einsum("psc,psc->ps", u[:, :-1], (cur[i] - cur[j])[:, 1:]))
        for kind, value in enumerate(values):
            pi, kk = np.nonzero(value < separation - tolerance)
            bucket = out[kind]
            bucket[0].append(i[pi])
            bucket[1].append(j[pi])
            bucket[2].append(kk)
            bucket[3].append(value[pi, kk])
    cat = np.concatenate
    return [
        (PairSteps(cat(bi), cat(bj), cat(bk).astype(np.intp)), cat(bv))
        for bi, bj, bk, bv in out
    ]


def worst_per_run(pairs: PairSteps, values: FloatArray) -> PairSteps:
    """The pair-step of smallest value in each run of consecutive steps of the same pair.

    A pair that violates its constraint does so over a run of neighbouring steps; the row
    at the deepest point of the run is the one most likely to be active, and the rows next
    to it are usually satisfied once it is imposed.
    """
    if len(pairs) == 0:
        return pairs
    order = np.lexsort((pairs.k, pairs.j, pairs.i))
    i, j, k, v = pairs.i[order], pairs.j[order], pairs.k[order], values[order]
    new_run = np.ones(len(i), dtype=bool)
    new_run[1:] = (i[1:] != i[:-1]) | (j[1:] != j[:-1]) | (k[1:] != k[:-1] + 1)
    run_id = np.cumsum(new_run) - 1
    # Sort by (run, value) and keep the first of each run.
    by_value = np.lexsort((v, run_id))
    first = np.ones(len(by_value), dtype=bool)
    first[1:] = run_id[by_value][1:] != run_id[by_value][:-1]
    pick = by_value[first]
    return PairSteps(i[pick], j[pick], k[pick])


def interval_lower_bounds(positions: FloatArray, accelerations: FloatArray, dt: float,
                          scale: FloatArray, below: float) -> PairSteps:
    """Pair-intervals [k, k+1] whose continuous-time distance may fall below `below`.

    A cheap certificate: the distance from the origin to the chord between the two
    endpoint differences, minus the largest bulge of a quadratic, dt^2/8 ||S alpha||. Only
    the intervals it cannot clear need the exact `interval_minima`.
    """
    n, stages = positions.shape[0], accelerations.shape[1]
    sp_ = positions / scale
    sa = accelerations / scale
    out_i, out_j, out_k = [], [], []
    for i, j in _pair_chunks(n, stages + 1):
        d = sp_[i] - sp_[j]  # (pairs, K+1, 3)
        u, w = d[:, :-1], d[:, 1:]
        chord = w - u
        length2 = np.einsum("psc,psc->ps", chord, chord)
        tau = np.clip(-np.einsum("psc,psc->ps", u, chord) / np.maximum(length2, 1e-300), 0, 1)
        closest = np.linalg.norm(u + tau[..., None] * chord, axis=-1)
        bulge = dt * dt / 8.0 * np.linalg.norm(sa[i] - sa[j], axis=-1)
        pi, kk = np.nonzero(closest - bulge < below)
        out_i.append(i[pi])
        out_j.append(j[pi])
        out_k.append(kk)
    cat = np.concatenate
    return PairSteps(cat(out_i), cat(out_j), cat(out_k).astype(np.intp))


def interval_minima(positions: FloatArray, velocities: FloatArray, accelerations: FloatArray,
                    dt: float, scale: FloatArray, intervals: PairSteps,
                    samples: int = 17, refinements: int = 40) -> tuple[FloatArray, FloatArray]:
    """Exact minimum scaled distance of each pair over its interval, and when (s in [0, dt]).

    The relative motion r(s) = r0 + s w + s^2/2 alpha is exact; ||S r(s)||^2 is a quartic in
    s, minimised by dense sampling followed by a golden-section search in the bracket of the
    best sample (the quartic has at most two minima, farther apart than the bracket).
    """
    i, j, k = intervals.i, intervals.j, intervals.k
    r0 = (positions[i, k] - positions[j, k]) / scale
    w = (velocities[i, k] - velocities[j, k]) / scale
    half_alpha = 0.5 * (accelerations[i, k] - accelerations[j, k]) / scale

    def dist(s: FloatArray) -> FloatArray:
        """Distance at times s: (pairs,) or (pairs, samples)."""
        s = s[..., None]
        if s.ndim == 2:
            return np.linalg.norm(r0 + s * w + s * s * half_alpha, axis=-1)
        return np.linalg.norm(
            r0[:, None] + s * w[:, None] + s * s * half_alpha[:, None], axis=-1
        )

    grid = np.linspace(0.0, dt, samples)
    values = dist(np.broadcast_to(grid, (len(i), samples)))
    best = np.argmin(values, axis=1)
    step = dt / (samples - 1)
    lo = np.clip(grid[best] - step, 0.0, dt)
    hi = np.clip(grid[best] + step, 0.0, dt)
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a = hi - ratio * (hi - lo)
    b = lo + ratio * (hi - lo)
    fa, fb = dist(a), dist(b)
    for _ in range(refinements):
        left = fa < fb  # the minimum lies in [lo, b]: drop (b, hi]
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
        probe = np.where(left, hi - ratio * (hi - lo), lo + ratio * (hi - lo))
        f_probe = dist(probe)
        a, b, fa, fb = (
            np.where(left, probe, b), np.where(left, a, probe),
            np.where(left, f_probe, fb), np.where(left, fa, f_probe),
        )
    s_best = np.where(fa < fb, a, b)
    d_best = np.minimum(fa, fb)
    # Compare with the sampled minimum and the endpoints (golden search is interior).
    sampled = values[np.arange(len(i)), best]
    use_sample = sampled < d_best
    s_best = np.where(use_sample, grid[best], s_best)
    d_best = np.where(use_sample, sampled, d_best)
    return d_best, s_best
