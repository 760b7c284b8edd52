"""Re-timed straight moves: a first linearisation point that removes a crowd before SCP.

With fixed goals the separation-free optimum flies every vehicle on the same time profile,
so a fleet whose straight lines cross (a formation flown sideways onto another, goals in
lattice order) meets in one crowd at once, and the first SCP iteration, linearised there,
links the whole fleet by tens of rows per vehicle into one QP too dense for its dual.

Here each vehicle keeps its straight line but gets its own timing: it may wait at its start
(`delay` steps) and arrive early (`early` steps before the end), moving rest to rest on the
minimum-thrust unit profile of the remaining steps, within its velocity, acceleration and
jerk boxes. Vehicles are placed one by one, longest move first, each on the first timing
(least shift first) that keeps it `GAP` beyond R from every vehicle already placed, on the
chords between steps (the motion deviates from its chords by dt^2/8 |a|, a few cm); a
vehicle no timing separates takes the one that keeps it farthest. Vehicles whose straight
moves meet no one keep them. SCP then starts from a (nearly) separated point: every row it
linearises there holds at the guess, so the first QP is feasible and its active rows are the
few pairs that actually touch.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from planner.first_qp import unit_profile
from planner.scenario import Scenario
from planner.separation import _chord_closest, _norm, close_rows, near_pairs
from planner.types import FloatArray, IntArray

__all__ = ["CROWD_MIN_PAIRS", "GAP", "Retiming", "crowd_pairs", "retime_moves"]

Trajectories = tuple[FloatArray, FloatArray, FloatArray]

#: Clearance beyond R (in units of R) a re-timed vehicle keeps from those already placed,
#: on the chords between steps: covers the curve's deviation from its chords.
GAP = 0.1
#: Re-time only when the straight synchronised moves bring at least this many pairs closer
#: than R per vehicle (a crowd): below it SCP's rows separate the few meetings directly.
CROWD_MIN_PAIRS = 0.5
#: Timing shifts are tried in steps of horizon / SHIFT_DIVISIONS.
SHIFT_DIVISIONS = 40
#: Candidate timings evaluated together (vectorised) before checking for a separated one.
BATCH = 12


@dataclass(frozen=True)
class Retiming:
    """The re-timed first linearisation point and what it did."""

    guess: Trajectories
    delay: IntArray
    """(N,) steps each vehicle waits at its start."""
    early: IntArray
    """(N,) steps each vehicle arrives before the end of the horizon."""
    crowded: int
    """Vehicles whose synchronised straight moves came within R of another."""
    unresolved: int
    """Of those, vehicles no timing kept GAP beyond R from every earlier-placed vehicle."""


@lru_cache(maxsize=256)
def _profile(moving: int, total: int, delay: int, dt: float
             ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(p, v, a) over `total` steps of the unit move: rest `delay` steps, the unit profile
    over `moving` steps, rest until the end."""
    phi_p, phi_v, phi_a = unit_profile(moving, dt)
    p = np.ones(total + 1)
    v = np.zeros(total + 1)
    a = np.zeros(total)
    p[:delay] = 0.0
    p[delay:delay + moving + 1] = phi_p
    v[delay:delay + moving + 1] = phi_v
    a[delay:delay + moving] = phi_a
    return p, v, a


@lru_cache(maxsize=256)
def _profile_peaks(moving: int, dt: float) -> tuple[float, float, float]:
    """Largest |v|, |a| and |jerk| of the unit profile over `moving` steps (a at rest
    before and after)."""
    _, phi_v, phi_a = unit_profile(moving, dt)
    jerk = np.abs(np.diff(np.concatenate([[0.0], phi_a, [0.0]]))) / dt
    return float(np.abs(phi_v).max()), float(np.abs(phi_a).max()), float(jerk.max())


def crowd_pairs(scenario: Scenario, lin: Trajectories, below: float) -> tuple[IntArray, IntArray]:
    """Pairs (i < j) whose trajectories `lin` come closer than `below` (separation metric) on
    some chord between steps."""
    p = lin[0]
    near = near_pairs(*lin, scenario.dt, scenario.separation_scale, below)
    pairs, _ = close_rows(p, scenario.separation_scale, below, True, near)
    if len(pairs) == 0:
        return pairs.i, pairs.j
    key = np.unique(pairs.i.astype(np.int64) * len(p) + pairs.j)
    return (key // len(p)).astype(np.intp), (key % len(p)).astype(np.intp)


def _segment_neighbours(starts: FloatArray, goals: FloatArray, reach: float
                        ) -> list[IntArray]:
    """Per vehicle, the others whose straight segment (scaled) comes within `reach` of its
    own anywhere: the only ones any timing of the two can bring that close."""
    from scipy.spatial import cKDTree

    n = len(starts)
    length = _norm(goals - starts)
    # Sample every segment densely enough that the samples' balls of radius `pad` cover it.
    pad = 0.5 * reach
    samples = np.maximum(2, np.ceil(length / pad).astype(int) + 1)
    owner = np.repeat(np.arange(n), samples)
    s = np.concatenate([np.linspace(0.0, 1.0, m) for m in samples])
    points = starts[owner] + s[:, None] * (goals - starts)[owner]
    tree = cKDTree(points)
    pairs = tree.query_pairs(reach + pad, output_type="ndarray")
    i, j = owner[pairs[:, 0]], owner[pairs[:, 1]]
    keep = i != j
    i, j = i[keep], j[keep]
    out: list[list[int]] = [[] for _ in range(n)]
    key = np.unique(np.minimum(i, j).astype(np.int64) * n + np.maximum(i, j))
    for a, b in zip((key // n).tolist(), (key % n).tolist(), strict=True):
        out[a].append(b)
        out[b].append(a)
    return [np.array(x, dtype=np.intp) for x in out]


def _timings(scenario: Scenario, move: FloatArray) -> list[tuple[int, int]]:
    """(delay, early) timings of one straight move that fit its boxes, least shift first
    (the synchronised move (0, 0) always first)."""
    steps, dt = scenario.steps, scenario.dt
    lim = scenario.limits
    stride = max(1, steps // SHIFT_DIVISIONS)
    extent = np.abs(move)
    out = [(0, 0)]
    for shift in range(stride, steps, stride):
        moving = steps - shift
        if moving < 3:
            break
        v, a, j = _profile_peaks(moving, dt)
        if lim.velocity_max is not None and np.any(extent * v > lim.velocity_max + 1e-9):
            break
        if lim.acceleration_max is not None and np.any(
                extent * a > lim.acceleration_max + 1e-9):
            break
        if lim.jerk_max is not None and np.any(extent * j > lim.jerk_max + 1e-9):
            break
        half = (shift // (2 * stride)) * stride
        for delay in dict.fromkeys((shift, 0, half)):
            out.append((delay, shift - delay))
    return out


def retime_moves(scenario: Scenario, base: Trajectories, force: bool = False
                 ) -> Retiming | None:
    """Straight moves re-timed per vehicle so that they keep clear of each other and of the
    scenario's fixed trajectories (see the module doc), or None when the synchronised moves
    `base` hold no crowd (fewer than CROWD_MIN_PAIRS close pairs per vehicle; `force`:
    re-time anyway) or the scenario is not one of straight rest-to-rest moves (start
    velocities)."""
    n = len(scenario.vehicles)
    if scenario.start_velocities is not None:
        return None
    separation, scale = scenario.min_separation, scenario.separation_scale
    ci, cj = crowd_pairs(scenario, base, separation)
    if not force and len(ci) < CROWD_MIN_PAIRS * n:
        return None
    fixed = scenario.fixed_set.positions / scale if scenario.fixed else np.zeros((0, 1, 3))
    steps, dt = scenario.steps, scenario.dt
    starts, goals = scenario.starts, scenario.goals
    need = separation * (1.0 + GAP)
    neighbours = _segment_neighbours(starts / scale, goals / scale, need)
    crowded = np.zeros(n, dtype=bool)
    crowded[ci] = crowded[cj] = True
    if scenario.fixed:
        crowded[:] = True
    p, v, a = (x.copy() for x in base)
    scaled = p / scale
    placed = ~crowded
    delay = np.zeros(n, dtype=np.intp)
    early = np.zeros(n, dtype=np.intp)
    move = goals - starts
    order = np.flatnonzero(crowded)
    order = order[np.argsort(-_norm(move[order] / scale), kind="stable")]
    unresolved = 0
    for vehicle in order.tolist():
        others = neighbours[vehicle]
        others = others[placed[others]]
        timings = _timings(scenario, move[vehicle])
        best, best_gap = timings[0], -np.inf
        for lo in range(0, len(timings), BATCH):
            batch = timings[lo:lo + BATCH]
            unit = np.stack([_profile(steps - d - e, steps, d, dt)[0] for d, e in batch])
            trial = (starts[vehicle] + unit[:, :, None] * move[vehicle]) / scale
            against = np.concatenate([scaled[others], fixed]) if len(fixed) else scaled[others]
            if len(against) == 0:
                best, best_gap = batch[0], np.inf
                break
            diff = trial[:, None, :, :] - against[None, :, :, :]
            gap = _norm(_chord_closest(diff[:, :, :-1], diff[:, :, 1:])).min(axis=(1, 2))
            top = int(np.argmax(gap))
            if gap[top] > best_gap:
                best, best_gap = batch[top], float(gap[top])
            ok = np.flatnonzero(gap >= need)
            if ok.size:
                best, best_gap = batch[int(ok[0])], float(gap[ok[0]])
                break
        if best_gap < need:
            unresolved += 1
        d, e = best
        if (d, e) != (0, 0):
            up, uv, ua = _profile(steps - d - e, steps, d, dt)
            p[vehicle] = starts[vehicle] + up[:, None] * move[vehicle]
            v[vehicle] = uv[:, None] * move[vehicle]
            a[vehicle] = ua[:, None] * move[vehicle]
            scaled[vehicle] = p[vehicle] / scale
        delay[vehicle], early[vehicle] = d, e
        placed[vehicle] = True
    return Retiming((p, v, a), delay, early, int(crowded.sum()), unresolved)
