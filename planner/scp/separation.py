"""Pair geometry for the separation constraint ||S (p_i - p_j)|| >= R, S = diag(1/scale).

Long: broad phases, directions, row values and bounds share the pair-step geometry (`PairSteps`).

Two ways to linearise it about a previous iterate (the linearisation point, `lin`):

- Step rows (the paper, eqs. 29-31): for pair (i, j) at step k, u_k'S(p_i - p_j)[k] >= R
  with u_k the unit direction of S(p_i - p_j)[k] at `lin`. Separates the pair at the steps.
- Interval rows (continuous time): for pair (i, j) on [t_k, t_k+1], one direction u and three
  rows, one per Bernstein control point of the relative motion r(s) = r_k + s w_k +
  s^2/2 alpha_k: u'S r_k >= R, u'S(r_k + dt/2 w_k) >= R, u'S r_k+1 >= R. A quadratic lies in
  the convex hull of its control points, so u'S r(s) >= R over the whole interval and the
  true distance ||S r(s)|| >= u'S r(s) is at least R at every instant. u is the direction of
  the point of the chord [S r_k, S r_k+1] closest to the origin at `lin` (which `lin`
  satisfies exactly when it is separated and the interval is straight); the first and last
  intervals use the direction of their fixed endpoint (start or goal), so the rows never
  contradict the boundary conditions.

Every function is vectorised over pairs and steps, in chunks that bound memory.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.scp.golden import golden_minimum
from planner.types import FloatArray, IntArray

__all__ = [
    "PairSteps",
    "all_pairs",
    "close_among",
    "close_rows",
    "directions",
    "displacements",
    "far_margin_bound",
    "interval_lower_bounds",
    "interval_margins",
    "interval_minima",
    "min_step_distance",
    "near_pairs",
    "near_windows",
    "pair_index",
    "pair_margins",
    "row_displacements",
    "row_values",
    "values_among",
    "violated_among",
    "violated_rows",
    "window_rows",
    "worst_per_run",
]


#: Pair-steps handled at once (bounds temporary memory to a few tens of MB).
CHUNK = 1 << 19
#: Last-resort direction where a pair coincides and does not move relative to itself.
_FALLBACK = np.array([0.0, 0.0, 1.0])


def _norm(x: FloatArray) -> FloatArray:
    """Euclidean norm over the last axis (3 coordinates): ~3x faster than np.linalg.norm
    on the (pairs, steps, 3) arrays of the hot path, which reduce over a short axis."""
    norm: FloatArray = np.sqrt(np.einsum("...c,...c->...", x, x))
    return norm


@dataclass(frozen=True)
class PairSteps:
    """A set of (i, j, k): vehicle pair i < j (scenario indices) at step/interval k."""

    i: IntArray
    j: IntArray
    k: IntArray

    def __len__(self) -> int:
        return len(self.i)

    def select(self, mask: NDArray[np.bool_] | IntArray | slice) -> PairSteps:
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

    @staticmethod
    def concat(parts: list[PairSteps]) -> PairSteps:
        if not parts:
            z = np.zeros(0, dtype=np.intp)
            return PairSteps(z, z, z)
        return PairSteps(*(np.concatenate([getattr(p, f) for p in parts]) for f in "ijk"))


def all_pairs(vehicles: int) -> tuple[IntArray, IntArray]:
    """Indices (i, j), i < j, of every pair."""
    i, j = np.triu_indices(vehicles, k=1)
    return i.astype(np.intp), j.astype(np.intp)


#: Steps per time window of the broad phase (`near_pairs`).
NEAR_WINDOW = 8
#: Below this many vehicles every pair is examined directly (the broad phase costs more).
NEAR_MIN_VEHICLES = 64


def near_pairs(positions: FloatArray, velocities: FloatArray, accelerations: FloatArray,
               dt: float, scale: FloatArray, reach: float, window: int = NEAR_WINDOW
               ) -> tuple[IntArray, IntArray]:
    """Broad phase: every pair (i < j) that may come within `reach` (separation metric) at
    some instant, a superset found with a k-d tree per time window (`near_windows`).
    Exact as a filter: pairs left out are provably far."""
    near = near_windows(positions, velocities, accelerations, dt, scale, reach, window)
    n = positions.shape[0]
    keys = np.unique(near.i.astype(np.int64) * n + near.j)
    return (keys // n).astype(np.intp), (keys % n).astype(np.intp)


def near_windows(positions: FloatArray, velocities: FloatArray, accelerations: FloatArray,
                 dt: float, scale: FloatArray, reach: float, window: int = NEAR_WINDOW
                 ) -> PairSteps:
    """Broad phase by time window: every (i < j, w) such that pair (i, j) may come within
    `reach` (separation metric) during window w (steps w * window .. (w + 1) * window).

    Over a window each vehicle's motion, and every row point (p_k, p_k + dt/2 v_k and the
    end of step k p_k + dt v_k + dt^2/2 a_k, the Bernstein control points of the step),
    lies in the box around its control points; a pair whose two boxes' bounding spheres are
    farther apart than `reach` is farther than `reach` at every instant, every row point and
    every point of the chords between its steps in that window.
    """
    n, stages = positions.shape[0], positions.shape[1]
    if n < 2 or stages < 2:
        return PairSteps.concat([])
    from scipy.spatial import cKDTree

    p = positions / scale
    mid = (positions[:, :-1] + 0.5 * dt * velocities[:, :-1]) / scale
    end = (positions[:, :-1] + dt * velocities[:, :-1] + 0.5 * dt * dt * accelerations) / scale
    # Every row point of step k (p_k, its middle point, its end, p_k+1), per window: the
    # boxes of all windows in one reduction per side.
    starts = np.arange(0, stages - 1, window)
    lows = np.minimum.reduceat(np.minimum(np.minimum(p[:, :-1], p[:, 1:]), np.minimum(mid, end)),
                               starts, axis=1)  # (n, windows, 3)
    highs = np.maximum.reduceat(np.maximum(np.maximum(p[:, :-1], p[:, 1:]),
                                           np.maximum(mid, end)), starts, axis=1)
    found = []
    for w in range(len(starts)):
        lo, hi = lows[:, w], highs[:, w]
        centre = 0.5 * (lo + hi)
        radius = 0.5 * np.linalg.norm(hi - lo, axis=1)
        pairs = cKDTree(centre).query_pairs(reach + 2.0 * float(radius.max()),
                                            output_type="ndarray")
        if len(pairs) == 0:
            continue
        i, j = pairs[:, 0], pairs[:, 1]
        keep = (np.linalg.norm(centre[i] - centre[j], axis=1)
                <= reach + radius[i] + radius[j])
        i, j = i[keep], j[keep]
        found.append(PairSteps(np.minimum(i, j).astype(np.intp), np.maximum(i, j).astype(np.intp),
                               np.full(len(i), w, dtype=np.intp)))
    return PairSteps.concat(found)


def pair_index(i: IntArray, j: IntArray, vehicles: int) -> IntArray:
    """Position of pairs (i < j) in `all_pairs` order."""
    i = np.asarray(i, dtype=np.int64)
    return (i * (2 * vehicles - i - 1) // 2 + (np.asarray(j) - i - 1)).astype(np.intp)


def far_margin_bound(lin_positions: FloatArray, lin_velocities: FloatArray, dt: float,
                     scale: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per-vehicle terms of a lower bound on the smallest row value at `lin` of a pair
    farther than `reach` at every instant and row point (see `near_pairs`): value >= reach
    - (dt/2 (V_i + V_j) + D_i + D_j), V the largest scaled speed, D the largest scaled step
    displacement. (A row is u'x at a control point x, u the unit direction of the chord's
    closest point, u'x >= |c| > reach on the chord, minus dt/2 |w| at the middle point; the
    first and last intervals use the end point's direction, off by at most one step.)
    Returns (dt/2 V, D) per vehicle."""
    speed = _norm(lin_velocities / scale).max(axis=1)
    step = _norm(np.diff(lin_positions, axis=1) / scale).max(axis=1)
    return 0.5 * dt * speed, step


def _pair_chunks(vehicles: int, stages: int) -> Iterator[tuple[IntArray, IntArray]]:
    i, j = all_pairs(vehicles)
    per_chunk = max(1, CHUNK // max(stages, 1))
    for lo in range(0, len(i), per_chunk):
        yield i[lo:lo + per_chunk], j[lo:lo + per_chunk]


def _keep_right(motion: FloatArray) -> FloatArray:
    """Unit horizontal directions to the right of `motion` (motion x up).

    Where a pair coincides at the linearisation point (e.g. a symmetric head-on swap in the
    separation-free first QP) its direction is undefined; a fixed fallback such as "up" for
    every pair would stack every vehicle meeting there vertically. Passing on the right of
    the relative motion is consistent for both vehicles of a pair and differs between pairs.
    """
    right = np.stack([motion[..., 1], -motion[..., 0], np.zeros(motion.shape[:-1])], axis=-1)
    norm = _norm(right)[..., None]
    out = right / np.where(norm < 1e-12, 1.0, norm)
    vertical = norm[..., 0] < 1e-12
    if vertical.any():
        out[vertical] = np.array([1.0, 0.0, 0.0])
    return out


#: How strongly a close pair's direction is turned toward its side of passing, in units of R.
PASSING_BIAS = 0.5


def _unit(d: FloatArray, motion: FloatArray, separation: float = 0.0) -> FloatArray:
    """d normalised; where d vanishes, `_keep_right(motion)` (or up if nothing moves).

    With `separation` R > 0, a pair closer than R at the linearisation point has d moved
    sideways, away from its line of relative motion on the side it already passes (the
    right for an exactly head-on pair), by PASSING_BIAS R (1 - |d| / R). Any unit direction
    gives a valid (inner) half-space; this one turns smoothly through a crossing, where the
    plain direction of a head-on pair flips from -x to +x in one step and asks the pair to
    jump 2R (found on symmetric swaps, which came back infeasible).
    """
    norm = _norm(d)
    if separation > 0.0:
        close = norm < separation  # the bias is zero elsewhere: only these are touched
        if close.any():
            near, along = d[close], motion[close]
            right = _keep_right(along)
            side = np.where(np.einsum("...c,...c->...", near, right) < 0.0, -1.0, 1.0)
            moving = _norm(along) >= 1e-12
            weight = PASSING_BIAS * (separation - norm[close])
            near = near + np.where(moving, weight * side, 0.0)[:, None] * right
            d = d.copy()
            d[close] = near
            norm[close] = _norm(near)
    tiny = norm < 1e-12
    out = d / np.where(tiny, 1.0, norm)[..., None]
    if tiny.any():
        moving = _norm(motion[tiny]) >= 1e-12
        fallback = np.broadcast_to(_FALLBACK, (int(tiny.sum()), 3)).copy()
        fallback[moving] = _keep_right(motion[tiny][moving])
        out[tiny] = fallback
    return out


def _step_motion(d: FloatArray) -> FloatArray:
    """Relative motion around each step of scaled differences (pairs, K+1, 3)."""
    padded = np.concatenate([d[:, :1], d, d[:, -1:]], axis=1)
    motion: FloatArray = padded[:, 2:] - padded[:, :-2]
    return motion


def _chord_closest(u: FloatArray, w: FloatArray) -> FloatArray:
    """The point of each segment [u, w] closest to the origin (last axis: coordinates)."""
    chord = w - u
    length2 = np.einsum("...c,...c->...", chord, chord)
    tau = np.clip(-np.einsum("...c,...c->...", u, chord) / np.maximum(length2, 1e-300), 0, 1)
    nearest: FloatArray = u + tau[..., None] * chord
    return nearest


def _interval_directions_all(d: FloatArray, separation: float, moving: bool = False
                             ) -> FloatArray:
    """Unit directions (pairs, K, 3) of every interval from scaled differences (pairs, K+1, 3);
    `moving`: see `directions`."""
    chord = d[:, 1:] - d[:, :-1]
    u = _unit(_chord_closest(d[:, :-1], d[:, 1:]), chord, separation)
    if not moving:
        u[:, 0] = _unit(d[:, 0], chord[:, 0], separation)
    u[:, -1] = _unit(d[:, -1], chord[:, -1], separation)
    return u


def _step_directions_all(d: FloatArray, separation: float) -> FloatArray:
    """Unit directions (pairs, K+1, 3) of every step from scaled differences (pairs, K+1, 3)."""
    return _unit(d, _step_motion(d), separation)


def directions(lin_positions: FloatArray, scale: FloatArray, rows: PairSteps,
               continuous: bool, separation: float, moving: bool = False) -> FloatArray:
    """(rows, 3) unit directions u (scaled space) of the rows' linearisations at `lin`.

    The QP row coefficients on p_i - p_j are u / scale. The first interval's direction is
    that of the fixed start difference d0 (its rows at p0 then hold exactly), except with
    `moving` starts (a scenario with start velocities): there a pair passing another near R
    turns within the first step, d0's half-space cuts its step end, and the chord's closest
    point (as for every other interval) is the direction its rows can hold along.
    """
    last = lin_positions.shape[1] - 1

    def diff(k: IntArray) -> FloatArray:
        return (lin_positions[rows.i, k] - lin_positions[rows.j, k]) / scale

    here = diff(rows.k)
    if not continuous:  # the same motion as `_step_motion`: the neighbouring steps
        motion = diff(np.minimum(rows.k + 1, last)) - diff(np.maximum(rows.k - 1, 0))
        return _unit(here, motion, separation)
    return _interval_units(here, diff(rows.k + 1), rows.k, last, separation, moving)


def _interval_units(here: FloatArray, after: FloatArray, k: IntArray, last: int,
                    separation: float, moving: bool) -> FloatArray:
    """`directions` of intervals k from their scaled pair differences at k and k + 1."""
    chord = after - here
    u = _unit(_chord_closest(here, after), chord, separation)
    first, final = (k == 0) & (not moving), k == last - 1
    u[first] = _unit(here[first], chord[first], separation)
    u[final] = _unit(after[final], chord[final], separation)
    return u


def row_values(positions: FloatArray, velocities: FloatArray, dt: float, scale: FloatArray,
               i: IntArray, j: IntArray, u: FloatArray, continuous: bool) -> FloatArray:
    """Smallest u'S(...) over each row set of pairs (i, j), vectorised over leading axes.

    i, j: pair index arrays (P,); u: (P, K+1, 3) step directions or (P, K, 3) interval
    directions. Returns (P, K+1) or (P, K) values; the rows hold where value >= R.
    """
    r = (positions[i] - positions[j]) / scale
    values: FloatArray
    if not continuous:
        values = np.einsum("psc,psc->ps", u, r)
        return values
    mid = r[:, :-1] + 0.5 * dt * (velocities[i] - velocities[j])[:, :-1] / scale
    values = np.minimum(
        np.minimum(np.einsum("psc,psc->ps", u, r[:, :-1]), np.einsum("psc,psc->ps", u, mid)),
        np.einsum("psc,psc->ps", u, r[:, 1:]),
    )
    return values


def _chunks_of(i: IntArray, j: IntArray, stages: int) -> Iterator[tuple[IntArray, IntArray]]:
    per_chunk = max(1, CHUNK // max(stages, 1))
    for lo in range(0, len(i), per_chunk):
        yield i[lo:lo + per_chunk], j[lo:lo + per_chunk]


def interval_margins(lin_positions: FloatArray, lin_velocities: FloatArray, dt: float,
                     scale: FloatArray, continuous: bool, separation: float,
                     pairs: tuple[IntArray, IntArray] | None = None,
                     moving: bool = False) -> FloatArray:
    """(pairs, K) or (pairs, K+1): per pair (in `all_pairs` order, or of `pairs`) and
    interval (or step), the smallest value of its linearised rows at `lin` itself: where
    the row check can stop looking (see `row_displacements`)."""
    n, stages = lin_positions.shape[0], lin_positions.shape[1]
    lin = lin_positions / scale
    out = []
    chunks = _pair_chunks(n, stages) if pairs is None else _chunks_of(*pairs, stages)
    for i, j in chunks:
        d = lin[i] - lin[j]
        u = (_interval_directions_all(d, separation, moving) if continuous
             else _step_directions_all(d, separation))
        out.append(row_values(lin_positions, lin_velocities, dt, scale, i, j, u, continuous))
    return (np.concatenate(out) if out
            else np.zeros((0, stages - 1 if continuous else stages)))


def pair_margins(lin_positions: FloatArray, lin_velocities: FloatArray, dt: float,
                 scale: FloatArray, continuous: bool, separation: float,
                 pairs: tuple[IntArray, IntArray] | None = None,
                 moving: bool = False) -> FloatArray:
    """Per pair (in `all_pairs` order, or of `pairs`), the smallest value of its linearised
    rows at `lin` itself: the starting point of the pruning bound of `violated_rows`."""
    n, stages = lin_positions.shape[0], lin_positions.shape[1]
    chunks = _pair_chunks(n, stages) if pairs is None else _chunks_of(*pairs, stages)
    out = [interval_margins(lin_positions, lin_velocities, dt, scale, continuous, separation,
                            (i, j), moving).min(axis=1) for i, j in chunks]
    return np.concatenate(out) if out else np.zeros(0)


def displacements(lin: tuple[FloatArray, FloatArray], current: tuple[FloatArray, FloatArray],
                  dt: float, scale: FloatArray) -> FloatArray:
    """Per vehicle, the largest scaled move of any row point (p_k and p_k + dt/2 v_k) from
    `lin` to `current`: a row's value moves by at most the sum of its two vehicles'."""
    dp = (current[0] - lin[0]) / scale
    dm = dp + 0.5 * dt * (current[1] - lin[1]) / scale
    bound: FloatArray = np.maximum(_norm(dp).max(axis=1), _norm(dm).max(axis=1))
    return bound


def row_displacements(lin: tuple[FloatArray, FloatArray],
                      current: tuple[FloatArray, FloatArray], dt: float, scale: FloatArray,
                      continuous: bool) -> FloatArray:
    """(vehicles, K) or (vehicles, K+1): per vehicle and interval (or step), the largest
    scaled move from `lin` to `current` of the points its rows read (p_k, p_k + dt/2 v_k,
    p_k+1; or p_k). A row set's value moves by at most the sum of its two vehicles' at the
    same interval, so it can be broken only where `interval_margins` is below that sum."""
    dp = (current[0] - lin[0]) / scale
    moved = _norm(dp)
    if not continuous:
        return moved
    middle = _norm(dp[:, :-1] + 0.5 * dt * (current[1] - lin[1])[:, :-1] / scale)
    return np.maximum(np.maximum(moved[:, :-1], moved[:, 1:]), middle)


def violated_rows(lin_positions: FloatArray, positions: FloatArray, velocities: FloatArray,
                  dt: float, scale: FloatArray, separation: float, tolerance: float,
                  continuous: bool, pairs: tuple[IntArray, IntArray] | None = None,
                  moving: bool = False) -> tuple[PairSteps, FloatArray]:
    """Every pair-step (or pair-interval) whose linearised rows about `lin` the iterate
    violates by more than `tolerance`, with the smallest row value.

    This is the all-pairs check that makes lazily generated rows give the optimum of the QP
    with every row. `pairs` restricts it to the pairs that can be violated at all (see
    `pair_margins`, `displacements`); by default every pair is checked.
    """
    n, stages = positions.shape[0], positions.shape[1]
    lin = lin_positions / scale
    found: list[PairSteps] = []
    found_v: list[FloatArray] = []
    chunks = _pair_chunks(n, stages) if pairs is None else _chunks_of(*pairs, stages)
    for i, j in chunks:
        d = lin[i] - lin[j]
        u = (_interval_directions_all(d, separation, moving) if continuous
             else _step_directions_all(d, separation))
        value = row_values(positions, velocities, dt, scale, i, j, u, continuous)
        pi, kk = np.nonzero(value < separation - tolerance)
        found.append(PairSteps(i[pi], j[pi], kk.astype(np.intp)))
        found_v.append(value[pi, kk])
    if not found:
        return PairSteps.concat([]), np.zeros(0)
    return PairSteps.concat(found), np.concatenate(found_v)


def values_among(lin_positions: FloatArray, positions: FloatArray, velocities: FloatArray,
                 dt: float, scale: FloatArray, separation: float, continuous: bool,
                 rows: PairSteps, moving: bool = False) -> FloatArray:
    """The smallest value of each of `rows`' linearised rows about `lin` (`directions`) at
    (positions, velocities): `row_values` for given pair-steps (pair-intervals)."""
    out = []
    at_lin = positions is lin_positions  # the margins: the differences are read once
    last = lin_positions.shape[1] - 1
    for lo in range(0, len(rows), CHUNK):
        part = rows.select(slice(lo, lo + CHUNK))
        i, j, k = part.i, part.j, part.k
        if continuous and at_lin:
            here = (positions[i, k] - positions[j, k]) / scale
            after = (positions[i, k + 1] - positions[j, k + 1]) / scale
            u = _interval_units(here, after, k, last, separation, moving)
        else:
            u = directions(lin_positions, scale, part, continuous, separation, moving)
            here = (positions[i, k] - positions[j, k]) / scale
        value = np.einsum("rc,rc->r", u, here)
        if continuous:
            if not at_lin:
                after = (positions[i, k + 1] - positions[j, k + 1]) / scale
            middle = here + 0.5 * dt * (velocities[i, k] - velocities[j, k]) / scale
            value = np.minimum(np.minimum(value, np.einsum("rc,rc->r", u, middle)),
                               np.einsum("rc,rc->r", u, after))
        out.append(value)
    return np.concatenate(out) if out else np.zeros(0)


def violated_among(lin_positions: FloatArray, positions: FloatArray, velocities: FloatArray,
                   dt: float, scale: FloatArray, separation: float, tolerance: float,
                   continuous: bool, rows: PairSteps, moving: bool = False
                   ) -> tuple[PairSteps, FloatArray]:
    """The pair-steps (or pair-intervals) among `rows` whose linearised rows about `lin` the
    iterate violates by more than `tolerance`, with the smallest row value: `violated_rows`
    for given pair-intervals instead of whole pairs."""
    value = values_among(lin_positions, positions, velocities, dt, scale, separation,
                         continuous, rows, moving)
    bad = value < separation - tolerance
    return rows.select(bad), value[bad]


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
    by_value = np.lexsort((v, run_id))
    first = np.ones(len(by_value), dtype=bool)
    first[1:] = run_id[by_value][1:] != run_id[by_value][:-1]
    pick = by_value[first]
    return PairSteps(i[pick], j[pick], k[pick])


def close_rows(positions: FloatArray, scale: FloatArray, below: float, continuous: bool,
               pairs: tuple[IntArray, IntArray] | None = None) -> tuple[PairSteps, FloatArray]:
    """Pair-steps (or pair-intervals, by chord distance) closer than `below`, with distance;
    only among `pairs` if given."""
    n, stages = positions.shape[0], positions.shape[1]
    scaled = positions / scale
    found: list[PairSteps] = []
    found_d: list[FloatArray] = []
    chunks = _pair_chunks(n, stages) if pairs is None else _chunks_of(*pairs, stages)
    for i, j in chunks:
        d = scaled[i] - scaled[j]
        dist = _norm(_chord_closest(d[:, :-1], d[:, 1:]) if continuous else d)
        pi, kk = np.nonzero(dist < below)
        found.append(PairSteps(i[pi], j[pi], kk.astype(np.intp)))
        found_d.append(dist[pi, kk])
    if not found:
        return PairSteps.concat([]), np.zeros(0)
    return PairSteps.concat(found), np.concatenate(found_d)


def close_among(positions: FloatArray, scale: FloatArray, below: float, continuous: bool,
                rows: PairSteps) -> tuple[PairSteps, FloatArray]:
    """The pair-steps (or pair-intervals, by chord distance) among `rows` closer than
    `below`, with distance: `close_rows` for given pair-steps."""
    found: list[PairSteps] = []
    found_d: list[FloatArray] = []
    for lo in range(0, len(rows), CHUNK):
        part = rows.select(slice(lo, lo + CHUNK))
        i, j, k = part.i, part.j, part.k
        here = (positions[i, k] - positions[j, k]) / scale
        if continuous:
            here = _chord_closest(here, (positions[i, k + 1] - positions[j, k + 1]) / scale)
        dist = _norm(here)
        close = dist < below
        found.append(part.select(close))
        found_d.append(dist[close])
    if not found:
        return PairSteps.concat([]), np.zeros(0)
    return PairSteps.concat(found), np.concatenate(found_d)


def window_rows(near: PairSteps, window: int, continuous: bool, steps: int) -> PairSteps:
    """The pair-intervals (or pair-steps) of `near_windows`' (pair, window)s, each once."""
    span = window if continuous else window + 1
    k = (near.k[:, None] * window + np.arange(span)).reshape(-1)
    rows = PairSteps(np.repeat(near.i, span), np.repeat(near.j, span), k)
    rows = rows.select(k < (steps if continuous else steps + 1))
    if continuous:  # windows do not overlap in intervals
        return rows
    keys = np.unique(rows.keys(int(near.j.max(initial=0)) + 1, steps + 1))
    return PairSteps.from_keys(keys, int(near.j.max(initial=0)) + 1, steps + 1)


def min_step_distance(positions: FloatArray, scale: FloatArray,
                      pairs: tuple[IntArray, IntArray] | None = None
                      ) -> tuple[float, int, int, int]:
    """The smallest scaled pair distance at the steps: (distance, i, j, k), among `pairs`
    if given."""
    n, stages = positions.shape[0], positions.shape[1]
    if n < 2:
        return float("inf"), -1, -1, -1
    scaled = positions / scale
    best = (float("inf"), -1, -1, -1)
    chunks = _pair_chunks(n, stages) if pairs is None else _chunks_of(*pairs, stages)
    for i, j in chunks:
        if len(i) == 0:
            continue
        d = np.linalg.norm(scaled[i] - scaled[j], axis=-1)
        flat = int(np.argmin(d))
        p, k = divmod(flat, stages)
        if d[p, k] < best[0]:
            best = (float(d[p, k]), int(i[p]), int(j[p]), int(k))
    return best


def interval_lower_bounds(positions: FloatArray, accelerations: FloatArray, dt: float,
                          scale: FloatArray, below: float,
                          pairs: tuple[IntArray, IntArray] | None = None) -> PairSteps:
    """Pair-intervals [k, k+1] whose continuous-time distance may fall below `below`.

    A cheap certificate: the distance from the origin to the chord between the two
    endpoint differences, minus the largest bulge of a quadratic, dt^2/8 ||S alpha||. Only
    the intervals it cannot clear need the exact `interval_minima`.
    """
    n, stages = positions.shape[0], accelerations.shape[1]
    scaled_p = positions / scale
    scaled_a = accelerations / scale
    found: list[PairSteps] = []
    chunks = _pair_chunks(n, stages + 1) if pairs is None else _chunks_of(*pairs, stages + 1)
    for i, j in chunks:
        d = scaled_p[i] - scaled_p[j]
        closest = np.linalg.norm(_chord_closest(d[:, :-1], d[:, 1:]), axis=-1)
        bulge = dt * dt / 8.0 * np.linalg.norm(scaled_a[i] - scaled_a[j], axis=-1)
        pi, kk = np.nonzero(closest - bulge < below)
        found.append(PairSteps(i[pi], j[pi], kk.astype(np.intp)))
    return PairSteps.concat(found)


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
        d: FloatArray
        if s.ndim == 2:
            d = np.linalg.norm(r0 + s * w + s * s * half_alpha, axis=-1)
        else:
            d = np.linalg.norm(r0[:, None] + s * w[:, None] + s * s * half_alpha[:, None],
                               axis=-1)
        return d

    grid = np.linspace(0.0, dt, samples)
    values = dist(np.broadcast_to(grid, (len(i), samples)))
    best = np.argmin(values, axis=1)
    step = dt / (samples - 1)
    lo = np.clip(grid[best] - step, 0.0, dt)
    hi = np.clip(grid[best] + step, 0.0, dt)
    s_best, d_best = golden_minimum(dist, lo, hi, refinements)
    # The golden search is interior: keep the sampled minimum (endpoints included) if lower.
    sampled = values[np.arange(len(i)), best]
    use_sample = sampled < d_best
    s_best = np.where(use_sample, grid[best], s_best)
    d_best = np.where(use_sample, sampled, d_best)
    return d_best, s_best
