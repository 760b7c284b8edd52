"""The first linearisation point of a prioritized batch (`clear_guess`): per vehicle the
cheapest polyline (the straight move, or its midpoint pushed sideways) departing at once or
later that keeps clear of every trajectory placed before it, so that the batch's SCP refines a
guess that is already separated. A crowd crossing one point (`crosses_one_point`) also tries
wider detours and later departures; a vehicle routed around obstacles tries its route.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.methods.routes import along
from planner.methods.spacetime import ROUTE_GAP, depart
from planner.model.scenario import Scenario
from planner.scp.first_qp import unit_profile, velocity_profile
from planner.types import FloatArray

__all__ = ["DELAYS", "DETOURS", "GUESS_GAP", "WIDE_DELAYS", "WIDE_DETOURS", "Placed",
           "clear_guess", "crosses_one_point", "polylines", "positions_along"]


#: A guess is taken as soon as it keeps this many R from everything placed before it.
GUESS_GAP = 1.3
#: Departure delays tried, as fractions of the horizon.
DELAYS = (0.0, 0.1, 0.2, 0.3)
#: Sideways detours through the move's midpoint tried, in units of R.
DETOURS = (0.0, 1.5, 3.0)
#: In a crowd crossing one point (`crosses_one_point`), where no candidate of DELAYS and
#: DETOURS (four directions) keeps even R, these are tried too: later departures, a wider
#: detour and the four diagonal directions (antipodal sphere 64: no batch replanned with
#: earlier vehicles, against 18 of 64, and 4x less CPU). Elsewhere they cost more than
#: they save (grid -> sphere 256: 1.3-1.5x the CPU, tried where R is not kept).
WIDE_DELAYS = (0.05, 0.15, 0.25, 0.35, 0.4, 0.45, 0.5)
WIDE_DETOURS = (4.5,)


def _pushes(amounts: tuple[float, ...], ways: FloatArray) -> FloatArray:
    """Every amount along every way ((W, 3) unit directions), amount-major: (A W, 3)."""
    return (np.asarray(amounts)[:, None, None] * ways[None]).reshape(-1, 3)


def polylines(scenario: Scenario, vehicle: int, wide: bool = False) -> FloatArray:
    """(C, 3, 3) polylines start -> midpoint -> goal to try, cheapest first: the straight
    move, then its midpoint pushed sideways by each of DETOURS in four directions (`wide`:
    and WIDE_DETOURS, in eight)."""
    s, g = scenario.starts[vehicle], scenario.goals[vehicle]
    move = g - s
    length = float(np.linalg.norm(move))
    axis = move / length if length > 1e-9 else np.array([1.0, 0.0, 0.0])
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    side = np.cross(axis, helper)
    side /= np.linalg.norm(side)
    up = np.cross(side, axis)
    low, high = scenario.limits.position_min, scenario.limits.position_max
    ways = np.stack([side, -side, up, -up])
    pushes = _pushes(DETOURS[1:], ways)
    if wide:  # after the first set: the diagonals, then the wider detours every way
        diagonals = np.stack([side + up, side - up, up - side, -side - up]) / 2**0.5
        pushes = np.concatenate([pushes, _pushes(DETOURS[1:], diagonals),
                                 _pushes(WIDE_DETOURS, np.concatenate([ways, diagonals]))])
    pushes = pushes * scenario.min_separation
    out = np.empty((1 + len(pushes), 3, 3))
    out[:, 0], out[:, 2] = s, g
    out[0, 1] = 0.5 * (s + g)
    out[1:, 1] = np.clip(0.5 * (s + g) + pushes, low, high)
    return out


def positions_along(lines: FloatArray, scenario: Scenario, delay: int) -> FloatArray:
    """(C, K+1, 3) positions along each polyline of `lines` (C, 3, 3), waiting `delay`
    steps, then on the unit profile (as `planner.methods.routes.along`)."""
    phi = np.clip(unit_profile(scenario.steps - delay, scenario.dt)[0], 0.0, 1.0)
    seg = np.diff(lines, axis=1)  # (C, 2, 3)
    seg_len = np.maximum(np.linalg.norm(seg, axis=2), 1e-12)  # (C, 2)
    total = seg_len.sum(axis=1)  # (C,)
    travelled = phi[None, :] * total[:, None]  # (C, T)
    second = travelled > seg_len[:, :1]
    frac = np.where(second, (travelled - seg_len[:, :1]) / seg_len[:, 1:],
                    travelled / seg_len[:, :1])
    frac = np.clip(frac, 0.0, 1.0)
    base = np.where(second[..., None], lines[:, 1:2], lines[:, 0:1])
    step = np.where(second[..., None], seg[:, 1:2], seg[:, 0:1])
    p: FloatArray = base + frac[..., None] * step
    if delay:
        p = np.concatenate([np.repeat(lines[:, :1], delay, axis=1), p], axis=1)
    return p


def crosses_one_point(scenario: Scenario) -> bool:
    """Do most of the fleet's straight moves pass within R of one point, the mean of their
    midpoints (antipodal swaps, grids mirrored through their centre)? Such a crowd needs
    the wide candidates of `clear_guess`."""
    s, g = scenario.starts, scenario.goals
    centre = 0.5 * (s + g).mean(axis=0)
    move = g - s
    t = np.clip(np.einsum("nc,nc->n", centre - s, move)
                / np.maximum(np.einsum("nc,nc->n", move, move), 1e-12), 0.0, 1.0)
    miss = np.linalg.norm((s + t[:, None] * move - centre) / scenario.separation_scale, axis=1)
    return bool(len(miss) > 1 and np.median(miss) < scenario.min_separation)


def clear_guess(scenario: Scenario, others: FloatArray,
                preset: tuple[FloatArray, FloatArray, FloatArray] | None = None,
                routes: dict[int, FloatArray] | None = None, crossing: bool = False
                ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A first linearisation point for a batch: per vehicle the cheapest candidate (a
    straight or detoured polyline, departing at once or later) that keeps GUESS_GAP R at
    every step from `others` (F, K+1, 3) and from the batch's vehicles placed before it,
    else the one that keeps farthest (with `crossing`, a crowd crossing one point, the wide
    candidates too where none keeps R); the last vehicles keep `preset` (p, v, a) if given
    (earlier vehicles planned again); a vehicle with a polyline in `routes` (around
    obstacles) only tries it, departing at once or later (at rest: `_routed_departure`).
    Rows linearised about a separated point ask the QP for no jump past a fixed vehicle."""
    n, stages = len(scenario.vehicles), scenario.steps + 1
    scale = scenario.separation_scale
    p = np.zeros((n, stages, 3))
    v = np.zeros((n, stages, 3))
    a = np.zeros((n, stages - 1, 3))
    fresh = n
    if preset is not None and len(preset[0]):
        fresh = n - len(preset[0])
        p[fresh:], v[fresh:], a[fresh:] = preset
    placed = Placed(np.concatenate([others / scale, p[fresh:] / scale]))
    need = GUESS_GAP * scenario.min_separation
    drift = _drift(scenario)
    for i in range(fresh):
        lines = polylines(scenario, i)
        chosen = (lines[0], 0)
        if routes and i in routes:
            if scenario.start_velocities is None:
                p[i], v[i], a[i] = _routed_departure(
                    scenario, routes[i], polylines(scenario, i, wide=True), placed)
                placed.add(p[i] / scale)
                continue
            chosen = _route_departure(scenario, routes[i], placed.points, need,
                                      drift[0][i])
        elif len(placed.points):
            best = -np.inf
            tries = [(lines[:1], 0)] + [(lines, int(d * scenario.steps)) for d in DELAYS]
            first = len(tries)
            if crossing:
                wide = polylines(scenario, i, wide=True)
                tries += ([(wide[len(lines):], int(d * scenario.steps)) for d in DELAYS]
                          + [(wide, int(d * scenario.steps)) for d in WIDE_DELAYS])
            for number, (subset, delay) in enumerate(tries):  # the straight move first
                if number == first and best >= scenario.min_separation:
                    break  # R kept: the wide candidates would cost more than they save
                trial = (positions_along(subset, scenario, delay) + drift[0][i]) / scale
                gap = placed.gaps(trial, need)
                clear = np.flatnonzero(gap >= need)
                pick = int(clear[0]) if clear.size else int(np.argmax(gap))
                if clear.size or gap[pick] > best:
                    chosen, best = (subset[pick], delay), float(gap[pick])
                if clear.size:
                    break
        p[i], v[i], a[i] = along(chosen[0], scenario, chosen[1])
        p[i] += drift[0][i]
        v[i] += drift[1][i]
        a[i] += drift[2][i]
        placed.add(p[i] / scale)
    return p, v, a


#: Samples per segment where a detoured polyline's clearance from the obstacles is checked.
CLEARANCE_SAMPLES = 24


def _clear_lines(scenario: Scenario, lines: FloatArray) -> NDArray[np.bool_]:
    """Per polyline of `lines` (C, P, 3): does every sample along it (CLEARANCE_SAMPLES per
    segment) keep the obstacle clearance, and a quarter of it more (the samples are
    apart)? The broad phase (`ObstacleSet.near`) picks the obstacles to measure."""
    s = np.linspace(0.0, 1.0, CLEARANCE_SAMPLES)
    a, b = lines[:, :-1], lines[:, 1:]
    points = (a[:, :, None] + s[None, None, :, None] * (b - a)[:, :, None]).reshape(
        len(lines), -1, 3)
    need = 1.25 * scenario.clearance
    geometry = scenario.obstacle_set
    box, obstacle = geometry.near(points.min(axis=1), points.max(axis=1), need)
    ok = np.ones(len(lines), dtype=bool)
    if box.size == 0:
        return ok
    count = points.shape[1]
    flat = points[box].reshape(-1, 3)
    distance = geometry.signed_distance(flat, np.repeat(obstacle, count)).reshape(-1, count)
    ok[box[(distance < need).any(axis=1)]] = False
    return ok


def _routed_departure(scenario: Scenario, route: FloatArray, lines: FloatArray,
                      placed: Placed) -> tuple[FloatArray, FloatArray, FloatArray]:
    """A routed vehicle's first linearisation point from rest: its route departing at the
    first delay that keeps ROUTE_GAP R from the trajectories placed before it
    (`planner.methods.spacetime.depart`); where none does and the route is the straight move (a
    crowd crossing one opening), the first detour of `lines` (`polylines`) clear of the
    obstacles that does at one of DELAYS or WIDE_DELAYS, else the departure that keeps
    farthest."""
    scale = scenario.separation_scale
    need = ROUTE_GAP * scenario.min_separation
    trial = depart(scenario, route, placed.points)
    if len(route) != 2 or len(placed.points) == 0:
        return trial
    best = float(placed.gaps((trial[0] / scale)[None], need)[0])
    if best >= need:
        return trial
    detours = lines[1:][_clear_lines(scenario, lines[1:])]
    if len(detours) == 0:
        return trial
    chosen: tuple[FloatArray, int] | None = None
    for delay in (int(d * scenario.steps) for d in DELAYS + WIDE_DELAYS):
        gap = placed.gaps(positions_along(detours, scenario, delay) / scale, need)
        pick = int(np.argmax(gap >= need)) if (gap >= need).any() else int(np.argmax(gap))
        if gap[pick] > best:
            chosen, best = (detours[pick], delay), float(gap[pick])
        if best >= need:
            break
    return trial if chosen is None else along(chosen[0], scenario, chosen[1])


def _drift(scenario: Scenario) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(p, v, a) per vehicle that its start velocity adds to a rest-to-rest move (the
    velocity profile scaled by it, as in `straight_moves`: out along it and back, braking):
    zeros for vehicles at rest."""
    n, steps = len(scenario.vehicles), scenario.steps
    if scenario.start_velocities is None:
        return np.zeros((n, steps + 1, 3)), np.zeros((n, steps + 1, 3)), np.zeros((n, steps, 3))
    v0 = scenario.start_velocities[:, None, :]
    psi_p, psi_v, psi_a = velocity_profile(steps, scenario.dt)
    return v0 * psi_p[None, :, None], v0 * psi_v[None, :, None], v0 * psi_a[None, :, None]


#: Steps per coarse box of `Placed.gaps`.
GAP_BLOCK = 10


class Placed:
    """Trajectories placed so far (scaled positions, (F, K+1, 3)) with the boxes of their
    positions over blocks of GAP_BLOCK steps, so that a candidate is compared step by step
    only with those whose box comes near its own in the same block."""

    def __init__(self, points: FloatArray) -> None:
        self.points = points
        self.firsts = np.arange(0, points.shape[1], GAP_BLOCK)
        self.lo, self.hi = self._boxes(points)

    def _boxes(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        if len(points) == 0:
            return np.zeros((0, len(self.firsts), 3)), np.zeros((0, len(self.firsts), 3))
        return (np.minimum.reduceat(points, self.firsts, axis=1),
                np.maximum.reduceat(points, self.firsts, axis=1))

    def add(self, trajectory: FloatArray) -> None:
        lo, hi = self._boxes(trajectory[None])
        self.points = np.concatenate([self.points, trajectory[None]])
        self.lo, self.hi = np.concatenate([self.lo, lo]), np.concatenate([self.hi, hi])

    def gaps(self, trial: FloatArray, need: float) -> FloatArray:
        """Per candidate of `trial` (C, K+1, 3) its smallest distance at the same step to
        a placed trajectory; inf when no box comes within `need` (it then keeps at least
        that)."""
        lo, hi = self._boxes(trial)  # (C, B, 3)
        gap = np.maximum(0.0, np.maximum(lo[:, None] - self.hi[None], self.lo[None] - hi[:, None]))
        cand, other, block = np.nonzero(np.einsum("cfbx,cfbx->cfb", gap, gap) < need * need)
        out = np.full(len(trial), np.inf)
        if cand.size == 0:
            return out
        k = (self.firsts[block][:, None] + np.arange(GAP_BLOCK)[None, :]).reshape(-1)
        cand, other = np.repeat(cand, GAP_BLOCK), np.repeat(other, GAP_BLOCK)
        inside = k < trial.shape[1]
        cand, other, k = cand[inside], other[inside], k[inside]
        diff = trial[cand, k] - self.points[other, k]
        np.minimum.at(out, cand, np.sqrt(np.einsum("rx,rx->r", diff, diff)))
        return out


def _route_departure(scenario: Scenario, route: FloatArray, against: FloatArray,
                     need: float, drift: FloatArray) -> tuple[FloatArray, int]:
    """(route, delay): the first of DELAYS at which the route (plus the vehicle's `drift`,
    (K+1, 3)) keeps `need` from `against` (scaled positions, (F, K+1, 3)) at every step,
    else the one that keeps farthest."""
    best, chosen = -np.inf, (route, 0)
    for delay in (int(d * scenario.steps) for d in DELAYS):
        if len(against) == 0:
            return route, delay
        trial = (along(route, scenario, delay)[0] + drift) / scenario.separation_scale
        gap = float(np.sqrt(np.einsum("fkx,fkx->fk", against - trial[None],
                                      against - trial[None]).min()))
        if gap >= need:
            return route, delay
        if gap > best:
            best, chosen = gap, (route, delay)
    return chosen
