"""The separation-free first QP (SCP iteration 0), solved by structure rather than brute force.

Without separation the QP splits per vehicle and axis into identical 1-D problems that differ
only in their start and goal. Their equality-only optimum is linear in the displacement:
p = start + (goal - start) phi(t) for one unit profile phi computed once per (K, dt) (the
gravity term of the cost is constant on the feasible set, since sum_k a_z[k] dt = v_z[K] -
v_z[0] = 0). Where that profile satisfies every box it is the exact optimum; only vehicles
whose profile breaks a box (long moves, tight limits) go to one batched, block-diagonal QP.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from planner.model.scenario import Scenario
from planner.scp.qp import SeparationRows, StageLayout, build_group_qp
from planner.scp.solvers import SOLVED, QPSolver
from planner.types import FloatArray

__all__ = [
    "FirstSolution",
    "solve_first_qp",
    "straight_moves",
    "straight_moves_of",
    "timed_first_qp",
    "unit_profile",
    "velocity_profile",
]


#: Slack allowed when deciding that the closed-form profile respects a box.
BOX_TOLERANCE = 1e-9


#: Constraint groups tried, in order, when explaining an infeasible vehicle: relaxing one
#: at a time, the first whose removal makes the vehicle feasible is the one that binds.
RELAXATIONS = (
    ("jerk", {"jerk_max": None}),
    ("acceleration", {"acceleration_max": None}),
    ("velocity", {"velocity_max": None}),
    ("position", {"position_min": np.full(3, -1e9), "position_max": np.full(3, 1e9)}),
)
#: At most this many vehicles are examined one by one when the batched QP is infeasible.
DIAGNOSE_MAX_VEHICLES = 16


@dataclass(frozen=True)
class Diagnosis:
    vehicle: int
    """Scenario index of an infeasible vehicle."""
    group: str
    """The constraint group that binds ('jerk', 'acceleration', ...), or 'boxes' if no
    single group explains it."""


@dataclass(frozen=True)
class FirstSolution:
    status: str
    """'solved', or the solver status of the batched QP (e.g. 'infeasible')."""
    positions: FloatArray
    velocities: FloatArray
    accelerations: FloatArray
    qp_solves: int
    """0 when every closed-form profile was already optimal, else 1 (the batched QP)."""
    diagnosis: Diagnosis | None = None


@lru_cache(maxsize=32)
def _unit_profile_cached(steps: int, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    return _solve_unit_profile(steps, dt)


def unit_profile(steps: int, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(p, v, a) of the minimum-thrust rest-to-rest move from 0 to 1 with a[K-1] = 0."""
    return _unit_profile_cached(int(steps), float(dt))


@lru_cache(maxsize=32)
def _velocity_profile_cached(steps: int, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    return _solve_unit_profile(steps, dt, moving=True)


def velocity_profile(steps: int, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(p, v, a) of the minimum-thrust move from 0 at unit velocity back to 0 at rest: the
    part of the optimum that a start velocity adds (the optimum is linear in the start
    state and the goal)."""
    return _velocity_profile_cached(int(steps), float(dt))


def _solve_unit_profile(steps: int, dt: float, moving: bool = False
                        ) -> tuple[FloatArray, FloatArray, FloatArray]:
    # One fake vehicle moving from 0 to 1 on every axis (or, `moving`, from 0 at unit
    # velocity back to 0); only the equalities matter here.
    from planner.model.scenario import Limits, Vehicle

    limits = Limits(
        position_min=np.full(3, -np.inf), position_max=np.full(3, np.inf),
        velocity_max=None, acceleration_max=None, jerk_max=None,
        thrust_min=0.0, thrust_max=np.inf, body_rate_max=np.inf,
    )
    unit = Scenario(
        name="unit", dt=dt, steps=steps, min_separation=1.0,
        separation_scale=np.ones(3), cost_threshold=1.0, max_iterations=1, limits=limits,
        vehicles=(Vehicle("u", np.zeros(3), np.ones(3)),),
        starts=np.zeros((1, 3)), goals=np.zeros((1, 3)) if moving else np.ones((1, 3)),
        start_velocities=np.ones((1, 3)) if moving else None,
    )
    qp = build_group_qp(unit, np.arange(1), SeparationRows.empty())
    n = qp.size
    kkt = sp.bmat([[qp.P, qp.A.T], [qp.A, None]], format="csc")
    rhs = np.concatenate([-qp.q, qp.b])
    # Remove the gravity term: it is constant on the feasible set, and keeping it would
    # tilt the z-profile by a multiple of the null space only through round-off.
    rhs[:n] = 0.0
    sol = spla.spsolve(kkt, rhs)
    p, v, a = StageLayout(steps, 1).unpack(sol[:n])
    return p[0, :, 0].copy(), v[0, :, 0].copy(), a[0, :, 0].copy()


def _profile_fits(scenario: Scenario, p: FloatArray, v: FloatArray, a: FloatArray
                  ) -> NDArray[np.bool_]:
    """Per vehicle: does the closed-form trajectory respect every box?"""
    lim = scenario.limits
    tol = BOX_TOLERANCE
    middle = p[:, :-1] + 0.5 * scenario.dt * v[:, :-1]  # Bernstein middle points
    ok: NDArray[np.bool_] = np.all((p >= lim.position_min - tol) & (p <= lim.position_max + tol),
                                   axis=(1, 2))
    ok &= np.all((middle >= lim.position_min - tol) & (middle <= lim.position_max + tol),
                 axis=(1, 2))
    if lim.velocity_max is not None:
        ok &= np.all(np.abs(v) <= lim.velocity_max + tol, axis=(1, 2))
    if lim.acceleration_max is not None:
        ok &= np.all(np.abs(a) <= lim.acceleration_max + tol, axis=(1, 2))
    if lim.jerk_max is not None:
        da = np.diff(a, axis=1, prepend=scenario.initial_accelerations[:, None, :])
        ok &= np.all(np.abs(da) <= lim.jerk_max * scenario.dt + tol, axis=(1, 2))
    return ok


def straight_moves(scenario: Scenario) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Every vehicle on the unit profile scaled by its move: synchronised straight
    rest-to-rest moves (CAPT's trajectories, see `planner.methods.assignment`), boxes ignored; a
    vehicle with a start velocity adds the velocity profile scaled by it (then the move is
    no longer straight, but it is still the separation-free optimum without boxes)."""
    return straight_moves_of(scenario, np.arange(len(scenario.vehicles)))


def straight_moves_of(scenario: Scenario, members: NDArray[np.intp]
                      ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """`straight_moves` of the vehicles `members` (scenario indices)."""
    phi_p, phi_v, phi_a = unit_profile(scenario.steps, scenario.dt)
    start = scenario.starts[members][:, None, :]
    move = (scenario.goals[members] - scenario.starts[members])[:, None, :]
    p = start + move * phi_p[None, :, None]
    v = move * phi_v[None, :, None]
    a = move * phi_a[None, :, None]
    if scenario.start_velocities is not None:
        psi_p, psi_v, psi_a = velocity_profile(scenario.steps, scenario.dt)
        v0 = scenario.start_velocities[members][:, None, :]
        p, v, a = p + v0 * psi_p[None, :, None], v + v0 * psi_v[None, :, None], \
            a + v0 * psi_a[None, :, None]
    return p, v, a


def timed_first_qp(scenario: Scenario, solver: QPSolver) -> tuple[FirstSolution, float]:
    """`solve_first_qp` and the seconds it took (the plan's `first_qp_s`)."""
    began = time.perf_counter()
    first = solve_first_qp(scenario, solver)
    return first, time.perf_counter() - began


def solve_first_qp(scenario: Scenario, solver: QPSolver) -> FirstSolution:
    """Iteration 0: every vehicle's separation-free optimum."""
    p, v, a = straight_moves(scenario)
    fits = _profile_fits(scenario, p, v, a)
    needs_qp = np.flatnonzero(~fits)
    if needs_qp.size == 0:
        return FirstSolution("solved", p, v, a, 0)
    qp = build_group_qp(scenario, needs_qp, SeparationRows.empty())
    result = solver.solve(qp)
    if result.status != SOLVED or result.x is None:
        return FirstSolution(result.status, p, v, a, 1, diagnose(scenario, needs_qp, solver))
    qp_p, qp_v, qp_a = StageLayout(scenario.steps, len(needs_qp)).unpack(result.x)
    p, v, a = p.copy(), v.copy(), a.copy()
    p[needs_qp], v[needs_qp], a[needs_qp] = qp_p, qp_v, qp_a
    return FirstSolution("solved", p, v, a, 1)


def _feasible(scenario: Scenario, vehicle: int, solver: QPSolver, **relax: Any) -> bool:
    limits = dataclasses.replace(scenario.limits, **relax)
    relaxed = dataclasses.replace(scenario, limits=limits)
    qp = build_group_qp(relaxed, np.array([vehicle]), SeparationRows.empty())
    return solver.solve(qp).status == SOLVED


def diagnose(scenario: Scenario, candidates: NDArray[np.intp], solver: QPSolver
             ) -> Diagnosis | None:
    """Find a vehicle whose own separation-free QP is infeasible, and which box binds."""
    for vehicle in candidates[:DIAGNOSE_MAX_VEHICLES].tolist():
        if _feasible(scenario, vehicle, solver):
            continue
        for group, relax in RELAXATIONS:
            if _feasible(scenario, vehicle, solver, **relax):
                return Diagnosis(vehicle, group)
        return Diagnosis(vehicle, "boxes")
    return None
