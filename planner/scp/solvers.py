"""QP backends behind one small interface: PIQP and Clarabel (interior point), OSQP (ADMM).

`make_solver(name)` returns an object with `solve(qp, warm_start=None) -> QPSolution`. A
backend may keep state between calls (OSQP keeps its factorisation and, when the sparsity of
the new problem equals the last one, calls `update` and warm-starts instead of a new setup).
Infeasibility is reported in `QPSolution.status`, never raised; `SolverError` is for a
missing backend or a solver that broke down.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

from planner.errors import SolverError
from planner.scp.qp import QuadraticProgram
from planner.types import FloatArray

__all__ = ["DEFAULT_SOLVER", "SOLVERS", "QPSolution", "QPSolver", "make_solver"]


#: Statuses a backend reports.
SOLVED, INFEASIBLE, MAX_ITER, FAILED = "solved", "infeasible", "max_iterations", "failed"


@dataclass(frozen=True)
class QPSolution:
    status: str
    x: FloatArray | None
    objective: float
    """1/2 x'Px + q'x + constant (the total-thrust cost), nan when not solved."""
    iterations: int
    seconds: float
    separation_duals: FloatArray | None = None
    """Multipliers (>= 0) of the separation rows (the last rows of G): > 0 means active."""


class QPSolver(Protocol):
    name: str

    def solve(self, qp: QuadraticProgram, warm_start: FloatArray | None = None) -> QPSolution: ...


def _objective(qp: QuadraticProgram, x: FloatArray) -> float:
    return float(0.5 * x @ (qp.P @ x) + qp.q @ x + qp.constant)


def solved(qp: QuadraticProgram, x: FloatArray, iterations: int, seconds: float,
           duals: FloatArray | None) -> QPSolution:
    """A backend's "solved" answer, checked: a solution with NaN or infinite entries (or
    objective) is a breakdown (`FAILED`), so no non-finite trajectory leaves the SCP loop."""
    if not np.isfinite(x).all():
        return QPSolution(FAILED, None, float("nan"), iterations, seconds)
    objective = _objective(qp, x)
    if not np.isfinite(objective):
        return QPSolution(FAILED, None, float("nan"), iterations, seconds)
    return QPSolution(SOLVED, x, objective, iterations, seconds, duals)


class PiqpSolver:
    """PIQP (proximal interior point), sparse LDL'. Native form, no conversion."""

    name = "piqp"

    def __init__(self, tolerance: float = 1e-8, kkt_solver: str = "sparse_ldlt") -> None:
        import piqp

        self._piqp = piqp
        self._tolerance = tolerance
        self._kkt = getattr(piqp.KKTSolver, kkt_solver)

    def solve(self, qp: QuadraticProgram, warm_start: FloatArray | None = None) -> QPSolution:
        piqp = self._piqp
        began = time.perf_counter()
        solver = piqp.SparseSolver()
        s = solver.settings
        s.eps_abs = self._tolerance
        s.eps_rel = self._tolerance * 1e-1
        s.max_iter = 200
        s.kkt_solver = self._kkt
        # Our rows are already well scaled (unit directions, unit dynamics coefficients);
        # PIQP's default 10 Ruiz passes cost ~10% of the time and changed no result.
        s.preconditioner_iter = 2
        solver.setup(
            qp.P, qp.q, qp.A, qp.b,
            qp.G if qp.G.shape[0] else None,
            qp.h_l if qp.G.shape[0] else None,
            qp.h_u if qp.G.shape[0] else None,
            qp.x_l, qp.x_u,
        )
        status = solver.solve()
        seconds = time.perf_counter() - began
        iterations = int(solver.result.info.iter)
        if status == piqp.PIQP_SOLVED:
            x = np.array(solver.result.x)
            duals = np.array(solver.result.z_l)[qp.G.shape[0] - qp.separation_rows:]
            return solved(qp, x, iterations, seconds, duals)
        if status in (piqp.PIQP_PRIMAL_INFEASIBLE, piqp.PIQP_DUAL_INFEASIBLE):
            return QPSolution(INFEASIBLE, None, float("nan"), iterations, seconds)
        if status == piqp.PIQP_MAX_ITER_REACHED:
            return QPSolution(MAX_ITER, None, float("nan"), iterations, seconds)
        return QPSolution(FAILED, None, float("nan"), iterations, seconds)


class ClarabelSolver:
    """Clarabel (interior point, conic). Boxes become non-negative cone rows."""

    name = "clarabel"

    def __init__(self, tolerance: float = 1e-8) -> None:
        import clarabel

        self._clarabel = clarabel
        self._tolerance = tolerance

    def solve(self, qp: QuadraticProgram, warm_start: FloatArray | None = None) -> QPSolution:
        clarabel = self._clarabel
        began = time.perf_counter()
        n = qp.size
        eye = sp.identity(n, format="csc")
        blocks = [qp.A]
        rhs = [qp.b]
        ineq: list[sp.csc_matrix] = []
        ineq_rhs: list[FloatArray] = []
        lower_rows_of_g = np.zeros(0, dtype=np.intp)  # where G's lower-bound rows land
        for mat, lo, hi in ((qp.G, qp.h_l, qp.h_u), (eye, qp.x_l, qp.x_u)):
            up = np.isfinite(hi)
            dn = np.isfinite(lo)
            if up.any():
                ineq.append(mat[up])
                ineq_rhs.append(hi[up])
            if dn.any():
                if mat is qp.G:
                    offset = qp.A.shape[0] + sum(m.shape[0] for m in ineq)
                    lower_rows_of_g = offset + np.cumsum(dn) - 1
                ineq.append(-mat[dn])
                ineq_rhs.append(-lo[dn])
        n_ineq = sum(m.shape[0] for m in ineq)
        A = sp.vstack(blocks + ineq, format="csc")
        b = np.concatenate(rhs + ineq_rhs)
        cones = [clarabel.ZeroConeT(qp.A.shape[0])]
        if n_ineq:
            cones.append(clarabel.NonnegativeConeT(n_ineq))
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = self._tolerance
        settings.tol_gap_rel = self._tolerance
        settings.tol_feas = self._tolerance
        solver = clarabel.DefaultSolver(sp.triu(qp.P, format="csc"), qp.q, A, b, cones, settings)
        sol = solver.solve()
        seconds = time.perf_counter() - began
        status = str(sol.status)
        if status in ("Solved", "AlmostSolved"):
            x = np.array(sol.x)
            duals = None
            if qp.separation_rows:
                z = np.array(sol.z)
                duals = z[lower_rows_of_g[qp.G.shape[0] - qp.separation_rows:]]
            return solved(qp, x, int(sol.iterations), seconds, duals)
        if "Infeasible" in status:
            return QPSolution(INFEASIBLE, None, float("nan"), int(sol.iterations), seconds)
        if status == "MaxIterations":
            return QPSolution(MAX_ITER, None, float("nan"), int(sol.iterations), seconds)
        return QPSolution(FAILED, None, float("nan"), int(sol.iterations), seconds)


class OsqpSolver:
    """OSQP (ADMM) called directly; reuses its factorisation through `update` when the new
    problem has the same sparsity as the previous one, and warm-starts from `warm_start`."""

    name = "osqp"

    def __init__(self, tolerance: float = 1e-7) -> None:
        import osqp

        self._osqp = osqp
        self._tolerance = tolerance
        self._solver: Any = None
        """The OSQP instance of the last problem (reused while the sparsity is the same)."""
        self._pattern: tuple[tuple[int, ...], bytes, bytes] | None = None
        self.setups = 0
        """How many times an OSQP instance was set up (factorised afresh); a problem with the
        last one's sparsity is updated instead, so this stays put."""

    @staticmethod
    def _stack(qp: QuadraticProgram) -> tuple[sp.csc_matrix, FloatArray, FloatArray]:
        n = qp.size
        bounded = np.isfinite(qp.x_l) | np.isfinite(qp.x_u)
        eye = sp.identity(n, format="csr")[bounded]
        A = sp.vstack([qp.A, qp.G, eye], format="csc")
        lo = np.concatenate([qp.b, qp.h_l, qp.x_l[bounded]])
        hi = np.concatenate([qp.b, qp.h_u, qp.x_u[bounded]])
        return A, lo, hi

    def solve(self, qp: QuadraticProgram, warm_start: FloatArray | None = None) -> QPSolution:
        osqp = self._osqp
        began = time.perf_counter()
        A, lo, hi = self._stack(qp)
        A.sort_indices()
        pattern = (A.shape, A.indptr.tobytes(), A.indices.tobytes())
        if self._solver is not None and pattern == self._pattern:
            solver = self._solver
            solver.update(q=qp.q, Ax=A.data, l=lo, u=hi)
        else:
            solver = osqp.OSQP()
            solver.setup(
                sp.triu(qp.P, format="csc"), qp.q, A, lo, hi,
                eps_abs=self._tolerance, eps_rel=self._tolerance,
                max_iter=200000, polishing=True, verbose=False,
                scaled_termination=False, adaptive_rho=True,
            )
            self._solver, self._pattern = solver, pattern
            self.setups += 1
        if warm_start is not None:
            solver.warm_start(x=warm_start)
        result = solver.solve(raise_error=False)
        seconds = time.perf_counter() - began
        status = str(result.info.status).lower()
        iterations = int(result.info.iter)
        if status.startswith("solved") and result.x is not None:
            x = np.array(result.x)
            end = qp.A.shape[0] + qp.G.shape[0]
            duals = np.maximum(0.0, -np.array(result.y)[end - qp.separation_rows:end])
            return solved(qp, x, iterations, seconds, duals)
        if "infeasible" in status:
            return QPSolution(INFEASIBLE, None, float("nan"), iterations, seconds)
        if "maximum iterations" in status:
            return QPSolution(MAX_ITER, None, float("nan"), iterations, seconds)
        return QPSolution(FAILED, None, float("nan"), iterations, seconds)


SOLVERS: dict[str, Callable[[], QPSolver]] = {
    "piqp": PiqpSolver, "clarabel": ClarabelSolver, "osqp": OsqpSolver}
DEFAULT_SOLVER = "piqp"


def make_solver(name: str | None = None) -> QPSolver:
    """A fresh backend by name ('piqp', 'clarabel', 'osqp'); None gives the default."""
    key = DEFAULT_SOLVER if name is None else name
    if key not in SOLVERS:
        raise SolverError(f"unknown solver {key!r}; choose one of {', '.join(SOLVERS)}")
    try:
        return SOLVERS[key]()
    except ImportError as exc:  # pragma: no cover - all three are dependencies
        raise SolverError(f"solver {key!r} is not installed: {exc}") from exc
